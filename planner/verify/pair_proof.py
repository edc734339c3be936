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

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from planner.camera import Camera
from planner.verify.envelope import Envelope, NotProvable, envelope

# The three-LED proof's geometric tests, shared (they take any pair and any LEDs to test).
from planner.verify.proof import MIN_CELL_M, NEAR, PAIR_BUDGET, _apex_cover, _hull_depth, _near, _spindle_count, _strip

SEARCH_BUDGET = 3_000
"""Most pairs whose axis points are searched by cells (about 14 ms each, measured on grid-32);
beyond it the site is not proved (it is sampled). grid-256 needs 21,218 (2026-12-03)."""

_CHUNK = 20_000
_CELL_CHUNK = 4000
_NEAR_CELL = 4
"""LEDs nearest each cell's centre tested against it, beside those nearest the pair's middle."""


def _axis_alive(xy: np.ndarray, radii: np.ndarray, pairs: np.ndarray, env: Envelope, tree: cKDTree) -> np.ndarray:
    """Whether some axis point ``q`` of case B is not excluded for each pair (M, 2), by cells.

    ``q`` lies within the axis reach of both members. A cell (centre ``q0``, half-side ``s``) is
    excluded when it lies beyond that reach, when another LED lies within ``ρ - d - s sqrt 2`` of
    ``q0`` (it would lie in ``E(α')`` for every ``q`` of the cell), or when a disc no larger than the
    members' lies deeper than ``2 d`` in ``conv({a, b} ∪ D(q0, ρ - s sqrt 2))``. A pair is kept as soon
    as a cell centre is not excluded with the full ``ρ``, or a cell reaches :data:`MIN_CELL_M`.
    """
    n = len(xy)
    a, b = xy[pairs[:, 0]], xy[pairs[:, 1]]
    near = _near(tree, 0.5 * (a + b), min(NEAR, n))
    smallest = radii[pairs].min(axis=1)
    reach, rho, d, m = env.axis_reach_m, env.disc_m, env.install_m, 2.0 * env.install_m + 1e-9
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
            cand = np.hstack([near[ww], _near(tree, qq, min(_NEAR_CELL, n))])
            other = (cand != pairs[ww, :1]) & (cand != pairs[ww, 1:])
            close = np.linalg.norm(xy[cand] - qq[:, None], axis=2) < rho - d - gg[:, None]
            out[sl] |= (close & other).any(axis=1)
            r = rho - gg
            ok = r > 0
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
class PairProof:
    """The outcome of :func:`prove_pair_set`: the proved pairs, or why there are none."""

    pairs: np.ndarray | None
    reason: str
    envelope: dict | None

    @property
    def complete(self) -> bool:
        return self.pairs is not None


def prove_pair_set(xyz: np.ndarray, radii: np.ndarray, camera: Camera, install_tolerance_m: float) -> PairProof:
    """Every pair that may be a two-LED window at some pose, or the reason this site and camera are not proved."""
    try:
        env = envelope(camera, xyz, radii, install_tolerance_m)
        return PairProof(possible_window_pairs(xyz[:, :2], radii, env), "", env.summary())
    except NotProvable as exc:
        return PairProof(None, str(exc), None)
