"""Read a camera YAML file (documented in ``docs/camera.md``) into a :class:`Camera`."""

from __future__ import annotations

from pathlib import Path

from planner._files import load_yaml
from planner._schema import validated
from planner.camera import Camera
from planner.errors import InputError
from planner.plan_file import CameraFields


def read_camera(path: str | Path) -> Camera:
    """A camera from YAML: ``hfov_deg`` or intrinsics (``fx_px``...), image size, heights, tilt, row time.

    The fields are checked by :class:`~planner.plan_file.CameraFields`, as a plan's ``camera`` section is.
    """
    path = Path(path)
    doc = load_yaml(path, "no such camera file")
    if not isinstance(doc, dict):
        raise InputError(f"{path}: expected a mapping of camera fields ({', '.join(CameraFields.model_fields)})")
    return validated(CameraFields, doc, str(path), "a camera", known=CameraFields.model_fields).to_camera()
