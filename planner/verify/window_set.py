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
from numba import njit
from scipy.spatial import cKDTree

from planner.verify.rivals import site_triples
from planner.verify.windows import MIN_FLATNESS, SAME_HEIGHT_M, twice_signed_area

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
    xyz = np.ascontiguousarray(xyz, dtype=np.float64)
    return _holds_kernel(np.ascontiguousarray(triples, dtype=np.int64), np.ascontiguousarray(near, dtype=np.int64),
                         xyz, np.ascontiguousarray(radii, dtype=np.float64), 2.0 * install_tolerance_m, SAME_HEIGHT_M)


@njit(cache=True)
def _holds_kernel(triples, near, xyz, radii, margin, same_height):
    """:func:`_holds`, one triple at a time, stopping at the first LED that forbids it (``margin``: ``2 d``;
    0 tests the closed triangle: an LED on an edge is nearer too). The arithmetic is numpy's, term by term."""
    held = np.zeros(len(triples), dtype=np.bool_)
    for t in range(len(triples)):
        i, j, k = triples[t, 0], triples[t, 1], triples[t, 2]
        zmin = min(xyz[i, 2], xyz[j, 2], xyz[k, 2])
        if max(xyz[i, 2], xyz[j, 2], xyz[k, 2]) - zmin >= same_height:
            continue  # not one ceiling: no claim
        rmin = min(radii[i], radii[j], radii[k])
        px = (xyz[i, 0], xyz[j, 0], xyz[k, 0])
        py = (xyz[i, 1], xyz[j, 1], xyz[k, 1])
        area2 = (px[1] - px[0]) * (py[2] - py[0]) - (py[1] - py[0]) * (px[2] - px[0])
        orient = 1.0 if area2 >= 0 else -1.0
        for c in range(near.shape[1]):
            q = near[t, c]
            if q == i or q == j or q == k or abs(xyz[q, 2] - zmin) >= same_height:
                continue
            qx, qy = xyz[q, 0], xyz[q, 1]
            inside = radii[q] <= rmin
            crossing = False
            for s in range(3):
                ax, ay = px[s], py[s]
                ex, ey = px[(s + 1) % 3] - ax, py[(s + 1) % 3] - ay
                length2 = ex * ex + ey * ey
                if orient * (ex * (qy - ay) - ey * (qx - ax)) < margin * max(np.sqrt(length2), 1e-12):
                    inside = False
                u = min(max(((qx - ax) * ex + (qy - ay) * ey) / max(length2, 1e-24), 0.0), 1.0)
                dx, dy = qx - (ax + u * ex), qy - (ay + u * ey)
                if np.sqrt(dx * dx + dy * dy) + margin < radii[q]:
                    crossing = True
            if inside or crossing:
                held[t] = True
                break
    return held


def may_be_decoded(p: np.ndarray) -> np.ndarray:
    """Triangles ``p`` (T, 3, 2) [m], as drawn, that the receiver does not call collinear (flatness at least
    :data:`MIN_FLATNESS`): it judges the plan's triangle of the luminaires it read, not their installed shape,
    so the install tolerance does not blur this line (docs/verification.md)."""
    return _decodable(np.ascontiguousarray(p[:, :, :2], dtype=np.float64), MIN_FLATNESS)


@njit(cache=True)
def _decodable(p, min_flatness):
    """:func:`may_be_decoded`, triangle by triangle (numpy's arithmetic, term by term)."""
    out = np.empty(len(p), dtype=np.bool_)
    for t in range(len(p)):
        longest = 0.0
        for s in range(3):
            dx, dy = p[t, (s + 1) % 3, 0] - p[t, s, 0], p[t, (s + 1) % 3, 1] - p[t, s, 1]
            longest = max(longest, np.sqrt(dx * dx + dy * dy))
        area2 = ((p[t, 1, 0] - p[t, 0, 0]) * (p[t, 2, 1] - p[t, 0, 1])
                 - (p[t, 1, 1] - p[t, 0, 1]) * (p[t, 2, 0] - p[t, 0, 0]))
        longest = max(longest, 1e-12)
        out[t] = abs(area2) >= min_flatness * (longest * longest)
    return out


def window_superset(xyz: np.ndarray, radii: np.ndarray, max_side_m: float, install_tolerance_m: float) -> np.ndarray:
    """Every triple with sides at most ``max_side_m`` that the empty-triangle and crossing rules allow (T x 3),
    less those drawn too flat to decode."""
    cand = site_triples(xyz[:, :2], max_side_m)
    cand = cand[empty_triangles(cand, xyz, radii, install_tolerance_m)]
    return cand[may_be_decoded(xyz[cand][:, :, :2])]
