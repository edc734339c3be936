"""Modulation tables: every luminaire's frame and the one chip rate the physics allows.

The chip rate must satisfy four limits at once (docs/modulation.md):

- flicker: the slowest on/off cycle of a frame, ``2 max_run`` chips, repeats at least
  at ``flicker_hz`` (200 Hz by default), so ``rate >= 2 max_run flicker_hz``;
- frame fit: the stripes of one LED image span ``rows x row_time`` seconds of the
  rolling shutter; at the farthest working distance (the smallest image of a window
  LED over sampled poses) ``frames_in_image`` whole frames must fit, so
  ``rate >= frames_in_image frame_chips / (rows row_time)``; two are asked for (a
  frame starting anywhere is then read whole), one is accepted with a note;
- resolution: a chip must span at least ``ROWS_PER_CHIP`` rows to be read,
  ``rate <= 1 / (ROWS_PER_CHIP row_time)``;
- driver: ``rate <= driver_max_hz``, what the luminaire's driver can switch.

The rate chosen is the geometric mean of the bounds, to three significant digits.
When not even one frame fits, the frame is read over ``k <= 4`` consecutive video
frames instead (:mod:`planner.modulation.multiframe`): the rate is then the whole-hertz rate
within the other three limits at which ``k`` windows of the smallest image cover it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.camera.model import Camera, disc_image_rows
from planner.defaults import DRIVER_MAX_HZ, FLICKER_HZ, MAX_VIDEO_FRAMES, VIDEO_FPS
from planner.errors import PlanningError
from planner.layout.model import area_m2
from planner.modulation.frame import LineCode, frame_chips
from planner.modulation.multiframe import MAX_RATE_HZ, VideoFit, fit_video, rows_needed
from planner.verify.windows import PoseSample

ROWS_PER_CHIP = 2.0
"""Image rows a chip must span to be read."""

TIMING_POSES = 20_000
"""Poses sampled to find the smallest LED image a window holds."""


@dataclass(frozen=True)
class Timing:
    """The chip rate and the limits it was chosen between (rates in Hz, times in s)."""

    chip_rate_hz: float
    frame_chips: int
    max_run: int
    smallest_image_rows: float
    row_time_s: float
    frames_in_image: int
    flicker_min_hz: float
    frame_fit_min_hz: float
    resolution_max_hz: float
    driver_max_hz: float
    video: VideoFit | None = None  # read over video.frames video frames; None: one LED image holds a frame

    def summary(self) -> dict:
        return {**self._summary(), **(self._video_summary() if self.video else {})}

    def _video_summary(self) -> dict:
        v = self.video
        assert v is not None
        return {"video_frames": v.frames, "video_fps": v.video_fps, "frame_offset_chips": round(v.offset_chips, 6),
                "window_chips": round(v.window_chips, 3), "overlap_margin_chips": round(v.margin_chips, 3),
                "video_fps_tolerance": v.fps_tolerance}

    def _summary(self) -> dict:
        return {"chip_rate_hz": self.chip_rate_hz, "frame_chips": self.frame_chips, "max_run": self.max_run,
                "frame_period_s": round(self.frame_chips / self.chip_rate_hz, 9),
                "frames_in_smallest_image": round(self.smallest_image_rows * self.row_time_s * self.chip_rate_hz
                                                  / self.frame_chips, 3),
                "smallest_image_rows": round(self.smallest_image_rows, 3), "row_time_s": self.row_time_s,
                "limits_hz": {"flicker_min": round(self.flicker_min_hz, 3),
                              "frame_fit_min": round(self.frame_fit_min_hz, 3),
                              "resolution_max": round(self.resolution_max_hz, 3),
                              "driver_max": round(self.driver_max_hz, 3)}}


def timing_per_m2(area: np.ndarray) -> float:
    """Pose density of the chip-timing sample over ``area`` [m]: :data:`TIMING_POSES` in all, at most 400 per m^2."""
    return min(400.0, TIMING_POSES / max(area_m2(area), 1e-6))


def smallest_window_image_rows(xyz: np.ndarray, radii: np.ndarray, camera: Camera, sample: PoseSample
                               ) -> float | None:
    """Rows of the smallest LED image in any window over the timing prefix of ``sample`` (the farthest
    working distance); None if no pose of that prefix sees three whole LEDs (no image to fit a frame into)."""
    poses, win = sample.first(timing_per_m2(sample.area))
    ok = win.covered
    if not ok.any():
        return None
    sub = poses.subset(np.flatnonzero(ok))
    t = win.triples[ok]
    return float(disc_image_rows(sub.position, sub.rotation, xyz[t], radii[t], camera).min())


def _three_digits(rate: float) -> float:
    scale = 10 ** (math.floor(math.log10(rate)) - 2)
    return float(round(rate / scale) * scale)


def choose_timing(frame_len: int, max_run: int, rows: float, row_time_s: float, *,
                  driver_max_hz: float = DRIVER_MAX_HZ, flicker_hz: float = FLICKER_HZ) -> Timing:
    """The chip rate within all four limits, or :class:`PlanningError` naming the numbers that conflict."""
    image_s = rows * row_time_s
    flicker = 2 * max_run * flicker_hz
    resolution = 1.0 / (ROWS_PER_CHIP * row_time_s)
    high = min(resolution, driver_max_hz)
    for frames in (2, 1):
        fit = frames * frame_len / image_s
        low = max(flicker, fit)
        if low <= high:
            rate = min(max(_three_digits(math.sqrt(low * high)), low), high)
            return Timing(rate, frame_len, max_run, rows, row_time_s, frames, flicker, fit, resolution,
                          driver_max_hz)
    fit = frame_len / image_s
    raise PlanningError(
        f"no chip rate fits: a frame of {frame_len} chips must fit in the smallest LED image "
        f"({rows:.1f} rows x {row_time_s * 1e6:g} us = {image_s * 1e3:.3f} ms), so >= {fit:,.0f} Hz, and flicker "
        f"needs >= {flicker:,.0f} Hz; but a chip must span {ROWS_PER_CHIP:g} rows (<= {resolution:,.0f} Hz) and the "
        f"driver switches at most {driver_max_hz:,.0f} Hz; use larger or closer LEDs, a faster driver, a camera "
        "with a longer row time (against the driver's limit; the 2-row limit scales with it), or fewer bits")


@dataclass(frozen=True)
class Modulation:
    """Every luminaire's frame (chips, in layout order) under one line code and chip rate."""

    code: LineCode
    timing: Timing
    frames: list[str]

    def summary(self) -> dict:
        return {"line_code": self.code.name, "preamble": self.code.preamble, **self.timing.summary()}


def frame_fits(frame_len: int, max_run: int, rows: float, row_time_s: float, *, driver_max_hz: float = DRIVER_MAX_HZ,
               flicker_hz: float = FLICKER_HZ, video_fps: float = VIDEO_FPS, max_video_frames: int = MAX_VIDEO_FRAMES,
               mcu_clock_hz: float | None = None) -> bool:
    """Whether :func:`modulate` finds a chip rate for frames of ``frame_len`` chips (the same two checks, without
    working out what would fit when none does)."""
    try:
        choose_timing(frame_len, max_run, rows, row_time_s, driver_max_hz=driver_max_hz, flicker_hz=flicker_hz)
        return True
    except PlanningError:
        if max_video_frames < 2:
            return False
    high = min(1.0 / (ROWS_PER_CHIP * row_time_s), driver_max_hz)
    return fit_video(frame_len, rows, row_time_s, 2 * max_run * flicker_hz, high, video_fps, max_video_frames,
                     mcu_clock_hz) is not None


def choose_video_timing(frame_len: int, max_run: int, rows: float, row_time_s: float, *,
                        driver_max_hz: float = DRIVER_MAX_HZ, flicker_hz: float = FLICKER_HZ,
                        video_fps: float = VIDEO_FPS, max_frames: int = MAX_VIDEO_FRAMES,
                        clock_hz: float | None = None) -> Timing:
    """The chip rate for reading a frame over the fewest video frames (2 .. ``max_frames``), one the drivers'
    timer clock ``clock_hz`` plays exactly when given, or :class:`PlanningError` saying what would fit."""
    flicker = 2 * max_run * flicker_hz
    resolution = 1.0 / (ROWS_PER_CHIP * row_time_s)
    high = min(resolution, driver_max_hz)
    fit = fit_video(frame_len, rows, row_time_s, flicker, high, video_fps, max_frames, clock_hz)
    if fit is None:
        raise PlanningError(_video_misfit(frame_len, rows, row_time_s, flicker, driver_max_hz, video_fps, max_frames,
                                          clock_hz))
    return Timing(fit.chip_rate_hz, frame_len, max_run, rows, row_time_s, 0, flicker, frame_len / (rows * row_time_s),
                  resolution, driver_max_hz, fit)


def _video_misfit(frame_len: int, rows: float, row_time_s: float, flicker_hz: float, driver_max_hz: float,
                  video_fps: float, max_frames: int, clock_hz: float | None) -> str:
    """Why ``max_frames`` video frames do not cover the frame, and the smallest image or row time that would."""
    def high(row_s: float) -> float:
        return min(1.0 / (ROWS_PER_CHIP * row_s), driver_max_hz)

    what = []
    need = rows_needed(frame_len, row_time_s, flicker_hz, high(row_time_s), video_fps, max_frames, clock_hz)
    if need is not None:
        what.append(f"LED images of at least {need:.1f} rows (larger or closer LEDs, or a narrower lens)")
    step_us = max(0.1, round(row_time_s * 1e6 / 100, 1))  # up to three times the row time, 200 tries at most
    slower = next((t for t in np.round(row_time_s * 1e6 + np.arange(1, 201) * step_us, 1) * 1e-6
                   if fit_video(frame_len, rows, float(t), flicker_hz, high(float(t)), video_fps, max_frames,
                                clock_hz)), None)
    if slower is not None:  # coverage is not monotonic in the row time: name one that fits
        what.append(f"a camera with a slower rolling shutter, e.g. a row time of {slower * 1e6:.1f} us")
    resolution = 1.0 / (ROWS_PER_CHIP * row_time_s)
    faster = _fastest_needed(frame_len, rows, row_time_s, flicker_hz, driver_max_hz, resolution, video_fps,
                             max_frames, clock_hz)
    if faster is not None:
        what.append(f"drivers that switch at least {faster:,.0f} Hz (--driver-max-hz {faster:.0f})")
    if max_frames < MAX_VIDEO_FRAMES and fit_video(frame_len, rows, row_time_s, flicker_hz, high(row_time_s),
                                                   video_fps, MAX_VIDEO_FRAMES, clock_hz):
        what.insert(0, f"--max-video-frames {MAX_VIDEO_FRAMES}")
    return (f"nor can it be read over up to {max_frames} video frames at {video_fps:g} fps (the windows of that many "
            f"LED images of {rows:.1f} rows do not cover it); "
            + ("what would: " + ", or ".join(what) if what else "use fewer bits"))


def _fastest_needed(frame_len: int, rows: float, row_time_s: float, flicker_hz: float, driver_max_hz: float,
                    resolution_hz: float, video_fps: float, max_frames: int,
                    clock_hz: float | None) -> float | None:
    """The slowest driver (whole kHz) above ``driver_max_hz`` at which the frames would fit, or None (bisection: a
    faster driver only adds rates)."""
    def fits(khz: int) -> bool:
        return fit_video(frame_len, rows, row_time_s, flicker_hz, min(khz * 1e3, resolution_hz), video_fps,
                         max_frames, clock_hz) is not None

    lo, hi = math.floor(min(driver_max_hz, MAX_RATE_HZ) / 1e3), math.floor(min(resolution_hz, MAX_RATE_HZ) / 1e3)
    if hi <= lo or not fits(hi):
        return None
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if fits(mid) else (mid, hi)
    return hi * 1e3


def modulate(words: np.ndarray, word_bits: int, code: LineCode, rows: float, camera: Camera, *,
             driver_max_hz: float = DRIVER_MAX_HZ, flicker_hz: float = FLICKER_HZ, video_fps: float = VIDEO_FPS,
             max_video_frames: int = MAX_VIDEO_FRAMES, mcu_clock_hz: float | None = None) -> Modulation:
    """Frames for the words the luminaires send (``id - 1`` or codewords, ``word_bits`` bits): read from one
    LED image when a frame fits in it, else over the fewest video frames up to ``max_video_frames``."""
    frames = [frame_chips(int(w), word_bits, code) for w in words]
    try:
        timing = choose_timing(len(frames[0]), code.max_run, rows, camera.row_time_s,
                               driver_max_hz=driver_max_hz, flicker_hz=flicker_hz)
    except PlanningError as exc:
        if max_video_frames < 2:
            raise
        try:
            timing = choose_video_timing(len(frames[0]), code.max_run, rows, camera.row_time_s,
                                         driver_max_hz=driver_max_hz, flicker_hz=flicker_hz, video_fps=video_fps,
                                         max_frames=max_video_frames, clock_hz=mcu_clock_hz)
        except PlanningError as why:
            raise PlanningError(f"{exc}; {why}") from None
    return Modulation(code, timing, frames)
