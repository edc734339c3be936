"""The observation model: what a receiver measures of the LEDs a camera pose sees.

For each LED wholly inside the image (the verification stage's rule and camera
model, :mod:`planner.camera.model`), the disc's rim is projected exactly, one point per
pixel of perimeter as an edge tracer finds them; each point gets Gaussian pixel
noise and is rounded to the pixel grid; the receiver then fits an ellipse
(:func:`planner.camera.ellipse.fit_ellipse`). Lengths in metres, image quantities in pixels.

With lens distortion the rim is projected through the lens (``Camera.project``), so the
ellipses are fitted to what a phone sees: no conic, and no exact ellipse even without
noise (the exact case fits :data:`EXACT_RIM_POINTS` noiseless points). "Wholly inside"
and "nearest the centre" follow the verification (the view, ray angle; docs/verification.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.camera.ellipse import Ellipse, centre_and_shape, ellipse_from_dual_conic, fit_ellipse
from planner.camera.model import Camera, disc_dual_conic, project_discs_at
from planner.defaults import NOISE_PX

EXACT_RIM_POINTS = 720
"""Noiseless rim points an exact observation through a distorting lens is fitted to."""


@dataclass(frozen=True)
class Sighting:
    """The LEDs one camera pose sees and the ellipses the receiver fits to them.

    ``index`` are indices into the site's luminaires, ordered by the distance of
    their image from the image centre (nearest first, as the paper picks them).
    """

    index: np.ndarray
    ellipses: list[Ellipse]


def rim_points(position: np.ndarray, rotation: np.ndarray, centres: np.ndarray, radii: np.ndarray,
               camera: Camera, counts) -> np.ndarray:
    """Image points [px] evenly spaced round horizontal discs' rims: ``counts[k]`` for disc k, stacked."""
    counts = np.asarray(counts, dtype=int)
    owner = np.repeat(np.arange(len(counts)), counts)
    phi = 2 * np.pi * (np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)) / counts[owner]
    ring = np.column_stack([np.cos(phi), np.sin(phi), np.zeros_like(phi)])
    rim = centres[owner] + radii[owner, None] * ring
    cam = (rim - position) @ rotation  # site -> camera: R^T (x - p), row-wise
    if camera.distorted:
        return camera.project(cam)
    return np.column_stack([camera.fx_px * cam[:, 0] / cam[:, 2] + camera.cx_px,
                            camera.fy_px * cam[:, 1] / cam[:, 2] + camera.cy_px])


def seen_leds(position: np.ndarray, rotation: np.ndarray, xyz: np.ndarray, radii: np.ndarray,
              camera: Camera) -> np.ndarray:
    """Indices of the LEDs whose whole disc images inside the image (the view), nearest the image centre first
    (by ray angle: ``u, v`` are ideal pixels)."""
    img = project_discs_at(position[None], rotation[None], xyz[None], radii[None], camera)
    inside = np.flatnonzero(img["inside"][0])
    off = np.hypot(img["u"][0, inside] - camera.cx_px, img["v"][0, inside] - camera.cy_px)
    return inside[np.argsort(off, kind="stable")]


def observe(position: np.ndarray, rotation: np.ndarray, xyz: np.ndarray, radii: np.ndarray, camera: Camera,
            rng: np.random.Generator | None = None, noise_px: float = NOISE_PX) -> Sighting:
    """Fitted ellipses of every LED the pose sees; exact ellipses when ``rng`` is None.

    Parameters
    ----------
    position, rotation
        Camera centre [m] and camera-to-site rotation (3 x 3).
    xyz, radii
        Every luminaire's centre (N x 3) [m] and radius (N,) [m].
    rng, noise_px
        Source and standard deviation [px] of the edge-point noise; with ``rng`` the
        points are also rounded to whole pixels.
    """
    index = seen_leds(position, rotation, xyz, radii, camera)
    cstar = disc_dual_conic(position, rotation, xyz[index], radii[index], camera)
    if len(index) == 0 or (rng is None and not camera.distorted):
        return Sighting(index, [ellipse_from_dual_conic(c) for c in cstar])
    if rng is None:
        counts = np.full(len(index), EXACT_RIM_POINTS)
        pts = rim_points(position, rotation, xyz[index], radii[index], camera, counts)
        return Sighting(index, [fit_ellipse(p) for p in np.split(pts, np.cumsum(counts)[:-1])])
    _, shape, _ = centre_and_shape(cstar)
    counts = np.maximum(16, (np.pi * np.trace(shape, axis1=1, axis2=2)).astype(int))  # perimeter [px]
    pts = rim_points(position, rotation, xyz[index], radii[index], camera, counts)
    pts = np.round(pts + rng.normal(0.0, noise_px, pts.shape))
    return Sighting(index, [fit_ellipse(p) for p in np.split(pts, np.cumsum(counts)[:-1])])
