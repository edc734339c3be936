"""The window set: every triple of the site that passes a proved necessary condition for a window.

**Empty-triangle rule.** If three LEDs ``a, b, c`` are a window at some pose, no other
LED of the same height and no larger disc lies in their closed triangle. Proof: such
an LED's disc lies in the convex hull of the three discs, whose image (a convex set:
the hull is in front of the camera) lies in the image, so it is wholly in view (through a
lens: ideal images and the view rectangle, both convex; docs/verification.md); and
the ceiling points whose image is within a distance of the image centre fill an
ellipse (a plane section of the cone of those rays, bounded while the largest tilt
plus the corner angle stays under 90 deg), so by strict convexity that LED is nearer
the image centre than the farthest of ``a, b, c``: the paper's rule would have taken
it. With luminaires installed up to ``d`` from the drawing, an edge line moves by at
most ``d`` at its ends and the LED by ``d``, so only LEDs deeper than ``2 d`` inside
every edge of the drawn triangle are sure to be inside the installed one.

**Crossing rule** (ours, not the paper's; docs/verification.md). The receiver refuses a window
one of whose sides, the straight segment between two members' centres, another LED's disc
overlaps (:func:`planner.verify.windows.crossed`). An LED whose drawn centre lies within
``r - 2 d`` of a drawn side (``r`` its radius) overlaps the installed side, so no such triple is
a window, whatever the installation: the LEDs on and near an edge that the ``2 d`` margin above
lets through are caught here. And the receiver judges a window collinear on the plan's (drawn)
triangle, so a triple drawn flatter than :data:`~planner.verify.windows.MIN_FLATNESS` is no window.

The rule needs every ray in view to meet the ceiling (largest tilt plus corner angle
under 90 deg; :func:`planner.verify.proof.envelope` checks it) and says nothing about
long triangles: here the set is bounded by a side length from a dense pose sample, so
it is complete only up to that bound. :mod:`planner.verify.proof` bounds it for every
pose instead (docs/verification.md).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from planner.verify.rivals import site_triples
from planner.verify.windows import MIN_FLATNESS, SAME_HEIGHT_M, segment_distance, twice_signed_area

NEIGHBOURS = 32
"""LEDs nearest a triangle's centroid that are tested for lying inside it (more only prune more)."""


FIRST = 4
"""LEDs nearest the centroid looked up and tested first: most triangles that hold an LED hold one of
these, so only the rest are tested against all :data:`NEIGHBOURS` (the same answer, measured 2026-12-03
on grid-512's 2.7 million candidates: 3.6 s, where one pass of all 35 over all of them took 28 s and 5.6 GB)."""

_CHUNK = 100_000


def empty_triangles(triples: np.ndarray, xyz: np.ndarray, radii: np.ndarray, install_tolerance_m: float) -> np.ndarray:
    """Which ``triples`` (T x 3 luminaire indices) hold no other LED that forbids them as a window."""
    triples = np.asarray(triples, dtype=np.int64).reshape(-1, 3)
    if len(triples) == 0 or len(xyz) <= 3:
        return np.ones(len(triples), dtype=bool)
    xy = xyz[:, :2]
    k = min(NEIGHBOURS + 3, len(xy))
    tree = cKDTree(xy)
    out = np.ones(len(triples), dtype=bool)
    for start in range(0, len(triples), _CHUNK):  # in chunks: (T, k) temporaries of millions of triples
        t = triples[start:start + _CHUNK]
        centroid = xy[t].mean(axis=1)
        first = min(FIRST, k)
        _, near = tree.query(centroid, k=first)
        held = _holds(t, near.reshape(len(t), first), xyz, radii, install_tolerance_m)
        rest = np.flatnonzero(~held)
        if len(rest) and k > first:
            _, near = tree.query(centroid[rest], k=k)
            held[rest] = _holds(t[rest], near.reshape(len(rest), k), xyz, radii, install_tolerance_m)
        p = xy[t]
        flat = np.abs(twice_signed_area(p)) <= 1e-12 * np.max(np.linalg.norm(p - p[:, [1, 2, 0]], axis=2), axis=1) ** 2
        out[start:start + len(t)] = ~held | flat  # three in a row: no claim
    return out


def _holds(triples: np.ndarray, near: np.ndarray, xyz: np.ndarray, radii: np.ndarray,
           install_tolerance_m: float) -> np.ndarray:
    """Whether some LED of ``near`` (T x m candidates per triple) forbids each triple: another LED of the
    same ceiling and no larger disc, deeper than ``2 d`` inside every edge of the drawn triangle, or any other
    LED of the same ceiling whose centre lies within its radius less ``2 d`` of a drawn side (it crosses that
    side however the luminaires are installed)."""
    xy = xyz[:, :2]
    p = xy[triples]  # (T, 3, 2)
    q = xy[near]  # (T, m, 2)
    orient = np.where(twice_signed_area(p) >= 0, 1.0, -1.0)[:, None]
    margin = 2.0 * install_tolerance_m  # 0: the closed triangle (an LED on an edge is nearer too)
    inside = np.ones(near.shape, dtype=bool)
    for s in range(3):  # signed distance from each edge line, positive towards the triangle
        a, b = p[:, s], p[:, (s + 1) % 3]
        edge = b - a
        length = np.linalg.norm(edge, axis=1)[:, None]
        dist = orient * (edge[:, None, 0] * (q[..., 1] - a[:, None, 1]) - edge[:, None, 1] * (q[..., 0] - a[:, None, 0]))
        inside &= dist >= margin * np.maximum(length, 1e-12)
    member = (near[:, :, None] == triples[:, None, :]).any(axis=2)
    crossing = np.zeros(near.shape, dtype=bool)
    for s in range(3):
        crossing |= segment_distance(p[:, s], p[:, (s + 1) % 3], q) + margin < radii[near]
    coplanar = (np.abs(xyz[near, 2] - xyz[triples, 2].min(axis=1)[:, None]) < SAME_HEIGHT_M) \
        & (np.ptp(xyz[triples, 2], axis=1) < SAME_HEIGHT_M)[:, None]
    small = radii[near] <= radii[triples].min(axis=1)[:, None]
    return (((inside & small) | crossing) & ~member & coplanar).any(axis=1)


def may_be_decoded(p: np.ndarray) -> np.ndarray:
    """Triangles ``p`` (T, 3, 2) [m], as drawn, that the receiver does not call collinear (flatness at least
    :data:`MIN_FLATNESS`): it judges the plan's triangle of the luminaires it read, not their installed shape,
    so the install tolerance does not blur this line (docs/verification.md)."""
    e = p[:, [1, 2, 0]] - p
    longest = np.linalg.norm(e, axis=2).max(axis=1)
    return np.abs(twice_signed_area(p)) >= MIN_FLATNESS * np.maximum(longest, 1e-12) ** 2


def window_superset(xyz: np.ndarray, radii: np.ndarray, max_side_m: float, install_tolerance_m: float) -> np.ndarray:
    """Every triple with sides at most ``max_side_m`` that the empty-triangle and crossing rules allow (T x 3),
    less those drawn too flat to decode."""
    cand = site_triples(xyz[:, :2], max_side_m)
    cand = cand[empty_triangles(cand, xyz, radii, install_tolerance_m)]
    return cand[may_be_decoded(xyz[cand][:, :, :2])]
