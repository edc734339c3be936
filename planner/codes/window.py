"""Window codes: short labels such that every three-LED window of a site reads uniquely.

A window (PRODUCT.md, "What decodable means") is three luminaires read as their
labels in counter-clockwise order plus the shape of their triangle. Its *key* is
``(shape, L[w0], L[w1], L[w2])``, or for a 3-fold symmetric (equilateral) shape
the smallest cyclic rotation of the three labels. A labelling with ``K`` labels is
valid when all keys differ. Triples may also be *passive* (``active`` False): other
luminaire triples of the site that a window must not read like, but that need not
differ from each other, since no camera uses them as a window. Labels are found by local search (vectorised
min-conflicts repair sweeps, then a focused heat-bath search with incremental key counts) and,
for small sites, OR-Tools CP-SAT, which can also prove a bit width infeasible.
Everything is deterministic given the seed: budgets are steps, never seconds.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import repeat

import numpy as np

from planner.codes import cpsat

DENSE_MAX = 1 << 23
"""Key counts live in a dense array when ``shapes * K**3`` is at most this, else a dict."""
LS_STEPS_PER_SECOND = 5000
"""Local-search steps granted per second of ``time_budget`` (5-15k steps/s measured, by K and degree)."""
TEMPERATURE = 0.6
"""Heat-bath temperature [conflicting pairs]: 0.6-0.7 suits K = 16 (16 x 32 L windows), 0.5 K = 32."""
STEP_WORK = 256 * 32
"""Candidate keys per luminaire (degree x labels) up to which a focused step counts as one step."""
STALL_SHARE = 0.25
"""A focused search stops when its best has not improved for this share of its steps (at least ``STALL_MIN``)."""
STALL_MIN = 5000
HOPELESS_SHARE = 0.1
"""With passive triples, widths start where random labels would leave conflicting pairs
under this share of the windows (expected pairs: those sharing a shape over K^3)."""
HOPELESS_MIN = 100
"""... or under this many pairs: small problems try every width from the counting bound."""
_SWEEP_CHUNK = 1 << 21
"""Candidate codes evaluated at once in a repair sweep (memory ~ 16 bytes each)."""


@dataclass(frozen=True)
class WindowCode:
    """Labels of a site under the window rule.

    ``labels`` (shape (n,), 0..K-1) is what each luminaire broadcasts in ``bits`` bits;
    ``K = 2**bits``. ``lower_bound_labels``/``lower_bound_bits`` come from counting keys.
    ``optimal`` is True when ``bits`` equals the bound or CP-SAT proved ``bits - 1`` infeasible.
    ``method`` is ``"local search"``, ``"CP-SAT"`` or ``"distinct labels"``.
    """

    labels: np.ndarray
    K: int
    bits: int
    lower_bound_labels: int
    lower_bound_bits: int
    method: str
    optimal: bool


def _active(active, m: int) -> np.ndarray:
    """The per-triple active flags (all True when not given)."""
    if active is None:
        return np.ones(m, dtype=bool)
    a = np.asarray(active, dtype=bool).reshape(-1)
    if len(a) != m:
        raise ValueError(f"{m} windows but {len(a)} active flags")
    return a


def _pairs(codes: np.ndarray, act: np.ndarray) -> tuple[int, np.ndarray]:
    """Conflicting pairs (two active triples, or one active and one passive, with one key)
    and the per-triple flag 'in such a pair'."""
    if len(codes) == 0:
        return 0, np.zeros(0, dtype=bool)
    _, inv = np.unique(codes, return_inverse=True)
    inv = inv.reshape(-1)
    a = np.bincount(inv, weights=act).astype(np.int64)
    p = np.bincount(inv) - a
    pairs = int((a * (a - 1) // 2 + a * p).sum())
    return pairs, np.where(act, (a[inv] >= 2) | (p[inv] >= 1), a[inv] >= 1)


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
    """Key of every window as an int64 code: equal codes iff equal keys.

    The code is ``shape * K**3 + triple`` (base K; smallest rotation for symmetric shapes),
    or that pair's rank among the windows when many shapes and labels would overflow int64.
    """
    w, s, sym = _arrays(windows, shape, symmetric)
    K, lab = int(K), np.asarray(labels, dtype=np.int64).reshape(-1)
    if len(lab) and (lab.min() < 0 or lab.max() >= K):
        raise ValueError(f"labels must lie in 0..{K - 1}")
    if K >= 2 ** 21:
        raise ValueError(f"K = {K} labels overflow int64 keys")
    triple = _encode(lab[w], sym, K)
    if (int(s.max(initial=0)) + 1) * K ** 3 < 2 ** 62:
        return s * K ** 3 + triple
    return np.unique(np.column_stack([s, triple]), axis=0, return_inverse=True)[1].reshape(-1)  # ranks


def count_conflicts(windows, shape, symmetric, labels, K: int, active=None) -> int:
    """Number of conflicting pairs (0 iff the labelling is valid); passive pairs do not count."""
    codes = window_keys(windows, shape, symmetric, labels, K)
    return _pairs(codes, _active(active, len(codes)))[0]


def conflicting_windows(windows, shape, symmetric, labels, K: int, active=None) -> np.ndarray:
    """Indices (ascending) of the triples in a conflicting pair."""
    codes = window_keys(windows, shape, symmetric, labels, K)
    return np.flatnonzero(_pairs(codes, _active(active, len(codes)))[1])


def _labels_for(count: int, symmetric: bool) -> int:
    """Fewest labels whose keys (K^3, or (K^3 + 2K)/3 necklaces) number at least ``count``."""
    k = max(1, int(round(count ** (1 / 3))) - 2)
    while (k ** 3 + 2 * k) // 3 < count if symmetric else k ** 3 < count:
        k += 1
    return k


def lower_bound_labels(shape, symmetric, active=None) -> int:
    """Counting bound: each shape class needs as many keys as it has active windows (at least 1)."""
    s = np.asarray(shape, dtype=np.int64).reshape(-1)
    s = s[_active(active, len(s))]
    sym = np.asarray(symmetric, dtype=bool).reshape(-1)
    counts = np.bincount(s, minlength=len(sym)) if len(s) else np.zeros(len(sym), np.int64)
    return max([1] + [_labels_for(int(c), bool(sym[i])) for i, c in enumerate(counts) if c])


class _Counts:
    """Exact multiset of key codes: a dense array (with a spare zero slot that the pad code -1
    reads) or, for large key spaces, a dict."""

    def __init__(self, codes: np.ndarray, size: int):
        self.dense = np.bincount(codes, minlength=size + 1) if size <= DENSE_MAX else None
        self.d: dict[int, int] = {}
        if self.dense is None:
            keys, counts = np.unique(codes, return_counts=True)
            self.d = dict(zip(keys.tolist(), counts.tolist()))

    def many(self, C: np.ndarray) -> np.ndarray:
        if self.dense is not None:
            return self.dense[C]
        return np.fromiter(map(self.d.get, C.ravel().tolist(), repeat(0)), np.int64, C.size).reshape(C.shape)

    def get(self, c: int) -> int:
        return int(self.dense[c]) if self.dense is not None else self.d.get(c, 0)

    def add(self, c: int, delta: int) -> int:
        """Add ``delta`` to code ``c``'s count; return the new count."""
        if self.dense is not None:
            self.dense[c] += delta
            return int(self.dense[c])
        v = self.d[c] = self.d.get(c, 0) + delta
        return v


class _Problem:
    """Windows and their incidence: for luminaire u, the windows through it (``inc_w``, padded
    with the dummy window M whose code is -1) and u's position in each (``inc_p``)."""

    def __init__(self, n: int, windows, shape, symmetric, K: int, active=None):
        w, s, sym = _arrays(windows, shape, symmetric)
        self.act = np.append(_active(active, len(w)), False)
        n, K = int(n), int(K)
        self.n, self.K, self.M = n, K, len(w)
        self.size = (int(s.max(initial=0)) + 1) * K ** 3
        if self.size >= 2 ** 62:
            raise ValueError(f"K = {K} overflows int64 keys")
        self.w = np.vstack([w, np.zeros((1, 3), np.int64)])
        self.off = np.append(s * K ** 3, -1)
        self.sym = np.append(sym, False)
        self.any_sym = bool(sym.any())
        lum = w.ravel()
        if len(lum) and (lum.min() < 0 or lum.max() >= n):
            raise ValueError(f"window luminaire indices must lie in 0..{n - 1}")
        order = np.argsort(lum, kind="stable")
        self.deg = np.bincount(lum, minlength=n)
        col = np.arange(len(lum)) - np.repeat(np.cumsum(self.deg) - self.deg, self.deg)
        shape_ = (n, max(1, int(self.deg.max(initial=0))))
        self.inc_w = np.full(shape_, self.M, np.int64)
        self.inc_p = np.zeros(shape_, np.int64)
        self.inc_w[lum[order], col] = order // 3
        self.inc_p[lum[order], col] = order % 3
        self.inc_wt = np.where(self.inc_w < self.M, K ** (2 - self.inc_p), 0)  # u's digit weight

    def codes(self, lab: np.ndarray) -> np.ndarray:
        """Key codes of all windows, plus -1 for the dummy window: shape (M + 1,)."""
        c = self.off + _encode(lab[self.w], self.sym, self.K)
        c[-1] = -1
        return c

    def candidates(self, lab: np.ndarray, codes: np.ndarray, us: np.ndarray) -> np.ndarray:
        """Codes of the windows through each of ``us`` with its label set to 0..K-1: (len(us), D, K).

        Pads (the dummy window) are -1 for every label, so they never change a label's score.
        """
        K, wi, ks = self.K, self.inc_w[us], np.arange(self.K, dtype=np.int64)
        tp = lab[us][:, None]  # u's own label, at position p of each of its windows
        wt = self.inc_wt[us]  # the digit of u in each window's code is replaced (pads: weight 0, code -1)
        cand = (codes[wi] - tp * wt)[..., None] + ks * wt[..., None]
        if not self.any_sym:
            return cand
        i, d = np.nonzero(self.sym[wi])  # 3-fold symmetric windows take their smallest rotation
        p, t, tp = self.inc_p[us][i, d], lab[self.w[wi[i, d]]], tp[i]
        best = None
        for r in range(3):
            enc = (t[:, r] * K + t[:, (r + 1) % 3]) * K + t[:, (r + 2) % 3]
            weight = K ** (2 - (p - r) % 3)
            c = (enc[:, None] - tp * weight[:, None]) + ks * weight[:, None]
            best = c if best is None else np.minimum(best, c)
        cand[i, d] = best + self.off[wi[i, d]][:, None]
        return cand

    def in_conflict(self, m: int, code: int, A: _Counts, P: _Counts) -> bool:
        """Triple ``m`` (at key ``code``) shares its key with an active triple, or is active and
        shares it with any triple."""
        a = A.get(code) - int(self.act[m])
        return a >= 1 or (bool(self.act[m]) and P.get(code) >= 1)


def _sweeps(prob: _Problem, lab: np.ndarray, rng: np.random.Generator, max_sweeps: int = 60) -> int:
    """Vectorised repair while conflicts fall fast; leaves the best labels in ``lab``, returns its pairs."""
    best_lab, best, prev = lab.copy(), None, None
    act = prob.act[:-1]
    for _ in range(max_sweeps + 1):
        codes = prob.codes(lab)
        pairs, hot = _pairs(codes[:-1], act)
        if best is None or pairs < best:
            best, best_lab = pairs, lab.copy()
        if pairs == 0 or (prev is not None and pairs > 0.8 * prev):
            break
        prev = pairs
        conf = rng.permutation(np.flatnonzero(hot))
        _, keep = np.unique(codes[conf], return_index=True)
        move = np.delete(conf, keep)  # all but one triple of each shared key
        us = np.unique(prob.w[move, rng.integers(0, 3, len(move))])
        step = max(1, _SWEEP_CHUNK // (prob.inc_w.shape[1] * prob.K))
        uniq, inv = np.unique(codes[:-1], return_inverse=True)
        inv = inv.reshape(-1)
        n_act = np.bincount(inv, weights=act, minlength=len(uniq)).astype(np.int64)
        n_pas = np.bincount(inv, minlength=len(uniq)) - n_act
        new = np.empty(len(us), np.int64)
        for a in range(0, len(us), step):  # each luminaire's best label against the snapshot
            chunk = us[a:a + step]
            C = prob.candidates(lab, codes, chunk)
            idx = np.minimum(np.searchsorted(uniq, C), len(uniq) - 1)
            found = uniq[idx] == C
            slot_act = prob.act[prob.inc_w[chunk]][..., None]
            # an active slot pairs with every other triple of its key, a passive one with the active ones
            cnt = np.where(found, n_act[idx] + slot_act * n_pas[idx], 0)
            cnt -= slot_act & (C == codes[prob.inc_w[chunk]][..., None])
            cost = cnt.sum(axis=1) + rng.random((len(chunk), prob.K)) * 0.5
            new[a:a + step] = cost.argmin(axis=1)
        lab[us] = new
    lab[:] = best_lab
    assert best is not None  # the first sweep sets it
    return best


def _focused_search(prob: _Problem, lab: np.ndarray, rng: np.random.Generator, max_steps: int,
                    temperature: float = TEMPERATURE) -> int:
    """Focused heat-bath search from ``lab``; leaves the best labels in ``lab``, returns its pairs.

    Each step takes a random conflicting window, scores every label for each of its
    three luminaires by the change in conflicting pairs (exact, from incremental key
    counts) and draws one move with probability ``exp(-delta / temperature)``. It stops
    early when the best has not improved for ``STALL_SHARE`` of ``max_steps``: a width
    that cannot be met then costs a fraction of the budget.
    """
    K, w, act = prob.K, prob.w, prob.act
    codes = prob.codes(lab)
    A = _Counts(codes[:-1][act[:-1]], prob.size)  # key counts of the active triples
    P = _Counts(codes[:-1][~act[:-1]], prob.size)  # and of the passive ones
    pairs, listed = _pairs(codes[:-1], act[:-1])
    todo = np.flatnonzero(listed).tolist()  # holds every triple in a conflicting pair
    best, best_lab = pairs, lab.copy()
    three, ks = np.arange(3), np.arange(K)
    step = last = 0
    stall = max(STALL_MIN, int(STALL_SHARE * max_steps))
    while pairs > 0 and step < max_steps and todo and step - last <= stall:
        j = int(rng.integers(len(todo)))
        m = todo[j]
        if not prob.in_conflict(m, int(codes[m]), A, P):  # resolved meanwhile: drop lazily
            todo[j] = todo[-1]
            todo.pop()
            listed[m] = False
            continue
        step += 1
        us = w[m]
        C = prob.candidates(lab, codes, us)  # (3, D, K)
        wi = prob.inc_w[us]
        # pairs each label would put u's windows in: others sharing the key (u's own windows
        # move, so their current keys do not count) plus repeats among u's windows; the pads'
        # terms are the same for every label and cancel in delta
        others_a, others_p = A.many(C), P.many(C)
        for i in range(3):  # minus u's own windows now at each candidate key (sorted look-up)
            by_code = np.argsort(codes[wi[i]], kind="stable")
            now_at = codes[wi[i]][by_code]
            act_before = np.zeros(len(by_code) + 1, np.int64)  # active windows before each sorted position
            np.cumsum(act[wi[i]][by_code], out=act_before[1:])
            lo, hi = np.searchsorted(now_at, C[i], "left"), np.searchsorted(now_at, C[i], "right")
            mine_a = act_before[hi] - act_before[lo]
            others_a[i] -= mine_a
            others_p[i] -= hi - lo - mine_a
        slot_act = act[wi]
        cost = (others_a + slot_act[..., None] * others_p).sum(axis=1)
        order = np.argsort(C, axis=1)
        Cs, As = C[three[:, None, None], order, ks], slot_act[three[:, None, None], order]
        cost = cost + ((Cs[:, 1:] == Cs[:, :-1]) & (As[:, 1:] | As[:, :-1])).sum(axis=1)
        now = lab[us]
        delta = cost - cost[three, now][:, None]
        weight = np.exp((delta.min() - delta) / temperature).ravel()
        cum = np.cumsum(weight)
        i, k = divmod(min(int(np.searchsorted(cum, rng.random() * cum[-1], side="right")), 3 * K - 1), K)
        if k == now[i]:
            continue
        u = int(us[i])
        lab[u] = k
        for m2, new in zip(wi[i, :prob.deg[u]].tolist(), C[i, :prob.deg[u], k].tolist()):
            old = int(codes[m2])
            if act[m2]:
                pairs -= A.add(old, -1) + P.get(old)
                pairs += A.get(new) + P.get(new)
                A.add(new, 1)
            else:
                P.add(old, -1)
                pairs += A.get(new) - A.get(old)
                P.add(new, 1)
            codes[m2] = new
            if prob.in_conflict(m2, new, A, P) and not listed[m2]:
                listed[m2] = True
                todo.append(m2)
        if pairs < best:
            best, best_lab, last = pairs, lab.copy(), step
    lab[:] = best_lab
    return best


def _local_search(prob: _Problem, lab: np.ndarray, seed: int, max_steps: int) -> int:
    # A focused step scores 3 x D x K candidate keys: on problems with many passive triples
    # per luminaire, fewer steps keep the work (not the time) of the search bounded.
    max_steps = int(max_steps * min(1.0, STEP_WORK / (prob.inc_w.shape[1] * prob.K)))
    rng = np.random.default_rng(seed)
    pairs = _sweeps(prob, lab, rng) if prob.M else 0
    if pairs and max_steps > 0:
        pairs = _focused_search(prob, lab, rng, max_steps)
    return pairs


def search_labels(n: int, windows, shape, symmetric, K: int, *, seed: int = 0,
                  max_steps: int = 100_000, active=None) -> np.ndarray | None:
    """A valid labelling with labels 0..K-1 by local search from random labels, or None.

    ``max_steps`` bounds the focused-search steps (after at most 60 repair sweeps).
    """
    prob = _Problem(n, windows, shape, symmetric, K, active)
    lab = np.random.default_rng([seed, 1]).integers(0, K, n).astype(np.int64)
    return lab if _local_search(prob, lab, seed, max_steps) == 0 else None


def repair_labels(labels, n: int, windows, shape, symmetric, K: int, *, seed: int = 0,
                  max_steps: int = 100_000, active=None) -> np.ndarray | None:
    """Continue the local search from ``labels`` (e.g. after new windows were found), or None."""
    lab = np.array(labels, dtype=np.int64).reshape(-1)
    if len(lab) != n or (n and (lab.min() < 0 or lab.max() >= K)):
        raise ValueError(f"labels must be {n} values in 0..{K - 1}")
    prob = _Problem(n, windows, shape, symmetric, K, active)
    return lab if _local_search(prob, lab, seed, max_steps) == 0 else None


def cpsat_window_labels(n: int, windows, shape, symmetric, K: int, *, seed: int = 0, time_budget: float = 10.0,
                 hint: np.ndarray | None = None) -> tuple[np.ndarray | None, bool, bool]:
    """CP-SAT: (valid labels or None, True if K labels are proved infeasible, True if the
    wall-clock safety net stopped the search, so the result may differ on another machine).

    ``time_budget`` is deterministic time (:mod:`planner.codes.cpsat`). ``hint`` seeds the search.
    """
    w, s, sym = _arrays(windows, shape, symmetric)
    model = cpsat.new_model()
    used = np.unique(w)
    x = {int(v): model.new_int_var(0, K - 1, f"x{v}") for v in used}
    groups: dict[int, list] = {}
    for m, (a, b, c) in enumerate(w.tolist()):
        r0 = K * K * x[a] + K * x[b] + x[c]
        if sym[m]:
            y = model.new_int_var(0, K ** 3 - 1, f"k{m}")
            model.add_min_equality(y, [r0, K * K * x[b] + K * x[c] + x[a], K * K * x[c] + K * x[a] + x[b]])
            r0 = y
        groups.setdefault(int(s[m]), []).append(r0)
    for exprs in groups.values():
        if len(exprs) > 1:
            model.add_all_different(exprs)
    if len(used):
        first = int(used[0])
        model.add(x[first] == 0)  # labels are interchangeable: fix one
        if hint is not None:
            h = np.asarray(hint, dtype=np.int64)
            swap = np.where(h == h[first], 0, np.where(h == 0, h[first], h))  # relabel so hint[first] == 0
            for v, var in x.items():
                model.add_hint(var, int(swap[v]))
    got = cpsat.solve(model, time_budget=time_budget, seed=seed, first_solution=True)  # else a long
    # interleaved task runs on to the wall limit
    if not got.found:
        return None, got.infeasible, got.wall_stopped
    lab = np.zeros(n, np.int64)
    for v, var in x.items():
        lab[v] = got.solver.value(var)
    if count_conflicts(w, s, symmetric, lab, K):
        return None, False, got.wall_stopped  # never expected: independent check of the model
    return lab, False, got.wall_stopped


def assign_window_code(n: int, windows, shape, symmetric, *, seed: int = 0, time_budget: float = 10.0,
                       cpsat_max_windows: int = 3000, active=None, min_bits: int = 1) -> WindowCode:
    """Fewest bits (``K = 2**bits`` labels) with all window keys distinct; deterministic.

    From the counting bound upwards, each bit width gets local search
    (``LS_STEPS_PER_SECOND * time_budget`` steps) and then, with at most
    ``cpsat_max_windows`` windows, CP-SAT for ``time_budget`` deterministic seconds,
    hinted with the local search's best labels; CP-SAT also proves widths infeasible.
    Distinct labels for every luminaire always work, so the loop ends once ``K >= n``.
    With passive triples CP-SAT is not run (its model would have to treat them as
    windows: a stricter problem, which proves nothing); widths where random labels would leave many times
    more conflicts than windows are skipped (``HOPELESS_SHARE``), so such a result is
    called optimal only when it meets the counting bound. ``min_bits`` skips narrower
    widths (the caller found them wanting).
    """
    w, s, _ = _arrays(windows, shape, symmetric)
    act = _active(active, len(w))  # passive triples may repeat, in other readings
    if len(np.unique(np.column_stack([s, np.sort(w, axis=1)])[act], axis=0)) < act.sum():
        raise ValueError("two windows of one shape hold the same three luminaires")
    lb = lower_bound_labels(s, symmetric, act)
    lbb = max(1, (lb - 1).bit_length())  # ceil(log2 lb), at least 1
    steps = int(LS_STEPS_PER_SECOND * time_budget)
    proved_below = wall_stopped = False
    start = max(lbb, min_bits)
    if not act.all():  # skip widths where random labels would leave far more conflicts than windows
        same = _pairs(s, act)[0]  # pairs that share a shape, whatever the labels
        while same / 8 ** start > max(HOPELESS_SHARE * act.sum(), HOPELESS_MIN):
            start += 1
    lab: np.ndarray | None  # None while no labels of this width are found
    for b in range(start, 64):
        K = 2 ** b
        if (int(s.max(initial=0)) + 1) * K ** 3 >= 2 ** 62:  # keys overflow: only absurd shape counts
            b = max(b, (n - 1).bit_length())
            return WindowCode(np.arange(n, dtype=np.int64), 2 ** b, b, lb, lbb, "distinct labels", False)
        lab = np.random.default_rng([seed, b]).integers(0, K, n).astype(np.int64)
        method, proved = "local search", False
        if _local_search(_Problem(n, w, s, symmetric, K, act), lab, seed, steps) > 0:
            hint, lab = lab, None
            if len(w) <= cpsat_max_windows and time_budget > 0 and act.all():
                method = "CP-SAT"
                lab, proved, wall = cpsat_window_labels(n, w, s, symmetric, K, seed=seed, time_budget=time_budget, hint=hint)
                wall_stopped |= wall
            if lab is None and K >= n:
                lab, method = np.arange(n, dtype=np.int64), "distinct labels"
        if lab is not None:
            if wall_stopped:
                method += " (CP-SAT stopped by the wall clock: the result may differ on another machine)"
            return WindowCode(lab, K, b, lb, lbb, method, b == lbb or proved_below)
        proved_below = proved
    raise AssertionError("unreachable: distinct labels are valid")
