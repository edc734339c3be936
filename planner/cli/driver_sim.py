"""``vlp-driver-sim``: simulated drivers behind a pseudo-terminal, for hosts that open a real port.

Prints the terminal's path as the first line of stdout, then serves until SIGTERM or
SIGINT (exit 0). Each driver's flash is the file ``<serial>.flash`` in ``--flash-dir``
(kept; default a temporary folder, reported on stderr and removed at exit). The host
may close and reopen the terminal at will.

``--firmware avr`` runs the reference firmware (firmware_templates/driver/) on emulated
ATmega328P MCUs instead of the Python model (planner/flash/avr/): one shared line, each
driver's EEPROM the file ``<serial>.eeprom`` in ``--eeprom-dir``, its LED pin traced to
``--trace DIR/<address>.vcd``.
"""

from __future__ import annotations

import argparse
import heapq
import json
import os
import select
import shutil
import signal
import sys
import tempfile
import time
import tty
from pathlib import Path
from typing import TYPE_CHECKING

from planner.cli import common as cli
from planner.errors import UsageError

if TYPE_CHECKING:  # the simulator loads when the command runs, not when it parses (--help at once)
    from planner.flash.sim.bus import SimBus

PROG = "vlp-driver-sim"


def build_parser() -> argparse.ArgumentParser:
    p = cli.parser(PROG, "Simulated luminaire drivers (docs/protocol.md) on a pseudo-terminal.",
                   ok="stopped by SIGTERM or SIGINT (Ctrl-C)", docs="docs/flashing.md, docs/protocol.md",
                   json="print the port, the drivers' addresses and the flash folder as one JSON line on stdout, "
                   "instead of the port alone")
    p.add_argument("--firmware", choices=("sim", "avr"), default="sim",
                   help="sim: the Python driver model (default); avr: the reference C firmware on emulated "
                        "ATmega328P MCUs (needs gcc-avr, avr-libc, simavr, libsimavr-dev)")
    p.add_argument("--drivers", type=int, default=1, metavar="N", help="drivers sharing the line (default 1)")
    p.add_argument("--first-address", type=int, default=1, metavar="N", help="bus address of the first driver (default 1)")
    p.add_argument("--key-file", type=Path, required=True, metavar="FILE", help="site key: a file holding it in hex or raw (16-64 bytes)")
    p.add_argument("--faults", default="", metavar="SPEC", help="fault spec, e.g. corrupt=0.001,reset=0.01,power=0.01,stall=0.01,seed=3")
    p.add_argument("--flash-dir", type=Path, metavar="DIR", help="folder of the drivers' flash files (default: a temporary folder)")
    p.add_argument("--serial-prefix", metavar="PREFIX", help="serial number prefix (default SIM-, AVR- with --firmware avr)")
    p.add_argument("--slot-size", type=int, metavar="BYTES", help="bytes per slot (default 4096)")
    p.add_argument("--max-block", type=int, metavar="BYTES", help="most data bytes per WRITE (default 256)")
    p.add_argument("--block-write-us", type=int, metavar="US", help="reported block programming time [us] (default 2000)")
    p.add_argument("--eeprom-dir", type=Path, metavar="DIR", help="with --firmware avr: folder of the drivers' EEPROM images "
                                                   "(default: a temporary folder)")
    p.add_argument("--trace", type=Path, metavar="DIR", help="with --firmware avr: write each driver's LED pin "
                                                              "to DIR/<address>.vcd")
    p.add_argument("--build-dir", type=Path, metavar="DIR", help="with --firmware avr: where the firmware and emulator are built "
                                                  "(default ~/.cache/vlp-plan/avr)")
    return p


def _wake_on_signals() -> tuple[int, int]:
    """A pipe that SIGTERM and SIGINT write to instead of ending the process, so the serving loop stops and
    the finally blocks clean up (temporary folders, emulators)."""
    wake_r, wake_w = os.pipe()
    os.set_blocking(wake_w, False)
    signal.set_wakeup_fd(wake_w)
    for signum in (signal.SIGTERM, signal.SIGINT):
        signal.signal(signum, lambda *_: None)
    return wake_r, wake_w


def serve(master: int, bus: SimBus, wakeup: int) -> None:
    """Move bytes between the terminal's ``master`` side and ``bus`` until ``wakeup`` is readable."""
    later: list[tuple[float, int, bytes]] = []  # (time due [s, monotonic], order, bytes): stalled answers
    order = 0
    while True:
        timeout = max(0.0, later[0][0] - time.monotonic()) if later else None
        readable, _, _ = select.select([master, wakeup], [], [], timeout)
        if wakeup in readable:
            return
        if master in readable:
            try:
                data = os.read(master, 4096)
            except OSError:  # no one has the terminal open: wait for the host to come back
                time.sleep(0.05)
                data = b""
            now = time.monotonic()
            for delay_s, answer in bus.send(data):
                heapq.heappush(later, (now + delay_s, order, answer))
                order += 1
        while later and later[0][0] <= time.monotonic():
            _send(master, heapq.heappop(later)[2])


def _send(master: int, data: bytes) -> None:
    try:
        os.write(master, data)
    except OSError:  # the terminal's buffer is full or closed: the bytes are lost, as on an unread line
        pass


def main(argv: list[str] | None = None) -> int:
    """Run the simulator; raises :class:`PlannerError` on bad arguments."""
    args = build_parser().parse_args(argv)
    key = cli.site_key(args.key_file, env=False, warn=False)  # a test double: vlp-flash warns about the key
    sim_only = {"--faults": args.faults, "--flash-dir": args.flash_dir, "--slot-size": args.slot_size,
                "--max-block": args.max_block, "--block-write-us": args.block_write_us}
    avr_only = {"--eeprom-dir": args.eeprom_dir, "--trace": args.trace, "--build-dir": args.build_dir}
    wrong = [flag for flag, value in (sim_only if args.firmware == "avr" else avr_only).items()
             if value not in (None, "")]
    if wrong:
        raise UsageError(f"{', '.join(wrong)} cannot be used with --firmware {args.firmware} "
                         f"(see {PROG} --help)")
    if args.firmware == "avr":
        return _main_avr(args, key)
    from planner.flash.sim.bus import Faults, make_bus

    faults = Faults.parse(args.faults)
    made_dir = args.flash_dir is None
    flash_dir = Path(tempfile.mkdtemp(prefix="vlp-driver-sim-")) if made_dir else args.flash_dir
    bus = None
    master = slave = wake_r = wake_w = -1
    try:
        bus = make_bus(args.drivers, key, first_address=args.first_address,
                       serial_prefix="SIM-" if args.serial_prefix is None else args.serial_prefix,
                       flash_dir=flash_dir, slot_size=4096 if args.slot_size is None else args.slot_size,
                       max_block=256 if args.max_block is None else args.max_block,
                       block_write_us=2000 if args.block_write_us is None else args.block_write_us, faults=faults)
        master, slave = os.openpty()
        tty.setraw(slave)  # no echo, no line editing: bytes pass unchanged
        os.set_blocking(master, False)
        wake_r, wake_w = _wake_on_signals()
        last = args.first_address + args.drivers - 1
        if args.json:
            print(json.dumps({"port": os.ttyname(slave), "drivers": args.drivers,
                              "addresses": [args.first_address, last], "flash_dir": str(flash_dir)}), flush=True)
        else:
            print(os.ttyname(slave), flush=True)
        print(f"{PROG}: {args.drivers} driver(s) at addresses {args.first_address}..{last}, flash in {flash_dir}"
              f"{' (temporary)' if made_dir else ''}", file=sys.stderr, flush=True)
        serve(master, bus, wake_r)  # slave stays open here, so the host may close and reopen it
    finally:
        signal.set_wakeup_fd(-1)
        for fd in (master, slave, wake_r, wake_w):
            if fd >= 0:
                os.close(fd)
        if bus is not None:
            bus.close()
        if made_dir:
            shutil.rmtree(flash_dir, ignore_errors=True)
    return 0


def _main_avr(args: argparse.Namespace, key: bytes) -> int:
    """``--firmware avr``: emulated MCUs on one shared line, served until SIGTERM or SIGINT."""
    from planner.flash.avr.runner import AvrBus

    made_dir = args.eeprom_dir is None
    eeprom_dir = Path(tempfile.mkdtemp(prefix="vlp-driver-avr-")) if made_dir else args.eeprom_dir
    bus = None
    wake_r = wake_w = -1
    try:
        bus = AvrBus(args.drivers, key, eeprom_dir, first_address=args.first_address,
                     serial_prefix="AVR-" if args.serial_prefix is None else args.serial_prefix,
                     trace_dir=args.trace, build_dir=args.build_dir)
        wake_r, wake_w = _wake_on_signals()
        last = args.first_address + args.drivers - 1
        if args.json:
            print(json.dumps({"port": bus.port, "drivers": args.drivers, "addresses": [args.first_address, last],
                              "eeprom_dir": str(eeprom_dir), "trace_dir": str(args.trace) if args.trace else None,
                              "firmware": str(bus.firmware)}), flush=True)
        else:
            print(bus.port, flush=True)
        print(f"{PROG}: {args.drivers} emulated ATmega328P driver(s) at addresses {args.first_address}..{last} "
              f"on one line, EEPROM in {eeprom_dir}{' (temporary)' if made_dir else ''}"
              f"{f', LED traces in {args.trace}' if args.trace else ''}; line rate 250000 bit/s",
              file=sys.stderr, flush=True)
        bus.serve(wake_r)
    finally:
        signal.set_wakeup_fd(-1)
        for fd in (wake_r, wake_w):
            if fd >= 0:
                os.close(fd)
        if bus is not None:
            bus.close()
        if made_dir:
            shutil.rmtree(eeprom_dir, ignore_errors=True)
    return 0


def console_main(argv: list[str] | None = None) -> int:
    """The ``vlp-driver-sim`` script: one line per error and a non-zero exit code (:func:`cli.console_main`; the
    serving loop sets its own SIGTERM and SIGINT handling, which stops it with exit 0)."""
    return cli.console_main(argv, main, PROG)


if __name__ == "__main__":
    sys.exit(console_main())
