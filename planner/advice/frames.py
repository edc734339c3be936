"""Does a changed site's frame still fit? The planner's own timing check, run on an advice candidate.

A change that brings more poses a window can still stop the plan of the changed site at "no chip
rate fits": a wider lens or higher luminaires make every LED image smaller, and the gravity
receiver's two-LED windows reach farther LEDs (docs/advice.md). For a candidate site this module
takes the smallest LED image of a window as the planner does (the windows of its receiver mode,
:meth:`planner.receivers.base.Receiver.window_leds`, on the same seeded timing sample a plan of
that site would draw: the advice passes the windows it found for the coverage) and asks the planner's
check (:func:`planner.modulation.timing.frame_fits`: one image, else over video frames,
:mod:`planner.modulation.multiframe`) whether a frame fits with the plan's driver limit and the
candidate camera's row time; if not, the slowest driver (whole kHz) at which it would.

The changed site's IDs are designed only when it is planned, so the frame is taken as long as
the longest it can be: unique IDs (``ceil(log2 N)`` bits, a scheme every site has) plus the plan's
check bits. A frame that fits so fits the shorter frames of any scheme the plan picks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from planner.camera.model import Poses, disc_image_rows
from planner.codes.assignment import bits_for
from planner.codes.check_bits import check_code
from planner.modulation.frame import frame_chips, line_code
from planner.modulation.multiframe import MAX_RATE_HZ
from planner.modulation.timing import ROWS_PER_CHIP, frame_fits, timing_per_m2
from planner.receivers.modes import receiver_for
from planner.verify.windows import sample_poses, working_area

if TYPE_CHECKING:
    from planner.advice.changes import Site

Windows = tuple[Poses, np.ndarray, np.ndarray]
"""Poses, each pose's window LEDs (P, k) and whether it sees a window (P,)."""


@dataclass(frozen=True)
class FrameLimits:
    """What a plan's frames must fit, from its options: line code, check distance, the drivers' fastest
    rate [Hz], the receiver's video rate [1/s] and frames, the drivers' timer clock [Hz]."""

    line_code: str
    check_distance: int
    driver_max_hz: float
    video_fps: float
    max_video_frames: int
    mcu_clock_hz: float | None


@dataclass(frozen=True)
class FrameFit:
    """How a candidate site's longest frame fits its smallest LED image: ``fits`` with the plan's driver;
    else ``needs_driver_hz``, the slowest driver (whole kHz) that fits, or None when none does."""

    frame_chips: int
    smallest_image_rows: float  # 0: no sampled pose sees a window
    fits: bool
    needs_driver_hz: float | None = None

    def summary(self) -> dict:
        return {"frame_chips": self.frame_chips, "smallest_image_rows": round(self.smallest_image_rows, 3),
                "fits": self.fits, "needs_driver_hz": self.needs_driver_hz}



def frame_text(frame: dict, driver_max_hz: float | None) -> str:
    """What the advice table says of a change whose coverage reaches the goal but whose frames (``FrameFit.summary``)
    do not fit the plan's drivers (``driver_max_hz``)."""
    if frame["needs_driver_hz"] is not None:
        these = f" (these: {driver_max_hz / 1e3:g} kHz)" if driver_max_hz else ""
        return f"its {frame['frame_chips']}-chip frames need drivers at >= {frame['needs_driver_hz'] / 1e3:g} kHz{these}"
    return (f"no chip rate fits its {frame['frame_chips']}-chip frames in its smallest LED image "
            f"({frame['smallest_image_rows']:.1f} rows) at any driver rate: not recommended")


def longest_word_bits(luminaires: int, limits: FrameLimits) -> int:
    """Bits of a word of unique IDs for ``luminaires`` with the plan's check bits (the longest frame's)."""
    return check_code(luminaires, bits_for(luminaires), limits.check_distance).word_bits


def smallest_image_rows(site: Site, seed: int, windows: Windows | None = None) -> float:
    """Rows of the smallest LED image of a window of ``site``'s receiver, as a plan of it with ``seed`` finds
    them; 0 when no sampled pose sees a window. ``windows``: the timing sample's poses, each pose's window LEDs
    and whether it sees one (:meth:`planner.receivers.base.Receiver.window_leds`), when the caller has them."""
    if windows is None:
        area = working_area(site.xyz[:, :2], site.outline)
        poses = sample_poses(area, site.camera, timing_per_m2(area), seed)  # the prefix a plan of the site times on
        windows = (poses, *receiver_for(site.receiver).window_leds(poses, site.xyz, site.radii, site.camera))
    poses, leds, covered = windows
    if not covered.any():
        return 0.0
    sub, t = poses.subset(np.flatnonzero(covered)), leds[covered]
    return float(disc_image_rows(sub.position, sub.rotation, site.xyz[t], site.radii[t], site.camera).min())


def frame_fit(site: Site, limits: FrameLimits, seed: int, windows: Windows | None = None) -> FrameFit:
    """Whether ``site``'s longest frame fits its smallest LED image (:func:`planner.modulation.timing.modulate`), with the
    plan's driver limit, else with which driver (bisection on whole kHz: a faster driver only adds rates);
    ``windows`` as :func:`smallest_image_rows` takes them."""
    words, code = longest_word_bits(len(site.xyz), limits), line_code(limits.line_code)
    chips = len(frame_chips(0, words, code))
    rows = smallest_image_rows(site, seed, windows)
    if rows <= 0:
        return FrameFit(chips, rows, False)

    def fits(driver_hz: float) -> bool:
        return frame_fits(chips, code.max_run, rows, site.camera.row_time_s, driver_max_hz=driver_hz,
                          video_fps=limits.video_fps, max_video_frames=limits.max_video_frames,
                          mcu_clock_hz=limits.mcu_clock_hz)

    if fits(limits.driver_max_hz):
        return FrameFit(chips, rows, True)
    resolution_hz = 1.0 / (ROWS_PER_CHIP * site.camera.row_time_s)  # a faster driver than this adds nothing
    lo, hi = math.floor(limits.driver_max_hz / 1e3), math.floor(min(resolution_hz, MAX_RATE_HZ) / 1e3)
    if hi <= lo or not fits(hi * 1e3):
        return FrameFit(chips, rows, False)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if fits(mid * 1e3) else (mid, hi)
    return FrameFit(chips, rows, False, hi * 1e3)
