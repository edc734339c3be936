"""The compact pair index of irregular sites: the same pairs as the listed ones, exact cost deltas,
and a search that clears a site whose pairs are too many to list."""
import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_classes import TOL, _xyz, sites

from conftest import grid_xy
from planner.codes import pairwise
from planner.codes.alike import AlikeIndex
from planner.verify.rivals import find_rivals, shape_matches, site_triples


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(sites, st.integers(2, 3), st.integers(0, 1000))
def test_the_index_holds_the_listed_pairs_and_its_cost_deltas_are_exact(xy, K, seed):
    """As many pairs as :func:`pairwise.alike_pairs` lists, the same conflicts under any labels, a move's cost
    delta equal to a count from scratch, and no conflict exactly when find_rivals finds no rival."""
    xyz = _xyz(xy)
    rng = np.random.default_rng(seed)
    site = site_triples(xy, 1.2)
    windows = site[rng.random(len(site)) < 0.4]
    index = AlikeIndex.build(windows, shape_matches(windows, xyz, TOL), xyz, TOL)
    listed = pairwise.alike_pairs(windows, xyz, TOL)
    assert index is not None and index.pairs == len(listed)
    lab = rng.integers(0, K, len(xy))
    total, bad = index.begin(lab)
    assert total == len(pairwise.conflicts(listed, lab))
    for _ in range(6):
        i = int(rng.integers(len(xy)))
        cost = index.cost(i, lab, K)
        for k in range(K):
            trial = lab.copy()
            trial[i] = k
            assert index.begin(trial)[0] - total == cost[k] - cost[lab[i]]
        old, lab[i] = lab[i], int(rng.integers(K))
        total += int(cost[lab[i]] - cost[old])
        total_now, bad = index.begin(lab)
        assert total_now == total
        assert set(index.moved(i, old, lab)) <= set(bad)
        assert all(index.in_conflict(u, lab) == (u in bad) for u in range(len(index.T)))
    assert (total == 0) == (find_rivals(windows, xyz, lab, TOL) == [])


def test_over_the_budget_there_is_no_index():
    xy = grid_xy(4, 5, 0.5, 0.5, jitter_m=0.02, seed=1)
    windows = site_triples(xy, 1.2)
    xyz = _xyz(xy)
    assert AlikeIndex.build(windows, shape_matches(windows, xyz, TOL), xyz, TOL, budget=10) is None


def test_a_search_clears_a_jittered_site_and_find_rivals_agrees():
    xy = grid_xy(9, 10, 0.6, 0.6, jitter_m=0.08, seed=5)
    xyz = _xyz(xy)
    windows = site_triples(xy, 1.0)
    index = AlikeIndex.build(windows, shape_matches(windows, xyz, TOL), xyz, TOL)
    assert index is not None
    labels, steps = pairwise.search(index, 8, seed=0, max_steps=20_000)
    assert labels is not None and steps > 0
    assert find_rivals(windows, xyz, labels, TOL) == []
