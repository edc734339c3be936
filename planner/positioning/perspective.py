"""The full-perspective method: the camera pose whose exact LED images match the ellipses seen.

No approximation of the LED image: the pose (position and orientation) starts from
P3P on the ellipse centres (OpenCV's solver, Ding et al. 2023) and from the paper's
weak-perspective position (P3P loses a root when two roots nearly coincide), the
ellipse sizes and shapes pick the best start, and a least-squares refinement
over every LED seen matches each predicted exact disc image (its dual conic,
:func:`planner.camera.model.disc_dual_conic`) to the fitted ellipse: centre and shape
matrix, five residuals per LED in pixels. That fit, every residual weighed alike, says
how well one pose explains the image (``residual_px``, what identification checks); the
position comes from a second fit from there with each residual divided by its standard
deviation under the error budget (:mod:`planner.positioning.uncertainty`: centres tens of
pixels, shapes about one), robust beyond three of them. ``docs/positioning.md`` compares
this with the paper's weak-perspective method.
"""

from __future__ import annotations

import numpy as np

from planner.camera.ellipse import Ellipse
from planner.camera.model import Camera
from planner.errors import PositioningError
from planner.positioning.error_terms import DEFAULT_TERMS, ErrorTerms
from planner.positioning.fix import (
    BAD_PX,
    Fix,
    anchor_triple,
    check_geometry,
    ellipse_residuals,
    observed,
    orientation_at,
    residuals_batch,
    rms,
)
from planner.positioning.paper import distance_weak_perspective, trilaterate_least_squares, trilaterate_same_height
from planner.positioning.uncertainty import residual_sigmas
from planner.positioning.undistort import ideal_ellipses

ROBUST_SIGMAS = 3.0
"""Whitened residual beyond which the weighted fit's soft-L1 loss turns linear: an ellipse off by more than
three standard deviations pulls the position less than its square would."""


def p3p_poses(xyz3: np.ndarray, centres3_px: np.ndarray, camera: Camera) -> list[tuple[np.ndarray, np.ndarray]]:
    """P3P's solutions as (camera centre [m], camera-to-site rotation), camera below the LEDs."""
    import cv2  # here, not at import: commands that never locate skip loading it

    n, rvecs, tvecs = cv2.solveP3P(np.ascontiguousarray(xyz3, dtype=np.float64),
                                   np.ascontiguousarray(centres3_px, dtype=np.float64),
                                   camera.intrinsics, None, flags=cv2.SOLVEPNP_P3P)
    out = []
    for rvec, tvec in zip(rvecs[:n], tvecs[:n]):
        r_wc = cv2.Rodrigues(rvec)[0]  # site -> camera
        position = -r_wc.T @ tvec.reshape(3)
        if np.all(np.isfinite(position)) and position[2] < xyz3[:, 2].min():
            out.append((position, r_wc.T))
    return out


def weak_perspective_pose(xyz3: np.ndarray, radii3: np.ndarray, ellipses3: list[Ellipse],
                          camera: Camera) -> tuple[np.ndarray, np.ndarray] | None:
    """The paper's position (Eq. 1-14) on three LEDs with the orientation fitted to it: a start for
    :func:`refine` where P3P's roots are lost (two close roots turn complex under small centre errors)."""
    focal = float(np.sqrt(camera.fx_px * camera.fy_px))
    d = np.array([distance_weak_perspective(e, r, focal, camera.cx_px, camera.cy_px) for e, r in zip(ellipses3, radii3)])
    try:
        if np.ptp(xyz3[:, 2]) < 1e-9:
            position = trilaterate_same_height(xyz3, d)
        else:
            position = trilaterate_least_squares(xyz3, d)[0]
    except PositioningError:
        return None
    if position[2] >= xyz3[:, 2].min():
        return None
    return position, orientation_at(position, xyz3, np.array([e.centre for e in ellipses3]), camera)


def initial_poses(xyz: np.ndarray, radii: np.ndarray, ellipses: list[Ellipse], anchor: list[int],
                  camera: Camera) -> list[tuple[np.ndarray, np.ndarray]]:
    """Starting poses: P3P's roots on the anchor LEDs' centres, and the weak-perspective pose."""
    centres = np.array([ellipses[k].centre for k in anchor])
    starts = p3p_poses(xyz[anchor], centres, camera)
    weak = weak_perspective_pose(xyz[anchor], radii[anchor], [ellipses[k] for k in anchor], camera)
    return starts + ([weak] if weak is not None else [])


def refine(position: np.ndarray, rotation: np.ndarray, xyz: np.ndarray, radii: np.ndarray,
           centres: np.ndarray, shapes: np.ndarray, camera: Camera, sigmas: np.ndarray | None = None,
           robust: bool = False) -> tuple[np.ndarray, np.ndarray, float]:
    """Least squares over the six pose parameters on :func:`ellipse_residuals`, each divided by its
    standard deviation ``sigmas`` [px] (:func:`planner.positioning.uncertainty.residual_sigmas`; None:
    all 1 px): Levenberg-Marquardt, or with ``robust`` a trust region on the soft-L1 loss scaled at
    :data:`ROBUST_SIGMAS`.
    Returns the position, rotation and the RMS of the unweighted residuals [px].

    The Jacobian is taken by forward differences in one batched evaluation.
    """
    from scipy.optimize import least_squares  # here, not at import: commands that never locate skip loading it
    from scipy.spatial.transform import Rotation

    args = (rotation, xyz, radii, centres, shapes, camera)
    w = 1.0 if sigmas is None else 1.0 / sigmas
    steps = np.diag(np.r_[np.full(3, 1e-7), np.full(3, 1e-7 * max(1.0, float(np.abs(position).max())))])

    def fun(x):
        return residuals_batch(x[None], *args)[0] * w

    def jac(x):
        r = residuals_batch(np.vstack([x, x + steps]), *args) * w
        return ((r[1:] - r[0]) / np.diag(steps)[:, None]).T

    start = np.concatenate([np.zeros(3), position])
    if robust:
        fit = least_squares(fun, start, jac=jac, x_scale="jac", loss="soft_l1", f_scale=ROBUST_SIGMAS)
    else:
        fit = least_squares(fun, start, jac=jac, x_scale="jac", method="lm")
    rot = rotation @ Rotation.from_rotvec(fit.x[:3]).as_matrix()
    return fit.x[3:], rot, rms(fit.fun / w)


def locate_perspective(xyz: np.ndarray, radii: np.ndarray, ellipses: list[Ellipse], camera: Camera,
                       terms: ErrorTerms = DEFAULT_TERMS) -> Fix:
    """Camera pose from three or more identified LEDs (``xyz`` N x 3 [m], ``radii`` [m]) and their ellipses,
    weighed by ``terms`` (the error budget the site is believed to have: the model, not its draws)."""
    xyz, radii = np.asarray(xyz, float), np.asarray(radii, float)
    ellipses, camera = ideal_ellipses(ellipses, camera)  # a distorting lens: undistorted first
    check_geometry(xyz)
    centres, shapes = observed(ellipses)
    best = None
    for position, rotation in initial_poses(xyz, radii, ellipses, anchor_triple(centres), camera):
        r = rms(ellipse_residuals(position, rotation, xyz, radii, centres, shapes, camera))
        if best is None or r < best[2]:
            best = (position, rotation, r)
    if best is None or best[2] >= BAD_PX:
        raise PositioningError("no camera pose below the luminaires explains the LED images")
    position, rotation, r = refine(best[0], best[1], xyz, radii, centres, shapes, camera)
    sigmas = residual_sigmas(centres, shapes, radii, camera, terms)
    position, rotation, _ = refine(position, rotation, xyz, radii, centres, shapes, camera, sigmas, robust=True)
    return Fix(position, rotation, r, "perspective", np.arange(len(xyz)))
