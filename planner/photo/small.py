"""Small LEDs in a glow: each LED's ellipse and its tone or frame (docs/tones.md, docs/photos.md; issue 37).

A phone photo's LEDs are often small: a saturated core of tens of pixels in a dimmer glow, 30-120 rows tall,
1.5-5 stripe periods. The frame sites' blob reader (:mod:`planner.photo.decode`) then fits the glow's rim and
thresholds clipped rows; this one, on :func:`planner.photo.read.receiver_frame`:

1. **LEDs**: :func:`planner.decode.tones.find_tone_leds`: the glow's pixels, the dark gaps between stripes
   closed (half the lowest tone's period; a frame site's longest dark run), LEDs cut by the border left out.
2. **Ellipse**: the core's rim, where each lit row crosses half its level (:func:`planner.decode.image.rim_points`
   on the pixels above half the LED's top level: the core, not the glow), fitted with an ellipse. Kept only where
   it agrees with the whole blob: its centre in the glow's box and no wider or taller than the glow
   (:data:`~planner.photo.decode.MISFIT` otherwise).
3. **Saturation**: a clipped core's rim lies outside the disc's by about the blur (the clip moves the half-level
   crossing out), so its ellipse reads a few per cent large while its centre holds to a fraction of a pixel
   (docs/tones.md). The blob is marked ``saturated``; the locator then takes the position from the centres where
   four or more LEDs allow it (:func:`planner.positioning.locate.refine_on_centres`).
4. **Signal**, from the LED's :func:`~planner.decode.tones.row_profile` (every row of the glow, the saturated
   core's columns left out: no row clipped): a tone site's tone (:func:`~planner.decode.tones.read_tone`), matched
   to the plan's by likelihood (:func:`~planner.decode.tones.match_tone`), not by rounding; a frame site's chips
   from the rows' mean light (``profile / width``) as :func:`planner.photo.decode.chips_from_runs` reads them.
"""

from __future__ import annotations

import numpy as np

from planner.camera.ellipse import Ellipse, fit_ellipse
from planner.camera.model import Camera
from planner.decode.image import FrameFormat, rim_points
from planner.decode.tones import ToneFormat, find_tone_leds, match_tone, read_tone, row_profile
from planner.errors import InputError, PositioningError
from planner.modulation.frame import decode_stream
from planner.photo.decode import MISFIT, NO_ELLIPSE, PhotoBlob, chips_from_runs, inner_runs, stripe_period_rows

CLIPPED_PX = 10
"""A core with this many pixels at the LED's highest level is clipped (noise and JPEG rarely repeat a maximum)."""


def _core_ellipse(roi: np.ndarray, mask: np.ndarray, box: tuple[int, int, int, int], dark: float,
                  camera: Camera) -> tuple[Ellipse, Ellipse, bool] | None:
    """The core's ellipse in the photo's pixels and through the ideal pinhole, and whether it agrees with the blob;
    None when too few rows cross (module notes, 2)."""
    u0, v0, u1, v1 = box
    threshold = dark + 0.5 * (float(np.percentile(roi[mask], 99)) - dark)
    pts = rim_points(roi, mask & (roi > threshold), threshold, dark) + (u0, v0)
    try:
        ellipse = ideal = fit_ellipse(pts)
        if camera.distorted:
            moved = camera.ideal_pixels(pts)
            ideal = fit_ellipse(moved[np.isfinite(moved).all(axis=1)])
    except PositioningError:
        return None
    half = np.sqrt(np.diag(ellipse.shape @ ellipse.shape))
    agrees = bool(u0 <= ellipse.cx <= u1 and v0 <= ellipse.cy <= v1 and np.all(2 * half <= [u1 - u0 + 3, v1 - v0 + 3]))
    return ellipse, ideal, agrees


def decode_small_photo(frame: np.ndarray, camera: Camera, fmt: ToneFormat | FrameFormat) -> list[PhotoBlob]:
    """Every whole LED of ``frame`` (uint8, :func:`~planner.photo.read.receiver_frame`), largest first, with its tone
    (a tone site) or chips (a frame site) and the plan's ID they name, or why none."""
    dark = float(np.median(frame[::7, ::7]))
    if isinstance(fmt, ToneFormat):
        lowest_hz, rows_per_chip = fmt.lowest_hz, 0.0
    else:
        rows_per_chip = 1.0 / (fmt.chip_rate_hz * camera.row_time_s)
        lowest_hz = 0.5 / ((fmt.code.max_run + 1) * rows_per_chip * camera.row_time_s)  # closes the longest dark run
    blobs = []
    for mask, box in find_tone_leds(frame, camera.row_time_s, lowest_hz):
        u0, v0, u1, v1 = box
        bbox = (u0, v0, u1 - u0 + 1, v1 - v0 + 1)
        roi = frame[v0:v1 + 1, u0:u1 + 1]
        saturated = int(np.count_nonzero(roi[mask] == roi[mask].max())) >= CLIPPED_PX
        core = _core_ellipse(roi, mask, box, dark, camera)
        if core is None:
            blobs.append(PhotoBlob(bbox, None, None, None, "", None, NO_ELLIPSE, saturated=saturated))
            continue
        ellipse, ideal, agrees = core
        if isinstance(fmt, ToneFormat):
            blobs.append(_tone_blob(frame, mask, box, camera, dark, fmt, bbox, ellipse, ideal, agrees, saturated))
            continue
        profile, width = row_profile(frame, mask, box, dark)
        values, runs = inner_runs(np.where(width > 0, profile / np.maximum(width, 1.0), np.nan))
        chips = chips_from_runs(values, runs, rows_per_chip)
        period = stripe_period_rows(runs)
        try:
            led_id = fmt.id_of(decode_stream(chips, fmt.word_bits, fmt.code)) if agrees else None
            problem = "" if led_id else MISFIT if not agrees else "the word read is not a codeword"
        except InputError:
            led_id, problem = None, (f"stripes, but no whole {fmt.code.name} frame in {len(chips)} chips (expected "
                                     f"{rows_per_chip:.1f} rows a chip)")
        blobs.append(PhotoBlob(bbox, ellipse, ideal, period, chips, led_id, problem, saturated=saturated))
    return sorted(blobs, key=lambda b: -b.bbox[2] * b.bbox[3])


def _tone_blob(frame: np.ndarray, mask: np.ndarray, box: tuple[int, int, int, int], camera: Camera, dark: float,
               fmt: ToneFormat, bbox: tuple[int, int, int, int], ellipse: Ellipse, ideal: Ellipse, agrees: bool,
               saturated: bool) -> PhotoBlob:
    """A tone site's LED: its tone, matched to the plan's (module notes, 4)."""
    reading = read_tone(frame, mask, box, camera.row_time_s, dark)
    period = 1.0 / (reading.tone_hz * camera.row_time_s) if reading.tone_hz > 0 else None
    plan_hz = np.array(fmt.tones_hz)
    match = match_tone(reading, plan_hz)
    if not agrees:
        problem = MISFIT
    elif match.index is None:
        shown = ", ".join(f"{t:g}" for t in plan_hz)
        problem = (f"a tone of {reading.tone_hz:.0f} +- {reading.sigma_hz:.0f} Hz: none of the plan's ({shown} Hz) "
                   f"within {match.z:.0f} sigma; a foreign light, or check the camera's row time")
    else:
        problem = ""
    led_id = fmt.ids[match.index] if match.index is not None and not problem else None
    return PhotoBlob(bbox, ellipse, ideal, period, "", led_id, problem, reading, match.probability, saturated)
