"""The paper's positioning method (section 2.3) on exact LED images."""

import numpy as np
import pytest

from planner.camera.ellipse import ellipse_from_dual_conic
from planner.camera.model import Camera, disc_dual_conic, rotation_from_angles
from planner.errors import PositioningError
from planner.positioning.paper import (
    distance_weak_perspective,
    fit_focal_length,
    trilaterate_least_squares,
    trilaterate_same_height,
)

# The paper's rig (Table 2), in metres; LED radius 0.1 m assumed (the paper does not say)
RIG = np.array([[0, 0.3, 2.5], [0, -0.3, 2.5], [0.5, 0, 2.5], [-0.5, 0, 2.5]])
RADIUS = 0.1


def locate(position, tilt_deg, azimuth_deg=30.0, roll_deg=10.0, cam=Camera()):
    rot = rotation_from_angles(np.radians(tilt_deg), np.radians(azimuth_deg), np.radians(roll_deg))[0]
    d = []
    for led in RIG[:3]:
        e = ellipse_from_dual_conic(disc_dual_conic(position, rot, led, RADIUS, cam))
        d.append(distance_weak_perspective(e, RADIUS, cam.fx_px, cam.cx_px, cam.cy_px))
    return trilaterate_same_height(RIG[:3], np.array(d)), np.array(d)


def test_ellipse_of_a_level_disc_is_a_circle_of_the_right_size():
    cam = Camera()
    pos = np.array([0.1, -0.2, 0.7])
    e = ellipse_from_dual_conic(disc_dual_conic(pos, np.eye(3), RIG[0], RADIUS, cam))
    depth = RIG[0, 2] - pos[2]
    assert e.major == pytest.approx(2 * RADIUS * cam.fx_px / depth, rel=1e-9)
    assert e.minor == pytest.approx(e.major, rel=1e-9)
    assert e.cx == pytest.approx(cam.cx_px + cam.fx_px * (RIG[0, 0] - pos[0]) / depth, rel=1e-9)


def test_level_receiver_is_located_exactly():
    # with the image plane parallel to the ceiling, weak perspective is exact (Eq. 1-6)
    for pos in ([0.0, 0.0, 0.7], [0.4, -0.3, 0.7], [-0.2, 0.25, 1.0]):
        found, d = locate(np.array(pos), 0.0, roll_deg=0.0)
        assert np.allclose(d, np.linalg.norm(RIG[:3] - pos, axis=1), atol=1e-9)
        assert np.allclose(found, pos, atol=1e-9)


def test_error_grows_with_tilt_as_in_the_paper():
    rng = np.random.default_rng(0)
    points = np.column_stack([rng.uniform(-0.3, 0.3, (16, 2)), np.full(16, 0.7)])
    mean_error = {}
    for tilt in (0, 20, 40):
        errs = [np.linalg.norm(locate(p, tilt, azimuth_deg=a)[0] - p)
                for p, a in zip(points, rng.uniform(0, 360, 16))]
        mean_error[tilt] = float(np.mean(errs))
    assert mean_error[0] < 1e-6 < mean_error[20] < mean_error[40]


def test_least_squares_agrees_and_takes_more_leds_and_heights():
    pos = np.array([0.1, 0.05, 0.8])
    leds = np.vstack([RIG, [[0.3, 0.4, 2.2]]])
    d = np.linalg.norm(leds - pos, axis=1)
    found, rms = trilaterate_least_squares(leds, d)
    assert np.allclose(found, pos, atol=1e-6) and rms < 1e-6
    assert np.allclose(trilaterate_same_height(RIG[:3], d[:3]), pos, atol=1e-9)


def test_collinear_and_too_few_leds_are_refused():
    line = np.array([[0, 0, 2.5], [0.5, 0, 2.5], [1.0, 0, 2.5]])
    with pytest.raises(PositioningError, match="collinear"):
        trilaterate_same_height(line, np.array([2.0, 2.0, 2.0]))
    with pytest.raises(PositioningError, match="at least three"):
        trilaterate_least_squares(line[:2], np.array([2.0, 2.0]))


def test_focal_length_calibration_recovers_a_drifting_focus():
    f0, k = 3000.0, 40.0  # px, px/m
    dist = np.array([1.0, 1.3, 1.6, 1.9, 2.2])
    f = f0 + k * dist
    image_radius = f * RADIUS / dist  # level shot: distance / radius = f / image radius
    assert fit_focal_length(dist, image_radius, RADIUS) == pytest.approx((f0, k), rel=1e-9)


def test_a_disc_straddling_the_camera_plane_has_no_ellipse():
    cam = Camera()
    sideways = rotation_from_angles(np.radians(90.0), 0.0, 0.0)[0]  # optical axis horizontal, towards +x
    # the disc spans x = -0.05 .. 0.15 m: partly behind the camera, so its image is a hyperbola
    with pytest.raises(PositioningError, match="not an ellipse"):
        ellipse_from_dual_conic(disc_dual_conic(np.array([0.0, 0.0, 2.0]), sideways, np.array([0.05, 0, 2.5]), RADIUS, cam))
