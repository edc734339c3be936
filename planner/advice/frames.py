"""Does a changed site's frame still fit? The planner's own timing check, run on an advice candidate.

A change that brings more poses a window can still stop the plan of the changed site at "no chip
rate fits": a wider lens or higher luminaires make every LED image smaller, and the gravity
receiver's two-LED windows reach farther LEDs (docs/advice.md). For a candidate site this module
takes the smallest LED image of a window as the planner does (:func:`planner.modulation.timing.
smallest_image_rows` of its receiver mode (:mod:`planner.receivers.modes`) on the same
seeded timing sample a plan of that site would draw) and asks :func:`planner.modulation.timing.modulate`,
the planner's check (one image, else over video frames, :mod:`planner.modulation.multiframe`), whether a frame
fits with the plan's driver limit and the candidate camera's row time; if not, the slowest driver
(whole kHz) at which it would.

The changed site's IDs are designed only when it is planned, so the frame is taken as long as
the longest it can be: unique IDs (``ceil(log2 N)`` bits, a scheme every site has) plus the plan's
check bits. A frame that fits so fits the shorter frames of any scheme the plan picks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from planner.codes.assignment import bits_for
from planner.codes.check_bits import check_code
from planner.errors import PlanningError
from planner.modulation.frame import frame_chips, line_code
from planner.modulation.multiframe import MAX_RATE_HZ
from planner.modulation.timing import ROWS_PER_CHIP, modulate, timing_per_m2
from planner.receivers.modes import receiver_for
from planner.verify.windows import PoseSample, find_windows, sample_poses, working_area

if TYPE_CHECKING:
    from planner.advice.changes import Site


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


def smallest_image_rows(site: Site, seed: int) -> float:
    """Rows of the smallest LED image of a window of ``site``'s receiver, as a plan of it with ``seed`` finds
    them; 0 when no sampled pose sees a window."""
    area = working_area(site.xyz[:, :2], site.outline)
    poses = sample_poses(area, site.camera, timing_per_m2(area), seed)  # the prefix a plan of the site times on
    sample = PoseSample(area, poses, find_windows(poses, site.xyz, site.radii, site.camera), seed)
    try:
        return receiver_for(site.receiver).smallest_image_rows(site.xyz, site.radii, site.camera, sample)
    except PlanningError:
        return 0.0


def frame_fit(site: Site, limits: FrameLimits, seed: int) -> FrameFit:
    """Whether ``site``'s longest frame fits its smallest LED image (:func:`planner.modulation.timing.modulate`), with the
    plan's driver limit, else with which driver (bisection on whole kHz: a faster driver only adds rates)."""
    words, code = longest_word_bits(len(site.xyz), limits), line_code(limits.line_code)
    chips = len(frame_chips(0, words, code))
    rows = smallest_image_rows(site, seed)
    if rows <= 0:
        return FrameFit(chips, rows, False)

    def fits(driver_hz: float) -> bool:
        try:
            modulate(np.zeros(1, dtype=np.int64), words, code, rows, site.camera,
                     driver_max_hz=driver_hz, video_fps=limits.video_fps, max_video_frames=limits.max_video_frames,
                     mcu_clock_hz=limits.mcu_clock_hz)
        except PlanningError:
            return False
        return True

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
