"""Tone clashes: two luminaires of tones the camera cannot tell apart, seen in one window (docs/tones.md).

A tone receiver names each LED it sees by its tone. Where a window holds two LEDs of one tone
class (:func:`planner.modulation.tones.tone_classes`), it cannot tell which is which: the pose
is ambiguous there for that receiver, whatever the window's shape says. The clashes are found
over the plan's sampled poses (a sample, and labelled so).
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

import numpy as np


@dataclass(frozen=True)
class ToneClash:
    """Luminaires ``a < b`` (indices) of one tone class that share the window of ``poses`` sampled poses, whose
    camera positions span ``low_xy``..``high_xy`` around ``centre_xy`` [m]."""

    a: int
    b: int
    poses: int
    centre_xy: tuple[float, float]
    low_xy: tuple[float, float]
    high_xy: tuple[float, float]


def tone_clashes(windows: np.ndarray, seen: np.ndarray, classes: np.ndarray, positions: np.ndarray) -> list[ToneClash]:
    """The clashes among sampled windows, most poses first.

    ``windows`` (P, k) luminaire indices of each pose's window, ``seen`` (P,) whether the pose sees one,
    ``classes`` (N,) tone classes, ``positions`` (P, 3) camera positions [m].
    """
    windows = np.asarray(windows, dtype=np.int64).reshape(len(seen), -1)
    pairs, rows = [], []
    for i, j in combinations(range(windows.shape[1]), 2):
        hit = np.flatnonzero(seen & (classes[windows[:, i]] == classes[windows[:, j]]))
        pairs.append(np.sort(windows[hit][:, [i, j]], axis=1))
        rows.append(hit)
    pair = np.concatenate(pairs) if pairs else np.empty((0, 2), dtype=np.int64)
    row = np.concatenate(rows) if rows else np.empty(0, dtype=np.int64)
    out = []
    for a, b in np.unique(pair, axis=0):
        xy = positions[row[(pair[:, 0] == a) & (pair[:, 1] == b)], :2]
        lo, hi, mid = xy.min(axis=0), xy.max(axis=0), xy.mean(axis=0)
        out.append(ToneClash(int(a), int(b), len(xy), (float(mid[0]), float(mid[1])), (float(lo[0]), float(lo[1])),
                             (float(hi[0]), float(hi[1]))))
    return sorted(out, key=lambda c: (-c.poses, c.a, c.b))


def shared_windows(windows: np.ndarray, seen: np.ndarray, n: int) -> list[set[int]]:
    """For each of ``n`` luminaires, the others that share a sampled window with it."""
    out: list[set[int]] = [set() for _ in range(n)]
    for w in np.unique(np.sort(np.asarray(windows, dtype=np.int64)[seen], axis=1), axis=0):
        for v in w:
            out[int(v)].update(int(u) for u in w if u != v)
    return out
