"""The receiver twin through a phone's wide lens: rendered through the distortion, undistorted to locate.

Issue 18's third "Done when": the twin decodes and locates at least 99 % of 300 covered
poses within 10 cm with a distorted wide-lens profile (``--camera wide``: 79 deg horizontal,
k1 = -0.08, k2 = 0.02) on ``grid-32``.
"""

import json

import numpy as np
import pytest

from conftest import STRONG_WIDE_CAMERA
from planner.camera.model import Camera, rotation_from_angles
from planner.cli.twin import console_main
from planner.plan.file import load_plan
from planner.twin.render import Sensor, render_frame
from planner.twin.twin import Twin, covered_poses, summary


def test_one_tilted_pose_renders_through_the_lens_decodes_and_locates(wide_plan_dir, capsys):
    code = console_main([str(wide_plan_dir / "plan.yaml"), "--pose", "2,1,1,35,45,10", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["located"] and out["error_m"] < 0.001
    assert out["leds_in_view"] == out["blobs_found"] == out["ids_read"] >= 6 and out["ids_misread"] == 0


def test_leds_are_drawn_where_the_lens_puts_them_not_where_a_pinhole_would(wide_plan_dir):
    site = Twin.from_plan(load_plan(wide_plan_dir / "plan.yaml")).site
    camera = Camera.from_dict(STRONG_WIDE_CAMERA)
    position, rotation = np.array([2.0, 1.0, 1.2]), rotation_from_angles(0.0, 0.0, 0.0)[0]
    frame = render_frame(site.xyz, site.radii, ["1" * 16] * len(site.xyz), 14_500.0, camera, position, rotation,
                         Sensor(blur_px=0.0, read_noise_dn=0.0, shot_dn=0.0), np.random.default_rng(0))
    cam = (site.xyz - position) @ rotation
    lens_px, pinhole_px = camera.project(cam), camera.ideal().project(cam)
    moved = np.linalg.norm(lens_px - pinhole_px, axis=1)
    shown = (lens_px > 0).all(axis=1) & (lens_px < [3999, 2999]).all(axis=1) & (moved > 150)
    assert shown.sum() >= 4  # off-axis LEDs the barrel lens draws inwards by more than their image radius
    u, v = np.round(lens_px[shown]).astype(int).T
    assert (frame.image[v, u] > 150).all()
    u, v = np.round(pinhole_px[shown]).astype(int).T
    inside = (u >= 0) & (u < 4000) & (v >= 0) & (v < 3000)
    assert (frame.image[v[inside], u[inside]] < 20).all()


@pytest.mark.slow
@pytest.mark.parametrize("poses", [30, pytest.param(300, marks=pytest.mark.acceptance)])
def test_covered_poses_through_a_wide_lens_decode_and_locate(wide_plan_dir, poses):
    """Issue 18: >= 99 % of 300 covered poses (tilt up to 40 deg) identified right and within 10 cm (the suite: all of
    30; the 300 under ``--acceptance``)."""
    doc = load_plan(wide_plan_dir / "plan.yaml")
    twin = Twin.from_plan(doc)
    assert twin.camera.distorted
    drawn = covered_poses(twin, poses, seed=0)
    assert np.degrees(drawn.tilt_rad).max() > 35
    from planner.cli.twin import build_parser, run_batch

    # the command's own flags and defaults (a flag added later reaches the batch without editing this test)
    args = build_parser().parse_args([str(wide_plan_dir / "plan.yaml"), "--poses", str(poses), "--seed", "0", "--jobs", "2",
                                "--max-error", "0.10"])

    s = summary(run_batch(doc, args, twin.sensor))
    assert s["success_rate"] >= 0.99, s["failed_by_stage"]
    assert s["error_m"]["p90"] < 0.01 and s["ids_misread"] == 0
    print(f"wide-lens twin: {s['located']} of {poses} located, error p90 {s['error_m']['p90']:.4f} m")


def test_an_led_the_lens_maps_far_off_the_sensor_is_skipped_without_an_overflow():
    # the ultrawide's polynomial sends an LED 10 m off, 1 mm above the camera, ~1e21 px away: its box was
    # cast to int past int64 (numpy's "invalid value encountered in cast"); it is off the sensor, not drawn
    import warnings

    from planner.camera.file import camera_profile

    camera = camera_profile("ultrawide")
    xyz = np.array([[10.0, 0.0, 1.001], [0.0, 0.0, 3.0]])
    rotation = rotation_from_angles(0.0, 0.0, 0.0)[0]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        frame = render_frame(xyz, np.array([0.1, 0.1]), ["1" * 20] * 2, 40_000.0, camera, np.array([0.0, 0.0, 1.0]),
                             rotation, Sensor(), np.random.default_rng(0))
    assert frame.drawn.tolist() == [1]  # the LED overhead is drawn, the far one is not
    assert frame.image[1512, 2016] > 150
