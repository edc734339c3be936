"""What a phone saves of a twin frame: blooming, saturation, sRGB gamma, JPEG, and portrait files turned.

The twin's frames (:mod:`planner.twin.render`) are linear light in DN (255 full scale), clipped where an LED
saturates. A phone then spreads some light of a bright LED round it (blooming: a share of the image blurred
wide), encodes sRGB (IEC 61966-2-1's transfer function), adds read noise after the tone curve, and writes
JPEG at its quality (phones: 85-95). A photo taken in portrait is saved with its pixels turned a quarter and
the EXIF orientation "normal": the rolling shutter's rows are then the file's columns (issue 37).
The receiver's reader (:mod:`planner.photo.read`) undoes the gamma and the ceiling; this module makes its
tests' input, as :func:`planner.twin.render.render_tones` makes the frames.
"""

from __future__ import annotations

import cv2
import numpy as np

from planner.decode.image import srgb_to_linear

BLOOM_SHARE = 0.05
"""Share of each pixel's light that blooming spreads round it (5 %: a faint halo round a saturated LED)."""

BLOOM_PX = 12.0
"""Standard deviation of blooming's spread [px]."""


def _encode_table() -> np.ndarray:
    """8-bit sRGB code of each linear level 0..4095 (of 4095): the transfer function as a lookup table."""
    codes = srgb_to_linear(np.arange(256) / 255.0)
    levels = np.arange(4096) / 4095.0
    return np.clip(np.searchsorted((codes[1:] + codes[:-1]) / 2, levels), 0, 255).astype(np.uint8)


def phone_photo(frame: np.ndarray, rng: np.random.Generator, *, quality: int = 90, bloom_share: float = BLOOM_SHARE,
                read_noise_dn: float = 1.0, turn: int = 0) -> bytes:
    """The colour JPEG (``quality`` 0-100, white light) a phone saves of ``frame`` (uint8 linear DN, a twin frame):
    blooming, sRGB 8 bits with ``read_noise_dn`` [DN of 255] after the tone curve, and the pixels turned ``turn``
    quarters counter-clockwise (1 or -1: a portrait photo; ``np.rot90``'s sense)."""
    light = frame.astype(np.float32)
    if bloom_share > 0:
        small = cv2.resize(light, None, fx=0.25, fy=0.25, interpolation=cv2.INTER_AREA)  # a wide blur, at a 16th
        halo = cv2.resize(cv2.GaussianBlur(small, (0, 0), BLOOM_PX / 4), light.shape[::-1],
                          interpolation=cv2.INTER_LINEAR)
        light += np.float32(bloom_share) * halo
    light *= np.float32(4095 / 255)
    index = np.clip(light, 0, 4095, out=light).astype(np.uint16)
    encoded = _encode_table()[index]
    del light, index
    if read_noise_dn > 0:
        noise = rng.standard_normal(encoded.shape, dtype=np.float32)
        noise *= np.float32(read_noise_dn)
        noise += encoded
        encoded = np.clip(np.rint(noise, out=noise), 0, 255, out=noise).astype(np.uint8)
    if turn:
        encoded = np.ascontiguousarray(np.rot90(encoded, turn))
    ok, data = cv2.imencode(".jpg", cv2.cvtColor(encoded, cv2.COLOR_GRAY2BGR), [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise RuntimeError("OpenCV could not encode the photo as JPEG")
    return data.tobytes()
