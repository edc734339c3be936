"""LED images as ellipses: parameters, their dual conics, and fitting them to edge points.

An ellipse is kept as the receiver reports it (centre, full axis lengths, angle of
the major axis from the image x axis) and, for arithmetic, as its centre ``c`` and
*shape matrix* ``M = R diag(a, b) R^T`` (``a``, ``b`` semi-axes [px]); ``M`` is
continuous through circles, where the angle is undefined. The dual conic of an
ellipse, scaled so that its last entry is -1, is ``[[M^2 - c c^T, -c], [-c^T, -1]]``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.errors import PositioningError


@dataclass(frozen=True)
class Ellipse:
    """An LED's image: centre [px], full axis lengths [px], major-axis angle from the image x axis [rad]."""

    cx: float
    cy: float
    major: float
    minor: float
    angle_rad: float

    @property
    def centre(self) -> np.ndarray:
        return np.array([self.cx, self.cy])

    @property
    def shape(self) -> np.ndarray:
        """Shape matrix ``M`` (2 x 2) [px]."""
        c, s = np.cos(self.angle_rad), np.sin(self.angle_rad)
        rot = np.array([[c, -s], [s, c]])
        return rot @ np.diag([self.major / 2, self.minor / 2]) @ rot.T


def centre_and_shape(cstar: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centres (..., 2), shape matrices (..., 2, 2) [px] and an ellipse flag (...) of dual conics (..., 3, 3).

    The flag is False where the conic is not a real ellipse (an LED partly behind the
    camera images as a hyperbola); the shape there is meaningless.
    """
    n = cstar / -cstar[..., 2:3, 2:3]
    c = -n[..., :2, 2]
    s = n[..., :2, :2] + c[..., :, None] * c[..., None, :]  # M^2
    det = s[..., 0, 0] * s[..., 1, 1] - s[..., 0, 1] * s[..., 1, 0]
    tr = s[..., 0, 0] + s[..., 1, 1]
    ok = (det > 0) & (tr > 0) & np.isfinite(det)
    root = np.sqrt(np.where(ok, det, 1.0))
    m = (s + root[..., None, None] * np.eye(2)) / np.sqrt(np.where(ok, tr + 2 * root, 1.0))[..., None, None]
    return c, m, ok


def ellipse_from_dual_conic(cstar: np.ndarray) -> Ellipse:
    """The ellipse whose dual conic is ``cstar`` (3 x 3); refuses an image that is not an ellipse."""
    c, m, ok = centre_and_shape(np.asarray(cstar, float))
    if not ok:
        raise PositioningError("the LED's image is not an ellipse: it is not wholly in front of the camera")
    evals, evecs = np.linalg.eigh(m)  # ascending: minor first
    direction = evecs[:, 1]
    return Ellipse(float(c[0]), float(c[1]), float(2 * evals[1]), float(2 * evals[0]),
                   float(np.arctan2(direction[1], direction[0]) % np.pi))


def fit_ellipse(points_px: np.ndarray) -> Ellipse:
    """Least-squares ellipse through edge points (N x 2) [px], as a receiver fits a blob's rim.

    Uses OpenCV's ``fitEllipse`` (Fitzgibbon's direct fit), the call a phone app makes.
    """
    pts = np.asarray(points_px, dtype=np.float32).reshape(-1, 1, 2)
    if len(pts) < 5:
        raise PositioningError(f"{len(pts)} edge points: an ellipse needs at least five")
    import cv2  # here: reading a camera file needs no OpenCV

    (cx, cy), (w, h), angle_deg = cv2.fitEllipse(pts)
    angle = np.radians(angle_deg)
    if h > w:
        w, h, angle = h, w, angle + np.pi / 2
    return Ellipse(float(cx), float(cy), float(w), float(h), float(angle % np.pi))
