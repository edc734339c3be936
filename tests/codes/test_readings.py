"""The index that lists the pairs sharing a luminaire and finds the others by their labels: the conflicts and
cost deltas of the listed pairs (``listing.alike_pairs``), and a search that clears a jittered site."""
import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from listing import alike_pairs
from test_classes import TOL, _xyz, sites

from conftest import grid_xy
from planner.codes import pairwise
from planner.codes.readings import ReadingIndex
from planner.verify.rivals import find_rivals, shape_matches, site_triples


def _against_listing(index: ReadingIndex, listed: np.ndarray, lab: np.ndarray) -> tuple[int, dict[int, set[int]]]:
    """The listed pairs' conflicts under ``lab``, and for each triple of the index in one, its partners' luminaires."""
    row = {tuple(sorted(t)): k for k, t in enumerate(index.T.tolist())}
    hit = pairwise.conflicts(listed, lab)
    partners: dict[int, set[int]] = {}
    for a, b in ((listed[p, :3], listed[p, 3:]) for p in hit):
        for x, y in ((a, b), (b, a)):
            partners.setdefault(row[tuple(sorted(x.tolist()))], set(x.tolist())).update(y.tolist())
    return len(hit), partners


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(sites, st.integers(2, 3), st.integers(0, 1000))
def test_the_index_has_the_listed_conflicts_and_exact_cost_deltas_through_moves(xy, K, seed):
    """Under random labels and after each move (the table re-keyed, never rebuilt): as many conflicts as the
    listed pairs, the same triples in one with the same partners, a cost delta per label equal to a count
    from scratch, and no conflict exactly when find_rivals finds no rival."""
    xyz = _xyz(xy)
    rng = np.random.default_rng(seed)
    site = site_triples(xy, 1.2)
    windows = site[rng.random(len(site)) < 0.4]
    listed = alike_pairs(windows, xyz, TOL)
    index = ReadingIndex.build(windows, shape_matches(windows, xyz, TOL), xyz, TOL)
    assert index is not None and index.local.pairs <= len(listed)
    lab = rng.integers(0, K, len(xy))
    total, bad = index.begin(lab)
    for step in range(7):
        want, partners = _against_listing(index, listed, lab)
        assert total == want and set(bad) == set(partners)
        assert all(index.in_conflict(u, lab) == (u in partners) for u in range(len(index.T)))
        assert all(set(index.holders(u, lab).tolist()) == partners[u] for u in bad[:20])
        if step == 6:
            break
        i = int(rng.integers(len(xy)))
        cost = index.cost(i, lab, K)
        for k in range(K):
            trial = lab.copy()
            trial[i] = k
            assert len(pairwise.conflicts(listed, trial)) - total == cost[k] - cost[lab[i]]
        old, lab[i] = lab[i], int(rng.integers(K))
        moved = index.moved(i, old, lab)
        total += int(cost[lab[i]] - cost[old])
        bad = sorted(_against_listing(index, listed, lab)[1])
        assert set(moved) <= set(bad)
    assert index.begin(lab) == (total, bad)
    assert (total == 0) == (find_rivals(windows, xyz, lab, TOL) == [])


def test_pairs_of_triples_far_apart_are_not_listed_but_found():
    """Translates of one triangle far apart share no luminaire: none is listed, every one is a conflict
    under equal labels and none under labels that tell them apart."""
    xy = np.array([[0, 0], [0.5, 0], [0, 0.5], [3, 0], [3.5, 0], [3, 0.5], [6, 0], [6.5, 0], [6, 0.5]], float)
    xyz = _xyz(xy)
    windows = np.array([[0, 1, 2], [3, 4, 5]])
    index = ReadingIndex.build(windows, shape_matches(windows, xyz, TOL), xyz, TOL)
    assert index is not None and index.local.pairs == 0 and len(index.T) == 3
    total, bad = index.begin(np.array([0, 1, 2] * 3))
    assert total == 3 and bad == [0, 1, 2]  # both windows with each other and with the third translate
    apart = np.array([0, 1, 2, 0, 1, 3, 0, 3, 2])
    assert index.begin(apart) == (0, [])
    assert index.cost(5, apart, 4).tolist() == [0, 0, 1, 0]  # luminaire 5 back at label 2: one pair again


def test_a_site_with_no_window_has_nothing_to_keep_apart():
    """A sparse house (lights 5 m apart): no pose sees three, the proved set is empty; the index is empty too."""
    from planner.codes.proved import proved_labels

    xyz = _xyz(np.array([[2 + 5 * i, 2 + 5 * j] for j in range(3) for i in range(4)], float))
    index = ReadingIndex.build(np.empty((0, 3), np.int64), np.empty((0, 3), np.int64), xyz, TOL)
    assert index is not None and len(index.T) == 0 and index.begin(np.zeros(12, np.int64)) == (0, [])
    got = proved_labels(np.empty((0, 3), np.int64), xyz, TOL)
    assert got is not None and got.labels is not None and got.detail["triples"] == 0


def test_over_the_budget_there_is_no_index():
    xy = grid_xy(4, 5, 0.5, 0.5, jitter_m=0.02, seed=1)
    windows = site_triples(xy, 1.2)
    xyz = _xyz(xy)
    assert ReadingIndex.build(windows, shape_matches(windows, xyz, TOL), xyz, TOL, budget=10) is None
    assert ReadingIndex.build(windows, shape_matches(windows, xyz, TOL), xyz, TOL) is not None


def test_a_search_clears_a_jittered_site_and_find_rivals_agrees():
    xy = grid_xy(9, 10, 0.6, 0.6, jitter_m=0.08, seed=5)
    xyz = _xyz(xy)
    windows = site_triples(xy, 1.0)
    index = ReadingIndex.build(windows, shape_matches(windows, xyz, TOL), xyz, TOL)
    assert index is not None
    labels, steps = pairwise.search(index, 8, seed=0, max_steps=20_000)
    assert labels is not None and steps > 0
    assert find_rivals(windows, xyz, labels, TOL) == []
