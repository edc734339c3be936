"""Two LEDs plus gravity: the gravity-aided receiver's fix (identification: :func:`planner.positioning.locate.identify_gravity`).

The accelerometer gives the vertical in the camera frame to about a degree (the paper does not
use it; docs/positioning.md says why we do). With the tilt known, the bearings to two LEDs on a
horizontal ceiling fix the rest: level the rays (turn gravity onto ``-z``), and each ray meets the
ceiling at ``s (x_i/z_i, y_i/z_i)`` from the camera in a frame turned by the unknown yaw ``ψ``,
``s`` the ceiling's height above the camera. The LEDs' known plan offset ``d = x_b - x_a`` equals
``s R(ψ) (o_b - o_a)``, so ``s = |d| / |o_b - o_a|`` and ``ψ`` is the angle between the two; then
the camera's plan position is ``x_a - s R(ψ) o_a`` and its height ``z_a - s``. That start is refined
by least squares over the full pose on every identified LED's exact image against its ellipse
(centre and shape, whitened by one pixel: the ellipses' sizes also measure the distance) and on
the measured gravity (whitened by its uncertainty), so the gravity error is weighed, not trusted.
Rays come from :meth:`planner.camera.model.Camera.rays`, so a distorting lens is handled.
"""

from __future__ import annotations

import math

import numpy as np

from planner.camera.ellipse import Ellipse
from planner.camera.model import Camera
from planner.defaults import ACCELEROMETER_SIGMA_DEG
from planner.errors import PositioningError
from planner.positioning.error_terms import DEFAULT_TERMS, ErrorTerms
from planner.positioning.fix import Fix, observed, residuals_batch, rms
from planner.positioning.perspective import ROBUST_SIGMAS
from planner.positioning.uncertainty import residual_sigmas
from planner.positioning.undistort import ideal_ellipses

DOWN = np.array([0.0, 0.0, -1.0])
FORWARD_STEP = float(np.finfo(float).eps) ** 0.5
"""Relative step of :func:`refine_gravity`'s forward differences: scipy's default for ``jac="2-point"``."""


def levelling(gravity_cam: np.ndarray) -> np.ndarray:
    """A camera-to-level rotation (3 x 3) that turns the measured gravity onto ``-z`` (yaw arbitrary)."""
    up = -np.asarray(gravity_cam, float) / np.linalg.norm(gravity_cam)
    seed = np.array([1.0, 0.0, 0.0]) if abs(up[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = seed - up * (seed @ up)
    x /= np.linalg.norm(x)
    return np.vstack([x, np.cross(up, x), up])


def two_point_pose(xyz2: np.ndarray, rays2: np.ndarray, gravity_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Camera centre [m] and camera-to-site rotation from two LEDs (2 x 3 [m]), their unit rays
    (2 x 3, camera frame) and gravity in the camera frame: the closed form of the module docstring."""
    level = levelling(gravity_cam)
    v = rays2 @ level.T
    if np.any(v[:, 2] <= 1e-9):
        raise PositioningError("an LED's ray points below the horizon given gravity: no fix from this pair")
    o = v[:, :2] / v[:, 2:3]
    d_img, d_site = o[1] - o[0], xyz2[1, :2] - xyz2[0, :2]
    if np.linalg.norm(d_img) < 1e-9:
        raise PositioningError("the two LEDs are seen along one ray: no fix from this pair")
    s = np.linalg.norm(d_site) / np.linalg.norm(d_img)
    yaw = math.atan2(d_site[1], d_site[0]) - math.atan2(d_img[1], d_img[0])
    turn = np.array([[math.cos(yaw), -math.sin(yaw), 0.0], [math.sin(yaw), math.cos(yaw), 0.0], [0.0, 0.0, 1.0]])
    position = np.r_[xyz2[0, :2] - s * (turn[:2, :2] @ o[0]), xyz2[0, 2] - s]
    return position, turn @ level


def refine_gravity(position: np.ndarray, rotation: np.ndarray, xyz: np.ndarray, radii: np.ndarray,
                   ellipses: list[Ellipse], gravity_cam: np.ndarray, sigma_rad: float,
                   camera: Camera, terms: ErrorTerms | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """Least squares over the pose on every LED's exact image against its ellipse (centre and shape;
    ellipses undistorted by :func:`planner.positioning.undistort.ideal_ellipses`) and on gravity
    (whitened by ``sigma_rad``). The ellipses' residuals are whitened by one pixel, or with ``terms`` by
    their standard deviations under that budget (:mod:`planner.positioning.uncertainty`), robust beyond
    :data:`~planner.positioning.perspective.ROBUST_SIGMAS`. Returns the position, rotation and the
    ellipses' RMS residual, unweighted [px]."""
    from scipy.optimize import least_squares  # here, not at import: commands that never locate skip loading it
    from scipy.spatial.transform import Rotation

    undistorted, ideal = ideal_ellipses(ellipses, camera)
    centres, shapes = observed(undistorted)
    g = np.asarray(gravity_cam, float) / np.linalg.norm(gravity_cam)
    args = (rotation, xyz, radii, centres, shapes, ideal)
    w = 1.0 if terms is None else 1.0 / residual_sigmas(centres, shapes, radii, ideal, terms)

    def batch(x):  # B poses (B x 6) to B rows of residuals
        rot = rotation @ Rotation.from_rotvec(x[:, :3]).as_matrix()
        tilt = np.cross(g, np.einsum("bji,j->bi", rot, DOWN)) / max(sigma_rad, 1e-9)
        return np.concatenate([residuals_batch(x, *args) * w, tilt], axis=1)

    def jac(x):
        """scipy's own 2-point rule (step sqrt(eps) max(1, |x|), signed as x), its 6 columns in one batch."""
        h = FORWARD_STEP * np.where(x >= 0, 1.0, -1.0) * np.maximum(1.0, np.abs(x))
        poses = np.tile(x, (len(x) + 1, 1))
        poses[1:][np.diag_indices(len(x))] += h
        r = batch(poses)
        return ((r[1:] - r[0]) / ((x + h) - x)[:, None]).T

    def fun(x):
        return batch(x[None])[0]

    start = np.r_[0.0, 0.0, 0.0, position]
    if terms is None:
        fit = least_squares(fun, start, jac=jac, method="lm", x_scale="jac")
    else:
        fit = least_squares(fun, start, jac=jac, x_scale="jac", loss="soft_l1", f_scale=ROBUST_SIGMAS)
    rot = rotation @ Rotation.from_rotvec(fit.x[:3]).as_matrix()
    return fit.x[3:], rot, rms(fit.fun[:-3] / w)


def locate_gravity(xyz: np.ndarray, radii: np.ndarray, ellipses, camera: Camera, gravity_cam: np.ndarray,
                   sigma_rad: float = math.radians(ACCELEROMETER_SIGMA_DEG), terms: ErrorTerms = DEFAULT_TERMS) -> Fix:
    """Camera pose from two or more identified LEDs (``xyz`` N x 3 [m]), their ellipses and gravity
    (camera frame, pointing down); the first two LEDs give the closed-form start. As the perspective fit:
    the fit with every ellipse residual weighed alike gives ``residual_px``, a second weighed by ``terms``
    (the budget's model) the position."""
    xyz, radii = np.asarray(xyz, float), np.asarray(radii, float)
    if len(xyz) < 2:
        raise PositioningError(f"{len(xyz)} usable LED{'s' if len(xyz) != 1 else ''}: a fix with gravity needs two")
    ellipses = list(ellipses)
    rays = camera.rays(np.array([e.centre for e in ellipses]))
    position, rotation = two_point_pose(xyz[:2], rays[:2], gravity_cam)
    position, rotation, residual = refine_gravity(position, rotation, xyz, radii, ellipses, gravity_cam, sigma_rad,
                                                  camera)
    position, rotation, _ = refine_gravity(position, rotation, xyz, radii, ellipses, gravity_cam, sigma_rad, camera,
                                           terms)
    return Fix(position, rotation, residual, "gravity", np.arange(len(xyz)))


def window_order(centres_px: np.ndarray, camera: Camera) -> np.ndarray:
    """LED indices by the angle of their ray from the optical axis, smallest first (the two-LED window's rule)."""
    return np.argsort(-camera.rays(np.asarray(centres_px, float))[:, 2], kind="stable")


def accelerometer(rotation: np.ndarray, sigma_rad: float, rng: np.random.Generator) -> np.ndarray:
    """The phone's measured down direction in the camera frame: the true one turned by a random
    angle, each of its two components Gaussian with ``sigma_rad / sqrt 2`` (RMS error ``sigma_rad``)."""
    g = rotation.T @ np.array([0.0, 0.0, -1.0])
    perp = np.linalg.svd(g[None])[2][1:]
    out = g + rng.normal(0.0, sigma_rad / math.sqrt(2), 2) @ perp
    return out / np.linalg.norm(out)
