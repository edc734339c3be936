"""The window proof and the rival search cut into tiles: work that grows with the site's area, not its square.

A site is cut into square tiles of about :data:`TILE_LEDS` luminaires (a grid that depends only on
the luminaires' positions). A pair ``i < j`` or a triple ``i < j < k`` belongs to the tile of its
smallest index ``i``; its other members lie within the reach of ``i``. Every test the proof makes
(:mod:`planner.verify.proof`) asks a KD-tree for the LEDs nearest a point within that reach of
``i``, so a tile's job carries only its **halo**: the LEDs of the tiles within ``2 r + d_K`` of it
(``r`` the reach, ``d_K`` the largest distance from one of the tile's LEDs to its ``K``-th nearest,
``K`` the most neighbours any test asks for): the nearest LEDs of every point the job queries are
in the halo. Each job returns its own pairs or triples; they are merged in tile order and sorted
as the untiled proof orders them, so the result depends on the site alone, never on which
process, machine or order ran the jobs (:mod:`planner.parallel`).

Per tile, the proof's budgets (:data:`~planner.verify.proof.PAIR_BUDGET` pairs,
:data:`~planner.verify.proof.TRIANGLE_BUDGET` candidates) bound the memory of one job; a tile
over one keeps every candidate its cheap tests leave (the empty-triangle rule and flatness):
still a superset of its windows, so still proved, only looser. :class:`TiledWindows` lists those
tiles and plan.yaml says so.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from planner.parallel import InProcess, Runner
from planner.verify.envelope import Envelope
from planner.verify.exclusion import NEAR, pair_reach_m, pairs_kept, windows_kept
from planner.verify.rivals import counter_clockwise, longest_side, sides, triples_of_pairs
from planner.verify.window_set import NEIGHBOURS, empty_triangles, may_be_decoded
from planner.verify.windows import ball_pairs

TILE_LEDS = 64
"""Luminaires per tile, about: enough tiles to share a 512-luminaire site between workers, few enough
that a job's fixed cost (its KD-tree) stays small beside its work."""

K_NEAREST = NEIGHBOURS + 3
"""The most nearest LEDs any test of the proof asks for (:mod:`planner.verify.window_set`'s)."""


@dataclass(frozen=True)
class Tiling:
    """A grid of square tiles over the site: each luminaire's tile, and each tile's cell."""

    side_m: float
    cells: np.ndarray  # (T, 2) grid cell of each non-empty tile, row-major order
    members: list[np.ndarray]  # owned luminaires of each tile, ascending

    def halo(self, t: int, width_m: float) -> np.ndarray:
        """Luminaires (ascending) of every tile whose cell lies within ``width_m`` of tile ``t``'s cell."""
        m = math.ceil(width_m / self.side_m) if self.side_m > 0 else 0
        near = np.flatnonzero(np.abs(self.cells - self.cells[t]).max(axis=1) <= m)
        return np.sort(np.concatenate([self.members[u] for u in near]))

    def near_tiles(self, t: int, width_m: float) -> np.ndarray:
        m = math.ceil(width_m / self.side_m) if self.side_m > 0 else 0
        return np.flatnonzero(np.abs(self.cells - self.cells[t]).max(axis=1) <= m)


def tiling(xy: np.ndarray, leds_per_tile: int = TILE_LEDS) -> Tiling:
    """Square tiles of about ``leds_per_tile`` luminaires over the bounding box of ``xy`` (N, 2) [m]."""
    n = len(xy)
    lo, span = xy.min(axis=0), np.ptp(xy, axis=0)
    count = max(1, round(n / leds_per_tile))
    side = max(math.sqrt(float(span[0] * span[1]) / count), float(span.max()) / count, 1e-6)
    last = np.maximum(np.ceil(span / side).astype(np.int64) - 1, 0)  # points on the far edge join the last cell
    cell = np.minimum(np.floor((xy - lo) / side).astype(np.int64), last)
    ncol = int(cell[:, 0].max()) + 1
    key = cell[:, 1] * ncol + cell[:, 0]
    keys, inverse = np.unique(key, return_inverse=True)
    order = np.argsort(inverse, kind="stable")
    starts = np.searchsorted(inverse[order], np.arange(len(keys) + 1))
    members = [order[starts[t]:starts[t + 1]] for t in range(len(keys))]
    return Tiling(side, np.column_stack([keys % ncol, keys // ncol]), members)


@dataclass(frozen=True)
class _Shared:
    env: Envelope
    min_radius_m: float
    n_site: int
    budget: int
    pair_budget: int


@dataclass(frozen=True)
class _Job:
    """One tile: its halo's global indices (ascending), their positions and radii, which of them the tile owns,
    and (windows only) the proved pairs of the tiles around it."""

    halo: np.ndarray
    xyz: np.ndarray
    radii: np.ndarray
    owned: np.ndarray  # bool (len(halo),)
    pairs: np.ndarray | None = None


def _pair_job(shared: _Shared, job: _Job) -> tuple[np.ndarray, bool]:
    """The tile's proved pairs (global indices, ascending) and whether it was over the pair budget."""
    xy = job.xyz[:, :2]
    tree = cKDTree(xy)
    own = np.flatnonzero(job.owned)
    pairs = _pairs_from(tree, xy, own, pair_reach_m(shared.env))
    over = len(pairs) > shared.pair_budget
    if not over and shared.n_site >= 4 and len(pairs):
        pairs = pairs[pairs_kept(xy, job.radii, shared.env, tree, pairs, shared.min_radius_m)]
    return job.halo[pairs].reshape(-1, 2), over


def _window_job(shared: _Shared, job: _Job) -> tuple[np.ndarray, bool]:
    """The tile's proved triangles (global indices, ``i < j < k``) and whether it was over a budget."""
    assert job.pairs is not None
    xy = job.xyz[:, :2]
    local = _to_local(job.halo, job.pairs)
    first = job.owned[local[:, 0]]
    nbrs = np.zeros(len(xy), dtype=bool)
    nbrs[local[first, 1]] = True
    nbrs |= job.owned
    local = local[nbrs[local[:, 0]] & nbrs[local[:, 1]]]
    cand = triples_of_pairs(local, len(xy), first=job.owned)
    cand = cand[may_be_decoded(xy[cand])]
    cand = cand[empty_triangles(cand, job.xyz, job.radii, shared.env.install_m)]
    over = len(cand) > shared.budget
    if not over and shared.n_site > 3 and len(cand):
        cand = cand[windows_kept(xy, job.radii, shared.env, cKDTree(xy), cand)]
    return job.halo[cand].reshape(-1, 3), over


def _pairs_from(tree: cKDTree, xy: np.ndarray, rows: np.ndarray, reach_m: float) -> np.ndarray:
    """Pairs ``(i, j)``, ``i`` in ``rows``, ``j > i`` within ``reach_m`` of it (local indices, lexsorted)."""
    which, j = ball_pairs(tree, xy[rows], reach_m)
    i = rows[which]
    pairs = np.column_stack([i, j])[j > i]
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]


def _to_local(halo: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """``pairs`` (global) with both members in ``halo`` (ascending), in halo indices."""
    pos = np.searchsorted(halo, pairs)
    pos = np.minimum(pos, len(halo) - 1)
    inside = (halo[pos] == pairs).all(axis=1)
    return pos[inside]


@dataclass(frozen=True)
class TiledWindows:
    """The proved window set and how it was made: the tiles, and those over a budget (kept loose)."""

    triangles: np.ndarray
    tiles: int
    over_budget: tuple[int, ...]

    def summary(self) -> dict:
        return {"tiles": self.tiles, "tile_leds": TILE_LEDS, "tiles_over_budget": len(self.over_budget)}


def tiled_windows(xyz: np.ndarray, radii: np.ndarray, env: Envelope, runner: Runner | None,
                  budget: int, pair_budget: int) -> TiledWindows:
    """:func:`planner.verify.proof.possible_windows` tile by tile on ``runner``: the same triples for any runner."""
    runner = runner or InProcess()
    xy = xyz[:, :2]
    n = len(xy)
    if n < 3:
        return TiledWindows(np.empty((0, 3), dtype=np.int64), 0, ())
    tiles = tiling(xy)
    k = min(max(K_NEAREST, NEAR), n)
    d_k = np.asarray(cKDTree(xy).query(xy, k=k)[0]).reshape(n, k)[:, -1]
    r = pair_reach_m(env)
    widths = [2 * r + float(d_k[m].max()) for m in tiles.members]
    shared = _Shared(env, float(radii.min()), n, budget, pair_budget)

    def job(t: int, pairs: np.ndarray | None = None) -> _Job:
        h = tiles.halo(t, widths[t])
        owned = np.isin(h, tiles.members[t])
        return _Job(h, xyz[h], radii[h], owned, pairs)

    count = len(tiles.members)
    first = runner.map(_pair_job, shared, (job(t) for t in range(count)), "proof: pairs", count)
    tile_pairs = [p for p, _ in first]
    jobs = (job(t, np.concatenate([tile_pairs[u] for u in tiles.near_tiles(t, r)])) for t in range(count))
    second = runner.map(_window_job, shared, jobs, "proof: triangles", count)
    pairs = np.concatenate(tile_pairs)
    cand = np.concatenate([c for c, _ in second])
    degree = np.bincount(pairs[:, 0], minlength=n)  # the untiled proof's order: triples_of_pairs of all pairs
    cand = cand[np.lexsort((cand[:, 2], cand[:, 1], cand[:, 0], degree[cand[:, 0]]))]
    over = tuple(t for t in range(count) if first[t][1] or second[t][1])
    return TiledWindows(cand, count, over)


# --- rivals: the site's triples that can read like a proved window ---------------------------------


@dataclass(frozen=True)
class _Shapes:
    shapes: np.ndarray  # (S, 3) the windows' side lengths in every rotation, rounded to GRAIN_M
    max_side_m: float
    reach_m: float
    token: str  # the shapes' digest: a process that runs many tiles builds their KD-tree once

    def tree(self) -> cKDTree:
        """The shapes' KD-tree, built once per process however many tiles it runs (about 1 s a million shapes)."""
        if self.token not in _TREES:
            _TREES.clear()
            _TREES[self.token] = cKDTree(self.shapes)
        return _TREES[self.token]


_TREES: dict[str, cKDTree] = {}


GRAIN_M = 1e-7
"""Shapes this close are one (a lattice's windows have a few hundred shapes) [m]; as in
:func:`planner.verify.rivals.shape_matches`."""


def _shape_job(shared: _Shapes, job: _Job) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The tile's counter-clockwise triples within ``max_side_m`` that surely match a shape, those within a
    grain of the border (global indices) with their sides, and each sure triple's order key."""
    xy = job.xyz[:, :2]
    tree = cKDTree(xy)
    own = np.flatnonzero(job.owned)
    p1 = _pairs_from(tree, xy, own, shared.max_side_m)
    nbrs = np.zeros(len(xy), dtype=bool)
    nbrs[p1[:, 1]] = True
    p2 = _pairs_from(tree, xy, np.flatnonzero(nbrs), shared.max_side_m)
    p2 = p2[nbrs[p2[:, 1]]]
    degree = np.bincount(p1[:, 0], minlength=len(xy))
    site = triples_of_pairs(np.unique(np.vstack([p1, p2]), axis=0), len(xy), first=job.owned)
    key = degree[site[:, 0]] if len(site) else np.empty(0, dtype=np.int64)
    site = counter_clockwise(site, xy)
    lengths = sides(site, job.xyz)
    near, _ = shared.tree().query(lengths, k=1, p=np.inf, distance_upper_bound=shared.reach_m + GRAIN_M)
    keep = np.asarray(near <= shared.reach_m - GRAIN_M)
    unsure = np.isfinite(near) & ~keep
    return (job.halo[site[keep]].reshape(-1, 3), key[keep], job.halo[site[unsure]].reshape(-1, 3),
            key[unsure])


def tiled_shape_matches(windows: np.ndarray, xyz: np.ndarray, tolerance_m: float,
                        runner: Runner | None = None) -> np.ndarray:
    """:func:`planner.verify.rivals.shape_matches` tile by tile on ``runner``: the same triples in the same order."""
    runner = runner or InProcess()
    xy = xyz[:, :2]
    win = counter_clockwise(np.asarray(windows, dtype=np.int64).reshape(-1, 3), xy)
    if len(win) == 0:
        return win
    max_side = longest_side(win, xyz) + tolerance_m + 1e-9
    exact = np.vstack([sides(np.roll(win, -r, axis=1), xyz) for r in range(3)])
    shapes = np.unique(np.round(exact / GRAIN_M), axis=0) * GRAIN_M
    shared = _Shapes(shapes, max_side, tolerance_m + 1e-9, hashlib.sha1(shapes.tobytes()).hexdigest())
    tiles = tiling(xy)

    def job(t: int) -> _Job:
        h = tiles.halo(t, max_side)
        return _Job(h, xyz[h], np.zeros(len(h)), np.isin(h, tiles.members[t]))

    count = len(tiles.members)
    found = runner.map(_shape_job, shared, (job(t) for t in range(count)), "rivals", count)
    sure, sure_key = np.concatenate([f[0] for f in found]), np.concatenate([f[1] for f in found])
    unsure, unsure_key = np.concatenate([f[2] for f in found]), np.concatenate([f[3] for f in found])
    if len(unsure):  # within a grain of the border: ask the exact shapes
        exact_near, _ = cKDTree(exact).query(sides(unsure, xyz), k=1, p=np.inf, distance_upper_bound=shared.reach_m)
        ok = np.isfinite(exact_near)
        sure, sure_key = np.vstack([sure, unsure[ok]]), np.concatenate([sure_key, unsure_key[ok]])
    order = np.sort(sure, axis=1)  # site_triples' order: by the first member's degree, then i, j, k
    return sure[np.lexsort((order[:, 2], order[:, 1], order[:, 0], sure_key))]
