"""Frames read over k video frames: the chip rate's coverage, the fallback from one image, the plan fields."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import minimal_plan
from planner.camera.model import Camera
from planner.errors import InputError, PlanningError
from planner.modulation.frame import line_code
from planner.modulation.multiframe import (
    EDGE_ROWS,
    OVERLAP_CHIPS,
    candidate_rates,
    coverage_margin,
    fit_video,
    rows_needed,
)
from planner.modulation.timing import choose_timing, choose_video_timing, modulate


def _read_slots(start: float, window: float, frame_len: int, chip_phase: float) -> set[int]:
    """Cyclic chip slots wholly inside a window starting at ``start`` chips (slots at ``chip_phase + n``)."""
    first = int(np.ceil(start - chip_phase))
    last = int(np.floor(start + window - chip_phase)) - 1
    return {n % frame_len for n in range(first, last + 1)}


@settings(max_examples=60, deadline=None)
@given(st.floats(15.0, 60.0), st.sampled_from([12, 16, 18, 20, 24]), st.floats(10e-6, 40e-6),
       st.sampled_from([24.0, 29.97, 30.0, 60.0]), st.floats(0, 1), st.floats(0, 1), st.sampled_from([None, 16e6, 8e6]))
def test_the_k_windows_cover_every_chip_from_any_start(rows, frame_len, row_time_s, fps, start, chip_phase, clock):
    """Brute force: every slot of the cyclic frame lies wholly inside one of the k windows, whatever the
    phase the first video frame starts at, with OVERLAP_CHIPS to spare; with a driver clock, the rate is
    one its timer plays exactly."""
    fit = fit_video(frame_len, rows, row_time_s, 1200.0, min(20_000.0, 1 / (2 * row_time_s)), fps, clock_hz=clock)
    if fit is None:
        return
    assert 2 <= fit.frames <= 4 and 1200 <= fit.chip_rate_hz <= min(20_000, 1 / (2 * row_time_s))
    if clock is not None:
        ticks = clock / fit.chip_rate_hz
        assert abs(ticks - round(ticks)) < 1e-6
    assert fit.margin_chips >= OVERLAP_CHIPS
    window = (rows - 2 * EDGE_ROWS) * row_time_s * fit.chip_rate_hz
    period = fit.chip_rate_hz / fps
    shrunk = window - OVERLAP_CHIPS  # even windows an overlap shorter cover it
    seen: set[int] = set()
    for j in range(fit.frames):
        seen |= _read_slots(start * frame_len + j * period, shrunk, frame_len, chip_phase)
    assert seen == set(range(frame_len))
    fewer = coverage_margin(candidate_rates(1200.0, min(20_000.0, 1 / (2 * row_time_s)), clock), frame_len,
                            fit.frames - 1, rows, row_time_s, fps) if fit.frames > 2 else np.array([-1.0])
    assert fewer.max() < OVERLAP_CHIPS  # the fewest frames: one frame fewer covers at no rate up to it


def test_the_office_frame_is_read_over_video_frames_when_no_image_holds_it():
    # the numbers: the 110 deg lens on the DIALux office, a 16-chip frame in 22.3 rows at 20 us
    with pytest.raises(PlanningError, match="no chip rate fits"):
        choose_timing(16, 3, 22.3, 20e-6)
    t = choose_video_timing(16, 3, 22.3, 20e-6)
    # three windows of 7.2 chips cannot cover 16 (gaps of 16/3 > 7.2 - 1 - 1); four, a quarter frame apart, can
    assert t.video is not None and t.video.frames == 4 and t.chip_rate_hz == 19_800
    s = t.summary()
    assert s["video_frames"] == 4 and s["video_fps"] == 30.0 and s["frame_offset_chips"] == 4.0  # 660 chips mod 16


def test_modulate_stays_single_frame_when_a_frame_fits():
    code = line_code("manchester")
    words = np.arange(16)
    single = modulate(words, 4, code, 200.0, Camera())
    assert single.timing.video is None and "video_frames" not in single.summary()
    assert single.timing == choose_timing(16, 3, 200.0, 20e-6)
    multi = modulate(words, 4, code, 22.3, Camera())
    assert multi.timing.video is not None and multi.summary()["video_frames"] == 4
    with pytest.raises(PlanningError, match="no chip rate fits") as err:
        modulate(words, 4, code, 22.3, Camera(), max_video_frames=1)
    assert "video frames" not in str(err.value)  # one image only: the single-frame refusal


def test_a_misfit_says_what_would_fit_and_that_does():
    with pytest.raises(PlanningError) as err:
        choose_video_timing(16, 3, 12.0, 20e-6)
    text = str(err.value)
    need = rows_needed(16, 20e-6, 1200.0, 20_000.0)
    assert need is not None and f"at least {need:.1f} rows" in text and "4 video frames" in text
    assert fit_video(16, need, 20e-6, 1200.0, 20_000.0) is not None
    assert fit_video(16, need - 0.2, 20e-6, 1200.0, 20_000.0) is None
    # between the two, a slower rolling shutter (longer row time, up to the 2-rows-per-chip limit) helps
    with pytest.raises(PlanningError, match=r"a row time of (\d+\.\d) us") as slow:
        choose_video_timing(16, 3, 18.0, 20e-6)
    row_us = float(slow.value.args[0].split("a row time of ")[1].split(" us")[0])
    assert choose_video_timing(16, 3, 18.0, row_us * 1e-6).video is not None


def test_old_plans_read_as_single_frame_and_a_half_video_section_is_refused():
    lum = [{"name": "A", "id": 1, "frame": {"chips": "01110001", "chip_rate_hz": 4470.0, "line_code": "manchester"}}]
    plan = minimal_plan(lum)
    assert plan.modulation is not None and plan.modulation.video_frames == 1 and plan.modulation.video_fps is None
    mod = {"line_code": "manchester", "preamble": "01110001", "chip_rate_hz": 4470.0, "frame_chips": 8,
           "frame_period_s": 8 / 4470, "frames_in_smallest_image": 0.5, "smallest_image_rows": 20.0,
           "row_time_s": 2e-5, "video_frames": 3}
    with pytest.raises(InputError, match="video_fps is missing"):
        minimal_plan(lum, modulation=mod)
    with pytest.raises(InputError, match="video_frames"):
        minimal_plan(lum, modulation={**mod, "video_frames": 5, "video_fps": 30.0})
    assert minimal_plan(lum, modulation={**mod, "video_fps": 30.0}).modulation.video_frames == 3


def test_a_driver_too_slow_for_a_fast_shutter_is_named_with_the_rate_that_fits():
    # the ultrawide profile's 10 us rows on the office (25.3 rows): 20 kHz shows only 4.2 chips a window
    with pytest.raises(PlanningError, match=r"--driver-max-hz 29000\)"):
        choose_video_timing(16, 3, 25.3, 10e-6)
    assert choose_video_timing(16, 3, 25.3, 10e-6, driver_max_hz=29_000).video is not None
    with pytest.raises(PlanningError):
        choose_video_timing(16, 3, 25.3, 10e-6, driver_max_hz=28_000)
