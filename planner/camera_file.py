"""Read a camera YAML file (documented in ``docs/camera.md``) into a :class:`Camera`."""

from __future__ import annotations

import math
from pathlib import Path

from planner._files import load_yaml
from planner.camera import Camera
from planner.errors import InputError

_KNOWN = {"width_px", "height_px", "fx_px", "fy_px", "cx_px", "cy_px", "hfov_deg", "receiver_height_m",
          "max_tilt_deg", "row_time_s"}


def read_camera(path: str | Path) -> Camera:
    """A camera from YAML: ``hfov_deg`` or intrinsics (``fx_px``...), image size, heights, tilt, row time."""
    path = Path(path)
    doc = load_yaml(path, "no such camera file")
    if not isinstance(doc, dict):
        raise InputError(f"{path}: expected a mapping of camera fields ({', '.join(sorted(_KNOWN))})")
    unknown = sorted(set(doc) - _KNOWN)
    if unknown:
        raise InputError(f"{path}: unknown field {unknown[0]!r}; known: {', '.join(sorted(_KNOWN))}")
    try:
        cam = Camera.from_dict(doc)
    except (TypeError, ValueError, IndexError) as exc:
        raise InputError(f"{path}: a field has the wrong type ({exc})") from exc
    checks = [
        (cam.width_px > 0 and cam.height_px > 0, "width_px and height_px must be positive"),
        (cam.fx_px > 0 and cam.fy_px > 0, "focal lengths must be positive"),
        (0 <= cam.min_height_m <= cam.max_height_m, "receiver_height_m must be [low, high] with 0 <= low <= high"),
        (0 <= cam.max_tilt_rad < math.radians(80), "max_tilt_deg must be in [0, 80)"),
        (cam.row_time_s > 0, "row_time_s must be positive"),
        (0 < cam.hfov_rad < math.pi, "the field of view must be between 0 and 180 deg"),
    ]
    for ok, message in checks:
        if not ok:
            raise InputError(f"{path}: {message}")
    return cam
