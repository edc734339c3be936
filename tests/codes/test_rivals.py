"""Rivals: every physical triple of the site that reads like a window, checked by brute force."""
import itertools

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import grid_xy
from planner.verify import rivals
from planner.verify.rivals import find_rivals, shape_matches, site_triples


def ccw(triples, xy):
    """Each row of ``triples`` (M, 3) counter-clockwise in plan (its last two swapped where clockwise)."""
    a, b, c = (xy[triples[:, k]] for k in range(3))
    cw = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]) < 0
    out = triples.copy()
    out[cw, 1], out[cw, 2] = triples[cw, 2], triples[cw, 1]
    return out


def reads_like(t, us, xy, ids, tol):
    """For each row u of ``us`` (M, 3): the same IDs counter-clockwise as the triple ``t`` and corresponding sides
    within tol (plus 1 nm for rounding), for some rotation of u."""
    t, us = ccw(np.array([t]), xy), ccw(np.asarray(us), xy)

    def sides(x):  # side k runs from x[k] to x[k + 1]
        return np.linalg.norm(xy[np.roll(x, -1, axis=1)] - xy[x], axis=2)

    side_t, side_u = sides(t), sides(us)
    hit = np.zeros(len(us), dtype=bool)
    for r in range(3):  # u rotated to start at its r-th vertex
        v, side_v = np.roll(us, -r, axis=1), np.roll(side_u, -r, axis=1)
        hit |= (ids[t] == ids[v]).all(axis=1) & (np.abs(side_t - side_v) <= tol + 1e-9).all(axis=1)
    return hit


sites = st.builds(lambda rows, cols, jitter, seed: grid_xy(rows, cols, 0.5, 0.5, jitter_m=jitter, seed=seed),
                  st.integers(2, 5), st.integers(2, 6), st.floats(0, 0.1), st.integers(0, 100))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(sites, st.floats(0.3, 1.6))
def test_site_triples_are_all_short_triples(xy, r):
    got = {tuple(t) for t in site_triples(xy, r).tolist()}
    d = np.linalg.norm(xy[:, None] - xy[None], axis=2)
    want = {t for t in itertools.combinations(range(len(xy)), 3)
            if d[t[0], t[1]] <= r and d[t[1], t[2]] <= r and d[t[0], t[2]] <= r}
    assert got == want


@pytest.mark.slow
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(sites, st.integers(1, 4), st.floats(0.0, 0.12), st.integers(0, 100))
def test_rivals_are_every_triple_that_reads_alike(xy, k, tol, seed):
    rng = np.random.default_rng(seed)
    ids = rng.integers(1, k + 1, len(xy))
    xyz = np.column_stack([xy, np.full(len(xy), 2.5)])
    windows = np.array(list(itertools.combinations(range(len(xy)), 3)))
    windows = windows[rng.random(len(windows)) < 0.3][:25]
    got = {(w, frozenset(t)) for w, t in find_rivals(windows, xyz, ids, tol)}
    every = np.array(list(itertools.combinations(range(len(xy)), 3)))
    want = {(m, frozenset(u)) for m, t in enumerate(windows.tolist())
            for u in every[reads_like(t, every, xy, ids, tol) & (every != t).any(axis=1)].tolist()}
    assert got == want


@settings(max_examples=20, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(sites, st.integers(1, 3), st.integers(1, 40), st.integers(0, 100))
def test_rivals_compared_a_few_at_a_time_are_the_same(monkeypatch, xy, k, chunk, seed):
    """The join runs in chunks of at most ``JOIN_CHUNK`` candidate pairs (the 10,000-luminaire site took 15.8 GB
    in one); any chunk size finds the same rivals."""
    ids = np.random.default_rng(seed).integers(1, k + 1, len(xy))
    xyz = np.column_stack([xy, np.full(len(xy), 2.5)])
    windows = site_triples(xy, 1.2)
    whole = find_rivals(windows, xyz, ids, 0.05)
    with monkeypatch.context() as m:
        m.setattr(rivals, "JOIN_CHUNK", chunk)
        assert find_rivals(windows, xyz, ids, 0.05) == whole


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(sites, st.floats(0.0, 0.12), st.integers(0, 100))
def test_shape_matches_are_the_triples_some_labels_could_make_rivals(xy, tol, seed):
    """Each triple of the site that reads like a window under equal IDs, by brute force, and no other."""
    rng = np.random.default_rng(seed)
    xyz = np.column_stack([xy, np.full(len(xy), 2.5)])
    every = np.array(list(itertools.combinations(range(len(xy)), 3)))
    windows = every[rng.random(len(every)) < 0.3][:25].reshape(-1, 3)
    same = np.ones(len(xy), dtype=int)
    got = {frozenset(t) for t in shape_matches(windows, xyz, tol).tolist()}
    want = {frozenset(u) for t in windows.tolist() for u in every[reads_like(t, every, xy, same, tol)].tolist()}
    assert want <= got  # a window reads like itself: the windows are matches too
    assert got <= want | {frozenset(t) for t in windows.tolist()}


def test_a_mirrored_triangle_is_no_rival_but_a_rotated_copy_is():
    xy = np.array([[0, 0], [1, 0], [0, 2], [5, 5], [5, 6], [3, 5], [9, 0], [8, 0], [9, 2]], float)
    xyz = np.column_stack([xy, np.zeros(len(xy))])
    ids = np.array([1, 2, 3, 1, 2, 3, 1, 2, 3])
    # (3, 4, 5) is (0, 1, 2) turned 90 deg; (6, 7, 8) is its mirror image, read clockwise.
    assert [t for _, t in find_rivals(np.array([[0, 1, 2]]), xyz, ids, 0.01)] == [(3, 4, 5)]
