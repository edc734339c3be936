"""One pose box of the certificate (:mod:`planner.verify.certify`): every window it may hold, compiled with numba.

A *pose box* fixes ranges of the axis point ``q`` (where the optical axis meets the ceiling) [m], the
ceiling distance ``h`` [m], the tilt ``τ`` and the tilt's plan direction ``φ`` [rad]; the roll is free.
Frame ``F = Rz(φ) Ry(τ)``: an LED whose centre lies ``(α, β)`` from ``q`` in the plan frame turned by ``φ``
images at ``m = (α cos τ, β) / (L + α sin τ)``, ``L = h / cos τ`` (normalised coordinates, before roll;
docs/verification.md, "The certificate over pose boxes"). With ``V = |c - q|`` and ``p = cos(Δ) sin τ``
(``Δ`` the LED's direction from ``q`` less ``φ``) the ray angle is ``tan θ = V sqrt(1 - p^2) / (L + V p)``:
increasing in ``V``, decreasing in ``L``, unimodal in ``p``, so its range over a box is exact in those three.

Roll is handled exactly: at roll ``ψ`` the LED's centre images at ``t (cos(γ), sin(γ))``, ``γ = β'' - ψ``, and
the disc is wholly inside the view rectangle ``|x| <= A, |y| <= B`` iff for each side the plane through the
camera and that side has the disc on its inner side: ``g·w + r |hor(g)| <= 0`` (``g = (u, -A)``, ``w`` the
centre in the camera frame, ``hor`` the horizontal part of ``g`` in the site). Bounding ``|hor(g)|`` above and
below over the box gives, per LED, the rolls at which it is **surely** seen and those at which it **may** be
seen: unions of at most four arcs each, in closed form (:func:`_g_arcs`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

TWO_PI = 2.0 * math.pi
ARC_EPS = 1e-9
"""Sure arcs are shrunk and possible arcs grown by this much [rad], against rounding."""
REL_EPS = 1e-9
"""Relative slack on every ray-angle bound, against rounding."""
FULL = -1
"""Arc count meaning the whole circle."""


@njit(cache=True)
def _cut(pieces: np.ndarray, n: int, s2: float, e2: float, tmp: np.ndarray) -> int:
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
    pieces[:k] = tmp[:k]
    return k


@njit(cache=True)
def _gamma_arcs(limits: np.ndarray, pieces: np.ndarray, tmp: np.ndarray) -> int:
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
        else:
            n = _cut(pieces, n, c + g, c + TWO_PI - g, tmp)
        if n == 0:
            return 0
    return FULL if n < 0 else n


@njit(cache=True)
def _limit(num: float, t_lo: float, t_hi: float, sure: bool) -> float:
    """Bound on ``cos`` from ``t cos <= num`` for ``t in [t_lo, t_hi]``: for every such ``t`` (``sure``) or for some."""
    if num >= 0.0:
        t = t_hi if sure else t_lo
    else:
        t = t_lo if sure else t_hi
    if t <= 0.0:
        return math.inf if num >= 0.0 else -math.inf
    return num / t


@njit(cache=True)
def _cos_range(d0: float, d1: float) -> tuple[float, float]:
    """Least and greatest ``cos`` over ``[d0, d1]`` [rad]."""
    if d1 - d0 >= TWO_PI:
        return -1.0, 1.0
    lo, hi = min(math.cos(d0), math.cos(d1)), max(math.cos(d0), math.cos(d1))
    if TWO_PI * math.ceil(d0 / TWO_PI) <= d1:
        hi = 1.0
    if math.pi + TWO_PI * math.ceil((d0 - math.pi) / TWO_PI) <= d1:
        lo = -1.0
    return lo, hi


@njit(cache=True)
def _corr(delta: float, ct: float) -> float:
    """Image direction less plan direction: ``atan2(sin Δ cos Δ (1 - cos τ), cos^2 Δ cos τ + sin^2 Δ)``."""
    s, c = math.sin(delta), math.cos(delta)
    return math.atan2(s * c * (1.0 - ct), c * c * ct + s * s)


@njit(cache=True)
def _corr_range(d0: float, d1: float, t0: float, t1: float) -> tuple[float, float]:
    """Range of :func:`_corr` over ``Δ in [d0, d1]``, ``τ in [t0, t1]``: monotone in ``τ``, so at ``t0``, ``t1``;
    in ``Δ`` at the ends and where ``sin^2 Δ = cos τ / (1 + cos τ)``."""
    lo, hi = math.inf, -math.inf
    for tau in (t0, t1):
        ct = math.cos(tau)
        crit = math.asin(math.sqrt(ct / (1.0 + ct)))
        for delta in (d0, d1):
            v = _corr(delta, ct)
            lo, hi = min(lo, v), max(hi, v)
        k0 = int(math.floor(d0 / math.pi)) - 1
        k1 = int(math.ceil(d1 / math.pi)) + 1
        for k in range(k0, k1 + 1):
            for delta in (k * math.pi - crit, k * math.pi + crit):
                if d0 <= delta <= d1:
                    v = _corr(delta, ct)
                    lo, hi = min(lo, v), max(hi, v)
    return lo, hi


@njit(cache=True)
def _tan_angle(v: float, big_l: float, p: float) -> float:
    """``tan θ = V sqrt(1 - p^2) / (L + V p)``."""
    return v * math.sqrt(max(1.0 - p * p, 0.0)) / (big_l + v * p)


SECTORS = 16
"""Roll sectors over which the disc's margin at each image side is bounded separately."""
PIECES = 4
"""Most arcs of ``γ`` where an LED is seen: four conditions, each one arc, meet in at most four."""
ARCS = SECTORS * 2 * PIECES
"""Room for an LED's arcs of roll: each piece of ``γ`` gives one arc of roll, cut by its sector into at most two."""


SLICES = 8
"""Slices of the disc of centres (by direction from the axis point) whose ray angles are bounded separately."""


@njit(cache=True)
def _disc_range(v0: float, rv: float, base0: float, base1: float, dang: float, s0: float, s1: float,
                big_l0: float, big_l1: float) -> tuple[float, float]:
    """Range of ``tan θ`` over centres within ``rv`` of one ``v0`` from the axis point (``v0 > rv``), the disc cut
    into :data:`SLICES` by direction ``ω`` from its own: in a slice ``V`` lies between ``v0 cos ω -+ sqrt(rv^2 -
    v0^2 sin^2 ω)`` at the slice's least ``|ω|`` (both monotone in ``|ω|``), ``Δ`` in the slice's directions less
    ``φ`` (``base0 = ang - φ1``, ``base1 = ang - φ0``)."""
    lo, hi = math.inf, 0.0
    for k in range(SLICES):
        w0 = -dang + 2.0 * dang * k / SLICES
        w1 = -dang + 2.0 * dang * (k + 1) / SLICES
        near = 0.0 if w0 <= 0.0 <= w1 else min(abs(w0), abs(w1))
        root = math.sqrt(max(rv * rv - (v0 * math.sin(near)) ** 2, 0.0))
        v_lo, v_hi = max(v0 * math.cos(near) - root, 0.0), v0 * math.cos(near) + root
        c_lo, c_hi = _cos_range(base0 + w0, base1 + w1)
        p_lo, p_hi = min(c_lo * s0, c_lo * s1), max(c_hi * s0, c_hi * s1)
        lo = min(lo, _tan_angle(v_lo, big_l1, p_lo), _tan_angle(v_lo, big_l1, p_hi))
        pstar = min(max(-v_hi / big_l0, p_lo), p_hi)
        hi = max(hi, _tan_angle(v_hi, big_l0, pstar))
    return lo * (1.0 - REL_EPS), hi * (1.0 + REL_EPS)


@njit(cache=True)
def _margins(box: np.ndarray, view: np.ndarray) -> np.ndarray:
    """``|hor(g)|`` bounds per roll sector and image side (SECTORS, 2, 4): [k, 0] the largest (sure seeing, the
    inner half-sides), [k, 1] the least (possible seeing, the outer ones). ``|hor g|^2 = 1 + K^2 - (v·g)^2`` with
    ``v·g = -(n_x sin τ + K cos τ)``, ``n_x`` the side's normal along the tilt, a cosine of the roll."""
    tau0, tau1, phi0, phi1 = box[6], box[7], box[8], box[9]
    s0, s1, c0, c1 = math.sin(tau0), math.sin(tau1), math.cos(tau1), math.cos(tau0)
    out = np.empty((SECTORS, 2, 4))
    w = TWO_PI / SECTORS
    for k in range(SECTORS):
        lo, hi = k * w - phi1, (k + 1) * w - phi0  # ψ' = ψ'' - φ
        co_lo, co_hi = _cos_range(lo, hi)
        si_lo, si_hi = _cos_range(lo - 0.5 * math.pi, hi - 0.5 * math.pi)
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
def led_bounds(box: np.ndarray, xy: np.ndarray, radii: np.ndarray, view: np.ndarray, d: float,
               t_lo: np.ndarray, t_hi: np.ndarray, seen: np.ndarray, seen_n: np.ndarray, maybe: np.ndarray,
               maybe_n: np.ndarray) -> None:
    """Per LED over ``box`` (qx0, qx1, qy0, qy1, h0, h1, τ0, τ1, φ0, φ1): the ray angle's tangent range
    ``[t_lo, t_hi]``, and the rolls (arcs of ``ψ''``, count FULL = every roll) at which it is surely wholly seen
    (``seen``) and at which it may be (``maybe``), every centre within ``d`` of ``xy``.

    ``view`` = (A_in, B_in, A_out, B_out, wz_min): the largest half-sides inside the view rectangle and the
    smallest holding it (normalised), and the least depth of a centre in view [m].
    """
    qx0, qx1, qy0, qy1, h0, h1 = box[0], box[1], box[2], box[3], box[4], box[5]
    tau0, tau1, phi0, phi1 = box[6], box[7], box[8], box[9]
    qcx, qcy = 0.5 * (qx0 + qx1), 0.5 * (qy0 + qy1)
    rv = 0.5 * math.hypot(qx1 - qx0, qy1 - qy0) + d
    s0, s1 = math.sin(tau0), math.sin(tau1)
    big_l0, big_l1 = h0 / math.cos(tau0), h1 / math.cos(tau1)
    wz_min = view[4]
    kappa = _margins(box, view)
    pieces, tmp, lim = np.empty((PIECES, 2)), np.empty((PIECES, 2)), np.empty(4)
    one, tmp2 = np.empty((2, 2)), np.empty((2, 2))
    n_led = len(xy)
    blo, bhi, zlo, zhi = np.empty(n_led), np.empty(n_led), np.empty(n_led), np.empty(n_led)
    fdir, can, todo = np.zeros(n_led, np.bool_), np.zeros(n_led, np.bool_), np.zeros(n_led, np.bool_)
    k_sure = np.array([kappa[:, 0, side].max() for side in range(4)])
    k_may = np.array([kappa[:, 1, side].min() for side in range(4)])
    corner = math.hypot(view[2], view[3])  # tan of the outer rectangle's corner angle
    w = TWO_PI / SECTORS
    for i in range(len(xy)):
        vx, vy = xy[i, 0] - qcx, xy[i, 1] - qcy
        v0 = math.hypot(vx, vy)
        v_lo, v_hi = max(v0 - rv, 0.0), v0 + rv
        seen_n[i], maybe_n[i] = 0, 0
        # cheap exclusion first: tan θ >= V cos τ / (L + V sin τ) lies beyond the view's corner
        if v_lo * math.cos(tau1) > corner * (big_l1 + v_lo * s1):
            t_lo[i], t_hi[i] = math.inf, math.inf
            continue
        full_dir = v0 <= rv
        if full_dir:
            c_lo, c_hi, b_lo, b_hi = -1.0, 1.0, 0.0, TWO_PI
        else:
            ang0 = math.atan2(vy, vx)
            dang = math.asin(rv / v0)
            d0, d1 = ang0 - dang - phi1, ang0 + dang - phi0
            c_lo, c_hi = _cos_range(d0, d1)
            k_lo, k_hi = _corr_range(d0, d1, tau0, tau1)
            b_lo, b_hi = ang0 - dang + k_lo, ang0 + dang + k_hi
            full_dir = b_hi - b_lo >= TWO_PI
        p_lo, p_hi = min(c_lo * s0, c_lo * s1), max(c_hi * s0, c_hi * s1)
        wz_lo = big_l0 + min(v_lo * p_lo, v_hi * p_lo, v_lo * p_hi, v_hi * p_hi)
        wz_hi = big_l1 + max(v_lo * p_lo, v_hi * p_lo, v_lo * p_hi, v_hi * p_hi)
        if wz_hi < wz_min:  # never in view
            t_lo[i], t_hi[i] = math.inf, math.inf
            continue
        if wz_lo < wz_min:  # may lie far off the axis or behind: a lower bound only
            pm = max(abs(p_lo), abs(p_hi))
            t_lo[i] = v_lo * math.sqrt(max(1.0 - pm * pm, 0.0)) / wz_hi * (1.0 - REL_EPS)
            t_hi[i] = math.inf
        elif full_dir:
            t_lo[i] = min(_tan_angle(v_lo, big_l1, p_lo), _tan_angle(v_lo, big_l1, p_hi)) * (1.0 - REL_EPS)
            pstar = min(max(-v_hi / big_l0, p_lo), p_hi)
            t_hi[i] = _tan_angle(v_hi, big_l0, pstar) * (1.0 + REL_EPS)
        else:
            t_lo[i], t_hi[i] = _disc_range(v0, rv, ang0 - phi1, ang0 - phi0, math.asin(rv / v0), s0, s1, big_l0, big_l1)
        r = radii[i]
        can[i] = wz_lo > r * s1 + 1e-9 and t_hi[i] < math.inf
        blo[i], bhi[i], zlo[i], zhi[i], fdir[i] = b_lo, b_hi, wz_lo, wz_hi, full_dir
        # every roll at once, with the margins of the worst and best sector: most LEDs are decided here
        if can[i]:
            for side in range(4):
                lim[side] = _limit(view[side // 2] - r * k_sure[side] / wz_lo, t_lo[i], t_hi[i], True)
            if _gamma_arcs(lim, pieces, tmp) == FULL:
                seen_n[i], maybe_n[i] = FULL, FULL
                continue
        for side in range(4):
            lim[side] = _limit(view[side // 2 + 2] - r * k_may[side] / wz_hi, t_lo[i], t_hi[i], False)
        if _gamma_arcs(lim, pieces, tmp) == 0:
            t_lo[i] = math.inf  # never seen: out of every window
            continue
        todo[i] = True
    # LEDs beyond three that are surely seen at every roll and surely nearer are out of every window
    third = np.sort(np.where(seen_n == FULL, t_hi, math.inf))[min(2, len(xy) - 1)]
    for i in range(len(xy)):
        if not todo[i] or t_lo[i] > third:
            continue
        r, b_lo, b_hi, wz_lo, wz_hi, full_dir = radii[i], blo[i], bhi[i], zlo[i], zhi[i], fdir[i]
        all_seen, all_maybe = can[i], True
        for k in range(SECTORS):
            p0, p1 = k * w, (k + 1) * w
            for which in range(2):  # 0: surely seen, 1: may be seen
                sure = which == 0
                if sure and not can[i]:
                    continue
                for side in range(4):
                    half = view[side // 2 + 2 * which]
                    num = half - r * kappa[k, which, side] / (wz_lo if sure else wz_hi)
                    lim[side] = _limit(num, t_lo[i], t_hi[i], sure)
                n = _gamma_arcs(lim, pieces, tmp)
                arcs, count = (seen, seen_n) if sure else (maybe, maybe_n)
                if n == FULL or (not sure and n > 0 and full_dir):
                    arcs[i, count[i], 0], arcs[i, count[i], 1] = p0, p1
                    count[i] += 1
                    continue
                if sure:
                    all_seen = False
                else:
                    all_maybe = False
                if n == 0 or (sure and full_dir):
                    continue
                for j in range(n):  # ψ with [β_lo - ψ, β_hi - ψ] inside (sure) or meeting (may) the piece
                    if sure:
                        a, b = b_hi - pieces[j, 1] + ARC_EPS, b_lo - pieces[j, 0] - ARC_EPS
                    else:
                        a, b = b_lo - pieces[j, 1] - ARC_EPS, b_hi - pieces[j, 0] + ARC_EPS
                    if a > b:
                        continue
                    if b - a >= TWO_PI:
                        a, b = p0, p1
                    one[0, 0], one[0, 1] = p0, p1
                    m = _cut(one, 1, a, b, tmp2)
                    for q in range(m):  # room: ARCS per LED
                        arcs[i, count[i], 0], arcs[i, count[i], 1] = one[q, 0], one[q, 1]
                        count[i] += 1
        if all_seen:
            seen_n[i] = FULL
        elif seen_n[i] > 1:
            seen_n[i] = _merge(seen, i, seen_n[i])
        if all_maybe:
            maybe_n[i] = FULL
        elif maybe_n[i] > 1:
            maybe_n[i] = _merge(maybe, i, maybe_n[i])


@njit(cache=True)
def _merge(arcs: np.ndarray, i: int, n: int) -> int:
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
            merged[k] = merged[j]
    arcs[i, :k + 1] = merged[:k + 1]
    return k + 1


@njit(cache=True)
def _on(psi: float, arcs: np.ndarray, i: int, n: int) -> bool:
    if n == FULL:
        return True
    for j in range(n):
        if (psi - arcs[i, j, 0]) % TWO_PI <= arcs[i, j, 1] - arcs[i, j, 0]:
            return True
    return False


@njit(cache=True)
def box_windows(box: np.ndarray, xy: np.ndarray, radii: np.ndarray, view: np.ndarray, d: float, cap: int,
                out: np.ndarray) -> int:
    """Every triple (local indices, ascending, into ``out`` (M, 3)) that may be the window at a pose of ``box``
    at some roll, the LEDs ``xy`` (all that the box's poses may see) moved up to ``d``; their number, or -1
    when more than ``cap`` LEDs may be among the three nearest at one roll (or ``out`` is full): split the box.

    At one roll an LED is a candidate unless three others, surely seen there, are surely nearer; a
    triple of candidates is left out when an LED outside it, surely seen there, is surely nearer than its
    farthest member. The rolls where these verdicts change are the arcs' ends: each end and each piece
    between two is tested, so every roll is.
    """
    n = len(xy)
    t_lo, t_hi = np.empty(n), np.empty(n)
    seen, maybe = np.empty((n, ARCS, 2)), np.empty((n, ARCS, 2))
    seen_n, maybe_n = np.zeros(n, np.int64), np.zeros(n, np.int64)
    led_bounds(box, xy, radii, view, d, t_lo, t_hi, seen, seen_n, maybe, maybe_n)
    # LEDs surely seen at every roll: the third least t_hi among them rules out any LED beyond it
    always = np.sort(np.where(seen_n == FULL, t_hi, math.inf))
    rel = np.empty(n, np.int64)
    m = 0
    for i in range(n):
        if maybe_n[i] == 0:
            continue
        below = 0
        for k in range(min(4, n)):
            if always[k] < t_lo[i]:
                below += 1
        if below < 3:
            rel[m] = i
            m += 1
    rel = rel[:m]
    # the rolls to test: every arc end and the middle of every piece between two
    ends = []
    for led in rel:
        for j in range(max(seen_n[led], 0)):
            ends.append(seen[led, j, 0] % TWO_PI)
            ends.append(seen[led, j, 1] % TWO_PI)
        for j in range(max(maybe_n[led], 0)):
            ends.append(maybe[led, j, 0] % TWO_PI)
            ends.append(maybe[led, j, 1] % TWO_PI)
    ends.append(0.0)
    sorted_ends = np.sort(np.array(ends))
    e = np.empty(len(sorted_ends))
    ne = 0
    for x in sorted_ends:  # distinct ends only
        if ne == 0 or x > e[ne - 1]:
            e[ne] = x
            ne += 1
    e = e[:ne]
    rolls = np.empty(2 * len(e))
    for k in range(len(e)):
        rolls[2 * k] = e[k]
        nxt = e[k + 1] if k + 1 < len(e) else e[0] + TWO_PI
        rolls[2 * k + 1] = 0.5 * (e[k] + nxt)
    count = 0
    sure = np.zeros(m, np.bool_)
    cand = np.empty(m, np.int64)
    for psi in rolls:
        for a in range(m):
            sure[a] = _on(psi, seen, rel[a], seen_n[rel[a]])
        c = 0
        for a in range(m):
            i = rel[a]
            if not (sure[a] or _on(psi, maybe, i, maybe_n[i])):
                continue
            nearer = 0
            for b in range(m):
                if b != a and sure[b] and t_hi[rel[b]] < t_lo[i]:
                    nearer += 1
            if nearer < 3:
                cand[c] = a
                c += 1
        if c > cap:
            return -1
        for x in range(c):
            for y in range(x + 1, c):
                for z in range(y + 1, c):
                    ia, ib, ic = cand[x], cand[y], cand[z]
                    far = max(t_lo[rel[ia]], t_lo[rel[ib]], t_lo[rel[ic]])
                    beaten = False
                    for b in range(m):
                        if sure[b] and b != ia and b != ib and b != ic and t_hi[rel[b]] < far:
                            beaten = True
                            break
                    if beaten:
                        continue
                    t0, t1, t2 = rel[ia], rel[ib], rel[ic]  # ascending: rel is
                    dup = False
                    for k in range(count):
                        if out[k, 0] == t0 and out[k, 1] == t1 and out[k, 2] == t2:
                            dup = True
                            break
                    if not dup:
                        if count == len(out):
                            return -1
                        out[count, 0], out[count, 1], out[count, 2] = t0, t1, t2
                        count += 1
    return count


@njit(cache=True)
def pose_window(pose: np.ndarray, xy: np.ndarray, radii: np.ndarray, view: np.ndarray) -> tuple[int, int, int]:
    """The exact window (local indices ascending; -1s when fewer than three are wholly seen) at ``pose`` =
    (qx, qy, h, τ, φ, ψ''), roll ``ψ''`` measured as the image's ``x`` axis from the plan's (in frame ``F``
    turned by ``-φ``); ``view`` = (x_lo, x_hi, y_lo, y_hi) the view rectangle (normalised)."""
    qx, qy, h, tau, phi, psi = pose[0], pose[1], pose[2], pose[3], pose[4], pose[5]
    ct, st, cf, sf = math.cos(tau), math.sin(tau), math.cos(phi), math.sin(phi)
    rp = psi - phi
    ux, uy = math.cos(rp), math.sin(rp)
    # sides: normal g = (n, -k) for x <= k along n; v = site vertical in F = (-sin τ, 0, cos τ)
    gx = (ux, -ux, -uy, uy)
    gy = (uy, -uy, ux, -ux)
    gk = (view[1], -view[0], view[3], -view[2])
    best = np.full(3, math.inf)
    idx = np.full(3, -1, np.int64)
    big_l = h / ct
    for i in range(len(xy)):
        dx, dy = xy[i, 0] - qx, xy[i, 1] - qy
        al, be = dx * cf + dy * sf, -dx * sf + dy * cf
        wx, wy, wz = al * ct, be, big_l + al * st
        r = radii[i]
        if wz - r * st <= 1e-9:
            continue
        inside = True
        for s in range(4):
            vg = -st * gx[s] - gk[s] * ct
            norm2 = gx[s] * gx[s] + gy[s] * gy[s] + gk[s] * gk[s]
            if gx[s] * wx + gy[s] * wy - gk[s] * wz + r * math.sqrt(max(norm2 - vg * vg, 0.0)) > 0.0:
                inside = False
                break
        if not inside:
            continue
        t = (wx * wx + wy * wy) / (wz * wz)
        if t < best[2]:
            k = 2
            while k > 0 and best[k - 1] > t:
                best[k], idx[k] = best[k - 1], idx[k - 1]
                k -= 1
            best[k], idx[k] = t, i
    if idx[2] < 0:
        return -1, -1, -1
    srt = np.sort(idx)
    return srt[0], srt[1], srt[2]


@njit(cache=True)
def _tan2(pose: np.ndarray, x: float, y: float) -> float:
    """``tan^2 θ`` of a ceiling point at ``pose`` (qx, qy, h, τ, φ)."""
    dx, dy = x - pose[0], y - pose[1]
    al = dx * math.cos(pose[4]) + dy * math.sin(pose[4])
    be = -dx * math.sin(pose[4]) + dy * math.cos(pose[4])
    wz = pose[2] / math.cos(pose[3]) + al * math.sin(pose[3])
    return ((al * math.cos(pose[3])) ** 2 + be * be) / (wz * wz)


@njit(cache=True)
def box_witnesses(box: np.ndarray, xy: np.ndarray, radii: np.ndarray, view: np.ndarray, count: int, seed: int,
                  out: np.ndarray, favour: np.ndarray, d: float) -> int:
    """Exact windows (local indices ascending, into ``out`` (>= 8 + count, 3)) at the box's centre at 8 rolls and
    at ``count`` poses drawn uniformly in ``box`` (any roll): real windows, never a bound. With ``favour`` (local
    indices), of the installation that moves those LEDs ``d`` towards the box's axis point and every other
    LED ``d`` away from it (an installation within tolerance that favours them as the window)."""
    np.random.seed(seed)
    site = xy.copy()
    if len(favour):
        centre = np.array([0.5 * (box[2 * a] + box[2 * a + 1]) for a in range(5)])
        for i in range(len(xy)):  # along the gradient of tan θ at the box's centre
            gx = _tan2(centre, xy[i, 0] + 1e-6, xy[i, 1]) - _tan2(centre, xy[i, 0] - 1e-6, xy[i, 1])
            gy = _tan2(centre, xy[i, 0], xy[i, 1] + 1e-6) - _tan2(centre, xy[i, 0], xy[i, 1] - 1e-6)
            norm = math.hypot(gx, gy)
            if norm > 0.0:
                step = -d if (i == favour[0] or i == favour[1] or i == favour[2]) else d
                site[i, 0] += step * gx / norm * (1.0 - 1e-12)
                site[i, 1] += step * gy / norm * (1.0 - 1e-12)
    pose = np.empty(6)
    k = 0
    for j in range(8 + count):
        for a in range(5):
            lo, hi = box[2 * a], box[2 * a + 1]
            pose[a] = 0.5 * (lo + hi) if j < 8 else lo + (hi - lo) * np.random.random()
        pose[5] = TWO_PI * (j / 8.0 if j < 8 else np.random.random())
        a0, a1, a2 = pose_window(pose, site, radii, view)
        if a0 >= 0:
            out[k, 0], out[k, 1], out[k, 2] = a0, a1, a2
            k += 1
    return k
