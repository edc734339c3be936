"""Labels against a complete window set: the listed pairs (``listing``, the tests' reference) are exactly the
rivals, and search over their index clears them."""
import itertools

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from listing import alike_pairs

from conftest import grid_xy
from planner.codes.pairwise import Index, conflicts, search
from planner.verify.rivals import find_rivals, site_triples

TOL = 0.05

sites = st.builds(lambda rows, cols, jitter, seed: grid_xy(rows, cols, 0.5, 0.5, jitter_m=jitter, seed=seed),
                  st.integers(2, 5), st.integers(3, 6), st.floats(0, 0.08), st.integers(0, 100))


def _xyz(xy):
    return np.column_stack([xy, np.full(len(xy), 2.5)])


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(sites, st.integers(1, 3), st.integers(0, 1000))
def test_a_pair_is_in_conflict_exactly_when_find_rivals_names_it(xy, k, seed):
    """For random labels of few values, the (window, rival) pairs the listed pairs put in conflict
    are the ones find_rivals reports, one for one."""
    xyz = _xyz(xy)
    site = site_triples(xy, 1.2)
    rng = np.random.default_rng(seed)
    windows = site[rng.random(len(site)) < 0.3]
    pairs = alike_pairs(windows, xyz, TOL)
    assert pairs is not None
    ids = rng.integers(0, k, len(xy))
    want = {frozenset([frozenset(windows[w].tolist()), frozenset(u)]) for w, u in find_rivals(windows, xyz, ids, TOL)}
    got = {frozenset([frozenset(p[:3].tolist()), frozenset(p[3:].tolist())]) for p in pairs[conflicts(pairs, ids)]}
    assert got == want


def test_each_pair_is_listed_once_whatever_its_rotation_or_order():
    xy = grid_xy(3, 4, 0.5, 0.5)  # an exact lattice: every shape has many copies, symmetric ones too
    xyz = _xyz(xy)
    windows = site_triples(xy, 0.75)
    pairs = alike_pairs(windows, xyz, TOL)
    seen = set()
    for p in pairs.tolist():
        a, b = p[:3], p[3:]
        forms = {tuple(a[r:] + a[:r] + b[r:] + b[:r]) for r in range(3)}
        forms |= {tuple(b[r:] + b[:r] + a[r:] + a[:r]) for r in range(3)}
        assert not forms & seen, p
        seen |= forms
    assert len(pairs) == len(np.unique(pairs, axis=0)) > 0


def test_search_clears_every_pair_and_the_rivals_agree():
    xy = grid_xy(4, 5, 0.5, 0.5, jitter_m=0.06, seed=3)
    xyz = _xyz(xy)
    windows = site_triples(xy, 1.2)
    pairs = alike_pairs(windows, xyz, TOL)
    labels, steps = search(Index(len(xy), pairs), 8, seed=1, max_steps=5000)
    assert labels is not None and 0 < steps < 5000
    assert len(conflicts(pairs, labels)) == 0
    assert find_rivals(windows, xyz, labels, TOL) == []
    assert labels.min() >= 0 and labels.max() < 8


def test_search_says_so_when_no_labels_exist():
    """Two translates of one triangle with one label each can only read alike."""
    xy = np.array([[0, 0], [1, 0], [0, 1], [5, 0], [6, 0], [5, 1]], float)
    xyz = _xyz(xy)
    pairs = alike_pairs(np.array([[0, 1, 2]]), xyz, TOL, site=np.array([[3, 4, 5]]))
    assert pairs.tolist() == [[0, 1, 2, 3, 4, 5]]
    assert search(Index(6, pairs), 1, max_steps=100) == (None, 0)
    labels, _ = search(Index(6, pairs), 2, max_steps=100)
    assert labels is not None and len(conflicts(pairs, labels)) == 0


def test_a_luminaire_in_two_places_of_one_pair_is_scored_in_full():
    """Triples sharing an edge in non-facing places (a, b, c) ~ (b, c, d): the cost of a label
    counts the luminaire's effect on both places, as brute force over every labelling says."""
    xy = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)  # a square: (0,1,2) ~ (1,2,3) ~ (2,3,0) ...
    xyz = _xyz(xy)
    pairs = alike_pairs(site_triples(xy, 1.5), xyz, TOL)
    best = min(len(conflicts(pairs, np.array(lab))) for lab in itertools.product(range(2), repeat=4))
    labels, _ = search(Index(4, pairs), 2, seed=0, max_steps=500)
    assert (best == 0) == (labels is not None)
    if labels is not None:
        assert len(conflicts(pairs, labels)) == 0
