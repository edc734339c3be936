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

DRIVER_KEY_LABEL = b"VLP driver key v1\x00"
DRIVER_KEY_BYTES = 32


def driver_key(site_key: bytes, serial: str) -> bytes:
    """The 32-byte signing key of the driver with ``serial`` (1 to 16 ASCII characters)."""
    if not serial.isascii() or not 0 < len(serial) <= 16:
        raise ValueError(f"driver serial {serial!r} must be 1 to 16 ASCII characters")
    return hmac.new(site_key, DRIVER_KEY_LABEL + serial.encode("ascii"), hashlib.sha256).digest()
