"""The observation file ``vlp-locate`` reads: a receiver's camera and the LED ellipses it decoded.

Format (``docs/positioning.md``), pixels with the origin at the image's top-left
corner, full axis lengths, major-axis angle from the image x axis in degrees::

    {"camera": {"fx": 4250.0, "fy": 4250.0, "cx": 2000.0, "cy": 1500.0, "width": 4000, "height": 3000},
     "leds": [{"id": 5, "ellipse": {"cx": 2100.3, "cy": 1400.2, "major": 60.1, "minor": 50.2, "angle_deg": 30.0}}]}
"""

from __future__ import annotations

import math
from pathlib import Path

from planner._files import load_json
from planner.camera import Camera
from planner.defaults import MAX_IMAGE_PX, MAX_OBSERVED_LEDS
from planner.ellipse import Ellipse
from planner.errors import InputError
from planner.positioning.locate import Snapshot


def _number(value, where: str, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InputError(f"{where} must be a number, got {value!r}")
    if positive and value <= 0:
        raise InputError(f"{where} must be positive, got {value!r}")
    return float(value)


def _field(mapping, key: str, where: str):
    if not isinstance(mapping, dict):
        raise InputError(f"{where} must be a mapping, got {type(mapping).__name__}")
    if key not in mapping:
        raise InputError(f"{where} lacks field {key!r}")
    return mapping[key]


def parse_snapshot(doc, where: str = "observation") -> Snapshot:
    """A :class:`Snapshot` from the decoded JSON document; :class:`InputError` names the bad field."""
    cam = _field(doc, "camera", where)
    w = int(_number(_field(cam, "width", f"{where}: camera"), f"{where}: camera.width", True))
    h = int(_number(_field(cam, "height", f"{where}: camera"), f"{where}: camera.height", True))
    fx = _number(_field(cam, "fx", f"{where}: camera"), f"{where}: camera.fx", True)
    fy = _number(cam.get("fy", fx), f"{where}: camera.fy", True)
    cx = _number(cam.get("cx", w / 2), f"{where}: camera.cx")
    cy = _number(cam.get("cy", h / 2), f"{where}: camera.cy")
    if max(w, h) > MAX_IMAGE_PX:
        raise InputError(f"{where}: camera image {w} x {h} px, larger than {MAX_IMAGE_PX:,} px on a side")
    leds = _field(doc, "leds", where)
    if not isinstance(leds, list):
        raise InputError(f"{where}: 'leds' must be a list")
    if len(leds) > MAX_OBSERVED_LEDS:
        raise InputError(f"{where}: {len(leds):,} LEDs in one image, more than the {MAX_OBSERVED_LEDS:,} a "
                         "photo can show whole; list the LEDs of one image")
    ids, ellipses = [], []
    for k, led in enumerate(leds):
        at = f"{where}: leds[{k}]"
        led_id = _field(led, "id", at)
        if isinstance(led_id, bool) or not isinstance(led_id, int) or led_id < 0:
            raise InputError(f"{at}.id must be a whole number >= 0, got {led_id!r}")
        e = _field(led, "ellipse", at)
        vals = {key: _number(_field(e, key, f"{at}.ellipse"), f"{at}.ellipse.{key}", key in ("major", "minor"))
                for key in ("cx", "cy", "major", "minor", "angle_deg")}
        if vals["minor"] > vals["major"] * (1 + 1e-9):
            raise InputError(f"{at}.ellipse: minor axis {vals['minor']:g} px is longer than major {vals['major']:g} px")
        if not (0 <= vals["cx"] <= w and 0 <= vals["cy"] <= h):
            raise InputError(f"{at}.ellipse: centre ({vals['cx']:g}, {vals['cy']:g}) px lies outside the "
                             f"{w} x {h} px image")
        ids.append(led_id)
        ellipses.append(Ellipse(vals["cx"], vals["cy"], vals["major"], vals["minor"],
                                math.radians(vals["angle_deg"]) % math.pi))
    return Snapshot(Camera(w, h, fx, fy, cx, cy), ids, ellipses)


def read_snapshot(path: str | Path) -> Snapshot:
    """Read an observation file; one-line :class:`InputError` for a missing file or bad JSON."""
    path = Path(path)
    return parse_snapshot(load_json(path, "observation file", "no such observation file"), str(path))


def snapshot_document(snap: Snapshot) -> dict:
    """The JSON mapping of a snapshot (inverse of :func:`parse_snapshot`), values rounded to 1/1000 px."""
    c = snap.camera
    return {
        "camera": {"fx": round(c.fx_px, 3), "fy": round(c.fy_px, 3), "cx": round(c.cx_px, 3), "cy": round(c.cy_px, 3),
                   "width": c.width_px, "height": c.height_px},
        "leds": [{"id": int(i), "ellipse": {"cx": round(e.cx, 3), "cy": round(e.cy, 3), "major": round(e.major, 3),
                                            "minor": round(e.minor, 3),
                                            "angle_deg": round(math.degrees(e.angle_rad), 3)}}
                 for i, e in zip(snap.ids, snap.ellipses)],
    }
