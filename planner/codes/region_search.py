"""The paper's pair rule on any layout, by search.

Where the lattice construction does not apply (irregular, staggered or
hexagonal layouts), IDs are found by search over labels: ``x_v`` in
``0..A-1`` for odd luminaires (ID ``2 x + 1``) and ``0..B-1`` for even ones
(ID ``2 y + 2``), such that every cross edge's pair ``(x_u, y_w)`` is used once
(``AllDifferent(x_u * B + y_w)``) and luminaires joined by a same-class edge
differ. A greedy first fit gives a plan at once; OR-Tools CP-SAT then looks for
one with fewer bits, within a deterministic time budget.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from planner.codes import cpsat
from planner.graph import NeighbourGraph

CPSAT_MAX_CROSS_EDGES = 300
"""CP-SAT is tried only up to this many cross edges: beyond it, its AllDifferent model
rarely finds a shorter code within budget (459 luminaires: nothing in 137 s)."""

def _bfs_order(graph: NeighbourGraph) -> list[int]:
    n = len(graph.odd)
    seen = np.zeros(n, dtype=bool)
    order = []
    for root in range(n):
        if seen[root]:
            continue
        seen[root] = True
        queue = deque([root])
        while queue:
            u = queue.popleft()
            order.append(u)
            for w in sorted(graph.graph.adj[u]):
                if not seen[w]:
                    seen[w] = True
                    queue.append(w)
    return order


def greedy_labels(graph: NeighbourGraph) -> np.ndarray:
    """First-fit labels in breadth-first order (labels are per class, 0-based)."""
    odd = graph.odd
    adj = graph.graph.adj
    n = len(odd)
    label = np.full(n, -1, dtype=np.int64)
    used_pairs: set[tuple[int, int]] = set()
    for v in _bfs_order(graph):
        cross = [w for w in adj[v] if odd[w] != odd[v]]
        forbidden = {int(label[w]) for w in adj[v] if odd[w] == odd[v] and label[w] >= 0}
        for w in cross:  # same-class luminaires sharing a neighbour must differ
            forbidden.update(int(label[u]) for u in adj[w] if u != v and odd[u] == odd[v] and label[u] >= 0)
        assigned = [int(label[w]) for w in cross if label[w] >= 0]
        x = 0
        while True:
            if x not in forbidden:
                pairs = [(x, y) if odd[v] else (y, x) for y in assigned]
                if not any(p in used_pairs for p in pairs):
                    break
            x += 1
        label[v] = x
        used_pairs.update((x, y) if odd[v] else (y, x) for y in assigned)
    return label


def cpsat_pair_labels(graph: NeighbourGraph, per_class: int, time_budget: float,
                 seed: int) -> tuple[np.ndarray | None, bool]:
    """Labels with at most ``per_class`` labels in each class (or None), and whether the
    wall-clock safety stop ended the search.

    ``time_budget`` is CP-SAT's deterministic time (:mod:`planner.codes.cpsat`).
    """
    odd = graph.odd
    n = len(odd)
    model = cpsat.new_model()
    x = [model.new_int_var(0, per_class - 1, f"x{v}") for v in range(n)]
    cross = graph.cross_edges
    if len(cross):
        model.add_all_different([x[int(u)] * per_class + x[int(w)] for u, w in cross])
    for u, w in graph.same_class_edges:
        model.add(x[int(u)] != x[int(w)])
    if n:
        model.add(x[0] == 0)  # labels are interchangeable: fix one
    got = cpsat.solve(model, time_budget=time_budget, seed=seed)
    if not got.found:
        return None, got.wall_stopped
    return np.array([got.solver.value(v) for v in x], dtype=np.int64), got.wall_stopped


def labels_to_ids(odd: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Odd class label x -> ID 2x+1; even class label y -> ID 2y+2."""
    return np.where(odd, 2 * labels + 1, 2 * labels + 2)


def search(graph: NeighbourGraph, min_bits: int, time_budget: float, seed: int) -> tuple[np.ndarray, str]:
    """IDs under the pair rule with as few bits as the budget allows, and how they were found."""
    ids = labels_to_ids(graph.odd, greedy_labels(graph))
    method = "greedy first fit"
    bits = max(1, math.ceil(math.log2(int(ids.max()))))
    small = len(graph.cross_edges) <= CPSAT_MAX_CROSS_EDGES
    while small and bits - 1 >= max(min_bits, 1) and time_budget > 0:
        labels, wall_stopped = cpsat_pair_labels(graph, 2 ** (bits - 2), time_budget, seed)
        if wall_stopped:
            method += " (CP-SAT stopped by the wall clock: the result may differ on another machine)"
        if labels is None:
            break
        ids = labels_to_ids(graph.odd, labels)
        method = "CP-SAT" + (" (stopped by the wall clock: the result may differ on another machine)"
                             if wall_stopped else "")
        bits = max(1, math.ceil(math.log2(int(ids.max()))))
    return ids, method
