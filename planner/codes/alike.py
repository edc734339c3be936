"""The pairs that must differ, for irregular sites with tens of millions of them: listed and searched in numba.

:mod:`planner.codes.pairwise` lists every (window, triple) pair that reads alike under equal labels
with a KD-tree and indexes each luminaire's six places in them: about 250 bytes and 5 us per pair,
so the hexagonal and jittered sites of issue 34 (49 and 42 million pairs) took 10-12 GB and 3-5
minutes to list. The groups of :mod:`planner.codes.classes` avoid the listing on lattices, where
congruent triples form cliques, but on an irregular site the shapes form a continuum and chain
into a few huge groups (the jittered site: 4 groups, over the tables' budget). Here the same pairs
are found by a grid over side lengths (cells as wide as the tolerance, 27 cells per window) and kept
from both of their triples as slots of the other triple and its luminaires in this one's reading order
(10 bytes a slot). A luminaire's cost of each label is counted from the slots of the triples that hold it. The conflicts are exactly
those of :func:`planner.verify.rivals.find_rivals` against the same windows and triples.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from planner.verify.rivals import counter_clockwise, sides

PAIR_BUDGET = 150_000_000
"""Most pairs listed (about 17 bytes each, so 2.6 GB at most)."""


@njit(cache=True)
def _scan(wsides, ukeys, starts, esides, etriple, eturn, nwin, tol, strides, out_w, out_t, out_r, count_only):
    """Pairs (window w, triple t, turn r) with t's sides turned by r within ``tol`` of w's; t != w, and
    t > w when t is a window too (each pair once). Returns how many; fills ``out_*`` unless counting."""
    n = 0
    for w in range(len(wsides)):
        s0, s1, s2 = wsides[w, 0], wsides[w, 1], wsides[w, 2]
        c0, c1, c2 = np.floor(s0 / tol), np.floor(s1 / tol), np.floor(s2 / tol)
        for d0 in range(-1, 2):
            for d1 in range(-1, 2):
                for d2 in range(-1, 2):
                    key = int(c0 + d0) * strides[0] + int(c1 + d1) * strides[1] + int(c2 + d2)
                    at = np.searchsorted(ukeys, key)
                    if at >= len(ukeys) or ukeys[at] != key:
                        continue
                    for e in range(starts[at], starts[at + 1]):
                        t = etriple[e]
                        if t == w or (t < nwin and t < w):
                            continue
                        if (abs(esides[e, 0] - s0) <= tol and abs(esides[e, 1] - s1) <= tol
                                and abs(esides[e, 2] - s2) <= tol):
                            if not count_only:
                                out_w[n], out_t[n], out_r[n] = w, t, eturn[e]
                            n += 1
    return n


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


def _csr(owner: np.ndarray, size: int, items: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    order = np.argsort(owner, kind="stable")
    return np.searchsorted(owner[order], np.arange(size + 1)).astype(np.int64), items[order].astype(np.int32)


class AlikeIndex:
    """Every pair (window, triple of the site) that reads alike under equal labels, as the protocol of
    :func:`planner.codes.pairwise.search` takes it: a unit is a triple, in conflict when it reads like
    another. Build with :meth:`build`."""

    def __init__(self, n: int, T: np.ndarray, pw: np.ndarray, pt: np.ndarray, pr: np.ndarray):
        self.n, self.T, self.pairs = n, T, len(pw)
        self.lum_start, self.lum_triples = _csr(T.reshape(-1), n, np.repeat(np.arange(len(T)), 3))
        self.ys = np.empty((2 * len(pw), 3), np.int16 if n < 2 ** 15 else np.int32)
        self.start, self.other = _slots(T, pw, pt, pr, self.ys)
        self._all = np.arange(len(T), dtype=np.int64)

    @classmethod
    def build(cls, windows: np.ndarray, matches: np.ndarray, xyz: np.ndarray, tolerance_m: float,
              budget: int | None = None) -> AlikeIndex | None:
        """The index of ``windows`` against themselves and ``matches`` (the site's triples within the tolerance
        of a window, :func:`planner.verify.rivals.shape_matches`); None when more than ``budget`` pairs
        (default :data:`PAIR_BUDGET`)."""
        xy = xyz[:, :2]
        win = counter_clockwise(np.unique(np.sort(np.asarray(windows, np.int64).reshape(-1, 3), axis=1), axis=0), xy)
        other = counter_clockwise(np.asarray(matches, np.int64).reshape(-1, 3), xy)
        other = other[~rows_in(np.sort(other, axis=1), np.sort(win, axis=1))]
        other = other[np.unique(np.sort(other, axis=1), axis=0, return_index=True)[1]]
        T = np.ascontiguousarray(np.vstack([win, other]).astype(np.int32))
        tol = tolerance_m + 1e-9
        es = np.stack([sides(np.roll(T, -r, axis=1), xyz) for r in range(3)], axis=1).reshape(-1, 3)
        cells = np.floor(es / tol).astype(np.int64)
        span = int(cells.max()) + 3
        strides = np.array([span * span, span], np.int64)
        key = cells[:, 0] * strides[0] + cells[:, 1] * strides[1] + cells[:, 2]
        order = np.argsort(key, kind="stable")
        ukeys, starts = np.unique(key[order], return_index=True)
        starts = np.append(starts, len(order)).astype(np.int64)
        esides = np.ascontiguousarray(es[order])
        etriple, eturn = order // 3, (order % 3).astype(np.int8)  # entry t * 3 + r: triple t turned by r
        wsides = np.ascontiguousarray(sides(win, xyz))
        args = (wsides, ukeys, starts, esides, etriple, eturn, len(win), tol, strides)
        empty = np.empty(0, np.int32)
        count = _scan(*args, empty, empty, np.empty(0, np.int8), True)
        if count > (PAIR_BUDGET if budget is None else budget):
            return None
        pw, pt, pr = np.empty(count, np.int32), np.empty(count, np.int32), np.empty(count, np.int8)
        _scan(*args, pw, pt, pr, False)
        return cls(len(xyz), T, pw, pt, pr)

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


def rows_in(rows: np.ndarray, among: np.ndarray) -> np.ndarray:
    """Whether each sorted row of ``rows`` is a row of ``among`` (both (M, 3) int)."""
    if len(among) == 0 or len(rows) == 0:
        return np.zeros(len(rows), bool)
    big = int(max(rows.max(), among.max())) + 1
    code = lambda r: (r[:, 0] * big + r[:, 1]) * big + r[:, 2]  # noqa: E731
    return np.isin(code(rows), code(among))
