"""Frames: line codes, the preamble's uniqueness, run limits, decoding from any phase, chip-rate limits."""


import numpy as np
import pytest
import yaml

from conftest import ROOT
from planner.errors import InputError, PlanningError
from planner.modulation.frame import FOUR_B_SIX_B, LINE_CODES, decode_stream, frame_chips, longest_run
from planner.modulation.timing import choose_timing
from planner.plan.file import load_plan


def test_4b6b_table_is_balanced_and_one_to_one():
    assert len(set(FOUR_B_SIX_B)) == 16
    assert all(len(c) == 6 and c.count("1") == 3 for c in FOUR_B_SIX_B)


@pytest.mark.parametrize("name", sorted(LINE_CODES))
def test_every_frame_is_balanced_run_limited_and_holds_one_preamble(name):
    code = LINE_CODES[name]
    payload_runs = 0
    for bits in range(1, 11):
        for word in range(2**bits):
            frame = frame_chips(word, bits, code)
            assert frame.count("1") * 2 == len(frame), frame  # DC-balanced: no ID dims differently
            assert longest_run(frame) <= code.max_run, frame
            payload_runs = max(payload_runs, longest_run(code.encode(word, bits), cyclic=False))
            cyclic = frame + frame[:len(code.preamble) - 1]
            hits = [i for i in range(len(frame)) if cyclic.startswith(code.preamble, i)]
            assert hits == [0], (frame, hits)
            assert code.decode(frame[len(code.preamble):], bits) == word
    assert payload_runs < code.max_run  # the preamble's longest run never occurs in a payload


@pytest.mark.parametrize("name", sorted(LINE_CODES))
def test_payload_runs_across_codeword_boundaries_stay_below_the_preamble(name):
    code = LINE_CODES[name]
    pairs = [code.encode(a, 8) for a in range(256)]  # two symbols, every neighbour pair
    assert max(longest_run(p, cyclic=False) for p in pairs) == code.max_run - 1


def test_decode_needs_a_whole_frame():
    code = LINE_CODES["manchester"]
    frame = frame_chips(9, 6, code)
    with pytest.raises(InputError, match="no whole manchester frame"):
        decode_stream(frame[3:] + frame[:2], 6, code)


@pytest.fixture(scope="module")
def plan_512(plan512_dir):
    return load_plan(plan512_dir / "plan.yaml")


def test_every_luminaire_of_the_512_plan_decodes_from_a_random_phase(plan_512):
    mod = plan_512.modulation
    code = LINE_CODES[mod.line_code]
    bits = plan_512.code.word_bits
    rng = np.random.default_rng(5)
    for lum in plan_512.luminaires:
        chips = lum.frame.chips
        assert len(chips) == mod.frame_chips and lum.frame.chip_rate_hz == mod.chip_rate_hz
        assert longest_run(chips) <= code.max_run
        phase = int(rng.integers(len(chips)))
        stream = (chips * 3)[phase:phase + 2 * len(chips)]
        assert decode_stream(stream, bits, code) + 1 == lum.id


def test_the_chip_rate_lies_within_every_limit(plan_512):
    m = plan_512.modulation
    lim = m.limits_hz  # a key the plan reader keeps without typing it
    assert max(lim["flicker_min"], lim["frame_fit_min"]) <= m.chip_rate_hz <= min(lim["resolution_max"],
                                                                                  lim["driver_max"])
    assert m.frames_in_smallest_image >= 2 and lim["flicker_min"] >= 1000  # well above 200 Hz


@pytest.mark.parametrize("rows, row_time_s, driver_hz, numbers", [
    (8.0, 20e-6, 20e3, "8.0 rows x 20 us"),  # a tiny LED image
    (200.0, 1e-3, 20e3, "<= 500 Hz"),  # a slow rolling shutter
    (200.0, 20e-6, 800.0, "at most 800 Hz"),  # a slow driver
])
def test_impossible_timing_is_refused_with_the_numbers(rows, row_time_s, driver_hz, numbers):
    with pytest.raises(PlanningError, match="no chip rate fits") as err:
        choose_timing(16, 3, rows, row_time_s, driver_max_hz=driver_hz)
    assert numbers in str(err.value)


def test_one_frame_is_accepted_when_two_do_not_fit():
    t = choose_timing(16, 3, 60.0, 20e-6)  # 1.2 ms of stripes: two frames need 26.7 kHz > 25 kHz
    assert t.frames_in_image == 1 and t.frame_fit_min_hz <= t.chip_rate_hz <= t.resolution_max_hz


def test_vlp_plan_with_a_driver_too_slow_writes_the_plan_and_advice_without_frames(tmp_path, capsys):
    """Verified, the plan is still written with its verdict and advice (exit 3); no firmware, and why."""
    from planner.cli.plan import console_main

    code = console_main([str(ROOT / "layouts" / "grid-32.yaml"), "-o", str(tmp_path / "o"), "--driver-max-hz", "900",
                         "--no-map", "--no-report"])
    out, err = capsys.readouterr()
    assert code == 3 and "without frames or firmware: no chip rate fits" in err and "900 Hz" in err
    assert "frame    none: no chip rate fits" in out
    plan = yaml.safe_load((tmp_path / "o" / "plan.yaml").read_text())
    assert plan["modulation"] is None and plan["no_frames"].startswith("no chip rate fits")
    assert not (tmp_path / "o" / "firmware").exists()


def test_vlp_plan_unverified_refuses_a_driver_too_slow(tmp_path, capsys):
    from planner.cli.plan import console_main

    code = console_main([str(ROOT / "layouts" / "grid-32.yaml"), "-o", str(tmp_path / "o"), "--driver-max-hz", "900",
                         "--no-verify", "--scheme", "paper"])
    err = capsys.readouterr().err
    assert code == 1 and "no chip rate fits" in err and "900 Hz" in err and not (tmp_path / "o").exists()
