"""The binary configuration image: the one contract between the planner, the flasher and a driver.

Little-endian, fixed size: header, luminaire name, ID, chip rate, chips, image
version, plan hash, a signature field (filled by the flasher) and a CRC-32.
docs/firmware.md has the byte layout; docs/protocol.md how a driver takes it.
"""

from __future__ import annotations

import struct
import zlib

from planner.defaults import MAX_IMAGE_VERSION
from planner.errors import InputError, UsageError

IMAGE_MAGIC = b"VLPC"
IMAGE_FORMAT_VERSION = 1
NAME_BYTES = 32
MAX_IMAGE_CHIPS = 512  # the image's 64-byte chip area
# magic, format version, header length, total length | name, id, chip rate [mHz], chip count,
# reserved | chips | image version, plan hash | signature | CRC-32 (docs/firmware.md has offsets)
_HEADER = struct.Struct("<4sHHI")
_BODY = struct.Struct(f"<4sHHI{NAME_BYTES}sIIHH{MAX_IMAGE_CHIPS // 8}sI8s")
SIGNATURE_OFFSET = _BODY.size  # the signature covers bytes [0, SIGNATURE_OFFSET)
SIGNATURE_BYTES = 32
CRC_OFFSET = SIGNATURE_OFFSET + SIGNATURE_BYTES  # the CRC covers bytes [0, CRC_OFFSET)
IMAGE_BYTES = CRC_OFFSET + 4


def pack_chips(chips: str) -> bytes:
    """Chips packed MSB first (chip 0 is bit 7 of byte 0); the last byte is zero-padded."""
    padded = chips + "0" * (-len(chips) % 8)
    return bytes(int(padded[i:i + 8], 2) for i in range(0, len(padded), 8))


def config_image(name: str, luminaire_id: int, chips: str, chip_rate_hz: float, plan_hash: str,
                 *, image_version: int = 1) -> bytes:
    """The binary configuration image (little-endian, docs/firmware.md), signature zero."""
    raw_name = name.encode("utf-8")
    if len(raw_name) > NAME_BYTES or "\0" in name:
        raise InputError(f"luminaire {name!r}: the image holds names of at most {NAME_BYTES} UTF-8 bytes "
                         f"without NUL (this one has {len(raw_name)}); shorten the name in the layout")
    if len(chips) > MAX_IMAGE_CHIPS:
        raise InputError(f"luminaire {name!r}: frame of {len(chips)} chips; the image holds at most {MAX_IMAGE_CHIPS}")
    if not 1 <= luminaire_id < 2**32:
        raise InputError(f"luminaire {name!r}: ID {luminaire_id} does not fit the image (1 to 2^32 - 1)")
    millihz = round(chip_rate_hz * 1000)
    if not 0 < millihz < 2**32:
        raise InputError(f"luminaire {name!r}: chip rate {chip_rate_hz:g} Hz does not fit the image (u32 mHz)")
    if not 0 <= image_version <= MAX_IMAGE_VERSION:
        raise UsageError(f"image version {image_version:,} must be in 0..{MAX_IMAGE_VERSION:,} (docs/flashing.md, "
                         "image versions)")
    body = _BODY.pack(IMAGE_MAGIC, IMAGE_FORMAT_VERSION, _HEADER.size, IMAGE_BYTES, raw_name, luminaire_id,
                      millihz, len(chips), 0, pack_chips(chips), image_version, bytes.fromhex(plan_hash)) + bytes(SIGNATURE_BYTES)
    return body + struct.pack("<I", zlib.crc32(body))


def parse_config_image(data: bytes) -> dict:
    """Check and decode a configuration image; :class:`InputError` says what is wrong."""
    if len(data) < _HEADER.size:
        raise InputError(f"configuration image is {len(data)} bytes, too short for its header")
    magic, version, header_len, total_len = _HEADER.unpack_from(data)
    if magic != IMAGE_MAGIC:
        raise InputError(f"not a configuration image: magic {magic!r}, expected {IMAGE_MAGIC!r}")
    if version != IMAGE_FORMAT_VERSION:
        raise InputError(f"configuration image format version {version}; this tool reads {IMAGE_FORMAT_VERSION}")
    if header_len != _HEADER.size or total_len != IMAGE_BYTES or len(data) != IMAGE_BYTES:
        raise InputError(f"configuration image is {len(data)} bytes, header says {total_len} "
                         f"(header length {header_len}); version {version} images are {IMAGE_BYTES} bytes")
    crc = struct.unpack_from("<I", data, CRC_OFFSET)[0]
    if zlib.crc32(data[:CRC_OFFSET]) != crc:
        raise InputError(f"configuration image CRC mismatch (stored {crc:08x}, computed "
                         f"{zlib.crc32(data[:CRC_OFFSET]):08x}): the image is damaged")
    fields = _BODY.unpack_from(data)
    raw_name, lum_id, millihz, count, _, packed, image_version, hash_bytes = fields[4:]
    if not 1 <= count <= MAX_IMAGE_CHIPS:
        raise InputError(f"configuration image chip count {count} outside [1, {MAX_IMAGE_CHIPS}]")
    try:
        name = raw_name.rstrip(b"\0").decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"configuration image name is not UTF-8: {exc}") from None
    chips = "".join(format(b, "08b") for b in packed)[:count]
    return {"format_version": version, "name": name, "id": lum_id, "chip_rate_hz": millihz / 1000,
            "chip_count": count, "chips": chips, "image_version": image_version, "plan_hash": hash_bytes.hex(),
            "signature": data[SIGNATURE_OFFSET:CRC_OFFSET], "crc32": crc}
