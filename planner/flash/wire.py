"""The flashing protocol's wire format (docs/protocol.md): COBS frames, CRC-32, fixed payloads.

A packet is ``address u16 | flags u8 | seq u8 | command u8 | length u16 | payload |
crc32 u32`` (little-endian; CRC-32/ISO-HDLC over everything before it), COBS-encoded
and followed by one zero byte. Both the host and the driver (simulated or real) use
this module, so the two sides cannot disagree on a byte.
"""

from __future__ import annotations

import hashlib
import hmac
import struct
import zlib
from dataclasses import dataclass, replace
from enum import IntEnum

from cobs import cobs

from planner.errors import PlannerError

ANY_ADDRESS = 0xFFFF  # point to point: whichever driver is plugged in answers
FLAG_RESPONSE = 0x01
FLAG_ERROR = 0x02
MAX_PAYLOAD = 1024
PROTOCOL_VERSION = 2
NONCE_BYTES = 16
"""The host's challenge in a HELLO request (protocol v2)."""
HELLO_MAC_LABEL = b"VLP hello v2\x00"
"""Starts the message a HELLO's MAC covers: never "VLPC", the first bytes of a signed image."""

_HEAD = struct.Struct("<HBBBH")
_CRC = struct.Struct("<I")
MAX_FRAME = cobs.max_encoded_length(_HEAD.size + MAX_PAYLOAD + _CRC.size) + 1


class Command(IntEnum):
    HELLO = 1
    BEGIN = 2
    WRITE = 3
    VERIFY = 4
    COMMIT = 5


class Status(IntEnum):
    """Error codes a driver returns in an error response."""

    BAD_REQUEST = 1  # unknown command or malformed payload
    OFFSET = 2  # WRITE not at the next offset; detail = bytes held
    TOO_LARGE = 3  # image longer than a slot
    NOT_BEGUN = 4  # WRITE/VERIFY/COMMIT without BEGIN
    INCOMPLETE = 5  # COMMIT before every byte arrived
    HASH = 6  # staged bytes do not hash to the announced SHA-256
    IMAGE = 7  # not a configuration image (magic, format, CRC)
    AUTH = 8  # signature is not HMAC-SHA256 under the driver's own key (docs/protocol.md section 7)
    ROLLBACK = 9  # image version older than the active one (or same version, other image)
    FLASH = 10  # the flash failed to program or read back


class WireError(PlannerError):
    """A frame that cannot be decoded (damaged in transit): the receiver drops it."""


class ReplyError(WireError):
    """A well-framed reply whose payload breaks the protocol: too short or long, a field out of range."""


@dataclass(frozen=True)
class Packet:
    address: int
    flags: int
    seq: int
    command: int
    payload: bytes = b""

    @property
    def is_response(self) -> bool:
        return bool(self.flags & FLAG_RESPONSE)

    @property
    def is_error(self) -> bool:
        return bool(self.flags & FLAG_ERROR)


def encode(packet: Packet) -> bytes:
    """The bytes on the line for ``packet``, delimiter included."""
    if len(packet.payload) > MAX_PAYLOAD:
        raise ValueError(f"payload of {len(packet.payload)} bytes exceeds {MAX_PAYLOAD}")
    body = _HEAD.pack(packet.address, packet.flags, packet.seq, packet.command, len(packet.payload)) + packet.payload
    return cobs.encode(body + _CRC.pack(zlib.crc32(body))) + b"\x00"


def decode(frame: bytes) -> Packet:
    """A packet from one frame (without its delimiter); :class:`WireError` if damaged."""
    try:
        raw = cobs.decode(frame)
    except cobs.DecodeError as exc:
        raise WireError(f"bad COBS frame ({exc})") from None
    if len(raw) < _HEAD.size + _CRC.size:
        raise WireError(f"frame of {len(raw)} bytes is shorter than a header")
    body, (crc,) = raw[:-_CRC.size], _CRC.unpack(raw[-_CRC.size:])
    if zlib.crc32(body) != crc:
        raise WireError("CRC mismatch")
    address, flags, seq, command, length = _HEAD.unpack(body[:_HEAD.size])
    if length != len(body) - _HEAD.size:
        raise WireError(f"length field {length} disagrees with {len(body) - _HEAD.size} payload bytes")
    return Packet(address, flags, seq, command, bytes(body[_HEAD.size:]))


class Deframer:
    """Splits a byte stream into frames at zero bytes; drops over-long garbage."""

    def __init__(self) -> None:
        self._buffer = bytearray()

    def feed(self, data: bytes) -> list[bytes]:
        frames = []
        for byte in data:
            if byte == 0:
                if self._buffer:
                    frames.append(bytes(self._buffer))
                self._buffer.clear()
            elif len(self._buffer) < MAX_FRAME:
                self._buffer.append(byte)
        return frames

    def packets(self, data: bytes) -> tuple[list[Packet], int]:
        """The packets ``data`` completes, and how many damaged frames were dropped (both ends of the line
        read this way: the host's link and the simulated driver)."""
        packets, dropped = [], 0
        for frame in self.feed(data):
            try:
                packets.append(decode(frame))
            except WireError:
                dropped += 1
        return packets, dropped


# Payloads (docs/protocol.md has the tables).
HELLO_REPLY = struct.Struct("<BBHII H16sBI32s")
"""protocol version, capabilities, max block, slot size [bytes], block write time [us], firmware version,
serial (ASCII, NUL-padded), active slot (0 none, 1 A, 2 B), active image version, active image SHA-256."""
CAP_AB_SLOTS, CAP_RESUME, CAP_HMAC = 0x01, 0x02, 0x04
HELLO_MAC_BYTES = 32
HELLO_MAC_ADDRESS = struct.Struct("<H")  # the driver's own bus address, in the MAC'd message

BEGIN_REQUEST = struct.Struct("<II32sB")  # length, version, SHA-256, restart (1 = discard staged)
BEGIN_REPLY = struct.Struct("<II")  # resume offset (bytes already staged), CRC-32 of those bytes
WRITE_HEAD = struct.Struct("<I")  # offset, followed by the data
WRITE_REPLY = struct.Struct("<I")  # bytes now staged
VERIFY_REPLY = struct.Struct("<I32s")  # bytes staged, their SHA-256
COMMIT_REQUEST = struct.Struct("<32s")  # SHA-256 the host expects to become active
COMMIT_REPLY = struct.Struct("<BI")  # active slot, active image version
ERROR_HEAD = struct.Struct("<BI")  # status, detail; followed by an ASCII message


MAX_BLOCK_RANGE = (16, 1016)
"""Fewest and most data bytes one WRITE may carry (HELLO ``max_block``)."""
MAX_SLOT_BYTES = 1 << 20
"""Largest slot a HELLO may report [bytes]: a configuration image is a few hundred bytes."""
MAX_BLOCK_WRITE_US = 2_000_000
"""Longest block programming time a HELLO may report [us] (the reference AVR driver: 435,200)."""


def unpack_reply(shape: struct.Struct, payload: bytes, what: str) -> tuple:
    """The fields of a reply that must be exactly ``shape``; :class:`ReplyError` otherwise."""
    if len(payload) != shape.size:
        raise ReplyError(f"{what} reply of {len(payload)} bytes, the protocol's is {shape.size}")
    return shape.unpack(payload)


@dataclass(frozen=True)
class Hello:
    protocol: int
    capabilities: int
    max_block: int
    slot_size: int
    block_write_us: int
    firmware_version: int
    serial: str
    active_slot: int
    active_version: int
    active_sha256: bytes
    mac: bytes = b""  # protocol v2, answering a challenge: hello_mac() of the fields above

    def body(self) -> bytes:
        """The 67 bytes of fields (without the MAC)."""
        return HELLO_REPLY.pack(self.protocol, self.capabilities, self.max_block, self.slot_size, self.block_write_us,
                                self.firmware_version, self.serial.encode("ascii")[:16], self.active_slot,
                                self.active_version, self.active_sha256)

    def pack(self) -> bytes:
        return self.body() + self.mac

    @classmethod
    def unpack(cls, payload: bytes) -> Hello:
        """A HELLO reply, every field checked against the protocol's bounds; :class:`ReplyError` if one is
        out of range (so no hostile value reaches a timeout, a loop or a message)."""
        mac = payload[HELLO_REPLY.size:] if len(payload) == HELLO_REPLY.size + HELLO_MAC_BYTES else b""
        f = list(unpack_reply(HELLO_REPLY, payload[:len(payload) - len(mac)], "HELLO"))
        raw = f[6].rstrip(b"\x00")
        if not raw or b"\x00" in raw or not all(0x21 <= c <= 0x7E for c in raw):
            raise ReplyError(f"HELLO serial {raw[:16]!r} is not 1 to 16 printable ASCII characters")
        f[6] = raw.decode("ascii")
        hello = replace(cls(*f), mac=mac)
        if hello.protocol not in (1, 2) or (mac and hello.protocol < 2):
            raise ReplyError(f"HELLO of protocol {hello.protocol} ({len(payload)} bytes): vlp-flash speaks 1 and 2")
        low, high = MAX_BLOCK_RANGE
        for name, value, bounds in (("max_block", hello.max_block, MAX_BLOCK_RANGE),
                                    ("slot_size", hello.slot_size, (low, MAX_SLOT_BYTES)),
                                    ("block_write_us", hello.block_write_us, (0, MAX_BLOCK_WRITE_US)),
                                    ("active slot", hello.active_slot, (0, 2))):
            if not bounds[0] <= value <= bounds[1]:
                raise ReplyError(f"HELLO {name} {value:,} is outside the protocol's {bounds[0]:,}..{bounds[1]:,}")
        return hello


def hello_mac(driver_key: bytes, nonce: bytes, address: int, body: bytes) -> bytes:
    """HELLO's MAC (protocol v2): HMAC-SHA256(driver key, label | nonce | address u16 | the 67 bytes of fields)."""
    message = HELLO_MAC_LABEL + nonce + HELLO_MAC_ADDRESS.pack(address) + body
    return hmac.new(driver_key, message, hashlib.sha256).digest()


def error_payload(status: Status, detail: int = 0, message: str = "") -> bytes:
    return ERROR_HEAD.pack(int(status), detail) + message.encode("ascii", "replace")[:200]


def parse_error(payload: bytes) -> tuple[int, int, str]:
    """Status, detail and message of an error reply; :class:`ReplyError` if it is shorter than its head. The
    message keeps printable ASCII only (at most 200 characters): a peer cannot forge or split a line with it."""
    status, detail = unpack_reply(ERROR_HEAD, payload[:ERROR_HEAD.size], "error")
    text = payload[ERROR_HEAD.size:ERROR_HEAD.size + 200].decode("ascii", "replace")
    return status, detail, "".join(c if c.isascii() and c.isprintable() else "?" for c in text)
