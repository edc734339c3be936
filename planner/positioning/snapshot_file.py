"""The observation file ``vlp-locate`` reads: a receiver's camera and the LED ellipses it decoded.

Format (``docs/positioning.md``), pixels with the origin at the image's top-left
corner, full axis lengths, major-axis angle from the image x axis in degrees::

    {"camera": {"fx": 4250.0, "fy": 4250.0, "cx": 2000.0, "cy": 1500.0, "width": 4000, "height": 3000,
                "lens": "pinhole", "distortion": [-0.2, 0.05]},
     "leds": [{"id": 5, "ellipse": {"cx": 2100.3, "cy": 1400.2, "major": 60.1, "minor": 50.2, "angle_deg": 30.0}}],
     "gravity": [0.05, -0.02, -0.99], "gravity_sigma_deg": 1.0}

``gravity`` (optional) is the accelerometer's down direction in the camera frame (x right, y down
the image, z along the optical axis; any length but zero); with it ``vlp-locate`` uses the
gravity-aided receiver (:mod:`planner.positioning.gravity`), ``gravity_sigma_deg`` its uncertainty
(default 1 deg).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from planner._files import load_json
from planner._schema import Count, Finite, Positive, validated
from planner.camera.ellipse import Ellipse
from planner.camera.file import Distortion, LensModel, check_distortion
from planner.camera.model import Camera
from planner.defaults import MAX_IMAGE_PX, MAX_OBSERVED_LEDS
from planner.positioning.locate import Snapshot


class _CameraFields(BaseModel):
    """The receiver's intrinsics [px]; ``fy`` defaults to ``fx``, the principal point to the image centre;
    ``lens`` and ``distortion`` as in a camera YAML (docs/camera.md), none by default."""

    model_config = ConfigDict(extra="ignore", frozen=True)

    fx: Positive
    fy: Positive | None = None
    cx: Finite | None = None
    cy: Finite | None = None
    width: Annotated[Count, Field(ge=1, le=MAX_IMAGE_PX)]
    height: Annotated[Count, Field(ge=1, le=MAX_IMAGE_PX)]
    lens: LensModel = "pinhole"
    distortion: Distortion = []

    @model_validator(mode="after")
    def _coefficients(self) -> _CameraFields:
        check_distortion(self.lens, self.distortion)
        return self


class _EllipseFields(BaseModel):
    model_config = ConfigDict(extra="ignore", frozen=True)

    cx: Finite
    cy: Finite
    major: Positive
    minor: Positive
    angle_deg: Finite

    @model_validator(mode="after")
    def _axes(self) -> _EllipseFields:
        if self.minor > self.major * (1 + 1e-9):
            raise ValueError(f"minor axis {self.minor:g} px is longer than major {self.major:g} px")
        return self


class _Led(BaseModel):
    model_config = ConfigDict(extra="ignore", frozen=True)

    id: Count
    ellipse: _EllipseFields


class ObservationFile(BaseModel):
    """An observation: the camera and the decoded LEDs (at most :data:`MAX_OBSERVED_LEDS`), centres inside the image."""

    model_config = ConfigDict(extra="ignore", frozen=True)

    camera: _CameraFields
    leds: Annotated[list[_Led], Field(max_length=MAX_OBSERVED_LEDS)]
    gravity: Annotated[list[Finite], Field(min_length=3, max_length=3)] | None = None
    gravity_sigma_deg: Annotated[Positive, Field(le=45)] = 1.0

    @model_validator(mode="after")
    def _inside(self) -> ObservationFile:
        if self.gravity is not None and math.hypot(*self.gravity) < 1e-9:
            raise ValueError("gravity: the vector is zero; give the accelerometer's down direction in the camera frame")
        w, h = self.camera.width, self.camera.height
        for k, led in enumerate(self.leds):
            e = led.ellipse
            if not (0 <= e.cx <= w and 0 <= e.cy <= h):
                raise ValueError(f"leds[{k}].ellipse: centre ({e.cx:g}, {e.cy:g}) px lies outside the {w} x {h} px "
                                 "image")
        return self


def parse_snapshot(doc, where: str = "observation") -> Snapshot:
    """A :class:`Snapshot` from the decoded JSON document; :class:`InputError` names the bad field."""
    obs = validated(ObservationFile, doc, where, "an observation", strict=True)
    c = obs.camera
    camera = Camera(c.width, c.height, c.fx, c.fy if c.fy is not None else c.fx,
                    c.cx if c.cx is not None else c.width / 2, c.cy if c.cy is not None else c.height / 2,
                    lens=c.lens, distortion=tuple(c.distortion))
    gravity = None if obs.gravity is None else np.array(obs.gravity) / math.hypot(*obs.gravity)
    return Snapshot(camera, [led.id for led in obs.leds],
                    [Ellipse(e.cx, e.cy, e.major, e.minor, math.radians(e.angle_deg) % math.pi)
                     for e in (led.ellipse for led in obs.leds)], gravity, math.radians(obs.gravity_sigma_deg))


def read_snapshot(path: str | Path) -> Snapshot:
    """Read an observation file; one-line :class:`InputError` for a missing file or bad JSON."""
    path = Path(path)
    return parse_snapshot(load_json(path, "observation file", "no such observation file"), str(path))


def snapshot_document(snap: Snapshot) -> dict:
    """The JSON mapping of a snapshot (inverse of :func:`parse_snapshot`), values rounded to 1/1000 px."""
    c = snap.camera
    return {
        "camera": {"fx": round(c.fx_px, 3), "fy": round(c.fy_px, 3), "cx": round(c.cx_px, 3), "cy": round(c.cy_px, 3),
                   "width": c.width_px, "height": c.height_px,
                   **({"lens": c.lens, "distortion": [float(k) for k in c.distortion]} if c.distorted else {})},
        "leds": [{"id": int(i), "ellipse": {"cx": round(e.cx, 3), "cy": round(e.cy, 3), "major": round(e.major, 3),
                                            "minor": round(e.minor, 3),
                                            "angle_deg": round(math.degrees(e.angle_rad), 3)}}
                 for i, e in zip(snap.ids, snap.ellipses)],
        **({"gravity": [round(float(g), 6) for g in snap.gravity],
            "gravity_sigma_deg": round(math.degrees(snap.gravity_sigma_rad), 6)} if snap.gravity is not None else {}),
    }
