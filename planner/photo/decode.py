"""Every LED blob of a photo: its ellipse, stripe period and ID, or why no ID was read.

The stages are the receiver twin's (:mod:`planner.decode.image`: blobs from the
threshold closed across the stripes, sub-pixel rim points where each lit row crosses
half its plateau, the ellipse fitted to them, the inner chords' levels thresholded to
chips, the preamble found, the word read), run on :func:`planner.photo.read.receiver_frame`.
What a photo adds:

- **Saturation and blooming.** A saturated LED's rows are a flat plateau, so its rim
  is still where a row crosses half of it; the halo that blooming spreads round a
  bright LED lies below that, so it widens the thresholded blob but not the rim. The
  check that the ellipse accounts for the blob's pixels looks at pixels above a
  quarter of the blob's plateau (:data:`FIT_SHARE`), which the halo does not reach.
- **Distortion.** With a distorted lens the rim points are moved to where an ideal
  pinhole of the same intrinsics puts them (:meth:`Camera.ideal_pixels`) and a second
  ellipse is fitted there: a disc's image through a pinhole is exactly a conic, so
  positioning gets an exact ellipse and the ideal camera.
- **Clipping bias.** A saturated LED's lit stripes read longer and its dark ones
  shorter; the shift is found and taken out before runs become chips
  (:func:`chips_from_runs`).
- **A stripe period.** The median length [rows] of one lit plus the next dark run,
  for foreign LEDs too: a PWM-dimmed lamp's period, or two to four chips of ours. A
  lamp whose dark stripes are longer than this site's frames make falls apart into
  one blob per stripe; they are joined again (:func:`group_stripes`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.camera.ellipse import Ellipse, fit_ellipse
from planner.camera.model import Camera
from planner.decode.image import (
    BORDER_PX,
    MIN_BLOB_PX,
    FrameFormat,
    fits_blob,
    rim_points,
    row_levels,
    segment,
)
from planner.decode.tones import ToneReading
from planner.errors import InputError, PositioningError
from planner.modulation.frame import decode_stream

FIT_SHARE = 0.25
"""Share of a blob's plateau (above the ceiling) a pixel must reach to count in the fit check; blooming's halo stays below."""

BLOOM_PX = 6.0
"""How far [px] blooming may widen a blob: added to the fit check's slack and to the blob's margin."""

NO_ELLIPSE = "too few lit rows for an ellipse"
MISFIT = "blob and fitted ellipse disagree"


@dataclass(frozen=True)
class PhotoBlob:
    """One LED image found in a photo and how far decoding got.

    ``ellipse`` is in the photo's pixels; ``ideal`` is the same rim seen through an ideal
    pinhole (equal to ``ellipse`` without distortion), what positioning uses.
    """

    bbox: tuple[int, int, int, int]  # x, y, width, height [px]
    ellipse: Ellipse | None
    ideal: Ellipse | None
    stripe_period_rows: float | None
    chips: str
    id: int | None
    problem: str  # "" when the ID was read
    tone: ToneReading | None = None  # a tone site's LED: its tone as read
    tone_probability: float = 0.0  # the matched tone's probability among the plan's (match_tone)
    saturated: bool = False  # a clipped core: the ellipse's size reads large by the blur (centres hold)


def inner_runs(levels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The runs of a row-level sequence thresholded halfway (as :func:`planner.decode.image.chips_from_levels`): each whole run's
    value (lit or dark) and length [rows], the partial runs at both ends dropped; empty without contrast."""
    levels = levels[np.isfinite(levels)]
    if len(levels) < 4:
        return np.zeros(0, bool), np.zeros(0, int)
    lo, hi = np.percentile(levels, [5, 95])
    if hi - lo < 8.0:  # no contrast: no stripes to read
        return np.zeros(0, bool), np.zeros(0, int)
    bits = levels > (lo + hi) / 2
    edges = np.flatnonzero(np.diff(bits.astype(np.int8))) + 1
    runs = np.diff(np.concatenate([[0], edges, [len(bits)]]))
    return bits[edges[:-1]], runs[1:-1]


def stripe_period_rows(runs: np.ndarray) -> float | None:
    """Median length [rows] of one run and the next (a lit and a dark stripe): None with fewer than two runs."""
    return float(np.median(runs[:-1] + runs[1:])) if len(runs) >= 2 else None


def chips_from_runs(values: np.ndarray, runs: np.ndarray, rows_per_chip: float) -> str:
    """The chips whole runs show, the clipping bias removed.

    A saturated LED's lit rows clip, so the halfway threshold of the clipped levels lies
    low on its true edges: every lit run reads some rows too long and every dark run as
    many too short. The shift ``d`` [rows] that brings the runs, lit ones ``- d`` and dark
    ones ``+ d``, closest to whole chips is taken out before each run becomes
    ``round(rows / rows_per_chip)`` chips. ``d`` is sought within one chip either way,
    no run left shorter than half a chip (which tells ``d`` from ``d`` minus a chip), the
    smaller shift preferred among equals; unclipped stripes give ``d`` near 0.
    """
    if not len(runs):
        return ""
    sign = np.where(values, -1.0, 1.0)
    shifts = np.linspace(-1.0, 1.0, 201) * rows_per_chip
    chips = (runs[None] + shifts[:, None] * sign[None]) / rows_per_chip
    score = np.sum((chips - np.rint(chips)) ** 2, axis=1) + 1e-3 * np.abs(shifts) / rows_per_chip
    score[chips.min(axis=1) < 0.5] = np.inf
    best = shifts[int(np.argmin(score))] if np.isfinite(score).any() else 0.0
    counts = np.maximum(1, np.rint((runs + best * sign) / rows_per_chip)).astype(int)
    return "".join(("1" if v else "0") * int(c) for v, c in zip(values, counts))


def decode_photo(frame: np.ndarray, camera: Camera, modulation: FrameFormat, *, blur_px: float,
                 exposure_s: float) -> list[PhotoBlob]:
    """Every LED blob of ``frame`` (uint8, from :func:`~planner.photo.read.receiver_frame`), largest first."""
    level, threshold, rows_per_chip, gap, count, labels, stats = segment(frame, camera, modulation, blur_px, exposure_s)
    blobs = []
    for k in sorted(range(1, count), key=lambda k: -int(stats[k][4])):
        if stats[k][4] >= MIN_BLOB_PX:
            blobs.append(_decode_blob(frame, labels, k, tuple(int(v) for v in stats[k][:4]), level, threshold,
                                      camera, modulation, rows_per_chip, blur_px))
    return group_stripes(blobs, gap)


def group_stripes(blobs: list[PhotoBlob], gap_rows: float) -> list[PhotoBlob]:
    """Blobs that are stripes of one light, joined into one blob each.

    A foreign light whose dark stripes are longer than ``gap_rows`` (what this site's
    frames make) falls apart into one blob per lit stripe: blobs with no ID that are
    flat (under a quarter as tall as wide; an LED's image is round or oval) or have no
    ellipse of their own are such fragments. Two fragments belong
    together when their columns overlap by half the narrower and the rows between
    them are fewer than half the wider's width (neighbouring LEDs lie further apart). The
    joined blob's stripe period is the median spacing of its stripes [rows].
    """
    loose = [k for k, b in enumerate(blobs)
             if b.id is None and (b.problem in (NO_ELLIPSE, MISFIT) or b.bbox[3] < 0.25 * b.bbox[2])]
    group = {k: k for k in loose}

    def root(k: int) -> int:
        while group[k] != k:
            k = group[k]
        return k

    for i in loose:
        for j in loose:
            (xa, ya, wa, ha), (xb, yb, wb, hb) = blobs[i].bbox, blobs[j].bbox
            overlap = min(xa + wa, xb + wb) - max(xa, xb)
            between = max(ya, yb) - min(ya + ha, yb + hb)
            if i < j and overlap >= 0.5 * min(wa, wb) and between <= 0.5 * max(wa, wb):
                group[root(j)] = root(i)
    members: dict[int, list[int]] = {}
    for k in loose:
        members.setdefault(root(k), []).append(k)
    joined = {}
    for head, ks in members.items():
        if len(ks) < 2:
            continue
        boxes = np.array([blobs[k].bbox for k in ks])
        x0, y0 = boxes[:, :2].min(axis=0)
        x1, y1 = (boxes[:, :2] + boxes[:, 2:]).max(axis=0)
        centres = np.sort(boxes[:, 1] + boxes[:, 3] / 2)
        dark = boxes[np.argsort(boxes[:, 1])]
        longest = int(np.max(dark[1:, 1] - (dark[:-1, 1] + dark[:-1, 3])))
        joined[head] = PhotoBlob((int(x0), int(y0), int(x1 - x0), int(y1 - y0)), None, None,
                                 float(np.median(np.diff(centres))), "", None,
                                 f"{len(ks)} stripes with dark gaps up to {longest} rows, longer than this site's "
                                 f"frames make ({gap_rows:.0f}): a foreign light (dimmed by PWM?)")
    dropped = {k for head, ks in members.items() if head in joined for k in ks}
    return [joined.get(k, b) for k, b in enumerate(blobs) if k not in dropped or k in joined]


def _decode_blob(frame: np.ndarray, labels: np.ndarray, k: int, bbox: tuple, level: float, threshold: float,
                 camera: Camera, modulation: FrameFormat, rows_per_chip: float, blur_px: float) -> PhotoBlob:
    height, width = frame.shape
    x, y, w, h = bbox
    pad = 4 + math.ceil(BLOOM_PX)
    x0, y0 = max(0, x - pad), max(0, y - pad)
    roi = frame[y0:min(height, y + h + pad), x0:min(width, x + w + pad)]
    own = (labels[y0:y0 + roi.shape[0], x0:x0 + roi.shape[1]] == k) & (roi > threshold)
    pts = rim_points(roi, own, threshold, level) + (x0, y0)
    try:
        ellipse = fit_ellipse(pts)
        ideal = ellipse
        if camera.distorted:  # where the lens's map folds (far outside its field) ideal_pixels is NaN
            moved = camera.ideal_pixels(pts)
            ideal = fit_ellipse(moved[np.isfinite(moved).all(axis=1)])
    except PositioningError:
        return PhotoBlob(bbox, None, None, None, "", None, NO_ELLIPSE)
    plateau = float(np.percentile(roi[own], 90))
    strong = own & (roi > level + FIT_SHARE * (plateau - level))
    touching = x == 0 or y == 0 or x + w >= width or y + h >= height
    half = np.sqrt(np.diag(ellipse.shape @ ellipse.shape))
    inside = np.all(ellipse.centre - half >= -BORDER_PX) and np.all(
        ellipse.centre + half <= (width - 1 + BORDER_PX, height - 1 + BORDER_PX))
    if not inside or not fits_blob(strong, ellipse, x0, y0, slack=4.0 + 3.0 * blur_px + BLOOM_PX):
        problem = "cut by the image border" if touching or not inside else MISFIT
        return PhotoBlob(bbox, ellipse, ideal, None, "", None, problem)
    levels = row_levels(roi, ellipse, x0, y0, margin=1.0 + blur_px)
    values, runs = inner_runs(levels)
    period = stripe_period_rows(runs)
    chips = chips_from_runs(values, runs, rows_per_chip)
    if not chips:
        return PhotoBlob(bbox, ellipse, ideal, period, "", None,
                         "no stripes: a steady light (not flashed), or an exposure longer than a chip")
    try:
        word = decode_stream(chips, modulation.word_bits, modulation.code)
    except InputError:
        frame_chips = len(modulation.code.preamble) + modulation.code.payload_chips(modulation.word_bits)
        return PhotoBlob(bbox, ellipse, ideal, period, chips, None,
                         f"stripes, but no whole {modulation.code.name} frame in {len(chips)} chips (a frame is "
                         f"{frame_chips}; expected {rows_per_chip:.1f} rows a chip): a foreign LED, another chip "
                         "rate or row time, or an image too small")
    led_id = modulation.id_of(word)
    return PhotoBlob(bbox, ellipse, ideal, period, chips, led_id, "" if led_id else f"word {word} is not a codeword")
