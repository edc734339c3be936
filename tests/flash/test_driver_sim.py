"""The simulated driver (docs/protocol.md, driver side), its bus, the sim:// port and the pty process.

Packets are built by hand with planner.flash.wire; no host code is used.
"""

import hashlib
import hmac
import json
import os
import struct
import subprocess
import time
import zlib

import pytest
import serial

from planner.cli.driver_sim import console_main
from planner.firmware.image import CRC_OFFSET, IMAGE_BYTES, SIGNATURE_OFFSET, config_image, parse_config_image
from planner.flash.keys import driver_key
from planner.flash.sim import protocol_sim
from planner.flash.sim.bus import Faults, SimBus, SimConfigError, make_bus
from planner.flash.sim.driver import Flash, SimulatedDriver
from planner.flash.sim.memory import RECORD_BYTES, CommitRecord
from planner.flash.wire import (
    ANY_ADDRESS,
    BEGIN_REPLY,
    BEGIN_REQUEST,
    COMMIT_REPLY,
    FLAG_RESPONSE,
    VERIFY_REPLY,
    WRITE_HEAD,
    WRITE_REPLY,
    Command,
    Deframer,
    Hello,
    Packet,
    Status,
    decode,
    encode,
    hello_mac,
    parse_error,
)

KEY = bytes(range(1, 33))
SLOT = 192  # small slots keep the power-cut sweep short
BLOCK = 64


def signed(image: bytes, key: bytes) -> bytes:
    """``image`` with its signature field set to HMAC-SHA256 under ``key`` itself, CRC redone."""
    body = image[:SIGNATURE_OFFSET] + hmac.new(key, image[:SIGNATURE_OFFSET], hashlib.sha256).digest()
    return body + struct.pack("<I", zlib.crc32(body))


def make_image(version: int = 1, key: bytes | None = KEY, chips: str = "1100101011110000",
               serial: str = "SIM-000001") -> bytes:
    """An image signed for the driver ``serial`` of the site with key ``key`` (None: unsigned)."""
    image = config_image("lum-1", 7, chips, 1000.0, "0123456789abcdef", image_version=version)
    return image if key is None else signed(image, driver_key(key, serial))


def sha(data: bytes) -> bytes:
    return hashlib.sha256(data).digest()


class Client:
    """Hand-built requests to one driver (or a bus); returns the decoded answers."""

    def __init__(self, target, address: int = 1):
        self.target, self.address, self.seq = target, address, 0

    def raw(self, command: int, payload: bytes = b"", seq: int | None = None, address: int | None = None) -> bytes:
        if seq is None:
            self.seq = seq = (self.seq + 1) & 0xFF
        frame = encode(Packet(self.address if address is None else address, 0, seq, command, payload))
        if isinstance(self.target, SimBus):
            return b"".join(data for _, data in self.target.send(frame))
        return self.target.receive(frame)

    def ask(self, command: int, payload: bytes = b"", **kw) -> Packet | None:
        frames = Deframer().feed(self.raw(command, payload, **kw))
        assert len(frames) <= 1
        return decode(frames[0]) if frames else None

    def ok(self, command: int, payload: bytes = b"", **kw) -> bytes:
        reply = self.ask(command, payload, **kw)
        assert reply is not None and reply.flags == FLAG_RESPONSE, reply and parse_error(reply.payload)
        return reply.payload

    def refused(self, command: int, payload: bytes = b"", **kw) -> tuple[int, int]:
        reply = self.ask(command, payload, **kw)
        assert reply is not None and reply.is_error
        return parse_error(reply.payload)[:2]

    def hello(self) -> Hello:
        return Hello.unpack(self.ok(Command.HELLO))

    def begin(self, image: bytes, restart: int = 0, version: int | None = None) -> tuple[int, int]:
        version = parse_config_image(image)["image_version"] if version is None else version
        return BEGIN_REPLY.unpack(self.ok(Command.BEGIN, BEGIN_REQUEST.pack(len(image), version, sha(image), restart)))

    def write_from(self, image: bytes, offset: int) -> int:
        while offset < len(image):
            offset = WRITE_REPLY.unpack(self.ok(Command.WRITE, WRITE_HEAD.pack(offset) + image[offset:offset + BLOCK]))[0]
        return offset

    def flash(self, image: bytes) -> tuple[int, int]:
        offset, _ = self.begin(image)
        self.write_from(image, offset)
        assert VERIFY_REPLY.unpack(self.ok(Command.VERIFY)) == (len(image), sha(image))
        return COMMIT_REPLY.unpack(self.ok(Command.COMMIT, sha(image)))


def driver(flash: Flash | None = None, key: bytes = KEY) -> SimulatedDriver:
    return SimulatedDriver(1, "SIM-000001", key, flash or Flash(SLOT), max_block=BLOCK, block_write_us=500)


def test_hello_of_a_blank_driver():
    h = Client(driver()).hello()
    assert (h.protocol, h.capabilities, h.max_block, h.slot_size, h.block_write_us) == (2, 7, BLOCK, SLOT, 500)
    assert (h.serial, h.active_slot, h.active_version, h.active_sha256) == ("SIM-000001", 0, 0, bytes(32))


def test_full_flash_makes_the_image_active_then_the_next_goes_to_the_other_slot():
    c, v1, v2 = Client(driver()), make_image(1), make_image(2)
    assert c.flash(v1) == (1, 1)
    h = c.hello()
    assert (h.active_slot, h.active_version, h.active_sha256) == (1, 1, sha(v1))
    assert c.flash(v2) == (2, 2)
    assert c.hello().active_sha256 == sha(v2)
    assert c.refused(Command.COMMIT, sha(v2)) == (Status.NOT_BEGUN, 0)  # a commit ends the BEGIN
    assert c.flash(v2) == (2, 2)  # the active image again: succeeds without a new record


@pytest.mark.parametrize("case", ["unsigned", "altered", "other site", "another driver", "the site key itself"])
def test_commit_refuses_images_not_signed_with_this_drivers_key(case):
    image = {"unsigned": make_image(1, key=None), "other site": make_image(1, key=bytes(32)),
             "another driver": make_image(1, serial="SIM-000002"),
             "the site key itself": signed(make_image(1, key=None), KEY)}.get(case)
    if case == "altered":
        altered = bytearray(make_image(1))
        altered[40] ^= 0x01  # in the name, covered by the signature
        image = bytes(altered[:CRC_OFFSET]) + struct.pack("<I", zlib.crc32(altered[:CRC_OFFSET]))
    parse_config_image(image)  # a well-formed image: only the signature is wrong
    c = Client(driver())
    c.begin(image)
    c.write_from(image, 0)
    assert c.refused(Command.COMMIT, sha(image)) == (Status.AUTH, 0)
    assert c.hello().active_slot == 0


def test_a_driver_keeps_only_its_own_derived_key_not_the_site_key():
    d = driver()
    held = [v for v in vars(d).values() if isinstance(v, bytes)]
    assert driver_key(KEY, "SIM-000001") in held and KEY not in held
    assert KEY not in d.flash.snapshot() and driver_key(KEY, "SIM-000001") not in d.flash.snapshot()
    other = SimulatedDriver(2, "SIM-000002", KEY, Flash(SLOT), max_block=BLOCK)
    assert Client(other, address=2).flash(make_image(1, serial="SIM-000002")) == (1, 1)  # its own image: taken


def test_commit_checks_in_protocol_order():
    c, image = Client(driver()), make_image(1)
    assert c.refused(Command.COMMIT, sha(image)) == (Status.NOT_BEGUN, 0)
    c.begin(image)
    c.ok(Command.WRITE, WRITE_HEAD.pack(0) + image[:BLOCK])
    assert c.refused(Command.COMMIT, sha(image)) == (Status.INCOMPLETE, BLOCK)
    c.write_from(image, BLOCK)
    assert c.refused(Command.COMMIT, bytes(32)) == (Status.HASH, 0)
    junk = b"\x5a" * IMAGE_BYTES
    c.begin(junk, version=1)
    c.write_from(junk, 0)
    assert c.refused(Command.COMMIT, sha(junk)) == (Status.IMAGE, 0)
    assert c.refused(Command.BEGIN, BEGIN_REQUEST.pack(SLOT + 1, 1, sha(junk), 0)) == (Status.TOO_LARGE, SLOT)
    assert c.refused(99) == (Status.BAD_REQUEST, 0)
    assert c.refused(Command.VERIFY, b"x") == (Status.BAD_REQUEST, 0)


def test_older_or_same_version_other_image_is_refused_as_rollback():
    c = Client(driver())
    c.flash(make_image(3))
    for older in (make_image(2), make_image(3, chips="1111000011110000")):
        c.begin(older)
        c.write_from(older, 0)
        assert c.refused(Command.COMMIT, sha(older)) == (Status.ROLLBACK, 3)
    assert c.hello().active_sha256 == sha(make_image(3))


def test_a_challenge_is_answered_with_a_mac_under_the_drivers_own_key_over_nonce_address_and_fields():
    d = driver()
    c = Client(d)
    c.flash(make_image(1))
    for nonce in (bytes(16), bytes(range(16))):
        payload = c.ok(Command.HELLO, nonce)
        h = Hello.unpack(payload)
        assert len(payload) == 99 and h.protocol == 2 and h.active_version == 1 and h.active_sha256 == d.active_sha256
        assert h.mac == hello_mac(driver_key(KEY, "SIM-000001"), nonce, 1, payload[:67])
        assert h.mac != hello_mac(driver_key(KEY, "SIM-000001"), nonce, 2, payload[:67])  # bound to its address
    # the same seq and command with another nonce is a new request, not a retry: a fresh MAC
    first, second = c.raw(Command.HELLO, bytes(16), seq=9), c.raw(Command.HELLO, b"\x01" * 16, seq=9)
    assert first != second and d.stats.repeats == 0
    assert c.refused(Command.HELLO, b"\x01" * 15)[0] == Status.BAD_REQUEST


def test_a_protocol_1_driver_takes_no_challenge():
    d = SimulatedDriver(1, "SIM-000001", KEY, Flash(SLOT), max_block=BLOCK, protocol=1)
    assert Client(d).refused(Command.HELLO, bytes(16))[0] == Status.BAD_REQUEST
    h = Client(d).hello()
    assert (h.protocol, h.mac) == (1, b"")


def test_a_repeated_request_is_answered_from_the_seq_cache_not_executed():
    d = driver()
    c, image = Client(d), make_image(1)
    c.begin(image)
    first = c.raw(Command.WRITE, WRITE_HEAD.pack(0) + image[:BLOCK], seq=40)
    again = c.raw(Command.WRITE, WRITE_HEAD.pack(0) + image[:BLOCK], seq=40)
    assert first == again and d.stats.repeats == 1 and d.staged == BLOCK
    c.seq = 40
    c.write_from(image, BLOCK)
    c.ok(Command.VERIFY)
    written = d.flash.bytes_written
    commit = c.raw(Command.COMMIT, sha(image), seq=77)
    assert c.raw(Command.COMMIT, sha(image), seq=77) == commit  # not NOT_BEGUN: the stored answer
    assert d.flash.bytes_written == written + RECORD_BYTES  # one record write, not two
    assert decode(Deframer().feed(commit)[0]).payload == COMMIT_REPLY.pack(1, 1)


def test_write_at_a_wrong_offset_reports_the_staged_count():
    c, image = Client(driver()), make_image(1)
    assert c.refused(Command.WRITE, WRITE_HEAD.pack(0) + image[:BLOCK]) == (Status.NOT_BEGUN, 0)
    c.begin(image)
    c.ok(Command.WRITE, WRITE_HEAD.pack(0) + image[:BLOCK])
    assert c.refused(Command.WRITE, WRITE_HEAD.pack(BLOCK + 8) + image[BLOCK + 8:2 * BLOCK]) == (Status.OFFSET, BLOCK)
    assert c.refused(Command.WRITE, WRITE_HEAD.pack(8) + image[8:8 + BLOCK]) == (Status.OFFSET, BLOCK)  # overlap
    assert WRITE_REPLY.unpack(c.ok(Command.WRITE, WRITE_HEAD.pack(0) + image[:16])) == (BLOCK,)  # a retransmission


def _expected_resume(image: bytes, n: int, erase_bytes: int) -> int:
    """Bytes a rebooted driver reports staged after a cut ``n`` bytes into BEGIN + WRITEs (+ record)."""
    if n < erase_bytes:
        return 0  # the staging header is not whole: no resume
    return len(image[:n - erase_bytes].rstrip(b"\xff"))


@pytest.mark.parametrize("start", ["blank", "old image"])
def test_power_cut_at_every_byte_leaves_a_valid_configuration_and_resumes(start):
    old, new = make_image(1), make_image(2)
    base = driver()
    if start == "old image":
        Client(base).flash(old)
    snapshot = base.flash.snapshot()
    before = (base.active_slot, base.active_sha256)
    probe = driver(Flash(SLOT, data=snapshot))
    Client(probe).flash(new)
    total = probe.flash.bytes_written
    erase_bytes = 3 * RECORD_BYTES + SLOT  # header + record + area erased, header programmed
    assert total == erase_bytes + len(new) + RECORD_BYTES
    for n in range(total + 1):
        d = driver(Flash(SLOT, data=snapshot))
        d.power_cut_after(n)
        c = Client(d)
        try:
            c.flash(new)
            assert n == total
            d.reset()
        except AssertionError:
            assert n < total and d.stats.power_cuts == 1
        h = c.hello()  # the first byte boots the driver from flash
        if n < total:
            assert (h.active_slot, h.active_sha256) == before, n
        else:
            assert (h.active_slot, h.active_sha256) == (2 if start == "old image" else 1, sha(new))
            continue
        if h.active_slot:  # the active slot is really valid: record and image agree
            rec = CommitRecord.unpack(d.flash.read(d.flash.record_offset(h.active_slot), RECORD_BYTES))
            assert rec and sha(d.flash.read(d.flash.area(h.active_slot), rec.length)) == rec.sha256
        offset, crc = c.begin(new)
        assert offset == _expected_resume(new, n, erase_bytes), n
        assert crc == zlib.crc32(new[:offset])
        c.write_from(new, offset)
        assert COMMIT_REPLY.unpack(c.ok(Command.COMMIT, sha(new)))[1] == 2


def test_file_backed_flash_survives_a_new_driver_object_and_a_cut(tmp_path):
    path, image = tmp_path / "d1.flash", make_image(5)
    d = driver(Flash(SLOT, path))
    Client(d).flash(image)
    d.power_cut_after(3 * RECORD_BYTES + SLOT + 100)  # 100 image bytes into the next transfer
    c = Client(d)
    c.begin(make_image(6))
    with pytest.raises(AssertionError):
        c.write_from(make_image(6), 0)
    assert path.read_bytes() == d.flash.snapshot()
    d.flash.close()
    d2 = driver(Flash(SLOT, path))
    c2 = Client(d2)
    assert c2.hello().active_sha256 == sha(image)
    assert c2.begin(make_image(6))[0] == 100
    d2.flash.close()
    with pytest.raises(Exception, match="slot size"):
        Flash(SLOT * 2, path)


def test_bus_delivers_to_the_addressed_driver_only():
    bus = make_bus(3, KEY, slot_size=SLOT, max_block=BLOCK)
    h = Hello.unpack(Client(bus, address=2).ok(Command.HELLO))
    assert h.serial == "SIM-000002"
    assert [d.stats.frames for d in bus.drivers] == [0, 1, 0]
    answer = Client(bus, address=3).raw(Command.HELLO)
    assert bus.send(answer) == []  # another driver's response is not a request
    damaged = bytearray(encode(Packet(1, 0, 9, Command.HELLO)))
    damaged[3] ^= 0x10
    assert bus.send(bytes(damaged)) == [] and bus.drivers[0].stats.dropped == 1
    Client(bus, address=2).flash(make_image(1, serial="SIM-000002"))
    assert [d.active_slot for d in bus.drivers] == [0, 1, 0]
    answers = [decode(f) for f in Deframer().feed(Client(bus).raw(Command.HELLO, address=ANY_ADDRESS))]
    assert [a.address for a in answers] == [1, 2, 3]  # "any driver" is for point to point: all answer
    bus.close()


def test_faults_spec_and_seeded_line_faults_repeat_exactly():
    f = Faults.parse("corrupt=0.02,drop=0.01,reset=0.1,power=0.1,stall=0.1,stall_s=0.2,seed=3")
    assert (f.corrupt_per_byte, f.drop_per_byte, f.power_cut_per_request, f.stall_s, f.seed) == (0.02, 0.01, 0.1, 0.2, 3)
    for bad in ("corrupt=2", "nonsense=1", "seed=x", "corrupt"):
        with pytest.raises(SimConfigError):
            Faults.parse(bad)
    runs = []
    for _ in range(2):
        bus = make_bus(2, KEY, slot_size=SLOT, max_block=BLOCK, faults=f)
        runs.append([bus.send(encode(Packet(1 + i % 2, 0, i, Command.HELLO))) for i in range(200)])
        assert all(bus.events.values()), bus.events
    assert runs[0] == runs[1]


def test_sim_url_opens_drivers_in_process_and_stalls_are_late():
    protocol_sim.register()
    port = serial.serial_for_url(f"sim://?drivers=3&first=10&key={KEY.hex()}&faults=stall=1,stall_s=0.5"
                                 f"&slot_size={SLOT}&prefix=T-", timeout=0.05)
    port.write(encode(Packet(11, 0, 1, Command.HELLO)))
    assert port.read(200) == b""  # later than the timeout
    port.timeout = 5.0
    started = time.monotonic()
    first = port.read(1)
    frames = Deframer().feed(first + port.read(port.in_waiting))
    assert time.monotonic() - started < 4.0  # read returns when the late answer arrives, not at its timeout
    assert Hello.unpack(decode(frames[0]).payload).serial == "T-000011"
    port.bus.stall(10, 2.0)  # the one-shot hook: only the next answer of address 10 is late
    port.write(encode(Packet(10, 0, 2, Command.HELLO)) + encode(Packet(12, 0, 3, Command.HELLO)))
    time.sleep(0.7)  # past the faults' 0.5 s stall, before the hook's 2 s (margins for a busy machine)
    assert [decode(f).address for f in Deframer().feed(port.read(port.in_waiting))] == [12]
    port.close()
    with pytest.raises(serial.SerialException, match="key"):
        serial.serial_for_url("sim://?drivers=2")


def _read_frame(port: serial.Serial, timeout_s: float = 3.0) -> Packet:
    deframer, deadline = Deframer(), time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        frames = deframer.feed(port.read(max(1, port.in_waiting)))
        if frames:
            return decode(frames[0])
    raise AssertionError("no answer from the simulator")


def test_driver_sim_process_serves_a_pty_and_exits_cleanly(tmp_path):
    (tmp_path / "key").write_text(KEY.hex() + "\n")
    proc = subprocess.Popen(["vlp-driver-sim", "--drivers", "2", "--key-file", str(tmp_path / "key"), "--flash-dir",
                             str(tmp_path / "flash"), "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        assert line, proc.stderr.read()
        doc = json.loads(line)  # --json: the port, addresses and flash folder on the first line
        path = doc["port"]
        assert path.startswith("/dev/") and doc["addresses"] == [1, 2] and doc["flash_dir"] == str(tmp_path / "flash")
        for address in (2, 1):  # close and reopen: the simulator keeps serving
            with serial.Serial(path, 115200, timeout=1) as port:
                port.write(encode(Packet(address, 0, 5, Command.HELLO)))
                reply = _read_frame(port)
            assert (reply.address, reply.flags, reply.seq) == (address, FLAG_RESPONSE, 5)
            assert Hello.unpack(reply.payload).serial == f"SIM-{address:06d}"
        assert sorted(os.listdir(tmp_path / "flash")) == ["SIM-000001.flash", "SIM-000002.flash"]
        proc.terminate()
        assert proc.wait(timeout=10) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()
        proc.stderr.close()


def test_driver_sim_reports_bad_arguments_in_one_line(tmp_path, capsys):
    (tmp_path / "key").write_bytes(KEY)  # raw
    assert console_main(["--key-file", str(tmp_path / "missing")]) == 2
    assert console_main(["--drivers", "0", "--key-file", str(tmp_path / "key")]) == 2
    (tmp_path / "short").write_text("abcd")
    assert console_main(["--key-file", str(tmp_path / "short")]) == 2
    assert console_main(["--bogus"]) == 2
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 4 and all(line.startswith("vlp-driver-sim: error: ") for line in lines)
    assert "--key-file" in lines[0] and "cannot read" in lines[0]
    assert "2 bytes; it must have 16 to 64" in lines[2]  # the same key rules and words as vlp-flash
