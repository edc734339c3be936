"""How far each measured ellipse number may be off under the error budget: the fits' weights.

The perspective and gravity fits compare five numbers per LED, its ellipse's centre (2) and
shape matrix (3 entries) [px] (:func:`planner.positioning.fix.residuals_batch`). They are not
equally reliable: a luminaire 2 cm off its drawn position moves its image's centre by tens of
pixels but leaves its shape (which measures the distance and the viewing angle) nearly alone.
Weighted equally, the fit follows the centres along the shift-tilt valley of a pose from LEDs on
one plane (docs/positioning.md, "Error budget") and errs by decimetres where the paper's
method, which uses the sizes, errs by centimetres. Here each residual gets its standard deviation
under :class:`planner.positioning.error_terms.ErrorTerms`, to first order and from the
observation alone (no pose): the LED's image scale ``a / r`` [px/m] (semi-axis over radius)
stands in for ``f / Z``, and the axis ratio ``b / a = cos(beta)`` gives the angle ``beta``
between the LED's ray and its normal. Per LED (all in px):

- centre, per axis: install ``(install_m / 2) a / r`` (a uniform disc of radius R has an
  RMS of R / 2 per axis); principal point; focal ``focal_rel * |c - c0|``; the distortion
  residual; skew ``w t_row |v - c_y| / sqrt 2`` with ``w = speed a / r + turn f`` the image
  speed [px/s]; edge noise ``sqrt((edge^2 + 1/12) 2 / N)`` over ``N`` rim points.
- shape entries ``M00, M01, M11``: focal ``focal_rel |M_ij|`` (the image scales); install
  ``a sin(beta) (install_m / 2) / Z`` (the viewing angle changes; zero for a level camera's
  image); skew ``0, g / 2, g`` with ``g = a t_row w / sqrt 2`` (the image shears along the rows
  while the LED's rows are read: ``M -> (I + G) M``, ``G`` nonzero in its second column only);
  edge noise as for the centre.

The fits are told the model (the terms' sizes), never the draws.
"""

from __future__ import annotations

import math

import numpy as np

from planner.camera.model import Camera
from planner.positioning.error_terms import ErrorTerms

FLOOR_PX = 1e-3
"""Smallest standard deviation given a residual [px]: exact images (no term) still weigh finitely."""


def residual_sigmas(centres_px: np.ndarray, shapes_px: np.ndarray, radii_m: np.ndarray, camera: Camera,
                    terms: ErrorTerms) -> np.ndarray:
    """Standard deviations [px] of the residuals of :func:`planner.positioning.fix.residuals_batch`, in its
    order (centre x, y, shape entries 00, 01, 11 per LED, flattened), for LEDs seen with these centres
    (N x 2) and shape matrices (N x 2 x 2) [px], radii (N,) [m] and ``terms`` at work."""
    centres_px, shapes_px = np.asarray(centres_px, float), np.asarray(shapes_px, float)
    eig = np.linalg.eigvalsh(shapes_px)  # semi-axes, minor first
    a = np.maximum(eig[:, 1], 1e-9)
    scale = a / np.asarray(radii_m, float)  # px per metre at the LED: f / Z
    sin_beta = np.sqrt(np.clip(1.0 - (eig[:, 0] / a) ** 2, 0.0, 1.0))
    focal = math.sqrt(camera.fx_px * camera.fy_px)
    off = np.hypot(centres_px[:, 0] - camera.cx_px, centres_px[:, 1] - camera.cy_px)
    speed = terms.speed_m_s * scale + terms.turn_rad_s * focal  # image speed [px/s]
    rim_points = np.maximum(16.0, 2 * math.pi * np.sqrt(np.maximum(eig[:, 0], 1e-9) * a))
    edge2 = (terms.edge_px ** 2 + (1 / 12 if terms.edge_px > 0 else 0.0)) * 2 / rim_points
    install = terms.install_m / 2 * scale
    skew_centre = speed * camera.row_time_s * np.abs(centres_px[:, 1] - camera.cy_px) / math.sqrt(2)
    centre = np.sqrt(install ** 2 + terms.principal_px ** 2 + (terms.focal_rel * off) ** 2
                     + terms.distortion_px ** 2 + skew_centre ** 2 + edge2 + FLOOR_PX ** 2)
    entries = np.column_stack([shapes_px[:, 0, 0], shapes_px[:, 0, 1], shapes_px[:, 1, 1]])
    shear = a * camera.row_time_s * speed / math.sqrt(2)  # per image axis, on the row direction's entries
    shape = np.sqrt((terms.focal_rel * entries) ** 2 + ((a * sin_beta * install / focal) ** 2)[:, None]
                    + np.column_stack([np.zeros_like(a), shear / 2, shear]) ** 2 + (edge2 + FLOOR_PX ** 2)[:, None])
    return np.column_stack([centre, centre, shape]).ravel()
