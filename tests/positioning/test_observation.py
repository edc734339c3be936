"""The observation model and the full-perspective method on exact and noisy LED images."""

import numpy as np
import pytest

from planner.camera.ellipse import Ellipse, centre_and_shape, ellipse_from_dual_conic, fit_ellipse
from planner.camera.model import Camera, disc_dual_conic, project_discs_at, rotation_from_angles
from planner.errors import PositioningError
from planner.positioning.fix import angles_of
from planner.positioning.observation import observe, rim_points
from planner.positioning.paper import locate_paper
from planner.positioning.perspective import locate_perspective

CAM = Camera()


def grid(rows, cols, pitch=0.5, z=2.5):
    gx, gy = np.meshgrid(np.arange(cols) * pitch + pitch / 2, np.arange(rows) * pitch + pitch / 2)
    return np.column_stack([gx.ravel(), gy.ravel(), np.full(gx.size, z)])


SITE = grid(8, 8)
RADII = np.full(len(SITE), 0.1)


def pose(x, y, z, tilt, az, roll):
    return np.array([x, y, z]), rotation_from_angles(*np.radians([tilt, az, roll]))[0]


def test_ellipse_shape_round_trips_through_its_dual_conic():
    e = Ellipse(1200.0, 800.0, 90.0, 40.0, np.radians(30.0))
    c, m = e.centre, e.shape
    dual = np.block([[m @ m - np.outer(c, c), -c[:, None]], [-c[None, :], -np.ones((1, 1))]])
    back = ellipse_from_dual_conic(3.7 * dual)  # any scale
    assert np.allclose([back.cx, back.cy, back.major, back.minor, back.angle_rad],
                       [e.cx, e.cy, e.major, e.minor, e.angle_rad], atol=1e-9)


def test_fitted_ellipse_of_exact_rim_points_is_the_exact_image():
    position, rotation = pose(1.0, 1.2, 1.0, 35, 20, 70)
    exact = ellipse_from_dual_conic(disc_dual_conic(position, rotation, SITE[27], 0.1, CAM))
    pts = rim_points(position, rotation, SITE[27][None], np.array([0.1]), CAM, [720])
    fitted = fit_ellipse(pts)
    assert abs(exact.major - exact.minor) > 5  # a real ellipse, not a circle
    assert np.allclose([fitted.cx, fitted.cy, fitted.major, fitted.minor], [exact.cx, exact.cy, exact.major, exact.minor],
                       atol=0.02)
    assert fitted.angle_rad == pytest.approx(exact.angle_rad, abs=1e-3)


def test_observe_keeps_only_whole_discs_nearest_the_centre_first():
    position, rotation = pose(1.3, 2.1, 1.2, 30, 200, 15)
    seen = observe(position, rotation, SITE, RADII, CAM)
    img = project_discs_at(position[None], rotation[None], SITE[None], RADII[None], CAM)
    assert set(seen.index) == set(np.flatnonzero(img["inside"][0])) and len(seen.index) >= 3
    off = [np.hypot(img["u"][0, k] - CAM.cx_px, img["v"][0, k] - CAM.cy_px) for k in seen.index]
    assert off == sorted(off)
    noisy = observe(position, rotation, SITE, RADII, CAM, np.random.default_rng(1), noise_px=0.5)
    for a, b in zip(seen.ellipses, noisy.ellipses):
        assert abs(a.cx - b.cx) < 0.3 and abs(a.cy - b.cy) < 0.3 and abs(a.major - b.major) < 0.6


@pytest.mark.parametrize("tilt, az, roll", [(0, 0, 0), (25, 60, 100), (40, 250, 300)])
def test_perspective_method_is_exact_on_exact_images(tilt, az, roll):
    position, rotation = pose(2.0, 1.7, 0.9, tilt, az, roll)
    seen = observe(position, rotation, SITE, RADII, CAM)
    fix = locate_perspective(SITE[seen.index], RADII[seen.index], seen.ellipses, CAM)
    assert np.allclose(fix.position, position, atol=1e-6) and fix.residual_px < 1e-3
    assert np.allclose(fix.rotation, rotation, atol=1e-6)
    assert np.allclose(np.degrees(angles_of(fix.rotation)), [tilt, az % 360, roll % 360] if tilt else
                       [0, 0, roll % 360], atol=1e-4)


def test_perspective_method_survives_the_lost_p3p_root():
    # Found in simulation: P3P on the ellipse centres of these three LEDs returns only two
    # (wrong) roots, because the two true-ish roots merge; the weak-perspective start saves it.
    site = grid(4, 32)
    position = np.array([14.85207836, 0.85840777, 0.54256826])
    rotation = rotation_from_angles(0.2786309813571847, np.radians(40.0), 0.3)[0]
    seen = observe(position, rotation, site, np.full(len(site), 0.1), CAM, np.random.default_rng(0))
    fix = locate_perspective(site[seen.index], np.full(len(seen.index), 0.1), seen.ellipses, CAM)
    assert np.linalg.norm(fix.position - position) < 1e-3


def test_noisy_images_locate_to_a_millimetre_and_the_paper_method_to_decimetres():
    rng = np.random.default_rng(3)
    errs = {"perspective": [], "paper": []}
    for _ in range(20):
        position, rotation = pose(*rng.uniform(1.2, 2.8, 2), rng.uniform(0.5, 1.5), 30, rng.uniform(0, 360),
                                  rng.uniform(0, 360))
        seen = observe(position, rotation, SITE, RADII, CAM, rng)
        if len(seen.index) < 3 or np.ptp(SITE[seen.index, 0]) == 0 or np.ptp(SITE[seen.index, 1]) == 0:
            continue  # too few, or all in one row
        for name, method in (("perspective", locate_perspective), ("paper", locate_paper)):
            errs[name].append(np.linalg.norm(method(SITE[seen.index], RADII[seen.index], seen.ellipses, CAM).position
                                             - position))
    assert len(errs["paper"]) >= 15
    assert np.max(errs["perspective"]) < 1e-3
    assert np.mean(errs["paper"]) > 0.02  # weak perspective is biased under tilt


def test_collinear_and_too_few_leds_are_refused():
    row = SITE[:3]
    e = [Ellipse(1000.0 + 300 * k, 1500.0, 200.0, 190.0, 0.0) for k in range(3)]
    for method in (locate_perspective, locate_paper):
        with pytest.raises(PositioningError, match="one line"):
            method(row, RADII[:3], e, CAM)
        with pytest.raises(PositioningError, match="at least three"):
            method(row[:2], RADII[:2], e[:2], CAM)


def test_centre_and_shape_flags_a_hyperbola():
    sideways = rotation_from_angles(np.radians(90.0), 0.0, 0.0)[0]
    _, _, ok = centre_and_shape(disc_dual_conic(np.array([0.0, 0.0, 2.0]), sideways, np.array([0.05, 0, 2.5]), 0.1, CAM))
    assert not ok
