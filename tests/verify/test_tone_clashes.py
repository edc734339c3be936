"""planner.verify.tones: the pairs of one tone class that share a sampled window, and where."""

import numpy as np

from planner.verify.tones import shared_windows, tone_clashes


def test_clashes_count_seen_windows_only_and_say_where():
    windows = np.array([[0, 1, 2], [1, 0, 3], [2, 3, 0], [3, 4, 0]])
    seen = np.array([True, True, True, False])
    classes = np.array([1, 1, 2, 3, 3])
    positions = np.array([[0.0, 0.0, 1.0], [2.0, 1.0, 1.0], [5.0, 5.0, 1.0], [9.0, 9.0, 1.0]])
    clashes = tone_clashes(windows, seen, classes, positions)
    assert [(c.a, c.b, c.poses) for c in clashes] == [(0, 1, 2)]  # (3, 4) share only pose 3's window, not seen
    c = clashes[0]
    assert c.centre_xy == (1.0, 0.5) and c.low_xy == (0.0, 0.0) and c.high_xy == (2.0, 1.0)


def test_two_led_windows_and_most_poses_first():
    windows = np.array([[0, 1], [2, 3], [2, 3], [0, 2]])
    seen = np.ones(4, dtype=bool)
    classes = np.array([1, 1, 2, 2])
    clashes = tone_clashes(windows, seen, classes, np.zeros((4, 3)))
    assert [(c.a, c.b, c.poses) for c in clashes] == [(2, 3, 2), (0, 1, 1)]


def test_no_clash_among_distinct_classes():
    windows = np.array([[0, 1, 2]])
    assert tone_clashes(windows, np.array([True]), np.array([1, 2, 3]), np.zeros((1, 3))) == []


def test_shared_windows():
    windows = np.array([[0, 1, 2], [2, 3, 4], [0, 3, 4]])
    out = shared_windows(windows, np.array([True, True, False]), 6)
    assert out == [{1, 2}, {0, 2}, {0, 1, 3, 4}, {2, 4}, {2, 3}, set()]
