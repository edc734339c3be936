"""The rolling shutter's row time from a photo of an LED blinking a square wave at a known rate.

Row ``v`` is exposed ``v * row_time_s`` after row 0, so a luminaire blinking at ``blink_hz``
draws stripes ``1 / (blink_hz * row_time_s)`` rows apart: ``row_time_s = 1 / (blink_hz *
period_rows)``. The brightest LED image is found first (the brightest spot once single hot pixels
are eroded away, and the lit parts around it), so the LED may be a small spot in a whole photo.
The stripes are then read in one of two ways:

* **the core band** (a large LED image): the LED's central columns, between the first and the last
  row lit across that band, where every row's mean is a stripe's level; thresholded halfway between
  the dark and lit levels.
* **the glow** (a small LED, whose saturated core spans less than two stripe periods): the sum over
  every column the LED's light reaches, core and glow, divided by its own envelope (interpolated,
  in log scale, through the lit rows), thresholded at one half. Light spread by the optics is
  sampled by the rolling shutter like the core's, so the glow carries the same stripes; only the
  edges between two lit stripes are used, since the outer ones fade into the glow.

Each crossing is placed to a fraction of a row (linear interpolation), and one least-squares line
through the rising and the falling edges (one offset each, one shared period) gives the period.
The duty cycle need not be one half; the exposure must be shorter than a period (else the stripes
wash out).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from planner.errors import InputError

MIN_CONTRAST_DN = 20.0
"""Least difference between the stripes' lit and dark rows [DN] for stripes to be read."""
MAX_EDGE_RESIDUAL = 0.2
"""Largest distance of an edge from the fitted stripe lattice, as a share of the period: beyond, the stripes are
not a steady square wave."""


@dataclass(frozen=True)
class Stripes:
    """What :func:`measure_stripes` read: the period [rows], the edges used, the LED image's rows and columns."""

    period_rows: float
    edges: int
    rows: tuple[int, int]
    columns: tuple[int, int]
    residual_rows: float  # RMS distance of the edges from the fitted lattice

    def row_time_s(self, blink_hz: float) -> float:
        """``1 / (blink_hz * period_rows)`` [s]."""
        return 1.0 / (blink_hz * self.period_rows)


def measure_stripes(gray: np.ndarray, where: str = "the photo") -> Stripes:
    """The stripe period of the brightest LED image in the grey photo (height, width); :class:`InputError` (naming
    ``where``) if there is no LED, no contrast or fewer than one whole period."""
    img = np.asarray(gray)
    (r0, r1), (c0, c1), noise = _brightest_led(img, where)
    crop = img[r0:r1, c0:c1].astype(float)
    try:
        stripes = _core_band(crop, r0, c0, where)
        if stripes.edges >= 2 * MIN_EDGES:
            return stripes
    except InputError:
        pass
    return _glow(crop, r0, c0, noise, where)


MIN_EDGES = 2
"""Fewest edges of each kind (rising, falling) the core band must show before the glow is read instead."""


def _brightest_led(img: np.ndarray, where: str) -> tuple[tuple[int, int], tuple[int, int], float]:
    """Rows and columns (half-open) around the brightest LED image, its stripes and its glow, and the photo's
    noise [DN]; :class:`InputError` if nothing stands out of the background."""
    sample = img[::4, ::4].astype(float)
    background = float(np.median(sample))
    noise = max(1.4826 * float(np.median(np.abs(sample - background))), 0.5)
    spot = cv2.erode(img, np.ones((3, 3), np.uint8)) if img.dtype == np.uint8 else img  # no single hot pixel
    v, u = np.unravel_index(int(np.argmax(spot)), spot.shape)
    peak = float(spot[v, u])
    if peak - background < MIN_CONTRAST_DN:
        raise InputError(f"{where}: no bright LED in the photo (brightest {peak:.0f}, background {background:.0f} "
                         "of 255); photograph the blinking luminaire from close by, at a short exposure")
    mask = (img > background + max(0.5 * MIN_CONTRAST_DN, 6 * noise)).astype(np.uint8)
    _, label, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    x0, y0, w, h = (int(s) for s in stats[label[v, u], :4])
    box = [x0, y0, x0 + w, y0 + h]
    parts = stats[1:, :4]
    for _ in range(32):  # the LED's other stripes: lit parts over the same columns, within a box's size
        reach = max(box[2] - box[0], box[3] - box[1])
        near = ((parts[:, 0] < box[2]) & (parts[:, 0] + parts[:, 2] > box[0])
                & (parts[:, 1] < box[3] + reach) & (parts[:, 1] + parts[:, 3] > box[1] - reach))
        grown = [min(box[0], int(parts[near, 0].min())), min(box[1], int(parts[near, 1].min())),
                 max(box[2], int((parts[near, 0] + parts[near, 2]).max())),
                 max(box[3], int((parts[near, 1] + parts[near, 3]).max()))]
        if grown == box:
            break
        box = grown
    margin = max(box[2] - box[0], box[3] - box[1])  # the LED then holds at most a third of the crop's rows
    return ((max(box[1] - margin, 0), min(box[3] + margin, img.shape[0])),
            (max(box[0] - margin, 0), min(box[2] + margin, img.shape[1])), noise)


def _core_band(img: np.ndarray, r_off: int, c_off: int, where: str) -> Stripes:
    """The stripes of the LED's central columns, between the first and the last row lit across them."""
    background, peak = float(np.median(img)), float(img.max())
    lit = img > background + 0.5 * (peak - background)
    counts = lit.sum(axis=0)
    c0, c1 = _run_around(counts >= 0.9 * counts.max(), int(np.argmax(counts)))  # the brightest LED's middle
    # From the first to the last row lit across the whole band: in between the LED (convex) spans the band, so
    # every row's mean is a stripe's level, not a share of the LED's rim.
    rows_full = np.flatnonzero(lit[:, c0:c1 + 1].all(axis=1))
    r0, r1 = int(rows_full.min()), int(rows_full.max())
    profile = img[r0:r1 + 1, c0:c1 + 1].mean(axis=1)
    lo, hi = np.percentile(profile, [5, 95])
    rows = (r_off + r0, r_off + r1)
    if hi - lo < MIN_CONTRAST_DN:
        raise _no_stripes(where, rows)
    level = (lo + hi) / 2
    above = profile > level
    k = np.flatnonzero(above[1:] != above[:-1])  # a crossing between rows k and k + 1
    where_rows = rows[0] + k + (level - profile[k]) / (profile[k + 1] - profile[k])
    return _fit(where_rows, above[k + 1], rows, (c_off + c0, c_off + c1), where)


def _glow(img: np.ndarray, r_off: int, c_off: int, noise: float, where: str) -> Stripes:
    """The stripes of every column the LED's light reaches, over their own envelope (a small LED in its glow)."""
    img = img - np.median(img, axis=0)  # each column's background (a lit ceiling may shade across the photo)
    cols = img.max(axis=0) > max(0.5 * MIN_CONTRAST_DN, 6 * noise)
    p = img[:, cols].sum(axis=1)
    lit = p > 6 * noise * np.sqrt(cols.sum())
    seen = np.flatnonzero(lit)
    rows = (r_off + int(seen.min()), r_off + int(seen.max())) if len(seen) else (r_off, r_off + len(p) - 1)
    runs = np.split(np.arange(len(p)), np.flatnonzero(lit[1:] != lit[:-1]) + 1)
    lit_runs = [r for r in runs if lit[r[0]]]
    if len(lit_runs) < 2:
        raise _no_stripes(where, rows)
    solid = np.concatenate([r[1:-1] if len(r) > 2 else r[[np.argmax(p[r])]] for r in lit_runs])  # not partly lit
    envelope = np.exp(np.interp(np.arange(len(p)), solid, np.log(np.maximum(p[solid], 1e-9))))
    level = p / envelope
    above = level > 0.5
    k = np.arange(lit_runs[0][-1], lit_runs[-1][0])  # between the first and the last lit stripe only
    k = k[above[k] != above[k + 1]]
    where_rows = r_off + k + (0.5 - level[k]) / (level[k + 1] - level[k])
    span = np.flatnonzero(cols)
    return _fit(where_rows, above[k + 1], rows, (c_off + int(span.min()), c_off + int(span.max())), where)


def _no_stripes(where: str, rows: tuple[int, int]) -> InputError:
    return InputError(f"{where}: the LED image (rows {rows[0]}-{rows[1]}) shows no stripes; shorten the exposure "
                      "below one blink period, or check that the luminaire blinks")


def _run_around(mask: np.ndarray, k: int) -> tuple[int, int]:
    """The run of true entries of ``mask`` that holds index ``k``."""
    lo, hi = k, k
    while lo > 0 and mask[lo - 1]:
        lo -= 1
    while hi < len(mask) - 1 and mask[hi + 1]:
        hi += 1
    return lo, hi


def _fit(edges: np.ndarray, rising: np.ndarray, rows: tuple[int, int], columns: tuple[int, int],
         where: str) -> Stripes:
    """One period and two offsets (rising, falling) fitted to the edge rows by least squares."""
    same = [np.sort(edges[rising == r]) for r in (True, False)]
    steps = np.concatenate([np.diff(e) for e in same])
    if len(steps) == 0:
        raise InputError(f"{where}: the LED image (rows {rows[0]}-{rows[1]}) holds less than one whole stripe "
                         "period between two lit stripes; photograph the luminaire from closer, or blink it slower if "
                         "its stripes are wider than its image (faster if a small LED shows under three)")
    guess = float(np.median(steps))
    a, b = [], []
    for j, e in enumerate(same):
        if len(e) == 0:
            continue
        n = np.rint((e - e[0]) / guess)
        for idx, pos in zip(n, e):
            a.append([idx, 1.0 if j == 0 else 0.0, 1.0 if j == 1 else 0.0])
            b.append(pos)
    design, target = np.array(a), np.array(b)
    design = design[:, np.any(design != 0, axis=0)]  # a kind of edge that is absent has no offset
    coef, *_ = np.linalg.lstsq(design, target, rcond=None)
    residual = target - design @ coef
    period = float(coef[0])
    rms = float(np.sqrt(np.mean(residual**2)))
    if period <= 0 or np.abs(residual).max() > MAX_EDGE_RESIDUAL * period:
        raise InputError(f"{where}: the stripes are not evenly spaced (edges up to {np.abs(residual).max():.1f} rows "
                         f"off a {period:.1f}-row period); the luminaire must blink a steady square wave")
    return Stripes(period, len(edges), rows, columns, rms)
