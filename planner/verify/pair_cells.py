"""Case B of the pair proof searched once for the whole site: cells of axis points, and the pairs each can serve.

A pose in case B (:mod:`planner.verify.pair_proof`) has its axis point ``q`` with no LED but the
window's within ``ρ - d`` of it, both members within the axis reach of ``q``, and no disc no larger
than theirs deeper than ``2 d`` in ``conv({a, b} ∪ D(q, ρ))``. Instead of searching the axis points of
each pair, one set of cells covers every axis point of the envelope; for a cell (centre ``q0``, radius
``g``) every ``q`` in it holds ``D(q0, ρ - g)`` in its disc, so:

* an LED within ``ρ - d - g`` of ``q0`` lies within ``ρ - d`` of every ``q``: one such LED must be a member
  of any pair the cell serves, two must be the pair, three leave none;
* a member ``a`` with another LED deep in ``conv({a} ∪ D(q0, ρ - g))`` (a subset of the pair's hull) can
  only be paired with that LED; with two such LEDs it serves no pair (its **blockers**);
* the pairs left are tested with the pair's hull at ``q0``; a pair whose hull at ``q0`` with the full
  ``ρ`` holds no LED, where ``q0`` itself qualifies, is kept (``q0`` is a pose the tests cannot exclude);
  the others are split into four cells down to :data:`~planner.verify.proof.MIN_CELL_M`, then kept.

Blockers are counted only with discs no larger than the smallest of the site (then no larger than
either member's); the pair's hull test uses the two members' own radii.
"""

from __future__ import annotations

import math
from itertools import chain

import numpy as np
from scipy.spatial import cKDTree

from planner.verify.envelope import Envelope
from planner.verify.exclusion import MIN_CELL_M, _near

_NEAR_Q = 8
"""LEDs nearest a cell's centre tested against every member and pair (the hull is widest there)."""

_NEAR_ALONG = 3
"""LEDs nearest the point halfway between the cell and a member, and the pair's middle, tested too."""

_ROWS = 400_000
"""Rows (cell, member) or (cell, pair) handled at once."""

_TOP_BATCH = 1000
"""First-level cells searched together (depth first by batches keeps the rows in memory few)."""


def _in_cone(a: np.ndarray, q: np.ndarray, rho: np.ndarray, x: np.ndarray, m: float) -> np.ndarray:
    """Whether ``x`` (N, K, 2) lies deeper than ``m`` in ``conv({a} ∪ D(q, rho))`` (a, q (N, 2), rho (N,)).

    Sufficient test: ``x`` in ``conv({a'} ∪ D(q, rho - m))``, ``a'`` the point on ``a q`` whose disc of
    radius ``m`` touches both tangents (``m |a - q| / rho`` from ``a``); that set's ``m``-neighbourhood
    lies in the cone, so each of its points is deeper than ``m``.
    """
    v = q - a
    length = np.linalg.norm(v, axis=1)
    inner = rho - m
    ok = (inner > 0) & (rho > 0)
    apex = a + v * (m / np.maximum(rho, 1e-12))[:, None]
    ell = np.maximum(length - m * length / np.maximum(rho, 1e-12), 0.0)  # |apex - q|
    w = x - q[:, None]
    in_disc = np.einsum("nkd,nkd->nk", w, w) < (inner * inner)[:, None]
    e = v / np.maximum(length, 1e-12)[:, None]
    rel = x - apex[:, None]
    t = np.einsum("nkd,nd->nk", rel, e)  # along the axis from the apex towards q
    dist = np.linalg.norm(rel, axis=2)
    sin_b = np.clip(inner / np.maximum(ell, 1e-12), 0.0, 1.0)
    cos_b = np.sqrt(1.0 - sin_b * sin_b)
    in_wedge = (t > cos_b[:, None] * dist) & (t < (ell * cos_b * cos_b)[:, None])
    return ok[:, None] & (in_disc | ((ell > inner)[:, None] & in_wedge))


def _pair_excluded(xy, radii, a_idx, b_idx, q, rho, tree, m) -> np.ndarray:
    """Whether a disc no larger than both members lies deeper than ``m`` in ``conv({a, b} ∪ D(q, rho))`` (R,).

    Tested on two parts of that hull: the cones ``conv({a} ∪ D(q, rho))``, ``conv({b} ∪ D(q, rho))``
    (:func:`_in_cone`) and the triangle ``a b q`` (depth beyond ``m`` from each side)."""
    out = np.zeros(len(a_idx), dtype=bool)
    n = len(xy)
    for s in range(0, len(a_idx), _ROWS):
        sl = slice(s, s + _ROWS)
        ai, bi, qq, rr = a_idx[sl], b_idx[sl], q[sl], rho[sl]
        a, b = xy[ai], xy[bi]
        cand = np.hstack([_near(tree, qq, min(_NEAR_Q, n)), _near(tree, 0.5 * (a + b), min(_NEAR_ALONG, n))])
        valid = (cand != ai[:, None]) & (cand != bi[:, None])
        valid &= radii[cand] <= np.minimum(radii[ai], radii[bi])[:, None]
        x = xy[cand]
        tri = (_triangle_depth(a, b, qq, x) > m) & (rr >= 0)[:, None]  # the triangle a b q0 lies in every q's hull
        deep = _in_cone(a, qq, rr, x, m) | _in_cone(b, qq, rr, x, m) | tri
        out[sl] = (deep & valid).any(axis=1)
    return out


def _both_in_view(xy, a_idx, b_idx, q, g, env) -> np.ndarray:
    """Whether both members may lie in the ceiling's view ``E(κ)`` of one pose with its axis point within ``g``
    of ``q`` (R,). ``E(κ)`` lies in ``{w : w·t >= -back, |w × t| <= side}`` about the axis point, ``t`` the
    tilt's direction (any): a member ``p`` farther than ``side`` whose ``sqrt(|p|² - side²)`` exceeds ``back``
    needs ``t`` within ``asin(side / |p|)`` of its own direction; two such members need those arcs to meet."""
    side, back = env.view_side_m + g, env.view_back_m + g
    pa, pb = xy[a_idx] - q, xy[b_idx] - q
    ra, rb = np.linalg.norm(pa, axis=1), np.linalg.norm(pb, axis=1)
    if not math.isfinite(side):
        return np.ones(len(a_idx), dtype=bool)

    def arc(r):
        bound = (r > side) & (np.sqrt(np.maximum(r * r - side * side, 0.0)) > back)
        return bound, np.arcsin(np.clip(side / np.maximum(r, 1e-12), 0.0, 1.0))

    (fa, ba), (fb, bb) = arc(ra), arc(rb)
    cos = np.einsum("nd,nd->n", pa, pb) / np.maximum(ra * rb, 1e-12)
    apart = np.arccos(np.clip(cos, -1.0, 1.0))
    return ~(fa & fb & (apart > ba + bb + 1e-12))


def _triangle_depth(a: np.ndarray, b: np.ndarray, c: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Depth of ``x`` (N, K, 2) in the triangles ``a b c`` (N, 2 each): least distance inside its sides, < 0 outside."""
    orient = np.sign((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    depth = np.full(x.shape[:2], np.inf)
    for u, v in ((a, b), (b, c), (c, a)):
        e = v - u
        length = np.maximum(np.linalg.norm(e, axis=1), 1e-12)
        cross = e[:, None, 0] * (x[..., 1] - u[:, None, 1]) - e[:, None, 1] * (x[..., 0] - u[:, None, 0])
        depth = np.minimum(depth, orient[:, None] * cross / length[:, None])
    return np.where((orient != 0)[:, None], depth, -np.inf)


def _cells(env: Envelope, xy: np.ndarray, area: np.ndarray | None, spread: float, half: float) -> np.ndarray:
    """Centres (C, 2) of cells of half-side ``half`` covering every axis point the envelope allows."""
    reach = env.axis_reach_m
    lo, hi = xy.min(axis=0) - reach, xy.max(axis=0) + reach
    if area is not None and math.isfinite(spread):
        lo, hi = np.maximum(lo, area.min(axis=0) - spread), np.minimum(hi, area.max(axis=0) + spread)
    nx, ny = (np.ceil((hi - lo) / (2 * half)).astype(int) + 1)
    gx, gy = np.meshgrid(lo[0] + 2 * half * np.arange(nx), lo[1] + 2 * half * np.arange(ny), indexing="ij")
    return np.column_stack([gx.ravel(), gy.ravel()])


def case_b_pairs(xy: np.ndarray, radii: np.ndarray, env: Envelope, area: np.ndarray | None, spread: float,
                 outside_by, known: np.ndarray | None = None) -> np.ndarray:
    """Pairs ``i < j`` (M, 2) that some axis point of case B may serve (a superset: see the module), beside
    the ``known`` pairs (K, 2), kept already (by another slice) and not searched again."""
    n = len(xy)
    tree = cKDTree(xy)
    kept = _Kept(n, known)
    half = max(MIN_CELL_M, (env.disc_m - env.install_m) / 6.0)
    top = _cells(env, xy, area, spread, half)
    for s in range(0, len(top), _TOP_BATCH):
        _search(xy, radii, env, area, spread, outside_by, tree, top[s:s + _TOP_BATCH], half, kept)
    return kept.pairs()


def _search(xy, radii, env, area, spread, outside_by, tree, centre, half, kept: _Kept) -> None:
    """Branch and bound over the cells ``centre`` (C, 2) of half-side ``half``: add the pairs they may serve."""
    n = len(xy)
    rho, d, reach = env.disc_m, env.install_m, env.axis_reach_m
    m = 2.0 * d + 1e-9
    rows = None  # (cell, a, b)
    while len(centre):
        g = half * math.sqrt(2.0)
        dist, idx = tree.query(centre, k=min(3, n))
        dist, idx = dist.reshape(len(centre), -1), idx.reshape(len(centre), -1)
        inside = dist < rho - d - g  # LEDs within rho - d of every axis point of the cell
        live = inside.sum(axis=1) < 3
        if area is not None and math.isfinite(spread):
            live &= outside_by(centre, area) - g <= spread
        if rows is None:
            rows = _first_rows(xy, radii, centre, live, inside, idx, tree, rho - g, reach + g, m,
                               env.reach_m + 2 * d, kept)
            rows = rows[_both_in_view(xy, rows[:, 1], rows[:, 2], centre[rows[:, 0]], g, env)]
        else:
            rows = rows[live[rows[:, 0]]]
            rows = rows[_forced_ok(rows, inside, idx)]
            qc = centre[rows[:, 0]]
            near_enough = (np.linalg.norm(xy[rows[:, 1]] - qc, axis=1) <= reach + g) & \
                          (np.linalg.norm(xy[rows[:, 2]] - qc, axis=1) <= reach + g)
            rows = rows[near_enough]
            rows = rows[_both_in_view(xy, rows[:, 1], rows[:, 2], centre[rows[:, 0]], g, env)]
        rows = _not_kept(rows, kept, n)
        if not len(rows):
            return
        rows = _witnesses(xy, radii, rows, centre, dist, idx, kept, tree, env, area, spread, outside_by, m)
        gone = _pair_excluded(xy, radii, rows[:, 1], rows[:, 2], centre[rows[:, 0]], np.full(len(rows), rho - g), tree, m)
        rows = rows[~gone]
        if half <= MIN_CELL_M:
            kept.add(rows[:, 1] * n + rows[:, 2])
            return
        used, inv = np.unique(rows[:, 0], return_inverse=True)  # split: each row goes to its cell's four children
        half /= 2.0
        off = np.array([[-1, -1], [-1, 1], [1, -1], [1, 1]], dtype=float) * half
        centre = (centre[used][:, None, :] + off[None]).reshape(-1, 2)
        rows = np.repeat(rows, 4, axis=0)
        rows[:, 0] = np.repeat(inv * 4, 4) + np.tile(np.arange(4), len(inv))


class _Kept:
    """Pairs kept so far, by code ``i n + j``: a bitmap for sites up to 4,096 luminaires, else a set."""

    def __init__(self, n: int, known: np.ndarray | None):
        self.n = n
        self.dense = np.zeros(n * n, dtype=bool) if n <= 4096 else None
        self.codes: set[int] = set()
        if known is not None and len(known):
            self.add(known[:, 0] * n + known[:, 1])

    def add(self, codes: np.ndarray) -> None:
        if self.dense is not None:
            self.dense[codes] = True
        else:
            self.codes.update(codes.tolist())

    def has(self, codes: np.ndarray) -> np.ndarray:
        if self.dense is not None:
            return self.dense[codes]
        return np.isin(codes, np.fromiter(self.codes, np.int64, len(self.codes)))

    def pairs(self) -> np.ndarray:
        out = np.flatnonzero(self.dense) if self.dense is not None else np.array(sorted(self.codes), dtype=np.int64)
        return np.column_stack([out // self.n, out % self.n]).reshape(-1, 2)


def _not_kept(rows: np.ndarray, kept: _Kept, n: int) -> np.ndarray:
    return rows[~kept.has(rows[:, 1] * n + rows[:, 2])] if len(rows) else rows


def _witnesses(xy, radii, rows, centre, dist, idx, kept, tree, env, area, spread, outside_by, m) -> np.ndarray:
    """Keep (into ``kept``) the pairs some cell centre serves with the full disc; the rows of the others.

    Tried in rounds, the first row of each pair, then the next two, four..., so that a pair kept early
    costs one test."""
    n = len(xy)
    rho, reach = env.disc_m, env.axis_reach_m
    qc = centre[rows[:, 0]]
    wit = _forced_ok(rows, dist < rho - env.install_m, idx)
    wit &= (np.linalg.norm(xy[rows[:, 1]] - qc, axis=1) <= reach) & (np.linalg.norm(xy[rows[:, 2]] - qc, axis=1) <= reach)
    if area is not None and math.isfinite(spread):
        wit &= outside_by(qc, area) <= spread
    wit &= _both_in_view(xy, rows[:, 1], rows[:, 2], qc, 0.0, env)
    code = rows[:, 1] * n + rows[:, 2]
    order = np.argsort(code, kind="stable")
    rows, code, wit = rows[order], code[order], wit[order]
    first = np.searchsorted(code, code, side="left")
    rank = np.arange(len(code)) - first
    done = np.zeros(len(rows), dtype=bool)
    lo = 0
    while True:
        hi = 2 * lo + 1
        pick = np.flatnonzero(wit & (rank >= lo) & (rank < hi) & ~done)
        if len(pick):
            free = ~_pair_excluded(xy, radii, rows[pick, 1], rows[pick, 2], centre[rows[pick, 0]],
                                   np.full(len(pick), rho), tree, m)
            kept.add(code[pick[free]])
            done |= kept.has(code)
        if hi > rank.max(initial=0):
            break
        lo = hi
    return rows[~done]


def _forced_ok(rows: np.ndarray, inside: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Whether every LED flagged ``inside`` for a row's cell is one of the row's two members."""
    ins, near = inside[rows[:, 0]], idx[rows[:, 0]]
    member = (near == rows[:, 1:2]) | (near == rows[:, 2:3])
    return ~(ins & ~member).any(axis=1)


def _first_rows(xy, radii, centre, live, inside, idx, tree, rho_in, member_reach, m, pair_reach, kept) -> np.ndarray:
    """(cell, a, b) rows of the first cells: members within reach with at most one blocker, paired
    (with the cell's forced LEDs, where it has any)."""
    n = len(xy)
    small = radii <= radii.min() + 1e-12
    cells = np.flatnonzero(live)
    if not len(cells):
        return np.empty((0, 3), np.int64)
    near_q = _near(tree, centre, min(_NEAR_Q, n))
    members = tree.query_ball_point(centre[cells], member_reach)
    counts = np.array([len(x) for x in members])
    if counts.sum() == 0:
        return np.empty((0, 3), np.int64)
    cell_of = np.repeat(cells, counts)
    mem = np.fromiter(chain.from_iterable(members), dtype=np.int64, count=int(counts.sum()))
    q, a = centre[cell_of], xy[mem]
    parts = [near_q[cell_of]] + [_near(tree, 0.5 * (q + a), min(_NEAR_ALONG, n))]
    cand = np.sort(np.hstack(parts), axis=1)
    dup = np.zeros(cand.shape, dtype=bool)
    dup[:, 1:] = cand[:, 1:] == cand[:, :-1]
    deep = np.zeros(cand.shape, dtype=bool)
    for r in range(0, len(mem), _ROWS):
        sl = slice(r, r + _ROWS)
        deep[sl] = _in_cone(a[sl], q[sl], np.full(len(a[sl]), rho_in), xy[cand[sl]], m)
    deep &= ~dup & (cand != mem[:, None]) & small[cand]
    nblock = deep.sum(axis=1)
    blocker = np.where(nblock == 1, cand[np.arange(len(mem)), np.argmax(deep, axis=1)], -1)
    ok = nblock <= 1
    cell_of, mem, blocker = cell_of[ok], mem[ok], blocker[ok]  # sorted by cell already
    starts = np.flatnonzero(np.r_[True, cell_of[1:] != cell_of[:-1]])
    sizes = np.diff(np.r_[starts, len(cell_of)])
    out = []
    for k in np.unique(sizes):
        if k < 2:
            continue
        st = starts[sizes == k]
        i, j = np.triu_indices(k, 1)
        ri, rj = (st[:, None] + i[None]).ravel(), (st[:, None] + j[None]).ravel()
        ai, bi = mem[ri], mem[rj]
        good = ((blocker[ri] < 0) | (blocker[ri] == bi)) & ((blocker[rj] < 0) | (blocker[rj] == ai))
        rows = np.column_stack([cell_of[ri], np.minimum(ai, bi), np.maximum(ai, bi)])[good]
        rows = rows[_forced_ok(rows, inside, idx)]
        rows = rows[np.linalg.norm(xy[rows[:, 1]] - xy[rows[:, 2]], axis=1) <= pair_reach]
        out.append(_not_kept(rows, kept, n))
    return np.vstack(out) if out else np.empty((0, 3), np.int64)
