"""The pose envelope the proof of :mod:`planner.verify.proof` assumes, from the camera and the site.

One ceiling plane, a pinhole camera with square pixels, receiver heights and the largest
tilt: from these the angles (the cone inscribed in the image, the corner cone, an LED
disc's largest angular radius) and lengths (the spindle radius ``R``, the axis disc ``ρ``,
the reach) that the proof's two cases use. A site or camera outside them is not proved
(:class:`NotProvable` says why) and is sampled instead.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.camera import Camera
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


def envelope(camera: Camera, xyz: np.ndarray, radii: np.ndarray, install_tolerance_m: float) -> Envelope:
    """The proof's envelope for this site and camera; :class:`NotProvable` says why there is none."""
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
    f = camera.fx_px
    half = min(camera.cx_px, camera.width_px - camera.cx_px, camera.cy_px, camera.height_px - camera.cy_px)
    corner = math.atan(math.hypot(max(camera.cx_px, camera.width_px - camera.cx_px),
                                  max(camera.cy_px, camera.height_px - camera.cy_px)) / f)
    if camera.max_tilt_rad + corner >= math.pi / 2:
        raise NotProvable(f"tilt {math.degrees(camera.max_tilt_rad):.1f} deg + corner angle "
                          f"{math.degrees(corner):.1f} deg reaches the horizon")
    env = Envelope(ceiling, near, far, camera.max_tilt_rad, math.atan(half / f), corner, math.asin(r / near),
                   float(install_tolerance_m))
    if env.sure_rad <= 0:
        raise NotProvable("an LED's disc can fill the cone inscribed in the image")
    return env
