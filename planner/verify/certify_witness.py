"""Exact windows for the certificate (:mod:`planner.verify.certify`): real windows at poses given by axis point,
ceiling distance, tilt, its direction and roll, compiled with numba (the same disc images and view as
:func:`planner.camera.project_discs`, tests/verify/test_certify.py)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from planner.verify.certify_roll import TWO_PI


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
