"""Window codes: keys, conflicts, the counting bound and the label search (checked independently)."""

import itertools

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from planner.codes import window as wc
from planner.codes.window import (
    assign_window_code,
    conflicting_windows,
    count_conflicts,
    cpsat_window_labels,
    lower_bound_labels,
    repair_labels,
    search_labels,
    window_keys,
)


def l_windows(rows: int, cols: int) -> np.ndarray:
    """Every unit cell's 4 L triangles: (corner, arm, arm + 90 deg), CCW from the corner."""
    out = []
    for r in range(rows - 1):
        for c in range(cols - 1):
            square = [r * cols + c, r * cols + c + 1, (r + 1) * cols + c + 1, (r + 1) * cols + c]  # CCW
            out += [(square[k], square[(k + 1) % 4], square[(k + 3) % 4]) for k in range(4)]
    return np.array(out, dtype=np.int64)


def ref_key(window, shape, symmetric, labels):
    """The key by its definition: shape, then the labels in order (smallest rotation if symmetric)."""
    t = tuple(int(labels[v]) for v in window)
    if symmetric[shape]:
        t = min(t, t[1:] + t[:1], t[2:] + t[:2])
    return (int(shape),) + t


def ref_conflicts(windows, shape, symmetric, labels):
    """Windows whose key another window shares, by a dict of reference keys."""
    seen = {}
    for m, win in enumerate(windows):
        seen.setdefault(ref_key(win, shape[m], symmetric, labels), []).append(m)
    return sorted(m for ms in seen.values() if len(ms) > 1 for m in ms)


@st.composite
def instances(draw, max_n=9, max_windows=40):
    """Random windows (distinct luminaire sets), shape classes, symmetry flags."""
    n = draw(st.integers(3, max_n))
    triples = draw(st.lists(st.permutations(range(n)).map(lambda p: tuple(p[:3])), min_size=1,
                            max_size=max_windows, unique_by=lambda t: frozenset(t)))
    S = draw(st.integers(1, 3))
    shape = np.array(draw(st.lists(st.integers(0, S - 1), min_size=len(triples), max_size=len(triples))))
    symmetric = np.array(draw(st.lists(st.booleans(), min_size=S, max_size=S)))
    return n, np.array(triples, dtype=np.int64), shape, symmetric


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(), st.integers(1, 6), st.data())
def test_keys_equal_iff_reference_keys_equal(inst, K, data):
    n, w, shape, sym = inst
    labels = np.array(data.draw(st.lists(st.integers(0, K - 1), min_size=n, max_size=n)))
    codes = window_keys(w, shape, sym, labels, K)
    assert codes.dtype == np.int64
    ref = [ref_key(win, shape[m], sym, labels) for m, win in enumerate(w)]
    for a in range(len(w)):
        for b in range(len(w)):
            assert (codes[a] == codes[b]) == (ref[a] == ref[b])
    assert conflicting_windows(w, shape, sym, labels, K).tolist() == ref_conflicts(w, shape, sym, labels)


def test_constructed_collision_is_detected():
    w = np.array([(0, 1, 2), (3, 4, 5), (0, 4, 2), (1, 3, 5)])
    shape, sym = np.array([0, 0, 1, 0]), np.array([False, False])
    labels = np.array([7, 1, 2, 7, 1, 2])  # windows 0 and 1 read (7, 1, 2); window 2 is another shape
    assert count_conflicts(w, shape, sym, labels, 8) == 1
    assert conflicting_windows(w, shape, sym, labels, 8).tolist() == [0, 1]
    labels[3] = 6
    assert count_conflicts(w, shape, sym, labels, 8) == 0
    assert conflicting_windows(w, shape, sym, labels, 8).tolist() == []
    # three windows on one key are three conflicting pairs
    assert count_conflicts(w[[0, 1, 3]], [0, 0, 0], [False], [1, 1, 1, 1, 1, 1], 2) == 3


def test_keys_of_many_shapes_and_labels_do_not_overflow():
    w = np.array([(0, 1, 2), (3, 4, 5), (0, 4, 2), (2, 1, 0)])
    labels = np.array([5, 199_999, 7, 5, 199_999, 7])  # K^3 = 8e15: 10,000 shapes would overflow
    shape, sym = np.array([0, 0, 9999, 9998]), np.zeros(10_000, bool)
    sym[9998] = True
    codes = window_keys(w, shape, sym, labels, 200_000)
    assert codes[0] == codes[1] and len(set(codes.tolist())) == 3
    assert conflicting_windows(w, shape, sym, labels, 200_000).tolist() == [0, 1]


def test_symmetric_shapes_compare_rotations():
    w = np.array([(0, 1, 2), (3, 4, 5)])
    labels = np.array([1, 2, 3, 2, 3, 1])  # the second reads the first rotated by one vertex
    assert count_conflicts(w, [0, 0], [True], labels, 4) == 1
    assert count_conflicts(w, [0, 0], [False], labels, 4) == 0
    mirrored = np.array([1, 2, 3, 1, 3, 2])  # reversed cyclic order is another reading
    assert count_conflicts(w, [0, 0], [True], mirrored, 4) == 0


def test_lower_bound_counting():
    for (rows, cols), k in {(4, 8): 5, (16, 32): 13, (100, 100): 34}.items():
        w = l_windows(rows, cols)
        assert len(w) == 4 * (rows - 1) * (cols - 1)
        assert lower_bound_labels(np.zeros(len(w), int), [False]) == k
    assert len(l_windows(16, 32)) == 1860
    # necklaces: K labels give (K^3 + 2K)/3 keys: 2 -> 4, 3 -> 11
    assert lower_bound_labels([0] * 4, [True]) == 2
    assert lower_bound_labels([0] * 5, [True]) == 3
    assert lower_bound_labels([0] * 8, [False]) == 2 and lower_bound_labels([0] * 9, [False]) == 3
    assert lower_bound_labels([0] * 8 + [1] * 11, [False, True]) == 3  # the largest class decides
    assert lower_bound_labels([], [False]) == 1 and lower_bound_labels([0], [False]) == 1


def test_16x32_l_windows_in_4_bits():
    w = l_windows(16, 32)
    shape, sym = np.zeros(len(w), int), np.array([False])
    labels = search_labels(512, w, shape, sym, 16, seed=0, max_steps=100_000)
    assert labels is not None and labels.min() >= 0 and labels.max() < 16
    assert ref_conflicts(w, shape, sym, labels) == []
    code = assign_window_code(512, w, shape, sym, seed=0)
    assert (code.K, code.bits, code.lower_bound_labels, code.lower_bound_bits, code.optimal) == (16, 4, 13, 4, True)
    assert ref_conflicts(w, shape, sym, code.labels) == []


def test_repair_after_new_windows():
    w = l_windows(12, 12)
    shape, sym = np.zeros(len(w), int), np.array([False, False])
    labels = search_labels(144, w, shape, sym, 16, seed=1)
    assert labels is not None
    # verification found straight triples too (another shape): continue from the labels
    straight = np.array([(r * 12 + c, r * 12 + c + 1, r * 12 + c + 2) for r in range(12) for c in range(10)])
    w2, shape2 = np.vstack([w, straight]), np.concatenate([shape, np.ones(len(straight), int)])
    labels[:20] = 0  # and some labels were lost
    assert count_conflicts(w2, shape2, sym, labels, 16) > 0
    fixed = repair_labels(labels, 144, w2, shape2, sym, 16, seed=0)
    assert fixed is not None and ref_conflicts(w2, shape2, sym, fixed) == []
    with pytest.raises(ValueError):
        repair_labels(labels, 144, w2, shape2, sym, 8, seed=0)  # labels beyond K


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(), st.integers(1, 5), st.integers(0, 3))
def test_search_results_are_valid(inst, K, seed):
    n, w, shape, sym = inst
    labels = search_labels(n, w, shape, sym, K, seed=seed, max_steps=300)
    if labels is not None:
        assert labels.shape == (n,) and labels.min() >= 0 and labels.max() < K
        assert ref_conflicts(w, shape, sym, labels) == []
    if K < lower_bound_labels(shape, sym):
        assert labels is None


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(max_n=8, max_windows=25), st.integers(0, 2))
def test_assign_is_valid_and_within_bounds(inst, seed):
    n, w, shape, sym = inst
    code = assign_window_code(n, w, shape, sym, seed=seed, time_budget=0.5)
    assert code.K == 2 ** code.bits and code.bits >= code.lower_bound_bits
    assert code.lower_bound_labels == lower_bound_labels(shape, sym) <= code.K
    assert ref_conflicts(w, shape, sym, code.labels) == []
    assert code.labels.min() >= 0 and code.labels.max() < code.K
    if code.bits == code.lower_bound_bits:
        assert code.optimal


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(), st.integers(1, 4), st.integers(0, 60), st.integers(0, 3))
def test_incremental_counts_are_exact(inst, K, steps, seed):
    n, w, shape, sym = inst  # the search's own pair count must match a recount
    labels = np.random.default_rng(seed).integers(0, K, n)
    pairs = wc._focused_search(wc._Problem(n, w, shape, sym, K), labels, np.random.default_rng(seed), steps)
    assert pairs == count_conflicts(w, shape, sym, labels, K)


@pytest.mark.slow
def test_deterministic_and_dict_counts_agree(monkeypatch):
    w = l_windows(8, 10)  # 252 windows in 8 labels (512 keys): some thousand steps
    shape, sym = np.zeros(len(w), int), np.array([False])
    a = search_labels(80, w, shape, sym, 8, seed=3, max_steps=50_000)
    b = search_labels(80, w, shape, sym, 8, seed=3, max_steps=50_000)
    assert a is not None and np.array_equal(a, b)
    assert not np.array_equal(a, search_labels(80, w, shape, sym, 8, seed=4, max_steps=50_000))
    c = assign_window_code(80, w, shape, sym, seed=3, time_budget=2)
    assert np.array_equal(c.labels, assign_window_code(80, w, shape, sym, seed=3, time_budget=2).labels)
    monkeypatch.setattr(wc, "DENSE_MAX", 0)  # the dict counter must make the same moves
    assert np.array_equal(a, search_labels(80, w, shape, sym, 8, seed=3, max_steps=50_000))


def test_symmetric_search():
    # a triangular lattice: every unit triangle equilateral, one symmetric shape class
    R = C = 12
    w = [(r * C + c, r * C + c + 1, (r + 1) * C + c) for r in range(R - 1) for c in range(C - 1)]
    w += [(r * C + c + 1, (r + 1) * C + c + 1, (r + 1) * C + c) for r in range(R - 1) for c in range(C - 1)]
    w, shape, sym = np.array(w), np.zeros(len(w), int), np.array([True])
    code = assign_window_code(R * C, w, shape, sym, seed=0)
    assert code.lower_bound_labels == 9 and code.bits == 4  # 242 windows; 8 labels give 176 necklaces, 9 249
    assert ref_conflicts(w, shape, sym, code.labels) == []


def test_cpsat_proves_and_finds():
    # three windows share luminaires 0 and 1 in the same places: 2, 3, 4 need distinct labels
    w, shape, sym = np.array([(0, 1, 2), (0, 1, 3), (0, 1, 4)]), np.zeros(3, int), np.array([False])
    assert lower_bound_labels(shape, sym) == 2
    assert cpsat_window_labels(5, w, shape, sym, 2, seed=0, time_budget=2)[:2] == (None, True)
    labels, proved, _ = cpsat_window_labels(5, w, shape, sym, 3, seed=0, time_budget=2)
    assert not proved and ref_conflicts(w, shape, sym, labels) == []
    assert search_labels(5, w, shape, sym, 2, seed=0, max_steps=200) is None
    code = assign_window_code(5, w, shape, sym, seed=0, time_budget=2)
    assert (code.bits, code.lower_bound_bits, code.optimal) == (2, 1, True)  # 1 bit proved infeasible
    hexes = [(0, 1, 2), (3, 4, 5)]  # symmetric shapes in the model: rotations collide
    labels, _, _ = cpsat_window_labels(6, hexes, [0, 0], [True], 2, seed=0, time_budget=2)
    assert ref_conflicts(hexes, [0, 0], [True], labels) == []


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(max_n=6, max_windows=12), st.integers(1, 3))
def test_cpsat_agrees_with_brute_force(inst, K):
    n, w, shape, sym = inst
    feasible = any(not ref_conflicts(w, shape, sym, lab) for lab in itertools.product(range(K), repeat=n))
    labels, proved, _ = cpsat_window_labels(n, w, shape, sym, K, seed=0, time_budget=5)
    assert (labels is not None, proved) == (feasible, not feasible)
    if feasible:
        assert ref_conflicts(w, shape, sym, labels) == []


def test_bad_input():
    with pytest.raises(ValueError):
        window_keys([(0, 0, 1)], [0], [False], [0, 0], 2)
    with pytest.raises(ValueError):
        assign_window_code(3, [(0, 1, 2), (1, 2, 0)], [0, 0], [True])
    with pytest.raises(ValueError):
        search_labels(2, [(0, 1, 2)], [0], [False], 2)


def ref_passive_pairs(windows, shape, symmetric, labels, active):
    """Pairs of triples with one key where at least one is active, by brute force."""
    keys = [ref_key(win, shape[m], symmetric, labels) for m, win in enumerate(windows)]
    return sum(1 for a, b in itertools.combinations(range(len(keys)), 2)
               if keys[a] == keys[b] and (active[a] or active[b]))


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(), st.integers(1, 4), st.integers(0, 60), st.integers(0, 3), st.data())
def test_passive_triples_pair_only_with_active_ones(inst, K, steps, seed, data):
    n, w, shape, sym = inst
    active = np.array(data.draw(st.lists(st.booleans(), min_size=len(w), max_size=len(w))))
    labels = np.random.default_rng(seed).integers(0, K, n)
    assert count_conflicts(w, shape, sym, labels, K, active) == ref_passive_pairs(w, shape, sym, labels, active)
    hot = conflicting_windows(w, shape, sym, labels, K, active).tolist()
    keys = [ref_key(win, shape[m], sym, labels) for m, win in enumerate(w)]
    assert hot == [m for m in range(len(w)) if any(keys[m] == keys[o] and (active[m] or active[o])
                                                   for o in range(len(w)) if o != m)]
    pairs = wc._focused_search(wc._Problem(n, w, shape, sym, K, active), labels, np.random.default_rng(seed), steps)
    assert pairs == count_conflicts(w, shape, sym, labels, K, active)  # the incremental count stays exact


def test_passive_triples_need_fewer_labels_than_windows():
    # One shape: 2 windows and 30 passive triples through luminaires 0..5. With K = 2 labels
    # 8 keys exist, so 32 windows could never be distinct; 2 windows avoiding 30 passives can.
    rng = np.random.default_rng(0)
    w = np.array([(0, 1, 2), (3, 4, 5)] + [tuple(rng.choice(np.arange(6, 40), 3, replace=False)) for _ in range(30)])
    w = w[np.unique(np.sort(w, axis=1), axis=0, return_index=True)[1]]
    active = np.array([set(t) <= set(range(6)) for t in w.tolist()])
    shape, sym = np.zeros(len(w), int), np.array([False])
    code = assign_window_code(40, w, shape, sym, seed=0, time_budget=1, active=active)
    assert count_conflicts(w, shape, sym, code.labels, code.K, active) == 0
    assert code.bits == 1 and lower_bound_labels(shape, sym, active) == 2
    assert count_conflicts(w, shape, sym, code.labels, code.K) > 0  # passives do share keys among themselves
