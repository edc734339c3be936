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
seen: in each of 16 roll sectors, at most four arcs, in closed form (:mod:`planner.verify.certify_roll`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from planner.verify.certify_roll import (
    ARC_EPS,
    ARCS,
    FULL,
    PIECES,
    SECTORS,
    TWO_PI,
    cos_limit,
    cos_range,
    cut_arcs,
    gamma_arcs,
    merge_arcs,
    on_arcs,
    side_margins,
)

REL_EPS = 1e-9
"""Relative slack on every ray-angle bound, against rounding."""


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
        c_lo, c_hi = cos_range(base0 + w0, base1 + w1)
        p_lo, p_hi = min(c_lo * s0, c_lo * s1), max(c_hi * s0, c_hi * s1)
        lo = min(lo, _tan_angle(v_lo, big_l1, p_lo), _tan_angle(v_lo, big_l1, p_hi))
        pstar = min(max(-v_hi / big_l0, p_lo), p_hi)
        hi = max(hi, _tan_angle(v_hi, big_l0, pstar))
    return lo * (1.0 - REL_EPS), hi * (1.0 + REL_EPS)


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
    kappa = side_margins(box, view)
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
            c_lo, c_hi = cos_range(d0, d1)
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
                lim[side] = cos_limit(view[side // 2] - r * k_sure[side] / wz_lo, t_lo[i], t_hi[i], np.bool_(True))
            if gamma_arcs(lim, pieces, tmp) == FULL:
                seen_n[i], maybe_n[i] = FULL, FULL
                continue
        for side in range(4):
            lim[side] = cos_limit(view[side // 2 + 2] - r * k_may[side] / wz_hi, t_lo[i], t_hi[i], np.bool_(False))
        if gamma_arcs(lim, pieces, tmp) == 0:
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
                    lim[side] = cos_limit(num, t_lo[i], t_hi[i], sure)
                n = gamma_arcs(lim, pieces, tmp)
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
                    m = cut_arcs(one, np.int64(1), a, b, tmp2)  # not literals: one signature to compile
                    for q in range(m):  # room: ARCS per LED
                        arcs[i, count[i], 0], arcs[i, count[i], 1] = one[q, 0], one[q, 1]
                        count[i] += 1
        if all_seen:
            seen_n[i] = FULL
        elif seen_n[i] > 1:
            seen_n[i] = merge_arcs(seen, i, seen_n[i])
        if all_maybe:
            maybe_n[i] = FULL
        elif maybe_n[i] > 1:
            maybe_n[i] = merge_arcs(maybe, i, maybe_n[i])


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
            sure[a] = on_arcs(psi, seen, rel[a], seen_n[rel[a]])
        c = 0
        for a in range(m):
            i = rel[a]
            if not (sure[a] or on_arcs(psi, maybe, i, maybe_n[i])):
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
