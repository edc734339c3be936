"""Per-driver signing keys: one driver's EEPROM never signs for another (docs/protocol.md).

A driver holds only its own key, ``HMAC-SHA256(site key, "VLP driver key v1" NUL serial)``,
provisioned once from the site key and its serial; the host derives the same key from the
site key and the serial the driver reports in HELLO. An image signed for one driver fails
the signature check (``Status.AUTH``) on every other, and reading one driver's memory
yields nothing that signs for the rest of the site.
"""

from __future__ import annotations

import hashlib
import hmac
import os
import stat
from pathlib import Path

DRIVER_KEY_LABEL = b"VLP driver key v1\x00"
DRIVER_KEY_BYTES = 32
SITE_KEY_BYTES = (16, 64)
"""Fewest and most bytes of a site key (docs/protocol.md)."""
KEY_FILE_MAX_BYTES = 4096
"""Most bytes read from a key file: 64 bytes in hex with any whitespace fit many times over."""


def site_key_from(data: bytes, *, raw: bool = True) -> bytes:
    """The site key that ``data`` holds: hex digits (whitespace ignored), else (if ``raw``: a key file)
    the bytes themselves; :class:`ValueError` unless it has 16 to 64 bytes. The one reading of a key,
    for files, the environment and ``sim://`` URLs alike."""
    try:
        key = bytes.fromhex(data.decode("ascii"))
    except (UnicodeDecodeError, ValueError):
        if not raw:
            raise ValueError("the site key must be hex digits (an even number of them)") from None
        key = bytes(data)
    low, high = SITE_KEY_BYTES
    if not low <= len(key) <= high:
        raise ValueError(f"the site key has {len(key)} bytes; it must have {low} to {high}"
                         + (" (hex or raw)" if raw else f" ({2 * low} to {2 * high} hex digits)"))
    return key


def driver_key(site_key: bytes, serial: str) -> bytes:
    """The 32-byte signing key of the driver with ``serial`` (1 to 16 ASCII characters)."""
    if not serial.isascii() or not 0 < len(serial) <= 16:
        raise ValueError(f"driver serial {serial!r} must be 1 to 16 ASCII characters")
    return hmac.new(site_key, DRIVER_KEY_LABEL + serial.encode("ascii"), hashlib.sha256).digest()


JOURNAL_KEY_LABEL = b"VLP journal key v1\x00"


def journal_key(site_key: bytes) -> bytes:
    """The key sealing as-built journal entries: HMAC-SHA256(site key, "VLP journal key v1" NUL), never a
    driver key (a driver's serial is never that label), so no driver can seal a journal entry."""
    return hmac.new(site_key, JOURNAL_KEY_LABEL, hashlib.sha256).digest()


PLAN_KEY_LABEL = b"VLP plan key v1\x00"


def plan_key(site_key: bytes) -> bytes:
    """The key sealing ``plan.yaml``: HMAC-SHA256(site key, "VLP plan key v1" NUL), apart from the driver keys
    and the journal key by its label, so neither a driver nor a journal seal can seal a plan."""
    return hmac.new(site_key, PLAN_KEY_LABEL, hashlib.sha256).digest()


def readable_by_all(path: str | Path) -> bool:
    """True if every user of this machine can read the key file ``path``: the file is readable by others and
    every folder above it searchable by others (a file in a private folder is not exposed)."""
    p = Path(path).resolve()
    try:
        if not p.stat().st_mode & stat.S_IROTH:
            return False
        return all(os.stat(folder).st_mode & stat.S_IXOTH for folder in p.parents)
    except OSError:
        return False
