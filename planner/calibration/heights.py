"""The paper's focal-length calibration (section 2.4): level photos of one steady LED at known distances below it.

Each photo gives the LED image's radius ``a`` [px] (the radius of a disc of the same area: the
pixels' share of the LED's level above the background, summed round the brightest blob, so that
the blurred rim counts by its share and the noise averages out); then :func:`planner.positioning.paper.fit_focal_length` fits ``f = f0 + k
(Z1 - Z)`` to ``f = (Z1 - Z) a / r``, the focal length drifting with autofocus.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from planner.errors import InputError
from planner.positioning.paper import fit_focal_length

MIN_SHOTS = 2
"""Fewest photos a straight-line fit takes."""


@dataclass(frozen=True)
class HeightFit:
    """The fitted line ``f = f0_px + k_px_per_m * distance`` and each shot's own focal length [px]."""

    f0_px: float
    k_px_per_m: float
    distances_m: tuple[float, ...]
    radii_px: tuple[float, ...]
    focal_px: tuple[float, ...]

    def focal_at(self, distance_m: float) -> float:
        """The fitted focal length at ``distance_m`` below the LED [px]."""
        return self.f0_px + self.k_px_per_m * distance_m


def led_image_radius_px(gray: np.ndarray, where: str = "the photo") -> float:
    """Radius of a disc with the area of the brightest LED image in the grey photo [px]."""
    img = np.asarray(gray, float)
    background, peak = float(np.median(img)), float(np.percentile(img, 99.99))
    if peak - background < 20.0:
        raise InputError(f"{where}: no bright LED in the photo (brightest {peak:.0f}, background {background:.0f} "
                         "of 255); photograph the steady luminaire from below, level, at a short exposure")
    mask = (img > background + 0.5 * (peak - background)).astype(np.uint8)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    blob = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    x, y, w, h = (int(v) for v in stats[blob, :4])
    if x == 0 or y == 0 or x + w >= img.shape[1] or y + h >= img.shape[0]:
        raise InputError(f"{where}: the LED image touches the photo's border; centre it in the image")
    pad = 4
    roi = img[max(y - pad, 0):y + h + pad, max(x - pad, 0):x + w + pad]
    level = float(np.median(img[labels == blob]))
    share = (roi - background) / max(level - background, 1.0)  # not clipped: the noise averages out
    return float(np.sqrt(share.sum() / np.pi))


def fit_heights(distances_m: list[float], radii_px: list[float], led_radius_m: float) -> HeightFit:
    """Section 2.4's line through the shots (distances below the LED [m], image radii [px])."""
    if len(distances_m) < MIN_SHOTS or len(set(distances_m)) < MIN_SHOTS:
        raise InputError(f"give at least {MIN_SHOTS} photos at different distances below the LED")
    f0, k = fit_focal_length(np.array(distances_m), np.array(radii_px), led_radius_m)
    focal = tuple(float(d * a / led_radius_m) for d, a in zip(distances_m, radii_px))
    return HeightFit(f0, k, tuple(distances_m), tuple(radii_px), focal)
