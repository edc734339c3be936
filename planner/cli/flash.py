"""``vlp-flash PLAN --port PORT``: flash the luminaires' drivers with their configuration images.

The plan must be sealed under the site key (``plan.yaml.seal``, written by ``vlp-plan --key-file``).
Each image is rebuilt from ``plan.yaml`` (and must equal ``firmware/<name>/vlp_config.bin``),
then signed for the driver that answers, at the version docs/flashing.md describes.
Interactive (default): one driver at a time on a point-to-point cable, the installer
is told which luminaire to plug. ``--bus``: every driver on one multi-drop bus,
addressed from ``--bus-map`` (else plan order from 1). Every result goes to the
as-built journal at once; ``--resume`` skips drivers it records as verified.
Exit codes: 0 every driver verified, 3 some failed (named; they keep their previous
configuration), 1 bad input, 2 usage (missing, busy, unknown or lost port).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import urllib.parse
from pathlib import Path
from typing import TYPE_CHECKING

from planner.cli import common as cli
from planner.defaults import MAX_IMAGE_VERSION
from planner.errors import ExitCode, InputError, UsageError

if TYPE_CHECKING:  # the stages load when the command runs, not when it parses
    from planner.flash.flasher import Versions
    from planner.flash.journal import Journal
    from planner.plan.file import Entry, PlanFile


def build_parser() -> argparse.ArgumentParser:
    p = cli.parser(
        "vlp-flash",
        "Flash luminaire drivers over a serial link with their configuration "
        "images, rebuilt from the plan (sealed under the site key by vlp-plan --key-file; they must equal "
        "the ones vlp-plan wrote in OUTDIR/firmware/) and "
        "signed with each driver's key (derived from the site key and the serial it reports); verify "
        "and journal each.",
        ok="all verified", check_failed="some drivers failed",
        bad_input="(a plan not sealed under the site key or an image file that differs from the plan)",
        usage="(or the port lost mid-batch: rerun with --resume)", docs="docs/flashing.md, docs/protocol.md",
        json="print the outcome per driver as JSON on stdout (progress goes to stderr); needs --bus or --dry-run",
    )
    p.add_argument("plan", metavar="PLAN", nargs="?", help="plan.yaml in a vlp-plan output directory")
    p.add_argument("names", metavar="LUMINAIRE", nargs="*", help="luminaires to flash (or --all)")
    p.add_argument("--all", action="store_true", help="every luminaire of the plan")
    p.add_argument("--port", help="serial port: a device (/dev/ttyUSB0, COM3), a pseudo-terminal, or sim://...")
    p.add_argument("--baud", type=cli.positive_int, default=115200, help="line rate [bit/s] (default 115200)")
    p.add_argument("--extra-timeout-ms", type=cli.at_most(10_000.0, strict=False), default=0.0, metavar="MS",
                   help="added to every request's timeout: for USB adapters with a latency timer, radio links or "
                   "emulated drivers on a busy machine (default 0, at most 10000)")
    p.add_argument("--driver-deadline-s", type=cli.at_most(3600.0), default=120.0, metavar="S",
                   help="time one driver may take, retries included, before it is reported failed and the batch "
                   "goes on (default 120, at most 3600)")
    p.add_argument("--bus", action="store_true", help="batch mode: all drivers on one multi-drop bus, no prompts")
    p.add_argument("--bus-map", metavar="CSV", help="with --bus: 'name,address' rows (default: plan order, from 1)")
    p.add_argument("--key-file", metavar="FILE", help="site key, hex or raw bytes (or env VLP_SITE_KEY, hex)")
    p.add_argument("--journal", metavar="JSON", help="as-built journal (default: as-built.json beside PLAN)")
    p.add_argument("--resume", action="store_true", help="skip drivers the journal records as verified")
    p.add_argument("--image-version", type=cli.count_up_to(MAX_IMAGE_VERSION), metavar="N",
                   help=f"sign exactly version N, at most {MAX_IMAGE_VERSION:,} (a driver at 2^32 - 1 could never "
                        "be updated again; drivers refuse one not above what they run); default: one above "
                        "the version each driver runs, at least the version in the plan's images, and never over "
                        "a newer image the journal shows came after this plan's (docs/flashing.md)")
    p.add_argument("--replace-driver", action="store_true",
                   help="let a driver other than the one bound to a luminaire in the journal take its image (a "
                   "replaced driver), or a driver bound to another luminaire move (journaled); without it both are "
                   "refused")
    p.add_argument("--dry-run", action="store_true", help="say what would be flashed; open no port (the plan's seal "
                   "is checked only with a key)")
    p.add_argument("--verify-only", action="store_true", help="only check that each driver holds its image")
    p.add_argument("--list-ports", action="store_true", help="list the serial ports of this machine and exit")
    return p




def _ports_text() -> str:
    from serial.tools import list_ports

    ports = [f"{p.device} ({p.description})" for p in list_ports.comports()]
    return ", ".join(ports) if ports else "none found"


def open_port(url: str, baud: int):
    """Open ``url`` exclusively; a missing or busy port is a :class:`UsageError` naming the ports there are."""
    import serial

    from planner.flash.sim import protocol_sim

    protocol_sim.register()
    try:
        return serial.serial_for_url(url, baudrate=baud, timeout=0.1, exclusive=True)
    except (serial.SerialException, ValueError, OSError) as exc:
        text = str(exc).replace(url, shown_port(url))  # pyserial may quote the URL, key and all
        if not isinstance(exc, protocol_sim.SimUrlError) and ("lock" in text.lower() or "busy" in text.lower()):
            raise UsageError(f"--port {shown_port(url)}: busy: another program holds it; close it and retry") from None
        raise UsageError(f"--port {shown_port(url)}: cannot open ({text}); serial ports here: {_ports_text()}") from None


SHOWN_PARAMETERS = ("drivers", "first", "prefix", "flash", "faults", "paced", "slot_size", "max_block",
                    "block_write_us", "protocol")
"""``sim://`` parameters whose values are shown; any other (``key``, a misspelt ``kye``) shows as ``<hidden>``."""


def shown_port(url: str) -> str:
    """``url`` as messages, the journal and ``--json`` show it: a ``sim://`` URL's key is never written out, nor
    the value of any parameter but the known harmless ones (a misspelt ``key`` stays hidden)."""
    head, sep, query = url.partition("?")
    if head.lower().startswith("sim://") and head[6:]:  # a sim:// URL has nothing before its query: a key pasted?
        head = "sim://<hidden>"
    items = []
    for item in query.split("&") if sep else []:
        name, eq, _ = item.partition("=")
        plain = urllib.parse.unquote_plus(name).strip().lower()
        items.append(item if plain in SHOWN_PARAMETERS or not eq else
                     f"{plain if plain.isidentifier() else '<hidden>'}=<hidden>")
    return head + sep + "&".join(items)


def _targets(plan: PlanFile, args) -> list[Entry]:
    lums = {e.name: e for e in plan.luminaires}
    if args.all == bool(args.names):
        raise UsageError("name the luminaires to flash, or give --all (not both)")
    missing = [n for n in args.names if n not in lums]
    if missing:
        raise UsageError(f"no luminaire {missing[0]!r} in {args.plan}")
    return [lums[n] for n in args.names] if args.names else list(plan.luminaires)


def plan_image(doc_path: Path, entry: Entry, digest: str) -> bytes:
    """The unsigned image the plan gives ``entry``, at the version of its file on disk; :class:`InputError`
    if the file is missing, damaged, of another plan, over the version bound, or differs in any byte."""
    from planner.firmware.image import config_image, parse_config_image
    from planner.firmware.render import IMAGE_FILE, file_name

    path = doc_path.parent / "firmware" / file_name(entry.name) / IMAGE_FILE
    try:
        on_disk = path.read_bytes()
    except OSError:
        raise InputError(f"{path}: missing; run vlp-plan again (without --no-firmware)") from None
    try:
        fields = parse_config_image(on_disk)
    except InputError as exc:
        raise InputError(f"{path}: {exc}; run vlp-plan again") from None
    if fields["plan_hash"] != digest:
        raise InputError(f"{path}: made for another plan than {doc_path}; run vlp-plan again")
    if fields["image_version"] > MAX_IMAGE_VERSION:
        raise InputError(f"{path}: image version {fields['image_version']:,} is above the {MAX_IMAGE_VERSION:,} "
                         "vlp-flash signs (a driver could never be updated again); run vlp-plan again")
    if entry.frame is None:
        raise InputError(f"{doc_path}: luminaire {entry.name!r} has no frame; make the plan with a vlp-plan that "
                         "writes frames")
    image = config_image(entry.name, entry.id, entry.frame.chips, entry.frame.chip_rate_hz, digest,
                         image_version=fields["image_version"])
    if image != on_disk:
        given = parse_config_image(image)
        wrong = [k for k in given if k != "crc32" and given[k] != fields[k]] or ["bytes"]
        raise InputError(f"{path}: differs from what {doc_path.name} gives luminaire {entry.name} (ID {entry.id}) in "
                         f"{', '.join(wrong)}: edited, or copied from another luminaire; vlp-flash signs only what "
                         "the plan gives: run vlp-plan again")
    return image


def _versions(journal: Journal, e: Entry, image: bytes, explicit: int | None) -> Versions:
    from planner.firmware.image import parse_config_image
    from planner.flash.flasher import Versions

    return Versions(floor=parse_config_image(image)["image_version"], explicit=explicit,
                    journal=journal.last_verified(e.name))


def _acceptor(journal: Journal, name: str, args, say):
    """flash_driver's ``accept``: the journal's binding of luminaires to drivers (``--replace-driver`` lifts it);
    in interactive mode the installer sees which driver answered before anything is written."""
    shown: set[str] = set()

    def accept(hello) -> str | None:
        refusal = None if args.replace_driver else journal.refusal(name, hello.serial)
        if not args.bus and hello.serial not in shown:
            shown.add(hello.serial)
            bound = journal.bound(name)
            print(f"  driver {hello.serial} answered (proved its key; runs version {hello.active_version}); "
                  + (f"{name} is bound to {bound}" if bound else f"{name} has no driver bound yet")
                  + (": refused" if refusal else ""), file=say, flush=True)
        return refusal
    return accept


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.list_ports:
        print(_ports_text())
        return 0
    if not args.plan:
        raise UsageError("give a PLAN (see vlp-flash --help)")
    if args.json and not (args.bus or args.dry_run):
        raise UsageError("--json needs --bus or --dry-run: interactive mode talks to the installer on this terminal")
    say = sys.stderr if args.json else sys.stdout  # with --json, stdout carries the JSON document alone
    report: list[dict] = []
    doc_path = Path(args.plan)
    from planner._files import read_text
    from planner.flash.flasher import flash_driver
    from planner.flash.journal import Journal
    from planner.flash.link import Link, PortLost
    from planner.flash.seal import check_seal
    from planner.flash.wire import ANY_ADDRESS
    from planner.plan.file import load_plan
    from planner.plan.model import plan_hash

    text = read_text(doc_path, "plan", "no such plan file; run vlp-plan first")  # one read: checked, hashed, sealed
    key = None if args.dry_run and not (args.key_file or os.environ.get("VLP_SITE_KEY")) else cli.site_key(args.key_file)
    sealed = ""  # the plan's generation: the time of its seal (a journal refuses a plan older than its own)
    if key is not None:  # only the site key's holder makes a plan vlp-flash signs images of (docs/plan-format.md)
        sealed = check_seal(doc_path, text, key)
    plan = load_plan(doc_path, text)
    digest = plan_hash(text)
    targets = _targets(plan, args)
    images = {e.name: plan_image(doc_path, e, digest) for e in targets}
    from planner.flash.bus_map import read_bus_map

    where = read_bus_map(plan, args.bus_map) if args.bus else {}
    if args.bus and (absent := [e.name for e in targets if e.name not in where]):
        raise InputError(f"--bus-map {args.bus_map}: no address for {absent[0]!r}")
    journal = Journal(args.journal or doc_path.with_name("as-built.json"), digest, key, sealed)
    if args.dry_run:
        for e in targets:
            skip = args.resume and journal.verified(e.name, args.image_version) is not None
            action = "skip" if skip else "verify" if args.verify_only else "flash"
            report.append({"name": e.name, "id": e.id, "address": where[e.name] if args.bus else None,
                           "action": action})
            print(f"{e.name:<16} id {e.id:<6} {'address ' + str(where[e.name]) if args.bus else 'plug in'}"
                  f"  {'skip (journal: verified)' if skip else action}", file=say)
        if args.json:
            print(json.dumps({"plan": str(doc_path), "dry_run": True, "drivers": report}, indent=2))
        return 0
    if not args.port:
        raise UsageError("give --port PORT (vlp-flash --list-ports lists them)")
    if not args.bus and not sys.stdin.isatty():
        raise UsageError("interactive mode asks the installer to plug each driver and needs a terminal; "
                         "use --bus for a batch without prompts")
    assert key is not None  # only a dry run goes without
    journal.check_writable()
    port, shown = open_port(args.port, args.baud), shown_port(args.port)
    link, failed, name = Link(port, args.baud, extra_timeout_s=args.extra_timeout_ms / 1000), [], ""
    try:
        for k, e in enumerate(targets, 1):
            name, image = e.name, images[e.name]
            if args.resume and journal.verified(name, args.image_version):
                print(f"[{k}/{len(targets)}] {name}: skipped (journal: verified)", file=say)
                report.append({"name": name, "id": e.id, "status": "skipped", "verified": True})
                continue
            if not args.bus:
                answer = input(f"[{k}/{len(targets)}] plug the driver of {name} (ID {e.id}, at x {e.x:.2f} m, "
                               f"y {e.y:.2f} m) and press Enter; s skips, q quits: ").strip().lower()
                if answer == "q":
                    break
                if answer == "s":
                    continue
            address = where.get(name, ANY_ADDRESS)
            result = flash_driver(link, address, image, key, _versions(journal, e, image, args.image_version),
                                  verify_only=args.verify_only, deadline_s=args.driver_deadline_s,
                                  accept=_acceptor(journal, name, args, say))
            journal.record(name, e.id, f"{shown}@{address}" if args.bus else shown, result)
            text = f"{result.status}, {'verified' if result.verified else 'NOT verified'}"
            version = f"version {result.image_version}, " if result.image_version else ""
            print(f"[{k}/{len(targets)}] {name}: driver {result.serial or '?'}: {text} ({version}{result.seconds:.2f} s)"
                  + (f": {result.message}" if result.message else ""), file=say, flush=True)
            report.append({"name": name, "id": e.id, "address": address if args.bus else None,
                           "serial": result.serial, "status": result.status, "verified": result.verified,
                           "image_version": result.image_version, "active_version": result.active_version,
                           "seconds": round(result.seconds, 3), "message": result.message})
            if not result.verified:
                failed.append(name)
            if args.bus and sys.stderr.isatty():
                done = int(30 * k / len(targets))
                print(f"\r  [{'#' * done}{'.' * (30 - done)}] {k}/{len(targets)}, {len(failed)} failed",
                      end="" if k < len(targets) else "\n", file=sys.stderr, flush=True)
    except PortLost as exc:
        done = sum(1 for t in targets if journal.verified(t.name))
        raise PortLost(f"--port {shown}: lost while flashing {name}: {exc}; {done} of {len(targets)} driver(s) "
                       f"verified in {journal.path}: reconnect and rerun with --resume") from None
    finally:
        try:
            port.close()
        except OSError:
            pass  # the port is gone already
    if args.json:
        line = {"requests": link.stats.requests, "retries": link.stats.retries, "bytes_sent": link.stats.bytes_sent,
                "bytes_received": link.stats.bytes_received, "dropped_frames": link.stats.dropped_frames}
        print(json.dumps({"plan": str(doc_path), "port": shown, "journal": str(journal.path), "drivers": report,
                          "verified": sum(r["verified"] for r in report), "failed": len(failed), "link": line},
                         indent=2))
    if failed:
        print(f"vlp-flash: {len(failed)} driver(s) failed and keep their previous configuration: "
              f"{', '.join(failed[:10])}{' ...' if len(failed) > 10 else ''}; journal {journal.path}", file=sys.stderr)
        return ExitCode.CHECK_FAILED
    return 0


def console_main(argv: list[str] | None = None) -> int:
    return cli.console_main(argv, main, "vlp-flash")


if __name__ == "__main__":
    sys.exit(console_main())
