"""Decode a camera frame as a receiver app does: LED blobs, ellipses, stripes, chips, IDs.

1. **Blobs**: threshold above the dark ceiling, close the stripes' dark gaps
   vertically (the longest dark run a frame allows, in rows), and keep connected
   components that do not touch the image border.
2. **Ellipse**: each lit row of a blob gives two rim points, where the row's
   brightness crosses half its plateau (sub-pixel, by interpolation). Rows are
   lit or dark as a whole, so these points lie on the LED's rim whatever the
   stripes; the ellipse is fitted to them (:func:`planner.camera.ellipse.fit_ellipse`).
   A fitted ellipse reaching outside the image, or leaving lit pixels of its own
   rows outside it (a sliver of an LED cut by the border fits a wrong small ellipse),
   is dropped; a blob merely touching the border, or merged with another LED's
   stripes below or above it, is kept if its ellipse fits.
3. **Chips**: the mean of each row's inner chord gives the LED's drive over time
   (row ``v`` at ``v * row_time_s``); thresholded halfway between its dark and lit
   levels, each run of rows becomes ``round(rows / rows_per_chip)`` chips; the
   partial runs at both ends are dropped.
4. **ID**: :func:`planner.modulation.frame.decode_stream` finds the preamble and reads the
   word; with check bits, the word is looked up among the codewords.

The receiver knows the site's modulation (line code, word length, chip rate)
and its own camera's intrinsics and row time, as an app set up for the site does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import cv2
import numpy as np

from planner.camera.ellipse import Ellipse, fit_ellipse
from planner.camera.model import Camera
from planner.errors import InputError, PositioningError
from planner.modulation.frame import LineCode, decode_stream, line_code

if TYPE_CHECKING:
    from planner.plan.file import PlanFile

MIN_BLOB_PX = 40
"""Smallest blob kept [px]: smaller ones are noise or LEDs too small to read."""

THRESHOLD_SIGMA = 10.0
"""A pixel is lit if it exceeds the ceiling's level by this many noise standard deviations (at least 16 DN)."""

BORDER_PX = 1.0
"""A fitted ellipse may reach this far past the outermost pixel centres [px] and count as whole: half a
pixel to the sensor's edge and half a pixel beyond it, whose sliver is lost in the fit's noise."""

CHORD_SHARE = 0.6
"""Share of each row's chord (centred) whose pixels are averaged into the row's drive level."""


@dataclass(frozen=True)
class FrameFormat:
    """What the receiver knows of the site's frames: line code, word bits, chip rate, codewords."""

    code: LineCode
    word_bits: int
    chip_rate_hz: float
    codewords: tuple[int, ...] | None = None  # word -> ID is index + 1; None: ID = word + 1

    @classmethod
    def from_plan(cls, plan: PlanFile) -> FrameFormat:
        from planner.codes.check_bits import check_code

        mod, code = plan.modulation, plan.code
        if mod is None:
            raise InputError("the plan has no 'modulation'; make it again with this vlp-plan")
        words = None
        if code.check_distance > 1:
            check = check_code(code.max_id, code.bits, code.check_distance)
            words = tuple(int(w) for w in check.codewords)
        return cls(line_code(mod.line_code), code.word_bits, mod.chip_rate_hz, words)

    def id_of(self, word: int) -> int | None:
        if self.codewords is None:
            return word + 1
        return self.codewords.index(word) + 1 if word in self.codewords else None


@dataclass(frozen=True)
class Blob:
    """One LED image found in the frame, and how far decoding it got."""

    bbox: tuple[int, int, int, int]  # x, y, width, height [px]
    ellipse: Ellipse | None
    chips: str
    id: int | None
    problem: str  # "" when the ID was read


def _background(image: np.ndarray) -> tuple[float, float]:
    """The ceiling's level and noise [DN], from a subsample (median and MAD)."""
    sample = image[::7, ::7].astype(np.float32)
    level = float(np.median(sample))
    return level, max(1.0, 1.4826 * float(np.median(np.abs(sample - level))))


def rim_points(roi: np.ndarray, own: np.ndarray, threshold: float, level: float) -> np.ndarray:
    """Sub-pixel rim points (x, y) of a blob's lit rows, in ROI coordinates (all rows at once)."""
    rows = np.flatnonzero(own.any(axis=1))
    width = roi.shape[1]
    own_rows, vals = own[rows], roi[rows].astype(np.float32)
    first = own_rows.argmax(axis=1)
    last = width - 1 - own_rows[:, ::-1].argmax(axis=1)
    col = np.arange(width)
    lit = (col >= first[:, None]) & (col <= last[:, None]) & (vals > threshold)
    n = lit.sum(axis=1)
    keep = n >= 3
    rows, vals, first, last, lit, n = rows[keep], vals[keep], first[keep], last[keep], lit[keep], n[keep]
    ordered = np.sort(np.where(lit, vals, np.inf), axis=1)  # each row's lit values first, ascending
    at = np.arange(len(rows))
    median = (ordered[at, (n - 1) // 2] + ordered[at, n // 2]) / np.float32(2)  # the middle value, or the two middle
    half = (level + 0.5 * (median.astype(float) - level)).astype(np.float32)
    s0, s1 = np.maximum(0, first - 4), np.minimum(width, last + 5)  # each row's segment [s0, s1)
    above = (col >= s0[:, None]) & (col < s1[:, None]) & (vals > half[:, None])
    a = above.argmax(axis=1)
    b = width - 1 - above[:, ::-1].argmax(axis=1)
    # at least two crossings, both inside the segment (else the edge is outside the ROI)
    ok = (above.sum(axis=1) >= 2) & (a > s0) & (b < s1 - 1)
    rows, vals, half, a, b = rows[ok], vals[ok], half[ok], a[ok], b[ok]
    at = np.arange(len(rows))
    below_a, at_a, at_b, below_b = vals[at, a - 1], vals[at, a], vals[at, b], vals[at, b + 1]
    left = (a - 1) + (half - below_a) / (at_a - below_a)  # float32 fractions, float64 positions
    right = b + (at_b - half) / (at_b - below_b)
    # where the segment starts at the ROI's column 0 the positions have always been float32 sums: kept bit for bit
    s32 = s0[ok] == 0
    left[s32], right[s32] = left[s32].astype(np.float32), right[s32].astype(np.float32)
    return np.stack([np.column_stack([left, rows]), np.column_stack([right, rows])], axis=1).reshape(-1, 2)


def chord_rows(height: int, ellipse: Ellipse, y0: int, margin: float) -> np.ndarray:
    """Rows of a region of interest starting at image row ``y0`` (``height`` rows) that the ellipse spans
    at least ``margin`` rows inside its rim: the rows :func:`row_levels` reads, in its order."""
    cy = ellipse.cy - y0
    half_h = math.sqrt(max((ellipse.shape @ ellipse.shape)[1, 1], 0.0))
    return np.arange(max(0, math.ceil(cy - half_h + margin)), min(height, math.floor(cy + half_h - margin) + 1))


def row_levels(roi: np.ndarray, ellipse: Ellipse, x0: int, y0: int, margin: float) -> np.ndarray:
    """Mean of the inner chord of every row of :func:`chord_rows` (NaN where the chord is too short)."""
    q = np.linalg.inv(ellipse.shape @ ellipse.shape)
    cx, cy = ellipse.cx - x0, ellipse.cy - y0
    rows = chord_rows(roi.shape[0], ellipse, y0, margin)
    dy = rows - cy
    # q00 dx^2 + 2 q01 dx dy + q11 dy^2 = 1
    a, b, c = q[0, 0], 2 * q[0, 1] * dy, q[1, 1] * dy * dy - 1
    disc = b * b - 4 * a * c
    root = np.sqrt(np.where(disc > 0, disc, 0.0))
    lo, hi = (-b - root) / (2 * a) + cx, (-b + root) / (2 * a) + cx
    mid, half = (lo + hi) / 2, CHORD_SHARE * (hi - lo) / 2
    c0 = np.maximum(0, np.ceil(mid - half)).astype(int)
    c1 = np.minimum(roi.shape[1] - 1, np.floor(mid + half)).astype(int)
    ok = (disc > 0) & (c1 - c0 >= 1)
    sums = np.concatenate([np.zeros((roi.shape[0], 1), np.int64), np.cumsum(roi, axis=1, dtype=np.int64)], axis=1)
    r, c0, c1 = rows[ok], c0[ok], c1[ok]
    levels = np.full(len(rows), np.nan)
    levels[ok] = (sums[r, c1 + 1] - sums[r, c0]) / (c1 - c0 + 1)
    return levels


def fits_blob(own: np.ndarray, ellipse: Ellipse, x0: int, y0: int, slack: float) -> bool:
    """Whether the fitted ellipse accounts for the blob's lit pixels in its own rows.

    In every row of the ellipse grown by ``slack`` [px] (blur, sub-pixel edges), the lit
    pixels must lie within the grown ellipse's chord, and together they must nearly span
    the ellipse's horizontal extent. A sliver of an LED cut by the border fits a small wrong
    ellipse whose rows hold lit pixels out to the border: refused. Rows beyond the
    grown ellipse belong to another LED merged into the blob by the stripe closing and
    are left to it.
    """
    grown = ellipse.shape + slack * np.eye(2)
    q = np.linalg.inv(grown @ grown)
    cx, cy = ellipse.cx - x0, ellipse.cy - y0
    half_y = math.sqrt((grown @ grown)[1, 1])
    rows = np.arange(max(0, math.ceil(cy - half_y)), min(own.shape[0], math.floor(cy + half_y) + 1))
    lit = own[rows].any(axis=1)
    if not lit.any():
        return False
    rows, lit_rows = rows[lit], own[rows[lit]]
    first = lit_rows.argmax(axis=1)
    last = lit_rows.shape[1] - 1 - lit_rows[:, ::-1].argmax(axis=1)
    dy = rows - cy
    a, b, c = q[0, 0], 2 * q[0, 1] * dy, q[1, 1] * dy * dy - 1
    root = np.sqrt(np.maximum(b * b - 4 * a * c, 0.0))
    lo, hi = (-b - root) / (2 * a) + cx, (-b + root) / (2 * a) + cx
    if np.any(first < lo - 1) or np.any(last > hi + 1):
        return False
    width = 2 * math.sqrt((ellipse.shape @ ellipse.shape)[0, 0])  # the ellipse's horizontal extent
    return float(last.max() - first.min()) >= 0.9 * width - slack


def chips_from_levels(levels: np.ndarray, rows_per_chip: float) -> str:
    """The chips a row-level sequence shows: threshold halfway, runs to chip counts, partial end runs dropped."""
    levels = levels[np.isfinite(levels)]
    if len(levels) < 4:
        return ""
    lo, hi = np.percentile(levels, [5, 95])
    if hi - lo < 8.0:  # no contrast: no stripes to read
        return ""
    bits = levels > (lo + hi) / 2
    edges = np.flatnonzero(np.diff(bits.astype(np.int8))) + 1
    runs = np.diff(np.concatenate([[0], edges, [len(bits)]]))
    values = bits[np.concatenate([[0], edges])]
    out = []
    for value, run in zip(values[1:-1], runs[1:-1]):
        out.append(("1" if value else "0") * max(1, int(round(run / rows_per_chip))))
    return "".join(out)


class Segments(NamedTuple):
    """Step 1's blobs: the ceiling's level and the lit threshold [DN], rows per chip, the longest dark gap
    closed [rows], and OpenCV's connected components (how many, label image, stats rows x, y, w, h, area)."""

    level: float
    threshold: float
    rows_per_chip: float
    gap_rows: float
    components: int
    labels: np.ndarray
    stats: np.ndarray


def segment(image: np.ndarray, camera: Camera, modulation: FrameFormat, blur_px: float, exposure_s: float) -> Segments:
    """Step 1: threshold ``image`` above its dark ceiling and close the stripes' dark gaps vertically."""
    level, noise = _background(image)
    threshold = level + max(THRESHOLD_SIGMA * noise, 16.0)
    rows_per_chip = 1.0 / (modulation.chip_rate_hz * camera.row_time_s)
    gap = (modulation.code.max_run + 1) * rows_per_chip + exposure_s / camera.row_time_s + 4 * blur_px + 2
    mask = (image > threshold).astype(np.uint8)
    kernel = np.ones((2 * math.ceil(gap / 2) + 1, 1), np.uint8)
    # Outside the image is dark: without a zero border, closing would stretch blobs near the edge to it.
    closed = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, kernel, borderType=cv2.BORDER_CONSTANT, borderValue=0)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(closed, connectivity=8)
    return Segments(level, threshold, rows_per_chip, gap, count, labels, stats)


def decode_frame(image: np.ndarray, camera: Camera, modulation: FrameFormat, *,
                 blur_px: float = 1.0, exposure_s: float = 0.0) -> list[Blob]:
    """Every LED blob in ``image`` (uint8, height x width) with its ellipse and, where readable, its ID."""
    level, threshold, rows_per_chip, _, count, labels, stats = segment(image, camera, modulation, blur_px, exposure_s)
    height, width = image.shape
    blobs = []
    for k in range(1, count):
        x, y, w, h, area = (int(v) for v in stats[k])
        if area < MIN_BLOB_PX:
            continue
        bbox = (x, y, w, h)
        pad = 4
        x0, y0 = max(0, x - pad), max(0, y - pad)
        x1, y1 = min(width, x + w + pad), min(height, y + h + pad)
        roi = image[y0:y1, x0:x1]
        own = (labels[y0:y1, x0:x1] == k) & (roi > threshold)
        pts = rim_points(roi, own, threshold, level)
        try:
            ellipse = fit_ellipse(pts + (x0, y0))
        except PositioningError:
            blobs.append(Blob(bbox, None, "", None, "too few lit rows for an ellipse"))
            continue
        half = np.sqrt(np.diag(ellipse.shape @ ellipse.shape))
        if not fits_blob(own, ellipse, x0, y0, slack=4.0 + 3.0 * blur_px):
            touching = x == 0 or y == 0 or x + w >= width or y + h >= height
            blobs.append(Blob(bbox, ellipse, "", None, "cut by the image border" if touching
                              else "blob and fitted ellipse disagree"))
            continue
        if np.any(ellipse.centre - half < -BORDER_PX) or np.any(ellipse.centre + half > (width - 1 + BORDER_PX,
                                                                                           height - 1 + BORDER_PX)):
            blobs.append(Blob(bbox, ellipse, "", None, "cut by the image border"))
            continue
        chips = chips_from_levels(row_levels(roi, ellipse, x0, y0, margin=1.0 + blur_px), rows_per_chip)
        try:
            word = decode_stream(chips, modulation.word_bits, modulation.code)
        except InputError:
            blobs.append(Blob(bbox, ellipse, chips, None, "no whole frame read"))
            continue
        led_id = modulation.id_of(word)
        blobs.append(Blob(bbox, ellipse, chips, led_id, "" if led_id else f"word {word} is not a codeword"))
    return blobs


def read_blobs(blobs: list[Blob], camera: Camera) -> list[int]:
    """Indices of the blobs whose ID was read, nearest the image centre first (the paper's order)."""
    read = [k for k, b in enumerate(blobs) if b.id is not None]
    return sorted(read, key=lambda k: _off_centre(blobs[k], camera))


def read_ellipse(blob: Blob) -> tuple[int, Ellipse]:
    """A read blob's ID and ellipse (an ID is only read from a blob with an ellipse)."""
    assert blob.id is not None and blob.ellipse is not None
    return blob.id, blob.ellipse


def _off_centre(blob: Blob, camera: Camera) -> float:
    """Distance of the blob's centre from the principal point in ideal pixels (undistorted: by ray angle)."""
    ellipse = read_ellipse(blob)[1]
    if camera.distorted:
        u, v = camera.ideal_pixels(ellipse.centre)
        return math.hypot(u - camera.cx_px, v - camera.cy_px)
    return math.hypot(ellipse.cx - camera.cx_px, ellipse.cy - camera.cy_px)


def srgb_to_linear(encoded: np.ndarray) -> np.ndarray:
    """Linear light 0..1 of sRGB-encoded values 0..1 (IEC 61966-2-1's inverse transfer function)."""
    v = np.asarray(encoded, np.float32)
    return np.where(v <= 0.04045, v / 12.92, np.power((v + 0.055) / 1.055, 2.4)).astype(np.float32)
