"""Receiver twin: rendered rolling-shutter frames decoded back to IDs and positions.

The end-to-end acceptance (issue 8): over 300 random covered poses of the bundled
512 plan (tilt up to 40 deg), at least 99 % decode to the right luminaires and
locate within 10 cm; statistics are pinned with the seed.
"""

import json

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.camera.model import rotation_from_angles
from planner.cli.twin import console_main
from planner.decode.image import FrameFormat, chips_from_levels, decode_frame
from planner.modulation.frame import frame_chips, line_code
from planner.plan.file import load_plan
from planner.twin.render import Sensor, exposure_means, render_frame
from planner.twin.twin import Twin, covered_poses, summary


@pytest.fixture(scope="module")
def plan512(plan512_dir):
    return plan512_dir / "plan.yaml"


# --- pieces ---------------------------------------------------------------------------------------

@settings(max_examples=80, deadline=None)
@given(st.text("01", min_size=2, max_size=24), st.floats(0, 30), st.floats(1e-6, 3e-4), st.floats(0, 0.5))
def test_exposure_means_integrates_the_repeated_frame(chips, phase, exposure_s, off):
    rate = 12_600.0
    rows = np.linspace(0, 5e-3, 40)
    got = exposure_means(chips, phase, rows, exposure_s, rate, off)
    fine = np.linspace(0, 1, 4001)[:-1] + 1 / 8000  # midpoints: numerical integral over each exposure
    t = rows[:, None] + fine[None] * exposure_s
    idx = np.floor(t * rate + phase).astype(int) % len(chips)
    level = np.where(np.array(list(chips))[idx] == "1", 1.0, off)
    np.testing.assert_allclose(got, level.mean(axis=1), atol=2e-3)


def test_chips_from_levels_reads_runs_and_drops_partial_ends():
    chips = "0111000110100110"
    rows_per_chip = 3.97
    t = np.arange(200) / rows_per_chip + 0.4  # row -> chip position
    levels = np.where(np.array(list(chips * 20))[np.floor(t).astype(int)] == "1", 200.0, 6.0)
    read = chips_from_levels(levels + np.random.default_rng(0).normal(0, 2, len(levels)), rows_per_chip)
    assert read in chips * 20 and len(read) > 40  # a contiguous stretch, ends dropped
    assert chips_from_levels(np.full(100, 90.0), rows_per_chip) == ""  # no contrast, no chips


def _single_led_frame(word, code_name, exposure_s=25e-6, seed=0, height_m=1.0):
    """One LED straight above a level camera, sending ``word``."""
    from planner.camera.model import Camera

    code = line_code(code_name)
    chips = frame_chips(word, 4, code)
    camera = Camera()
    rate = 12_600.0
    frame = render_frame(np.array([[0.0, 0.0, 2.5]]), np.array([0.1]), [chips], rate, camera,
                         np.array([0.0, 0.0, 2.5 - height_m]), rotation_from_angles(0, 0, 0)[0],
                         Sensor(exposure_s=exposure_s), np.random.default_rng(seed))
    return frame, FrameFormat(code, 4, rate), camera


@pytest.mark.parametrize("code_name", ["manchester", "4b6b"])
@pytest.mark.parametrize("word", [0, 5, 15])
def test_one_led_renders_and_decodes_to_its_id(word, code_name):
    frame, mod, camera = _single_led_frame(word, code_name, seed=word)
    blobs = decode_frame(frame.image, camera, mod, blur_px=0.8, exposure_s=25e-6)
    assert len(blobs) == 1 and blobs[0].problem == "" and blobs[0].id == word + 1
    # the disc is 0.2 m across, 1 m above the lens: 0.2 * fx px, centred on the principal point
    e = blobs[0].ellipse
    assert abs(e.cx - camera.cx_px) < 0.3 and abs(e.cy - camera.cy_px) < 0.3
    assert abs(e.major - 0.2 * camera.fx_px) < 0.5 and abs(e.minor - 0.2 * camera.fx_px) < 0.5


def test_a_dark_frame_has_no_blobs_and_a_cut_led_is_refused(plan512):
    from planner.camera.model import Camera

    camera = Camera()
    dark = np.full((camera.height_px, camera.width_px), 6, np.uint8)
    mod = FrameFormat.from_plan(load_plan(plan512))
    assert decode_frame(dark, camera, mod) == []
    frame, mod4, _ = _single_led_frame(3, "manchester")
    shifted = np.zeros_like(frame.image) + 6
    shifted[:, :2150] = frame.image[:, 1850:]  # the LED's left part now lies off the sensor
    blobs = decode_frame(shifted, camera, mod4, blur_px=0.8, exposure_s=25e-6)
    assert len(blobs) == 1 and blobs[0].id is None and blobs[0].problem == "cut by the image border"


def test_exposure_as_long_as_a_chip_still_reads_but_twice_that_does_not():
    read = {}
    for exposure_us in (25, 79, 160):
        frame, mod, camera = _single_led_frame(9, "manchester", exposure_s=exposure_us * 1e-6)
        read[exposure_us] = decode_frame(frame.image, camera, mod, exposure_s=exposure_us * 1e-6)[0].id
    assert read[25] == read[79] == 10 and read[160] is None


# --- the plan, end to end ------------------------------------------------------------------------

def test_render_and_decode_one_pose_of_the_512_plan(plan512, tmp_path, capsys):
    png = tmp_path / "frame.png"
    code = console_main([str(plan512), "--pose", "8,4,1,30,45,10", "--png", str(png), "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["located"] and out["error_m"] < 0.001
    assert out["leds_in_view"] == out["blobs_found"] == out["ids_read"] == 8 and out["ids_misread"] == 0
    image = cv2.imread(str(png), cv2.IMREAD_UNCHANGED)
    assert image.shape == (3000, 4000) and image.dtype == np.uint8
    assert 0.05 < (image > 100).mean() < 0.5  # LEDs lit on a dark ceiling
    assert not list(tmp_path.glob(".*"))


GOLDEN = {30: (30, 203, 203, 203, 0), 300: (300, 2134, 2134, 2134, 0)}
"""(located, LEDs in view, blobs found, IDs read, IDs misread) of the covered poses drawn with seed 0."""


@pytest.mark.slow
@pytest.mark.parametrize("poses", [30, pytest.param(300, marks=pytest.mark.acceptance)])
def test_covered_poses_decode_and_locate(plan512, poses):
    """Issue 8's acceptance: >= 99 % of 300 covered poses (tilt up to 40 deg) right and within 10 cm (the suite: all
    of 30; the 300 under ``--acceptance``)."""
    doc = load_plan(plan512)
    twin = Twin.from_plan(doc)
    drawn = covered_poses(twin, poses, seed=0)
    assert np.degrees(drawn.tilt_rad).max() > 35 and np.degrees(drawn.tilt_rad).max() <= 40
    from planner.cli.twin import build_parser, run_batch

    # the command's own flags and defaults (a flag added later reaches the batch without editing this test)
    args = build_parser().parse_args([str(plan512), "--poses", str(poses), "--seed", "0", "--jobs", "2",
                                "--max-error", "0.10"])

    results = run_batch(doc, args, twin.sensor)
    s = summary(results)
    assert s["success_rate"] >= 0.99, [r.detail for r in results if not r.ok]
    assert s["error_m"]["max"] < 0.10
    # golden statistics, seed 0 (OpenCV and NumPy's PCG64 streams): any change in rendering or decoding shows here
    assert (s["located"], s["leds_in_view"], s["blobs_found"], s["ids_read"], s["ids_misread"]) == GOLDEN[poses]
    assert s["failed_by_stage"] == {"blobs": 0, "ids": 0, "identify": 0, "position": 0}
    # measured 2026-12-05 (300 poses): median 0.25 mm, 90 % 0.67 mm, max 2.49 mm; the fit weighs the ellipses by the plan's error
    # budget, discounting centres the twin renders exactly (issue 37; weighing every residual alike: 0.08 mm)
    assert s["error_m"]["median"] < 5e-4
    print(f"512 grid twin: {s['located']} of {poses} located, error median {s['error_m']['median'] * 1e3:.2f} mm,"
          f" max {s['error_m']['max'] * 1e3:.2f} mm")


@pytest.mark.slow
def test_batch_command_reports_stages_and_exit_code(plan512, tmp_path, capsys):
    code = console_main([str(plan512), "--poses", "6", "--jobs", "1", "--seed", "3", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["poses"] == 6 and out["located"] == 6 and out["failures"] == []
    # a sensor that smears every chip fails at reading IDs; the command says so and exits 3
    code = console_main([str(plan512), "--poses", "4", "--jobs", "1", "--exposure-us", "400",
                         "--save-failures", str(tmp_path / "fail")])
    text = capsys.readouterr().out
    assert code == 3 and "ids 4" in text and "no whole frame read" in text
    assert len(list((tmp_path / "fail").glob("pose-*-ids.png"))) == 4


def test_another_phone_than_the_plans_sees_more_leds_and_reads_fewer_of_them(plan512, capsys):
    """--camera: the 512 plan filmed by the ultra-wide profile (110 deg, 10 us rows) instead of the paper's
    camera: ten times the LEDs in view, but most images are too small for a frame timed for the paper's."""
    args = [str(plan512), "--poses", "4", "--jobs", "1", "--seed", "3", "--json"]
    assert console_main(args) == 0
    planned = json.loads(capsys.readouterr().out)
    console_main([*args, "--camera", "ultrawide"])
    other = json.loads(capsys.readouterr().out)
    assert other["leds_in_view"] > 5 * planned["leds_in_view"]
    assert other["ids_read"] < other["leds_in_view"] / 4 and planned["ids_read"] == planned["leds_in_view"]


def test_usage_errors_are_one_line(plan512, capsys):
    assert console_main([str(plan512), "--png", "x.png"]) == 2
    assert console_main([str(plan512), "--pose", "1,2,3"]) == 2
    assert console_main([str(plan512), "--off-level", "1.5"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len([e for e in err if e.startswith("vlp-twin: error:")]) == 3 and not any("Traceback" in e for e in err)


def test_a_plan_without_frames_is_refused(plan512, tmp_path, capsys):
    import yaml

    doc = yaml.safe_load(plan512.read_text())
    doc.pop("modulation")
    bad = tmp_path / "plan.yaml"
    bad.write_text(yaml.safe_dump(doc))
    assert console_main([str(bad), "--poses", "2"]) == 1
    assert "no frames" in capsys.readouterr().err
