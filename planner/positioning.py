"""Positioning: a camera's position from the ellipses of three or more LEDs.

The paper's method (section 2.3): under weak perspective an LED's image is an
ellipse whose major axis keeps the LED's diameter, which gives the distance to
each LED; three LEDs at known positions then give the position by
trilateration. Pure functions on plain arrays; lengths in metres, image
quantities in pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from .errors import PlanningError


@dataclass(frozen=True)
class Ellipse:
    """An LED's image: centre [px], full axis lengths [px], major-axis angle from the image x axis [rad]."""

    cx: float
    cy: float
    major: float
    minor: float
    angle_rad: float


def ellipse_from_dual_conic(cstar: np.ndarray) -> Ellipse:
    """Centre, axes and angle of the ellipse whose dual conic is ``cstar`` (3 x 3)."""
    c = np.linalg.inv(cstar)
    c = c / -c[2, 2] if c[2, 2] != 0 else c
    a2 = c[:2, :2]
    centre = np.linalg.solve(a2, -c[:2, 2])
    k = centre @ a2 @ centre - c[2, 2]  # x^T A x = k in centred coordinates
    evals, evecs = np.linalg.eigh(a2 / k)
    if not np.all(evals > 0):
        raise PlanningError("the LED's image is not an ellipse: it is not wholly in front of the camera")
    semi = 1.0 / np.sqrt(evals)  # ascending eigenvalues: major axis first
    direction = evecs[:, 0]
    return Ellipse(float(centre[0]), float(centre[1]), float(2 * semi[0]), float(2 * semi[1]),
                   float(np.arctan2(direction[1], direction[0]) % np.pi))


def distance_weak_perspective(ellipse: Ellipse, radius_m: float, focal_px: float, cx_px: float, cy_px: float) -> float:
    """Camera-to-LED distance [m] by the paper's Eq. (1)-(6).

    Notes
    -----
    Eq. (1): l2 / f = 2r / Zc, so ``Zc = 2 r f / l2`` (the paper's Eq. (2) prints
    ``Zc = (2r / f) l2``, an erratum, READING.md section 3). Eq. (5): the lateral
    offset ``m = (2r / l2) j`` with ``j`` the image distance from the principal point
    to the ellipse centre; Eq. (6): ``d = sqrt(m^2 + Zc^2)``.
    """
    l2 = ellipse.major
    z_c = 2.0 * radius_m * focal_px / l2
    j = float(np.hypot(ellipse.cx - cx_px, ellipse.cy - cy_px))
    m = 2.0 * radius_m / l2 * j
    return float(np.hypot(m, z_c))


def trilaterate_same_height(leds_m: np.ndarray, d_m: np.ndarray) -> np.ndarray:
    """Position [m] from three LEDs at one height and their distances, Eq. (11)-(14).

    The receiver is below the LEDs (Eq. 14 takes the lower root).
    """
    (x1, y1, z1), (x2, y2, _), (x3, y3, _) = leds_m[:3]
    d1, d2, d3 = d_m[:3]
    a = np.array([[x2 - x1, y2 - y1], [x3 - x1, y3 - y1]])
    if abs(np.linalg.det(a)) < 1e-9:
        raise PlanningError("the three LEDs are collinear: no position can be trilaterated from them")
    b = 0.5 * np.array([d1**2 - d2**2 + x2**2 - x1**2 + y2**2 - y1**2,
                        d1**2 - d3**2 + x3**2 - x1**2 + y3**2 - y1**2])
    x, y = np.linalg.solve(a, b)  # Eq. (13)
    h2 = d1**2 - (x - x1) ** 2 - (y - y1) ** 2
    return np.array([x, y, z1 - np.sqrt(max(h2, 0.0))])  # Eq. (14)


def trilaterate_least_squares(leds_m: np.ndarray, d_m: np.ndarray, start: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """Position [m] from three or more LEDs at any heights: least squares on the sphere equations (7).

    Returns the position and the RMS residual of the distances [m]. Starts below the
    LEDs' centroid (or at ``start``), so the solution under the ceiling is found.
    """
    leds_m, d_m = np.asarray(leds_m, float), np.asarray(d_m, float)
    if len(leds_m) < 3:
        raise PlanningError(f"{len(leds_m)} LEDs: a position needs at least three")
    if start is None:
        start = leds_m.mean(axis=0) - np.array([0.0, 0.0, float(np.mean(d_m))])
    fit = least_squares(lambda p: np.linalg.norm(leds_m - p, axis=1) - d_m, start)
    return fit.x, float(np.sqrt(np.mean(fit.fun**2)))


def fit_focal_length(distance_below_m: np.ndarray, image_radius_px: np.ndarray, radius_m: float) -> tuple[float, float]:
    """Section 2.4's calibration: level shots at known distances below an LED.

    Each shot gives ``f = (Z1 - Z) a / r`` (distance over LED radius equals focal
    length over image radius ``a``); a straight line ``f = f0 + k (Z1 - Z)`` is fitted.
    Returns ``(f0 [px], k [px/m])``.
    """
    dist = np.asarray(distance_below_m, float)
    f = dist * np.asarray(image_radius_px, float) / radius_m
    k, f0 = np.polyfit(dist, f, 1)
    return float(f0), float(k)
