"""Every pair that must differ, listed: the reference the planner's indexes are tested against.

A pair is a window and another triple of the site (a window or not) whose sides, counter-clockwise in
one rotation, each differ by at most the tolerance; labels are valid when no pair has equal labels in all
three corresponding places (:func:`planner.verify.rivals.find_rivals`' verdict). The planner does not list
them: they grow with the square of the site (:mod:`planner.codes.readings`).
"""
import numpy as np
from scipy.spatial import cKDTree

from planner.verify.rivals import counter_clockwise, longest_side, sides, site_triples


def _canonical(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """One row (a0 a1 a2 b0 b1 b2) per pair, the same for every rotation and either order: the pair turned so
    that its first triple starts at that triple's smallest luminaire, in the order whose row is smaller."""
    def turned(x, y):
        idx = (np.arange(3)[None, :] + np.argmin(x, axis=1)[:, None]) % 3
        return np.hstack([np.take_along_axis(x, idx, axis=1), np.take_along_axis(y, idx, axis=1)])

    one, two = turned(a, b), turned(b, a)
    diff = two - one
    first = np.argmax(diff != 0, axis=1)
    swap = diff[np.arange(len(diff)), first] < 0
    return np.where(swap[:, None], two, one)


def alike_pairs(windows: np.ndarray, xyz: np.ndarray, tolerance_m: float, site: np.ndarray | None = None) -> np.ndarray:
    """Every pair (window, other triple of ``site``, default every triple short enough) that reads alike
    whenever the labels agree: (P, 6) int64 rows ``a0 a1 a2 b0 b1 b2``, each pair once whatever its
    rotation or order."""
    windows = np.unique(np.sort(np.asarray(windows, dtype=np.int64).reshape(-1, 3), axis=1), axis=0)
    if len(windows) == 0:
        return np.empty((0, 6), dtype=np.int64)
    if site is None:
        site = site_triples(xyz[:, :2], longest_side(windows, xyz) + tolerance_m + 1e-9)
    win = counter_clockwise(windows, xyz[:, :2])
    other = counter_clockwise(np.asarray(site, dtype=np.int64).reshape(-1, 3), xyz[:, :2])
    tree = cKDTree(sides(other, xyz))
    parts = [np.empty((0, 6), dtype=np.int64)]
    for r in range(3):
        w = np.roll(win, -r, axis=1)
        hits = tree.query_ball_point(sides(w, xyz), tolerance_m + 1e-9, p=np.inf)
        n = np.array([len(h) for h in hits], dtype=np.int64)
        u = other[np.concatenate([np.asarray(h, dtype=np.int64) for h in hits])] if n.sum() else other[:0]
        a = np.repeat(w, n, axis=0)
        differ = (np.sort(a, axis=1) != np.sort(u, axis=1)).any(axis=1)
        parts.append(_canonical(a[differ], u[differ]))
    return np.unique(np.concatenate(parts), axis=0)
