"""Labels against a proved window set by shape groups: every rival is a group conflict, the cost
deltas are exact, and search clears lattices whose pairs are too many to list."""
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import grid_xy, hex_xy
from planner.codes.classes import ClassIndex, clique_lower_bound, shape_groups
from planner.codes.pairwise import search
from planner.verify.rivals import find_rivals, site_triples

TOL = 0.05

sites = st.one_of(
    st.builds(lambda rows, cols, jitter, seed: grid_xy(rows, cols, 0.5, 0.5, jitter_m=jitter, seed=seed),
              st.integers(2, 5), st.integers(3, 6), st.sampled_from([0.0, 0.02, 0.06]), st.integers(0, 100)),
    st.builds(lambda rows, cols: hex_xy(rows, cols, 0.5), st.integers(2, 4), st.integers(3, 5)))


def _xyz(xy):
    return np.column_stack([xy, np.full(len(xy), 2.5)])


def _keys(groups, labels):
    t = labels[groups.triples]
    return {(g, *row) for g, row in zip(groups.group.tolist(), t.tolist())}, t


@pytest.mark.slow
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(sites, st.integers(1, 3), st.integers(0, 1000), st.sampled_from([1e-6, TOL / 2, TOL]))
def test_every_rival_find_rivals_names_is_a_conflict_of_the_groups(xy, k, seed, resolution):
    """Exact lattices (many congruent copies), near-equilateral hexagonal ones (a shape that
    matches itself turned) and jittered sites, with classes of exact shapes or cells of side
    lengths as wide as the tolerance (irregular sites): for random labels of few values, each
    (window, rival) find_rivals reports has a row of each in one group with equal labels in order."""
    xyz = _xyz(xy)
    rng = np.random.default_rng(seed)
    site = site_triples(xy, 1.2)
    windows = site[rng.random(len(site)) < 0.4]
    groups = shape_groups(windows, xyz, TOL, resolution_m=resolution)
    ids = rng.integers(0, k, len(xy))
    labels = ids[groups.triples]
    for w, u in find_rivals(windows, xyz, ids, TOL):
        rows_w = np.flatnonzero((np.sort(groups.triples, axis=1) == np.sort(windows[w])).all(axis=1))
        rows_u = np.flatnonzero((np.sort(groups.triples, axis=1) == np.sort(u)).all(axis=1))
        assert len(rows_w) and len(rows_u), (windows[w], u)
        assert groups.window[rows_w].all()
        assert any(groups.group[a] == groups.group[b] and (labels[a] == labels[b]).all()
                   for a in rows_w for b in rows_u), (windows[w], u)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(sites, st.integers(0, 1000))
def test_cost_deltas_and_moves_match_a_count_from_scratch(xy, seed):
    xyz = _xyz(xy)
    rng = np.random.default_rng(seed)
    windows = site_triples(xy, 1.2)
    groups = shape_groups(windows, xyz, TOL)
    K = 3
    index = ClassIndex(len(xy), groups, K)
    lab = rng.integers(0, K, len(xy))
    total, _ = index.begin(lab)
    for _ in range(5):
        i = int(rng.integers(len(xy)))
        cost = index.cost(i, lab, K)
        for k in range(K):
            trial = lab.copy()
            trial[i] = k
            assert ClassIndex(len(xy), groups, K).begin(trial)[0] == total - cost[lab[i]] + cost[k]
        old, lab[i] = lab[i], int(rng.integers(K))
        now = set(index.moved(i, old, lab))
        total = total - cost[old] + cost[lab[i]]
        fresh_total, fresh_bad = ClassIndex(len(xy), groups, K).begin(lab)
        assert fresh_total == total
        assert now <= set(fresh_bad)
        assert all(index.in_conflict(u, lab) == (u in fresh_bad) for u in range(len(groups.triples)))


def test_a_lattice_too_big_for_pairs_is_cleared_by_the_groups_and_find_rivals_agrees():
    """An exact 8 x 10 lattice: its congruent triples make one group, and labels of 16 values (4 bits,
    against 7 for distinct IDs) leave no window reading like any triple of the site."""
    xy = grid_xy(8, 10, 0.6, 0.6)
    xyz = _xyz(xy)
    windows = site_triples(xy, 0.9)
    groups = shape_groups(windows, xyz, TOL)
    assert groups.count == 1 and len(groups.triples) == len(windows)  # one shape: a clique of 252
    labels, steps = search(ClassIndex(len(xy), groups, 16), 16, seed=0, max_steps=20_000)
    assert labels is not None and steps > 0
    assert find_rivals(windows, xyz, labels, TOL) == []


def test_a_hexagonal_lattice_is_cleared_despite_its_equilateral_windows():
    xy = hex_xy(6, 7, 0.6)
    xyz = _xyz(xy)
    windows = site_triples(xy, 0.65)  # the unit equilateral triangles
    groups = shape_groups(windows, xyz, TOL)
    assert len(groups.triples) == 3 * len(np.unique(np.sort(groups.triples, axis=1), axis=0))  # every turn
    labels, _ = search(ClassIndex(len(xy), groups, 8), 8, seed=0, max_steps=20_000)
    assert labels is not None
    assert find_rivals(windows, xyz, labels, TOL) == []


def test_too_many_labels_for_the_table_budget_do_not_fit():
    xy = grid_xy(3, 4, 0.5, 0.5)
    groups = shape_groups(site_triples(xy, 0.75), _xyz(xy), TOL)
    assert ClassIndex.fits(groups, 8)
    assert not ClassIndex.fits(groups, 2 ** 12)


def test_a_group_too_large_for_16_bit_counters_is_counted_in_32_bits():
    """On a 100,000-luminaire lattice a shape holds more triples than int16 counts: every group was refused and
    the site fell to the sampled design. 40,000 triples of one group, all reading alike, count every pair."""
    from planner.codes.classes import Groups

    m, windows = 40_000, 100
    triples = np.column_stack([np.arange(m), np.arange(m) + m, np.arange(m) + 2 * m])
    groups = Groups(triples, np.zeros(m, np.int64), np.arange(m) < windows)
    assert ClassIndex.counter(groups) is np.int32 and ClassIndex.fits(groups, 2)
    total, bad = ClassIndex(3 * m, groups, 2).begin(np.zeros(3 * m, np.int64))
    assert total == windows * (windows - 1) // 2 + windows * (m - windows) and len(bad) == m
    small = Groups(triples[:1000], np.zeros(1000, np.int64), np.arange(1000) < windows)
    assert ClassIndex.counter(small) is np.int16


def test_the_clique_bound_counts_the_largest_set_of_windows_of_one_shape():
    """Copies of one L triangle (any of its four turns) read alike under equal labels, so each needs
    its own label triple: 64 copies fit 4 labels (4^3), 73 need 5. On an exact triangular lattice the
    unit triangles have threefold symmetry, so only (K^3 + 2K) / 3 readings tell them apart."""
    xy = grid_xy(6, 6, 0.5, 0.5)
    at = {(round(x / 0.5), round(y / 0.5)): k for k, (x, y) in enumerate(xy)}
    ls = [(at[c, r], at[c + dc, r], at[c, r + dr]) for c in range(1, 5) for r in range(1, 5)
          for dc, dr in ((1, 1), (-1, 1), (1, -1), (-1, -1))]
    assert len(ls) == 64 and clique_lower_bound(np.array(ls), _xyz(xy)) == 4
    ls += [(at[c, 0], at[c + 1, 0], at[c, 1]) for c in range(5)] + [(at[0, r], at[1, r], at[0, r + 1]) for r in (1, 2, 3, 4)]
    assert clique_lower_bound(np.array(ls), _xyz(xy)) == 5
    mirrored = [(a, c, b) for a, b, c in ls[:64]]  # the same triples: the bound does not depend on vertex order
    assert clique_lower_bound(np.array(mirrored), _xyz(xy)) == 4
    tri_xy = np.array([(c + 0.5 * (r % 2), r * np.sqrt(3) / 2) for r in range(8) for c in range(8)]) * 0.6
    units = site_triples(tri_xy, 0.6 + 1e-9)
    k = clique_lower_bound(units, _xyz(tri_xy))
    assert (k ** 3 + 2 * k) // 3 >= len(units) > ((k - 1) ** 3 + 2 * (k - 1)) // 3


def test_an_irregular_site_over_the_budgets_is_labelled_by_its_pairs_or_by_groups_of_shape_cells(monkeypatch):
    """A jittered lattice has no two congruent triples: with the listed pairs over their budget and the
    links between one-triple classes over theirs, the reading index lists the pairs sharing a luminaire and
    finds the others by their labels; with those over its budget too, the groups are cells of the
    tolerance's width. Either way no window reads like any triple."""
    from listing import alike_pairs

    from planner.codes import alike, classes
    from planner.codes.proved import proved_labels

    xy = grid_xy(8, 10, 0.6, 0.6, jitter_m=0.03, seed=3)
    xyz = _xyz(xy)
    windows = site_triples(xy, 0.9)
    monkeypatch.setattr(classes, "LINK_BUDGET", 5_000)
    assert shape_groups(windows, xyz, TOL) is None
    got = proved_labels(windows, xyz, TOL)
    assert got is not None and got.labels is not None and got.bits < 7
    assert 0 < got.detail["listed_pairs"] < len(alike_pairs(windows, xyz, TOL))
    assert got.detail["triples"] >= len(windows)
    assert find_rivals(windows, xyz, got.labels, TOL) == []
    monkeypatch.setattr(alike, "PAIR_BUDGET", 100)
    got = proved_labels(windows, xyz, TOL)
    assert got is not None and got.labels is not None and got.bits < 7
    assert 0 < got.detail["shape_groups"] < 20
    assert find_rivals(windows, xyz, got.labels, TOL) == []


def test_an_irregular_site_whose_windows_alone_are_over_the_link_budget_gets_no_groups_before_its_matches(monkeypatch):
    """The windows' own classes are some of the classes: their links over the budget, the groups are refused
    before the site's matches are found or ranked (a 10,000-luminaire site: minutes and 10 GB); under it, the
    groups are what they were."""
    from planner.codes import classes

    xy = grid_xy(6, 7, 0.6, 0.6, jitter_m=0.03, seed=5)
    xyz = _xyz(xy)
    windows = site_triples(xy, 0.9)
    classes_of_windows = len(np.unique(np.round(np.sort(np.linalg.norm(
        xy[windows] - xy[np.roll(windows, -1, axis=1)], axis=2), axis=1), 6), axis=0))
    assert classes_of_windows == len(windows)  # irregular: every window its own class
    monkeypatch.setattr(classes, "LINK_BUDGET", len(windows) - 1)  # each class links at least itself
    monkeypatch.setattr(classes, "shape_matches", lambda *a: (_ for _ in ()).throw(AssertionError("matched")))
    assert shape_groups(windows, xyz, TOL) is None
    monkeypatch.undo()
    assert shape_groups(windows, xyz, TOL, resolution_m=TOL) is not None
