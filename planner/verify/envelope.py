"""The pose envelope the proof of :mod:`planner.verify.proof` assumes, from the camera and the site.

One ceiling plane, a pinhole camera with square pixels (and, if the lens distorts, a radial
pinhole-model lens proved to map the view rectangle onto the sensor, :func:`proved_view`),
receiver heights and the largest tilt: from these the angles (the cone inscribed in the image, the corner cone, an LED
disc's largest angular radius) and lengths (the spindle radius ``R``, the axis disc ``ρ``,
the reach) that the proof's two cases use. A site or camera outside them is not proved
(:class:`NotProvable` says why) and is sampled instead.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.camera import lens
from planner.camera.model import Camera
from planner.errors import PlanningError
from planner.verify.window_set import SAME_HEIGHT_M


class NotProvable(PlanningError):
    """The envelope or the site is outside what the proof covers (the message says why)."""


@dataclass(frozen=True)
class Envelope:
    """What the proof assumes, in SI units: one ceiling plane, a pinhole camera, the pose envelope."""

    ceiling_m: float
    near_m: float
    far_m: float
    tilt_rad: float
    inscribed_rad: float
    corner_rad: float
    disc_rad: float
    install_m: float

    @property
    def sure_rad(self) -> float:
        """``α'``: LEDs whose centre lies within this angle of the axis are wholly seen."""
        return self.inscribed_rad - self.disc_rad

    @property
    def disc_m(self) -> float:
        """``ρ``: the ceiling disc about the axis point that lies within ``α'`` at every pose [m]."""
        return self.near_m * math.sin(self.sure_rad)

    @property
    def reach_m(self) -> float:
        """Farthest two ceiling points in view at one pose (the corner cone's section) [m]."""
        return self.far_m * (math.tan(self.tilt_rad + self.corner_rad) - math.tan(self.tilt_rad - self.corner_rad))

    @property
    def axis_reach_m(self) -> float:
        """Farthest a ceiling point in view lies from the axis point (the far end of the corner cone's section) [m]."""
        return self.far_m * (math.tan(self.tilt_rad + self.corner_rad) - math.tan(self.tilt_rad))

    @property
    def curvature_m(self) -> float:
        """``R``: the largest radius of curvature of ``E(θ)`` for ``θ <= α'`` [m] (``a^2/b`` of the section)."""
        t, th = self.tilt_rad, self.sure_rad
        a = 0.5 * self.far_m * (math.tan(t + th) - math.tan(t - th))
        e = math.sin(t) / math.cos(th)
        return a / math.sqrt(1.0 - e * e)

    def summary(self) -> dict:
        return {"ceiling_m": round(self.ceiling_m, 4), "ceiling_distance_m": [round(self.near_m, 4), round(self.far_m, 4)],
                "max_tilt_deg": round(math.degrees(self.tilt_rad), 4),
                "inscribed_deg": round(math.degrees(self.inscribed_rad), 4),
                "corner_deg": round(math.degrees(self.corner_rad), 4),
                "disc_deg": round(math.degrees(self.disc_rad), 4), "install_tolerance_m": self.install_m,
                "spindle_radius_m": round(self.curvature_m, 4), "axis_disc_m": round(self.disc_m, 4),
                "reach_m": round(self.reach_m, 4), "axis_reach_m": round(self.axis_reach_m, 4)}


def proved_view(camera: Camera) -> None:
    """Prove that ``camera.view_px`` (the rectangle of ideal pixels in which an LED counts as wholly seen)
    lies on the sensor and that the lens does not fold over it; :class:`NotProvable` says why not.

    For OpenCV's pinhole model with radial terms only, ``ρ(r) = r L(r^2)``, ``L(s) = 1 + k1 s + k2 s^2 +
    k3 s^3``. If ``dρ/dr > 0`` up to the farthest corner of the view and of the image (exact minimum of a
    cubic in ``s``: the map is monotone over the whole image), every
    point ``t q`` (``q`` on the view's border, ``0 <= t <= 1``) distorts onto the segment from the principal
    point to ``q``'s image; so it is enough that every border point lands on the sensor: on a side at
    ``x = X`` with ``y`` in ``[y0, y1]``, ``|x_d| <= |X| max L`` and ``|y_d| <= |y| max L`` with ``max L`` over
    that side's ``s`` range (exact again). Tangential terms and the fisheye model are not covered.
    """
    if not camera.distorted:
        return
    if camera.lens != "pinhole":
        raise NotProvable(f"the proof covers the pinhole lens model's radial terms; the {camera.lens} lens is "
                          "verified by sampling")
    k = camera.dist_coeffs
    if k[2] or k[3]:
        raise NotProvable(f"the lens has tangential distortion (p1={k[2]:g}, p2={k[3]:g}), which the proof does "
                          "not cover; verified by sampling")
    u0, u1, v0, v1 = camera.view_px
    f, cx, cy = camera.fx_px, camera.cx_px, camera.cy_px
    x0, x1, y0, y1 = (u0 - cx) / f, (u1 - cx) / f, (v0 - cy) / f, (v1 - cy) / f
    sensor = (-cx / f, (camera.width_px - cx) / f, -cy / f, (camera.height_px - cy) / f)
    big_l, slope = lens.radial_polynomials(camera.distortion)
    corners = camera.normalized(np.array([[0.0, 0.0], [camera.width_px, 0.0], [0.0, camera.height_px],
                                          [camera.width_px, camera.height_px]], dtype=float))
    if np.isnan(corners).any():
        raise NotProvable("the lens's radial map folds inside the image (in its corners, beyond the view)")
    corner2 = max(max(x0 * x0, x1 * x1) + max(y0 * y0, y1 * y1), float(np.max(np.sum(corners**2, axis=1))))
    if lens.poly_range(slope, 0.0, corner2)[0] <= 0:
        raise NotProvable("the lens's radial map is not monotone over the image (it folds before "
                          f"{math.degrees(math.atan(math.sqrt(corner2))):.1f} deg off axis)")
    t = np.polynomial.Polynomial([0.0, 1.0])  # the coordinate along a side
    for fixed, (lo, hi), (a, b), (c, d) in ((x0, (y0, y1), sensor[:2], sensor[2:]), (x1, (y0, y1), sensor[:2], sensor[2:]),
                                            (y0, (x0, x1), sensor[2:], sensor[:2]), (y1, (x0, x1), sensor[2:], sensor[:2])):
        radial = big_l(fixed * fixed + t * t)  # L along the side
        across, along = lens.poly_range(fixed * radial, lo, hi), lens.poly_range(t * radial, lo, hi)
        if not (a <= across[0] and across[1] <= b and c <= along[0] and along[1] <= d):
            raise NotProvable("the view rectangle is not proved to lie on the sensor (lens distortion)")


def ceiling_distances(camera: Camera, xyz: np.ndarray, radii: np.ndarray) -> tuple[float, float, float, float]:
    """The ceiling plane's height, its nearest and farthest distance above the receiver, and the largest LED
    radius [m], for any proof's envelope; :class:`NotProvable` where the site or camera allows none."""
    z = xyz[:, 2]
    if np.ptp(z) >= SAME_HEIGHT_M:
        raise NotProvable(f"the luminaires are not on one ceiling plane (heights {z.min():.3f}-{z.max():.3f} m)")
    if abs(camera.fx_px - camera.fy_px) > 1e-9 * camera.fx_px:
        raise NotProvable("the camera's pixels are not square (fx != fy): the nearest-to-centre rule is not by angle")
    ceiling = float(np.median(z))
    near, far = ceiling - camera.max_height_m, ceiling - camera.min_height_m
    r = float(np.max(radii))
    if near <= r:
        raise NotProvable(f"the receiver may come within {near:.2f} m of the ceiling, inside an LED's radius")
    return ceiling, near, far, r


def envelope(camera: Camera, xyz: np.ndarray, radii: np.ndarray, install_tolerance_m: float) -> Envelope:
    """The proof's envelope for this site and camera; :class:`NotProvable` says why there is none."""
    ceiling, near, far, r = ceiling_distances(camera, xyz, radii)
    proved_view(camera)
    f = camera.fx_px
    u0, u1, v0, v1 = camera.view_px  # the sensor itself without distortion
    cx, cy = camera.cx_px, camera.cy_px
    half = min(cx - u0, u1 - cx, cy - v0, v1 - cy)
    corner = math.atan(math.hypot(max(cx - u0, u1 - cx), max(cy - v0, v1 - cy)) / f)
    if camera.max_tilt_rad + corner >= math.pi / 2:
        raise NotProvable(f"tilt {math.degrees(camera.max_tilt_rad):.1f} deg + corner angle "
                          f"{math.degrees(corner):.1f} deg reaches the horizon")
    env = Envelope(ceiling, near, far, camera.max_tilt_rad, math.atan(half / f), corner, math.asin(r / near),
                   float(install_tolerance_m))
    if env.sure_rad <= 0:
        raise NotProvable("an LED's disc can fill the cone inscribed in the image")
    return env
