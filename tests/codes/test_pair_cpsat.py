"""Pair labels by CP-SAT and the clique bound: labels found are valid, widths proved infeasible have no labelling."""

from itertools import product

import numpy as np

from planner.codes.pair_code import PairIndex, assign_pairs
from planner.codes.pair_cpsat import cpsat_pair_labels, window_clique
from planner.graph import build_graph
from planner.verify.pair_windows import pair_rivals, site_pairs


def _row(n: int, spacing_m: float = 1.0) -> np.ndarray:
    return np.column_stack([np.arange(n) * spacing_m, np.zeros(n), np.full(n, 3.0)])


def _brute_force_feasible(index: PairIndex, K: int) -> bool:
    return any(index.begin(np.array(lab))[0] == 0 for lab in product(range(K), repeat=index.n))


def test_cpsat_agrees_with_enumerating_every_labelling():
    # five in a row, windows up to 2 m: per length class the pairs of labels must differ
    xyz = _row(5)
    windows = site_pairs(xyz, 2.0 + 1e-9)
    verdicts = {}
    for K in (2, 3, 4):
        index = PairIndex(5, windows, xyz, 0.05, K)
        labels, infeasible, wall = cpsat_pair_labels(index, K, time_budget=5.0)
        assert not wall
        assert (labels is not None) == _brute_force_feasible(index, K)  # found exactly when some labelling exists
        assert infeasible == (labels is None)  # and proved infeasible otherwise, not merely given up
        if labels is not None:
            assert pair_rivals(windows, xyz, labels + 1, 0.05) == []  # the independent checker agrees
        verdicts[K] = labels is not None
    assert verdicts == {2: False, 3: False, 4: True}  # both answers occur (3 labels: 3 pairs for 4 windows of 1 m)


def test_cpsat_labels_a_grid_and_proves_the_narrower_width_infeasible():
    xy = np.array([[x, y] for x in range(5) for y in range(4)], float) * 1.2
    xyz = np.column_stack([xy, np.full(len(xy), 2.8)])
    windows = site_pairs(xyz, 1.7)  # neighbours (1.2 m, 31 pairs) and diagonals (1.7 m, 24 pairs)
    found = {}
    for K in (4, 16):
        index = PairIndex(len(xyz), windows, xyz, 0.05, K)
        labels, infeasible, _ = cpsat_pair_labels(index, K, time_budget=10.0)
        found[K] = (labels, infeasible)
    assert found[4][0] is None and found[4][1]  # 4 labels give 6 pairs for 31 neighbour windows
    labels = found[16][0]
    assert labels is not None and pair_rivals(windows, xyz, labels + 1, 0.05) == []


def test_the_clique_bound_settles_a_site_whose_pairs_are_all_windows():
    xyz = _row(6)
    windows = site_pairs(xyz, 10.0)  # every pair is a window: every label must differ
    assert window_clique(6, windows).tolist() == [0, 1, 2, 3, 4, 5]
    a = assign_pairs(xyz, build_graph(xyz[:, :2]), windows, tolerance_m=0.05, proved=True)
    assert a.bits == 3 and a.detail["optimal"] and a.detail["clique_labels"] == 6
    assert a.lower_bound_bits == 3 and "optimal" in a.method
    # one pair fewer (the two ends never seen together) and the clique is 5
    assert len(window_clique(6, windows[~((windows[:, 0] == 0) & (windows[:, 1] == 5))])) == 5


def test_assign_pairs_meets_the_counting_bound_on_a_grid_and_says_so():
    xy = np.array([[x, y] for x in range(5) for y in range(4)], float) * 1.2
    xyz = np.column_stack([xy, np.full(len(xy), 2.8)])
    windows = site_pairs(xyz, 1.7)
    a = assign_pairs(xyz, build_graph(xy), windows, tolerance_m=0.05, time_budget=10.0)
    assert pair_rivals(windows, xyz, a.ids, 0.05) == []
    # the counting bound (31 neighbour windows need 9 labels) gives 4 bits, which min-conflicts or CP-SAT meets
    assert a.detail["lower_bound_labels"] >= 9 and a.lower_bound_bits == 4
    assert a.bits == 4 and a.detail["optimal"] and a.detail["widths_tried"] == [4]


def _jittered(seed: int) -> np.ndarray:
    xy = np.array([[x, y] for x in range(6) for y in range(5)], float) * 1.2
    xy += np.random.default_rng(seed).uniform(-0.15, 0.15, xy.shape)
    return np.column_stack([xy, np.full(len(xy), 2.8)])


def test_cpsat_saves_the_bit_min_conflicts_gives_up_on_and_proves_a_width_infeasible():
    xyz = _jittered(3)  # 30 luminaires 1.2 m apart, jittered: lengths differ, windows up to 2.5 m
    windows = site_pairs(xyz, 2.5)
    graph = build_graph(xyz[:, :2])
    alone = assign_pairs(xyz, graph, windows, tolerance_m=0.05, time_budget=0)
    both = assign_pairs(xyz, graph, windows, tolerance_m=0.05, time_budget=10.0)
    # measured: min-conflicts gives up on 4 bits (distinct labels, 5 bits); CP-SAT finds 4, the bound's width
    assert alone.bits == 5 and not alone.detail["cpsat"]
    assert both.bits == 4 and both.detail["cpsat"] == {"4": "found"} and both.method.startswith("CP-SAT")
    assert both.detail["optimal"] and pair_rivals(windows, xyz, both.ids, 0.05) == []
    # windows up to 3.7 m: CP-SAT proves 16 labels cannot work, so distinct labels are optimal
    other = _jittered(1)
    far = site_pairs(other, 3.7)
    proved = assign_pairs(other, build_graph(other[:, :2]), far, tolerance_m=0.05, time_budget=10.0)
    assert proved.bits == 5 and proved.detail["cpsat"] == {"4": "infeasible"} and proved.detail["optimal"]
    assert "CP-SAT proved fewer bits infeasible" in proved.method
