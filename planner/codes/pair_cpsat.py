"""Pair labels by CP-SAT, and the clique bound: where min-conflicts gives up, find labels or prove none exist.

The model is exactly the validity rule of :mod:`planner.codes.pair_code` on a :class:`PairIndex`:
a label ``x_i`` in ``0..K-1`` per luminaire, each window's two labels differ, and within a length
class the key ``min * K + max`` of every window differs from every other window's and from every
passive pair's. Redundant constraints help propagation: a luminaire's partners in one class carry
pairwise distinct labels, unlike its own. Labels are interchangeable, so the first window's two
ends are fixed to labels 0 and 1. An infeasible answer is a proof that ``K`` labels cannot work.

The **clique bound**: luminaires that are pairwise windows need pairwise distinct labels (each
window's two labels differ), so a clique of the window graph of size ``q`` needs ``q`` labels.
A greedy clique is a valid bound; where the windows are nearly every site pair (a wide lens on a
small room) it is nearly ``n`` and settles the width without a search.
"""

from __future__ import annotations

import numpy as np

from planner.codes import cpsat


def window_clique(n: int, windows: np.ndarray) -> np.ndarray:
    """Luminaires (ascending) that are pairwise windows, found greedily: take the candidate with
    the most window partners among the candidates, keep only its partners, repeat."""
    adj = np.zeros((n, n), dtype=bool)
    w = np.asarray(windows, dtype=np.int64).reshape(-1, 2)
    adj[w[:, 0], w[:, 1]] = adj[w[:, 1], w[:, 0]] = True
    cand, clique = np.arange(n), []
    while len(cand):
        best = int(cand[np.argmax(adj[np.ix_(cand, cand)].sum(axis=1))])
        clique.append(best)
        cand = cand[adj[best, cand]]
    return np.array(sorted(clique), dtype=np.int64)


def cpsat_pair_labels(index, K: int, *, time_budget: float, seed: int = 0) -> tuple[np.ndarray | None, bool, bool]:
    """Labels 0..K-1 valid on ``index`` (a :class:`planner.codes.pair_code.PairIndex`) or None; True if
    ``K`` labels are proved infeasible; True if the wall-clock safety net stopped the search.

    ``time_budget`` is CP-SAT's deterministic time (:mod:`planner.codes.cpsat`)."""
    n, rows, act, cls = index.n, index.rows, index.active, index.cls
    m = cpsat.new_model()
    x = [m.new_int_var(0, K - 1, f"x{i}") for i in range(n)]
    keys = []
    for r, (a, b) in enumerate(rows.tolist()):
        lo, hi = m.new_int_var(0, K - 1, f"lo{r}"), m.new_int_var(0, K - 1, f"hi{r}")
        m.add_min_equality(lo, [x[a], x[b]])
        m.add_max_equality(hi, [x[a], x[b]])
        keys.append(lo * K + hi)
        if act[r]:
            m.add(x[a] != x[b])
    partners: dict[tuple[int, int], list[int]] = {}
    for r in np.flatnonzero(act).tolist():
        a, b = rows[r].tolist()
        partners.setdefault((a, int(cls[r])), [a]).append(b)
        partners.setdefault((b, int(cls[r])), [b]).append(a)
    for group in partners.values():
        if len(group) > 2:
            m.add_all_different([x[i] for i in group])
    for c in range(index.classes):
        here = np.flatnonzero((cls == c) & act).tolist()
        if len(here) > 1:
            m.add_all_different([keys[r] for r in here])
        for p in np.flatnonzero((cls == c) & ~act).tolist():
            for r in here:
                m.add(keys[p] != keys[r])
    first = np.flatnonzero(act)
    if len(first):
        a, b = rows[first[0]].tolist()
        m.add(x[a] == 0)
        m.add(x[b] == 1)
    got = cpsat.solve(m, time_budget=time_budget, seed=seed, first_solution=True)
    if not got.found:
        return None, got.infeasible, got.wall_stopped
    lab = np.array([got.solver.value(v) for v in x], dtype=np.int64)
    if index.begin(lab)[0]:
        return None, False, got.wall_stopped  # never expected: the index checks the model independently
    return lab, False, got.wall_stopped
