"""The simulated driver's configuration flash: two slots with commit records, a staging header.

Layout (offsets in bytes, ``S`` = slot size)::

    0           slot A image area (S bytes)
    S           commit record A (52 bytes: 48 + CRC-32; docs/protocol.md section 5)
    S + 52      slot B image area (S bytes)
    2S + 52     commit record B (52 bytes)
    2S + 104    staging header (52 bytes; simulator detail, below)

The staging header lets a transfer resume after a power cut: BEGIN erases it, then
the inactive slot's record and image area, then programs it with what BEGIN announced::

    0   4   magic ``VLPH``
    4   1   slot being staged (1 A, 2 B)
    5   3   reserved, zero
    8   4   image length u32 [bytes]
    12  4   image version u32
    16  32  image SHA-256
    48  4   CRC-32 of bytes 0..47

The bytes staged are not recorded anywhere: at boot they are counted up to the last
byte that is not erased (0xFF) within the announced length. Trailing 0xFF image bytes
are thus counted as not staged, which is safe (the host writes them again; 0xFF
over erased flash changes nothing) and the host checks the prefix by its CRC-32.

Erasing sets bytes to 0xFF and programming stores bytes as given; both count toward
:meth:`Flash.power_cut_after`. With a ``path`` every erase or program is written
through to the file at once, so a killed process keeps exactly what was programmed.
"""

from __future__ import annotations

import io
import os
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path

from planner.errors import UsageError

ERASED = 0xFF
RECORD_MAGIC = b"VLPS"
HEADER_MAGIC = b"VLPH"
_RECORD = struct.Struct("<4sIII32s")  # magic, counter, length, version, SHA-256
_HEADER = struct.Struct("<4sB3xII32s")  # magic, slot, reserved, length, version, SHA-256
_CRC = struct.Struct("<I")
RECORD_BYTES = _RECORD.size + _CRC.size  # 52
HEADER_BYTES = _HEADER.size + _CRC.size  # 52


class PowerCut(Exception):
    """The flash lost power part-way through an erase or program (raised by :class:`Flash`)."""


@dataclass(frozen=True)
class CommitRecord:
    counter: int
    length: int
    version: int
    sha256: bytes

    def pack(self) -> bytes:
        body = _RECORD.pack(RECORD_MAGIC, self.counter, self.length, self.version, self.sha256)
        return body + _CRC.pack(zlib.crc32(body))

    @classmethod
    def unpack(cls, raw: bytes) -> CommitRecord | None:
        """The record, or None if its magic or CRC is wrong (erased, torn by a power cut)."""
        body, (crc,) = raw[:_RECORD.size], _CRC.unpack(raw[_RECORD.size:RECORD_BYTES])
        magic, counter, length, version, sha = _RECORD.unpack(body)
        return cls(counter, length, version, sha) if magic == RECORD_MAGIC and zlib.crc32(body) == crc else None


@dataclass(frozen=True)
class StagingHeader:
    slot: int
    length: int
    version: int
    sha256: bytes

    def pack(self) -> bytes:
        body = _HEADER.pack(HEADER_MAGIC, self.slot, self.length, self.version, self.sha256)
        return body + _CRC.pack(zlib.crc32(body))

    @classmethod
    def unpack(cls, raw: bytes) -> StagingHeader | None:
        body, (crc,) = raw[:_HEADER.size], _CRC.unpack(raw[_HEADER.size:HEADER_BYTES])
        magic, slot, length, version, sha = _HEADER.unpack(body)
        ok = magic == HEADER_MAGIC and zlib.crc32(body) == crc and slot in (1, 2)
        return cls(slot, length, version, sha) if ok else None


class Flash:
    """``slot_size``-byte A/B slots in RAM, or written through to the file ``path``.

    ``data`` seeds a RAM flash (e.g. another flash's :meth:`snapshot`). An existing
    file must have this layout's size; a missing one is created erased.
    """

    def __init__(self, slot_size: int, path: Path | str | None = None, data: bytes | None = None):
        if not 16 <= slot_size < 2**32:
            raise UsageError(f"slot size {slot_size} bytes must be in [16, 2^32)")
        self.slot_size = slot_size
        self.size = 2 * (slot_size + RECORD_BYTES) + HEADER_BYTES
        self.path = Path(path) if path is not None else None
        self.bytes_written = 0  # erased + programmed bytes over this object's life
        self._budget: int | None = None
        self._file: io.BufferedRandom | None = None
        if self.path is not None:
            self._memory = self._open_file(self.path)
        else:
            self._memory = bytearray(data) if data is not None else bytearray([ERASED]) * self.size
            if len(self._memory) != self.size:
                raise UsageError(f"flash data of {len(self._memory)} bytes; slot size {slot_size} needs {self.size}")

    def _open_file(self, path: Path) -> bytearray:
        try:
            if not path.exists():
                path.write_bytes(bytes([ERASED]) * self.size)
            self._file = open(path, "r+b")
            memory = bytearray(self._file.read())
        except OSError as exc:
            raise UsageError(f"{path}: cannot use as simulated flash ({exc.strerror or exc})") from None
        if len(memory) != self.size:
            self.close()
            raise UsageError(f"{path}: {len(memory)} bytes, but slot size {self.slot_size} needs {self.size}; "
                             "use the slot size it was made with or another flash folder")
        return memory

    # Layout.
    def area(self, slot: int) -> int:
        """Offset of slot 1 (A) or 2 (B)'s image area."""
        return (slot - 1) * (self.slot_size + RECORD_BYTES)

    def record_offset(self, slot: int) -> int:
        return self.area(slot) + self.slot_size

    @property
    def header_offset(self) -> int:
        return 2 * (self.slot_size + RECORD_BYTES)

    # Access.
    def read(self, offset: int, n: int) -> bytes:
        return bytes(self._memory[offset:offset + n])

    def snapshot(self) -> bytes:
        return bytes(self._memory)

    def program(self, offset: int, data: bytes) -> None:
        """Store ``data`` at ``offset``; :class:`PowerCut` after the armed number of bytes."""
        if offset < 0 or offset + len(data) > self.size:
            raise ValueError(f"flash range {offset}+{len(data)} outside {self.size} bytes")
        cut = self._budget is not None and len(data) > self._budget
        done = data[:self._budget] if cut else data
        self._memory[offset:offset + len(done)] = done
        self.bytes_written += len(done)
        if self._file is not None and done:
            self._file.seek(offset)
            self._file.write(done)
            self._file.flush()
        if cut:
            self._budget = None
            raise PowerCut(f"power cut at flash offset {offset + len(done)}")
        if self._budget is not None:
            self._budget -= len(done)

    def erase(self, offset: int, n: int) -> None:
        self.program(offset, bytes([ERASED]) * n)

    def power_cut_after(self, n_bytes: int) -> None:
        """Arm a power cut: the flash stops after ``n_bytes`` more erased or programmed bytes."""
        self._budget = max(0, n_bytes)

    def close(self) -> None:
        if self._file is not None:
            self._file.flush()
            os.fsync(self._file.fileno())
            self._file.close()
            self._file = None
