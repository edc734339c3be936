"""Window codes: short labels such that every three-LED window of a site reads uniquely.

A window (PRODUCT.md, "What decodable means") is three luminaires read as their
labels in counter-clockwise order plus the shape of their triangle. Its *key* is
``(shape, L[w0], L[w1], L[w2])``, or for a 3-fold symmetric (equilateral) shape
the smallest cyclic rotation of the three labels. A labelling with ``K`` labels is
valid when all keys differ. Labels are found by min-conflicts local search
(vectorised repair sweeps, then tabu min-conflicts with incremental key counts) and,
for small sites, OR-Tools CP-SAT, which can also prove a bit width infeasible.
Everything is deterministic given the seed: budgets are steps, never seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from ortools.sat.python import cp_model

DENSE_MAX = 1 << 24
"""Key counts live in a dense array when ``shapes * K**3`` is at most this, else a dict."""
LS_STEPS_PER_SECOND = 5000
"""Local-search steps granted per second of ``time_budget`` (about 5-10k steps/s measured)."""
_SWEEP_CHUNK = 1 << 21
"""Candidate codes evaluated at once in a repair sweep (memory ~ 16 bytes each)."""


@dataclass(frozen=True)
class WindowCode:
    """Labels of a site under the window rule.

    ``labels`` (shape (n,), 0..K-1) is what each luminaire broadcasts in ``bits`` bits;
    ``K = 2**bits``. ``lower_bound_labels``/``lower_bound_bits`` come from counting keys.
    ``optimal`` is True when ``bits`` equals the bound or CP-SAT proved ``bits - 1`` infeasible.
    """

    labels: np.ndarray
    K: int
    bits: int
    lower_bound_labels: int
    lower_bound_bits: int
    method: str
    optimal: bool


def _arrays(windows, shape, symmetric) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    w = np.asarray(windows, dtype=np.int64).reshape(-1, 3)
    s = np.asarray(shape, dtype=np.int64).reshape(-1)
    sym = np.asarray(symmetric, dtype=bool).reshape(-1)
    if len(s) != len(w):
        raise ValueError(f"{len(w)} windows but {len(s)} shapes")
    if len(s) and (s.min() < 0 or s.max() >= len(sym)):
        raise ValueError(f"shape classes must lie in 0..{len(sym) - 1}")
    if len(w) and ((w[:, 0] == w[:, 1]) | (w[:, 1] == w[:, 2]) | (w[:, 0] == w[:, 2])).any():
        raise ValueError("a window repeats a luminaire")
    return w, s, sym[s]


def _encode(t: np.ndarray, sym: np.ndarray, K: int) -> np.ndarray:
    """Base-K code of label triples ``t`` (..., 3); smallest rotation where ``sym``."""
    code = (t[..., 0] * K + t[..., 1]) * K + t[..., 2]
    if sym.any():
        r1 = (t[..., 1] * K + t[..., 2]) * K + t[..., 0]
        r2 = (t[..., 2] * K + t[..., 0]) * K + t[..., 1]
        code = np.where(sym, np.minimum(code, np.minimum(r1, r2)), code)
    return code


def window_keys(windows, shape, symmetric, labels, K: int) -> np.ndarray:
    """Key of every window as an int64 code ``shape * K**3 + triple``: equal codes iff equal keys."""
    w, s, sym = _arrays(windows, shape, symmetric)
    if (int(s.max(initial=0)) + 1) * K ** 3 >= 2 ** 62:
        raise ValueError(f"K = {K} with {int(s.max(initial=0)) + 1} shapes overflows int64 keys")
    t = np.asarray(labels, dtype=np.int64)[w]
    return s * K ** 3 + _encode(t, sym, K)


def _pairs(codes: np.ndarray) -> int:
    _, c = np.unique(codes, return_counts=True)
    return int((c * (c - 1) // 2).sum())


def count_conflicts(windows, shape, symmetric, labels, K: int) -> int:
    """Number of conflicting window pairs (0 iff the labelling is valid)."""
    return _pairs(window_keys(windows, shape, symmetric, labels, K))


def conflicting_windows(windows, shape, symmetric, labels, K: int) -> np.ndarray:
    """Indices (ascending) of the windows whose key another window shares."""
    codes = window_keys(windows, shape, symmetric, labels, K)
    _, inv, cnt = np.unique(codes, return_inverse=True, return_counts=True)
    return np.flatnonzero(cnt[inv] >= 2)


def _labels_for(count: int, symmetric: bool) -> int:
    """Fewest labels whose keys (K^3, or (K^3 + 2K)/3 necklaces) number at least ``count``."""
    k = max(1, int(round(count ** (1 / 3))) - 2)
    while (k ** 3 + 2 * k) // 3 < count if symmetric else k ** 3 < count:
        k += 1
    return k


def lower_bound_labels(shape, symmetric) -> int:
    """Counting bound: each shape class needs as many keys as it has windows (at least 1)."""
    s = np.asarray(shape, dtype=np.int64).reshape(-1)
    sym = np.asarray(symmetric, dtype=bool).reshape(-1)
    counts = np.bincount(s, minlength=len(sym)) if len(s) else np.zeros(len(sym), np.int64)
    return max([1] + [_labels_for(int(c), bool(sym[i])) for i, c in enumerate(counts) if c])


def _bits(K: int) -> int:
    """Bits to send labels 0..K-1: ``ceil(log2 K)``, at least 1."""
    return max(1, math.ceil(math.log2(K))) if K > 1 else 1


class _Counts:
    """Exact multiset of key codes: dense array or dict."""

    def __init__(self, codes: np.ndarray, size: int):
        self.dense = np.bincount(codes, minlength=size).astype(np.int64) if size <= DENSE_MAX else None
        if self.dense is None:
            u, c = np.unique(codes, return_counts=True)
            self.d = dict(zip(u.tolist(), c.tolist()))

    def many(self, C: np.ndarray) -> np.ndarray:
        if self.dense is not None:
            return np.where(C >= 0, self.dense[np.maximum(C, 0)], 0)
        d = self.d
        return np.fromiter((d.get(c, 0) for c in C.ravel().tolist()), np.int64, C.size).reshape(C.shape)

    def __getitem__(self, c: int) -> int:
        return int(self.dense[c]) if self.dense is not None else self.d.get(c, 0)

    def add(self, c: int, delta: int) -> int:
        """Add ``delta`` to code ``c``'s count; return the new count."""
        if self.dense is not None:
            self.dense[c] += delta
            return int(self.dense[c])
        v = self.d.get(c, 0) + delta
        if v:
            self.d[c] = v
        else:
            del self.d[c]
        return v


class _Problem:
    """Windows with their incidence: for luminaire u, the windows through it and u's position."""

    def __init__(self, n: int, windows, shape, symmetric, K: int):
        self.w, s, self.sym = _arrays(windows, shape, symmetric)
        self.n, self.K, self.M = n, K, len(self.w)
        self.size = (int(s.max(initial=0)) + 1) * K ** 3
        if self.size >= 2 ** 62:
            raise ValueError(f"K = {K} overflows int64 keys")
        self.off = s * K ** 3
        lum = self.w.ravel()
        order = np.argsort(lum, kind="stable")
        deg = np.bincount(lum, minlength=n)
        D = max(1, int(deg.max(initial=0)))
        start = np.concatenate([[0], np.cumsum(deg)[:-1]])
        col = np.arange(len(lum)) - np.repeat(start, deg)
        self.inc_w = np.zeros((n, D), np.int64)
        self.inc_p = np.zeros((n, D), np.int64)
        self.inc_v = np.zeros((n, D), bool)
        self.inc_w[lum[order], col] = order // 3
        self.inc_p[lum[order], col] = order % 3
        self.inc_v[lum[order], col] = True
        self.used = deg > 0

    def codes(self, lab: np.ndarray) -> np.ndarray:
        return self.off + _encode(lab[self.w], self.sym, self.K)

    def candidates(self, lab: np.ndarray, us: np.ndarray) -> np.ndarray:
        """Codes of the windows through each ``us`` with its label set to 0..K-1: (len(us), D, K); -1 pads."""
        K, wi, p = self.K, self.inc_w[us], self.inc_p[us]
        t, sym = lab[self.w[wi]], self.sym[wi]
        ks = np.arange(K, dtype=np.int64)
        tp = np.take_along_axis(t, p[..., None], axis=-1)[..., 0]
        best = None
        for r in range(3 if sym.any() else 1):
            enc = (t[..., r] * K + t[..., (r + 1) % 3]) * K + t[..., (r + 2) % 3]
            weight = K ** (2 - (p - r) % 3)
            cand = (enc - tp * weight)[..., None] + ks * weight[..., None]
            best = cand if best is None else np.where(sym[..., None], np.minimum(best, cand), best)
        return np.where(self.inc_v[us][..., None], best + self.off[wi][..., None], -1)


def _sweeps(prob: _Problem, lab: np.ndarray, rng: np.random.Generator, max_sweeps: int = 60) -> int:
    """Vectorised repair while conflicts fall fast; leaves the best labels in ``lab``, returns its pairs."""
    best_lab, best, prev = lab.copy(), None, None
    for _ in range(max_sweeps + 1):
        codes = prob.codes(lab)
        uniq, inv, cnts = np.unique(codes, return_inverse=True, return_counts=True)
        pairs = int((cnts * (cnts - 1) // 2).sum())
        if best is None or pairs < best:
            best, best_lab = pairs, lab.copy()
        if pairs == 0 or (prev is not None and pairs > 0.8 * prev):
            break
        prev = pairs
        conf = rng.permutation(np.flatnonzero(cnts[inv] >= 2))
        _, keep = np.unique(codes[conf], return_index=True)
        move = np.delete(conf, keep)  # all but one window of each shared key
        us = np.unique(prob.w[move, rng.integers(0, 3, len(move))])
        step = max(1, _SWEEP_CHUNK // (prob.inc_w.shape[1] * prob.K))
        new = np.empty(len(us), np.int64)
        for a in range(0, len(us), step):
            chunk = us[a:a + step]
            C = prob.candidates(lab, chunk)
            idx = np.minimum(np.searchsorted(uniq, C), len(uniq) - 1)
            cnt = np.where(uniq[idx] == C, cnts[idx], 0) - (C == codes[prob.inc_w[chunk]][..., None])
            cost = cnt.sum(axis=1) + rng.random((len(chunk), prob.K)) * 0.5
            new[a:a + step] = cost.argmin(axis=1)
        lab[us] = new
    lab[:] = best_lab
    return best


def _min_conflicts(prob: _Problem, lab: np.ndarray, rng: np.random.Generator, max_steps: int,
                   noise: float = 0.05) -> int:
    """Tabu min-conflicts from ``lab``; leaves the best labels found in ``lab``, returns its pairs."""
    K, w = prob.K, prob.w
    codes = prob.codes(lab)
    counts = _Counts(codes, prob.size)
    _, inv, c = np.unique(codes, return_inverse=True, return_counts=True)
    pairs = int((c * (c - 1) // 2).sum())
    listed = c[inv] >= 2
    todo = np.flatnonzero(listed).tolist()  # holds all but at most one window of each shared key
    best, best_lab = pairs, lab.copy()
    tabu: dict[int, np.ndarray] = {}
    big = 1 << 40
    step = 0
    while pairs > 0 and step < max_steps and todo:
        j = int(rng.integers(len(todo)))
        m = todo[j]
        if counts[int(codes[m])] < 2:  # resolved meanwhile: drop lazily
            todo[j] = todo[-1]
            todo.pop()
            listed[m] = False
            continue
        step += 1
        us = w[m]
        C = prob.candidates(lab, us)  # (3, D, K)
        wi = prob.inc_w[us]
        cur = np.where(prob.inc_v[us], codes[wi], -2)
        cost = counts.many(C) - (C[..., None] == cur[:, None, None, :]).sum(-1)
        Cs = np.sort(C, axis=1)
        dup = (Cs[:, 1:] == Cs[:, :-1]) & (Cs[:, 1:] >= 0)
        cost = cost.sum(axis=1) + dup.sum(axis=1)  # (3, K): pairs u's windows would be in
        now = lab[us]
        delta = cost - cost[np.arange(3), now][:, None]
        delta[np.arange(3), now] = big
        if rng.random() < noise:
            i = int(rng.integers(3))
            k = int((now[i] + 1 + rng.integers(K - 1)) % K) if K > 1 else 0
        else:
            for i in range(3):
                t = tabu.get(int(us[i]))
                if t is not None:
                    delta[i] = np.where((t > step) & (pairs + delta[i] >= best), big, delta[i])
            flat = int((delta + rng.random(delta.shape) * 0.5).argmin())
            i, k = divmod(flat, K)
            if delta[i, k] >= big:
                continue
        u = int(us[i])
        if K == 1 or k == now[i]:
            continue
        tabu.setdefault(u, np.zeros(K, np.int64))[now[i]] = step + 5 + int(rng.integers(10))
        lab[u] = k
        for d in np.flatnonzero(prob.inc_v[u]).tolist():
            m2, new = int(wi[i, d]), int(C[i, d, k])
            pairs -= counts.add(int(codes[m2]), -1)
            after = counts.add(new, 1)
            pairs += after - 1
            codes[m2] = new
            if after >= 2 and not listed[m2]:
                listed[m2] = True
                todo.append(m2)
        if pairs < best:
            best, best_lab = pairs, lab.copy()
    lab[:] = best_lab
    return best


def _local_search(prob: _Problem, lab: np.ndarray, seed: int, max_steps: int) -> int:
    rng = np.random.default_rng(seed)
    pairs = _sweeps(prob, lab, rng) if prob.M else 0
    if pairs and max_steps > 0:
        pairs = _min_conflicts(prob, lab, rng, max_steps)
    return pairs


def search_labels(n: int, windows, shape, symmetric, K: int, *, seed: int = 0,
                  max_steps: int = 100_000) -> np.ndarray | None:
    """A valid labelling with labels 0..K-1 by local search from random labels, or None.

    ``max_steps`` bounds the min-conflicts moves (after at most 60 repair sweeps).
    """
    prob = _Problem(n, windows, shape, symmetric, K)
    lab = np.random.default_rng([seed, 1]).integers(0, K, n).astype(np.int64)
    return lab if _local_search(prob, lab, seed, max_steps) == 0 else None


def repair_labels(labels, n: int, windows, shape, symmetric, K: int, *, seed: int = 0,
                  max_steps: int = 100_000) -> np.ndarray | None:
    """Continue the local search from ``labels`` (e.g. after new windows were found), or None."""
    lab = np.array(labels, dtype=np.int64).reshape(-1)
    if len(lab) != n or (n and (lab.min() < 0 or lab.max() >= K)):
        raise ValueError(f"labels must be {n} values in 0..{K - 1}")
    prob = _Problem(n, windows, shape, symmetric, K)
    return lab if _local_search(prob, lab, seed, max_steps) == 0 else None


def cpsat_labels(n: int, windows, shape, symmetric, K: int, *, seed: int = 0, time_budget: float = 10.0,
                 hint: np.ndarray | None = None) -> tuple[np.ndarray | None, bool]:
    """CP-SAT: (valid labels or None, True if K labels are proved infeasible).

    ``time_budget`` is deterministic time (about seconds, reproducible); wall time is
    capped at three times that as a safety net. ``hint`` seeds the search.
    """
    w, s, sym = _arrays(windows, shape, symmetric)
    model = cp_model.CpModel()
    used = np.unique(w)
    x = {int(v): model.NewIntVar(0, K - 1, f"x{v}") for v in used}
    groups: dict[int, list] = {}
    for m, (a, b, c) in enumerate(w.tolist()):
        r0 = K * K * x[a] + K * x[b] + x[c]
        if sym[m]:
            y = model.NewIntVar(0, K ** 3 - 1, f"k{m}")
            model.AddMinEquality(y, [r0, K * K * x[b] + K * x[c] + x[a], K * K * x[c] + K * x[a] + x[b]])
            r0 = y
        groups.setdefault(int(s[m]), []).append(r0)
    for exprs in groups.values():
        if len(exprs) > 1:
            model.AddAllDifferent(exprs)
    if len(used):
        first = int(used[0])
        model.Add(x[first] == 0)  # labels are interchangeable: fix one
        if hint is not None:
            h = np.asarray(hint, dtype=np.int64)
            swap = np.where(h == h[first], 0, np.where(h == 0, h[first], h))  # relabel so hint[first] == 0
            for v, var in x.items():
                model.AddHint(var, int(swap[v]))
    solver = cp_model.CpSolver()
    solver.parameters.max_deterministic_time = time_budget
    solver.parameters.max_time_in_seconds = 3.0 * time_budget
    solver.parameters.num_workers = 2
    solver.parameters.interleave_search = True
    solver.parameters.random_seed = seed
    status = solver.Solve(model)
    if status not in (cp_model.OPTIMAL, cp_model.FEASIBLE):
        return None, status == cp_model.INFEASIBLE
    lab = np.zeros(n, np.int64)
    for v, var in x.items():
        lab[v] = solver.Value(var)
    if count_conflicts(w, s, symmetric, lab, K):
        return None, False  # never expected: independent check of the model
    return lab, False


def assign_window_code(n: int, windows, shape, symmetric, *, seed: int = 0, time_budget: float = 10.0,
                       cpsat_max_windows: int = 3000) -> WindowCode:
    """Fewest bits (K = 2**bits labels) with all window keys distinct.

    From the counting bound upwards: local search (``LS_STEPS_PER_SECOND * time_budget``
    moves), then, for at most ``cpsat_max_windows`` windows, CP-SAT for ``time_budget``
    deterministic seconds. Once ``2**bits >= n`` distinct labels always work.
    """
    w, s, sym = _arrays(windows, shape, symmetric)
    lb = lower_bound_labels(s, symmetric)
    lbb = _bits(lb)
    steps = int(LS_STEPS_PER_SECOND * time_budget)
    proved_below = False
    b = lbb
    while True:
        K = 2 ** b
        prob = _Problem(n, w, s, symmetric, K)
        lab = np.random.default_rng([seed, b]).integers(0, K, n).astype(np.int64)
        method = "min-conflicts local search"
        if _local_search(prob, lab, seed, steps) == 0:
            found = lab
        else:
            found, proved = None, False
            if len(w) <= cpsat_max_windows and time_budget > 0:
                found, proved = cpsat_labels(n, w, s, symmetric, K, seed=seed, time_budget=time_budget, hint=lab)
                method = "CP-SAT"
            if found is None and K >= n:
                found, method = np.arange(n, dtype=np.int64), "distinct labels"
        if found is not None:
            return WindowCode(found, K, b, lb, lbb, method, b == lbb or proved_below)
        proved_below = proved
        b += 1
