"""Flashing one driver: choose the version, sign for that driver, transfer, verify, commit, confirm.

Safe by construction: the host signs only the image the plan gives (rebuilt by the
caller from ``plan.yaml``), only for a driver that has just proved its serial by
answering a fresh challenge with a MAC under that serial's key (protocol v2,
docs/protocol.md section 7) and that the caller accepts (the journal's binding), at the
version the host decides (docs/flashing.md, image versions), with that driver's key
(:func:`~planner.flash.keys.driver_key`). The image goes into the driver's inactive
slot, is read back by hash before the commit and confirmed active by a new challenge;
an interrupted transfer resumes from what the driver reports. Every reply is bounded
(sizes, fields, progress, timeouts, a deadline), so a hostile driver fails alone.
Whatever happens, the result says what the driver last proved it holds (asked again
after a failure).
"""

from __future__ import annotations

import hashlib
import hmac
import secrets
import struct
import time
import zlib
from collections.abc import Callable
from dataclasses import dataclass, replace

from planner.defaults import MAX_IMAGE_VERSION
from planner.errors import PlannerError
from planner.firmware.image import CRC_OFFSET, SIGNATURE_OFFSET, config_image, parse_config_image
from planner.flash.keys import driver_key
from planner.flash.link import MAX_ATTEMPT_S, DeadlineError, Link, LinkError
from planner.flash.wire import (
    BEGIN_REPLY,
    BEGIN_REQUEST,
    CAP_AB_SLOTS,
    CAP_HMAC,
    CAP_RESUME,
    COMMIT_REQUEST,
    NONCE_BYTES,
    VERIFY_REPLY,
    WRITE_HEAD,
    WRITE_REPLY,
    Command,
    Hello,
    Status,
    WireError,
    hello_mac,
    unpack_reply,
)

SESSIONS = 3
"""Whole BEGIN..COMMIT attempts per driver before it is reported failed."""

ASK_AFTER_FAILURE = 2
"""HELLO requests (each with the link's retries) that ask a failed driver what it runs."""

FINAL = (Status.AUTH, Status.ROLLBACK, Status.IMAGE, Status.TOO_LARGE)
"""Refusals of the image itself: retrying cannot help."""

DRIVER_DEADLINE_S = 120.0
"""Default time one driver may take, all sessions and retries included [s] (vlp-flash --driver-deadline-s)."""

ASK_GRACE_S = 2 * MAX_ATTEMPT_S
"""Time the HELLO after a failure may take once the driver's deadline has passed [s]."""

HELLO_MAC_S = 0.1
"""Driver time for a HELLO challenge [s]: the reference AVR driver computes its HMAC-SHA256 in about 30 ms."""

STALLED_WRITES = 4
"""WRITE answers in a row that stage nothing new before the transfer is given up (a peer answering "0 bytes")."""


def sign_image(image: bytes, key: bytes) -> bytes:
    """The image with its signature field set to HMAC-SHA256(key, bytes before it), CRC redone."""
    body = image[:SIGNATURE_OFFSET] + hmac.new(key, image[:SIGNATURE_OFFSET], hashlib.sha256).digest()
    assert len(body) == CRC_OFFSET
    return body + struct.pack("<I", zlib.crc32(body)) + image[CRC_OFFSET + 4:]


def at_version(image: bytes, version: int) -> bytes:
    """The unsigned ``image`` with version ``version``: what ``config_image`` gives for its fields."""
    f = parse_config_image(image)
    return config_image(f["name"], f["id"], f["chips"], f["chip_rate_hz"], f["plan_hash"], image_version=version)


VERSION_STEP = 100
"""Most a driver's claimed version may exceed what the host knows (plan images, journal) and still be followed."""


@dataclass(frozen=True)
class Versions:
    """Which version to sign (docs/flashing.md, image versions): the host decides, from the plan and the journal.

    ``explicit`` (``--image-version``): exactly that one, the driver refuses it if not newer.
    Otherwise one above the version the driver runs, at least ``floor`` (the version in the plan's image
    files); the driver's claim is followed only up to :data:`VERSION_STEP` above what the host knows
    (``floor``, and ``journal``: (serial, version) of this plan's image last verified on this luminaire),
    so no peer's claim pushes the signed version up (a version burn). If ``journal`` says this plan's image
    was verified on this very driver, a newer image found there since is not replaced.
    """

    floor: int = 1
    explicit: int | None = None
    journal: tuple[str, int] | None = None

    @property
    def known(self) -> int:
        """The highest version the host itself knows of for this luminaire."""
        return max(self.floor, self.journal[1] if self.journal else 0)


@dataclass(frozen=True)
class FlashResult:
    """What happened to one driver, and what it last reported holding."""

    status: str  # "flashed", "current" (already held this image), "verified" (verify-only), "failed",
    # "unauthenticated" (a protocol v1 driver: it cannot prove who it is, so nothing is signed for it)
    serial: str = ""
    image_sha256: str = ""  # the signed image meant for this driver ("" if it never answered)
    image_version: int = 0
    active_version: int = 0  # what the driver last reported (0: none, or never answered)
    active_sha256: str = ""
    verified: bool = False
    message: str = ""
    seconds: float = 0.0


class _Refused(PlannerError):
    """The host will not sign for this driver (a rollback, a version out of bounds)."""


class _Unauthenticated(PlannerError):
    """A protocol v1 driver: its HELLO proves nothing, so the host signs nothing for it."""

    def __init__(self, hello: Hello):
        why = (f"speaks protocol {hello.protocol}, whose HELLO is unauthenticated" if hello.protocol < 2 else
               "answered the challenge without a MAC")
        super().__init__(f"{why} (serial, version and image hash are its own word): vlp-flash signs nothing for it "
                         "and cannot verify it; update its firmware to protocol 2")
        self.hello = hello


def _hello(link: Link, address: int, site_key: bytes) -> Hello:
    """The driver's HELLO, proved (protocol v2): it answers a fresh nonce with a MAC under the key of the serial
    it reports, over the nonce, its bus address and every field (docs/protocol.md section 7). A MAC that does
    not check is :class:`LinkError` (status AUTH); a v1 driver is :class:`_Unauthenticated`."""
    nonce = secrets.token_bytes(NONCE_BYTES)
    try:
        reply = link.request(address, Command.HELLO, nonce, response_bytes=120, driver_s=HELLO_MAC_S)
    except LinkError as exc:
        if exc.status != Status.BAD_REQUEST:
            raise
        reply = link.request(address, Command.HELLO, response_bytes=80)  # a v1 driver takes no challenge
        raise _Unauthenticated(Hello.unpack(reply.payload)) from None
    hello = Hello.unpack(reply.payload)  # bounds checked
    if not hello.mac:
        raise _Unauthenticated(hello)
    need = CAP_AB_SLOTS | CAP_RESUME | CAP_HMAC
    if hello.capabilities & need != need:
        raise LinkError(f"driver {hello.serial} has capabilities {hello.capabilities:#04x}; vlp-flash needs A/B slots, "
                        "resume and HMAC (update the driver's firmware)")
    if not hmac.compare_digest(hello_mac(_key(site_key, hello.serial), nonce, reply.address, hello.body()), hello.mac):
        raise LinkError(f"driver claiming serial {hello.serial} at address {reply.address} failed the challenge: its "
                        "HELLO's MAC is not that driver's (an impostor or a replayed answer, or a driver provisioned "
                        "from another site key): nothing signed for it", Status.AUTH)
    return hello


def _key(site_key: bytes, serial: str) -> bytes:
    try:
        return driver_key(site_key, serial)
    except ValueError as exc:
        raise _Refused(f"{exc}: the driver's serial cannot name its key (check its firmware)") from None


def _runs_plan(hello: Hello, image: bytes, key: bytes) -> bool:
    """True if the driver runs the plan's ``image``, signed with ``key``, at the version it reports."""
    if not hello.active_slot or not 0 <= hello.active_version <= MAX_IMAGE_VERSION:
        return False
    return hashlib.sha256(sign_image(at_version(image, hello.active_version), key)).digest() == hello.active_sha256


def _choose_version(hello: Hello, versions: Versions) -> int:
    """The version to sign for a driver that runs another image; :class:`_Refused` says what to do."""
    running = hello.active_version if hello.active_slot else 0
    if versions.explicit is not None:
        return versions.explicit
    if versions.journal and versions.journal[0] == hello.serial and running >= versions.journal[1]:
        raise _Refused(f"runs version {running}, flashed after this plan's image (version {versions.journal[1]}, "
                       f"journal): this plan is older than what the driver runs; flash the newer plan, or give "
                       f"--image-version {running + 1} to put this plan's image back deliberately")
    if running > versions.known + VERSION_STEP:
        raise _Refused(f"claims to run version {running:,}, more than {VERSION_STEP} above the {versions.known:,} this "
                       "host knows for it (plan images, journal): vlp-flash does not follow such a claim; check which "
                       "driver this is, or give --image-version N to choose the version deliberately")
    version = max(versions.floor, running + 1)
    if version > MAX_IMAGE_VERSION:
        raise _Refused(f"runs version {running:,}, and vlp-flash signs versions up to {MAX_IMAGE_VERSION:,} only: "
                       "the driver's image did not come from vlp-flash; erase its configuration and flash again")
    return version


def _transfer(link: Link, address: int, hello: Hello, image: bytes, version: int, sha: bytes,
              progress: Callable[[int, int], None] | None) -> None:
    block_s = hello.block_write_us * 1e-6  # HELLO bounds it; the link caps every attempt as well
    erase_s = (-(-hello.slot_size // hello.max_block) + 1) * block_s  # BEGIN may erase the whole slot
    reply = link.request(address, Command.BEGIN, BEGIN_REQUEST.pack(len(image), version, sha, 0), driver_s=erase_s)
    offset, crc = unpack_reply(BEGIN_REPLY, reply.payload, "BEGIN")
    if offset > len(image) or crc != zlib.crc32(image[:offset]):
        reply = link.request(address, Command.BEGIN, BEGIN_REQUEST.pack(len(image), version, sha, 1), driver_s=erase_s)
        offset = 0
    stalled = 0
    while offset < len(image):
        chunk = image[offset:offset + hello.max_block]
        try:
            reply = link.request(address, Command.WRITE, WRITE_HEAD.pack(offset) + chunk, driver_s=block_s)
            staged = unpack_reply(WRITE_REPLY, reply.payload, "WRITE")[0]
        except LinkError as exc:
            if exc.status != Status.OFFSET:
                raise
            staged = exc.detail  # the driver holds fewer (or more) bytes: continue from there
        stalled = stalled + 1 if staged <= offset else 0
        if stalled >= STALLED_WRITES:
            raise LinkError(f"driver {hello.serial} staged nothing new in {stalled} WRITEs at offset {offset} "
                            f"(it answers {staged} bytes staged): the transfer makes no progress")
        offset = staged
        if progress:
            progress(min(offset, len(image)), len(image))
    verify = link.request(address, Command.VERIFY, driver_s=block_s)  # the driver hashes what it reads back
    staged, digest = unpack_reply(VERIFY_REPLY, verify.payload, "VERIFY")
    if staged != len(image) or digest != sha:
        raise LinkError(f"driver {hello.serial} read back {staged} bytes hashing to {digest.hex()[:16]}..., "
                        f"not the image ({len(image)} bytes, {sha.hex()[:16]}...)", Status.HASH)
    link.request(address, Command.COMMIT, COMMIT_REQUEST.pack(sha), driver_s=2 * block_s)


Accept = Callable[[Hello], str | None]
"""Asked with a driver's proved HELLO before anything is signed for it: a refusal message, or None to go on."""


def flash_driver(link: Link, address: int, image: bytes, site_key: bytes, versions: Versions = Versions(), *,
                 verify_only: bool = False, progress: Callable[[int, int], None] | None = None,
                 deadline_s: float = DRIVER_DEADLINE_S, accept: Accept | None = None) -> FlashResult:
    """Bring the driver at ``address`` to the plan's ``image`` (unsigned; or, ``verify_only``, check it runs it)
    within ``deadline_s`` [s]. Only a driver that proves its serial (protocol v2) and that ``accept`` takes
    gets an image signed. Whatever the peer answers, this returns a result: a reply that breaks the protocol,
    no progress, a failed challenge or the deadline fail this driver only, in one line."""
    started = time.perf_counter()
    result, wrote = FlashResult("failed"), False
    link.deadline = started + deadline_s
    try:
        result, wrote = _sessions(link, address, image, site_key, versions, verify_only, progress, started, accept)
    finally:
        link.deadline = None
    if result.verified or result.status == "unauthenticated":
        return replace(result, seconds=time.perf_counter() - started)
    link.deadline = time.perf_counter() + ASK_GRACE_S
    try:
        return _asked(link, address, image, site_key, result, wrote, verify_only, started, accept)
    finally:
        link.deadline = None


def _sessions(link: Link, address: int, image: bytes, site_key: bytes, versions: Versions, verify_only: bool,
              progress: Callable[[int, int], None] | None, started: float,
              accept: Accept | None) -> tuple[FlashResult, bool]:
    """Up to :data:`SESSIONS` attempts: the result (verified, or the last failure) and whether bytes were sent."""
    result, wrote = FlashResult("failed"), False
    for _ in range(SESSIONS):
        try:
            hello = _hello(link, address, site_key)
            key = _key(site_key, hello.serial)
            result = replace(result, serial=hello.serial, active_version=hello.active_version,
                             active_sha256=hello.active_sha256.hex())
            if accept is not None and (refusal := accept(hello)):
                raise _Refused(refusal)
            if _runs_plan(hello, image, key):
                status = "verified" if verify_only else "flashed" if wrote else "current"
                return replace(result, status=status, image_sha256=result.active_sha256, verified=True, message="",
                               image_version=hello.active_version, seconds=time.perf_counter() - started), wrote
            if verify_only:
                result = replace(result, message="the driver holds another image")
                break
            version = _choose_version(hello, versions)
            signed = sign_image(at_version(image, version), key)
            sha = hashlib.sha256(signed).digest()
            result = replace(result, image_sha256=sha.hex(), image_version=version)
            if len(signed) > hello.slot_size:
                result = replace(result, message=f"image of {len(signed)} bytes exceeds the driver's "
                                                 f"{hello.slot_size}-byte slot")
                break
            wrote = True
            _transfer(link, address, hello, signed, version, sha, progress)  # the next HELLO confirms
            result = replace(result, message="after COMMIT the driver reports another active image")
        except _Refused as exc:
            result = replace(result, message=str(exc))
            break
        except _Unauthenticated as exc:
            return replace(result, status="unauthenticated", serial=exc.hello.serial, message=str(exc),
                           active_version=exc.hello.active_version, active_sha256=exc.hello.active_sha256.hex()), wrote
        except WireError as exc:  # a reply that breaks the protocol: retrying the same peer cannot help
            result = replace(result, message=f"driver {_who(result, address)} answered outside the protocol: {exc}")
            break
        except DeadlineError:
            result = replace(result, message=f"driver {_who(result, address)} gave no result within its "
                                             f"{(link.deadline or started) - started:g} s deadline "
                                             "(--driver-deadline-s)"
                                             + (f" (last: {result.message})" if result.message else ""))
            break
        except LinkError as exc:
            message = str(exc)
            if exc.status == Status.ROLLBACK:
                message += (f"; the driver runs version {exc.detail}: leave out --image-version to follow it, or give "
                            f"--image-version {exc.detail + 1} or more")
            result = replace(result, message=message)
            if exc.status in FINAL:
                break
    return result, wrote


def _who(result: FlashResult, address: int) -> str:
    return result.serial or ("(any)" if address == 0xFFFF else f"at address {address}")


def _asked(link: Link, address: int, image: bytes, site_key: bytes, result: FlashResult, wrote: bool,
           verify_only: bool, started: float, accept: Accept | None) -> FlashResult:
    """``result`` after a failure, with what the driver now reports (it may run the new image after all). A
    driver that never answered is asked too: it may have lost power in the midst of HELLO and booted since."""
    for _ in range(ASK_AFTER_FAILURE):
        try:
            hello = _hello(link, address, site_key)
            if accept is not None and accept(hello):
                return replace(result, seconds=time.perf_counter() - started)  # not this luminaire's driver
            held = _runs_plan(hello, image, _key(site_key, hello.serial))
            break
        except (LinkError, WireError, _Refused, _Unauthenticated):
            continue
    else:  # silent: what it runs is unknown (it may have taken the image before it fell silent)
        unknown = "; it did not answer afterwards, so what it runs is unknown" if wrote else ""
        return replace(result, active_sha256="" if wrote else result.active_sha256, message=result.message + unknown,
                       seconds=time.perf_counter() - started)
    result = replace(result, serial=hello.serial, active_version=hello.active_version,
                     active_sha256=hello.active_sha256.hex(), seconds=time.perf_counter() - started)
    if held:
        status = "verified" if verify_only else "flashed" if wrote else "current"
        return replace(result, status=status, verified=True, message="", image_sha256=result.active_sha256,
                       image_version=hello.active_version)
    return result
