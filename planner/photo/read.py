"""A phone photo as the receiver needs it: linear luminance above the lit ceiling, in the twin's DN.

A phone saves 8-bit (or 16-bit PNG) sRGB: gamma-encoded colour. The receiver's
stages (:mod:`planner.decode.image`) work on linear light, where a row's level is
proportional to the LED's drive over the row's exposure, on a dark ceiling. So:

1. **Read** the pixels as the sensor wrote them (``IMREAD_IGNORE_ORIENTATION``: an
   EXIF rotation would turn the rolling shutter's rows into columns).
2. **Linearise**: the inverse sRGB transfer function of IEC 61966-2-1.
3. **Luminance**: Rec. 709 / sRGB weights ``Y = 0.2126 R + 0.7152 G + 0.0722 B``. A
   saturated LED clips at 1 in every channel, so its plateau is flat at 1.
4. **Ceiling**: a lit ceiling (daylight, other lamps) is a smooth surface under the
   LEDs; it is fitted as a cubic polynomial in x and y to block medians of the image,
   leaving out blocks lit by LEDs (iterated sigma clipping), and subtracted. The LEDs
   then stand on a flat level, as in the twin's frames.
5. **DN**: the difference is scaled to 0..255 on the level :data:`DARK_DN`, so the
   receiver's thresholds (in DN of 255) apply unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

from planner.camera.model import Camera
from planner.decode.image import FrameFormat, srgb_to_linear
from planner.decode.tones import ToneFormat
from planner.defaults import MAX_IMAGE_PX, SENSOR_BLUR_PX, SENSOR_EXPOSURE_S
from planner.errors import InputError
from planner.photo.decode import PhotoBlob, decode_photo
from planner.photo.small import decode_small_photo

if TYPE_CHECKING:
    from planner.plan.file import PlanFile

LUMA_BGR = np.array([0.0722, 0.7152, 0.2126], np.float32)
"""Rec. 709 luminance weights in OpenCV's channel order (blue, green, red)."""

DARK_DN = 16.0
"""Level the subtracted ceiling sits at [DN]: room below it for the noise of the ceiling."""

BLOCK_PX = 16
"""Side of the blocks whose medians the ceiling is fitted to [px]."""

LARGE_PX = 16_000_000
SAMPLE_STEP = 4
"""A photo over ``LARGE_PX`` pixels has its block medians taken over every ``SAMPLE_STEP``-th pixel each way (16 of a
block's 256): a 33 MP photo's ceiling in a tenth of the time, the medians alike within their noise."""

CLIP_SIGMA = 4.0
"""Blocks brighter than the fitted ceiling by this many robust standard deviations are LED light."""

SUFFIXES = (".jpg", ".jpeg", ".png")
"""The photo files ``vlp-report --photos`` reads from a folder."""


def header_size(data: bytes) -> tuple[int, int] | None:
    """Width and height [px] a PNG or JPEG header states, read before any pixel is decoded (None: neither format,
    or no size found in the header)."""
    if data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR":
        return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
    if data[:2] != b"\xff\xd8":
        return None
    k = 2
    while k + 9 <= len(data):  # JPEG markers up to the frame header (SOF0-15 but DHT C4, JPG C8, DAC CC)
        if data[k] != 0xFF:
            return None
        marker = data[k + 1]
        if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7 or marker == 0xFF:
            k += 1 if marker == 0xFF else 2
            continue
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            return int.from_bytes(data[k + 7:k + 9], "big"), int.from_bytes(data[k + 5:k + 7], "big")
        k += 2 + int.from_bytes(data[k + 2:k + 4], "big")
    return None


def check_size(data: bytes, path: str | Path) -> None:
    """:class:`InputError` if the header of the image ``data`` (from ``path``) states a side over
    :data:`~planner.defaults.MAX_IMAGE_PX`: refused before decoding, which would take gigabytes."""
    size = header_size(data)
    if size is not None and max(size) > MAX_IMAGE_PX:
        raise InputError(f"{path}: the image header states {size[0]:,} x {size[1]:,} px, more than the "
                         f"{MAX_IMAGE_PX:,} px a side any phone takes; give the photo as the phone saved it")


def read_image(path: str | Path) -> np.ndarray:
    """The pixels of a JPEG or PNG as saved, grey or BGR (uint8 or uint16); :class:`InputError` if unreadable
    or if its header states an image larger than any phone's (:func:`check_size`)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such photo; give a JPEG or PNG the phone took")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    check_size(data, path)
    flags = cv2.IMREAD_ANYCOLOR | cv2.IMREAD_ANYDEPTH | cv2.IMREAD_IGNORE_ORIENTATION
    try:
        image = cv2.imdecode(np.frombuffer(data, np.uint8), flags) if data else None
    except cv2.error:  # OpenCV's own pixel cap (CV_IO_MAX_IMAGE_PIXELS) or a corrupt stream
        image = None
    if image is None:
        raise InputError(f"{path}: not an image OpenCV can read; give the photo as JPEG or PNG")
    if image.dtype not in (np.uint8, np.uint16):
        raise InputError(f"{path}: {image.dtype} pixels; give an 8-bit or 16-bit JPEG or PNG")
    if image.ndim == 3 and image.shape[2] == 4:  # PNG with alpha: the colour is what the camera saw
        image = image[..., :3]
    return image


BAND_ROWS = 256
"""Rows of a colour photo made linear at a time: a 33 MP photo's three float channels would take 400 MB at once."""


def linear_luminance(image: np.ndarray) -> np.ndarray:
    """Linear relative luminance 0..1 (float32, height x width) of an sRGB image (grey or BGR, 8 or 16 bit)."""
    if image.dtype != np.uint8:
        lin = srgb_to_linear(image / 65535.0)
        return lin if lin.ndim == 2 else np.tensordot(lin[..., :3], LUMA_BGR, axes=([2], [0])).astype(np.float32)
    if image.ndim == 2:  # a table: 12 M pixels through pow() would take a second
        return cv2.LUT(image, _table8())
    out = np.empty(image.shape[:2], np.float32)  # by bands of rows: one float32 plane at the end, not three
    weights = LUMA_BGR.reshape(1, 3)
    for r in range(0, image.shape[0], BAND_ROWS):
        out[r:r + BAND_ROWS] = cv2.transform(cv2.LUT(image[r:r + BAND_ROWS], _table8()), weights).reshape(-1, image.shape[1])
    return out


@lru_cache(maxsize=1)
def _table8() -> np.ndarray:
    """Linear light of each 8-bit sRGB code."""
    return srgb_to_linear(np.arange(256) / 255.0)


def _design(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Cubic polynomial terms in x and y (normalised to -1..1): 10 columns."""
    return np.stack([x**i * y**j for i in range(4) for j in range(4 - i)], axis=-1)


def ceiling(luminance: np.ndarray) -> np.ndarray:
    """The smooth lit ceiling under the LEDs (float32, the image's size): a cubic fitted to block medians.

    Blocks brighter than the fit by :data:`CLIP_SIGMA` robust standard deviations, and
    their neighbours (the LED's rim and halo), are left out, and the fit repeated.
    """
    h, w = luminance.shape
    bh, bw = h // BLOCK_PX, w // BLOCK_PX
    if bh < 4 or bw < 4:
        raise InputError(f"a {w} x {h} px photo is too small to tell the ceiling from the LEDs")
    step = 1 if h * w <= LARGE_PX else SAMPLE_STEP
    blocks = luminance[:bh * BLOCK_PX:step, :bw * BLOCK_PX:step].reshape(bh, BLOCK_PX // step, bw, BLOCK_PX // step)
    med = np.median(blocks.transpose(0, 2, 1, 3).reshape(bh, bw, -1), axis=2)
    yy, xx = np.mgrid[0:bh, 0:bw]
    a = _design(2 * (xx + 0.5) / bw - 1, 2 * (yy + 0.5) / bh - 1).reshape(-1, 10)
    z = med.ravel()
    keep = z <= np.median(z) + CLIP_SIGMA * max(_mad(z), 1e-4)
    coef = np.zeros(10)
    for _ in range(4):
        coef = np.linalg.lstsq(a[keep], z[keep], rcond=None)[0]
        resid = z - a @ coef
        lit = (resid > CLIP_SIGMA * max(_mad(resid[keep]), 1e-4)).reshape(bh, bw).astype(np.uint8)
        keep = ~cv2.dilate(lit, np.ones((5, 5), np.uint8)).astype(bool).ravel()
        if keep.sum() < 20:
            raise InputError("the photo is nearly all bright: no ceiling to see the LEDs against; "
                             "photograph the ceiling with a shorter exposure")
    small = (a @ coef).reshape(bh, bw).astype(np.float32)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)


def _mad(v: np.ndarray) -> float:
    """Robust standard deviation (1.4826 x the median absolute deviation)."""
    return 1.4826 * float(np.median(np.abs(v - np.median(v))))


def receiver_frame(lum: np.ndarray) -> np.ndarray:
    """The photo as a twin frame (uint8) from its :func:`linear_luminance` (float32, reused in place): linear
    luminance above the fitted ceiling, 0..1 to 0..255 DN on :data:`DARK_DN`; where an LED saturated, its plateau
    is flat at ``255 (1 - ceiling)``."""
    lum -= ceiling(lum)
    lum *= 255.0
    lum += DARK_DN
    return np.clip(np.rint(lum, out=lum), 0, 255, out=lum).astype(np.uint8)


STRIPE_RATIO = 1.3
"""The LEDs' light must change this many times more across rows than across columns (or the reverse) for their
stripes to count as running along the rows (columns): a round LED's rim changes it alike both ways."""


def stripe_axis(frame: np.ndarray) -> str | None:
    """``rows`` if the LEDs' stripes in ``frame`` (uint8, :func:`receiver_frame`) run along its rows (the light
    changes from row to row, as the rolling shutter draws them), ``columns`` if along its columns (a turned photo),
    None if neither shows (no LED, or steady ones). Summed over every pixel lit 25 DN above the ceiling."""
    flat = frame.ravel()
    width = frame.shape[1]
    lit = np.flatnonzero(flat > np.median(frame[::7, ::7]) + 25)
    lit = lit[(lit % width < width - 1) & (lit < flat.size - width)]
    if len(lit) < 40:
        return None
    here = flat[lit].astype(np.int16)
    across_rows = float(np.abs(flat[lit + width] - here).sum())
    across_columns = float(np.abs(flat[lit + 1] - here).sum())
    if across_rows > STRIPE_RATIO * across_columns:
        return "rows"
    return "columns" if across_columns > STRIPE_RATIO * across_rows else None


@dataclass(frozen=True)
class Photo:
    """A photo as the receiver reads it: its frame in the sensor's orientation (:func:`receiver_frame`), the
    quarter turns (``np.rot90``'s sense) that brought the file's pixels there, and a note saying so ("" if none)."""

    frame: np.ndarray
    turns: int = 0
    note: str = ""


def load_photo(path: str | Path, camera: Camera) -> Photo:
    """A photo taken with ``camera``, as :func:`receiver_frame`, turned back to the sensor's rows if the phone turned
    its pixels (a portrait photo: the file is the camera's height wide; a square one, its stripes along columns);
    the turn, or stripes that run across the way the size says (:func:`stripe_axis`), said in the photo's note
    (the size decides: a lamp of another shape may sway the stripes' measure). :class:`InputError` if unreadable
    or of another size."""
    image = read_image(path)
    h, w = image.shape[:2]
    size = (camera.width_px, camera.height_px)
    named = f"camera {camera.name!r}" if camera.name else "the camera"
    if (w, h) != size and (h, w) != size:
        raise InputError(f"{path}: the photo is {w} x {h} px but {named} takes {size[0]} x {size[1]} px; give the "
                         "camera that took it (--camera NAME or YAML) and the photo as the phone saved it, not resized "
                         "or cropped")
    lum = linear_luminance(image)
    del image  # a colour 33 MP photo: 100 MB freed before the ceiling's full-size plane is made
    frame = receiver_frame(lum)
    del lum
    axis = stripe_axis(frame)
    if (w, h) == size and (axis != "columns" or w != h):
        return Photo(frame, 0, "" if axis != "columns" else (
            f"the LEDs' stripes seem to run along the photo's columns, but a {w} x {h} px photo of {named} has its "
            "rolling shutter's rows as rows: read as saved; if no LED reads, give the camera file as the sensor "
            f"reads ({h} x {w} px), or check that the photo was not turned and resized"))
    unturned = ("; its LEDs' stripes seem to run along its rows, as they would unturned: if no LED reads, it was "
                "resized or cropped, or taken with another camera") if axis == "rows" and w != h else ""
    along = ", its LEDs' stripes along its columns" if axis == "columns" else ""
    return Photo(np.ascontiguousarray(np.rot90(frame, 1)), 1,
                 f"the photo's pixels are turned a quarter (a portrait photo, {w} x {h} px{along}): read turned back a "
                 "quarter counter-clockwise to the sensor's rows; ellipses and blob boxes are in the sensor's pixels"
                 f"{unturned}")


def read_photo(path: str | Path, camera: Camera, modulation: FrameFormat | ToneFormat) -> tuple[list[PhotoBlob], str]:
    """Every LED blob of the photo at ``path`` taken with ``camera``, decoded with the site's ``modulation`` (a
    frame or a tone site), and the photo's note (:class:`Photo`).

    A tone site's LEDs are read as small LEDs in a glow (:mod:`planner.photo.small`). A frame site's are read as
    the receiver twin reads them (:mod:`planner.photo.decode`), and as small LEDs where that reads fewer than
    three IDs; a turned photo's rows may run either way in time, so it is read turned the other way too while
    fewer than three read (a tone's frequency is the same either way). The exposure and blur of a phone photo are
    not known; the twin's defaults (:data:`~planner.defaults.SENSOR_EXPOSURE_S`,
    :data:`~planner.defaults.SENSOR_BLUR_PX`) set the stripe closing and the fit's slack, which have margin.
    """
    photo = load_photo(path, camera)
    if isinstance(modulation, ToneFormat):
        return decode_small_photo(photo.frame, camera, modulation), photo.note
    best: list[PhotoBlob] | None = None
    note = photo.note
    for turned in range(2 if photo.turns else 1):
        frame = np.ascontiguousarray(np.rot90(photo.frame, 2)) if turned else photo.frame
        for decode in (_frame_blobs, decode_small_photo):
            blobs = decode(frame, camera, modulation)
            if best is None or _read(blobs) > _read(best):
                best, note = blobs, photo.note.replace("counter-clockwise", "clockwise") if turned else photo.note
            if _read(best) >= 3:
                return best, note
    assert best is not None
    return best, note


def _read(blobs: list[PhotoBlob]) -> int:
    return sum(b.id is not None for b in blobs)


def _frame_blobs(frame: np.ndarray, camera: Camera, modulation: FrameFormat | ToneFormat) -> list[PhotoBlob]:
    assert isinstance(modulation, FrameFormat)
    return decode_photo(frame, camera, modulation, blur_px=SENSOR_BLUR_PX, exposure_s=SENSOR_EXPOSURE_S)


def site_format(plan: PlanFile) -> FrameFormat | ToneFormat:
    """What the receiver knows of the plan's site: its tones (a tone site) or its frames."""
    if any(e.tone_hz is not None for e in plan.luminaires):
        return ToneFormat.from_plan(plan)
    return FrameFormat.from_plan(plan)


def photo_blobs(path: str | Path, camera: Camera, modulation: FrameFormat | ToneFormat) -> list[PhotoBlob]:
    """:func:`read_photo`'s blobs."""
    return read_photo(path, camera, modulation)[0]
