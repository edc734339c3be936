"""Pair codes: short labels such that every two-LED window of a site names one place.

The gravity-aided receiver (:mod:`planner.verify.pair_windows`) reads a window as its
distance and the unordered pair of labels ``{L[a], L[b]}``. Labels are valid when every
window's two labels differ and no other pair of the site that reads alike carries the same
two. Pairs read alike when their lengths agree within the tolerance; lengths are grouped into
**classes** by single linkage (sorted lengths split where neighbours differ by more than the
tolerance), which never splits two alike pairs, so a code valid per class is valid (exactly so
on lattices, whose lengths are exact). Pairs of different classes reuse labels freely: this is
where the pair's distance helps. The paper's pair rule (section 2.2) is the special case with
one class of neighbouring pairs and labels split by parity.

Labels are found by the min-conflicts search of :mod:`planner.codes.pairwise` on the index
:class:`PairIndex` (budgets are steps) and, where it gives up, by CP-SAT
(:mod:`planner.codes.pair_cpsat`, deterministic time), from the larger of the counting and the
clique bound upwards.
"""

from __future__ import annotations

import math

import numpy as np

from planner.codes import pairwise
from planner.codes.assignment import Assignment, bits_for, tile_regions
from planner.codes.pair_cpsat import cpsat_pair_labels, window_clique
from planner.graph import NeighbourGraph
from planner.verify.pair_windows import pair_lengths, site_pairs

DENSE_KEYS = 1 << 24
"""Widths whose ``classes x K^2`` keys exceed this are not searched (the counts are dense arrays)."""

STEPS_PER_LUMINAIRE = 40
"""Moves a width's search may make, per luminaire (it also stops when it stalls)."""

STALL_STEPS = 3000
"""Moves without a new fewest count of conflicts after which a width is given up."""

CPSAT_MAX_ROWS = 3000
"""Sites with more pairs in the index than this get no CP-SAT (as the three-LED window code's ``cpsat_max_windows``)."""


def length_classes(lengths: np.ndarray, tolerance_m: float) -> np.ndarray:
    """Class of each length (M,): sorted lengths split where neighbours differ by more than the tolerance."""
    order = np.argsort(lengths, kind="stable")
    cls = np.concatenate([[0], np.cumsum(np.diff(lengths[order]) > tolerance_m)]).astype(np.int64)
    out = np.empty(len(lengths), dtype=np.int64)
    out[order] = cls
    return out


class PairIndex:
    """The pairs of a site that matter to the windows, their classes, and live key counts.

    Rows are the windows (active) and every other site pair in a window-holding class
    (passive). A row's key is ``(class, min label, max label)``; conflicts are two active rows
    with one key, an active and a passive row with one key, or an active row with equal labels.
    Implements the :class:`planner.codes.pairwise.ConflictIndex` protocol (a unit is an active row).
    """

    def __init__(self, n: int, windows: np.ndarray, xyz: np.ndarray, tolerance_m: float, K: int):
        windows = np.unique(np.sort(np.asarray(windows, dtype=np.int64).reshape(-1, 2), axis=1), axis=0)
        longest = float(pair_lengths(windows, xyz).max()) if len(windows) else 0.0
        rows = np.unique(np.vstack([windows, site_pairs(xyz, longest + tolerance_m + 1e-9)]), axis=0)
        cls = length_classes(pair_lengths(rows, xyz), tolerance_m)
        code = rows[:, 0] * n + rows[:, 1]
        active = np.isin(code, windows[:, 0] * n + windows[:, 1])
        held = np.isin(cls, cls[active])
        self.rows, self.active = rows[held], active[held]
        _, self.cls = np.unique(cls[held], return_inverse=True)
        self.n, self.K, self.classes = n, K, int(self.cls.max(initial=-1)) + 1
        owner = np.concatenate([self.rows[:, 0], self.rows[:, 1]])
        order = np.argsort(owner, kind="stable")
        self.of = np.tile(np.arange(len(self.rows)), 2)[order]  # rows holding each luminaire, by luminaire
        self.other = np.concatenate([self.rows[:, 1], self.rows[:, 0]])[order]
        self.start = np.searchsorted(owner[order], np.arange(n + 1))
        self.a = np.zeros(max(self.classes, 1) * K * K, dtype=np.int64)
        self.p = np.zeros_like(self.a)
        self.key = np.zeros(len(self.rows), dtype=np.int64)

    @staticmethod
    def fits(classes: int, K: int) -> bool:
        return classes * K * K <= DENSE_KEYS

    def lower_bound(self) -> int:
        """Fewest labels any valid code needs: each class's windows need distinct label pairs
        (``K (K - 1) / 2`` of them), and a luminaire's windows of one class distinct partners."""
        act = self.active
        per_class = np.bincount(self.cls[act], minlength=self.classes)
        need = max((math.ceil((1 + math.sqrt(1 + 8 * int(c))) / 2) for c in per_class), default=1)
        ends = np.concatenate([self.rows[act, 0], self.rows[act, 1]])
        deg = np.unique(np.column_stack([ends, np.tile(self.cls[act], 2)]), axis=0, return_counts=True)[1]
        return max(need, int(deg.max(initial=0)) + 1, 2)

    def _keys(self, lab: np.ndarray, rows) -> np.ndarray:
        pair = np.sort(lab[self.rows[rows]], axis=-1)
        return (self.cls[rows] * self.K + pair[..., 0]) * self.K + pair[..., 1]

    def _row_conflicts(self, rows: np.ndarray, lab: np.ndarray) -> np.ndarray:
        k = self.key[rows]
        same = lab[self.rows[rows, 0]] == lab[self.rows[rows, 1]]
        return self.active[rows] & ((self.a[k] >= 2) | (self.p[k] >= 1) | same)

    def begin(self, lab: np.ndarray) -> tuple[int, list[int]]:
        self.key = self._keys(lab, slice(None))
        size = len(self.a)
        self.a = np.bincount(self.key[self.active], minlength=size)
        self.p = np.bincount(self.key[~self.active], minlength=size)
        same = int((self.active & (lab[self.rows[:, 0]] == lab[self.rows[:, 1]])).sum())
        total = int((self.a * (self.a - 1) // 2 + self.a * self.p).sum()) + same
        return total, np.flatnonzero(self._row_conflicts(np.arange(len(self.rows)), lab)).tolist()

    def _mine(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        s, e = self.start[i], self.start[i + 1]
        return self.of[s:e], self.other[s:e]

    def _shift(self, rows: np.ndarray, sign: int) -> None:
        act = self.active[rows]
        np.add.at(self.a, self.key[rows[act]], sign)
        np.add.at(self.p, self.key[rows[~act]], sign)

    def cost(self, i: int, lab: np.ndarray, K: int) -> np.ndarray:
        """Conflicts between the rows holding ``i`` and all others, for each label of ``i`` (K,)."""
        rows, other = self._mine(i)
        if not len(rows):
            return np.zeros(K, dtype=np.int64)
        self._shift(rows, -1)
        k = np.arange(K)[None, :]
        lj = lab[other][:, None]
        key = (self.cls[rows][:, None] * self.K + np.minimum(k, lj)) * self.K + np.maximum(k, lj)
        act = self.active[rows][:, None]
        out = np.where(act, self.a[key] + self.p[key] + (k == lj), self.a[key]).sum(axis=0)
        self._shift(rows, 1)
        return out

    def holders(self, unit: int, lab: np.ndarray) -> np.ndarray:
        return self.rows[unit]

    def in_conflict(self, unit: int, lab: np.ndarray) -> bool:
        return bool(self._row_conflicts(np.array([unit]), lab)[0])

    def moved(self, i: int, old: int, lab: np.ndarray) -> list[int]:
        rows, _ = self._mine(i)
        self._shift(rows, -1)
        self.key[rows] = self._keys(lab, rows)
        self._shift(rows, 1)
        touched = np.flatnonzero(self.active & np.isin(self.key, self.key[rows]))
        return touched[self._row_conflicts(touched, lab)].tolist()


def assign_pairs(xyz: np.ndarray, graph: NeighbourGraph, windows: np.ndarray, *, tolerance_m: float, seed: int = 0,
                 proved: bool = False, time_budget: float = 10.0) -> Assignment:
    """The window scheme for the two-LED window: the fewest bits whose labels make every pair of
    ``windows`` (M, 2) read uniquely, or distinct labels.

    From the larger of the counting and the clique bound upwards, each width gets min-conflicts and,
    where that gives up on a site of at most ``CPSAT_MAX_ROWS`` pairs, CP-SAT for ``time_budget``
    deterministic seconds, which may also prove the width infeasible. ``optimal`` in the detail: the
    width meets the bound, or CP-SAT proved the width below infeasible."""
    n = len(xyz)
    unique_bits = bits_for(n)
    probe = PairIndex(n, windows, xyz, tolerance_m, 2)
    clique, counted = len(window_clique(n, probe.rows[probe.active])), probe.lower_bound()
    bound = max(counted, clique)
    labels, k, tried, steps, proved_below, wall, found_by = None, n, [], 0, False, False, ""
    max_steps = max(2000, STEPS_PER_LUMINAIRE * n)
    cpsat_widths: dict[int, str] = {}
    for b in range(bits_for(bound), unique_bits):
        if not PairIndex.fits(probe.classes, 2 ** b):
            proved_below = False
            continue
        index = PairIndex(n, windows, xyz, tolerance_m, 2 ** b)
        labels, steps = pairwise.search(index, 2 ** b, seed=seed, max_steps=max_steps, stall_steps=STALL_STEPS)
        tried.append(b)
        found_by, infeasible = "min-conflicts", False
        if labels is None and time_budget > 0 and len(index.rows) <= CPSAT_MAX_ROWS:
            labels, infeasible, stopped = cpsat_pair_labels(index, 2 ** b, time_budget=time_budget, seed=seed)
            wall |= stopped
            cpsat_widths[b] = "found" if labels is not None else "infeasible" if infeasible else "gave up"
            found_by = "CP-SAT"
        if labels is not None:
            k = 2 ** b
            break
        proved_below = infeasible
    against = f"the {len(probe.rows[probe.active]):,} {'proved' if proved else 'sampled'} two-LED windows"
    method = f"{found_by} against {against}" if labels is not None else ""
    bits = bits_for(max(k, 2))
    optimal = bits == bits_for(bound) or proved_below
    if labels is None:
        labels = np.arange(n, dtype=np.int64)
        why = ("CP-SAT proved fewer bits infeasible" if bits != bits_for(bound) else
               f"{clique} luminaires are pairwise windows" if clique >= counted else "the counting bound")
        method = f"distinct labels (optimal: {why})" if optimal else "distinct labels (no shorter labels found)"
    if wall:
        method += " (CP-SAT stopped by the wall clock: the result may differ on another machine)"
    detail = {"receiver": "gravity", "windows": int(probe.active.sum()), "rival_pairs": int((~probe.active).sum()),
              "length_classes": probe.classes, "widths_tried": tried, "steps": int(steps), "max_steps": max_steps,
              "cpsat": {str(b): v for b, v in cpsat_widths.items()}, "labels": int(k), "optimal": optimal,
              "lower_bound_labels": int(bound), "clique_labels": int(clique)}
    return Assignment("window", labels.astype(np.int64) + 1, tile_regions(xyz[:, :2], graph, k), bits, unique_bits,
                      bits_for(bound), method, detail)
