"""The proved pair set: every pair of LEDs that a pose of the envelope could take as its two-LED window.

The two-LED window (:mod:`planner.verify.pair_windows`) is the two wholly seen LEDs at the
smallest angle from the optical axis. The argument of :mod:`planner.verify.proof` carries over
with the third member gone. Take a pose, its window ``{a, b}``, the angle ``θ2`` of the farther
member, and the level set ``E(θ)`` (the ceiling points within ``θ`` of the axis, an ellipse):

* **A** (``θ2 <= α'``): both are wholly seen and no other LED lies inside ``E(θ2)``, which holds
  the ``R``-spindle of ``a, b``: so no other LED lies in that spindle (the three-LED proof allows
  one, the unknown third member; here none).
* **B** (``θ2 > α'``): ``E(α')`` holds the axis disc ``D(q, ρ)`` and no LED but ``a, b``, and every
  LED in ``conv({a, b} ∪ D(q, ρ))`` with a disc no larger than theirs is wholly seen and nearer,
  so that hull holds none. It holds a triangle on ``ab`` with its apex ``ρ`` from the line on
  ``q``'s side, so an LED deep in every such triangle excludes ``q`` on that side; ``q`` on the
  line belongs to both sides.

A pair is excluded only when both cases are; what is left is a superset of every two-LED window.
Installed luminaires lie up to ``d`` from the drawing, counted as in the three-LED proof (an LED
counts against a pair only when deeper than ``2 d``; spindles over every centre within ``R + d``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from planner.camera import Camera
from planner.verify.envelope import Envelope, NotProvable, ceiling_distances
from planner.verify.proof import (  # the three-LED proof's geometric tests: they take any pair and LEDs
    MIN_CELL_M,
    NEAR,
    PAIR_BUDGET,
    _apex_cover,
    _hull_depth,
    _near,
    _spindle_count,
    _strip,
)

SEARCH_BUDGET = 3_000
"""Most pairs whose axis points are searched by cells (about 14 ms each, measured on grid-32);
beyond it the site is not proved (it is sampled). grid-256 needs 21,218 (2026-12-03)."""

_CHUNK = 20_000
_CELL_CHUNK = 4000
_NEAR_CELL = 4
"""LEDs nearest each cell's centre tested against it, beside those nearest the pair's middle."""


def _depth_in_triangles(a: np.ndarray, b: np.ndarray, apex: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Depth of ``x`` (C, K, 2) in the triangles ``a b apex_j`` (a, b (C, 2), apex (C, J, 2)), least over ``j``
    (C, K); negative outside one of them."""
    p = [np.broadcast_to(a[:, None], apex.shape), np.broadcast_to(b[:, None], apex.shape), apex]
    orient = np.sign((p[1][..., 0] - p[0][..., 0]) * (p[2][..., 1] - p[0][..., 1])
                     - (p[1][..., 1] - p[0][..., 1]) * (p[2][..., 0] - p[0][..., 0]))  # (C, J)
    depth = np.full(x.shape[:2] + apex.shape[1:2], np.inf)
    for i in range(3):
        u, v = p[i], p[(i + 1) % 3]
        e = v - u
        length = np.maximum(np.linalg.norm(e, axis=-1), 1e-12)
        cross = e[:, None, :, 0] * (x[:, :, None, 1] - u[:, None, :, 1]) - e[:, None, :, 1] * (x[:, :, None, 0] - u[:, None, :, 0])
        depth = np.minimum(depth, orient[:, None] * cross / length[:, None])
    return np.where((orient != 0)[:, None], depth, -np.inf).min(axis=2)


def _axis_alive(xy: np.ndarray, radii: np.ndarray, pairs: np.ndarray, env: Envelope, tree: cKDTree) -> np.ndarray:
    """Whether some axis point ``q`` of case B is not excluded for each pair (M, 2), by cells.

    ``q`` lies within the axis reach of both members. A cell (centre ``q0``, half-side ``s``) is
    excluded when it lies beyond that reach, when another LED lies within ``ρ - d - s sqrt 2`` of
    ``q0`` (it would lie in ``E(α')`` for every ``q`` of the cell), or when a disc no larger than the
    members' lies deeper than ``2 d`` in ``conv({a, b} ∪ D(q0, ρ - s sqrt 2))``, or in every triangle
    ``a b c`` for the cell's corners ``c`` (the axis points ``q`` with that LED deep in ``a b q`` form
    a convex set, the meet of two wedges; every hull holds its triangle ``a b q``). A pair is kept as soon
    as a cell centre is not excluded with the full ``ρ``, or a cell reaches :data:`MIN_CELL_M`.
    """
    n = len(xy)
    a, b = xy[pairs[:, 0]], xy[pairs[:, 1]]
    near = _near(tree, 0.5 * (a + b), min(NEAR, n))
    smallest = radii[pairs].min(axis=1)
    reach, rho, d, m = env.axis_reach_m, env.disc_m, env.install_m, 2.0 * env.install_m + 1e-9
    area = np.array(env.axis_area) if isinstance(env, PairEnvelope) and env.axis_area else None
    spread = env.axis_spread_m if isinstance(env, PairEnvelope) else math.inf
    alive = np.zeros(len(pairs), dtype=bool)
    which = np.arange(len(pairs))
    centre, half = 0.5 * (a + b), np.full(len(pairs), reach)
    off = np.array([[-1, -1], [-1, 1], [1, -1], [1, 1]], dtype=float)

    def excluded(w, q, grow):
        out = np.zeros(len(w), dtype=bool)
        for c in range(0, len(w), _CELL_CHUNK):
            sl = slice(c, c + _CELL_CHUNK)
            ww, qq, gg = w[sl], q[sl], grow[sl]
            out[sl] |= (np.linalg.norm(qq - a[ww], axis=1) - gg > reach) | (np.linalg.norm(qq - b[ww], axis=1) - gg > reach)
            if area is not None:  # the camera stands in the working area: the axis point within the spread of it
                out[sl] |= _outside_by(qq, area) - gg > spread
            cand = np.hstack([near[ww], _near(tree, qq, min(_NEAR_CELL, n))])
            other = (cand != pairs[ww, :1]) & (cand != pairs[ww, 1:])
            close = np.linalg.norm(xy[cand] - qq[:, None], axis=2) < rho - d - gg[:, None]
            out[sl] |= (close & other).any(axis=1)
            small_all = radii[cand] <= smallest[ww][:, None]
            corners = qq[:, None] + (gg / np.sqrt(2))[:, None, None] * off[None]
            deep = _depth_in_triangles(a[ww], b[ww], corners, xy[cand]) > m
            out[sl] |= (deep & other & small_all).any(axis=1)
            r = rho - gg
            ok = (r > 0) & ~out[sl]
            if ok.any():
                tri = np.stack([a[ww[ok]], b[ww[ok]], b[ww[ok]]], axis=1)
                depth = _hull_depth(tri, qq[ok], r[ok], xy[cand[ok]])
                small = radii[cand[ok]] <= smallest[ww[ok]][:, None]
                out[np.flatnonzero(ok) + c] |= ((depth > m) & other[ok] & small).any(axis=1)
        return out

    while len(which):
        free = ~excluded(which, centre, np.zeros(len(which)))
        alive[which[free]] = True
        gone = excluded(which, centre, half * np.sqrt(2))
        alive[which[~gone & (half <= MIN_CELL_M)]] = True
        keep = ~gone & (half > MIN_CELL_M) & ~alive[which]
        which, centre, half = which[keep], centre[keep], half[keep] / 2
        centre = (centre[:, None, :] + off[None] * half[:, None, None]).reshape(-1, 2)
        which, half = np.repeat(which, 4), np.repeat(half, 4)
    return alive


def possible_window_pairs(xy: np.ndarray, radii: np.ndarray, env: Envelope, budget: int = PAIR_BUDGET) -> np.ndarray:
    """Pairs ``i < j`` (M, 2) that may be the two-LED window at some pose of the envelope;
    :class:`NotProvable` when more than ``budget`` pairs lie within reach."""
    n = len(xy)
    tree = cKDTree(xy)
    pairs = tree.query_pairs(env.reach_m + 2 * env.install_m, output_type="ndarray").astype(np.int64).reshape(-1, 2)
    if len(pairs) > budget:
        raise NotProvable(f"{len(pairs):,} pairs of luminaires within the camera's reach of "
                          f"{env.reach_m:.2f} m, over the proof's budget of {budget:,}")
    if len(pairs) == 0 or n < 3:
        return pairs
    keep = np.zeros(len(pairs), dtype=bool)
    undecided = np.zeros(len(pairs), dtype=bool)
    for start in range(0, len(pairs), _CHUNK):
        pr = pairs[start:start + _CHUNK]
        a, b = xy[pr[:, 0]], xy[pr[:, 1]]
        near = _near(tree, 0.5 * (a + b), min(NEAR, n))
        valid = (near != pr[:, :1]) & (near != pr[:, 1:])
        case_a = _spindle_count(a, b, xy[near], valid, env) == 0
        strip = _strip(tree, a, b, env.disc_m, n)
        sv = (strip >= 0) & (strip != pr[:, :1]) & (strip != pr[:, 1:])
        sv &= radii[np.maximum(strip, 0)] <= radii[pr].min(axis=1)[:, None]
        xs = xy[np.maximum(strip, 0)]
        case_b = (_apex_cover(a, b, xs, sv, env, 1.0) < 1) | (_apex_cover(a, b, xs, sv, env, -1.0) < 1)
        keep[start:start + len(pr)] = case_a
        undecided[start:start + len(pr)] = case_b & ~case_a  # beyond the line not excluded: search the axis points
    if undecided.sum() > SEARCH_BUDGET:
        raise NotProvable(f"{int(undecided.sum()):,} pairs need the search of their axis points, over the pair "
                          f"proof's budget of {SEARCH_BUDGET:,}")
    keep[undecided] = _axis_alive(xy, radii, pairs[undecided], env, tree)
    return pairs[keep]


@dataclass(frozen=True)
class PairEnvelope(Envelope):
    """The proof's envelope with the lens's true angles and two bounds that keep it finite past the horizon.

    The camera stands in the working area, so the axis point lies within ``far tan(tilt)`` of it
    (``axis_area``, ``axis_spread_m``); two LEDs in view are two LEDs of the site, no farther apart
    than its diameter; and a point in view lies within ``axis_bound_m`` of the axis point.
    """

    site_diameter_m: float = math.inf
    axis_bound_m: float = math.inf
    axis_spread_m: float = math.inf
    axis_area: tuple = ()

    @property
    def _bounded(self) -> bool:
        return self.tilt_rad + self.corner_rad < math.pi / 2 - 1e-9

    @property
    def reach_m(self) -> float:
        return min(super().reach_m if self._bounded else math.inf, self.site_diameter_m)

    @property
    def axis_reach_m(self) -> float:
        return min(super().axis_reach_m if self._bounded else math.inf, self.axis_bound_m)

    def summary(self) -> dict:
        out = {k: v for k, v in super().summary().items() if self._bounded or "reach" not in k}
        out.update(reach_m=round(self.reach_m, 4), axis_reach_m=round(self.axis_reach_m, 4),
                   axis_within_m_of_working_area=round(self.axis_spread_m, 4))
        return out


SURE_CAP_RAD = math.radians(75.0)
"""The sure-seen cone is narrowed so that tilt plus its half-angle stays under this (a bounded spindle radius)."""


def pair_envelope(camera: Camera, xyz: np.ndarray, radii: np.ndarray, install_tolerance_m: float,
                  area: np.ndarray | None) -> PairEnvelope:
    """The pair proof's envelope: the three-LED proof's where that exists, with the lens's angles from
    :meth:`~planner.camera.Camera.rays` (edge middles and corners: a radial lens's extremes), the sure cone
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
                        tuple(map(tuple, np.asarray(area, float))) if area is not None else ())


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
