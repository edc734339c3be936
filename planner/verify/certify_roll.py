"""Roll in closed form for the certificate (:mod:`planner.verify.certify_box`): arcs of roll, compiled with numba.

At roll ``ψ`` an LED's centre images at ``t (cos γ, sin γ)``, ``γ = β'' - ψ``; it is wholly inside the view
rectangle iff ``t cos γ <= A - r |hor(g)| / w_z`` and likewise at the other three sides
(docs/verification.md, "The certificate over pose boxes"). Each such condition holds on one arc of ``γ``;
their meet is at most four arcs. ``|hor(g)|`` is bounded per roll sector (:func:`side_margins`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

TWO_PI = 2.0 * math.pi


ARC_EPS = 1e-9
"""Sure arcs are shrunk and possible arcs grown by this much [rad], against rounding."""


FULL = -1
"""Arc count meaning the whole circle."""


@njit(cache=True)
def cut_arcs(pieces: np.ndarray, n: int | np.int64, s2: float, e2: float, tmp: np.ndarray) -> int:
    """Intersect the arcs ``pieces[:n]`` (each ``[s, e]``, ``e - s <= 2π``) with the arc ``[s2, e2]``, in place."""
    k = 0
    for j in range(n):
        s, e = pieces[j, 0], pieces[j, 1]
        a = s2 - TWO_PI * math.floor((s2 - s) / TWO_PI)  # s2's turn starting in [s, s + 2π)
        b = a + (e2 - s2)
        for lo, hi in ((max(s, a - TWO_PI), min(e, b - TWO_PI)), (max(s, a), min(e, b))):
            if lo <= hi and k < len(tmp):
                tmp[k, 0], tmp[k, 1] = lo, hi
                k += 1
    for j in range(k):  # element by element: a slice copy compiles numba's shape-error message machinery
        pieces[j, 0], pieces[j, 1] = tmp[j, 0], tmp[j, 1]
    return k


@njit(cache=True)
def gamma_arcs(limits: np.ndarray, pieces: np.ndarray, tmp: np.ndarray) -> int:
    """Arcs of ``γ`` (into ``pieces``) where ``cos γ <= l0``, ``-cos γ <= l1``, ``sin γ <= l2``, ``-sin γ <= l3``:
    their number, or FULL. Each condition alone is one arc, ``cos(γ - c) <= l`` for ``c`` = 0, π, π/2, -π/2."""
    n = -1
    for j in range(4):
        lim = limits[j]
        if lim >= 1.0:
            continue
        if lim < -1.0:
            return 0
        g = math.acos(lim)
        c = (0.0, math.pi, 0.5 * math.pi, -0.5 * math.pi)[j]
        if n < 0:
            pieces[0, 0], pieces[0, 1] = c + g, c + TWO_PI - g
            n = 1
        else:  # n as int64, not a literal: cut_arcs compiles for one signature
            n = cut_arcs(pieces, np.int64(n), c + g, c + TWO_PI - g, tmp)
        if n == 0:
            return 0
    return FULL if n < 0 else n


@njit(cache=True)
def cos_limit(num: float, t_lo: float, t_hi: float, sure: bool | np.bool_) -> float:
    """Bound on ``cos`` from ``t cos <= num`` for ``t in [t_lo, t_hi]``: for every such ``t`` (``sure``) or for some."""
    if num >= 0.0:
        t = t_hi if sure else t_lo
    else:
        t = t_lo if sure else t_hi
    if t <= 0.0:
        return math.inf if num >= 0.0 else -math.inf
    return num / t


@njit(cache=True)
def cos_range(d0: float, d1: float) -> tuple[float, float]:
    """Least and greatest ``cos`` over ``[d0, d1]`` [rad]."""
    if d1 - d0 >= TWO_PI:
        return -1.0, 1.0
    lo, hi = min(math.cos(d0), math.cos(d1)), max(math.cos(d0), math.cos(d1))
    if TWO_PI * math.ceil(d0 / TWO_PI) <= d1:
        hi = 1.0
    if math.pi + TWO_PI * math.ceil((d0 - math.pi) / TWO_PI) <= d1:
        lo = -1.0
    return lo, hi


SECTORS = 16
"""Roll sectors over which the disc's margin at each image side is bounded separately."""


PIECES = 4
"""Most arcs of ``γ`` where an LED is seen: four conditions, each one arc, meet in at most four."""


ARCS = SECTORS * 2 * PIECES
"""Room for an LED's arcs of roll: each piece of ``γ`` gives one arc of roll, cut by its sector into at most two."""


@njit(cache=True)
def side_margins(box: np.ndarray, view: np.ndarray) -> np.ndarray:
    """``|hor(g)|`` bounds per roll sector and image side (SECTORS, 2, 4): [k, 0] the largest (sure seeing, the
    inner half-sides), [k, 1] the least (possible seeing, the outer ones). ``|hor g|^2 = 1 + K^2 - (v·g)^2`` with
    ``v·g = -(n_x sin τ + K cos τ)``, ``n_x`` the side's normal along the tilt, a cosine of the roll."""
    tau0, tau1, phi0, phi1 = box[6], box[7], box[8], box[9]
    s0, s1, c0, c1 = math.sin(tau0), math.sin(tau1), math.cos(tau1), math.cos(tau0)
    out = np.empty((SECTORS, 2, 4))
    w = TWO_PI / SECTORS
    for k in range(SECTORS):
        lo, hi = k * w - phi1, (k + 1) * w - phi0  # ψ' = ψ'' - φ
        co_lo, co_hi = cos_range(lo, hi)
        si_lo, si_hi = cos_range(lo - 0.5 * math.pi, hi - 0.5 * math.pi)
        normals = ((co_lo, co_hi), (-co_hi, -co_lo), (-si_hi, -si_lo), (si_lo, si_hi))
        for side in range(4):
            n0, n1 = normals[side]
            ns_lo = min(n0 * s0, n0 * s1, n1 * s0, n1 * s1)
            ns_hi = max(n0 * s0, n0 * s1, n1 * s0, n1 * s1)
            for which in range(2):
                big_k = view[side // 2 + 2 * which]
                e_lo, e_hi = ns_lo + big_k * c0, ns_hi + big_k * c1
                least = 0.0 if e_lo <= 0.0 <= e_hi else min(abs(e_lo), abs(e_hi))
                most = max(abs(e_lo), abs(e_hi))
                if which == 0:
                    out[k, 0, side] = math.sqrt(1.0 + big_k * big_k - least * least)
                else:
                    out[k, 1, side] = math.sqrt(max(0.0, 1.0 + big_k * big_k - most * most))
    return out


@njit(cache=True)
def merge_arcs(arcs: np.ndarray, i: int, n: int) -> int:
    """Join LED ``i``'s arcs that overlap or touch (within ARC_EPS / 10, sure arcs are shrunk by more): fewer
    ends to sweep. Arcs are put in ``[0, 2π)`` by their start first."""
    for j in range(n):
        shift = TWO_PI * math.floor(arcs[i, j, 0] / TWO_PI)
        arcs[i, j, 0] -= shift
        arcs[i, j, 1] -= shift
    order = np.argsort(arcs[i, :n, 0])
    merged = arcs[i, order[:n]].copy()
    k = 0
    for j in range(1, n):
        if merged[j, 0] <= merged[k, 1] + 0.1 * ARC_EPS:
            merged[k, 1] = max(merged[k, 1], merged[j, 1])
        else:
            k += 1
            merged[k, 0], merged[k, 1] = merged[j, 0], merged[j, 1]
    for j in range(k + 1):
        arcs[i, j, 0], arcs[i, j, 1] = merged[j, 0], merged[j, 1]
    return k + 1


@njit(cache=True)
def on_arcs(psi: float, arcs: np.ndarray, i: int, n: int) -> bool:
    if n == FULL:
        return True
    for j in range(n):
        if (psi - arcs[i, j, 0]) % TWO_PI <= arcs[i, j, 1] - arcs[i, j, 0]:
            return True
    return False
