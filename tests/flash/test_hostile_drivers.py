"""Hostile drivers (issue 36): peers that speak the protocol to stall, crash or fool vlp-flash, on a real
pseudo-terminal (the installed vlp-flash against a line served by planner.cli.driver_sim.serve) and in
process. Each attack fails that driver with one clear line; the batch goes on; the journal is true."""

import json
import os
import subprocess
import sys
import threading
from dataclasses import replace
from pathlib import Path

import pytest

from conftest import SITE_KEY, grid32_copy, vlp
from planner.cli.driver_sim import serve
from planner.cli.flash import console_main
from planner.firmware.image import config_image
from planner.flash.flasher import VERSION_STEP, Versions, flash_driver
from planner.flash.link import MAX_ATTEMPT_S, Link
from planner.flash.sim import protocol_sim
from planner.flash.sim.bus import Faults, SimBus
from planner.flash.sim.driver import SimulatedDriver, _Refuse
from planner.flash.wire import BEGIN_REQUEST, WRITE_REPLY, Command, Deframer, Hello, Packet, Status, decode, encode

BIN = Path(sys.executable).parent  # the installed console scripts
KEY = SITE_KEY
NAMES = ["R01C01", "R01C02", "R01C03"]
PLAN_IMAGE = config_image("L1", 5, "0111000110011010", 12600.0, "0123456789abcdef")


class Hostile(SimulatedDriver):
    """A driver that follows the protocol except for one ``behaviour`` (docs/protocol.md has the rules)."""

    def __init__(self, address: int, behaviour: str, serial: str | None = None, **kw):
        super().__init__(address, serial or f"SIM-{address:06d}", KEY, **kw)
        self.behaviour = behaviour
        self.begun_versions: list[int] = []  # the versions of the images BEGIN announced to it

    def hello(self) -> Hello:
        h, b = super().hello(), self.behaviour
        wrong = {"max-block-0": {"max_block": 0}, "slow-blocks": {"block_write_us": 2**32 - 1},
                 "huge-timing": {"max_block": 0xFFFF, "slot_size": 2**32 - 1, "block_write_us": 2**32 - 1},
                 "control-serial": {"serial": "SIM\n000002"},
                 "version-999999": {"active_slot": 1, "active_version": 999_999}}.get(b, {})
        return replace(h, **wrong)

    def _execute(self, command: int, payload: bytes) -> bytes:
        b = self.behaviour
        if command == Command.HELLO and b == "short-hello":
            return b"\x01"
        if command == Command.WRITE and b == "zero-staged":
            self._begun_staging()
            return WRITE_REPLY.pack(0)
        if command == Command.WRITE and b == "offset-zero":
            raise _Refuse(Status.OFFSET, 0, "0 bytes staged")
        if command == Command.BEGIN and b == "short-begin":
            return b"\x00\x00"
        if command == Command.BEGIN:
            self.begun_versions.append(BEGIN_REQUEST.unpack(payload)[1])
        if command == Command.HELLO and b == "no-mac":  # a version 2 answer to the challenge, but no MAC
            return self.hello().body()
        if command == Command.HELLO and b == "replay":  # a real driver's answer, recorded earlier
            return self.recorded
        if command == Command.HELLO and b == "relay":  # the host's challenge, passed to a real driver elsewhere
            frames = Deframer().feed(self.victim.receive(encode(Packet(self.victim.address, 0, 1, command, payload))))
            return decode(frames[0]).payload
        return super()._execute(command, payload)


ATTACKS = {  # behaviour: what the failed driver's line says
    "zero-staged": "staged nothing new in 4 WRITEs at offset 0 (it answers 0 bytes staged)",
    "offset-zero": "staged nothing new in 4 WRITEs at offset 0 (it answers 0 bytes staged)",
    "max-block-0": "HELLO max_block 0 is outside the protocol's 16..1,016",
    "slow-blocks": "HELLO block_write_us 4,294,967,295 is outside the protocol's 0..2,000,000",
    "huge-timing": "HELLO max_block 65,535 is outside the protocol's 16..1,016",
    "short-hello": "HELLO reply of 1 bytes, the protocol's is",
    "short-begin": "BEGIN reply of 2 bytes, the protocol's is 8",
    "control-serial": "is not 1 to 16 printable ASCII characters",
    "version-999999": "claims to run version 999,999, more than 100 above the 1 this host knows for it",
    "replay": "driver claiming serial SIM-000002 at address 2 failed the challenge: its HELLO's MAC is not that driver's",
    "relay": "driver claiming serial SIM-000009 at address 2 failed the challenge: its HELLO's MAC is not that driver's",
    "protocol-1": "speaks protocol 1, whose HELLO is unauthenticated (serial, version and image hash are its own word)",
    "no-mac": "answered the challenge without a MAC (serial, version and image hash are its own word)",
}


def _holding(plans: Path, name: str, address: int, serial_: str) -> SimulatedDriver:
    """A real driver holding the plan's image for ``name``, flashed by the host."""
    import serial

    protocol_sim.register()
    port = serial.serial_for_url(f"sim://?key={KEY.hex()}", timeout=0.1)
    real = SimulatedDriver(address, serial_, KEY)
    port.bus = SimBus([real])
    image = (plans / "a" / "firmware" / name / "vlp_config.bin").read_bytes()
    assert flash_driver(Link(port), address, image, KEY).verified
    return real


def _bus(behaviour: str, plans: Path) -> SimBus:
    """Three drivers at addresses 1..3; the second is hostile (for "replay" and "relay": blank, and without
    the site's keys; it answers HELLO with a recorded or relayed answer of a real driver holding the image)."""
    peer = Hostile(2, behaviour, protocol=1 if behaviour == "protocol-1" else 2)
    if behaviour == "replay":
        real = _holding(plans, "R01C02", 2, "SIM-000002")
        peer.recorded = decode(Deframer().feed(real.receive(encode(Packet(2, 0, 1, Command.HELLO, bytes(16)))))[0]).payload
    if behaviour == "relay":  # SIM-000009 holds R01C02's image, and answers the host's challenge through the peer
        peer.victim = _holding(plans, "R01C02", 9, "SIM-000009")
    return SimBus([SimulatedDriver(1, "SIM-000001", KEY), peer, SimulatedDriver(3, "SIM-000003", KEY)])


@pytest.fixture(scope="module")
def plans(tmp_path_factory) -> Path:
    base = tmp_path_factory.mktemp("hostile-plans")
    (base / "key").write_text(KEY.hex())
    grid32_copy(tmp_path_factory, base / "a", sealed=True)  # sealed: vlp-flash flashes no other plan
    return base


class PtyLine:
    """``bus`` served on a real pseudo-terminal by vlp-driver-sim's own loop, in a thread."""

    def __init__(self, bus: SimBus):
        import tty

        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        os.set_blocking(self.master, False)
        self.wake_r, self.wake_w = os.pipe()
        self.port = os.ttyname(self.slave)
        self.thread = threading.Thread(target=serve, args=(self.master, bus, self.wake_r), daemon=True)
        self.thread.start()

    def close(self) -> None:
        os.write(self.wake_w, b"x")
        self.thread.join(timeout=5)
        for fd in (self.master, self.slave, self.wake_r, self.wake_w):
            os.close(fd)


def _check_batch(out: str, err: str, code: int, journal: Path, why: str) -> None:
    lines = out.splitlines()
    assert code == 3 and len(lines) == 3, out + err
    assert "R01C01: driver SIM-000001: flashed, verified" in lines[0]
    assert "R01C03: driver SIM-000003: flashed, verified" in lines[2]  # the batch went on
    status = "unauthenticated" if "own word" in why else "failed"
    assert lines[1].startswith("[2/3] R01C02: driver ") and f"{status}, NOT verified" in lines[1], lines[1]
    assert why in lines[1], lines[1]
    assert err.splitlines() == [f"vlp-flash: 1 driver(s) failed and keep their previous configuration: R01C02; "
                                f"journal {journal}"]
    entries = json.loads(journal.read_text())["luminaires"]
    assert [entries[n]["verified"] for n in NAMES] == [True, False, True]  # the one in progress is journaled
    assert entries["R01C02"]["status"] == status and why in entries["R01C02"]["message"]


@pytest.mark.parametrize("behaviour", sorted(ATTACKS))
def test_a_hostile_driver_on_a_pty_fails_alone_in_one_line(plans, tmp_path, behaviour):
    bus = _bus(behaviour, plans)
    line = PtyLine(bus)
    journal = tmp_path / "j.json"
    try:
        got = vlp("vlp-flash", str(plans / "a" / "plan.yaml"), *NAMES, "--bus", "--port",
                  line.port, "--key-file", str(plans / "key"), "--journal", str(journal))
    finally:
        line.close()
    _check_batch(got.stdout, got.stderr, got.returncode, journal, ATTACKS[behaviour])
    assert bus.drivers[1].begun_versions == [] or behaviour in ("zero-staged", "offset-zero", "short-begin")


@pytest.mark.parametrize("behaviour", ["zero-staged", "huge-timing", "short-hello", "replay", "relay", "protocol-1"])
def test_a_hostile_driver_in_process_fails_alone_in_one_line(plans, tmp_path, behaviour, monkeypatch, capsys):
    bus = _bus(behaviour, plans)
    monkeypatch.setattr(protocol_sim, "bus_from_url", lambda url: bus)
    journal = tmp_path / "j.json"
    code = console_main([str(plans / "a" / "plan.yaml"), *NAMES, "--bus", "--port", "sim://", "--key-file",
                         str(plans / "key"), "--journal", str(journal)])
    out, err = capsys.readouterr()
    _check_batch(out, err, code, journal, ATTACKS[behaviour])
    if behaviour in ("replay", "relay", "protocol-1"):  # and --verify-only does not take its word either
        code = console_main([str(plans / "a" / "plan.yaml"), *NAMES, "--bus", "--port", "sim://", "--key-file",
                             str(plans / "key"), "--journal", str(journal), "--verify-only"])
        out = capsys.readouterr().out
        assert code == 3 and "R01C02" in out and out.count(", verified (") == 2, out
        assert json.loads(journal.read_text())["luminaires"]["R01C02"]["verified"] is False
    assert bus.drivers[1].begun_versions == [] or behaviour == "zero-staged"  # never signed for


def test_every_attempt_has_a_ceiling_and_each_driver_a_deadline():
    protocol_sim.register()
    import serial

    port = serial.serial_for_url(f"sim://?key={KEY.hex()}&faults=stall=1,stall_s=0.05", timeout=0.1)
    link = Link(port)
    assert link.timeout_s(80, 80, driver_s=(2**32 - 1) * 1e-6 * 65537) == MAX_ATTEMPT_S  # 12.8 days asked
    result = flash_driver(link, 1, PLAN_IMAGE, KEY, deadline_s=0.12)  # answers 50 ms late: COMMIT never starts in time
    assert result.status == "failed" and not result.verified
    assert "driver SIM-000001 gave no result within its 0.12 s deadline (--driver-deadline-s)" in result.message \
        or "driver at address 1 gave no result within its 0.12 s deadline" in result.message, result.message
    assert link.deadline is None  # the next driver starts afresh
    port.close()


@pytest.mark.parametrize("flag", ["--key-file", "--bus-map", "--journal"])
def test_dev_zero_as_an_input_is_refused_without_reading_it_whole(plans, tmp_path, flag, capsys):
    args = {"--key-file": str(plans / "key"), "--bus-map": None, "--journal": str(tmp_path / "j.json")}
    args[flag] = "/dev/zero"
    argv = [str(plans / "a" / "plan.yaml"), "R01C01", "--bus", "--port", f"sim://?key={KEY.hex()}"]
    argv += [item for name, value in args.items() if value for item in (name, value)]
    code = console_main(argv)
    err = capsys.readouterr().err
    assert code in (1, 2) and len(err.splitlines()) == 1 and "/dev/zero: more than" in err, err


@pytest.mark.parametrize("url", ["sim://?drivers=1&kye={k}", "sim:?key={k}", "sim://{k}?drivers=1",
                                 "sim://?drivers=x&key={k}", "sim://?drivers=1&k%65y={k}&bogus=1"])
def test_a_mistyped_sim_url_never_echoes_the_key(plans, tmp_path, url, capsys):
    code = console_main([str(plans / "a" / "plan.yaml"), "R01C01", "--bus", "--port", url.format(k=KEY.hex()),
                         "--key-file", str(plans / "key"), "--journal", str(tmp_path / "j.json")])
    out, err = capsys.readouterr()
    assert code == 2 and len(err.splitlines()) == 1 and "<hidden>" in err, err
    assert KEY.hex() not in out + err and "busy" not in err


def test_a_stalled_line_is_not_a_fault_of_the_protocol():
    """The hostile checks refuse nothing a faithful driver says: a faulted line still ends verified."""
    protocol_sim.register()
    import serial

    port = serial.serial_for_url(f"sim://?key={KEY.hex()}", timeout=0.1)
    port.bus = SimBus(port.bus.drivers, Faults(corrupt_per_byte=0.002, reset_per_request=0.05, seed=4))
    assert flash_driver(Link(port), 1, PLAN_IMAGE, KEY).verified
    port.close()


def test_no_claim_of_a_peer_burns_a_version():
    """A peer claiming a high version is never signed an image above what the host knows plus the step; the
    host's own knowledge (the plan's floor, the journal) and --image-version decide."""
    for claimed, versions, signed in ((999_999, Versions(), None), (VERSION_STEP + 1, Versions(), 102),
                                      (999_999, Versions(floor=999_990), 1_000_000),
                                      (5_000, Versions(journal=("SIM-000009", 4_950)), 5_001)):
        protocol_sim.register()
        import serial

        port = serial.serial_for_url(f"sim://?key={KEY.hex()}", timeout=0.1)
        peer = Hostile(1, "version-999999")
        peer.hello = lambda p=peer, v=claimed: replace(SimulatedDriver.hello(p), active_slot=1, active_version=v)
        port.bus = SimBus([peer])
        result = flash_driver(Link(port), 1, PLAN_IMAGE, KEY, versions)
        port.close()
        if signed is None:
            assert result.status == "failed" and "vlp-flash does not follow such a claim" in result.message
            assert peer.begun_versions == [] and result.image_version == 0  # nothing was signed for it
        else:  # within the step: followed (the real driver refuses it as a rollback: it runs version 0)
            assert peer.begun_versions and set(peer.begun_versions) == {signed}, (claimed, peer.begun_versions)


def _run(plans: Path, journal: Path, flash: Path, bus_map: str, *extra: str, prefix: str = "SIM-") -> int:
    (journal.parent / "map.csv").write_text(bus_map)
    names = [row.split(",")[0] for row in bus_map.split()]
    code = console_main([str(plans / "a" / "plan.yaml"), *names, "--bus", "--bus-map", str(journal.parent / "map.csv"),
                         "--key-file", str(plans / "key"), "--journal", str(journal), "--port",
                         f"sim://?drivers=3&key={KEY.hex()}&flash={flash}&prefix={prefix}", *extra])
    return code


def _entries(journal: Path) -> dict:
    return json.loads(journal.read_text())["luminaires"]


def test_a_swapped_bus_map_or_a_foreign_driver_is_refused_and_replace_driver_is_journaled(plans, tmp_path, capsys):
    journal, flash = tmp_path / "j.json", tmp_path / "flash"
    assert _run(plans, journal, flash, "R01C01,1\nR01C02,2\n") == 0  # first images: bound to SIM-1, SIM-2
    capsys.readouterr()
    assert [_entries(journal)[n]["bound_serial"] for n in ("R01C01", "R01C02")] == ["SIM-000001", "SIM-000002"]
    assert _run(plans, journal, flash, "R01C01,2\nR01C02,1\n") == 3  # a swapped map: each the other's driver
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 2 and all("failed, NOT verified" in line for line in out)
    assert "driver SIM-000002 answered, but R01C01 is bound to driver SIM-000001" in out[0]
    assert "driver SIM-000001 answered, but R01C02 is bound to driver SIM-000002" in out[1]
    entries = _entries(journal)  # nothing rebound, and nothing reflashed: each driver plays its own luminaire
    assert [entries[n]["bound_serial"] for n in ("R01C01", "R01C02")] == ["SIM-000001", "SIM-000002"]
    assert _run(plans, journal, flash, "R01C01,1\nR01C02,2\n", "--verify-only") == 0
    capsys.readouterr()
    # the same driver offered for a second luminaire (R01C03 at SIM-000001's address)
    assert _run(plans, journal, flash, "R01C03,1\n") == 3
    assert "driver SIM-000001 is bound to luminaire R01C01 (journal), not R01C03" in capsys.readouterr().out
    assert "R01C03" not in [n for n, e in _entries(journal).items() if e["verified"]]
    # a new driver (another serial) in R01C01's place: refused, then taken with --replace-driver
    assert _run(plans, journal, flash, "R01C01,1\n", prefix="NEW-") == 3
    assert "driver NEW-000001 answered, but R01C01 is bound to driver SIM-000001" in capsys.readouterr().out
    assert _run(plans, journal, flash, "R01C01,1\n", "--replace-driver", prefix="NEW-") == 0
    capsys.readouterr()
    e = _entries(journal)["R01C01"]
    assert (e["bound_serial"], e["replaced_drivers"], e["verified"]) == ("NEW-000001", ["SIM-000001"], True)
    # and a driver moved on purpose: SIM-000002 to R01C03; R01C02's entry says so and is no longer verified
    assert _run(plans, journal, flash, "R01C03,2\n", "--replace-driver") == 0
    capsys.readouterr()
    entries = _entries(journal)
    assert entries["R01C03"]["bound_serial"] == "SIM-000002" and entries["R01C03"]["verified"]
    assert (entries["R01C02"]["bound_serial"], entries["R01C02"]["verified"]) == ("", False)
    assert "its driver SIM-000002 was moved to R01C03 (--replace-driver)" in entries["R01C02"]["message"]


def test_a_forged_or_edited_journal_is_refused_and_resume_skips_nothing_on_its_word(plans, tmp_path, capsys):
    from planner.flash.journal import Journal

    journal, flash = tmp_path / "j.json", tmp_path / "flash"
    assert _run(plans, journal, flash, "R01C01,1\n") == 0
    capsys.readouterr()
    doc = json.loads(journal.read_text())
    real = doc["luminaires"]["R01C01"]
    assert len(real["seal"]) == 64 and Journal(journal, doc["plan_hash"], KEY).entries["R01C01"]["verified"]
    forged = [  # a hand-written entry with the right plan hash; a sealed entry moved to another luminaire; an edit
        {**doc, "luminaires": {**doc["luminaires"], "R01C02": {**real, "id": 2, "seal": ""}}},
        {**doc, "luminaires": {"R01C02": {**real}}},
        {**doc, "luminaires": {"R01C01": {**real, "bound_serial": "SIM-000002"}}},
    ]
    for k, edited in enumerate(forged):
        journal.write_text(json.dumps(edited))
        code = _run(plans, journal, flash, "R01C01,1\nR01C02,2\n", "--resume")
        out, err = capsys.readouterr()
        assert code == 1 and out == "" and len(err.splitlines()) == 1, (k, out, err)
        assert "journal seal does not check: the entry of" in err and "vlp-flash --verify-only rebuilds it" in err
        assert json.loads(journal.read_text()) == edited  # refused before anything: no driver flashed, no entry
    assert Journal(journal, doc["plan_hash"]).entries  # read without the key (vlp-report without --key-file), unchecked


def test_interactive_mode_shows_the_driver_that_answered_and_refuses_the_wrong_one(plans, tmp_path):
    """The installer plugs R01C01's driver again for R01C02: it is named before anything is written, and refused."""
    journal, flash = tmp_path / "j.json", tmp_path / "flash"
    url = f"sim://?key={KEY.hex()}&flash={flash}"
    outs = []
    for name in ("R01C01", "R01C02"):
        master, slave = os.openpty()
        os.write(master, b"\n")
        got = subprocess.run([str(BIN / "vlp-flash"), str(plans / "a" / "plan.yaml"), name, "--port", url,
                              "--key-file", str(plans / "key"), "--journal", str(journal)], stdin=slave,
                             capture_output=True, text=True, timeout=60)
        os.close(master)
        os.close(slave)
        outs.append((got.returncode, got.stdout))
    assert outs[0][0] == 0 and "driver SIM-000001 answered (proved its key; runs version 0); R01C01 has no " \
                                "driver bound yet" in outs[0][1]
    code, out = outs[1]
    assert code == 3 and "driver SIM-000001 answered (proved its key; runs version 1); R01C02 has no driver " \
                         "bound yet: refused" in out
    assert "R01C02: driver SIM-000001: failed, NOT verified" in out and "is bound to luminaire R01C01" in out
    entries = _entries(journal)
    assert entries["R01C01"]["verified"] and not entries["R01C02"]["verified"]
    assert entries["R01C02"]["bound_serial"] == ""
