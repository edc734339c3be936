"""The rolling shutter's row time from a photo of an LED blinking a square wave at a known rate.

Row ``v`` is exposed ``v * row_time_s`` after row 0, so a luminaire blinking at ``blink_hz``
draws stripes ``1 / (blink_hz * row_time_s)`` rows apart: ``row_time_s = 1 / (blink_hz *
period_rows)``. The stripes are read from the brightest LED image's central columns (the
band where it is widest), between the first and the last row lit across that band: each
row's mean, thresholded halfway between its dark and lit levels; every crossing is placed to
a fraction of a row (linear interpolation), and one least-squares line through the rising and
the falling edges (one offset each, one shared period) gives the period. The duty cycle need
not be one half; the exposure must be shorter than a period (else the stripes wash out).
"""

from __future__ import annotations

from dataclasses import dataclass

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
    img = np.asarray(gray, float)
    background, peak = float(np.median(img)), float(np.percentile(img, 99.9))
    if peak - background < MIN_CONTRAST_DN:
        raise InputError(f"{where}: no bright LED in the photo (brightest {peak:.0f}, background {background:.0f} "
                         "of 255); photograph the blinking luminaire from close by, at a short exposure")
    lit = img > background + 0.5 * (peak - background)
    counts = lit.sum(axis=0)
    c0, c1 = _run_around(counts >= 0.9 * counts.max(), int(np.argmax(counts)))  # the brightest LED's middle
    # From the first to the last row lit across the whole band: in between the LED (convex) spans the band, so
    # every row's mean is a stripe's level, not a share of the LED's rim.
    rows_full = np.flatnonzero(lit[:, c0:c1 + 1].all(axis=1))
    r0, r1 = int(rows_full.min()), int(rows_full.max())
    profile = img[r0:r1 + 1, c0:c1 + 1].mean(axis=1)
    lo, hi = np.percentile(profile, [5, 95])
    if hi - lo < MIN_CONTRAST_DN:
        raise InputError(f"{where}: the LED image (rows {r0}-{r1}) shows no stripes; shorten the exposure below one "
                         "blink period, or check that the luminaire blinks")
    level = (lo + hi) / 2
    above = profile > level
    k = np.flatnonzero(above[1:] != above[:-1])  # a crossing between rows k and k + 1
    where_rows = r0 + k + (level - profile[k]) / (profile[k + 1] - profile[k])
    rising = above[k + 1]
    return _fit(where_rows, rising, (r0, r1), (c0, c1), where)


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
                         "period; blink slower, or photograph the luminaire from closer")
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
