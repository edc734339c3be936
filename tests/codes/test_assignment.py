"""The paper's region code: the three cases of section 2.2 and the pair rule everywhere."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import grid_xy, hex_xy
from planner.codes.assignment import assign_paper, pair_conflicts, pair_lower_bound
from planner.graph import build_graph


def repeated_pairs(xy, g, ids):
    """Independent check: (odd ID, even ID) of every neighbour pair, counted."""
    pairs = {}
    for u, v in g.graph.edges():
        if g.odd[u] == g.odd[v]:
            assert ids[u] != ids[v]
            continue
        o, e = (u, v) if g.odd[u] else (v, u)
        assert ids[o] % 2 == 1 and ids[e] % 2 == 0
        pairs[(int(ids[o]), int(ids[e]))] = pairs.get((int(ids[o]), int(ids[e])), 0) + 1
    return {p: n for p, n in pairs.items() if n > 1}


@pytest.mark.parametrize("rows,cols,bits,naive,groups,efficiency", [
    (4, 8, 4, 5, 2, 0.20),      # 32 = 2 groups of 16, 4 bits instead of 5
    (16, 16, 6, 8, 4, 0.25),    # 256 = 4 groups of 64, 6 bits instead of 8
    (16, 32, 6, 9, 8, 1 / 3),   # 512 = 8 groups of 64, 6 bits instead of 9
])
def test_paper_cases(rows, cols, bits, naive, groups, efficiency):
    xy = grid_xy(rows, cols)
    g = build_graph(xy)
    a = assign_paper(xy, g)
    assert (a.bits, a.naive_bits, a.lower_bound_bits) == (bits, naive, bits)
    assert a.efficiency == pytest.approx(efficiency, abs=1e-9)
    assert repeated_pairs(xy, g, a.ids) == {}
    assert a.regions.max() + 1 == groups
    size = len(xy) // groups
    for r in range(groups):  # a group of 2M luminaires carries IDs 1..2M, each once
        assert sorted(a.ids[a.regions == r].tolist()) == list(range(1, size + 1))
    # the odd arrangement repeats in every group: same position in the group, same ID
    block = a.detail["group_columns"], a.detail["group_rows"]
    cells = g.lattice if not a.detail["transposed"] else g.lattice[:, ::-1]
    pos = cells % np.array(block)
    for key in {tuple(p) for p in pos[g.odd]}:
        same = g.odd & np.all(pos == key, axis=1)
        assert len(set(a.ids[same].tolist())) == 1


def test_lower_bound_matches_the_counting_argument():
    # a * b >= adjacent pairs: 52 for 4 x 8, 480 for 16 x 16, 976 for 16 x 32 (READING.md 2)
    for (r, c), bits in {(4, 8): 4, (16, 16): 6, (16, 32): 6, (100, 100): 9}.items():
        g = build_graph(grid_xy(r, c))
        assert pair_lower_bound(g)[1] == bits


@pytest.mark.slow
def test_large_grid_reaches_the_bound_by_construction():
    xy = grid_xy(100, 100)
    g = build_graph(xy)
    a = assign_paper(xy, g)
    assert a.method == "lattice construction"
    assert a.bits == a.lower_bound_bits == 9 and a.naive_bits == 14
    assert pair_conflicts(g, a.ids) == []


def test_checker_catches_a_swapped_pair():
    xy = grid_xy(4, 8)
    g = build_graph(xy)
    ids = assign_paper(xy, g).ids.copy()
    evens = np.flatnonzero(~g.odd)
    ids[evens[0]], ids[evens[5]] = ids[evens[5]], ids[evens[0]]
    ids[evens[1]] = ids[evens[9]]  # two even luminaires with one ID: some pair repeats
    assert pair_conflicts(g, ids)


def test_hexagonal_layout_is_planned_by_search():
    xy = hex_xy(8, 8)
    g = build_graph(xy)
    a = assign_paper(xy, g, time_budget=1.0)
    assert not g.bipartite
    assert a.method in ("greedy first fit", "CP-SAT")
    assert repeated_pairs(xy, g, a.ids) == {}


def test_search_is_deterministic():
    xy = np.random.default_rng(5).uniform(0, 10, (60, 2))
    g = build_graph(xy)
    first = assign_paper(xy, g, time_budget=1.0, seed=3)
    second = assign_paper(xy, build_graph(xy), time_budget=1.0, seed=3)
    assert np.array_equal(first.ids, second.ids)
    assert first.bits >= first.lower_bound_bits


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(rows=st.integers(2, 24), cols=st.integers(2, 24), holes=st.integers(0, 30), seed=st.integers(0, 10**6))
def test_lattice_with_holes_never_repeats_a_pair(rows, cols, holes, seed):
    xy = grid_xy(rows, cols)
    rng = np.random.default_rng(seed)
    keep = np.ones(len(xy), dtype=bool)
    keep[rng.choice(len(xy), size=min(holes, len(xy) - 3), replace=False)] = False
    xy = xy[keep]
    g = build_graph(xy)
    a = assign_paper(xy, g, time_budget=0.2)
    assert repeated_pairs(xy, g, a.ids) == {}
    assert a.lower_bound_bits <= a.bits <= max(a.naive_bits, a.lower_bound_bits) + 2


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(3, 80), seed=st.integers(0, 10**6))
def test_irregular_layouts_never_repeat_a_pair(n, seed):
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, 10, (n, 2))
    g = build_graph(xy)
    a = assign_paper(xy, g, time_budget=0.2, seed=seed)
    assert repeated_pairs(xy, g, a.ids) == {}
