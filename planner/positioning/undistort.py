"""Undistort first: a distorted camera's LED ellipses as the ideal pinhole of the same intrinsics sees them.

A lens's distortion bends a disc's image out of the conic every positioning formula
assumes (the paper's Eq. 1-14, P3P, the exact disc conics of
:func:`planner.camera.model.disc_dual_conic`). The receiver therefore moves the rim back:
:data:`RIM_SAMPLES` points of each fitted (distorted) ellipse are mapped through
:meth:`planner.camera.model.Camera.ideal_pixels` and an ellipse is fitted to them again
(:func:`planner.camera.ellipse.fit_ellipse`); positioning then runs on ``camera.ideal()``.
docs/positioning.md ("Distortion") gives the error this leaves.
"""

from __future__ import annotations

import numpy as np

from planner.camera.ellipse import Ellipse, fit_ellipse
from planner.camera.model import Camera
from planner.errors import PositioningError

RIM_SAMPLES = 64
"""Points taken round each distorted ellipse before it is undistorted and fitted again."""


def ellipse_points(ellipse: Ellipse, count: int = RIM_SAMPLES) -> np.ndarray:
    """``count`` points (count x 2) [px] evenly spread (in parameter) round an ellipse."""
    phi = 2 * np.pi * np.arange(count) / count
    return ellipse.centre + np.column_stack([np.cos(phi), np.sin(phi)]) @ ellipse.shape


def ideal_ellipses(ellipses: list[Ellipse], camera: Camera) -> tuple[list[Ellipse], Camera]:
    """The ellipses and camera the pinhole formulas take: unchanged for an ideal camera, else each
    ellipse's rim undistorted and refitted, with ``camera.ideal()``."""
    if not camera.distorted:
        return ellipses, camera
    out = []
    for k, e in enumerate(ellipses):
        ideal = camera.ideal_pixels(ellipse_points(e))
        if np.isnan(ideal).any():
            raise PositioningError(f"LED {k} (ellipse at {e.cx:.0f}, {e.cy:.0f} px) lies where the camera's lens model "
                                   "folds: it cannot be undistorted; check the distortion coefficients")
        out.append(fit_ellipse(ideal))
    return out, camera.ideal()
