"""Read a tone LED's stripe frequency from a rolling-shutter image, to a fraction of a row (docs/tones.md).

A square wave of ``f`` [Hz] draws stripes of ``f t_r`` cycles per row (``t_r`` the row time). On a small
LED (a saturated core in a glow, 30-60 rows, 1.5-5 periods) a halfway threshold cuts the ramping outer
stripes short and reads 3-38 % too high (issue 37). This reader uses every row the LED lights, glow
included, and no threshold:

1. **LEDs**: pixels above the dark level (the image's median) by ``LIT_DN``: the glow, not the core;
   gaps closed vertically over half the longest period asked for; connected components of at least
   ``MIN_LED_PX`` not cut by the image's border.
2. **Profile**: each row's light above the dark level summed over the LED's pixels in that row, every row
   of the LED: a window wider than the saturated core. Columns clipped over ``SATURATED_ROWS`` rows running
   (a saturated core) and ``CORE_MARGIN_PX`` beside them are left out while other columns remain.
3. **Frequency**: the model ``width(v) (a + sum_h b_h cos(2 pi h c v) + c_h sin(2 pi h c v))``,
   ``width(v)`` the LED's pixels in row ``v`` (its envelope). The periodogram's peak over ``1 / L .. 1 / 4``
   cycles per row (``L`` the profile's rows), one harmonic, on a grid 8 times finer than an FFT's bins,
   with the offset fitted at each trial (a DC term leaks into the first bins of a plain FFT over 1.5
   periods); then refined with ``HARMONICS`` harmonics (clipping and blur make the stripes uneven).
4. **Uncertainty**: the fit's standard error, ``s^2 (J^T J)^-1`` at the optimum (``s^2`` the residual
   variance, ``J`` the model's Jacobian). Rows blurred together are not independent, so it is a lower
   bound (about half the error on saturated chips in a glow, docs/tones.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np
from scipy.optimize import minimize_scalar

if TYPE_CHECKING:
    from planner.plan.file import PlanFile

LIT_DN = 25.0
"""A pixel belongs to an LED (its glow included) this far above the image's dark level [DN]."""

MIN_LED_PX = 40
"""Smallest LED kept [px]."""

SATURATED_DN = 255
"""A pixel at this level [DN of 255] is clipped."""

SATURATED_ROWS = 4
"""A column of the LED clipped over this many rows in a row crosses the saturated core (noise clips single
pixels of a bright LED, a saturated core whole stripes): left out while others are not."""

CORE_MARGIN_PX = 3
"""Columns beside a clipped one left out too: the saturated core's blurred rim."""

HARMONICS = 3
"""Harmonics of the refined fit: a clipped, blurred square wave is no sine."""


@dataclass(frozen=True)
class ToneReading:
    """One LED's tone: ``tone_hz`` and its standard error ``sigma_hz`` [Hz], over ``rows`` rows
    (``periods`` periods), from the LED at ``box`` (u0, v0, u1, v1) [px, inclusive]."""

    tone_hz: float
    sigma_hz: float
    rows: int
    periods: float
    box: tuple[int, int, int, int]


TILE_PX = 16
"""Side of the tiles the LEDs are first found in [px]: the closing and labelling then run on the tiles lit only."""


def find_tone_leds(image: np.ndarray, row_time_s: float, lowest_hz: float) -> list[tuple[np.ndarray, tuple]]:
    """Each LED of ``image`` (8-bit, rows x columns): its closed mask and box (u0, v0, u1, v1); the gaps between
    stripes of tones down to ``lowest_hz`` [Hz] are closed. The lit pixels are grouped by :data:`TILE_PX` tiles
    first (a 33 MP photo's LEDs cover under 1 % of it), each group closed and labelled on its own."""
    height, width = image.shape
    lit = image > float(np.median(image[::7, ::7])) + LIT_DN
    gap = max(1, int(np.ceil(0.5 / (lowest_hz * row_time_s))))  # half the longest period [rows]
    th, tw = -(-height // TILE_PX), -(-width // TILE_PX)
    padded = np.zeros((th * TILE_PX, tw * TILE_PX), bool)
    padded[:height, :width] = lit
    tiles = np.asarray(padded.reshape(th, TILE_PX, tw, TILE_PX).any(axis=(1, 3)), dtype=np.uint8)
    reach = gap // TILE_PX + 1  # tiles a closed gap may bridge
    grown = cv2.dilate(tiles, np.ones((2 * reach + 1, 3), np.uint8))
    groups, group_of, boxes, _ = cv2.connectedComponentsWithStats(grown, connectivity=8)
    out = []
    for g in range(1, groups):
        tx, ty, tww, thh = (int(x) for x in boxes[g, :4])
        r0, c0 = ty * TILE_PX, tx * TILE_PX
        r1, c1 = min((ty + thh) * TILE_PX, height), min((tx + tww) * TILE_PX, width)
        mine = np.repeat(np.repeat(group_of[ty:ty + thh, tx:tx + tww] == g, TILE_PX, 0), TILE_PX, 1)
        part = (lit[r0:r1, c0:c1] & mine[:r1 - r0, :c1 - c0]).astype(np.uint8)
        closed = cv2.morphologyEx(part, cv2.MORPH_CLOSE, np.ones((gap + 1, 1), np.uint8))
        count, labels, stats, _ = cv2.connectedComponentsWithStats(closed, connectivity=8)
        for k in range(1, count):
            u0, v0, w, h, area = (int(x) for x in stats[k])
            u0, v0 = u0 + c0, v0 + r0
            whole = u0 > 0 and v0 > 0 and u0 + w < width and v0 + h < height  # not cut by the border
            if area >= MIN_LED_PX and whole:
                out.append((labels[v0 - r0:v0 - r0 + h, u0 - c0:u0 - c0 + w] == k, (u0, v0, u0 + w - 1, v0 + h - 1)))
    return out


def _design(cycles: float, rows: np.ndarray, width: np.ndarray, harmonics: int) -> np.ndarray:
    """Columns of the model ``width(v) (a + sum_h b_h cos(2 pi h c v) + c_h sin(2 pi h c v))``."""
    phase = 2 * np.pi * cycles * rows
    cols = [np.ones_like(rows)]
    for h in range(1, harmonics + 1):
        cols += [np.cos(h * phase), np.sin(h * phase)]
    return np.column_stack(cols) * width[:, None]


def _rss(cycles: float, rows: np.ndarray, width: np.ndarray, profile: np.ndarray, harmonics: int) -> float:
    x = _design(cycles, rows, width, harmonics)
    coef, *_ = np.linalg.lstsq(x, profile, rcond=None)
    r = profile - x @ coef
    return float(r @ r)


def _solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a^-1 b`` for a stack of small normal matrices (pseudo-inverse where one is singular)."""
    try:
        return np.linalg.solve(a, b[..., None])[..., 0]
    except np.linalg.LinAlgError:
        return np.einsum("gij,gj->gi", np.linalg.pinv(a), b)


def stripe_frequency(profile: np.ndarray, width: np.ndarray) -> tuple[float, float]:
    """The stripes' frequency [cycles per row] of a row profile (each row's light above the dark level, summed over
    the LED's ``width`` pixels in it) and its standard error (module notes, 3-4)."""
    n = len(profile)
    rows = np.arange(n, dtype=float) - (n - 1) / 2
    step = 1.0 / (8 * n)
    grid = np.arange(1.0 / n, 0.25 + step, step)
    phase = 2 * np.pi * grid[:, None] * rows[None, :]  # the one-harmonic periodogram, every trial at once
    x = np.stack([np.ones_like(phase), np.cos(phase), np.sin(phase)], axis=-1) * width[None, :, None]
    xty = np.einsum("gni,n->gi", x, profile)
    coef = _solve(np.einsum("gni,gnj->gij", x, x), xty)
    rss = float(profile @ profile) - np.einsum("gi,gi->g", coef, xty)
    best = float(grid[int(np.argmin(rss))])
    found = minimize_scalar(_rss, bounds=(max(best - 2 * step, 0.5 / n), best + 2 * step), method="bounded",
                            args=(rows, width, profile, HARMONICS), options={"xatol": 1e-7})
    cycles = float(found.x)
    x = _design(cycles, rows, width, HARMONICS)
    coef, *_ = np.linalg.lstsq(x, profile, rcond=None)
    phase = 2 * np.pi * cycles * rows
    slope = width * sum(2 * np.pi * h * rows * (-coef[2 * h - 1] * np.sin(h * phase) + coef[2 * h] * np.cos(h * phase))
                        for h in range(1, HARMONICS + 1))
    jac = np.column_stack([x, slope])
    s2 = float(found.fun) / max(n - jac.shape[1], 1)
    cov = s2 * np.linalg.pinv(jac.T @ jac)
    return cycles, float(np.sqrt(max(cov[-1, -1], 0.0)))


def row_profile(image: np.ndarray, mask: np.ndarray, box: tuple[int, int, int, int],
                dark_dn: float) -> tuple[np.ndarray, np.ndarray]:
    """Each row's light above ``dark_dn`` summed over the LED's closed ``mask`` at ``box`` (:func:`find_tone_leds`),
    every row of the mask, columns through a saturated core left out (module notes, 2); and the pixels summed in
    each row (the envelope). ``profile / width`` is the row's mean light: the LED's drive over its exposure."""
    u0, v0, u1, v1 = box
    pixels = image[v0:v1 + 1, u0:u1 + 1]
    full = pixels >= SATURATED_DN
    run = np.ones(full[SATURATED_ROWS - 1:].shape, dtype=bool)
    for k in range(SATURATED_ROWS):
        run &= full[k:len(full) - SATURATED_ROWS + 1 + k]
    clipped = run.any(axis=0)
    # and the core's blurred rim ("full", cut to the LED's columns: "same" returns the kernel's length on an LED
    # narrower than it)
    near = np.convolve(clipped, np.ones(2 * CORE_MARGIN_PX + 1))[CORE_MARGIN_PX:CORE_MARGIN_PX + pixels.shape[1]] > 0
    clear = ~near  # the glow beside the core
    keep = mask & clear[None, :] if clear.any() else mask
    block = np.clip(pixels.astype(float) - dark_dn, 0.0, None)
    return (block * keep).sum(axis=1), keep.sum(axis=1).astype(float)


def read_tone(image: np.ndarray, mask: np.ndarray, box: tuple[int, int, int, int], row_time_s: float,
              dark_dn: float) -> ToneReading:
    """The tone of the LED at ``box`` whose closed mask is ``mask`` (:func:`find_tone_leds`) [Hz], from its
    :func:`row_profile`."""
    profile, width = row_profile(image, mask, box, dark_dn)
    cycles, sigma = stripe_frequency(profile, width)
    return ToneReading(cycles / row_time_s, sigma / row_time_s, len(profile), cycles * len(profile), box)


def read_tones(image: np.ndarray, row_time_s: float, lowest_hz: float) -> list[ToneReading]:
    """Every LED's tone in ``image``, tones down to ``lowest_hz`` [Hz], top to bottom then left to right."""
    dark = float(np.median(image))
    found = [read_tone(image, mask, box, row_time_s, dark) for mask, box in find_tone_leds(image, row_time_s, lowest_hz)]
    return sorted(found, key=lambda r: (r.box[1], r.box[0]))


@dataclass(frozen=True)
class ToneMatch:
    """The plan tone a reading is matched to (``index``), its probability among the plan's tones, and how many
    standard deviations the reading lies from it (``z``); ``index`` None when no tone lies within ``MAX_Z``."""

    index: int | None
    probability: float
    z: float


MAX_Z = 4.0
"""A reading farther than this many standard deviations from every plan tone is matched to none."""


def match_tone(reading: ToneReading, tones_hz: np.ndarray) -> ToneMatch:
    """The plan tone most likely to have drawn ``reading``, by likelihood, not by rounding to the nearest: each tone
    ``f_k`` reads within ``f_k (1 +- 1/R)`` (docs/tones.md; a uniform spread, sigma ``f_k / (R sqrt 3)``) plus the
    fit's own error, so a tone's spread grows with it; equal priors."""
    tones = np.asarray(tones_hz, dtype=float)
    sigma = np.hypot(reading.sigma_hz, tones / (reading.rows * np.sqrt(3.0)))
    z = (reading.tone_hz - tones) / sigma
    log_like = -0.5 * z**2 - np.log(sigma)
    best = int(np.argmax(log_like))
    weights = np.exp(log_like - log_like[best])
    if abs(z[best]) > MAX_Z:
        return ToneMatch(None, 0.0, float(abs(z[best])))
    return ToneMatch(best, float(weights[best] / weights.sum()), float(abs(z[best])))


@dataclass(frozen=True)
class ToneFormat:
    """What a receiver knows of a tone site: the plan's distinct tones [Hz] and the ID (tone class) each names."""

    tones_hz: tuple[float, ...]
    ids: tuple[int, ...]

    @classmethod
    def from_plan(cls, plan: PlanFile) -> ToneFormat:
        pairs = sorted({(float(e.tone_hz), int(e.id)) for e in plan.luminaires if e.tone_hz is not None})
        return cls(tuple(t for t, _ in pairs), tuple(i for _, i in pairs))

    @property
    def lowest_hz(self) -> float:
        """The lowest tone the LED finder closes stripes for: the plan's lowest less a quarter [Hz]."""
        return 0.75 * min(self.tones_hz)
