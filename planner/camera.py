"""The camera model: the receiver the plan is made for.

Defaults follow the paper's experiment and PRODUCT.md: horizontal field of view
50.4 deg, a 4000 x 3000 px image (assumed; the paper does not say), receiver
0.5-1.5 m above the floor, tilt up to 40 deg, rolling-shutter row time 20 us.
Angles are radians inside; degrees only at the user's edge.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Camera:
    """A pinhole camera with a rolling shutter.

    Attributes
    ----------
    hfov_rad : float
        Horizontal field of view [rad].
    width_px, height_px : int
        Image size [px].
    min_height_m, max_height_m : float
        Range of receiver heights above the floor [m].
    max_tilt_rad : float
        Largest tilt of the optical axis from vertical, in any direction [rad].
    row_time_s : float
        Rolling-shutter time between two image rows [s].
    """

    hfov_rad: float = math.radians(50.4)
    width_px: int = 4000
    height_px: int = 3000
    min_height_m: float = 0.5
    max_height_m: float = 1.5
    max_tilt_rad: float = math.radians(40.0)
    row_time_s: float = 20e-6

    @property
    def focal_px(self) -> float:
        """Focal length in pixels, from the horizontal field of view."""
        return (self.width_px / 2) / math.tan(self.hfov_rad / 2)

    def to_dict(self) -> dict:
        """The camera as written into ``plan.yaml`` (degrees and SI units, as named)."""
        return {
            "hfov_deg": round(math.degrees(self.hfov_rad), 6),
            "width_px": self.width_px,
            "height_px": self.height_px,
            "focal_px": round(self.focal_px, 3),
            "receiver_height_m": [self.min_height_m, self.max_height_m],
            "max_tilt_deg": round(math.degrees(self.max_tilt_rad), 6),
            "row_time_s": self.row_time_s,
        }
