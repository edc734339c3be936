"""The pairs of triples that must differ, too many to list: those sharing a luminaire listed, the rest found by labels.

A pair is a window and another triple of the site whose sides, in one turn, each lie within the
tolerance of the window's (:mod:`planner.codes.pairwise`). On an irregular site a window
is near thousands of triples in shape, all over the site, so the pairs grow with the square of the
site: the 10,000-luminaire site of issue 34 has about a billion. Under given labels only the few that
also read alike matter. Here the pairs whose triples share a luminaire are listed
(:class:`planner.codes.alike.AlikeIndex`; they are local, linear in the site); every other pair is
found when it is needed, in hash tables of the triples (the windows', the others') keyed by their side
cells (:data:`CELL_TOLERANCES` wide) and the labels of two of their places, each triple once per
free place. A luminaire's cost of each label is read from the triples that hold it, one lookup per
rotation and neighbouring cell; a move re-keys the entries of the triples that hold the luminaire.
The conflicts and cost deltas are exactly those of the listed pairs.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from planner.codes import alike
from planner.codes.alike import AlikeIndex, holding, triples
from planner.verify.rivals import sides

EMPTY = -1
"""A free slot of the hash table."""
CELL_TOLERANCES = 2
"""Width of a side cell in tolerances (measured on the jittered 2,040 site: 4 and 8 are slower, their buckets larger)."""


@njit(cache=True)
def _share(T, a, b):
    """Whether triples ``a`` and ``b`` (rows of ``T``) have a luminaire in common."""
    for x in range(3):
        for y in range(3):
            if T[a, x] == T[b, y]:
                return True
    return False


@njit(cache=True)
def _home(key, mask):
    h = np.uint64(key) * np.uint64(0x9E3779B97F4A7C15)
    return np.int64((h ^ (h >> np.uint64(29))) & np.uint64(mask))


@njit(cache=True)
def _find(tkeys, key, mask):
    """The slot holding ``key``, or the free slot where it would go (linear probing)."""
    s = _home(key, mask)
    while tkeys[s] != key and tkeys[s] != EMPTY:
        s = (s + 1) & mask
    return s


@njit(cache=True)
def _key(T, S, u, f, lab, w, strides):
    """Entry (triple ``u``, free place ``f``): its side cells, ``f`` and the labels of its other two places."""
    return (int(S[u, 0] / w) * strides[0] + int(S[u, 1] / w) * strides[1] + int(S[u, 2] / w) * strides[2]
            + f * strides[3] + lab[T[u, (f + 1) % 3]] * strides[4] + lab[T[u, (f + 2) % 3]])


@njit(cache=True)
def _insert(tkeys, thead, nxt, prv, slot, e, key, mask):
    s = _find(tkeys, key, mask)
    if tkeys[s] == EMPTY:
        tkeys[s], thead[s] = key, -1
    h = thead[s]
    nxt[e], prv[e] = h, -1
    if h != -1:
        prv[h] = e
    thead[s], slot[e] = e, s


@njit(cache=True)
def _remove(tkeys, thead, nxt, prv, slot, e, mask):
    """Unlink entry ``e``; an emptied key leaves the table, later keys of its probe run shifted back."""
    s = slot[e]
    if prv[e] != -1:
        nxt[prv[e]] = nxt[e]
    else:
        thead[s] = nxt[e]
    if nxt[e] != -1:
        prv[nxt[e]] = prv[e]
    if thead[s] != -1:
        return
    j = s
    while True:
        j = (j + 1) & mask
        if tkeys[j] == EMPTY:
            break
        h = _home(tkeys[j], mask)
        if (s < j and s < h <= j) or (j < s and (h > s or h <= j)):
            continue  # its home lies after the hole: it stays
        tkeys[s], thead[s] = tkeys[j], thead[j]
        x = thead[s]
        while x != -1:
            slot[x] = s
            x = nxt[x]
        s = j
    tkeys[s], thead[s] = EMPTY, -1


@njit(cache=True)
def _fill(T, S, nwin, lab, w, strides, wkeys, whead, wmask, mkeys, mhead, mmask, nxt, prv, slot):
    """Every entry keyed under ``lab``: the windows' in one table, the other triples' in another."""
    for tkeys, thead in ((wkeys, whead), (mkeys, mhead)):
        tkeys[:] = EMPTY
        thead[:] = -1
    for u in range(len(T)):
        for f in range(3):
            key = _key(T, S, u, f, lab, w, strides)
            if u < nwin:
                _insert(wkeys, whead, nxt, prv, slot, 3 * u + f, key, wmask)
            else:
                _insert(mkeys, mhead, nxt, prv, slot, 3 * u + f, key, mmask)


@njit(cache=True)
def _rekey(i, T, S, nwin, lab, w, strides, lum_start, lum_triples, wkeys, whead, wmask, mkeys, mhead, mmask,
           nxt, prv, slot):
    """Luminaire ``i`` has a new label: move the entries that hold it in a keyed place."""
    for a in range(lum_start[i], lum_start[i + 1]):
        u = np.int64(lum_triples[a])  # int64 everywhere: each kernel compiles for one signature
        for f in range(3):
            if T[u, f] != i:
                e, key = 3 * u + f, _key(T, S, u, f, lab, w, strides)
                if u < nwin:
                    _remove(wkeys, whead, nxt, prv, slot, e, wmask)
                    _insert(wkeys, whead, nxt, prv, slot, e, key, wmask)
                else:
                    _remove(mkeys, mhead, nxt, prv, slot, e, mmask)
                    _insert(mkeys, mhead, nxt, prv, slot, e, key, mmask)


@njit(cache=True)
def _head(tkeys, thead, mask, key):
    s = _find(tkeys, key, mask)
    return thead[s] if tkeys[s] != EMPTY else -1


@njit(cache=True)
def _visit(T, S, q, j, f, r, lab, tol, s0, s1, s2, e, nxt, out, partners, n):
    """The entries of one bucket, from ``e`` on, against triple ``q`` turned by ``r`` (:func:`_remote`)."""
    while e != -1:
        u = e // 3
        if (abs(S[u, 0] - s0) <= tol and abs(S[u, 1] - s1) <= tol and abs(S[u, 2] - s2) <= tol
                and not _share(T, q, u)):
            if j >= 0:
                out[lab[T[u, f]]] += 1
            elif lab[T[u, f]] == lab[T[q, (f + r) % 3]]:
                if n < len(partners):
                    partners[n] = u
                n += 1
                out[0] += 1
                if u > q:
                    out[1] += 1
        e = nxt[e]
    return n


@njit(cache=True)
def _remote(T, S, nwin, q, j, lab, tol, w, strides, wkeys, whead, wmask, mkeys, mhead, mmask, nxt, out, partners):
    """The pairs of triple ``q`` with the triples that share no luminaire with it (a window's with any triple,
    another triple's with the windows).

    ``j`` >= 0: ``out[k]`` counts the pairs that read alike when ``q``'s place ``j`` has label k (the other
    places as labelled). ``j`` < 0: the triples that read like ``q`` under ``lab`` fill ``partners`` (as
    many as fit), ``out[0]`` counts them and ``out[1]`` those after ``q``. Returns how many partners."""
    n = np.int64(0)  # not the literal 0: _visit would compile once more for it
    for r in range(3):  # q turned by r: its place p is T[q, (p + r) % 3], its side p is S[q, (p + r) % 3]
        f = (j - r) % 3 if j >= 0 else 0
        la, lb = lab[T[q, (f + 1 + r) % 3]], lab[T[q, (f + 2 + r) % 3]]
        s0, s1, s2 = S[q, r % 3], S[q, (1 + r) % 3], S[q, (2 + r) % 3]
        rest = f * strides[3] + la * strides[4] + lb
        for c0 in range(int(max(s0 - tol, 0.0) / w), int((s0 + tol) / w) + 1):
            for c1 in range(int(max(s1 - tol, 0.0) / w), int((s1 + tol) / w) + 1):
                for c2 in range(int(max(s2 - tol, 0.0) / w), int((s2 + tol) / w) + 1):
                    key = c0 * strides[0] + c1 * strides[1] + c2 * strides[2] + rest
                    n = _visit(T, S, q, j, f, r, lab, tol, s0, s1, s2, _head(wkeys, whead, wmask, key), nxt, out,
                               partners, n)
                    if q < nwin:
                        n = _visit(T, S, q, j, f, r, lab, tol, s0, s1, s2, _head(mkeys, mhead, mmask, key), nxt,
                                   out, partners, n)
    return n


@njit(cache=True)
def _remote_cost(i, T, S, nwin, lab, K, tol, w, strides, lum_start, lum_triples, wkeys, whead, wmask, mkeys, mhead,
                 mmask, nxt):
    out = np.zeros(K, np.int64)
    none = np.empty(0, np.int64)
    for a in range(lum_start[i], lum_start[i + 1]):
        q = np.int64(lum_triples[a])
        j = 0 if T[q, 0] == i else (1 if T[q, 1] == i else 2)
        _remote(T, S, nwin, q, j, lab, tol, w, strides, wkeys, whead, wmask, mkeys, mhead, mmask, nxt, out, none)
    return out


@njit(cache=True)
def _remote_conflicts(T, S, nwin, lab, tol, w, strides, wkeys, whead, wmask, mkeys, mhead, mmask, nxt, only):
    """Pairs of unshared triples alike under ``lab`` (each once) and the triples of ``only`` in one."""
    total = 0
    bad = np.empty(len(only), np.int64)
    n = 0
    out = np.zeros(2, np.int64)
    none = np.empty(0, np.int64)
    for q in only:
        out[:] = 0
        if _remote(T, S, nwin, q, np.int64(-1), lab, tol, w, strides, wkeys, whead, wmask, mkeys, mhead, mmask, nxt,
                   out, none) > 0:
            bad[n] = q
            n += 1
        total += out[1]
    return total, bad[:n]


@njit(cache=True)
def _shared_pairs(T, S, nwin, lum_start, lum_triples, tol, out_w, out_t, out_r, count_only):
    """The pairs (window w, triple t, turn r: t's sides turned by r within ``tol`` of w's; t > w when t is a
    window too) whose triples share a luminaire, found among the triples holding each luminaire x (sorted by
    a side, so a window looks only at those within the tolerance of its first), each once: at the smallest
    luminaire the two share. Returns how many; fills ``out_*`` unless counting."""
    n = 0
    for x in range(len(lum_start) - 1):
        held = lum_triples[lum_start[x]:lum_start[x + 1]]
        first = np.empty(3 * len(held))
        for a in range(len(held)):
            for r in range(3):
                first[3 * a + r] = S[held[a], r]  # the first side of the triple turned by r
        order = np.argsort(first)
        ranked = first[order]
        for a in range(len(held)):
            w = held[a]
            if w >= nwin:
                continue
            s0, s1, s2 = S[w, 0], S[w, 1], S[w, 2]
            for b in range(np.searchsorted(ranked, s0 - tol), np.searchsorted(ranked, s0 + tol, "right")):
                e = order[b]
                t, r = held[e // 3], e % 3
                if t == w or (t < nwin and t < w):
                    continue
                if abs(S[t, (r + 1) % 3] - s1) > tol or abs(S[t, (r + 2) % 3] - s2) > tol or abs(S[t, r] - s0) > tol:
                    continue
                low = x  # x is shared: count the pair at the smallest shared luminaire
                for i in range(3):
                    for j in range(3):
                        if T[w, i] == T[t, j] and T[w, i] < low:
                            low = T[w, i]
                if low != x:
                    continue
                if not count_only:
                    out_w[n], out_t[n], out_r[n] = w, t, r
                n += 1
    return n


def _span(S: np.ndarray, w: float) -> int:
    """Side cells per side (0..span-1) for sides ``S`` [m] in cells ``w`` wide: a lookup reaches one past the largest."""
    return int(S.max(initial=0.0) / w) + 2


class ReadingIndex:
    """The protocol of :func:`planner.codes.pairwise.search` over every pair of a window and a triple that read alike
    under equal labels, with only those of triples sharing a luminaire listed (``local``). Build with :meth:`build`."""

    def __init__(self, local: AlikeIndex, nwin: int, S: np.ndarray, tolerance_m: float):
        self.local, self.n, self.nwin = local, local.n, nwin
        self.T, self.S = local.T, S  # the triples (windows first) and their sides [m]
        self.tol = tolerance_m + 1e-9
        self.w = CELL_TOLERANCES * self.tol
        span, labels = _span(S, self.w), max(self.n, 2)
        self.strides = np.array([span ** 2 * 3 * labels ** 2, span * 3 * labels ** 2, 3 * labels ** 2, labels ** 2,
                                 labels], np.int64)
        wsize, msize = (1 << int(np.ceil(np.log2(max(6 * m, 16)))) for m in (nwin, len(self.T) - nwin))
        # two tables, at most half full (three keys per triple): the windows', and the other triples'
        self.tables: tuple[np.ndarray, np.ndarray, int, np.ndarray, np.ndarray, int] = (
            np.full(wsize, EMPTY, np.int64), np.full(wsize, -1, np.int32), wsize - 1,
            np.full(msize, EMPTY, np.int64), np.full(msize, -1, np.int32), msize - 1)
        self.nxt, self.prv, self.slot = (np.empty(3 * len(self.T), np.int32) for _ in range(3))
        self._all = np.arange(len(self.T), dtype=np.int64)

    @classmethod
    def build(cls, windows: np.ndarray, matches: np.ndarray, xyz: np.ndarray, tolerance_m: float,
              budget: int | None = None) -> ReadingIndex | None:
        """The index of ``windows`` against themselves and ``matches`` (the site's triples within the tolerance of a
        window, :func:`planner.verify.rivals.shape_matches`); None when the pairs sharing a luminaire are over
        ``budget`` (default :data:`planner.codes.alike.PAIR_BUDGET`) or the keys would not fit 63 bits."""
        T, nwin = triples(windows, matches, xyz)
        S = np.ascontiguousarray(sides(T, xyz))
        if _span(S, CELL_TOLERANCES * (tolerance_m + 1e-9)) ** 3 * 3 * max(len(xyz), 2) ** 2 >= 2 ** 63:
            return None  # the keys would not fit 63 bits
        lum = holding(T, len(xyz))
        args = (T, S, nwin, *lum, tolerance_m + 1e-9)
        count = _shared_pairs(*args, np.empty(0, np.int32), np.empty(0, np.int32), np.empty(0, np.int8), True)
        if count > (alike.PAIR_BUDGET if budget is None else budget):
            return None
        pw, pt, pr = np.empty(count, np.int32), np.empty(count, np.int32), np.empty(count, np.int8)
        _shared_pairs(*args, pw, pt, pr, False)
        return cls(AlikeIndex(len(xyz), T, pw, pt, pr, lum), nwin, S, tolerance_m)

    def _alike(self, q: int, lab: np.ndarray) -> np.ndarray:
        """The triples sharing no luminaire with ``q`` that read like it under ``lab``."""
        partners = np.empty(64, np.int64)
        while True:
            n = _remote(self.T, self.S, self.nwin, q, -1, lab, self.tol, self.w, self.strides, *self.tables, self.nxt,
                        np.zeros(2, np.int64), partners)
            if n <= len(partners):
                return partners[:n]
            partners = np.empty(n, np.int64)

    def _far(self, only: np.ndarray, lab: np.ndarray) -> tuple[int, np.ndarray]:
        """The pairs of unshared triples alike under ``lab`` among ``only`` (each once) and the triples in one."""
        total, bad = _remote_conflicts(self.T, self.S, self.nwin, lab, self.tol, self.w, self.strides, *self.tables,
                                       self.nxt, only)
        return int(total), bad

    # The protocol of :func:`planner.codes.pairwise.search`.

    def begin(self, lab: np.ndarray) -> tuple[int, list[int]]:
        _fill(self.T, self.S, self.nwin, lab, self.w, self.strides, *self.tables, self.nxt, self.prv, self.slot)
        total, bad = self.local.begin(lab)
        far, far_bad = self._far(self._all, lab)
        return total + far, sorted(set(bad) | set(far_bad.tolist()))

    def cost(self, i: int, lab: np.ndarray, K: int) -> np.ndarray:
        return self.local.cost(i, lab, K) + _remote_cost(i, self.T, self.S, self.nwin, lab, K, self.tol, self.w,
                                                         self.strides, self.local.lum_start, self.local.lum_triples,
                                                         *self.tables, self.nxt)

    def holders(self, unit: int, lab: np.ndarray) -> np.ndarray:
        return np.unique(np.concatenate([self.local.holders(unit, lab), self.T[self._alike(unit, lab)].reshape(-1)]))

    def in_conflict(self, unit: int, lab: np.ndarray) -> bool:
        return self.local.in_conflict(unit, lab) or len(self._alike(unit, lab)) > 0

    def moved(self, i: int, old: int, lab: np.ndarray) -> list[int]:
        _rekey(i, self.T, self.S, self.nwin, lab, self.w, self.strides, self.local.lum_start, self.local.lum_triples,
               *self.tables, self.nxt, self.prv, self.slot)
        held = self.local.lum_triples[self.local.lum_start[i]:self.local.lum_start[i + 1]].astype(np.int64)
        _, far = self._far(held, lab)
        return sorted(set(self.local.moved(i, old, lab)) | set(far.tolist()))
