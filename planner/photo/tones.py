"""Every LED of a tone site's photo: its tone, the plan's ID it matches, and its ellipse (docs/tones.md, issue 37).

A tone site's LEDs are often small: a saturated core of tens of pixels in a dimmer glow, 30-120 rows tall,
1.5-5 stripe periods. So, on :func:`planner.photo.read.receiver_frame`:

1. **LEDs and tones**: :func:`planner.decode.tones.find_tone_leds` (the glow's pixels, stripes closed) and
   :func:`~planner.decode.tones.read_tone` (every row of the LED, glow included, fitted with three harmonics,
   with the fit's standard error); matched to the plan's tones by likelihood
   (:func:`~planner.decode.tones.match_tone`), not by rounding.
2. **Ellipse**: the core's rim, where each lit row crosses half its level (:func:`planner.decode.image.rim_points`,
   the frame sites' rim), fitted with an ellipse. Kept only where it agrees with the whole blob: its centre
   within the glow's box and no larger than the glow, else the blob says so (:data:`MISFIT`).
3. **Saturation**: a clipped core's rim lies outside the disc's by about the blur (the clip moves the half-level
   crossing out), so its ellipse reads a few per cent large while its centre holds to a fraction of a pixel
   (measured, docs/tones.md). The blob is marked ``saturated``; the locator then takes the position from the
   centres where four or more LEDs allow it (:func:`planner.positioning.locate.refine_on_centres`).
"""

from __future__ import annotations

import numpy as np

from planner.camera.ellipse import fit_ellipse
from planner.camera.model import Camera
from planner.decode.image import rim_points
from planner.decode.tones import ToneFormat, find_tone_leds, match_tone, read_tone
from planner.errors import PositioningError
from planner.photo.decode import MISFIT, NO_ELLIPSE, PhotoBlob

CLIPPED_PX = 10
"""A core with this many pixels at the LED's highest level is clipped (noise and JPEG rarely repeat a maximum)."""


def decode_tone_photo(frame: np.ndarray, camera: Camera, tones: ToneFormat) -> list[PhotoBlob]:
    """Every whole LED of ``frame`` (uint8, :func:`~planner.photo.read.receiver_frame`), largest first, with its tone
    and the plan's ID it matches (or why none)."""
    dark = float(np.median(frame[::7, ::7]))
    plan_hz = np.array(tones.tones_hz)
    blobs = []
    for mask, box in find_tone_leds(frame, camera.row_time_s, tones.lowest_hz):
        u0, v0, u1, v1 = box
        bbox = (u0, v0, u1 - u0 + 1, v1 - v0 + 1)
        reading = read_tone(frame, mask, box, camera.row_time_s, dark)
        period = 1.0 / (reading.tone_hz * camera.row_time_s) if reading.tone_hz > 0 else None
        roi = frame[v0:v1 + 1, u0:u1 + 1]
        top = int(roi[mask].max())
        saturated = int(np.count_nonzero(roi[mask] == top)) >= CLIPPED_PX
        threshold = dark + 0.5 * (float(np.percentile(roi[mask], 99)) - dark)
        try:
            ellipse = fit_ellipse(rim_points(roi, mask & (roi > threshold), threshold, dark) + (u0, v0))
        except PositioningError:
            blobs.append(PhotoBlob(bbox, None, None, period, "", None, NO_ELLIPSE, reading, 0.0, saturated))
            continue
        half = np.sqrt(np.diag(ellipse.shape @ ellipse.shape))
        inside = u0 <= ellipse.cx <= u1 and v0 <= ellipse.cy <= v1 and np.all(2 * half <= np.array(bbox[2:]) + 2)
        ideal = ellipse
        if camera.distorted:
            pts = rim_points(roi, mask & (roi > threshold), threshold, dark) + (u0, v0)
            moved = camera.ideal_pixels(pts)
            ideal = fit_ellipse(moved[np.isfinite(moved).all(axis=1)])
        match = match_tone(reading, plan_hz)
        if not inside:
            problem = MISFIT
        elif match.index is None:
            shown = ", ".join(f"{t:g}" for t in plan_hz)
            problem = (f"a tone of {reading.tone_hz:.0f} +- {reading.sigma_hz:.0f} Hz: none of the plan's ({shown} Hz) "
                       f"within {match.z:.0f} sigma; a foreign light, or check the camera's row time")
        else:
            problem = ""
        led_id = tones.ids[match.index] if match.index is not None and not problem else None
        blobs.append(PhotoBlob(bbox, ellipse, ideal, period, "", led_id, problem, reading, match.probability,
                               saturated))
    return sorted(blobs, key=lambda b: -b.bbox[2] * b.bbox[3])
