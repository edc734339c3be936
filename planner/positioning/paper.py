"""Positioning: a camera's position from the ellipses of three or more LEDs.

The paper's method (section 2.3): under weak perspective an LED's image is an
ellipse whose major axis keeps the LED's diameter, which gives the distance to
each LED; three LEDs at known positions then give the position by
trilateration. Pure functions on plain arrays; lengths in metres, image
quantities in pixels.
"""

from __future__ import annotations

from itertools import combinations

import numpy as np

from planner.camera.ellipse import Ellipse
from planner.camera.model import Camera
from planner.errors import PositioningError
from planner.positioning.fix import Fix, check_geometry, ellipse_residuals, orientation_at, rms
from planner.positioning.undistort import ideal_ellipses


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
        raise PositioningError("the three LEDs are collinear: no position can be trilaterated from them")
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
    from scipy.optimize import least_squares  # here, not at import: commands that never locate skip loading it

    leds_m, d_m = np.asarray(leds_m, float), np.asarray(d_m, float)
    if len(leds_m) < 3:
        raise PositioningError(f"{len(leds_m)} LEDs: a position needs at least three")
    if start is None:
        start = leds_m.mean(axis=0) - np.array([0.0, 0.0, float(np.mean(d_m))])

    def residuals(p: np.ndarray) -> np.ndarray:
        return np.linalg.norm(leds_m - p, axis=1) - d_m

    fit = least_squares(residuals, start)
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


def _nearest_triple(xyz: np.ndarray, off_px: np.ndarray) -> list[int]:
    """The three LEDs nearest the image centre (section 3), skipping triples on one line."""
    order = np.argsort(off_px, kind="stable")
    for t in sorted(combinations(range(len(order)), 3), key=lambda t: (sum(t), t)):
        pick = order[list(t)]
        a, b, c = xyz[pick, :2]
        if abs((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])) > 1e-6:
            return list(pick)
    raise PositioningError("the LEDs seen lie on one line: no unique position; turn the camera to take in "
                           "a luminaire off that line")


def locate_paper(xyz: np.ndarray, radii: np.ndarray, ellipses: list[Ellipse], camera: Camera) -> Fix:
    """The paper's method end to end: three LEDs nearest the image centre, Eq. (1)-(6), then Eq. (13)-(14).

    LEDs at different heights use the least-squares form of Eq. (7). The orientation
    is not part of the paper's method; it is fitted afterwards (Kabsch, on the ellipse
    centres) only to report how well the position explains the image (``residual_px``).
    """
    xyz, radii = np.asarray(xyz, float), np.asarray(radii, float)
    ellipses, camera = ideal_ellipses(ellipses, camera)  # a distorting lens: undistorted first
    check_geometry(xyz)
    centres = np.array([e.centre for e in ellipses])
    off = np.hypot(centres[:, 0] - camera.cx_px, centres[:, 1] - camera.cy_px)
    pick = _nearest_triple(xyz, off)
    focal = float(np.sqrt(camera.fx_px * camera.fy_px))
    d = np.array([distance_weak_perspective(ellipses[k], radii[k], focal, camera.cx_px, camera.cy_px) for k in pick])
    if np.ptp(xyz[pick, 2]) < 1e-9:
        position = trilaterate_same_height(xyz[pick], d)
    else:
        position = trilaterate_least_squares(xyz[pick], d)[0]
    rotation = orientation_at(position, xyz, centres, camera)
    shapes = np.array([e.shape for e in ellipses])
    residual = rms(ellipse_residuals(position, rotation, xyz, radii, centres, shapes, camera))
    return Fix(position, rotation, residual, "paper", np.array(pick))
