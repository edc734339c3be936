"""A simulated luminaire driver: the driver side of docs/protocol.md as a state machine over bytes.

:meth:`SimulatedDriver.receive` takes raw line bytes and returns the raw bytes the
driver answers. RAM state (the last request's seq/command/response, the BEGIN in
progress, the receive buffer) is lost on :meth:`~SimulatedDriver.reset` and on a
power cut (:meth:`~SimulatedDriver.power_cut_after`); the flash
(:class:`~planner.flash.sim.memory.Flash`, layout documented there) keeps what was
programmed, and the driver boots from it.
"""

from __future__ import annotations

import hashlib
import hmac
import zlib
from dataclasses import dataclass

from planner.errors import InputError, UsageError
from planner.firmware.image import CRC_OFFSET, SIGNATURE_OFFSET, parse_config_image
from planner.flash.keys import driver_key
from planner.flash.sim.memory import ERASED, HEADER_BYTES, RECORD_BYTES, CommitRecord, Flash, PowerCut, StagingHeader
from planner.flash.wire import (
    ANY_ADDRESS,
    BEGIN_REPLY,
    BEGIN_REQUEST,
    CAP_AB_SLOTS,
    CAP_HMAC,
    CAP_RESUME,
    COMMIT_REPLY,
    COMMIT_REQUEST,
    FLAG_ERROR,
    FLAG_RESPONSE,
    NONCE_BYTES,
    PROTOCOL_VERSION,
    VERIFY_REPLY,
    WRITE_HEAD,
    WRITE_REPLY,
    Command,
    Deframer,
    Hello,
    Packet,
    Status,
    encode,
    error_payload,
    hello_mac,
)

__all__ = ["Flash", "PowerCut", "SimulatedDriver", "DriverStats"]

FIRMWARE_VERSION = 0x0100  # 1.0
NO_SHA = bytes(32)


class _Refuse(Exception):
    def __init__(self, status: Status, detail: int = 0, message: str = ""):
        super().__init__(message)
        self.status, self.detail, self.message = status, detail, message


@dataclass
class DriverStats:
    """Simulator counters (not driver RAM: they survive resets)."""

    frames: int = 0  # frames decoded and addressed to this driver
    dropped: int = 0  # damaged frames
    executed: int = 0  # requests executed
    repeats: int = 0  # requests answered from the seq cache
    boots: int = 0
    power_cuts: int = 0


class SimulatedDriver:
    """One driver at bus ``address`` with serial ``serial``, provisioned from the site key ``site_key``.

    The driver keeps only its own key, :func:`~planner.flash.keys.driver_key` of the site key and
    its serial (docs/protocol.md section 7), derived here; the site key itself is not kept.

    ``flash`` defaults to a RAM flash of ``slot_size`` (default 4096) bytes per slot; ``max_block`` is the
    most data one WRITE may carry, ``block_write_us`` the programming time HELLO reports [us]. ``protocol``
    2 (default) answers a HELLO's challenge with a MAC under its key; 1 is the unauthenticated version 1.
    """

    def __init__(self, address: int, serial: str, site_key: bytes, flash: Flash | None = None, *,
                 slot_size: int | None = None, max_block: int = 256, block_write_us: int = 2000, protocol: int = 2):
        if not 1 <= address <= 0xFFFE:
            raise UsageError(f"driver address {address} must be in 1..65534")
        if not serial.isascii() or not 0 < len(serial) <= 16:
            raise UsageError(f"driver serial {serial!r} must be 1 to 16 ASCII characters")
        if not 16 <= len(site_key) <= 64:
            raise UsageError(f"site key of {len(site_key)} bytes; the protocol needs 16 to 64")
        if not 16 <= max_block <= 1016:
            raise UsageError(f"max block {max_block} bytes must be in 16..1016")
        if protocol not in (1, PROTOCOL_VERSION):
            raise UsageError(f"protocol {protocol}: the simulated driver speaks 1 and {PROTOCOL_VERSION}")
        if flash is not None and slot_size not in (None, flash.slot_size):
            raise UsageError(f"slot size {slot_size} disagrees with the flash's {flash.slot_size}")
        self.flash = flash if flash is not None else Flash(slot_size or 4096)
        self.address, self.serial, self.max_block, self.block_write_us = address, serial, max_block, block_write_us
        self.protocol = protocol
        self.slot_size = self.flash.slot_size
        self._key = driver_key(bytes(site_key), serial)  # the site key is not kept
        self.stats = DriverStats()
        self._boot()

    # Boot and RAM state.
    def _boot(self) -> None:
        """RAM state from nothing but the flash (docs/protocol.md section 5)."""
        self.stats.boots += 1
        self._down = False
        self._deframer = Deframer()
        self._last: tuple[tuple, bytes] | None = None  # the last request's fields, its response
        self._load()

    def _load(self) -> None:
        """Active slot and staging state as the flash holds them; no BEGIN in progress."""
        self._begun = False
        valid = []
        for slot in (1, 2):
            rec = CommitRecord.unpack(self.flash.read(self.flash.record_offset(slot), RECORD_BYTES))
            if rec and rec.length <= self.slot_size and \
                    hashlib.sha256(self.flash.read(self.flash.area(slot), rec.length)).digest() == rec.sha256:
                valid.append((rec.counter, -slot, slot, rec))
        best = max(valid, default=None)
        self.active_slot = best[2] if best else 0
        self._active: CommitRecord | None = best[3] if best else None
        self.staging_slot = 2 if self.active_slot == 1 else 1
        head = StagingHeader.unpack(self.flash.read(self.flash.header_offset, HEADER_BYTES))
        if head and head.slot == self.staging_slot and 0 < head.length <= self.slot_size:
            self._staging: StagingHeader | None = head
            data = self.flash.read(self.flash.area(self.staging_slot), head.length)
            self.staged = len(data.rstrip(bytes([ERASED])))
        else:
            self._staging, self.staged = None, 0

    def reset(self) -> None:
        """Lose RAM state and boot from flash at once (a watchdog or reset pin)."""
        self._boot()

    def power_cut_after(self, n_bytes: int) -> None:
        """Lose power after ``n_bytes`` more erased or programmed flash bytes; boot on the next byte received."""
        self.flash.power_cut_after(n_bytes)

    @property
    def active_version(self) -> int:
        return self._active.version if self._active else 0

    @property
    def active_sha256(self) -> bytes:
        return self._active.sha256 if self._active else NO_SHA

    def hello(self) -> Hello:
        """The HELLO fields (without a MAC)."""
        return Hello(self.protocol, CAP_AB_SLOTS | CAP_RESUME | CAP_HMAC, self.max_block, self.slot_size,
                     self.block_write_us, FIRMWARE_VERSION, self.serial, self.active_slot, self.active_version,
                     self.active_sha256)

    # The line.
    def receive(self, data: bytes) -> bytes:
        """Feed line bytes; return the bytes the driver sends back (possibly none)."""
        if self._down and data:
            self._boot()
        out = bytearray()
        packets, dropped = self._deframer.packets(data)
        self.stats.dropped += dropped
        for packet in packets:
            if packet.is_response or packet.address not in (self.address, ANY_ADDRESS):
                continue
            self.stats.frames += 1
            try:
                out += self._answer(packet)
            except PowerCut:
                self.stats.power_cuts += 1
                self._down = True  # the rest of this input arrives while the driver is off
                break
        return bytes(out)

    def _answer(self, packet: Packet) -> bytes:
        request = (packet.address, packet.flags, packet.seq, packet.command, packet.payload)
        if self._last and self._last[0] == request:  # a retry: the same request, byte for byte
            self.stats.repeats += 1
            return self._last[1]
        self.stats.executed += 1
        flags = FLAG_RESPONSE
        try:
            payload = self._execute(packet.command, packet.payload)
        except _Refuse as refusal:
            flags |= FLAG_ERROR
            payload = error_payload(refusal.status, refusal.detail, refusal.message)
        response = encode(Packet(self.address, flags, packet.seq, packet.command, payload))
        self._last = (request, response)
        return response

    def _execute(self, command: int, payload: bytes) -> bytes:
        handler = {Command.HELLO: self._hello, Command.BEGIN: self._begin, Command.WRITE: self._write,
                   Command.VERIFY: self._verify, Command.COMMIT: self._commit}.get(command)  # type: ignore[call-overload]
        if handler is None:
            raise _Refuse(Status.BAD_REQUEST, 0, f"unknown command {command}")
        return handler(payload)

    # Commands.
    def _hello(self, payload: bytes) -> bytes:
        """Protocol v2: a challenge (the host's nonce) is answered with the fields and their MAC under this
        driver's key, over the nonce, its address and the fields; an empty HELLO with the fields alone."""
        if self.protocol >= 2 and len(payload) == NONCE_BYTES:
            body = self.hello().body()
            return body + hello_mac(self._key, payload, self.address, body)
        _size(payload, 0, "HELLO")
        return self.hello().pack()

    def _begin(self, payload: bytes) -> bytes:
        _size(payload, BEGIN_REQUEST.size, "BEGIN")
        length, version, sha, restart = BEGIN_REQUEST.unpack(payload)
        if length > self.slot_size:
            raise _Refuse(Status.TOO_LARGE, self.slot_size, f"image of {length} bytes exceeds the slot")
        if length == 0 or restart > 1:
            raise _Refuse(Status.BAD_REQUEST, 0, "BEGIN needs a length above 0 and restart 0 or 1")
        wanted = StagingHeader(self.staging_slot, length, version, sha)
        if restart or self._staging != wanted:
            f, slot = self.flash, self.staging_slot
            self._staging, self.staged = None, 0
            f.erase(f.header_offset, HEADER_BYTES)  # no resume from here on, until the new header is whole
            f.erase(f.record_offset(slot), RECORD_BYTES)  # the old fallback is invalid from here on
            f.erase(f.area(slot), self.slot_size)
            f.program(f.header_offset, wanted.pack())
            self._staging = wanted
        self._begun = True
        return BEGIN_REPLY.pack(self.staged, zlib.crc32(self._staged_bytes()))

    def _write(self, payload: bytes) -> bytes:
        if len(payload) < WRITE_HEAD.size + 1 or len(payload) > WRITE_HEAD.size + self.max_block:
            raise _Refuse(Status.BAD_REQUEST, 0, f"WRITE carries 1..{self.max_block} data bytes")
        staging = self._begun_staging()
        (offset,), data = WRITE_HEAD.unpack_from(payload), payload[WRITE_HEAD.size:]
        if offset + len(data) <= self.staged:
            return WRITE_REPLY.pack(self.staged)  # a retransmission: already there
        if offset != self.staged:
            raise _Refuse(Status.OFFSET, self.staged, f"{self.staged} bytes staged")
        if offset + len(data) > staging.length:
            raise _Refuse(Status.BAD_REQUEST, 0, f"WRITE past the announced {staging.length} bytes")
        self.flash.program(self.flash.area(self.staging_slot) + offset, data)
        self.staged += len(data)
        return WRITE_REPLY.pack(self.staged)

    def _verify(self, payload: bytes) -> bytes:
        _size(payload, 0, "VERIFY")
        self._begun_staging()
        return VERIFY_REPLY.pack(self.staged, hashlib.sha256(self._staged_bytes()).digest())

    def _commit(self, payload: bytes) -> bytes:
        _size(payload, COMMIT_REQUEST.size, "COMMIT")
        (expected,) = COMMIT_REQUEST.unpack(payload)
        staging = self._begun_staging()
        if self.staged < staging.length:
            raise _Refuse(Status.INCOMPLETE, self.staged, f"{self.staged} of {staging.length} bytes staged")
        image = self.flash.read(self.flash.area(self.staging_slot), staging.length)
        digest = hashlib.sha256(image).digest()
        if digest != staging.sha256 or digest != expected:
            raise _Refuse(Status.HASH, 0, "staged bytes do not hash to the announced SHA-256")
        try:
            version = parse_config_image(image)["image_version"]
        except InputError as exc:
            raise _Refuse(Status.IMAGE, 0, str(exc)) from None
        if version != staging.version:
            raise _Refuse(Status.IMAGE, 0, f"image holds version {version}, BEGIN announced {staging.version}")
        mac = hmac.new(self._key, image[:SIGNATURE_OFFSET], hashlib.sha256).digest()
        if not hmac.compare_digest(mac, image[SIGNATURE_OFFSET:CRC_OFFSET]):
            raise _Refuse(Status.AUTH, 0, "signature is not HMAC-SHA256 under this driver's key")
        if self._active and (version < self._active.version or
                             (version == self._active.version and digest != self._active.sha256)):
            raise _Refuse(Status.ROLLBACK, self._active.version, f"active version is {self._active.version}")
        if digest != self.active_sha256:
            record = CommitRecord((self._active.counter if self._active else 0) + 1, staging.length, version, digest)
            where = self.flash.record_offset(self.staging_slot)
            self.flash.program(where, record.pack())  # last: the slot becomes valid with its final byte
            if self.flash.read(where, RECORD_BYTES) != record.pack():
                raise _Refuse(Status.FLASH, where, "commit record did not read back")
        self._load()  # the new active slot as the flash now holds it; a new BEGIN is needed
        return COMMIT_REPLY.pack(self.active_slot, self.active_version)

    def _begun_staging(self) -> StagingHeader:
        if not self._begun or self._staging is None:
            raise _Refuse(Status.NOT_BEGUN, 0, "no BEGIN since the last commit or reset")
        return self._staging

    def _staged_bytes(self) -> bytes:
        return self.flash.read(self.flash.area(self.staging_slot), self.staged)


def _size(payload: bytes, size: int, name: str) -> None:
    if len(payload) != size:
        raise _Refuse(Status.BAD_REQUEST, 0, f"{name} payload of {len(payload)} bytes, expected {size}")
