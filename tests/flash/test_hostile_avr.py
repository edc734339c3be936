"""Hostile drivers beside the reference firmware (issue 36, the AVR side of test_hostile_drivers.py).

One line shared by five emulated ATmega328P drivers (firmware_templates/driver/ on simavr,
AVR-00000N at address N) and hostile Python peers (planner.flash.avr.runner's ``peers``):
the model's faulty drivers (stalls, fields out of range, short replies, a version no host
signed, HELLOs that prove nothing), and impostors without the site's keys that claim the
real drivers' serials and versions or replay a real driver's recorded answer in its place
or relay a real driver's answers to the host's challenges. The installed vlp-flash runs one batch over all of them, then
``--verify-only``: every attack fails its driver alone in one line, the firmware drivers are
flashed and verified, and the journal says what the firmware proves when asked afterwards.
Every image the host sent on the shared line, replayed by a listener into a real driver it
was not signed for, is refused by that driver's firmware. One bus and three vlp-flash runs
(bind, flash, verify) for the whole module.
"""

import hashlib
import json
import os
import select
import struct
import subprocess
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace

import pytest
import serial
from test_driver_avr import BAUD, RETRIES, _send
from test_hostile_drivers import ATTACKS as MODEL_ATTACKS
from test_hostile_drivers import Hostile

from conftest import SITE_KEY, grid32_copy, vlp
from planner.flash.avr.runner import AvrBus, EmulatedDriver
from planner.flash.flasher import flash_driver
from planner.flash.keys import driver_key
from planner.flash.link import Link, LinkError
from planner.flash.wire import (
    BEGIN_REQUEST,
    FLAG_RESPONSE,
    WRITE_HEAD,
    Command,
    Deframer,
    Hello,
    Packet,
    Status,
    encode,
    hello_mac,
)

pytestmark = [pytest.mark.needs_avr, pytest.mark.slow]

KEY = SITE_KEY
SLACK_MS = 1000
"""vlp-flash's --extra-timeout-ms here: every address asked answers (a firmware driver or a peer), so a long wait
costs nothing unless the emulators or the peers' thread lag, as they do for seconds on two cores shared with
other busy processes (measured 2026-12-05 with three busy loops beside this module: peers' answers 1.3 s late)."""
OTHER_SITE = bytes(range(100, 132))
"""The site key an impostor holds: not this one (it derives no real driver's key)."""

HONEST = {"R01C01": 1, "R01C03": 3, "R02C05": 5}
"""Luminaires whose own firmware drivers (AVR-00000<address>) are on the line: first images in the batch."""

BOUND = {"R01C02": 2, "R01C08": 4}
"""Luminaires whose firmware drivers took their first image before the batch (journal: bound). AVR-000002 is then
taken from the line (powered off) and an impostor answers in its place; AVR-000004 answers at R01C04's address
and, through a relay, in R01C08's place."""

IDENTITY = {  # attack: (luminaire, address, what its line says)
    "replay": ("R01C02", 2, "driver claiming serial AVR-000002 at address 2 failed the challenge: its HELLO's MAC "
                            "is not that driver's"),
    "wrong-map": ("R01C04", 4, "driver AVR-000004 is bound to luminaire R01C08 (journal), not R01C04"),
    "version-burn": ("R01C05", 12, "driver claiming serial AVR-000002 at address 12 failed the challenge"),
    "other-serial": ("R01C06", 13, "driver claiming serial AVR-000001 at address 13 failed the challenge"),
    "relay": ("R01C08", 14, "driver claiming serial AVR-000004 at address 14 failed the challenge: its HELLO's MAC "
                            "is not that driver's"),
}
"""Attacks on the firmware drivers' identities. replay: blank, it answers every challenge with AVR-000002's answer
recorded before (AVR-000002 is off). wrong-map is no peer: the real AVR-000004 answers at the address the bus map
gives R01C04 (a swapped map, or the wrong driver plugged). version-burn and other-serial hold another site's key and
claim AVR-000002 at version 999,999, and AVR-000001 (R01C01's driver, flashed just before). relay: in R01C08's
place, it passes the host's challenge to R01C08's own driver AVR-000004 (over that driver's pipe, not the line) and
returns its answer as its own."""

FAULTY = ("zero-staged", "offset-zero", "max-block-0", "slow-blocks", "huge-timing", "short-hello", "short-begin",
          "control-serial", "version-999999", "protocol-1", "no-mac")
"""The model's faulty drivers (test_hostile_drivers.ATTACKS: stalls, fields out of range, short replies, a version
no host signed, HELLOs that prove nothing), each with a key of its own (SIM-0000NN at address NN): the same lines."""

ATTACKS = IDENTITY | {attack: (name, 21 + k, MODEL_ATTACKS[attack]) for k, (attack, name) in enumerate(zip(
    FAULTY, ["R01C07", "R02C01", "R02C02", "R02C03", "R02C04", "R02C06", "R02C07", "R02C08", "R03C01", "R03C02",
             "R03C03"], strict=True))}
BATCH = dict([("R01C01", 1), *[ATTACKS[a][:2] for a in IDENTITY], ("R01C03", 3),
              *[ATTACKS[a][:2] for a in FAULTY], ("R02C05", 5)])
"""The batch's bus map, in its order: honest drivers first, among the attacks and last."""
IMPOSTORS = ("replay", "version-burn", "other-serial", "relay")
SIGNED = ("zero-staged", "offset-zero", "short-begin")
"""The faulty peers that prove their key and fail only after BEGIN: an image is signed for them (their own serial)."""


def _peer(attack: str, address: int) -> Hostile:
    """The Python peer of ``attack`` (test_hostile_drivers.Hostile); impostors hold another site's key."""
    if attack == "version-burn":
        peer = Hostile(address, "version-999999", serial="AVR-000002")
    elif attack == "other-serial":
        peer = Hostile(address, "honest", serial="AVR-000001")
    else:
        peer = Hostile(address, attack, protocol=1 if attack == "protocol-1" else 2)
    if attack in IMPOSTORS:
        peer._key = driver_key(OTHER_SITE, peer.serial)
    return peer


@dataclass
class Relay:
    """A peer at ``address`` that passes the host's HELLO challenges to the firmware driver ``victim`` and answers
    with the victim's answers. It runs in the bus's thread, which reads no driver while it waits."""

    address: int
    victim: EmulatedDriver | None = None
    relayed: list[tuple[bytes, bytes]] = field(default_factory=list)  # (nonce, the victim's answer)
    deframer: Deframer = field(default_factory=Deframer)

    def receive(self, data: bytes) -> bytes:
        out = b""
        for p in self.deframer.packets(data)[0]:
            if not p.is_response and p.address == self.address and p.command == Command.HELLO:
                answer = self._ask(p.payload, p.seq)
                self.relayed.append((p.payload, answer))
                if answer:
                    out += encode(Packet(self.address, FLAG_RESPONSE, p.seq, Command.HELLO, answer))
        return out

    def _ask(self, nonce: bytes, seq: int) -> bytes:
        """The victim's answer to ``nonce``; b"" if none within 10 s (the test then fails on ``relayed``)."""
        assert self.victim is not None and self.victim.process is not None
        stdin, stdout = self.victim.process.stdin, self.victim.process.stdout
        assert stdin is not None and stdout is not None
        stdin.write(encode(Packet(self.victim.address, 0, seq, Command.HELLO, nonce)))
        deframer, deadline = Deframer(), time.monotonic() + 10
        while time.monotonic() < deadline:
            if select.select([stdout], [], [], 0.05)[0]:
                for p in deframer.packets(os.read(stdout.fileno(), 4096))[0]:
                    if p.is_response and p.seq == seq:
                        return p.payload
        return b""


@dataclass
class Plug:
    """A peer's place on the line: it hears and answers only while ``on``."""

    receive: Callable[[bytes], bytes]
    on: bool = True

    def __call__(self, data: bytes) -> bytes:
        return self.receive(data) if self.on else b""


@dataclass
class Sniffer:
    """A listener on the line: every request the host sends, whoever it is for; it never answers."""

    deframer: Deframer = field(default_factory=Deframer)
    begun: list[tuple[int, int, int, bytes]] = field(default_factory=list)  # (address, length, version, sha)
    writes: list[tuple[int, int, bytes]] = field(default_factory=list)  # (address, offset, data)

    def __call__(self, data: bytes) -> bytes:
        for p in self.deframer.packets(data)[0]:
            if p.command == Command.BEGIN and len(p.payload) == BEGIN_REQUEST.size:
                self.begun.append((p.address, *BEGIN_REQUEST.unpack(p.payload)[:3]))
            elif p.command == Command.WRITE and len(p.payload) > WRITE_HEAD.size:
                self.writes.append((p.address, WRITE_HEAD.unpack_from(p.payload)[0], p.payload[WRITE_HEAD.size:]))
        return b""

    def images(self) -> list[bytes]:
        """Every image the line carried whole (its bytes hash to the SHA-256 its BEGIN announced)."""
        got = []
        for address, length, _, sha in self.begun:
            image = bytearray(length)
            for to, offset, data in self.writes:
                if to == address and offset + len(data) <= length:
                    image[offset:offset + len(data)] = data
            if hashlib.sha256(image).digest() == sha and bytes(image) not in got:
                got.append(bytes(image))
        return got


def _vlp_flash(base: Path, port: str, where: dict[str, int], *extra: str) -> subprocess.CompletedProcess:
    """The installed vlp-flash over the luminaires of ``where`` (their bus map), journal ``base/as-built.json``."""
    bus_map = base / "map.csv"
    bus_map.write_text("".join(f"{name},{address}\n" for name, address in where.items()))
    return vlp("vlp-flash", str(base / "a" / "plan.yaml"), *where, "--bus", "--bus-map",
               str(bus_map), "--port", port, "--key-file", str(base / "key"), "--baud", str(BAUD),
               "--journal", str(base / "as-built.json"), "--extra-timeout-ms", str(SLACK_MS),
               *extra)


def _image(base: Path, name: str) -> bytes:
    return (base / "a" / "firmware" / name / "vlp_config.bin").read_bytes()


def _run(result: subprocess.CompletedProcess, journal: Path) -> SimpleNamespace:
    lines = result.stdout.splitlines()
    by_name = {line.split(": ")[0].split("] ")[-1]: line for line in lines}
    return SimpleNamespace(code=result.returncode, lines=lines, by_name=by_name, err=result.stderr.splitlines(),
                           entries=json.loads(journal.read_text())["luminaires"])


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> SimpleNamespace:
    """The bus, the runs, and what the firmware proves when asked afterwards (read only)."""
    base = tmp_path_factory.mktemp("hostile-avr")
    (base / "key").write_text(KEY.hex())
    grid32_copy(tmp_path_factory, base / "a", sealed=True)  # sealed: vlp-flash flashes no other plan
    journal = base / "as-built.json"
    peers = {a: _peer(a, address) for a, (_, address, _) in ATTACKS.items() if a not in ("wrong-map", "relay")}
    plugs = {a: Plug(p.receive, on=a != "replay") for a, p in peers.items()}
    relay, sniffer = Relay(ATTACKS["relay"][1]), Sniffer()
    with AvrBus(5, KEY, base / "eeprom", peers=[sniffer, relay.receive, *plugs.values()]).start() as bus:
        relay.victim = bus.driver(4)
        for _ in range(3):  # the starting point: R01C02 and R01C08 bound (resumed if the machine is slow)
            setup = _vlp_flash(base, bus.port, BOUND, "--resume")
            if setup.returncode == 0:
                break
        assert setup.returncode == 0, setup.stdout + setup.stderr
        with serial.Serial(bus.port, BAUD, timeout=0.05) as port:  # what the impostor recorded then
            link = Link(port, BAUD, retries=RETRIES, extra_timeout_s=SLACK_MS / 1000)
            recorded = link.request(2, Command.HELLO, bytes(16), driver_s=0.1)
        peers["replay"].recorded = recorded.payload
        bus.power_off(2)  # AVR-000002 taken from the line; the impostor in its place
        plugs["replay"].on = True
        sniffer.begun.clear()
        sniffer.writes.clear()
        flashed = _run(_vlp_flash(base, bus.port, BATCH), journal)
        checked = _run(_vlp_flash(base, bus.port, BATCH, "--verify-only"), journal)
        begun, images = list(sniffer.begun), sniffer.images()  # what the host sent in the two runs
        plugs["replay"].on = False
        bus.power_cut(2)  # AVR-000002 back, booted from its EEPROM
        with serial.Serial(bus.port, BAUD, timeout=0.05) as port:
            link = Link(port, BAUD, retries=RETRIES, extra_timeout_s=SLACK_MS / 1000)
            proved = {name: flash_driver(link, address, _image(base, name), KEY, verify_only=True)
                      for name, address in (HONEST | BOUND).items()}
            replayed = []
            for image in images:  # into AVR-000002, for which the host signed none of them
                try:
                    replayed.append(("accepted", _send(link, 2, image).payload))
                except LinkError as exc:
                    replayed.append((Status(exc.status).name if exc.status is not None else str(exc), exc.detail))
            victim_after = flash_driver(link, 2, _image(base, "R01C02"), KEY, verify_only=True)
    return SimpleNamespace(base=base, recorded=recorded, relayed=relay.relayed, flashed=flashed, checked=checked, proved=proved,
                           begun=begun, images=images, replayed=replayed, victim_after=victim_after)


@pytest.mark.parametrize("attack", sorted(ATTACKS))
def test_each_attack_fails_its_driver_alone_in_one_line(site, attack):
    name, address, why = ATTACKS[attack]
    status = "unauthenticated" if "own word" in why else "failed"  # a v1 HELLO, or one without a MAC
    line = site.flashed.by_name[name]
    assert line.startswith(f"[{list(BATCH).index(name) + 1}/{len(BATCH)}] {name}: driver "), line
    assert f"{status}, NOT verified" in line and why in line, line
    entry = site.flashed.entries[name]
    assert (entry["status"], entry["verified"]) == (status, False) and why in entry["message"]
    bound = f"AVR-{BOUND[name]:06d}" if name in BOUND else ""
    assert entry["bound_serial"] == bound  # never bound to what answered
    signed_for = [version for to, _, version, _ in site.begun if to == address]
    if attack in SIGNED:  # a faulty driver with its own key: signed for it, at the plan's version
        assert signed_for and set(signed_for) == {1}
    else:  # nothing signed for it, nor sent to the real driver at the wrong luminaire
        assert signed_for == []
    line = site.checked.by_name[name]
    assert "NOT verified" in line and site.checked.entries[name]["verified"] is False, line
    if attack in IMPOSTORS:  # --verify-only does not take an impostor's word either
        assert "failed the challenge" in line, line


def test_the_firmware_drivers_are_flashed_and_the_batch_finishes(site):
    flashed, checked = site.flashed, site.checked
    failed = [name for name in BATCH if name not in HONEST]
    for run in (flashed, checked):
        assert run.code == 3 and len(run.lines) == len(BATCH), run.lines + run.err
        assert run.err == [f"vlp-flash: {len(failed)} driver(s) failed and keep their previous configuration: "
                           f"{', '.join(failed[:10])} ...; journal {site.base / 'as-built.json'}"]
    for name, address in HONEST.items():
        assert f"{name}: driver AVR-{address:06d}: flashed, verified (version 1, " in flashed.by_name[name]
        assert f"{name}: driver AVR-{address:06d}: verified, verified (version 1, " in checked.by_name[name]
        begun = {(to, version) for to, _, version, _ in site.begun if to == address}
        assert begun == {(address, 1)}  # its own image, at the plan's version


def test_the_journal_says_what_the_firmware_proves(site):
    """Asked by fresh challenges after both runs, each firmware driver holds its own luminaire's image. The journal
    says so of the honest ones; of R01C02 and R01C08, whose drivers hold theirs too but where an impostor and a
    relay answered in the batch, it says failed, keeping each bound to its driver and its last proof."""
    entries = site.checked.entries
    for name, result in site.proved.items():
        address = (HONEST | BOUND)[name]
        assert result.verified and (result.status, result.serial) == ("verified", f"AVR-{address:06d}"), result
        assert entries[name]["bound_serial"] == result.serial
        if name in HONEST:
            assert entries[name]["verified"] and entries[name]["active_sha256"] == result.active_sha256
        else:
            assert (entries[name]["verified"], entries[name]["driver_serial"]) == (False, "")
            assert entries[name]["last_verified"] == {"driver_serial": result.serial, "image_version": 1}
    assert sorted(n for n, e in entries.items() if e["verified"]) == sorted(HONEST)


def test_images_seen_on_the_line_are_refused_by_the_firmware_they_were_not_signed_for(site):
    """A listener on the shared line holds every image the host sent in the batch (the honest drivers', and the
    faulty peers' with their own keys); replayed into AVR-000002, each is refused (AUTH), and AVR-000002 still
    plays R01C02's image at version 1. No image on the line was signed above the plan's version 1."""
    images = site.images
    assert len(images) == 5 and {struct.unpack_from("<I", image, 120)[0] for image in images} == {1}
    assert site.replayed == [("AUTH", 0)] * len(images), site.replayed
    after = site.victim_after
    assert after.verified and (after.serial, after.active_version) == ("AVR-000002", 1)
    assert after.active_sha256 == site.proved["R01C02"].active_sha256


def test_the_replayed_and_relayed_answers_were_the_real_firmware_s(site):
    """The impostor's recording is a genuine answer of AVR-000002 at its own address (its MAC checks for the nonce
    it answered), so the host's fresh nonce alone refused it; the relay's answers are AVR-000004's to the host's
    own nonces, so the address in the MAC alone refused them."""
    hello = Hello.unpack(site.recorded.payload)
    assert (hello.serial, hello.active_version, site.recorded.address) == ("AVR-000002", 1, 2)
    assert hello.mac == hello_mac(driver_key(KEY, "AVR-000002"), bytes(16), 2, hello.body())
    assert len(site.relayed) >= 2  # the flash and the --verify-only run each asked
    for nonce, answer in site.relayed:
        hello = Hello.unpack(answer)
        assert (hello.serial, hello.active_version) == ("AVR-000004", 1)
        assert hello.mac == hello_mac(driver_key(KEY, "AVR-000004"), nonce, 4, hello.body())

