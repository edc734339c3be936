"""Labels against a complete window set: the min-conflicts search, and an index of listed pairs.

Where the window set is proved complete (:mod:`planner.verify.proof`), the IDs need not
be searched by shape cells (:mod:`planner.codes.window`, a safe over-approximation that
calls triples up to two tolerances apart alike): the pairs that must differ are exact. A
pair is a window and another triple of the site (a window or not) whose sides,
counter-clockwise in one rotation, each differ by at most the tolerance; the labels are
valid when no pair has equal labels in all three corresponding places, which is exactly
the verdict of :func:`planner.verify.rivals.find_rivals`. The pairs are held by
:mod:`planner.codes.readings` (or groups, :mod:`planner.codes.classes`); :class:`Index`
holds listed ones (the pairs left alike by shorter labels, :func:`planner.codes.proved.split_labels`).
Labels are found by min-conflicts search with a tabu list; budgets are steps, so the
result depends on the seed only.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from numba import njit

NOISE = 0.05
"""Share of steps that move a random luminaire of the chosen conflict (to its best other label)."""
TABU_STEPS = 10
"""Steps for which a luminaire may not return to the label it just left."""
STALL_STEPS = 300
"""Moves without a new fewest count of conflicts after which a search gives up."""


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
