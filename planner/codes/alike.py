"""Listed pairs of triples that must differ, held compactly and searched in numba.

:mod:`planner.codes.pairwise` indexes each luminaire's six places in every listed pair: about 250
bytes and 5 us per pair, so the hexagonal and jittered sites of issue 34 (49 and 42 million pairs)
took 10-12 GB and 3-5 minutes. Here a pair (window w, triple t, turn r: t's sides turned by r within
the tolerance of w's) is kept from both of its triples as a slot of the other triple and its
luminaires in this one's reading order (10 bytes a slot), and a luminaire's cost of each label is
counted from the slots of the triples that hold it. :mod:`planner.codes.readings` lists here the
pairs whose triples share a luminaire and finds the others by their labels.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from planner.codes.pairwise import distinct
from planner.verify.rivals import counter_clockwise

PAIR_BUDGET = 150_000_000
"""Most pairs listed (about 20 bytes each, so 3 GB at most)."""


@njit(cache=True)
def _slots(T, pw, pt, pr, ys):
    """Each triple's pairs from its own side (CSR over the triples): the other triple, and its members in
    the order this triple's places read against them (``ys``, filled: (2P, 3))."""
    m = len(T)
    start = np.zeros(m + 1, np.int64)
    for p in range(len(pw)):
        start[pw[p] + 1] += 1
        start[pt[p] + 1] += 1
    for q in range(m):
        start[q + 1] += start[q]
    fill = start[:-1].copy()
    other = np.empty(start[m], np.int32)
    for p in range(len(pw)):
        w, t, r = pw[p], pt[p], pr[p]
        at = fill[w]
        other[at] = t
        for j in range(3):
            ys[at, j] = T[t, (j + r) % 3]
        fill[w] += 1
        at = fill[t]
        other[at] = w
        for j in range(3):
            ys[at, j] = T[w, (j + 3 - r) % 3]
        fill[t] += 1
    return start, other


@njit(cache=True)
def _need(i, lab, q0, q1, q2, u0, u1, u2):
    """For two triples read place by place (``q`` against ``u``) and luminaire ``i``: -2 if they cannot read
    alike whatever ``i``'s label, -1 if they do whatever it is, else the one label of ``i`` that makes them."""
    need = -1
    for x, y in ((q0, u0), (q1, u1), (q2, u2)):
        if x == i and y == i:
            continue
        if x == i:
            v = lab[y]
        elif y == i:
            v = lab[x]
        elif lab[x] != lab[y]:
            return -2
        else:
            continue
        if need == -1:
            need = v
        elif need != v:
            return -2
    return need


@njit(cache=True)
def _cost(T, lum_start, lum_triples, start, other, ys, i, lab, K, moved):
    """Pairs in conflict for each label 0..K-1 of luminaire ``i`` (K,); with ``moved``, instead the triples
    holding ``i`` that read like another under ``lab`` (:meth:`AlikeIndex.moved`)."""
    out = np.zeros(K, np.int64)
    found = np.empty(lum_start[i + 1] - lum_start[i], np.int64)
    n = 0
    for a in range(lum_start[i], lum_start[i + 1]):
        q = lum_triples[a]
        q0, q1, q2 = T[q, 0], T[q, 1], T[q, 2]
        j = 0 if q0 == i else (1 if q1 == i else 2)  # i's place in q (once: a triple's members differ)
        j1, j2 = (j + 1) % 3, (j + 2) % 3
        l1, l2 = lab[T[q, j1]], lab[T[q, j2]]
        for b in range(start[q], start[q + 1]):
            y1 = ys[b, j1]  # most pairs differ in a place without i: skip them first
            if y1 != i and lab[y1] != l1:
                continue
            y2 = ys[b, j2]
            if y2 != i and lab[y2] != l2:
                continue
            u0, u1, u2 = ys[b, 0], ys[b, 1], ys[b, 2]
            if (u0 == i or u1 == i or u2 == i) and other[b] < q:
                continue  # both hold i: counted from the lower triple
            need = _need(i, lab, q0, q1, q2, u0, u1, u2)
            if need == -2:
                continue
            if moved:
                if need == -1 or need == lab[i]:
                    found[n] = q
                    n += 1
                    break
            elif need == -1:
                out += 1
            else:
                out[need] += 1
    return out, found[:n]


@njit(cache=True)
def _conflicts(T, start, other, ys, lab, only):
    """Pairs in conflict under ``lab`` (each once) and the triples in one, among the triples ``only``."""
    total = 0
    bad = np.empty(len(only), np.int64)
    n = 0
    for q in only:
        hit = False
        for b in range(start[q], start[q + 1]):
            if lab[T[q, 0]] == lab[ys[b, 0]] and lab[T[q, 1]] == lab[ys[b, 1]] and lab[T[q, 2]] == lab[ys[b, 2]]:
                hit = True
                if other[b] > q:
                    total += 1
        if hit:
            bad[n] = q
            n += 1
    return total, bad[:n]


def holding(T: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The triples (rows of ``T``) holding each of the ``n`` luminaires, as CSR: starts (n + 1,), triples."""
    owner = T.reshape(-1)
    order = np.argsort(owner, kind="stable")
    return np.searchsorted(owner[order], np.arange(n + 1)).astype(np.int64), (order // 3).astype(np.int32)


class AlikeIndex:
    """Listed pairs (rows ``pw``, ``pt`` of the triples ``T`` and turn ``pr``) that read alike under equal labels,
    as the protocol of :func:`planner.codes.pairwise.search` takes them: a unit is a triple, in conflict
    when it reads like another; ``lum`` the triples holding each luminaire (:func:`holding`), if known."""

    def __init__(self, n: int, T: np.ndarray, pw: np.ndarray, pt: np.ndarray, pr: np.ndarray,
                 lum: tuple[np.ndarray, np.ndarray] | None = None):
        self.n, self.T, self.pairs = n, T, len(pw)
        self.lum_start, self.lum_triples = lum or holding(T, n)
        self.ys = np.empty((2 * len(pw), 3), np.int16 if n < 2 ** 15 else np.int32)
        self.start, self.other = _slots(T, pw, pt, pr, self.ys)
        self._all = np.arange(len(T), dtype=np.int64)

    # The protocol of :func:`planner.codes.pairwise.search`.

    def begin(self, lab: np.ndarray) -> tuple[int, list[int]]:
        total, bad = _conflicts(self.T, self.start, self.other, self.ys, lab, self._all)
        return int(total), bad.tolist()

    def cost(self, i: int, lab: np.ndarray, K: int) -> np.ndarray:
        return _cost(self.T, self.lum_start, self.lum_triples, self.start, self.other, self.ys, i, lab, K,
                     False)[0]

    def holders(self, unit: int, lab: np.ndarray) -> np.ndarray:
        """The triple's luminaires and those of the triples it reads like."""
        ys = self.ys[self.start[unit]:self.start[unit + 1]]
        alike = (lab[self.T[unit]][None, :] == lab[ys]).all(axis=1)
        return np.unique(np.concatenate([self.T[unit], ys[alike].reshape(-1)]))

    def in_conflict(self, unit: int, lab: np.ndarray) -> bool:
        return len(_conflicts(self.T, self.start, self.other, self.ys, lab, np.array([unit]))[1]) > 0

    def moved(self, i: int, old: int, lab: np.ndarray) -> list[int]:
        return _cost(self.T, self.lum_start, self.lum_triples, self.start, self.other, self.ys, i, lab, 1,
                     True)[1].tolist()


def triples(windows: np.ndarray, matches: np.ndarray, xyz: np.ndarray) -> tuple[np.ndarray, int]:
    """The distinct ``windows`` then the ``matches`` that are not windows, each once (the first met), both in the
    order of their sorted members, counter-clockwise ((M, 3) int32); and how many of them are windows."""
    xy, n = xyz[:, :2], len(xyz)

    def code(rows: np.ndarray) -> np.ndarray:
        r = np.sort(rows, axis=1)
        return (r[:, 0] * n + r[:, 1]) * n + r[:, 2]

    held = distinct(code(np.asarray(windows, np.int64).reshape(-1, 3)))
    win = counter_clockwise(np.column_stack([held // (n * n), held // n % n, held % n]), xy)
    other = np.asarray(matches, np.int64).reshape(-1, 3)
    key = code(other)
    at = np.searchsorted(held, key).clip(max=max(len(held) - 1, 0))
    fresh = held[at] != key if len(held) else np.ones(len(key), bool)
    order = np.flatnonzero(fresh)[np.argsort(key[fresh], kind="stable")]
    first = np.r_[True, key[order[1:]] != key[order[:-1]]] if len(order) else np.zeros(0, bool)
    other = counter_clockwise(other[order[first]], xy)
    return np.ascontiguousarray(np.vstack([win, other]).astype(np.int32)), len(win)


def rows_in(rows: np.ndarray, among: np.ndarray) -> np.ndarray:
    """Whether each sorted row of ``rows`` is a row of ``among`` (both (M, 3) int)."""
    if len(among) == 0 or len(rows) == 0:
        return np.zeros(len(rows), bool)
    big = int(max(rows.max(), among.max())) + 1
    code = lambda r: (r[:, 0] * big + r[:, 1]) * big + r[:, 2]  # noqa: E731
    return np.isin(code(rows), code(among))
