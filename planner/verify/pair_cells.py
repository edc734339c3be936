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

import numpy as np
from numba import njit
from scipy.spatial import cKDTree

from planner.verify.envelope import Envelope
from planner.verify.exclusion import MIN_CELL_M, _near
from planner.verify.windows import ball_pairs

_NEAR_Q = 8
"""LEDs nearest a cell's centre tested against every member and pair (the hull is widest there)."""

_NEAR_ALONG = 3
"""LEDs nearest the point halfway between the cell and a member, and the pair's middle, tested too."""

_ROWS = 400_000
"""Rows (cell, member) or (cell, pair) handled at once."""

_TOP_BATCH = 1000
"""First-level cells searched together (depth first by batches keeps the rows in memory few)."""


@njit(cache=True)
def _cone(ax, ay, qx, qy, rho, px, py, m):
    """Whether ``p`` lies deeper than ``m`` in ``conv({a} ∪ D(q, rho))``.

    Sufficient test: ``p`` in ``conv({a'} ∪ D(q, rho - m))``, ``a'`` the point on ``a q`` whose disc of
    radius ``m`` touches both tangents (``m |a - q| / rho`` from ``a``); that set's ``m``-neighbourhood
    lies in the cone, so each of its points is deeper than ``m``.
    """
    inner = rho - m
    if not (inner > 0 and rho > 0):
        return False
    wx, wy = px - qx, py - qy
    if wx * wx + wy * wy < inner * inner:
        return True
    vx, vy = qx - ax, qy - ay
    length = np.sqrt(vx * vx + vy * vy)
    r = max(rho, 1e-12)
    ell = max(length - m * length / r, 0.0)  # |apex - q|
    if not ell > inner:
        return False
    f, e = m / r, max(length, 1e-12)
    rx, ry = px - (ax + vx * f), py - (ay + vy * f)
    t = rx * (vx / e) + ry * (vy / e)  # along the axis from the apex towards q
    dist = np.sqrt(rx * rx + ry * ry)
    sin_b = min(max(inner / max(ell, 1e-12), 0.0), 1.0)
    cos_b = np.sqrt(1.0 - sin_b * sin_b)
    return t > cos_b * dist and t < ell * cos_b * cos_b


@njit(cache=True)
def _depth(ax, ay, bx, by, cx, cy, px, py):
    """Depth of ``p`` in the triangle ``a b c``: least distance inside its sides, < 0 outside (-inf if flat)."""
    turn = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    if turn == 0:
        return -np.inf
    orient = 1.0 if turn > 0 else -1.0
    depth = np.inf
    for ux, uy, vx, vy in ((ax, ay, bx, by), (bx, by, cx, cy), (cx, cy, ax, ay)):
        ex, ey = vx - ux, vy - uy
        length = max(np.sqrt(ex * ex + ey * ey), 1e-12)
        depth = min(depth, orient * (ex * (py - uy) - ey * (px - ux)) / length)
    return depth


@njit(cache=True)
def _excluded(xy, radii, ai, bi, q, rho, cand, m):
    out = np.zeros(len(ai), dtype=np.bool_)
    for r in range(len(ai)):
        a, b = ai[r], bi[r]
        ax, ay, bx, by, qx, qy = xy[a, 0], xy[a, 1], xy[b, 0], xy[b, 1], q[r, 0], q[r, 1]
        largest = min(radii[a], radii[b])  # discs no larger than both members count
        for k in range(cand.shape[1]):
            c = cand[r, k]
            if c == a or c == b or radii[c] > largest:
                continue
            px, py = xy[c, 0], xy[c, 1]
            if ((rho[r] >= 0 and _depth(ax, ay, bx, by, qx, qy, px, py) > m)
                    or _cone(ax, ay, qx, qy, rho[r], px, py, m) or _cone(bx, by, qx, qy, rho[r], px, py, m)):
                out[r] = True
                break
    return out


def _pair_excluded(xy, radii, a_idx, b_idx, centre, cell, rho, tree, m) -> np.ndarray:
    """Whether a disc no larger than both members lies deeper than ``m`` in ``conv({a, b} ∪ D(q, rho))`` (R,),
    ``q = centre[cell]`` (the LEDs nearest each cell's centre are found once for all its rows).

    Tested on two parts of that hull: the cones ``conv({a} ∪ D(q, rho))``, ``conv({b} ∪ D(q, rho))``
    (:func:`_cone`) and the triangle ``a b q`` (depth beyond ``m`` from each side; it lies in every
    ``q``'s hull of the cell, so it is tested wherever ``rho >= 0``)."""
    out = np.zeros(len(a_idx), dtype=bool)
    n = len(xy)
    for s in range(0, len(a_idx), _ROWS):
        sl = slice(s, s + _ROWS)
        ai, bi = np.ascontiguousarray(a_idx[sl]), np.ascontiguousarray(b_idx[sl])
        used, inv = np.unique(cell[sl], return_inverse=True)
        near_q = _near(tree, centre[used], min(_NEAR_Q, n))[inv]
        cand = np.hstack([near_q, _near(tree, 0.5 * (xy[ai] + xy[bi]), min(_NEAR_ALONG, n))])
        out[sl] = _excluded(xy, radii, ai, bi, centre[cell[sl]], rho[sl], cand, m)
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
    xy = np.ascontiguousarray(xy, dtype=float)  # one layout: each kernel compiles for one signature
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
        gone = _pair_excluded(xy, radii, rows[:, 1], rows[:, 2], centre, rows[:, 0], np.full(len(rows), rho - g), tree, m)
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
            free = ~_pair_excluded(xy, radii, rows[pick, 1], rows[pick, 2], centre, rows[pick, 0],
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


@njit(cache=True)
def _blockers(xy, centre, cell_of, mem, near_q, near_mid, rho_in, m, small):
    """For each (cell, member) row: how many small LEDs among the cell's and the row's nearest (``near_q``,
    ``near_mid``) lie deep in ``conv({a} ∪ D(q, rho_in))`` (:func:`_cone`), and the one if there is one (else -1)."""
    nblock = np.zeros(len(mem), dtype=np.int64)
    blocker = np.full(len(mem), -1, dtype=np.int64)
    nq, nm = near_q.shape[1], near_mid.shape[1]
    row = np.empty(nq + nm, dtype=np.int64)
    for r in range(len(mem)):
        a, cell = mem[r], cell_of[r]
        for t in range(nq):  # element by element: slice copies compile numba's shape-error message machinery
            row[t] = near_q[cell, t]
        for t in range(nm):
            row[nq + t] = near_mid[r, t]
        ax, ay, qx, qy = xy[a, 0], xy[a, 1], centre[cell, 0], centre[cell, 1]
        for t in range(len(row)):
            c = row[t]
            again = False  # each LED once, whichever list names it
            for u in range(t):
                again |= row[u] == c
            if again or c == a or not small[c]:
                continue
            if _cone(ax, ay, qx, qy, rho_in, xy[c, 0], xy[c, 1], m):
                nblock[r] += 1
                blocker[r] = c if blocker[r] < 0 else min(blocker[r], c)
        if nblock[r] != 1:
            blocker[r] = -1
    return nblock, blocker


def _first_rows(xy, radii, centre, live, inside, idx, tree, rho_in, member_reach, m, pair_reach, kept) -> np.ndarray:
    """(cell, a, b) rows of the first cells: members within reach with at most one blocker, paired
    (with the cell's forced LEDs, where it has any)."""
    n = len(xy)
    small = radii <= radii.min() + 1e-12
    cells = np.flatnonzero(live)
    if not len(cells):
        return np.empty((0, 3), np.int64)
    near_q = _near(tree, centre, min(_NEAR_Q, n))
    which, mem = ball_pairs(tree, centre[cells], member_reach)
    if not len(mem):
        return np.empty((0, 3), np.int64)
    cell_of = cells[which]
    near_mid = _near(tree, 0.5 * (centre[cell_of] + xy[mem]), min(_NEAR_ALONG, n))
    nblock, blocker = _blockers(xy, centre, cell_of, mem, near_q, near_mid, rho_in, m, small)
    ok = nblock <= 1
    cell_of, mem, blocker = cell_of[ok], mem[ok], blocker[ok]  # sorted by cell already
    starts = np.flatnonzero(np.r_[True, cell_of[1:] != cell_of[:-1]])
    rows = _cell_pairs(xy, cell_of, mem, blocker, starts, np.diff(np.r_[starts, len(cell_of)]), inside, idx, pair_reach)
    return _not_kept(rows, kept, n)


@njit(cache=True)
def _cell_pairs(xy, cell_of, mem, blocker, starts, sizes, inside, idx, pair_reach):
    """(cell, a, b) rows, ``a < b``, of the members of each cell (``mem[starts[g]:starts[g] + sizes[g]]``)
    taken two at a time: neither blocked by a third LED, the cell's forced LEDs among them (:func:`_forced_ok`),
    at most ``pair_reach`` apart."""
    out = np.empty((int(np.sum(sizes * (sizes - 1) // 2)), 3), dtype=np.int64)
    count = 0
    for g in range(len(starts)):
        s, k, cell = starts[g], sizes[g], cell_of[starts[g]]
        for i in range(s, s + k - 1):
            for j in range(i + 1, s + k):
                a, b = mem[i], mem[j]
                if not ((blocker[i] < 0 or blocker[i] == b) and (blocker[j] < 0 or blocker[j] == a)):
                    continue
                forced = True
                for t in range(idx.shape[1]):
                    if inside[cell, t] and idx[cell, t] != a and idx[cell, t] != b:
                        forced = False
                dx, dy = xy[a, 0] - xy[b, 0], xy[a, 1] - xy[b, 1]
                if forced and np.sqrt(dx * dx + dy * dy) <= pair_reach:
                    out[count, 0], out[count, 1], out[count, 2] = cell, min(a, b), max(a, b)
                    count += 1
    return out[:count]
