"""Tone sites: luminaires that broadcast a square-wave tone instead of a frame (docs/tones.md).

What the camera tells apart
---------------------------
An LED image ``R`` rows tall shows the tone's stripes for ``T = R t_r`` seconds of the rolling
shutter (``t_r`` the row time), ``n = f T`` periods. The receiver reads ``f`` from the span of
the stripe pattern: placing each end to half a row puts the span, and so the period
``P = R t_r / n``, within one row in ``R``, so a tone reads within ``f (1 +- 1/R)``. Two tones
``f1 < f2`` are told apart when those intervals do not overlap::

    f2 - f1 > (f1 + f2) / R                                            (tone resolution)

``1 / (R t_r)`` itself, the bin width of a Fourier transform over the image, is the lowest tone
the smallest image shows one whole period of; it is also the spacing at which *two tones in one
image* separate. A receiver reads one tone per LED, so it tells tones apart far more finely than
that bin width (the FFT reader interpolates within the bin: :mod:`planner.decode.tones`).

Limits (those of frames, :mod:`planner.modulation.timing`, for a square wave): at least
``FLICKER_HZ`` (checked when the layout is read); two switchings per period within the driver,
``2 f <= driver_max_hz``; a stripe (half a period) at least ``ROWS_PER_CHIP`` rows,
``f <= 1 / (2 ROWS_PER_CHIP t_r)``.
"""

from __future__ import annotations

import numpy as np

from planner.codes.assignment import Assignment, bits_for, pair_lower_bound
from planner.errors import InputError
from planner.graph import NeighbourGraph
from planner.modulation.timing import ROWS_PER_CHIP


def tones_apart(f1_hz: np.ndarray | float, f2_hz: np.ndarray | float, rows: float) -> np.ndarray:
    """Whether the camera tells tones ``f1`` and ``f2`` [Hz] apart on an LED image ``rows`` tall (module notes)."""
    f1, f2 = np.asarray(f1_hz, dtype=float), np.asarray(f2_hz, dtype=float)
    return np.abs(f2 - f1) > (f1 + f2) / rows


def lowest_readable_hz(rows: float, row_time_s: float) -> float:
    """The lowest tone of which an LED image ``rows`` tall shows one whole period [Hz]: ``1 / (R t_r)``."""
    return 1.0 / (rows * row_time_s)


def highest_tone_hz(row_time_s: float, driver_max_hz: float) -> tuple[float, str]:
    """The highest tone the drivers play and the camera resolves [Hz], and which limit sets it."""
    camera = 1.0 / (2 * ROWS_PER_CHIP * row_time_s)
    driver = driver_max_hz / 2
    if driver <= camera:
        return driver, f"the drivers switch at most {driver_max_hz:,.0f} times a second (--driver-max-hz), twice a period"
    return camera, (f"a stripe (half a period) must span {ROWS_PER_CHIP:g} rows of {row_time_s * 1e6:g} us "
                    "(the camera's row time)")


def check_tone_limits(names: list[str], tones_hz: np.ndarray, row_time_s: float, driver_max_hz: float,
                      where: str) -> None:
    """:class:`InputError` naming the first luminaire whose tone the drivers or the camera cannot serve."""
    high, why = highest_tone_hz(row_time_s, driver_max_hz)
    k = int(np.argmax(tones_hz))
    if tones_hz[k] > high:
        raise InputError(f"{where}: luminaire {names[k]!r}'s tone_hz {tones_hz[k]:g} Hz is above {high:,.0f} Hz: {why}; "
                         "retune it lower, or give the drivers' or the camera's real figures")


def tone_classes(tones_hz: np.ndarray, rows: float) -> np.ndarray:
    """Each luminaire's tone class, 1.. in order of frequency: tones chained by pairs the camera cannot tell apart
    (``rows`` tall images) share a class. Chaining is conservative: 2,000, 2,030 and 2,060 Hz are one class even if
    the outer two read apart, so a clash is never missed."""
    order = np.argsort(tones_hz, kind="stable")
    ordered = tones_hz[order]
    step = np.r_[True, tones_apart(ordered[:-1], ordered[1:], rows)]
    classes = np.empty(len(tones_hz), dtype=np.int64)
    classes[order] = np.cumsum(step)
    return classes


def assign_tones(tones_hz: np.ndarray, rows: float, graph: NeighbourGraph) -> Assignment:
    """The site's tones kept as its IDs: each luminaire's ID is its tone class (:func:`tone_classes`), so the
    verification reads two luminaires of tones the camera cannot tell apart as one ID."""
    ids = tone_classes(tones_hz, rows)
    n = len(ids)
    detail = {"tones": int(len(np.unique(tones_hz))), "tone_classes": int(ids.max()),
              "smallest_image_rows": round(float(rows), 3)}
    return Assignment("tones", ids, np.zeros(n, dtype=np.int64), bits_for(int(ids.max())), bits_for(n),
                      pair_lower_bound(graph)[1], "kept: the layout's tones", detail)
