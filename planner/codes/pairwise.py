"""Labels against a complete window set, pair by pair.

Where the window set is proved complete (:mod:`planner.verify.proof`), the IDs need not
be searched by shape cells (:mod:`planner.codes.window`, a safe over-approximation that
calls triples up to two tolerances apart alike): the pairs that must differ can be listed
exactly. A pair is a window and another triple of the site (a window or not) whose sides,
counter-clockwise in one rotation, each differ by at most the tolerance; the labels are
valid when no pair has equal labels in all three corresponding places, which is exactly
the verdict of :func:`planner.verify.rivals.find_rivals`. Labels are found by min-conflicts
search with a tabu list; budgets are steps, so the result depends on the seed only.
"""

from __future__ import annotations

from itertools import chain
from typing import Protocol

import numpy as np
from numba import njit
from scipy.spatial import cKDTree

from planner.verify.rivals import counter_clockwise, longest_side, sides, triples_of_pairs

NOISE = 0.05
"""Share of steps that move a random luminaire of the chosen conflict (to its best other label)."""
TABU_STEPS = 10
"""Steps for which a luminaire may not return to the label it just left."""
STALL_STEPS = 300
"""Moves without a new fewest count of conflicts after which a search gives up."""
ALIKE_BUDGET = 12_000_000
"""Most (window, triple, rotation) shape matches listed (about 100 bytes each while listing)."""
SITE_BUDGET = 36_000_000
"""Most triples of the site short enough to match a window (counted from above before they are made) that
the listing holds with their sides and KD-tree (about 100 bytes each); beyond it, as beyond
:data:`ALIKE_BUDGET`, the pairs are not listed (a 10,000-luminaire irregular site holds 114 million)."""
_CHUNK = 20_000
"""Windows whose matches are listed at once."""


def _canonical(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """One row (a0 a1 a2 b0 b1 b2) per pair, the same for every rotation and either order."""
    return _canonical_rows(np.ascontiguousarray(a, dtype=np.int64), np.ascontiguousarray(b, dtype=np.int64))


@njit(cache=True)
def _canonical_rows(a, b):
    """:func:`_canonical`: each pair turned so that its first triple starts at that triple's smallest luminaire,
    in the order (``a`` first or ``b`` first) whose row is lexicographically smaller."""
    out = np.empty((len(a), 6), dtype=np.int64)
    one = np.empty(6, dtype=np.int64)
    two = np.empty(6, dtype=np.int64)
    for p in range(len(a)):
        ra, rb = np.argmin(a[p]), np.argmin(b[p])
        for c in range(3):
            one[c], one[3 + c] = a[p, (c + ra) % 3], b[p, (c + ra) % 3]
            two[c], two[3 + c] = b[p, (c + rb) % 3], a[p, (c + rb) % 3]
        swap = False
        for c in range(6):
            if two[c] != one[c]:
                swap = two[c] < one[c]
                break
        out[p] = two if swap else one
    return out


def alike_pairs(windows: np.ndarray, xyz: np.ndarray, tolerance_m: float, site: np.ndarray | None = None,
                budget: int = ALIKE_BUDGET) -> np.ndarray | None:
    """Every pair (window, other triple) that reads alike whenever the labels agree.

    ``windows`` (M x 3 luminaire indices), ``xyz`` (N x 3 [m]), ``tolerance_m`` the largest
    side difference the receiver cannot tell apart [m]; ``site`` the triples a window must
    not read like (default: every triple short enough). Returns (P x 6) int64 rows
    ``a0 a1 a2 b0 b1 b2``: ``a`` reads like ``b`` when label ``a_j`` equals label ``b_j`` for
    every ``j``. Each pair appears once, whatever its rotation or order. None when more than
    ``budget`` (window, triple, rotation) matches are found, or the site has more than
    :data:`SITE_BUDGET` triples to match.
    """
    windows = np.unique(np.sort(np.asarray(windows, dtype=np.int64).reshape(-1, 3), axis=1), axis=0)
    if len(windows) == 0:
        return np.empty((0, 6), dtype=np.int64)
    if site is None:
        near = cKDTree(xyz[:, :2]).query_pairs(longest_side(windows, xyz) + tolerance_m + 1e-9, output_type="ndarray")
        deg = np.bincount(near.min(axis=1), minlength=len(xyz)) if len(near) else np.zeros(1, np.int64)
        if int((deg * (deg - 1) // 2).sum()) > SITE_BUDGET:  # at least as many as the site's triples
            return None
        site = triples_of_pairs(near, len(xyz))
    win = counter_clockwise(windows, xyz[:, :2])
    other = counter_clockwise(np.asarray(site, dtype=np.int64).reshape(-1, 3), xyz[:, :2])
    tree = cKDTree(sides(other, xyz))
    every = max(1, len(win) // 2000)  # estimated from every so many windows first: listing them is slow
    if every > 1 and every * sum(int(tree.query_ball_point(sides(np.roll(win[::every], -r, axis=1), xyz),
                                                           tolerance_m + 1e-9, p=np.inf, return_length=True).sum())
                                 for r in range(3)) > 2 * budget:
        return None
    parts, found = [], 0
    for r in range(3):
        for start in range(0, len(win), _CHUNK):
            w = np.roll(win[start:start + _CHUNK], -r, axis=1)
            hits = tree.query_ball_point(sides(w, xyz), tolerance_m + 1e-9, p=np.inf, return_sorted=False)
            n = np.fromiter(map(len, hits), np.int64, len(hits))
            found += int(n.sum())
            if found > budget:
                return None
            u = other[np.fromiter(chain.from_iterable(hits), np.int64, int(n.sum()))]
            a = np.repeat(w, n, axis=0)
            differ = (np.sort(a, axis=1) != np.sort(u, axis=1)).any(axis=1)
            parts.append(_unique_rows(_canonical(a[differ], u[differ]), len(xyz)))
    return _unique_rows(np.concatenate(parts), len(xyz))


def _unique_rows(rows: np.ndarray, n: int) -> np.ndarray:
    """``np.unique(rows, axis=0)`` for rows of six indices below ``n``; one int64 key each when they fit."""
    if n ** 6 >= 2 ** 63:
        return np.unique(rows, axis=0)
    key = np.zeros(len(rows), dtype=np.int64)
    for c in range(6):
        key = key * n + rows[:, c]
    key = distinct(key)
    out = np.empty((len(key), 6), dtype=np.int64)
    for c in range(5, -1, -1):
        key, out[:, c] = np.divmod(key, n)
    return out


def distinct(values: np.ndarray) -> np.ndarray:
    """``np.unique(values)`` of a 1-D array by sorting: numpy 2.4's hash-based ``unique`` of int64 is 10-80 times
    slower (measured 2026-12-05: 25 million keys in 33 s, sorted in 0.4 s)."""
    v = np.sort(np.asarray(values).reshape(-1))
    return v[np.concatenate([[True], v[1:] != v[:-1]])] if len(v) else v


@njit(cache=True)
def stable_order(keys, n):
    """``np.argsort(keys, kind="stable")`` for keys in ``0..n-1``, by counting (linear, not ``n log n``)."""
    at = np.zeros(n + 1, dtype=np.int64)
    for k in keys:
        at[k + 1] += 1
    at = np.cumsum(at)
    order = np.empty(len(keys), dtype=np.int64)
    for i in range(len(keys)):
        order[at[keys[i]]] = i
        at[keys[i]] += 1
    return order


def conflicts(pairs: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Rows of ``pairs`` whose two triples have equal labels in all three places."""
    lab = np.asarray(labels, dtype=np.int64)
    return np.flatnonzero((lab[pairs[:, :3]] == lab[pairs[:, 3:]]).all(axis=1))


class Index:
    """Where each luminaire sits in the pairs (built once, for any number of labels), and the
    cost of each label for one luminaire.

    For a luminaire in one place of a pair, the pair conflicts after a move exactly when its
    other two places agree and the new label is the partner's: so each such entry keeps the
    four luminaires of the other places and the partner (int32). Pairs that hold a luminaire
    in two places that do not face each other are scored in full.
    """

    def __init__(self, n: int, pairs: np.ndarray):
        pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 6)
        small = np.int32 if n < 2 ** 31 and len(pairs) < 2 ** 31 // 6 else np.int64  # half the memory: millions of pairs
        p = pairs.astype(small)
        self.n, self.P = n, p
        srt = np.sort(p, axis=1)
        facing = (p[:, :3] == p[:, 3:]).sum(axis=1)
        full = (srt[:, 1:] == srt[:, :-1]).sum(axis=1) > facing
        del srt
        m = np.repeat(np.arange(len(p), dtype=small), 6)
        col = np.tile(np.arange(6, dtype=np.int8), len(p))
        lum = p.reshape(-1)
        partner = p[m, (col + 3) % 6]
        keep = (lum != partner) & ~full[m]  # a luminaire facing itself agrees whatever its label
        m, col, lum, partner = m[keep], col[keep], lum[keep], partner[keep]
        del keep
        order = stable_order(lum, n)
        m, col, partner, lum = m[order], col[order], partner[order], lum[order]
        del order
        j1, j2 = (col + 1) % 3, (col + 2) % 3
        self.other = np.empty((len(m), 4), dtype=np.int32)
        for k, (c, off) in enumerate(((j1, 0), (j1, 3), (j2, 0), (j2, 3))):
            self.other[:, k] = p[m, c + off]
        self.partner = partner.astype(np.int32)
        self.row = m
        self.start = np.searchsorted(lum, np.arange(n + 1))
        fm = np.flatnonzero(full)
        held = np.unique(np.column_stack([p[fm].reshape(-1).astype(np.int64), np.repeat(fm, 6)]), axis=0)
        self.full_row = held[:, 1]
        self.full_start = np.searchsorted(held[:, 0], np.arange(n + 1))

    def cost(self, i: int, lab: np.ndarray, K: int) -> np.ndarray:
        """Pairs in conflict among those holding luminaire ``i``, for each label 0..K-1 of ``i`` (K,)."""
        s, e = self.start[i], self.start[i + 1]
        o = lab[self.other[s:e]]
        ready = (o[:, 0] == o[:, 1]) & (o[:, 2] == o[:, 3])  # the other two places agree: i's label decides
        out = np.bincount(lab[self.partner[s:e][ready]], minlength=K)[:K]
        full = self.full_row[self.full_start[i]:self.full_start[i + 1]]
        if len(full):
            trial = np.repeat(lab[self.P[full]][:, None, :], K, axis=1)  # (F, K, 6)
            mine = np.broadcast_to((self.P[full] == i)[:, None, :], trial.shape)
            trial[mine] = np.broadcast_to(np.arange(K)[None, :, None], trial.shape)[mine]
            out = out + (trial[..., :3] == trial[..., 3:]).all(axis=2).sum(axis=0)
        return out

    def rows_of(self, i: int) -> np.ndarray:
        """Every pair holding luminaire ``i`` (some more than once)."""
        return np.concatenate([self.row[self.start[i]:self.start[i + 1]],
                               self.full_row[self.full_start[i]:self.full_start[i + 1]]])

    # The protocol that :func:`search` uses (a unit is a pair).

    def begin(self, lab: np.ndarray) -> tuple[int, list[int]]:
        """The number of conflicts under ``lab`` and the units in conflict."""
        bad = conflicts(self.P, lab)
        return len(bad), bad.tolist()

    def holders(self, unit: int, lab: np.ndarray) -> np.ndarray:
        return np.unique(self.P[unit])

    def in_conflict(self, unit: int, lab: np.ndarray) -> bool:
        return bool((lab[self.P[unit, :3]] == lab[self.P[unit, 3:]]).all())

    def moved(self, i: int, old: int, lab: np.ndarray) -> list[int]:
        """Luminaire ``i`` left label ``old`` for ``lab[i]``: the units holding it now in conflict."""
        rows = distinct(self.rows_of(i))
        return rows[(lab[self.P[rows, :3]] == lab[self.P[rows, 3:]]).all(axis=1)].tolist()


class ConflictIndex(Protocol):
    """What :func:`search` needs of an index: conflicts are counted between *units* (a pair of
    triples here; a congruence class's members in :mod:`planner.codes.classes`)."""

    n: int

    def begin(self, lab: np.ndarray) -> tuple[int, list[int]]: ...
    def cost(self, i: int, lab: np.ndarray, K: int) -> np.ndarray: ...
    def holders(self, unit: int, lab: np.ndarray) -> np.ndarray:
        """The luminaires whose move can end the unit's conflicts."""
    def in_conflict(self, unit: int, lab: np.ndarray) -> bool: ...
    def moved(self, i: int, old: int, lab: np.ndarray) -> list[int]: ...


def search(index: ConflictIndex, K: int, *, seed: int = 0, max_steps: int = 20_000,
           stall_steps: int = STALL_STEPS) -> tuple[np.ndarray | None, int]:
    """Labels 0..K-1 of the ``index.n`` luminaires with no conflict in the index (or None),
    and the steps taken: :func:`search_from` seeded random labels."""
    rng = np.random.default_rng([seed, K])
    lab = rng.integers(0, K, index.n).astype(np.int64)
    left, steps = search_from(index, K, lab, rng=rng, max_steps=max_steps, stall_steps=stall_steps)
    return (lab if left == 0 else None), steps


def search_from(index: ConflictIndex, K: int, lab: np.ndarray, *, rng: np.random.Generator, max_steps: int = 20_000,
                stall_steps: int = STALL_STEPS) -> tuple[int, int]:
    """Min-conflicts from ``lab`` (labels 0..K-1, changed in place to the best labels seen):
    returns the conflicts left under them and the steps taken.

    Take a unit in conflict, move the one of its luminaires whose best other
    label removes most conflicts (ties and, with probability ``NOISE``, the luminaire at
    random), never back to a label left within ``TABU_STEPS`` steps. At most ``max_steps``
    moves, and none once ``stall_steps`` moves have not lowered the fewest conflicts seen.
    ``index.cost`` differences are exact, so the count of conflicts is kept by them.
    """
    total, pool = index.begin(lab)  # the pool: every unit in conflict, and some no longer (dropped when drawn)
    if total == 0 or K < 2:
        return total, 0
    tabu: dict[tuple[int, int], int] = {}
    fewest, since, best = total, 0, lab.copy()
    step = 0
    for step in range(max_steps):
        if total == 0:
            return 0, step
        if total < fewest:
            fewest, since, best = total, step, lab.copy()
        elif step - since > stall_steps:
            break
        while True:  # a unit in conflict, uniformly: draw from the pool, dropping stale entries
            at = int(rng.integers(len(pool)))
            unit = pool[at]
            if index.in_conflict(unit, lab):
                break
            pool[at] = pool[-1]
            pool.pop()
        cands = index.holders(unit, lab)
        if rng.random() < NOISE:
            cands = cands[[int(rng.integers(len(cands)))]]
        choice: tuple[float, int, int] | None = None
        for i in cands.tolist():
            c = index.cost(i, lab, K).astype(float)
            c = c - c[lab[i]]
            c[lab[i]] = np.inf
            for k, until in ((k, u) for (v, k), u in tabu.items() if v == i):
                if until > step:
                    c[k] = np.inf
            k = int(np.argmin(c + rng.random(K) * 1e-3))
            if choice is None or c[k] < choice[0]:
                choice = (c[k], i, k)
        assert choice is not None
        delta, i, k = choice
        if not np.isfinite(delta):
            continue
        old = int(lab[i])
        tabu[(i, old)] = step + TABU_STEPS
        lab[i] = k
        total += int(round(delta))
        pool.extend(index.moved(i, old, lab))
        if len(tabu) > 4 * TABU_STEPS:
            tabu = {key: u for key, u in tabu.items() if u > step}
    else:
        step = max_steps
    if total == 0:
        return 0, step
    lab[:] = best
    index.begin(lab)  # the index's live counts follow the labels
    return fewest, step
