"""Labels against a proved window set on a lattice: congruence classes instead of pairs.

On an exact lattice every translate of a triangle has the same shape, so the pairs that
must differ (:mod:`planner.codes.pairwise`) number hundreds per window: 76 million on the
16 x 16 grid. They are cliques, though: the triples of one shape (within the tolerance)
must all carry different labels, read in corresponding order. So the triples that may
read like a window are grouped by shape, exactly congruent ones into a class and classes
within the tolerance of each other into one group (a safe over-approximation: a group
asks more than the pairs do), each triple turned to its group's vertex order. Labels are
valid for the groups when no two triples of a group, one of them a window, have equal
labels in order; a dense table per group counts the labels in use, so a luminaire's cost
is a lookup per triple that holds it. A class that matches itself turned (a near-equilateral
shape) or whose group order disagrees with a direct match (a chain of near shapes) is entered
in all three turns, so every match within the tolerance is a conflict of equal keys; the price
is that such a window may not carry one label thrice. The verdict is still
:func:`planner.verify.rivals.find_rivals` against the proved set: the groups guide the search.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from planner.verify.rivals import counter_clockwise, shape_matches, sides

LINK_BUDGET = 20_000_000
"""Most (class, class within the tolerance) links joined into groups: an irregular site whose pairs are
over :data:`planner.codes.alike.PAIR_BUDGET` has one class per triple, each near thousands (the
hexagonal site of issue 34 at 0 cm: memory ran out past 17 GB), so it gets no groups."""
TABLE_BUDGET = 64_000_000
"""Most (group, label triple) counters kept in two int16 tables (4 bytes per counter; half as many in int32)."""
SHAPE_RESOLUTION_M = 1e-6
"""Side lengths equal to this are one exact shape [m] (lattice coordinates carry float noise)."""


@dataclass(frozen=True)
class Groups:
    """The triples that may read like a window, grouped by shape.

    ``triples`` (M x 3) turned to their group's vertex order, ``group`` (M,) the group of
    each, ``window`` (M,) whether it is a window (else only a triple it must not read like).
    """

    triples: np.ndarray
    group: np.ndarray
    window: np.ndarray

    @property
    def count(self) -> int:
        return int(self.group.max()) + 1 if len(self.group) else 0


def _distinct_ccw(windows: np.ndarray, xyz: np.ndarray) -> np.ndarray:
    """The distinct triples of ``windows``, each counter-clockwise."""
    return counter_clockwise(np.unique(np.sort(np.asarray(windows, np.int64).reshape(-1, 3), axis=1), axis=0),
                             xyz[:, :2])


def _turn_ranks(triples: np.ndarray, xyz: np.ndarray,
                resolution_m: float = SHAPE_RESOLUTION_M) -> tuple[np.ndarray, np.ndarray]:
    """The distinct side vectors of every turn of ``triples`` (rounded to ``resolution_m``) and
    each triple's three turns as ranks among them (T x 3): equal ranks are one shape (to that resolution)."""
    rounded = np.round(np.stack([sides(np.roll(triples, -r, axis=1), xyz) for r in range(3)], 1)
                       / resolution_m).astype(np.int64)
    vectors, rank = np.unique(rounded.reshape(-1, 3), axis=0, return_inverse=True)
    return vectors, rank.reshape(-1, 3)


def shape_groups(windows: np.ndarray, xyz: np.ndarray, tolerance_m: float,
                 matches: np.ndarray | None = None, resolution_m: float = SHAPE_RESOLUTION_M) -> Groups | None:
    """Group the windows and every triple of the site within the tolerance of one of them (``matches``,
    if already found: :func:`planner.verify.rivals.shape_matches` of these windows); None when joining
    the classes would take more than :data:`LINK_BUDGET` links.

    A class is the triples whose sides round alike to ``resolution_m``: exact shapes by default (a
    lattice), cells as wide as the tolerance on irregular sites, where no two
    triples are exactly congruent and classes of one triple each would be near thousands of others."""
    win = _distinct_ccw(windows, xyz)
    reach = tolerance_m + resolution_m + SHAPE_RESOLUTION_M
    vectors, rank = _turn_ranks(win, xyz, resolution_m)
    if _links(vectors[np.unique(rank.min(axis=1))] * resolution_m, reach, 1) > LINK_BUDGET:
        return None  # the windows' classes alone are over: so are theirs with the matches' (an irregular site)
    everything = np.vstack([win, shape_matches(win, xyz, tolerance_m) if matches is None else matches])
    key = np.sort(everything, axis=1)
    _, first = np.unique(key, axis=0, return_index=True)  # windows come first, so they keep their flag
    triples = everything[np.sort(first)]
    is_window = np.sort(first) < len(win)
    vectors, rank = _turn_ranks(triples, xyz, resolution_m)  # classes: the turn whose rounded sides rank lowest
    turn = np.argmin(rank, axis=1)
    cls = rank[np.arange(len(rank)), turn]
    used, cls = np.unique(cls, return_inverse=True)
    shape = vectors[used] * resolution_m  # (C, 3) each class's sides in its order
    # rounding moves a side by at most half the resolution: classes within the tolerance plus one
    # resolution hold every pair of triples within the tolerance
    merged = _merge(shape, reach)
    if merged is None:
        return None
    group, turn_by, spin = merged
    total = (turn + turn_by[cls]) % 3
    turned = np.flatnonzero(spin[cls])  # entered again in the two other turns
    rows = np.concatenate([np.arange(len(triples)), turned, turned])
    total = np.concatenate([total, total[turned] + 1, total[turned] + 2]) % 3
    idx = (np.arange(3)[None, :] + total[:, None]) % 3
    return Groups(np.take_along_axis(triples[rows], idx, axis=1), group[cls][rows], is_window[rows])


def clique_lower_bound(windows: np.ndarray, xyz: np.ndarray) -> int:
    """Fewest labels any valid labelling needs, by counting: windows of one exact shape (sides equal
    to :data:`SHAPE_RESOLUTION_M`, read counter-clockwise) all read like each other under equal labels,
    so each needs its own label triple: ``K^3`` (``(K^3 + 2K)/3`` for a shape with threefold symmetry)
    must reach the largest such class (:func:`planner.codes.window.lower_bound_labels`)."""
    from planner.codes.window import lower_bound_labels

    win = _distinct_ccw(windows, xyz)
    if len(win) == 0:
        return 1
    _, rank = _turn_ranks(win, xyz)
    used, shape = np.unique(rank.min(axis=1), return_inverse=True)
    symmetric = np.zeros(len(used), dtype=bool)
    symmetric[shape] = (rank == rank[:, :1]).all(axis=1)
    return lower_bound_labels(shape, symmetric)


def near_lower_bound(windows: np.ndarray, xyz: np.ndarray, tolerance_m: float) -> int:
    """Fewest labels any valid labelling needs, by counting windows of *nearly* one shape: windows whose
    sides (counter-clockwise, in some rotation) fall in one cube of side ``tolerance_m`` differ by less
    than the tolerance side by side, so they all read alike under equal labels and each needs its own
    label triple: ``K^3`` must reach the most distinct windows in one cube (cubes on two grids, the second
    shifted half a side). On irregular sites no two windows are exactly congruent and
    :func:`clique_lower_bound` says 1; this one still counts."""
    win = _distinct_ccw(windows, xyz)
    if len(win) == 0 or tolerance_m <= 0:
        return 1
    turns = np.concatenate([sides(np.roll(win, -r, axis=1), xyz) for r in range(3)]) / tolerance_m
    ids = np.tile(np.arange(len(win)), 3)
    most = 1
    for shift in (0.0, 0.5):
        cells = np.floor(turns + shift).astype(np.int64)
        rows = np.unique(np.column_stack([cells, ids]), axis=0)  # a window once per cube
        most = max(most, int(np.unique(rows[:, :3], axis=0, return_counts=True)[1].max()))
    k = 1
    while k ** 3 < most:
        k += 1
    return k


def _links(shape: np.ndarray, reach_m: float, step: int, tree: cKDTree | None = None) -> int:
    """Links between classes of ``shape`` (C, 3) within ``reach_m`` in some rotation, each one's own too:
    counted from every ``step``-th class and scaled (exact for 1)."""
    tree = cKDTree(shape) if tree is None else tree
    return step * sum(int(tree.query_ball_point(np.roll(shape[::step], -r, axis=1), reach_m, p=np.inf,
                                                return_length=True).sum()) for r in range(3))


def _merge(shape: np.ndarray, reach_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Join classes whose shapes lie within ``reach_m`` in some rotation; returns each class's
    group, the further turn that brings it into its group's order (first found wins), and
    whether it must be entered in every turn (a match the group order does not cover); None when
    that would take more than :data:`LINK_BUDGET` links."""
    c = len(shape)
    tree = cKDTree(shape)
    links: list[list[tuple[int, int]]] = [[] for _ in range(c)]
    spin = np.zeros(c, dtype=bool)
    every = max(1, c // 2000)  # links estimated from every so many classes first: counting them all is slow
    for step in sorted({every, 1}, reverse=True):
        if _links(shape, reach_m, step, tree) > LINK_BUDGET:
            return None
    for r in range(3):
        for u, hits in enumerate(tree.query_ball_point(np.roll(shape, -r, axis=1), reach_m, p=np.inf)):
            for v in hits:
                if v != u:  # roll(shape_u, -r) is near shape_v: u turned by r reads in v's order
                    links[u].append((v, (3 - r) % 3))
                    links[v].append((u, r))
                elif r:
                    spin[u] = True
    group = np.full(c, -1, dtype=np.int64)
    turn = np.zeros(c, dtype=np.int64)
    g = 0
    for root in range(c):
        if group[root] >= 0:
            continue
        group[root] = g
        todo = deque([root])
        while todo:
            u = todo.popleft()
            for v, r in links[u]:
                if group[v] < 0:
                    group[v], turn[v] = g, (turn[u] + r) % 3
                    todo.append(v)
        g += 1
    for u in range(c):
        for v, r in links[u]:
            if turn[v] != (turn[u] + r) % 3:
                spin[u] = spin[v] = True
    return group, turn, spin


class ClassIndex:
    """Conflicts between the triples of each group under labels 0..K-1 (the protocol of
    :func:`planner.codes.pairwise.search`; a unit is a triple of :class:`Groups`).

    Two triples of a group conflict when their labels agree in order and one is a window.
    """

    def __init__(self, n: int, groups: Groups, K: int):
        self.n, self.K, self.g = n, K, groups
        self.T = groups.triples
        self.win = groups.window.astype(np.int64)
        self.base = groups.group * K ** 3
        m = np.repeat(np.arange(len(self.T)), 3)
        pos = np.tile(np.arange(3), len(self.T))
        lum = self.T.reshape(-1)
        order = np.argsort(lum, kind="stable")
        self.m, self.pw = m[order], K ** (2 - pos[order])
        self.start = np.searchsorted(lum[order], np.arange(n + 1))
        size = groups.count * K ** 3
        counter = ClassIndex.counter(groups)
        self.cw: np.ndarray = np.zeros(size, dtype=counter)
        self.cs: np.ndarray = np.zeros(size, dtype=counter)
        self._moving: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self.by_group = np.argsort(groups.group, kind="stable")
        self.group_start = np.searchsorted(groups.group[self.by_group], np.arange(groups.count + 1))

    @staticmethod
    def counter(groups: Groups) -> type:
        """The tables' counter: int16, or int32 where a group holds too many triples for it (a 100,000-luminaire
        lattice: one shape per luminaire and turn)."""
        biggest = np.bincount(groups.group).max() if len(groups.group) else 0
        return np.int16 if biggest < 2 ** 15 else np.int32

    @staticmethod
    def fits(groups: Groups, K: int) -> bool:
        """Whether the tables for ``K`` labels are within :data:`TABLE_BUDGET` (counted in int16 counters)."""
        return groups.count * K ** 3 * np.dtype(ClassIndex.counter(groups)).itemsize <= 2 * TABLE_BUDGET

    def _keys(self, lab: np.ndarray, rows: np.ndarray | slice = slice(None)) -> np.ndarray:
        t = lab[self.T[rows]]
        return self.base[rows] + (t[:, 0] * self.K + t[:, 1]) * self.K + t[:, 2]

    def begin(self, lab: np.ndarray) -> tuple[int, list[int]]:
        keys = self._keys(lab)
        self.cw[:] = 0
        self.cs[:] = 0
        np.add.at(self.cw, keys[self.win == 1], 1)
        np.add.at(self.cs, keys[self.win == 0], 1)
        w, s = self.cw.astype(np.int64), self.cs.astype(np.int64)
        total = int((w * (w - 1) // 2 + w * s).sum())
        bad = np.flatnonzero(self._partners(keys, self.win) > 0)
        return total, bad.tolist()

    def _partners(self, keys: np.ndarray, win: np.ndarray) -> np.ndarray:
        """Triples each (with its own current key) conflicts with."""
        w, s = self.cw[keys].astype(np.int64), self.cs[keys].astype(np.int64)
        return np.where(win == 1, w - 1 + s, w)

    def holders(self, unit: int, lab: np.ndarray) -> np.ndarray:
        """The unit's luminaires and those of the triples of its group it reads like."""
        rows = self.by_group[self.group_start[self.g.group[unit]]:self.group_start[self.g.group[unit] + 1]]
        keys = self._keys(lab, rows)
        alike = rows[keys == self._keys(lab, np.array([unit]))[0]]
        return np.unique(self.T[alike])

    def in_conflict(self, unit: int, lab: np.ndarray) -> bool:
        return bool(self._partners(self._keys(lab, np.array([unit])), self.win[[unit]])[0] > 0)

    def alike_rows(self, lab: np.ndarray) -> np.ndarray:
        """Every pair of triples the labels leave alike, one a window, as (P, 6) luminaire rows ``a0 a1 a2 b0 b1
        b2`` in the order the labels are read (the rows :class:`planner.codes.pairwise.Index` takes): the
        conflicts :meth:`begin` counts, listed."""
        keys = self._keys(lab)
        order = np.argsort(keys, kind="stable")
        k = keys[order]
        start = np.flatnonzero(np.r_[True, k[1:] != k[:-1]])
        size = np.diff(np.r_[start, len(k)])
        out = []
        for s, m in zip(start[size > 1].tolist(), size[size > 1].tolist()):
            rows = order[s:s + m]
            a, b = np.triu_indices(m, 1)
            keep = (self.win[rows[a]] | self.win[rows[b]]) == 1
            out.append(np.hstack([self.T[rows[a[keep]]], self.T[rows[b[keep]]]]))
        return np.vstack(out).astype(np.int64) if out else np.empty((0, 6), np.int64)

    def _pairs(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Pairs (local indices into ``i``'s rows) of triples holding ``i`` in one group, one of
        them a window: they move together when ``i`` does (cached)."""
        if i not in self._moving:
            s, e = self.start[i], self.start[i + 1]
            rows = self.m[s:e]
            order = np.argsort(self.g.group[rows], kind="stable")
            grp = self.g.group[rows][order]
            end = np.searchsorted(grp, grp, side="right")  # each one's block end, in group order
            later = end - np.arange(len(grp)) - 1  # partners after it in its block
            a = np.repeat(np.arange(len(grp)), later)
            b = a + 1 + np.arange(len(a)) - np.repeat(np.cumsum(later) - later, later)
            a, b = order[a], order[b]
            keep = (self.win[rows[a]] | self.win[rows[b]]) == 1
            self._moving[i] = (a[keep], b[keep])
        return self._moving[i]

    def cost(self, i: int, lab: np.ndarray, K: int) -> np.ndarray:
        """Conflicts among the triples holding ``i``, for each label 0..K-1 of ``i`` (K,)."""
        s, e = self.start[i], self.start[i + 1]
        rows, pw = self.m[s:e], self.pw[s:e]
        win = self.win[rows] == 1
        cur = self._keys(lab, rows)
        new = (cur - lab[i] * pw)[:, None] + np.arange(K)[None, :] * pw[:, None]  # (h, K)
        tables = ((self.cw, cur[win]), (self.cs, cur[~win]))
        for table, mine in tables:  # the other triples only: take the moving ones out for the look-up
            np.subtract.at(table, mine, 1)
        w, st = self.cw[new], self.cs[new]
        for table, mine in tables:
            np.add.at(table, mine, 1)
        out = w.sum(axis=0, dtype=np.int64) + st[win].sum(axis=0, dtype=np.int64)
        a, b = self._pairs(i)  # and the moving triples that agree with each other under the new label
        return out + (new[a] == new[b]).sum(axis=0)

    def moved(self, i: int, old: int, lab: np.ndarray) -> list[int]:
        s, e = self.start[i], self.start[i + 1]
        rows, pw = self.m[s:e], self.pw[s:e]
        win = self.win[rows]
        new = self._keys(lab, rows)
        was = new + (old - lab[i]) * pw
        for table, mine in ((self.cw, win == 1), (self.cs, win == 0)):
            np.subtract.at(table, was[mine], 1)
            np.add.at(table, new[mine], 1)
        return rows[self._partners(new, win) > 0].tolist()
