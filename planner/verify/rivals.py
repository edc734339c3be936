"""Rivals: every other set of three luminaires on the site that reads like a given window.

PRODUCT.md defines a pose as ambiguous when *another set of luminaires anywhere on
the site* has the same key: the same IDs in counter-clockwise order and a triangle
of the same shape. A rival need not be a window of any sampled pose, so this module
enumerates all physical triples of the site whose sides could match (each side at
most the longest queried side plus the tolerance), not the windows some sample
produced. Two triples match when, for one of the three cyclic rotations, the IDs are
equal and every pair of corresponding sides differs by at most the tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from planner.verify.windows import twice_signed_area


def site_triples(xy: np.ndarray, max_side_m: float) -> np.ndarray:
    """All triples ``i < j < k`` of points ``xy`` (N x 2 [m]) whose three sides are at most ``max_side_m``."""
    return triples_of_pairs(cKDTree(xy).query_pairs(max_side_m, output_type="ndarray"), len(xy))


def triples_of_pairs(pairs: np.ndarray, n: int, first: np.ndarray | None = None) -> np.ndarray:
    """All triples ``i < j < k`` of ``n`` points whose three pairs are among ``pairs`` (M x 2, ``i < j``);
    with ``first`` (n,) bool, only those whose ``i`` it marks (one tile's, :mod:`planner.verify.tiles`)."""
    if len(pairs) == 0:
        return np.empty((0, 3), dtype=np.int64)
    pairs = np.sort(np.asarray(pairs, dtype=np.int64), axis=1)
    pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
    code = pairs[:, 0] * n + pairs[:, 1]  # sorted, since pairs are lexsorted
    start = np.searchsorted(pairs[:, 0], np.arange(n + 1))
    deg = np.diff(start)
    # For every first vertex i, every two of its higher neighbours j < k; keep those with j-k a pair.
    out = []
    for d in np.unique(deg[deg >= 2]):
        rows = np.flatnonzero((deg == d) & (True if first is None else first))
        a, b = np.triu_indices(int(d), 1)
        nb = pairs[start[rows][:, None] + np.arange(d), 1]  # (rows, d) neighbours, ascending
        j, k = nb[:, a].ravel(), nb[:, b].ravel()
        i = np.repeat(rows, len(a))
        pos = np.searchsorted(code, j * n + k)
        ok = (pos < len(code)) & (code[np.minimum(pos, len(code) - 1)] == j * n + k)
        out.append(np.column_stack([i[ok], j[ok], k[ok]]))
    return np.concatenate(out) if out else np.empty((0, 3), dtype=np.int64)


def sides(triples: np.ndarray, xyz: np.ndarray) -> np.ndarray:
    """Side lengths (M x 3) [m] of ``triples`` (M x 3 indices into ``xyz``): side s joins vertex s and s+1."""
    p = xyz[np.asarray(triples, dtype=np.int64).reshape(-1, 3)]
    return np.linalg.norm(p[:, [1, 2, 0]] - p, axis=2)


def longest_side(triples: np.ndarray, xyz: np.ndarray) -> float:
    """Longest side of any of ``triples`` (M x 3 indices into ``xyz``) [m]; 0 for none."""
    return float(sides(triples, xyz).max()) if len(triples) else 0.0


def shape_matches(windows: np.ndarray, xyz: np.ndarray, tolerance_m: float) -> np.ndarray:
    """Every triple of the site (counter-clockwise) whose sides, in some rotation, each lie within
    ``tolerance_m`` of a window's: the only triples that can read like one, whatever the IDs."""
    xy = xyz[:, :2]
    win = counter_clockwise(np.asarray(windows, dtype=np.int64).reshape(-1, 3), xy)
    if len(win) == 0:
        return win
    site = counter_clockwise(site_triples(xy, longest_side(win, xyz) + tolerance_m + 1e-9), xy)
    grain = 1e-7  # shapes this close are one (a lattice's windows have a few hundred shapes) [m]
    exact = np.vstack([sides(np.roll(win, -r, axis=1), xyz) for r in range(3)])
    shapes = np.unique(np.round(exact / grain), axis=0) * grain
    reach = tolerance_m + 1e-9
    lengths = sides(site, xyz)
    near, _ = cKDTree(shapes).query(lengths, k=1, p=np.inf, distance_upper_bound=reach + grain)
    keep = np.asarray(near <= reach - grain)  # certainly within reach of the exact shape the rounded one stands for
    unsure = np.flatnonzero(np.isfinite(near) & ~keep)  # within a grain of the border: ask the exact shapes
    if len(unsure):
        exact_near, _ = cKDTree(exact).query(lengths[unsure], k=1, p=np.inf, distance_upper_bound=reach)
        keep[unsure] = np.isfinite(exact_near)
    return site[keep]


def counter_clockwise(triples: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """The triples in counter-clockwise plan order (as the receiver reads IDs)."""
    p = xy[triples]
    return np.where((twice_signed_area(p) < 0)[:, None], triples[:, [0, 2, 1]], triples)


@dataclass(frozen=True)
class _Readings:
    """Each oriented triple in every rotation whose ID sequence is the smallest: code, sides, triple."""

    code: np.ndarray
    sides: np.ndarray
    triple: np.ndarray
    row: np.ndarray


def _readings(triples: np.ndarray, xyz: np.ndarray, ids: np.ndarray) -> _Readings:
    t = counter_clockwise(np.asarray(triples, dtype=np.int64).reshape(-1, 3), xyz[:, :2])
    k = int(ids.max()) + 1
    codes, lengths, trip, rows = [], [], [], []
    rot = [np.roll(t, -r, axis=1) for r in range(3)]
    c = [(ids[x[:, 0]] * k + ids[x[:, 1]]) * k + ids[x[:, 2]] for x in rot]
    best = np.minimum(np.minimum(c[0], c[1]), c[2])
    for r in range(3):  # several rotations tie only when the three IDs are equal
        keep = c[r] == best
        x = rot[r][keep]
        codes.append(c[r][keep])
        lengths.append(sides(x, xyz))
        trip.append(x)
        rows.append(np.flatnonzero(keep))
    return _Readings(np.concatenate(codes), np.concatenate(lengths), np.concatenate(trip), np.concatenate(rows))


JOIN_CHUNK = 5_000_000
"""Most (window reading, site reading) candidate pairs :func:`find_rivals` compares at once (about 120 bytes each)."""


def find_rivals(windows: np.ndarray, xyz: np.ndarray, ids: np.ndarray, tolerance_m: float,
                site: np.ndarray | None = None) -> list[tuple[int, tuple[int, int, int]]]:
    """Pairs (window row, rival triple) for every physical triple that reads like a window.

    ``windows`` (M x 3 luminaire indices), ``xyz`` (N x 3 [m]), ``ids`` (N,) the IDs,
    ``tolerance_m`` the largest side difference the receiver cannot tell apart [m].
    ``site`` are the triples searched (default: all triples short enough to match).
    Rival triples are returned counter-clockwise, sorted, without repeats per window.
    """
    windows = np.asarray(windows, dtype=np.int64).reshape(-1, 3)
    ids = np.asarray(ids, dtype=np.int64)
    if len(windows) == 0:
        return []
    if site is None:
        site = site_triples(xyz[:, :2], longest_side(windows, xyz) + tolerance_m + 1e-9)
    q, s = _readings(windows, xyz, ids), _readings(site, xyz, ids)
    order = np.argsort(s.code, kind="stable")
    s_code = s.code[order]
    lo, hi = np.searchsorted(s_code, q.code, "left"), np.searchsorted(s_code, q.code, "right")
    found: set[tuple[int, tuple[int, int, int]]] = set()
    cum = np.r_[0, np.cumsum(hi - lo)]
    start = 0
    while start < len(q.code):  # a chunk of readings at a time: at most JOIN_CHUNK candidate pairs (or one reading)
        end = max(start + 1, int(np.searchsorted(cum, cum[start] + JOIN_CHUNK, "right")) - 1)
        a = np.arange(start, end)
        n = hi[a] - lo[a]
        qi = np.repeat(a, n)
        si = order[np.repeat(lo[a] - np.cumsum(np.r_[0, n[:-1]]), n) + np.arange(n.sum())]
        near = np.all(np.abs(q.sides[qi] - s.sides[si]) <= tolerance_m + 1e-9, axis=1)
        same = np.sort(q.triple[qi], axis=1) == np.sort(s.triple[si], axis=1)
        hit = near & ~same.all(axis=1)
        found |= {(int(q.row[x]), _triple(s.triple[y])) for x, y in zip(qi[hit], si[hit])}
        start = end
    return sorted(found)


def _triple(t: np.ndarray) -> tuple[int, int, int]:
    a, b, c = (int(v) for v in t)
    return a, b, c
