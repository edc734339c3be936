"""The proved pair set: every pair of LEDs that a pose of the envelope could take as its two-LED window.

The two-LED window (:mod:`planner.verify.pair_windows`) is the two wholly seen LEDs at the
smallest angle from the optical axis. The argument of :mod:`planner.verify.proof` carries over
with the third member gone. Take a pose, its window ``{a, b}``, the angle ``θ2`` of the farther
member, and the level set ``E(θ)`` (the ceiling points within ``θ`` of the axis, an ellipse):

* **A** (``θ2 <= α'``): both are wholly seen and no other LED lies inside ``E(θ2)``, which holds
  the ``R``-spindle of ``a, b``: so no other LED lies in that spindle (the three-LED proof allows
  one, the unknown third member; here none).
* **B** (``θ2 > α'``): ``E(α')`` holds the axis disc ``D(q, ρ)`` and no LED but ``a, b``, both lie in
  the view ``E(κ)``, and every LED in ``conv({a, b} ∪ D(q, ρ))`` with a disc no larger than theirs is
  wholly seen and nearer, so that hull holds none. Searched once for the site over cells of axis
  points (:mod:`planner.verify.pair_cells`).

A pair is excluded only when both cases are; what is left is a superset of every two-LED window.
The envelope is cut into :data:`SLICES` ranges of ceiling distance and tilt, each proved with its own
sure cone, sure disc ``ρ = L sin α'`` (``L`` the least distance to the axis point), reach, spindle and
view box (:class:`PairEnvelope`); a pair is kept if some range keeps it.
Installed luminaires lie up to ``d`` from the drawing, counted as in the three-LED proof (an LED
counts against a pair only when deeper than ``2 d``; spindles over every centre within ``R + d``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial import cKDTree

from planner.camera.model import Camera
from planner.verify.envelope import Envelope, NotProvable, ceiling_distances
from planner.verify.exclusion import NEAR, _near, _spindle_count  # the three-LED proof's spindle test
from planner.verify.pair_cells import case_b_pairs
from planner.verify.proof import PAIR_BUDGET

SLICES = (4, 4)
"""The envelope is cut into this many ranges of ceiling distance and of tilt; each range has its own sure
disc, reach and spindle (a pair is kept if some range keeps it)."""

_CHUNK = 20_000


def possible_window_pairs(xy: np.ndarray, radii: np.ndarray, env: PairEnvelope, budget: int = PAIR_BUDGET) -> np.ndarray:
    """Pairs ``i < j`` (M, 2) that may be the two-LED window at some pose of the envelope: the union over
    its slices (:meth:`PairEnvelope.slices`) of case A's and case B's; :class:`NotProvable` when more than
    ``budget`` pairs lie within reach."""
    n = len(xy)
    tree = cKDTree(xy)
    pairs = tree.query_pairs(env.reach_m + 2 * env.install_m, output_type="ndarray").astype(np.int64).reshape(-1, 2)
    if len(pairs) > budget:
        raise NotProvable(f"{len(pairs):,} pairs of luminaires within the camera's reach of "
                          f"{env.reach_m:.2f} m, over the proof's budget of {budget:,}")
    if len(pairs) == 0 or n < 3:
        return pairs
    area = np.array(env.axis_area) if env.axis_area else None
    kept = np.zeros(len(pairs), dtype=bool)
    code = pairs[:, 0] * n + pairs[:, 1]
    length = np.linalg.norm(xy[pairs[:, 0]] - xy[pairs[:, 1]], axis=1)
    for sl in env.slices():
        short = np.flatnonzero(~kept & (length <= sl.sure_diameter_m + 2 * sl.install_m))
        for start in range(0, len(short), _CHUNK):
            pr = pairs[short[start:start + _CHUNK]]
            a, b = xy[pr[:, 0]], xy[pr[:, 1]]
            near = _near(tree, 0.5 * (a + b), min(NEAR, n))
            valid = (near != pr[:, :1]) & (near != pr[:, 1:])
            kept[short[start:start + _CHUNK]] |= _spindle_count(a, b, xy[near], valid, sl) == 0
        served = case_b_pairs(xy, radii, sl, area, sl.axis_spread_m, _outside_by, pairs[kept])
        kept |= np.isin(code, served[:, 0] * n + served[:, 1])
    return pairs[kept]


@dataclass(frozen=True)
class PairEnvelope(Envelope):
    """The proof's envelope with the lens's true angles, two bounds that keep it finite past the horizon,
    and the least tilt (a slice of the envelope, :meth:`slices`, has one above 0).

    The camera stands in the working area, so the axis point lies within ``far tan(tilt)`` of it
    (``axis_area``, ``axis_spread_m``); two LEDs in view are two LEDs of the site, no farther apart
    than its diameter; and a point in view lies within ``axis_bound_m`` of the axis point.
    """

    site_diameter_m: float = math.inf
    axis_bound_m: float = math.inf
    axis_spread_m: float = math.inf
    axis_area: tuple = ()
    tilt_min_rad: float = 0.0
    view_inscribed_rad: float = math.inf
    area_diameter_m: float = math.inf
    led_radius_m: float = 0.0

    @property
    def _bounded(self) -> bool:
        return self.tilt_rad + self.corner_rad < math.pi / 2 - 1e-9

    @property
    def disc_m(self) -> float:
        """``ρ = L sin α'`` with ``L = near / cos(least tilt)`` the least distance to the axis point: a point
        ``s`` from the axis point lies within ``asin(s / L)`` of the axis at any tilt (the largest angle over
        directions, ``tan θ = s sqrt(1 - c²) / (L + s c)``, is at ``c = -s / L``)."""
        return self.near_m / math.cos(self.tilt_min_rad) * math.sin(self.sure_rad)

    @property
    def reach_m(self) -> float:
        return min(super().reach_m if self._bounded else math.inf, self.site_diameter_m)

    @property
    def axis_reach_m(self) -> float:
        return min(super().axis_reach_m if self._bounded else math.inf, self.axis_bound_m)

    @property
    def view_back_m(self) -> float:
        """Farthest a point in view lies behind the axis point, against the tilt (``E(κ)``'s near end) [m]."""
        k = self.corner_rad
        return max(self.far_m * (math.tan(t) - math.tan(t - k)) for t in (self.tilt_min_rad, self.tilt_rad))

    @property
    def view_side_m(self) -> float:
        """Farthest a point in view lies to the side of the tilt's plane (``E(κ)``'s semi-minor axis,
        ``h sin κ / sqrt(cos² τ - sin² κ)``) [m]; infinite past the horizon."""
        c, k = math.cos(self.tilt_rad), math.sin(self.corner_rad)
        return self.far_m * k / math.sqrt(c * c - k * k) if c > k + 1e-9 else math.inf

    @property
    def sure_diameter_m(self) -> float:
        """Farthest apart two points within ``α'`` of the axis lie (the major axis of ``E(α')``) [m]: case A's pairs."""
        t, th = self.tilt_rad, self.sure_rad
        return self.far_m * (math.tan(t + th) - math.tan(t - th)) if t + th < math.pi / 2 - 1e-9 else self.reach_m

    def slices(self) -> list[PairEnvelope]:
        """The envelope cut into :data:`SLICES` ranges of ceiling distance and tilt, each a sound envelope for
        the poses in it: its own sure cone (the disc's angular radius at its nearest distance), sure disc,
        reach, spindle and spread (at its farthest distance and largest tilt)."""
        hs = np.linspace(self.near_m, self.far_m, SLICES[0] + 1)
        ts = np.linspace(0.0, self.tilt_rad, SLICES[1] + 1)
        out = []
        for h0, h1 in zip(hs[:-1], hs[1:]):
            disc = math.asin(self.led_radius_m / h0)
            for t0, t1 in zip(ts[:-1], ts[1:]):
                inscribed = min(self.view_inscribed_rad, SURE_CAP_RAD - t1 + disc)
                spread = h1 * math.tan(t1)
                out.append(replace(self, near_m=float(h0), far_m=float(h1), tilt_rad=float(t1), tilt_min_rad=float(t0),
                                   inscribed_rad=inscribed, disc_rad=disc, axis_spread_m=spread,
                                   axis_bound_m=self.area_diameter_m + spread + 2 * self.install_m))
        return out

    def summary(self) -> dict:
        out = {k: v for k, v in super().summary().items() if self._bounded or "reach" not in k}
        out.update(reach_m=round(self.reach_m, 4), axis_reach_m=round(self.axis_reach_m, 4),
                   axis_within_m_of_working_area=round(self.axis_spread_m, 4), slices=list(SLICES))
        return out


SURE_CAP_RAD = math.radians(75.0)
"""The sure-seen cone is narrowed so that tilt plus its half-angle stays under this (a bounded spindle radius)."""


def pair_envelope(camera: Camera, xyz: np.ndarray, radii: np.ndarray, install_tolerance_m: float,
                  area: np.ndarray | None) -> PairEnvelope:
    """The pair proof's envelope: the three-LED proof's where that exists, with the lens's angles from
    :meth:`~planner.camera.model.Camera.rays` (edge middles and corners: a radial lens's extremes), the sure cone
    narrowed to :data:`SURE_CAP_RAD` less the tilt, and reach bounded by the site; :class:`NotProvable` else."""
    ceiling, near, far, r = ceiling_distances(camera, xyz, radii)
    w, h, cx, cy = float(camera.width_px), float(camera.height_px), camera.cx_px, camera.cy_px

    def angle(px):
        return np.arccos(np.clip(camera.rays(np.array(px, float))[:, 2], -1.0, 1.0))

    edges, corners = angle([[0, cy], [w, cy], [cx, 0], [cx, h]]), angle([[0, 0], [w, 0], [0, h], [w, h]])
    if not (np.isfinite(edges).all() and np.isfinite(corners).all()):
        raise NotProvable("the lens model folds inside the image: its angles at the border are not defined")
    disc = math.asin(r / near)
    inscribed = min(float(edges.min()), SURE_CAP_RAD - camera.max_tilt_rad + disc)
    if inscribed - disc <= 0:
        raise NotProvable("an LED's disc can fill the cone inscribed in the image")
    spread = far * math.tan(camera.max_tilt_rad)
    pts = np.vstack([xyz[:, :2]] + ([np.asarray(area, float)] if area is not None else []))
    diameter = float(np.max(np.linalg.norm(pts[:, None] - pts[None], axis=2))) if len(pts) < 4000 else math.inf
    led_diameter = float(np.max(np.linalg.norm(xyz[:, None, :2] - xyz[None, :, :2], axis=2))) if len(xyz) < 4000 \
        else math.inf
    return PairEnvelope(ceiling, near, far, camera.max_tilt_rad, inscribed, float(corners.max()), disc,
                        float(install_tolerance_m), led_diameter + 2 * install_tolerance_m,
                        diameter + spread + 2 * install_tolerance_m, spread,
                        tuple(map(tuple, np.asarray(area, float))) if area is not None else (),
                        0.0, float(edges.min()), diameter, r)


def _outside_by(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Distance [m] of ``points`` (M, 2) from ``polygon`` (K, 2): 0 inside."""
    from matplotlib.path import Path as PolygonPath

    a, b = polygon, np.roll(polygon, -1, axis=0)
    ab = b - a
    t = np.clip(np.einsum("mkd,kd->mk", points[:, None] - a[None], ab) / np.maximum((ab ** 2).sum(1), 1e-18), 0, 1)
    dist = np.linalg.norm(points[:, None] - (a[None] + t[..., None] * ab[None]), axis=2).min(axis=1)
    return np.where(PolygonPath(polygon).contains_points(points), 0.0, dist)


@dataclass(frozen=True)
class PairProof:
    """The outcome of :func:`prove_pair_set`: the proved pairs, or why there are none."""

    pairs: np.ndarray | None
    reason: str
    envelope: dict | None

    @property
    def complete(self) -> bool:
        return self.pairs is not None


def prove_pair_set(xyz: np.ndarray, radii: np.ndarray, camera: Camera, install_tolerance_m: float,
                   area: np.ndarray | None = None) -> PairProof:
    """Every pair that may be a two-LED window at some pose with the camera over ``area`` (the working area;
    None: anywhere), or the reason this site and camera are not proved."""
    try:
        env = pair_envelope(camera, xyz, radii, install_tolerance_m, area)
        return PairProof(possible_window_pairs(xyz[:, :2], radii, env), "", env.summary())
    except NotProvable as exc:
        return PairProof(None, str(exc), None)
