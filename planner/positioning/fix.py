"""A position found from one image, and how well it explains what the camera saw.

Shared by both positioning methods: the exact LED images a pose predicts
(:func:`planner.camera.model.disc_dual_conic`) are compared with the ellipses seen,
centre and shape matrix (:mod:`planner.camera.ellipse`), five residuals per LED [px].
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations

import numpy as np

from planner.camera.ellipse import Ellipse, centre_and_shape
from planner.camera.model import Camera, disc_conics, rotation_from_angles
from planner.errors import PositioningError

BAD_PX = 1e4  # residual standing in for an LED the pose would not image as an ellipse


@dataclass(frozen=True)
class Fix:
    """A position found from one observation.

    ``rotation`` is the camera-to-site rotation (columns: the camera's x, y, z axes);
    ``residual_px`` the RMS difference between the ellipses seen and the exact images
    of the LEDs at this pose [px] (the perspective and gravity fits: at the pose of their fit
    weighing every residual alike, how well any pose explains the image; their position comes
    from the weighted fit after it); ``used`` indices of the LEDs the method used.
    """

    position: np.ndarray
    rotation: np.ndarray
    residual_px: float
    method: str
    used: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))


def observed(ellipses: list[Ellipse]) -> tuple[np.ndarray, np.ndarray]:
    return np.array([e.centre for e in ellipses]), np.array([e.shape for e in ellipses])


def ellipse_residuals(position: np.ndarray, rotation: np.ndarray, xyz: np.ndarray, radii: np.ndarray,
                      centres: np.ndarray, shapes: np.ndarray, camera: Camera) -> np.ndarray:
    """Predicted minus observed centre (2) and shape matrix (3 entries) per LED [px], flattened."""
    return residuals_batch(np.r_[0.0, 0.0, 0.0, position][None], rotation, xyz, radii, centres, shapes, camera)[0]


def rms(res: np.ndarray) -> float:
    return float(np.sqrt(np.mean(res**2)))


def bearings(centres_px: np.ndarray, camera: Camera) -> np.ndarray:
    """Unit rays (N x 3, camera frame) through image points [px]."""
    ray = np.column_stack([(centres_px[:, 0] - camera.cx_px) / camera.fx_px,
                           (centres_px[:, 1] - camera.cy_px) / camera.fy_px, np.ones(len(centres_px))])
    return ray / np.linalg.norm(ray, axis=1, keepdims=True)


def orientation_at(position: np.ndarray, xyz: np.ndarray, centres_px: np.ndarray, camera: Camera) -> np.ndarray:
    """Camera-to-site rotation that best turns the image rays onto the LEDs from ``position`` (Kabsch)."""
    to_led = xyz - position
    to_led /= np.linalg.norm(to_led, axis=1, keepdims=True)
    u, _, vt = np.linalg.svd(to_led.T @ bearings(centres_px, camera))
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


def check_geometry(xyz: np.ndarray) -> None:
    """Refuse fewer than three LEDs, or LEDs on one line (no unique position)."""
    if len(xyz) < 3:
        raise PositioningError(f"{len(xyz)} usable LED{'s' if len(xyz) != 1 else ''}: a position needs at least three")
    spread = np.linalg.svd(xyz - xyz.mean(axis=0), compute_uv=False)
    if spread[1] < 1e-3 * max(spread[0], 1e-9):
        raise PositioningError("the LEDs seen lie on one line: no unique position; turn the camera to take in "
                               "a luminaire off that line")


def anchor_triple(centres_px: np.ndarray) -> list[int]:
    """Of the (up to six) first LEDs, the three spanning the largest image triangle.

    If those six lie on one line (a snapshot listing a row of LEDs first), all LEDs
    are searched. Lines image as lines, so LEDs whose images are all collinear are
    collinear on the ceiling: refused here, before any luminaire is identified.
    """
    span = np.ptp(centres_px, axis=0).max() if len(centres_px) else 0.0
    best, area = [0, 1, 2], -1.0
    for first in (6, len(centres_px)):
        for t in combinations(range(min(len(centres_px), first)), 3):
            a, b, c = centres_px[list(t)]
            s = abs((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
            if s > area:
                best, area = list(t), s
        if area >= 1e-3 * span**2:
            return best
    raise PositioningError("the LEDs seen lie on one line: no unique position; turn the camera to take in "
                           "a luminaire off that line")


def residuals_batch(x: np.ndarray, rotation: np.ndarray, xyz: np.ndarray, radii: np.ndarray,
                     centres: np.ndarray, shapes: np.ndarray, camera: Camera) -> np.ndarray:
    """Ellipse residuals for B poses ``x`` (B x 6): ``rotation`` turned by the rotation vector
    ``x[:3]`` (camera frame), camera centre ``x[3:]`` [m]; LEDs not imaged as ellipses get a large residual."""
    from scipy.spatial.transform import Rotation  # here, not at import: commands that never locate skip loading it

    rot = rotation @ Rotation.from_rotvec(x[:, :3]).as_matrix()  # (B, 3, 3) camera-to-site
    rel = xyz[None] - x[:, None, 3:]
    c, m, ok = centre_and_shape(disc_conics(x[:, 3:], rot, np.broadcast_to(xyz, rel.shape), radii, camera))
    ok &= np.einsum("bni,bi->bn", rel, rot[:, :, 2]) > radii
    res = np.concatenate([c - centres, m[..., 0, 0:2] - shapes[:, 0, 0:2], m[..., 1, 1:2] - shapes[:, 1, 1:2]], axis=2)
    res[~ok] = BAD_PX
    return res.reshape(len(x), -1)


def _turn(angle_rad: float) -> float:
    """An angle in [0, 2 pi) [rad], with rounding just below a full turn taken as zero."""
    a = angle_rad % (2 * np.pi)
    return 0.0 if a > 2 * np.pi - 1e-9 else a


def angles_of(rotation: np.ndarray) -> tuple[float, float, float]:
    """(tilt, azimuth, roll) [rad] of a camera-to-site rotation, inverse of :func:`rotation_from_angles`.

    A level camera (tilt below 1 urad) has azimuth 0; its turn is all roll.
    """
    tilt = float(np.arccos(np.clip(rotation[2, 2], -1.0, 1.0)))
    azimuth = float(np.arctan2(rotation[1, 2], rotation[0, 2])) if tilt > 1e-6 else 0.0
    base = rotation_from_angles(tilt, azimuth, 0.0)[0].T @ rotation
    return tilt, _turn(azimuth), _turn(float(np.arctan2(base[1, 0], base[0, 0])))
