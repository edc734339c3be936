"""What rules a pair or a triangle out as a window: the proof's cases A and B, chunk by chunk.

The argument is in :mod:`planner.verify.proof` and docs/verification.md ("The proof"); these are its
tests, pure functions of the drawn positions, the envelope and a KD-tree, run per tile by
:mod:`planner.verify.tiles`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from scipy.spatial import cKDTree

from planner.verify.envelope import Envelope
from planner.verify.windows import twice_signed_area

MIN_CELL_M = 0.005
"""Smallest cell of axis points searched inside a triangle [m]: a triple with an unexcluded cell is kept."""

NEAR = 24
"""LEDs nearest a pair's middle or a triangle's centroid that are tested against it (more only exclude more)."""

_CHUNK = 20_000


# --- case A: spindles ---------------------------------------------------------------------------


def _in_spindle(a: np.ndarray, b: np.ndarray, x: np.ndarray, radius_m: float, d: float) -> np.ndarray:
    """Whether ``x`` (..., 2) lies in the installed ``R``-spindle of ``a, b`` (..., 2) for every displacement <= d.

    True when every centre ``c`` within ``R + d`` of both ends has ``|c - x| < R - d``:
    the farthest such ``c`` is a corner of that lens or the far point of one of its arcs.
    """
    rho = radius_m + d
    ab = b - a
    length = np.linalg.norm(ab, axis=-1)
    half2 = rho * rho - 0.25 * length * length
    ok = half2 > 0
    n = np.stack([-ab[..., 1], ab[..., 0]], -1) / np.maximum(length, 1e-12)[..., None]
    mid = 0.5 * (a + b)
    h = np.sqrt(np.maximum(half2, 0.0))[..., None]
    far = np.maximum(np.linalg.norm(mid + h * n - x, axis=-1), np.linalg.norm(mid - h * n - x, axis=-1))
    for p, o in ((a, b), (b, a)):
        away = p - x
        c = p + rho * away / np.maximum(np.linalg.norm(away, axis=-1), 1e-12)[..., None]
        on_arc = np.linalg.norm(c - o, axis=-1) <= rho
        far = np.where(on_arc, np.maximum(far, rho + np.linalg.norm(away, axis=-1)), far)
    return ok & (far < radius_m - d)


def _spindle_count(a, b, xs, valid, env: Envelope) -> np.ndarray:
    """LEDs among ``xs`` (P, K, 2) in the spindle of each pair; pairs longer than ``2 (R + d)`` count as full."""
    inside = _in_spindle(a[:, None], b[:, None], xs, env.curvature_m, env.install_m) & valid
    count = inside.sum(axis=1)
    too_long = np.linalg.norm(b - a, axis=1) > 2 * (env.curvature_m + env.install_m)
    return np.where(too_long, np.iinfo(np.int64).max // 2, count)


# --- case B, axis point beyond a side: apex intervals ----------------------------------------------


def _apex_cover(a, b, xs, valid, env: Envelope, side: float) -> np.ndarray:
    """Fewest LEDs deep (> 2 d) in ``triangle(a, b, apex)`` over apex positions ``ρ`` from line ``ab`` on ``side``.

    ``a, b`` (P, 2), ``xs`` (P, K, 2). An LED ``x`` at ``(s, h)`` in the frame of ``ab``
    (``s`` along, ``h`` towards ``side``) is deep for apexes ``s' in [L - φ(L - s), φ(s)]``,
    ``φ(u) = ρ (u h - m sqrt(u^2 + h^2 - m^2)) / (h^2 - m^2)``; the apex lies between the
    side's middle and the axis point, which is within the axis reach of both ends: over
    ``[L - reach, reach]``. Returns the minimum cover over that range (P,).
    """
    rho, m = env.disc_m, 2.0 * env.install_m + 1e-9
    ab = b - a
    length = np.linalg.norm(ab, axis=1)
    u = ab / np.maximum(length, 1e-12)[:, None]
    rel = xs - a[:, None]
    s = rel[..., 0] * u[:, None, 0] + rel[..., 1] * u[:, None, 1]
    h = side * (rel[..., 1] * u[:, None, 0] - rel[..., 0] * u[:, None, 1])
    use = valid & (h > m) & (h < rho)
    hh = np.where(use, h, 2 * m + 1.0)
    den = hh * hh - m * m

    def phi(w):
        return rho * (w * hh - m * np.sqrt(w * w + den)) / den

    lo_lim, hi_lim = length - env.axis_reach_m, np.full(len(a), env.axis_reach_m)  # q within reach of a and b
    lo = np.maximum(length[:, None] - phi(length[:, None] - s), lo_lim[:, None])
    hi = np.minimum(phi(s), hi_lim[:, None])
    use &= lo < hi
    lo, hi = np.where(use, lo, np.inf), np.where(use, hi, np.inf)
    cover = _min_cover(lo, hi, lo_lim, hi_lim)
    return np.where(lo_lim > hi_lim, np.iinfo(np.int64).max // 2, cover)


def _min_cover(lo: np.ndarray, hi: np.ndarray, start: np.ndarray, stop: np.ndarray) -> np.ndarray:
    """Fewest closed intervals ``[lo, hi]`` (P, K; inf = none) covering a point of ``[start, stop]`` (P,)."""
    return _min_cover_rows(np.ascontiguousarray(lo, dtype=np.float64), np.ascontiguousarray(hi, dtype=np.float64),
                           np.ascontiguousarray(start, dtype=np.float64), np.ascontiguousarray(stop, dtype=np.float64))


@njit(cache=True)
def _min_cover_rows(lo, hi, start, stop):
    """:func:`_min_cover` row by row: sweep the ends in order (ties keep the starts first, as listed), counting
    the intervals over each open piece between two ends that meets ``[start, stop]``; none before the first."""
    p, k = lo.shape
    out = np.empty(p, dtype=np.int64)
    ev = np.empty(2 * k)
    step = np.empty(2 * k, dtype=np.int64)
    for r in range(p):
        for c in range(k):
            ev[c], ev[k + c] = lo[r, c], hi[r, c]
            step[c] = 1 if np.isfinite(lo[r, c]) else 0
            step[k + c] = -1 if np.isfinite(hi[r, c]) else 0
        order = np.argsort(ev, kind="mergesort")
        best, count = np.iinfo(np.int64).max, 0
        for e in range(2 * k):
            here = ev[order[e]]
            count += step[order[e]]
            nxt = ev[order[e + 1]] if e + 1 < 2 * k else np.inf
            if nxt > here and min(nxt, stop[r]) > max(here, start[r]):
                best = min(best, count)
        out[r] = 0 if ev[order[0]] > start[r] else best  # inf > start: no interval at all
    return out


# --- case B, axis point inside the triangle: cells --------------------------------------------------


def _hull_depth(p: np.ndarray, q: np.ndarray, rho: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Depth of ``x`` (N, K, 2) in ``conv(p ∪ D(q, rho))``, ``p`` (N, 3, 2), ``q`` (N, 2), ``rho`` (N,); < 0 outside.

    The depth is ``min_u max(u·p_i, u·q + rho) - u·x`` over unit ``u``; the minimum lies
    where two pieces cross or at one piece's own minimum, so those directions suffice.
    """
    ang = []
    for i, j in ((0, 1), (1, 2), (2, 0)):
        e = p[:, j] - p[:, i]
        base = np.arctan2(e[:, 1], e[:, 0])
        ang += [base + np.pi / 2, base - np.pi / 2]
    for i in range(3):
        w = p[:, i] - q
        dist = np.linalg.norm(w, axis=1)
        turn = np.arccos(np.clip(rho / np.maximum(dist, 1e-12), -1.0, 1.0))
        base = np.arctan2(w[:, 1], w[:, 0])
        ang += [base + turn, base - turn]
    ang_nk = [np.broadcast_to(a[:, None], x.shape[:2]) for a in ang]
    dq = x - q[:, None]
    ang_nk.append(np.arctan2(dq[..., 1], dq[..., 0]))
    for i in range(3):
        dp = p[:, i][:, None] - x
        ang_nk.append(np.arctan2(-dp[..., 1], -dp[..., 0]))
    th = np.stack(ang_nk, axis=-1)  # (N, K, 16)
    u = np.stack([np.cos(th), np.sin(th)], axis=-1)  # (N, K, 16, 2)
    support = np.einsum("nkcd,nid->nkci", u, p).max(axis=-1)
    support = np.maximum(support, np.einsum("nkcd,nd->nkc", u, q) + rho[:, None, None])
    return (support - np.einsum("nkcd,nkd->nkc", u, x)).min(axis=-1)


def _inside_alive(p: np.ndarray, xs: np.ndarray, valid: np.ndarray, env: Envelope) -> np.ndarray:
    """Whether some axis point inside each triangle ``p`` (T, 3, 2) is not excluded (T,), by cells.

    A cell (centre ``q0``, half-side ``s``) is excluded when an LED is deep in
    ``conv(T ∪ D(q0, ρ - s sqrt 2))``, which every axis point of the cell's hull holds;
    a triangle is kept as soon as one cell centre is not excluded with the full ``ρ``,
    or a cell reaches :data:`MIN_CELL_M` unexcluded.
    """
    lo, hi = p.min(axis=1), p.max(axis=1)
    half = 0.5 * (hi - lo).max(axis=1) + 1e-9
    tri = np.arange(len(p))
    centre = 0.5 * (lo + hi)
    alive = np.zeros(len(p), dtype=bool)
    m = 2.0 * env.install_m + 1e-9
    off = np.array([[-1, -1], [-1, 1], [1, -1], [1, 1]], dtype=float)

    def excluded(t, q, rho):
        out = np.zeros(len(t), dtype=bool)
        for c in range(0, len(t), 4000):
            sl = slice(c, c + 4000)
            depth = _hull_depth(p[t[sl]], q[sl], rho[sl], xs[t[sl]])
            out[sl] = ((depth > m) & valid[t[sl]]).any(axis=1)
        return out

    while len(tri):
        pt = p[tri]
        sign = np.where(twice_signed_area(pt) >= 0, 1.0, -1.0)
        meets = np.ones(len(tri), dtype=bool)  # cells that miss the triangle are left to the sides' test
        for i in range(3):
            e = pt[:, (i + 1) % 3] - pt[:, i]
            dist = sign * (e[:, 0] * (centre[:, 1] - pt[:, i, 1]) - e[:, 1] * (centre[:, 0] - pt[:, i, 0]))
            meets &= dist >= -half * math.sqrt(2) * np.linalg.norm(e, axis=1)
        tri, centre, half = tri[meets], centre[meets], half[meets]
        free = ~excluded(tri, centre, np.full(len(tri), env.disc_m))
        alive[tri[free]] = True
        rho = env.disc_m - half * math.sqrt(2)
        gone = np.zeros(len(tri), dtype=bool)
        test = (rho > 0) & ~alive[tri]
        gone[test] = excluded(tri[test], centre[test], rho[test])
        alive[tri[~gone & (half <= MIN_CELL_M)]] = True
        keep = ~gone & (half > MIN_CELL_M) & ~alive[tri]
        tri, centre, half = tri[keep], centre[keep], half[keep] / 2
        centre = (centre[:, None, :] + off[None] * half[:, None, None]).reshape(-1, 2)
        tri, half = np.repeat(tri, 4), np.repeat(half, 4)
    return alive


# --- putting it together ----------------------------------------------------------------------------


def _near(tree: cKDTree, points: np.ndarray, k: int) -> np.ndarray:
    _, idx = tree.query(points, k=k)
    return idx.reshape(len(points), k)


def _strip(tree: cKDTree, a: np.ndarray, b: np.ndarray, step_m: float, n: int) -> np.ndarray:
    """Distinct LEDs near the segments ``a b`` (P, 2): the 3 nearest to each of points spaced along it."""
    length = np.linalg.norm(b - a, axis=1)
    steps = max(2, int(np.ceil(length.max() / step_m)) + 1)
    t = np.linspace(0.0, 1.0, steps)
    pts = a[:, None] + t[None, :, None] * (b - a)[:, None]
    k = min(3, n)
    idx = _near(tree, pts.reshape(-1, 2), k).reshape(len(a), steps * k)
    idx = np.sort(idx, axis=1)
    dup = np.zeros_like(idx, dtype=bool)
    dup[:, 1:] = idx[:, 1:] == idx[:, :-1]
    return np.where(dup, -1, idx)


def pair_reach_m(env: Envelope) -> float:
    """Farthest apart two members of one window can be drawn [m]: the reach plus both displacements."""
    return env.reach_m + 2 * env.install_m


def pairs_kept(xy: np.ndarray, radii: np.ndarray, env: Envelope, tree: cKDTree, pairs: np.ndarray,
               min_radius_m: float) -> np.ndarray:
    """Which ``pairs`` (M, 2) of ``xy`` (whose KD-tree is ``tree``) neither case excludes (M,); ``min_radius_m``
    is the smallest disc of the site (only those surely count in case B at pair level)."""
    n = len(xy)
    small = radii <= min_radius_m + 1e-12
    keep = np.zeros(len(pairs), dtype=bool)
    for start in range(0, len(pairs), _CHUNK):
        pr = pairs[start:start + _CHUNK]
        a, b = xy[pr[:, 0]], xy[pr[:, 1]]
        near = _near(tree, 0.5 * (a + b), min(NEAR, n))
        valid = (near != pr[:, :1]) & (near != pr[:, 1:])
        case_a = _spindle_count(a, b, xy[near], valid, env) < 2
        strip = _strip(tree, a, b, env.disc_m, n)
        sv = (strip >= 0) & (strip != pr[:, :1]) & (strip != pr[:, 1:])
        sv &= small[np.maximum(strip, 0)]
        xs = xy[np.maximum(strip, 0)]
        case_b = (_apex_cover(a, b, xs, sv, env, 1.0) < 2) | (_apex_cover(a, b, xs, sv, env, -1.0) < 2)
        keep[start:start + len(pr)] = case_a | case_b
    return keep


def windows_kept(xy: np.ndarray, radii: np.ndarray, env: Envelope, tree: cKDTree, cand: np.ndarray) -> np.ndarray:
    """Which candidate triangles ``cand`` (T, 3) of ``xy`` (whose KD-tree is ``tree``) case A or case B keeps (T,)."""
    n = len(xy)
    keep = np.zeros(len(cand), dtype=bool)
    for start in range(0, len(cand), _CHUNK):
        tr = cand[start:start + _CHUNK]
        p = xy[tr]
        near = _near(tree, p.mean(axis=1), min(NEAR, n))
        member = (near[:, :, None] == tr[:, None, :]).any(axis=2)
        valid = ~member
        case_a = np.ones(len(tr), dtype=bool)
        for i, j in ((0, 1), (1, 2), (2, 0)):
            case_a &= _spindle_count(p[:, i], p[:, j], xy[near], valid, env) == 0
        small = radii[near] <= radii[tr].min(axis=1)[:, None]
        out_side = np.where(twice_signed_area(p) >= 0, -1.0, 1.0)  # left of i->j is inside for a counter-clockwise triangle
        beyond = np.zeros(len(tr), dtype=bool)  # some axis point beyond a side is not excluded
        for i, j in ((0, 1), (1, 2), (2, 0)):
            strip = _strip(tree, p[:, i], p[:, j], env.disc_m, n)
            sv = (strip >= 0) & ~(strip[:, :, None] == tr[:, None, :]).any(axis=2)
            sv &= radii[np.maximum(strip, 0)] <= radii[tr].min(axis=1)[:, None]
            xs = xy[np.maximum(strip, 0)]
            for side in (1.0, -1.0):
                on = out_side == side
                if on.any():
                    beyond[on] |= _apex_cover(p[on, i], p[on, j], xs[on], sv[on], env, side) < 1
        case_b = beyond.copy()
        undecided = ~case_a & ~beyond
        if undecided.any():
            case_b[undecided] = _inside_alive(p[undecided], xy[near[undecided]], (valid & small)[undecided], env)
        keep[start:start + len(tr)] = case_a | case_b
    return keep
