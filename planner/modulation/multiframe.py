"""Chip rates for reading a frame over ``k`` consecutive video frames, when no LED image holds a whole one.

A phone filming at ``video_fps`` exposes row ``v`` of video frame ``j`` at
``j T_v + v row_time`` (``T_v = 1 / video_fps``). An LED image of ``rows`` rows
shows a *window* of its cyclic frame ``(rows - 2 EDGE_ROWS) row_time rate`` chips
long; from one video frame to the next the window's start advances by

    offset = (T_v rate) mod frame_chips   chips,

so frames ``0 .. k-1`` see windows starting at ``j offset mod frame_chips``. The rate
is chosen so that these ``k`` windows of the smallest LED image cover the whole
cyclic frame, each circular gap between window starts at most the window less one
chip (a chip cut by a window's end is not read) less :data:`OVERLAP_CHIPS` (chips
read twice, which the receiver compares). Coverage does not depend on where the
first window starts, so it holds for every start phase; it assumes the LED stays at
the same rows for the ``k`` frames (a phone held still). docs/modulation.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.defaults import MAX_VIDEO_FRAMES, VIDEO_FPS

MAX_RATE_HZ = 1e6
"""Fastest chip rate considered for reading over video frames [Hz] (LED drivers switch at tens of kHz)."""

MAX_RATES = 50_000
"""Most candidate rates tried: whole hertz, or evenly spaced over a wider range."""

EDGE_ROWS = 2.0
"""Rows at each end of an LED image the receiver does not read (its 1 px margin plus blur)."""

OVERLAP_CHIPS = 1.0
"""Chips each window must share with the next around the cycle, read in both and compared."""


@dataclass(frozen=True)
class VideoFit:
    """A rate at which ``frames`` video frames cover the frame, and by how much."""

    chip_rate_hz: float
    frames: int
    video_fps: float
    offset_chips: float  # advance of the window per video frame
    window_chips: float  # chips the smallest LED image shows
    margin_chips: float  # window - 1 - largest gap: at least OVERLAP_CHIPS
    fps_tolerance: float  # the windows still cover the frame (no overlap left) at video_fps (1 +- this)


def window_chips(rows: float, row_time_s: float, rate_hz: np.ndarray | float) -> np.ndarray:
    """Chips of the cyclic frame an LED image of ``rows`` rows shows, at each rate."""
    return np.maximum(rows - 2 * EDGE_ROWS, 0.0) * row_time_s * np.asarray(rate_hz, float)


def window_starts(rate_hz: np.ndarray | float, frame_len: int, frames: int, video_fps: float) -> np.ndarray:
    """Start of each video frame's window [chips, mod ``frame_len``]: shape (frames, rates)."""
    rate = np.atleast_1d(np.asarray(rate_hz, float))
    j = np.arange(frames)[:, None]
    return np.mod(j * (rate[None, :] / video_fps), frame_len)


def largest_gap(starts: np.ndarray, frame_len: int) -> np.ndarray:
    """Largest circular gap between consecutive window starts [chips], per column of ``starts``."""
    s = np.sort(starts, axis=0)
    wrap = s[:1] + frame_len - s[-1:]
    return np.max(np.concatenate([np.diff(s, axis=0), wrap]), axis=0)


def coverage_margin(rate_hz: np.ndarray | float, frame_len: int, frames: int, rows: float, row_time_s: float,
                    video_fps: float) -> np.ndarray:
    """Window less one chip less the largest gap [chips]; the ``frames`` windows cover the frame with
    ``OVERLAP_CHIPS`` to spare where it is at least that."""
    gap = largest_gap(window_starts(rate_hz, frame_len, frames, video_fps), frame_len)
    return window_chips(rows, row_time_s, rate_hz) - 1.0 - gap


def candidate_rates(low_hz: float, high_hz: float, clock_hz: float | None = None) -> np.ndarray:
    """Rates to try in ``[low_hz, high_hz]``: whole hertz, or with a driver clock the rates ``clock_hz / n`` its
    timer plays exactly (at most :data:`MAX_RATES`, spread evenly)."""
    high_hz = min(high_hz, MAX_RATE_HZ)
    if not math.ceil(low_hz) <= high_hz:  # also NaN
        return np.zeros(0)
    if clock_hz is not None:
        first, last = float(math.ceil(clock_hz / high_hz)), float(math.floor(clock_hz / max(low_hz, 1e-9)))
        ticks = (np.unique(np.round(np.linspace(first, last, MAX_RATES))) if last - first >= MAX_RATES
                 else np.arange(first, last + 1.0))
        return clock_hz / ticks[ticks >= 2][::-1]
    first, last = float(math.ceil(low_hz)), float(math.floor(high_hz))
    return (np.unique(np.round(np.linspace(first, last, MAX_RATES))) if last - first >= MAX_RATES
            else np.arange(first, last + 1.0))


def fit_video(frame_len: int, rows: float, row_time_s: float, low_hz: float, high_hz: float,
              video_fps: float = VIDEO_FPS, max_frames: int = MAX_VIDEO_FRAMES,
              clock_hz: float | None = None) -> VideoFit | None:
    """The fewest video frames (2 .. ``max_frames``) and the rate in ``[low_hz, high_hz]``
    (:func:`candidate_rates`) that covers the frame with the widest margin; None if none does.

    With the drivers' timer clock ``clock_hz`` the rate is one they play exactly: an error of
    ``d`` in the rate moves each video frame's window by ``T_v rate d`` chips (0.07 chips at
    100 ppm, 20 kHz and 30 fps), which the coverage does not allow for."""
    rates = candidate_rates(low_hz, high_hz, clock_hz)
    for frames in range(2, max_frames + 1):
        margin = coverage_margin(rates, frame_len, frames, rows, row_time_s, video_fps)
        if len(rates) and margin.max() >= OVERLAP_CHIPS:
            best = int(np.argmax(margin))
            rate = float(rates[best])
            return VideoFit(rate, frames, video_fps, float(np.mod(rate / video_fps, frame_len)),
                            float(window_chips(rows, row_time_s, rate)), float(margin[best]),
                            fps_tolerance(rate, frame_len, frames, rows, row_time_s, video_fps))
    return None


def fps_tolerance(rate_hz: float, frame_len: int, frames: int, rows: float, row_time_s: float,
                  video_fps: float) -> float:
    """Largest relative error of the video frame rate (in 1e-4 steps, up to 1 %) at which the windows still
    cover the frame, every chip read at least once."""
    steps = np.arange(1, 101) * 1e-4
    for sign in (1.0, -1.0):  # every step at once: the same arithmetic as coverage_margin's, element by element
        rate = np.full(len(steps), float(rate_hz))
        starts = np.mod(np.arange(frames)[:, None] * (rate / (video_fps * (1 + sign * steps)))[None, :], frame_len)
        ok = window_chips(rows, row_time_s, rate) - 1.0 - largest_gap(starts, frame_len) >= 0
        steps = steps if ok.all() else steps[:int(np.argmin(ok))]
    return float(steps[-1]) if len(steps) else 0.0


def rows_needed(frame_len: int, row_time_s: float, low_hz: float, high_hz: float, video_fps: float = VIDEO_FPS,
                max_frames: int = MAX_VIDEO_FRAMES, clock_hz: float | None = None) -> float | None:
    """Fewest rows of the smallest LED image (to 0.1 row) that ``max_frames`` frames cover; None if even 4,000
    rows do not (coverage only grows with the rows, so bisection finds the edge)."""
    def fits(rows: float) -> bool:
        return fit_video(frame_len, rows, row_time_s, low_hz, high_hz, video_fps, max_frames, clock_hz) is not None

    lo, hi = 2 * EDGE_ROWS, 4000.0
    if not fits(hi):
        return None
    while hi - lo > 0.1:
        mid = (lo + hi) / 2
        lo, hi = (lo, mid) if fits(mid) else (mid, hi)
    return math.ceil(hi * 10) / 10
