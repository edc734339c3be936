"""Lens distortion: OpenCV's two models, as plain numpy so that every stage can batch them.

``pinhole``: Brown-Conrady with OpenCV's coefficient order ``k1 k2 p1 p2 k3`` (radial
``1 + k1 r^2 + k2 r^4 + k3 r^6`` and tangential ``p1 p2`` terms on the normalised image
coordinates ``x = X/Z, y = Y/Z``). ``fisheye``: OpenCV's fisheye (Kannala-Brandt) model
``k1 k2 k3 k4``: the ray's angle ``θ`` from the axis maps to ``θ_d = θ (1 + k1 θ^2 + k2 θ^4 +
k3 θ^6 + k4 θ^8)`` along the same direction. Missing coefficients are zero; an empty tuple
is the ideal pinhole. Both agree with ``cv2.projectPoints`` / ``cv2.fisheye.projectPoints``
to 1e-9 px (tests/test_lens.py).
"""

from __future__ import annotations

import functools

import numpy as np
from numpy.polynomial import Polynomial

from planner.errors import InputError

LENS_MODELS = ("pinhole", "fisheye")
COEFFICIENTS = {"pinhole": ("k1", "k2", "p1", "p2", "k3"), "fisheye": ("k1", "k2", "k3", "k4")}
"""The coefficients each model takes, in OpenCV's order (camera YAML ``distortion: [...]``)."""


def padded(model: str, coefficients: tuple[float, ...]) -> np.ndarray:
    """The coefficients of ``model`` as OpenCV takes them (5 or 4 values, zeros filled in)."""
    n = len(COEFFICIENTS[model])
    if len(coefficients) > n:
        raise ValueError(f"the {model} lens takes at most {n} distortion coefficients "
                         f"({' '.join(COEFFICIENTS[model])}), got {len(coefficients)}")
    return np.array([*coefficients, *[0.0] * (n - len(coefficients))], dtype=float)


def distort_rays(model: str, coefficients: tuple[float, ...], rays: np.ndarray) -> np.ndarray:
    """Distorted normalised image coordinates (..., 2) of camera-frame rays or points (..., 3)
    (in front of the camera, ``Z > 0``; the fisheye model also takes rays at or past 90 deg)."""
    rays = np.asarray(rays, float)
    if model == "fisheye":
        d = padded(model, coefficients)
        rho = np.hypot(rays[..., 0], rays[..., 1])
        theta = np.arctan2(rho, rays[..., 2])
        t2 = theta * theta
        theta_d = theta * (1 + t2 * (d[0] + t2 * (d[1] + t2 * (d[2] + t2 * d[3]))))
        with np.errstate(invalid="ignore", divide="ignore"):
            scale = np.where(rho > 0, theta_d / np.where(rho > 0, rho, 1.0), 1.0 / rays[..., 2])
        return np.stack([rays[..., 0] * scale, rays[..., 1] * scale], axis=-1)
    return distort_normalized(model, coefficients, rays[..., :2] / rays[..., 2:3])


def distort_normalized(model: str, coefficients: tuple[float, ...], xy: np.ndarray) -> np.ndarray:
    """Distorted normalised coordinates (..., 2) of ideal normalised coordinates ``xy`` (..., 2)."""
    xy = np.asarray(xy, float)
    if model == "fisheye":
        return distort_rays(model, coefficients, np.concatenate([xy, np.ones_like(xy[..., :1])], axis=-1))
    k1, k2, p1, p2, k3 = padded(model, coefficients)
    x, y = xy[..., 0], xy[..., 1]
    r2 = x * x + y * y
    radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return np.stack([xd, yd], axis=-1)


def undistort_normalized(model: str, coefficients: tuple[float, ...], xy_d: np.ndarray,
                         iterations: int = 30) -> np.ndarray:
    """Ideal normalised coordinates (..., 2) whose distorted image is ``xy_d`` (..., 2): Newton's
    method on the distortion map, from the distorted point. Where the map folds (a lens pushed past
    its monotone range) the result is NaN, never a wrong point."""
    xy_d = np.asarray(xy_d, float)
    if not np.any(padded(model, coefficients)):
        return xy_d.copy()
    if model == "fisheye":
        d = padded(model, coefficients)
        theta_d = np.hypot(xy_d[..., 0], xy_d[..., 1])
        theta = theta_d.copy()
        for _ in range(iterations):
            t2 = theta * theta
            f = theta * (1 + t2 * (d[0] + t2 * (d[1] + t2 * (d[2] + t2 * d[3])))) - theta_d
            df = 1 + t2 * (3 * d[0] + t2 * (5 * d[1] + t2 * (7 * d[2] + t2 * 9 * d[3])))
            theta = theta - f / np.where(df > 0, df, np.nan)
        with np.errstate(invalid="ignore", divide="ignore"):
            scale = np.where(theta_d > 0, np.tan(theta) / np.where(theta_d > 0, theta_d, 1.0), 1.0)
        scale = np.where((theta >= 0) & (theta < np.pi / 2), scale, np.nan)
        return xy_d * scale[..., None]
    xy = xy_d.copy()
    step = 1e-7
    for _ in range(iterations):
        f = distort_normalized(model, coefficients, xy) - xy_d
        jx = (distort_normalized(model, coefficients, xy + [step, 0]) - f - xy_d) / step
        jy = (distort_normalized(model, coefficients, xy + [0, step]) - f - xy_d) / step
        det = jx[..., 0] * jy[..., 1] - jy[..., 0] * jx[..., 1]
        det = np.where(det > 0, det, np.nan)  # a fold or a flip: no unique ideal point
        dx = (jy[..., 1] * f[..., 0] - jy[..., 0] * f[..., 1]) / det
        dy = (-jx[..., 1] * f[..., 0] + jx[..., 0] * f[..., 1]) / det
        xy = xy - np.stack([dx, dy], axis=-1)
        if not np.any(np.abs(f) > 1e-15):  # converged everywhere (NaN, a fold, stops too)
            break
    residual = np.hypot(*np.moveaxis(distort_normalized(model, coefficients, xy) - xy_d, -1, 0))
    return np.where((residual < 1e-9)[..., None], xy, np.nan)


def radial_polynomials(coefficients: tuple[float, ...]) -> tuple[Polynomial, Polynomial]:
    """The pinhole model's radial factor ``L(s) = 1 + k1 s + k2 s^2 + k3 s^3`` in ``s = r^2``, and the
    derivative ``dρ/dr = 1 + 3 k1 s + 5 k2 s^2 + 7 k3 s^3`` of the distorted radius ``ρ = r L(r^2)``."""
    k1, k2, _, _, k3 = padded("pinhole", coefficients)
    return Polynomial([1.0, k1, k2, k3]), Polynomial([1.0, 3 * k1, 5 * k2, 7 * k3])


def poly_range(p: Polynomial, s0: float, s1: float) -> tuple[float, float]:
    """Exact minimum and maximum of polynomial ``p`` over ``[s0, s1]``: at the ends or a critical point.
    Every root's real part (clipped to the interval) is tried, so a nearly double root is never lost."""
    roots = np.asarray(p.deriv().roots(), dtype=complex)
    points = [s0, s1, *np.clip(roots.real, s0, s1).tolist()]
    values = p(np.array(points))
    return float(values.min()), float(values.max())


VIEW_SLACK = 1e-7
"""Relative shrink of the view rectangle below the lens's inverse (whose residual is under 1e-9)."""


@functools.lru_cache(maxsize=64)  # the error map asks it again for every simulated image of one camera
def view_rectangle(model: str, coefficients: tuple[float, ...],
                   sensor: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
    """The *view*: an axis-aligned rectangle ``(x_lo, x_hi, y_lo, y_hi)`` of ideal normalised coordinates
    about the axis whose distorted image lies on the sensor ``sensor`` (distorted normalised bounds).

    Its sides start at the nearer of the undistorted edge midpoint and the undistorted corners (barrel
    lenses: the midpoints; pincushion: the corners) and shrink until the sampled check passes: 400
    distorted points per side on the sensor and a positive Jacobian on a 41 x 41 grid. The proof checks
    the result exactly (:func:`planner.verify.envelope.envelope`). :class:`InputError` if the lens folds
    before any usable rectangle.
    """
    lo_x, hi_x, lo_y, hi_y = sensor
    names = " ".join(f"{n}={v:g}" for n, v in zip(COEFFICIENTS[model], padded(model, coefficients)))
    if not (lo_x < 0 < hi_x and lo_y < 0 < hi_y):
        raise InputError("the camera's principal point lies outside its image: check cx_px and cy_px")
    mids = undistort_normalized(model, coefficients, np.array([[lo_x, 0], [hi_x, 0], [0, lo_y], [0, hi_y]]))
    corners = undistort_normalized(model, coefficients, np.array([[lo_x, lo_y], [hi_x, lo_y], [lo_x, hi_y], [hi_x, hi_y]]))
    if np.isnan(mids).any():
        raise InputError(f"the {model} lens's distortion ({names}) folds inside the image, or takes in rays 90 deg "
                         "or more from its axis: check the coefficients and the focal length, or calibrate again")
    with np.errstate(invalid="ignore"):
        view = np.array([np.nanmax([mids[0, 0], corners[0, 0], corners[2, 0]]),
                         np.nanmin([mids[1, 0], corners[1, 0], corners[3, 0]]),
                         np.nanmax([mids[2, 1], corners[0, 1], corners[1, 1]]),
                         np.nanmin([mids[3, 1], corners[2, 1], corners[3, 1]])]) * (1 - VIEW_SLACK)
    for _ in range(700):  # 0.999 ** 700 ~ 0.5
        if _maps_onto(model, coefficients, view, sensor):
            return float(view[0]), float(view[1]), float(view[2]), float(view[3])
        view *= 0.999
    raise InputError(f"the {model} lens's distortion ({names}) maps no rectangle about the principal point onto "
                     "the image without folding: check the coefficients")


def _maps_onto(model: str, coefficients: tuple[float, ...], view: np.ndarray, sensor) -> bool:
    """Sampled check of :func:`view_rectangle`: the view's border distorts onto the sensor, the map does not fold."""
    x0, x1, y0, y1 = view
    t = np.linspace(0.0, 1.0, 400)
    border = np.concatenate([np.column_stack([x0 + (x1 - x0) * t, np.full_like(t, y)]) for y in (y0, y1)]
                            + [np.column_stack([np.full_like(t, x), y0 + (y1 - y0) * t]) for x in (x0, x1)])
    d = distort_normalized(model, coefficients, border)
    if not (np.all(d[:, 0] >= sensor[0]) and np.all(d[:, 0] <= sensor[1])
            and np.all(d[:, 1] >= sensor[2]) and np.all(d[:, 1] <= sensor[3])):
        return False
    g = np.stack(np.meshgrid(np.linspace(x0, x1, 41), np.linspace(y0, y1, 41)), axis=-1).reshape(-1, 2)
    step = 1e-6
    jx = (distort_normalized(model, coefficients, g + [step, 0]) - distort_normalized(model, coefficients, g)) / step
    jy = (distort_normalized(model, coefficients, g + [0, step]) - distort_normalized(model, coefficients, g)) / step
    return bool(np.all(jx[:, 0] * jy[:, 1] - jx[:, 1] * jy[:, 0] > 0))
