"""Windows: the three LEDs a camera uses at a pose, for many poses at once.

A window is, by the paper's rule (section 3), the three LEDs wholly inside the
image that are closest to its centre. Two refusals are ours (docs/verification.md): a window
is no fix when its triangle, as drawn in the plan, is (nearly) collinear, or when another
LED's disc overlaps one of its sides (:func:`crossed`). This module samples poses over a working
area, finds each pose's window (vectorised over poses), and canonicalises the
windows found: counter-clockwise order and a congruence class of their triangle,
as the receiver sees them (it reads IDs in cyclic order and measures the
triangle, but does not know its yaw).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from itertools import chain

import numpy as np
from matplotlib.path import Path as PolygonPath
from numba import njit
from scipy.spatial import ConvexHull, QhullError, cKDTree

from planner.camera.model import Camera, Poses
from planner.defaults import CONGRUENCE_TOLERANCE_M, POSES_PER_M2
from planner.layout.model import area_m2

CANDIDATES = 24
"""LEDs examined per pose: those nearest the point where the optical axis meets the ceiling."""

MIN_FLATNESS = 0.1
"""A triangle whose height is under this share of its longest side counts as collinear."""

SAME_HEIGHT_M = 1e-3
"""LEDs whose heights differ by less than this count as one ceiling plane [m]."""


_BATCH = 20000
_SOBOL_CHUNK_LOG2 = 16


def working_area(xy: np.ndarray, outline) -> np.ndarray:
    """The floor area poses are sampled in: the room outline, else the luminaires' convex hull."""
    if outline is not None and len(outline) >= 3:
        return np.asarray(outline, dtype=float)
    try:
        return xy[ConvexHull(xy).vertices]
    except QhullError:  # collinear: a thin strip around them
        lo, hi = xy.min(axis=0) - 0.25, xy.max(axis=0) + 0.25
        return np.array([lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]])




def pose_count(area: np.ndarray, per_m2: float) -> int:
    """Poses :func:`sample_poses` draws over ``area`` (polygon [m]) at ``per_m2`` per square metre."""
    return max(1, int(round(per_m2 * max(area_m2(area), 1e-6))))


def sample_poses(area: np.ndarray, camera: Camera, per_m2: float = POSES_PER_M2, seed: int = 0) -> Poses:
    """Quasi-random poses over ``area`` (polygon [m]): position, height, tilt, azimuth, roll.

    A scrambled Sobol sequence over (x, y, height, tilt, azimuth, roll); tilt is
    uniform in [0, max_tilt] (more weight on strong tilts than a uniform cap, so
    the hard cases are well sampled); points outside the area are dropped. The
    sample at a lower density is the first :func:`pose_count` poses of this one
    (same seed): the points are kept in sequence order.
    """
    polygon = PolygonPath(area)
    lo, hi = area.min(axis=0), area.max(axis=0)
    wanted = pose_count(area, per_m2)
    from scipy.stats import qmc  # here: scipy.stats alone costs about 0.4 s to import, and only sampling needs it

    sobol = qmc.Sobol(d=6, scramble=True, seed=seed)
    chunks, have = [], 0
    while have < wanted:  # draw in power-of-two chunks (Sobol balance), keep those inside the area
        u = sobol.random_base2(_SOBOL_CHUNK_LOG2) if sobol.num_generated == 0 else sobol.random(2**_SOBOL_CHUNK_LOG2)
        u = u[polygon.contains_points(lo + u[:, :2] * (hi - lo))]
        chunks.append(u[: wanted - have])
        have += len(chunks[-1])
    u = np.concatenate(chunks)
    xy = lo + u[:, :2] * (hi - lo)
    height = camera.min_height_m + u[:, 2] * (camera.max_height_m - camera.min_height_m)
    return Poses(np.column_stack([xy, height]), u[:, 3] * camera.max_tilt_rad, u[:, 4] * 2 * math.pi,
                 u[:, 5] * 2 * math.pi)


@dataclass(frozen=True)
class PoseWindows:
    """The window of every pose.

    Attributes
    ----------
    triples : numpy.ndarray of int, shape (P, 3)
        Luminaire indices of each pose's window, in increasing index order; -1 where
        fewer than three LEDs are seen.
    seen : numpy.ndarray of int, shape (P,)
        LEDs wholly inside the image, among those examined (at most ``CANDIDATES``).
    collinear : numpy.ndarray of bool, shape (P,)
        No fix from the window: its three LEDs are (nearly) on one line, or another LED's
        disc overlaps one of its sides (:func:`crossed`).
    """

    triples: np.ndarray
    seen: np.ndarray
    collinear: np.ndarray

    @property
    def covered(self) -> np.ndarray:
        """Poses with three non-collinear LEDs seen."""
        return (self.triples[:, 0] >= 0) & ~self.collinear

    def first(self, n: int) -> PoseWindows:
        return PoseWindows(self.triples[:n], self.seen[:n], self.collinear[:n])


@dataclass(frozen=True)
class PoseSample:
    """One seeded pose sample over a working area and each pose's window, drawn once per plan.

    Stages that sample at different densities (verification, chip timing, the error map)
    take :meth:`first`: a prefix is exactly what :func:`sample_poses` draws at the lower
    density with the same seed, so sharing one draw changes no result.
    """

    area: np.ndarray
    poses: Poses
    windows: PoseWindows
    seed: int
    found: dict = field(default_factory=dict, compare=False, repr=False)  # other windows of these poses, found once

    @classmethod
    def draw(cls, area: np.ndarray, xyz: np.ndarray, radii: np.ndarray, camera: Camera, per_m2: float,
             seed: int = 0) -> PoseSample:
        poses = sample_poses(area, camera, per_m2, seed)
        return cls(area, poses, find_windows(poses, xyz, radii, camera), seed)

    def first(self, per_m2: float) -> tuple[Poses, PoseWindows]:
        """The poses and windows :func:`sample_poses` and :func:`find_windows` give at ``per_m2``."""
        n = pose_count(self.area, per_m2)
        if n > len(self.poses):
            raise ValueError(f"{per_m2:g} poses per m^2 need {n} poses; the sample holds {len(self.poses)}")
        return self.poses.subset(slice(0, n)), self.windows.first(n)


def twice_signed_area(p: np.ndarray) -> np.ndarray:
    """Twice the signed plan area of triangles ``p`` (T, 3, >= 2) [m^2]: positive when counter-clockwise."""
    return (p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0])


def flatness(p: np.ndarray) -> np.ndarray:
    """Triangle height over longest side, for triangles ``p`` of shape (..., 3, 3) [m]."""
    e = np.stack([p[..., 1, :] - p[..., 0, :], p[..., 2, :] - p[..., 1, :], p[..., 0, :] - p[..., 2, :]], -2)
    longest2 = np.max(np.sum(e**2, axis=-1), axis=-1)
    twice_area = np.linalg.norm(np.cross(e[..., 0, :], -e[..., 2, :]), axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(longest2 > 0, twice_area / longest2, 0.0)


def nearest_seen(poses: Poses, xyz: np.ndarray, radii: np.ndarray, camera: Camera, count: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The ``count`` wholly seen LEDs nearest the image centre at every pose, (P, count) luminaire indices
    ascending (-1 where fewer are seen), and how many LEDs are wholly seen (P,) among those examined.

    Through a distorting lens "wholly seen" is inside ``camera.view_px`` and "nearest" is by the ray
    angle from the optical axis (ideal pixels, as :func:`planner.camera.model.project_discs` gives them;
    docs/verification.md). The image bounds and the choice are compiled (:func:`_nearest_inside`).
    """
    tree = cKDTree(xyz[:, :2])
    ceiling = float(np.median(xyz[:, 2]))
    chosen = np.full((len(poses), count), -1, dtype=np.int64)
    seen = np.zeros(len(poses), dtype=np.int64)
    for start in range(0, len(poses), _BATCH):
        part = poses.subset(slice(start, start + _BATCH))
        axis = np.ascontiguousarray(part.rotation[:, :, 2])
        kr = camera.intrinsics @ np.swapaxes(part.rotation, 1, 2)  # K R^T, as planner.camera.model._disc_terms has it
        _nearest_inside(kr, axis, np.hypot(axis[:, 0], axis[:, 1]), part.position, xyz, radii,
                        candidates(part, tree, ceiling), np.array(camera.view_px), camera.cx_px, camera.cy_px,
                        chosen[start:start + len(part)], seen[start:start + len(part)])
    return chosen, seen


def candidates(poses: Poses, tree: cKDTree, ceiling_m: float) -> np.ndarray:
    """The :data:`CANDIDATES` LEDs (P, K) whose centres lie nearest the point where each pose's optical axis meets
    the ceiling at height ``ceiling_m`` [m] (``tree``: the LEDs' x, y): those :func:`nearest_seen` examines."""
    axis = poses.rotation[:, :, 2]
    reach = (ceiling_m - poses.position[:, 2]) / np.maximum(axis[:, 2], 1e-6)
    k = min(CANDIDATES, tree.n)
    _, cand = tree.query(poses.position[:, :2] + reach[:, None] * axis[:, :2], k=k)
    return cand.reshape(len(poses), k)


@njit(cache=True)
def _dot(row, x, y, z):
    """``row · (x, y, z)``, summed from zero in order as ``numpy.einsum`` sums."""
    acc = 0.0
    acc += row[0] * x
    acc += row[1] * y
    acc += row[2] * z
    return acc


@njit(cache=True, error_model="numpy")
def _nearest_inside(kr, axis, tilt, position, xyz, radii, cand, view, cx, cy, chosen, seen):
    """:func:`nearest_seen` for one batch of P poses, into ``chosen`` (P, count) and ``seen`` (P,).

    Of the candidates ``cand`` (P, K), the discs wholly in front of the camera and imaged wholly inside ``view``
    (u_lo, u_hi, v_lo, v_hi) [px] are seen; the ``count`` whose centres image nearest (``cx``, ``cy``) [px], ties
    in candidate order, are chosen, as luminaire indices ascending. ``kr`` is ``K R^T`` (P, 3, 3), ``axis`` the
    optical axis (P, 3) and ``tilt`` its horizontal length (P,). The arithmetic is
    :func:`planner.camera.model.project_discs_at`'s, term by term and in its order (the same floats)."""
    count = chosen.shape[1]
    best_d = np.empty(count)
    best_k = np.empty(count, np.int64)
    for p in range(cand.shape[0]):
        n_in = 0
        n_best = 0
        for k in range(cand.shape[1]):
            c = cand[p, k]
            d0, d1, d2 = xyz[c, 0] - position[p, 0], xyz[c, 1] - position[p, 1], xyz[c, 2] - position[p, 2]
            if not _dot(axis[p], d0, d1, d2) - radii[c] * tilt[p] > 1e-9:
                continue  # some of the rim is behind the camera
            h = (_dot(kr[p, 0], d0, d1, d2), _dot(kr[p, 1], d0, d1, d2), _dot(kr[p, 2], d0, d1, d2))  # H's third column
            r2 = radii[c] * radii[c]
            c22 = r2 * (kr[p, 2, 0] * kr[p, 2, 0] + kr[p, 2, 1] * kr[p, 2, 1]) - h[2] * h[2]
            inside = True
            for a in range(2):  # the image's extent along u, then v: tangents solve a quadratic
                caa = r2 * (kr[p, a, 0] * kr[p, a, 0] + kr[p, a, 1] * kr[p, a, 1]) - h[a] * h[a]
                ca2 = r2 * (kr[p, a, 0] * kr[p, 2, 0] + kr[p, a, 1] * kr[p, 2, 1]) - h[a] * h[2]
                t = ca2 * ca2 - caa * c22
                if not (t >= 0.0 or t != t):  # np.maximum(t, 0.0)
                    t = 0.0
                disc = np.sqrt(t)
                lo, hi = (ca2 - disc) / c22, (ca2 + disc) / c22
                if lo != lo or hi != hi or not (min(lo, hi) >= view[2 * a] and max(lo, hi) <= view[2 * a + 1]):
                    inside = False
                    break
            if not inside:
                continue
            n_in += 1
            du, dv = h[0] / h[2] - cx, h[1] / h[2] - cy
            d = du * du + dv * dv
            if not np.isfinite(d) or (n_best == count and not d < best_d[count - 1]):
                continue  # a stable sort keeps the earlier of equals
            j = min(n_best, count - 1)
            while j > 0 and d < best_d[j - 1]:
                best_d[j], best_k[j] = best_d[j - 1], best_k[j - 1]
                j -= 1
            best_d[j], best_k[j] = d, k
            n_best = min(n_best + 1, count)
        seen[p] = n_in
        if n_best == count:  # the chosen, ascending (an insertion sort: np.sort would compile a quicksort)
            for j in range(count):
                v, i = cand[p, best_k[j]], j
                while i > 0 and chosen[p, i - 1] > v:
                    chosen[p, i] = chosen[p, i - 1]
                    i -= 1
                chosen[p, i] = v


def find_windows(poses: Poses, xyz: np.ndarray, radii: np.ndarray, camera: Camera) -> PoseWindows:
    """The paper's window at every pose: the 3 fully seen LEDs nearest the image centre (:func:`nearest_seen`);
    collinear (drawn) and crossed windows give no fix."""
    triples, seen = nearest_seen(poses, xyz, radii, camera, 3)
    collinear = np.zeros(len(poses), dtype=bool)
    has = triples[:, 0] >= 0
    if has.any():
        distinct, back = np.unique(triples[has], axis=0, return_inverse=True)
        no_fix = (flatness(xyz[distinct]) < MIN_FLATNESS) | crossed(distinct, xyz, radii)
        collinear[has] = no_fix[back.ravel()]
    return PoseWindows(triples, seen, collinear)


def crossed(triples: np.ndarray, xyz: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Whether another LED's disc overlaps a side of each triangle ``triples`` (T, 3): the straight segment
    between two members' centres, in plan (T,).

    The receiver refuses such a window. Its sides lie wholly in view (they join centres of whole discs),
    so an overlapping disc shows where it overlaps, and the image's segment between the two members'
    centres runs through that LED's blob: the receiver sees it. This is what lets the proof count LEDs
    on and near a triangle's edge at any install tolerance, which the paper's rule alone does not
    (docs/verification.md, "The crossing rule")."""
    xy = xyz[:, :2]
    out = np.zeros(len(triples), dtype=bool)
    if len(triples) == 0 or len(xy) <= 3:
        return out
    tree = cKDTree(xy)
    big = float(np.max(radii))
    for i, j in ((0, 1), (1, 2), (2, 0)):
        a, b = xy[triples[:, i]], xy[triples[:, j]]
        half = 0.5 * np.linalg.norm(b - a, axis=1)
        t, k = ball_pairs(tree, 0.5 * (a + b), half + big)  # (triangle, LED) pairs near this side
        other = (k != triples[t, 0]) & (k != triples[t, 1]) & (k != triples[t, 2])
        other &= np.abs(xyz[k, 2] - xyz[triples[t, i], 2]) < SAME_HEIGHT_M  # another LED, at the side's height
        t, k = t[other], k[other]
        gap = segment_distance(a[t], b[t], xy[k][:, None])[:, 0]
        out[t[gap < radii[k]]] = True
    return out


def ball_pairs(tree: cKDTree, points: np.ndarray, reach_m) -> tuple[np.ndarray, np.ndarray]:
    """Every hit of ``tree.query_ball_point(points, reach_m)`` as a pair: the index into ``points`` and the tree's
    point within ``reach_m`` [m] (scalar or one per point) of it, (M,) each, by query and in the tree's order."""
    found = tree.query_ball_point(points, reach_m)
    counts = np.fromiter(map(len, found), dtype=np.int64, count=len(found))
    return (np.repeat(np.arange(len(found)), counts),
            np.fromiter(chain.from_iterable(found), dtype=np.int64, count=int(counts.sum())))


def segment_distance(a: np.ndarray, b: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Distance [m] from points ``x`` (T, m, 2) to the segments ``a b`` (T, 2) in plan."""
    ab = b - a
    length2 = np.maximum(np.sum(ab * ab, axis=1), 1e-24)[:, None]
    t = np.clip(np.einsum("tmk,tk->tm", x - a[:, None], ab) / length2, 0.0, 1.0)
    return np.linalg.norm(x - (a[:, None] + t[..., None] * ab[:, None]), axis=2)


@dataclass(frozen=True)
class WindowSet:
    """Distinct non-collinear windows, canonicalised for keys.

    Attributes
    ----------
    windows : numpy.ndarray of int, shape (M, 3)
        Luminaire indices, counter-clockwise in plan, starting at the shape's canonical vertex.
    shape : numpy.ndarray of int, shape (M,)
        Congruence class of the window's triangle.
    symmetric : numpy.ndarray of bool, shape (S,)
        Shapes with three equal sides (any vertex can start).
    """

    windows: np.ndarray
    shape: np.ndarray
    symmetric: np.ndarray

    def __len__(self) -> int:
        return len(self.windows)


def _length_classes(lengths: np.ndarray, tolerance_m: float) -> np.ndarray:
    """Class of each length: sorted lengths split where neighbours differ by more than the tolerance."""
    order = np.argsort(lengths, kind="stable")
    cls_sorted = np.concatenate([[0], np.cumsum(np.diff(lengths[order]) > tolerance_m)])
    out = np.empty(len(lengths), dtype=np.int64)
    out[order] = cls_sorted
    return out


def canonical_windows(triples: np.ndarray, xyz: np.ndarray, tolerance_m: float = CONGRUENCE_TOLERANCE_M) -> WindowSet:
    """Canonical form of the distinct windows among ``triples`` (rows of 3 indices, -1 rows ignored)."""
    t = np.unique(np.sort(triples[triples[:, 0] >= 0], axis=1), axis=0)
    if len(t) == 0:
        return WindowSet(np.empty((0, 3), dtype=np.int64), np.empty(0, dtype=np.int64), np.zeros(0, dtype=bool))
    p = xyz[t]
    t = np.where((twice_signed_area(p) < 0)[:, None], t[:, [0, 2, 1]], t)  # counter-clockwise in plan
    p = xyz[t]
    sides = np.linalg.norm(p[:, [1, 2, 0]] - p, axis=2)  # side k joins vertex k and k+1
    cls = _length_classes(sides.ravel(), tolerance_m).reshape(-1, 3)
    rotations = np.stack([np.roll(cls, -r, axis=1) for r in range(3)], axis=1)  # (M, 3 rot, 3)
    code = (rotations[..., 0] * (cls.max() + 1) + rotations[..., 1]) * (cls.max() + 1) + rotations[..., 2]
    best = np.argmin(code, axis=1)
    t = np.stack([np.roll(row, -r) for row, r in zip(t, best)]) if len(t) else t
    shape_code = code[np.arange(len(code)), best]
    shapes, shape = np.unique(shape_code, return_inverse=True)
    canon = rotations[np.arange(len(code)), best]
    symmetric = np.zeros(len(shapes), dtype=bool)
    equal = (canon[:, 0] == canon[:, 1]) & (canon[:, 1] == canon[:, 2])
    symmetric[shape[equal]] = True
    return WindowSet(t.astype(np.int64), shape.astype(np.int64), symmetric)
