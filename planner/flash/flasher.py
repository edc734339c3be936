"""Flashing one driver: sign its image, transfer, verify by hash, commit, confirm (docs/protocol.md).

Safe by construction: the image is signed with the site key, written into the
driver's inactive slot, read back by hash before the commit, and confirmed active
after it; an interrupted transfer resumes from what the driver reports. A driver
that cannot be brought to the new image is reported failed and still holds its
previous valid configuration (the protocol never touches the active slot).
"""

from __future__ import annotations

import hashlib
import hmac
import struct
import time
import zlib
from collections.abc import Callable
from dataclasses import dataclass

from planner.firmware.image import CRC_OFFSET, SIGNATURE_OFFSET, parse_config_image
from planner.flash.link import Link, LinkError
from planner.flash.wire import (
    BEGIN_REPLY,
    BEGIN_REQUEST,
    CAP_AB_SLOTS,
    CAP_HMAC,
    CAP_RESUME,
    COMMIT_REQUEST,
    PROTOCOL_VERSION,
    VERIFY_REPLY,
    WRITE_HEAD,
    WRITE_REPLY,
    Command,
    Hello,
    Status,
)

SESSIONS = 3
"""Whole BEGIN..COMMIT attempts per driver before it is reported failed."""


def sign_image(image: bytes, site_key: bytes) -> bytes:
    """The image with its signature field set to HMAC-SHA256(site key, bytes before it), CRC redone."""
    body = image[:SIGNATURE_OFFSET] + hmac.new(site_key, image[:SIGNATURE_OFFSET], hashlib.sha256).digest()
    assert len(body) == CRC_OFFSET
    return body + struct.pack("<I", zlib.crc32(body)) + image[CRC_OFFSET + 4:]


@dataclass(frozen=True)
class FlashResult:
    """What happened to one driver."""

    status: str  # "flashed", "current" (already held this image), "verified" (verify-only), "failed"
    serial: str = ""
    image_sha256: str = ""
    active_version: int = 0
    verified: bool = False
    message: str = ""
    seconds: float = 0.0


def _hello(link: Link, address: int) -> Hello:
    hello = Hello.unpack(link.request(address, Command.HELLO, response_bytes=80).payload)
    need = CAP_AB_SLOTS | CAP_RESUME | CAP_HMAC
    if hello.protocol != PROTOCOL_VERSION or hello.capabilities & need != need:
        raise LinkError(f"driver {hello.serial} speaks protocol {hello.protocol} with capabilities "
                        f"{hello.capabilities:#04x}; vlp-flash needs protocol {PROTOCOL_VERSION} with A/B slots, "
                        "resume and HMAC (update the driver's firmware)")
    return hello


def _transfer(link: Link, address: int, hello: Hello, image: bytes, version: int, sha: bytes,
              progress: Callable[[int, int], None] | None) -> None:
    block_s = hello.block_write_us * 1e-6
    reply = link.request(address, Command.BEGIN, BEGIN_REQUEST.pack(len(image), version, sha, 0), driver_s=block_s)
    offset, crc = BEGIN_REPLY.unpack(reply.payload[:BEGIN_REPLY.size])
    if offset > len(image) or crc != zlib.crc32(image[:offset]):
        reply = link.request(address, Command.BEGIN, BEGIN_REQUEST.pack(len(image), version, sha, 1), driver_s=block_s)
        offset = 0
    while offset < len(image):
        chunk = image[offset:offset + hello.max_block]
        try:
            reply = link.request(address, Command.WRITE, WRITE_HEAD.pack(offset) + chunk, driver_s=block_s)
            offset = WRITE_REPLY.unpack(reply.payload[:WRITE_REPLY.size])[0]
        except LinkError as exc:
            if exc.status != Status.OFFSET:
                raise
            offset = exc.detail  # the driver holds fewer (or more) bytes: continue from there
        if progress:
            progress(min(offset, len(image)), len(image))
    staged, digest = VERIFY_REPLY.unpack(link.request(address, Command.VERIFY).payload[:VERIFY_REPLY.size])
    if staged != len(image) or digest != sha:
        raise LinkError(f"driver {hello.serial} read back {staged} bytes hashing to {digest.hex()[:16]}..., "
                        f"not the image ({len(image)} bytes, {sha.hex()[:16]}...)", Status.HASH)
    link.request(address, Command.COMMIT, COMMIT_REQUEST.pack(sha), driver_s=2 * block_s)


def flash_driver(link: Link, address: int, signed_image: bytes, *, verify_only: bool = False,
                 progress: Callable[[int, int], None] | None = None) -> FlashResult:
    """Bring the driver at ``address`` to ``signed_image`` (or, ``verify_only``, check it holds it)."""
    started = time.perf_counter()
    version = parse_config_image(signed_image)["image_version"]
    sha = hashlib.sha256(signed_image).digest()
    serial, last, wrote = "", "", False
    for _ in range(SESSIONS):
        try:
            hello = _hello(link, address)
            serial = hello.serial
            if hello.active_sha256 == sha or verify_only:
                ok = hello.active_sha256 == sha
                status = "verified" if verify_only and ok else "flashed" if ok and wrote else "current" if ok else "failed"
                return FlashResult(status, serial,
                                   sha.hex(), hello.active_version, ok,
                                   "" if ok else "the driver holds another image", time.perf_counter() - started)
            if len(signed_image) > hello.slot_size:
                return FlashResult("failed", serial, sha.hex(), hello.active_version, False,
                                   f"image of {len(signed_image)} bytes exceeds the driver's {hello.slot_size}-byte slot",
                                   time.perf_counter() - started)
            wrote = True
            _transfer(link, address, hello, signed_image, version, sha, progress)
            after = _hello(link, address)
            if after.active_sha256 == sha:
                return FlashResult("flashed", serial, sha.hex(), after.active_version, True, "",
                                   time.perf_counter() - started)
            last = "after COMMIT the driver reports another active image"
        except LinkError as exc:
            last = str(exc)
            if exc.status in (Status.AUTH, Status.ROLLBACK, Status.IMAGE, Status.TOO_LARGE):
                break  # the driver refuses this image: retrying cannot help
    return FlashResult("failed", serial, sha.hex(), 0, False, last, time.perf_counter() - started)
