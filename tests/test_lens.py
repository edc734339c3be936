"""The lens models against OpenCV's own projection, and their inverse."""

import math

import cv2
import numpy as np
import pytest

from planner.camera.model import Camera
from planner.errors import InputError
from planner.plan.file import CameraFields

WIDE = Camera.from_fov(math.radians(80), lens="pinhole", distortion=(-0.3, 0.1, 0.001, -0.0005, -0.02))
FISHEYE = Camera.from_fov(math.radians(120), lens="fisheye", distortion=(0.05, -0.01, 0.002, 0.0))


def _points(n, half_x, half_y, seed=1):
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(-half_x, half_x, n), rng.uniform(-half_y, half_y, n), np.ones(n)])


def test_pinhole_distortion_matches_opencv_and_inverts():
    pts = _points(500, 0.7, 0.5)
    ref, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), WIDE.intrinsics, WIDE.dist_coeffs)
    uv = WIDE.project(pts)
    assert np.abs(uv - ref.reshape(-1, 2)).max() < 1e-9
    assert np.abs(WIDE.normalized(uv) - pts[:, :2]).max() < 1e-9
    assert np.abs(WIDE.ideal_pixels(uv) - WIDE.ideal().project(pts)).max() < 1e-6


def test_fisheye_distortion_matches_opencv_and_inverts():
    pts = _points(500, 1.5, 1.0, seed=2)
    ref, _ = cv2.fisheye.projectPoints(pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), FISHEYE.intrinsics,
                                       FISHEYE.dist_coeffs)
    uv = FISHEYE.project(pts)
    assert np.abs(uv - ref.reshape(-1, 2)).max() < 1e-9
    assert np.abs(FISHEYE.normalized(uv) - pts[:, :2]).max() < 1e-9


def test_rays_are_unit_and_point_through_the_pixels():
    pts = _points(50, 0.6, 0.4, seed=3)
    rays = WIDE.rays(WIDE.project(pts))
    assert np.allclose(np.linalg.norm(rays, axis=1), 1.0)
    assert np.allclose(rays[:, :2] / rays[:, 2:], pts[:, :2], atol=1e-9)


def test_a_folding_lens_gives_nan_not_a_wrong_point():
    folding = Camera.from_fov(math.radians(90), lens="pinhole", distortion=(-0.6,))  # folds past r ~ 0.75
    assert np.isnan(folding.normalized(np.array([[4000.0, 3000.0]]))).all()


def test_the_field_of_view_counts_the_distortion():
    assert WIDE.ideal().hfov_rad == pytest.approx(math.radians(80))
    assert WIDE.hfov_rad > math.radians(82)  # barrel distortion squeezes a wider view into the same pixels


def test_camera_fields_round_trip_and_refuse_too_many_coefficients():
    cam = CameraFields(**WIDE.to_dict()).to_camera()
    assert cam.distortion == WIDE.distortion and cam.lens == "pinhole"
    assert "distortion" not in Camera().to_dict()  # an ideal camera's plan.yaml is unchanged
    with pytest.raises(ValueError, match="at most 4"):
        CameraFields(lens="fisheye", distortion=[0.1] * 5)
    with pytest.raises(InputError):
        from planner._schema import validated
        validated(CameraFields, {"lens": "barrel"}, "cam.yaml", "a camera", known=CameraFields.model_fields)
