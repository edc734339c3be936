"""Cameras from files and names: a camera YAML (``docs/camera.md``) or a bundled profile
(``planner/data/cameras.yaml``: real phone cameras with the source of every figure)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from planner._files import load_yaml
from planner._schema import Count, Finite, Positive, Text, validated
from planner.camera.lens import COEFFICIENTS, LENS_MODELS
from planner.camera.model import Camera
from planner.defaults import MAX_FOCAL_PX, MAX_HEIGHT_M, MAX_IMAGE_PX
from planner.errors import InputError, UsageError

PROFILES_FILE = "cameras.yaml"
"""The bundled profiles, in ``planner/data/``."""


LensModel = Literal[LENS_MODELS]  # type: ignore[valid-type]  # the names, from planner.camera.lens
"""A lens model's name, as camera files, plans and observation files write it."""

Distortion = Annotated[list[Annotated[Finite, Field(ge=-100, le=100)]], Field(max_length=5)]
"""Distortion coefficients as the files write them (how many a lens takes: :func:`check_distortion`)."""


def check_distortion(lens: str, distortion: list[float]) -> None:
    """ValueError (a file reader's field error) if ``lens`` takes fewer coefficients than ``distortion`` holds."""
    if len(distortion) > len(COEFFICIENTS[lens]):
        raise ValueError(f"the {lens} lens takes at most {len(COEFFICIENTS[lens])} distortion "
                         f"coefficients ({' '.join(COEFFICIENTS[lens])}), got {len(distortion)}")


class CameraFields(BaseModel):
    """A camera's fields as ``plan.yaml`` and camera YAML files write them (``docs/camera.md``)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    width_px: Annotated[Count, Field(ge=1, le=MAX_IMAGE_PX)] = 4000
    height_px: Annotated[Count, Field(ge=1, le=MAX_IMAGE_PX)] = 3000
    fx_px: Annotated[Positive, Field(ge=1, le=MAX_FOCAL_PX)] | None = None
    fy_px: Annotated[Positive, Field(ge=1, le=MAX_FOCAL_PX)] | None = None
    cx_px: Finite | None = None
    cy_px: Finite | None = None
    hfov_deg: Annotated[Positive, Field(ge=0.1, lt=180)] | None = None
    receiver_height_m: tuple[Annotated[Finite, Field(ge=0, le=MAX_HEIGHT_M)],
                             Annotated[Finite, Field(ge=0, le=MAX_HEIGHT_M)]] = (0.5, 1.5)
    max_tilt_deg: Annotated[Finite, Field(ge=0, lt=80)] = 40.0
    row_time_s: Annotated[Positive, Field(le=1.0)] = 20e-6
    lens: LensModel = "pinhole"
    distortion: Distortion = []
    name: Annotated[Text, Field(max_length=64)] = ""

    @model_validator(mode="after")
    def _heights_in_order(self) -> CameraFields:
        low, high = self.receiver_height_m
        if low > high:
            raise ValueError(f"receiver_height_m must be [low, high] with low <= high, got [{low}, {high}]")
        for name, value, size in (("cx_px", self.cx_px, self.width_px), ("cy_px", self.cy_px, self.height_px)):
            if value is not None and not 0 <= value <= size:
                raise ValueError(f"{name} {value:g} lies outside the {self.width_px} x {self.height_px} px image")
        check_distortion(self.lens, self.distortion)
        return self

    def to_camera(self) -> Camera:
        return Camera.from_dict(self.model_dump(exclude_none=True))


class _ProfileFields(BaseModel):
    """One entry of ``cameras.yaml``."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    role: Text
    example: Text
    row_time_range_s: tuple[Annotated[Positive, Field(le=1.0)], Annotated[Positive, Field(le=1.0)]]
    camera: CameraFields
    sources: dict[str, Text]


@dataclass(frozen=True)
class Profile:
    """A bundled camera profile: the camera (its ``name`` set), what it stands for, and its sources."""

    camera: Camera
    role: str
    example: str
    row_time_range_s: tuple[float, float]
    sources: dict[str, str]

    @property
    def name(self) -> str:
        return self.camera.name


@cache
def camera_profiles() -> dict[str, Profile]:
    """The bundled profiles by name, in file order (checked as a camera file is)."""
    with resources.as_file(resources.files("planner") / "data" / PROFILES_FILE) as path:
        doc = load_yaml(path)
    out = {}
    for name, entry in doc.items():
        f = validated(_ProfileFields, entry, f"{PROFILES_FILE}: {name}", "a camera profile")
        cam = f.camera.model_copy(update={"name": name}).to_camera()
        out[name] = Profile(cam, f.role, f.example, f.row_time_range_s, dict(f.sources))
    return out


def camera_profile(name: str) -> Camera:
    """The bundled profile ``name``; :class:`UsageError` listing the names if there is none."""
    profiles = camera_profiles()
    if name not in profiles:
        raise UsageError(f"`camera` {name}: no such camera profile or file; profiles: {', '.join(profiles)} "
                         "(vlp-plan --list-cameras), or give a camera YAML file")
    return profiles[name].camera


def camera_from(spec: str) -> Camera:
    """``--camera NAME`` or ``--camera FILE``: a bundled profile's name, else a camera YAML file."""
    if spec in camera_profiles():
        return camera_profile(spec)
    path = Path(spec)
    if not path.exists() and path.suffix.lower() not in (".yaml", ".yml"):
        return camera_profile(spec)  # neither a profile nor a file: the line lists the profiles
    return read_camera(path)


def profile_rows() -> list[dict]:
    """One row per profile for ``--list-cameras``: name, role, lens, image size, horizontal field of view
    [deg], row time and its range [s], and the figures' sources."""
    rows = []
    for name, p in camera_profiles().items():
        c = p.camera
        rows.append({"name": name, "role": p.role, "example": p.example, "lens": c.lens,
                     "distortion": list(c.distortion), "width_px": c.width_px, "height_px": c.height_px,
                     "fx_px": c.fx_px, "hfov_deg": round(math.degrees(c.hfov_rad), 2), "row_time_s": c.row_time_s,
                     "row_time_range_s": list(p.row_time_range_s), "sources": p.sources})
    return rows


def read_camera(path: str | Path) -> Camera:
    """A camera from YAML: ``hfov_deg`` or intrinsics (``fx_px``...), image size, heights, tilt, row time.

    The fields are checked by :class:`~planner.plan.file.CameraFields`, as a plan's ``camera`` section is.
    """
    path = Path(path)
    doc = load_yaml(path, "no such camera file")
    if not isinstance(doc, dict):
        raise InputError(f"{path}: expected a mapping of camera fields ({', '.join(CameraFields.model_fields)})")
    return validated(CameraFields, doc, str(path), "a camera", known=CameraFields.model_fields).to_camera()
