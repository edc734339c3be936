"""Candidate changes of a site for the advice (:mod:`planner.advice.advise`): the site, its coverage measure per receiver
mode, and the changes an integrator can make, knob by knob (receiver mode, camera profile, mounting height,
density), each list from the least to the most change. ``docs/advice.md``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial

import numpy as np

from planner.camera.model import Camera
from planner.layout.model import area_m2, fill_outline
from planner.receivers.base import Receiver
from planner.receivers.modes import RECEIVERS as MODES
from planner.receivers.modes import receiver_for
from planner.verify.windows import working_area

DENSER_MAX_LUMINAIRES = 20000
"""Denser layouts are tried up to this many luminaires."""

RAISE_M = (0.5, 1.0, 2.0)
"""How much higher the luminaires are tried [m]."""

DENSER = (2, 4, 8)
"""Luminaire count multipliers tried (a regular lattice over the working area)."""


@dataclass(frozen=True)
class Site:
    """What the coverage measure needs: luminaire centres (N, 3) [m], radii (N,) [m], the outline, the camera and
    the receiver mode."""

    xyz: np.ndarray
    radii: np.ndarray
    outline: Sequence[tuple[float, float]] | None
    camera: Camera
    receiver: str = "three"
    filled: bool = False  # the luminaires were laid out by ``--leds N`` in an outline-only drawing


def _coverage(mode: Receiver, site: Site, per_m2: float, seed: int) -> float:
    return mode.coverage(site.xyz, site.radii, site.outline, site.camera, per_m2, seed)


WINDOW_WORDS = {name: mode.window_words for name, mode in MODES.items()}
"""What a pose must see to decode, per receiver mode, as the summary and the report say it."""

RECEIVERS: dict[str, Callable[[Site, float, int], float]] = {name: partial(_coverage, mode) for name, mode in MODES.items()}
"""Coverage measure per receiver mode (``--receiver``, :mod:`planner.receivers.modes`): each mode is a candidate change."""


@dataclass(frozen=True)
class Change:
    """One change to a site: what it is for people, the vlp-plan flags that apply it, and how."""

    knob: str  # "receiver", "camera", "height" or "density"
    text: str
    flags: tuple[str, ...]  # empty: the site itself must change (e.g. redraw the luminaires)
    apply: Callable[[Site], Site] = dataclasses.field(compare=False, repr=False)
    camera: dict | None = None  # the camera file that applies a camera change (camera.to_dict())


def _camera_changes(site: Site) -> list[Change]:
    """The bundled phone profiles (``--camera NAME``) wider than the site's camera, held as the site's camera is
    (receiver heights, tilt)."""
    from planner.camera.file import camera_profiles

    now = math.degrees(site.camera.hfov_rad)
    held = {k: getattr(site.camera, k) for k in ("min_height_m", "max_height_m", "max_tilt_rad")}
    wider = sorted((p.camera for p in camera_profiles().values() if math.degrees(p.camera.hfov_rad) > now + 1.0),
                   key=lambda cam: cam.hfov_rad)
    out = []
    for cam in wider:
        cam = dataclasses.replace(cam, **held)

        def with_camera(s: Site, cam: Camera = cam) -> Site:
            return dataclasses.replace(s, camera=cam)

        out.append(Change("camera", f"camera {cam.name} ({math.degrees(cam.hfov_rad):.0f} deg wide, now {now:.0f})",
                          ("--camera", cam.name), with_camera, cam.to_dict()))
    return out


def _height_changes(site: Site) -> list[Change]:
    z = float(np.median(site.xyz[:, 2]))
    out = []
    for dz in RAISE_M:
        def raise_(s: Site, dz: float = dz) -> Site:
            xyz = s.xyz.copy()
            xyz[:, 2] += dz
            return dataclasses.replace(s, xyz=xyz)

        out.append(Change("height", f"luminaires {dz:g} m higher ({z + dz:g} m)",
                          ("--height", f"{z + dz:g}") if site.filled else (), raise_))
    return out


def _density_changes(site: Site) -> list[Change]:
    area = working_area(site.xyz[:, :2], site.outline)
    radius = float(np.median(site.radii))
    out = []
    for k in DENSER:
        n = k * len(site.xyz)
        if n * (2 * radius) ** 2 > area_m2(area) or n > DENSER_MAX_LUMINAIRES:
            break

        def denser(s: Site, n: int = n) -> Site:
            lums, _ = fill_outline(area, n, float(np.median(s.xyz[:, 2])), radius)
            xyz = np.array([[lum.x, lum.y, lum.z] for lum in lums])
            # poses over the same floor as the site's: the new lattice's hull is smaller than the old one's
            return dataclasses.replace(s, xyz=xyz, radii=np.full(len(lums), radius),
                                       outline=[(float(x), float(y)) for x, y in area])

        pitch = math.sqrt(area_m2(area) / n)
        out.append(Change("density", f"{n} luminaires ({k} x, {pitch:.2g} m apart)",
                          ("--leds", str(n)) if site.filled else (), denser))
    return out


def _receiver_changes(site: Site) -> list[Change]:
    def with_mode(mode: str) -> Callable[[Site], Site]:
        return lambda s: dataclasses.replace(s, receiver=mode)

    return [Change("receiver", f"receiver mode {mode}", ("--receiver", mode), with_mode(mode))
            for mode in RECEIVERS if MODES[mode] is not receiver_for(site.receiver)]


KNOBS = (_receiver_changes, _camera_changes, _height_changes, _density_changes)
"""Candidate changes per knob, each list from the least to the most change; the order of the table."""
