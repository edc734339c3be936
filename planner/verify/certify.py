"""The certificate over pose boxes: which candidate windows no pose of the envelope can take.

:func:`certify_windows` takes a proved superset of the windows (T x 3 luminaire indices, e.g. from
:func:`planner.verify.proof.possible_windows`) and returns the subset it cannot prove impossible. The axis
points are cut into square tiles; each tile's poses (axis point in the tile, every ceiling distance, tilt
and tilt direction of the envelope, every roll) are searched by branch and bound over pose boxes
(:mod:`planner.verify.certify_box` bounds one box). A box is a leaf when every triple that may be its
window is already *known*: a real window found by evaluating poses (the seed), a triple already kept, or
one outside the candidate set. A box that still has unknown possible windows is split; at the smallest
width its possible windows are kept. So every window of every pose is kept (docs/verification.md, "The
certificate over pose boxes"). Tiles whose neighbourhood (and candidates) repeat by translation, as on a
lattice, are certified once. A tile over its box budget keeps every candidate within its reach.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from planner.camera.model import Camera
from planner.verify import certify_box as cb
from planner.verify import certify_witness as cw
from planner.verify.envelope import Envelope, envelope
from planner.verify.window_set import SAME_HEIGHT_M

MIN_WIDTH = 0.004
"""Box width (the largest of its scaled sides, roughly radians of ray angle) below which a box is not split."""

BOX_BUDGET = 400_000
"""Most boxes one tile may take; a tile over it keeps every candidate within its reach."""

CAP = 12
"""Most LEDs that may be among a box's three nearest at one roll before the box is split."""

LEAF_CAP = 32
"""Most candidates at one roll in a box too small to split; more and the tile falls back."""

SEED_POSES = 4_000
"""Poses drawn per tile, their exact windows known before the search."""

WITNESSES = 24
"""Poses drawn in a box whose possible windows are not all known, before it is split."""

FAVOURED = 3
"""Unknown possible windows of a box tried, each with the installation that favours it, before it is split."""


Triple = tuple[int, int, int]


def _triples(rows: np.ndarray) -> list[Triple]:
    """Rows of three indices as tuples (set members)."""
    return [(int(a), int(b), int(c)) for a, b, c in rows.tolist()]


@dataclass
class TileResult:
    """One tile's outcome: the certified triples (global indices), boxes searched, and whether it fell back."""

    triples: set[Triple]
    boxes: int
    fallback: bool
    leaf_kept: int = 0


@dataclass
class Certificate:
    """What :func:`certify_windows` found: the kept triangles (T x 3) and how the tiles went."""

    triangles: np.ndarray
    tiles: int
    distinct_tiles: int
    fallback_tiles: int
    boxes: int
    seconds: float = 0.0
    per_tile: list[TileResult] = field(default_factory=list, repr=False)


def view_bounds(camera: Camera, env: Envelope) -> tuple[np.ndarray, np.ndarray]:
    """The view rectangle in normalised coordinates ``(x_lo, x_hi, y_lo, y_hi)`` for exact windows, and for box
    bounds ``(A_in, B_in, A_out, B_out, wz_min)``: half-sides inside and around it, and the least depth [m] of a
    centre in view (``near cos κ``: a centre in view is within the corner angle ``κ`` of the axis)."""
    f = camera.fx_px
    u0, u1, v0, v1 = camera.view_px
    view = np.array([(u0 - camera.cx_px) / f, (u1 - camera.cx_px) / f, (v0 - camera.cy_px) / f, (v1 - camera.cy_px) / f])
    a_in, a_out = min(-view[0], view[1]), max(-view[0], view[1])
    b_in, b_out = min(-view[2], view[3]), max(-view[2], view[3])
    near = env.near_m - SAME_HEIGHT_M
    return view, np.array([a_in, b_in, a_out, b_out, near * math.cos(env.corner_rad) * (1 - 1e-9)])


def _widths(box: np.ndarray, near_m: float) -> np.ndarray:
    """A box's sides scaled to their effect on a ray angle [rad]: plan sides over the nearest ceiling distance,
    the distance's side a third of that, tilt as is, tilt direction by the sine of the largest tilt."""
    return np.array([(box[1] - box[0]) / near_m, (box[3] - box[2]) / near_m, 0.3 * (box[5] - box[4]) / near_m,
                     box[7] - box[6], 0.5 * math.sin(box[7]) * (box[9] - box[8])])


def certify_tile(tile: np.ndarray, xy: np.ndarray, radii: np.ndarray, cand: set[Triple],
                 env: Envelope, views: tuple[np.ndarray, np.ndarray], *, min_width: float = MIN_WIDTH,
                 budget: int = BOX_BUDGET, seed: int = 0) -> TileResult:
    """Certify one tile of axis points ``tile`` = (x0, x1, y0, y1) [m]: ``xy``, ``radii`` the LEDs (local indices)
    any of its poses may see, ``cand`` the candidate triples among them (local, ascending). Returns the kept
    candidates (local indices)."""
    view, bview = views
    d = env.install_m
    root = np.array([tile[0], tile[1], tile[2], tile[3], env.near_m - SAME_HEIGHT_M, env.far_m + SAME_HEIGHT_M,
                     0.0, env.tilt_rad, 0.0, 2 * math.pi])
    known: set[Triple] = set()
    buf = np.empty((max(SEED_POSES, WITNESSES) + 8, 3), dtype=np.int64)

    def learn(box: np.ndarray, count: int, s: int, favour: tuple[int, ...] = ()) -> None:
        k = cw.box_witnesses(box, xy, radii, view, count, s, buf, np.array(favour, dtype=np.int64), d)
        known.update(t for t in _triples(buf[:k]) if t in cand)

    learn(root, SEED_POSES, seed)
    out, big = np.empty((4096, 3), dtype=np.int64), np.empty((LEAF_CAP**3 // 6 * 4, 3), dtype=np.int64)
    stack = [root]
    boxes = leaf_kept = 0
    while stack:
        box = stack.pop()
        boxes += 1
        if boxes > budget:
            return TileResult(set(cand), boxes, True)
        widths = _widths(box, env.near_m)
        small = widths.max() < min_width
        n = cb.box_windows(box, xy, radii, bview, d, CAP, out)
        if n < 0 and small:  # a crowded leaf: every possible window kept, however many
            n = cb.box_windows(box, xy, radii, bview, d, LEAF_CAP, big)
            if n < 0:
                return TileResult(set(cand), boxes, True)
            out_n = big
        else:
            out_n = out
        if n >= 0:
            new = [t for t in _triples(out_n[:n]) if t in cand and t not in known]
            if not new:
                continue
            learn(box, WITNESSES, boxes)
            for t in new[:FAVOURED]:
                if t not in known:
                    learn(box, WITNESSES, boxes, t)
            new = [t for t in new if t not in known]
            if not new:
                continue
            if small:
                known.update(new)
                leaf_kept += len(new)
                continue
        axis = int(np.argmax(widths))
        mid = 0.5 * (box[2 * axis] + box[2 * axis + 1])
        lo, hi = box.copy(), box.copy()
        lo[2 * axis + 1], hi[2 * axis] = mid, mid
        stack += [lo, hi]
    return TileResult(known, boxes, False, leaf_kept)


def tile_grid(xy: np.ndarray, env: Envelope, tile_m: float | None = None) -> tuple[np.ndarray, float, int, int]:
    """The tiles of axis points: origin [m], side [m] (default: the median distance between nearest luminaires,
    so that a lattice's tiles are its cells), columns and rows; they cover every axis point within the axis
    reach (and the tolerance) of a luminaire, the only ones whose poses may see one. Tile ``k`` is column
    ``k % nx``, row ``k // nx``."""
    if tile_m is None:
        tile_m = float(np.median(np.asarray(cKDTree(xy).query(xy, k=2)[0])[:, 1])) if len(xy) > 1 else 1.0
    grow = env.axis_reach_m + env.install_m
    origin = xy.min(axis=0) - tile_m * np.ceil(grow / tile_m)
    nx, ny = (np.ceil((xy.max(axis=0) + grow - origin) / tile_m).astype(int)).tolist()
    return origin, tile_m, nx, ny


def certify_windows(xyz: np.ndarray, radii: np.ndarray, camera: Camera, install_tolerance_m: float,
                    candidates: np.ndarray, *, tile_m: float | None = None, min_width: float = MIN_WIDTH,
                    budget: int = BOX_BUDGET, tiles: list[int] | None = None) -> Certificate:
    """The candidate triangles (T x 3 luminaire indices) that some pose of the envelope may still take as its
    window, luminaires displaced up to ``install_tolerance_m`` [m]; every other one is proved impossible.

    ``tile_m``: side of the square tiles of axis points [m] (default: the median distance between nearest
    luminaires, so a lattice's tiles are its cells). ``tiles``: certify only these tile numbers (row-major;
    a benchmark's sample), the others keep nothing. :class:`planner.verify.envelope.NotProvable` where the
    envelope does not apply.
    """
    start = time.perf_counter()
    env = envelope(camera, xyz, radii, install_tolerance_m)
    views = view_bounds(camera, env)
    xy = np.asarray(xyz, float)[:, :2]
    cand = np.sort(np.asarray(candidates, dtype=np.int64).reshape(-1, 3), axis=1)
    tree = cKDTree(xy)
    origin, tile_m, nx, ny = tile_grid(xy, env, tile_m)
    reach = env.axis_reach_m + env.install_m + tile_m / math.sqrt(2) + 0.01  # 1 cm: the ceiling distances widened by 1 mm
    cand_by_led: dict[int, list[int]] = {}
    for k, t in enumerate(cand.tolist()):
        cand_by_led.setdefault(t[0], []).append(k)
    cache: dict[bytes, TileResult] = {}
    kept: set[Triple] = set()
    results, boxes, fallback = [], 0, 0
    for number in range(nx * ny) if tiles is None else tiles:
        ix, iy = number % nx, number // nx
        x0, y0 = origin[0] + ix * tile_m, origin[1] + iy * tile_m
        centre = np.array([x0 + tile_m / 2, y0 + tile_m / 2])
        local = np.array(tree.query_ball_point(centre, reach), dtype=np.int64)
        if len(local) < 3:
            continue
        rel = np.round(xy[local] - centre, 9)
        order = np.lexsort((rel[:, 1], rel[:, 0]))
        local = local[order]
        where = {int(g): i for i, g in enumerate(local)}
        mine: set[Triple] = set()
        for i in local.tolist():
            for k in cand_by_led.get(i, []):
                if all(int(g) in where for g in cand[k]):
                    a, b, c = sorted(where[int(g)] for g in cand[k])
                    mine.add((a, b, c))
        if not mine:
            continue
        key = rel[order].tobytes() + np.asarray(radii, float)[local].tobytes() + np.array(sorted(mine)).tobytes()
        if key not in cache:
            tile = np.array([x0, x0 + tile_m, y0, y0 + tile_m])
            cache[key] = certify_tile(tile, xy[local], np.asarray(radii, float)[local], mine, env, views,
                                      min_width=min_width, budget=budget, seed=number)
            boxes += cache[key].boxes
            fallback += cache[key].fallback
        res = cache[key]
        results.append(res)
        for t in res.triples:
            a, b, c = sorted(int(local[i]) for i in t)
            kept.add((a, b, c))
    out = np.array(sorted(kept), dtype=np.int64).reshape(-1, 3)
    return Certificate(out, len(results), len(cache), fallback, boxes, time.perf_counter() - start, results)
