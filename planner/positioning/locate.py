"""Locating a receiver on a planned site: identify the luminaires seen, then position.

IDs repeat across a site (the paper's regions, the window scheme), so the receiver
identifies luminaires as a phone app would: every luminaire whose ID matches is a
candidate; candidates whose spacing disagrees with the spacing the ellipse sizes
suggest are dropped; each remaining combination is fitted with the full-perspective
method (:mod:`planner.positioning.perspective`) and kept only if one pose explains every ellipse
within ``max_residual_px``. Exactly one place must remain.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from planner.camera.ellipse import Ellipse, centre_and_shape
from planner.camera.model import Camera, disc_dual_conic
from planner.defaults import MAX_RESIDUAL_PX
from planner.errors import InputError, PositioningError
from planner.positioning.error_terms import DEFAULT_TERMS, ErrorTerms
from planner.positioning.fix import Fix, anchor_triple, bearings, check_geometry, ellipse_residuals, rms
from planner.positioning.gravity import locate_gravity, refine_gravity, two_point_pose, window_order
from planner.positioning.paper import distance_weak_perspective, locate_paper
from planner.positioning.perspective import initial_poses, locate_perspective
from planner.positioning.undistort import ideal_ellipses

if TYPE_CHECKING:
    from planner.plan.file import PlanFile

SPACING_TOLERANCE = 0.35
"""Relative error allowed between a luminaire pair's spacing and its weak-perspective estimate."""

METHODS = {"perspective": locate_perspective, "paper": locate_paper}


@dataclass(frozen=True)
class Site:
    """The planned luminaires: names, centres (N x 3) [m], radii (N,) [m], IDs (N,); for a gravity plan,
    the longest two-LED window its receiver reads [m] (None: no cap; docs/verification.md); the error
    budget the perspective and gravity fits weigh their measurements by (the plan's, else the defaults)."""

    names: list[str]
    xyz: np.ndarray
    radii: np.ndarray
    ids: np.ndarray
    window_length_cap_m: float | None = None
    terms: ErrorTerms = DEFAULT_TERMS

    @classmethod
    def from_plan(cls, plan: PlanFile) -> Site:
        recorded = plan.accuracy.terms if plan.accuracy is not None else None
        return cls(plan.names, plan.xyz, plan.radii, plan.ids, plan.window_length_cap_m,
                   ErrorTerms.from_dict(recorded) if recorded else DEFAULT_TERMS)


@dataclass(frozen=True)
class Snapshot:
    """What a receiver reports from one image: its camera, and each LED's decoded ID and ellipse;
    with an accelerometer, ``gravity`` (unit vector down, camera frame) and its uncertainty [rad]."""

    camera: Camera
    ids: list[int]
    ellipses: list[Ellipse]
    gravity: np.ndarray | None = None
    gravity_sigma_rad: float = math.radians(1.0)

    def ideal(self) -> Snapshot:
        """This snapshot undistorted (:func:`planner.positioning.undistort.ideal_ellipses`): ellipses and
        camera as an ideal pinhole sees them; itself when the camera does not distort."""
        ellipses, camera = ideal_ellipses(self.ellipses, self.camera)
        return self if camera is self.camera else Snapshot(camera, self.ids, ellipses, self.gravity,
                                                            self.gravity_sigma_rad)


@dataclass(frozen=True)
class Located:
    """A position with the luminaires it rests on (``luminaires``: index per LED of the snapshot)."""

    fix: Fix
    luminaires: np.ndarray


def _spacing_ok(pa: np.ndarray, pb: np.ndarray, xa: np.ndarray, xb: np.ndarray) -> np.ndarray:
    """Candidate pairs whose spacing matches the image's estimate: (len(pa), len(pb)) booleans."""
    est = np.linalg.norm(pa[:, None] - pb[None], axis=2)
    true = np.linalg.norm(xa[:, None] - xb[None], axis=2)
    return np.abs(est - true) <= SPACING_TOLERANCE * est + 0.05


def _complete(site: Site, snap: Snapshot, anchor: list[int], combo: tuple, position: np.ndarray,
              rotation: np.ndarray) -> np.ndarray | None:
    """Luminaire per LED: the anchor's combo, and for the rest the same-ID luminaire imaged nearest
    (within its ellipse's major axis, at least 10 px). LEDs too far off for the anchor's pose are
    tried once more from a pose refitted on all matched ones: at a wide lens's edge a pose error of
    a fraction of a degree moves an ideal-pinhole image by more than its size (1 of 300 office poses
    through the 150 deg fisheye, measured 2026-12-03)."""
    out = np.full(len(snap.ids), -1)
    out[anchor] = combo
    for attempt in range(2):
        left = []
        for k in np.flatnonzero(out < 0):
            cand = np.flatnonzero(site.ids == snap.ids[k])
            c, _, ok = centre_and_shape(disc_dual_conic(position, rotation, site.xyz[cand], site.radii[cand],
                                                        snap.camera))
            dist = np.where(ok, np.linalg.norm(c - snap.ellipses[k].centre, axis=1), np.inf)
            best = int(np.argmin(dist))
            if dist[best] > max(10.0, snap.ellipses[k].major):
                left.append(k)
            else:
                out[k] = cand[best]
        if not left:
            return out
        if attempt:
            return None
        matched = list(anchor) + [k for k in np.flatnonzero(out >= 0).tolist() if k not in anchor]
        try:
            position, rotation = _refit(site, snap, out[matched], matched)
        except PositioningError:
            return None
    return None


def _refit(site: Site, snap: Snapshot, luminaires: np.ndarray, leds: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """The pose from the matched LEDs (the anchor first): with gravity, or full perspective."""
    ellipses = [snap.ellipses[k] for k in leds]
    xyz, radii = site.xyz[luminaires], site.radii[luminaires]
    if snap.gravity is not None:
        fix = locate_gravity(xyz, radii, ellipses, snap.camera, snap.gravity, snap.gravity_sigma_rad, site.terms)
    else:
        fix = locate_perspective(xyz, radii, ellipses, snap.camera, site.terms)
    return fix.position, fix.rotation


def identify(site: Site, snap: Snapshot, max_residual_px: float = MAX_RESIDUAL_PX) -> Located:
    """The one set of luminaires whose exact images, at one pose, match the snapshot's ellipses
    (a distorted snapshot is undistorted first)."""
    snap = snap.ideal()
    cam, n = snap.camera, len(snap.ids)
    if n < 3:
        raise PositioningError(f"{n} LED{'s' if n != 1 else ''} in the image: a position needs at least three")
    cands = [np.flatnonzero(site.ids == i) for i in snap.ids]
    centres = np.array([e.centre for e in snap.ellipses])
    shapes = np.array([e.shape for e in snap.ellipses])
    anchor = anchor_triple(centres)
    rays = bearings(centres[anchor], cam)
    focal = float(np.sqrt(cam.fx_px * cam.fy_px))
    est = [np.array([distance_weak_perspective(snap.ellipses[k], r, focal, cam.cx_px, cam.cy_px)
                     for r in site.radii[cands[k]]])[:, None] * rays[j] for j, k in enumerate(anchor)]
    xs = [site.xyz[cands[k]] for k in anchor]
    ok01, ok02, ok12 = (_spacing_ok(est[a], est[b], xs[a], xs[b]) for a, b in ((0, 1), (0, 2), (1, 2)))
    found: list[Located] = []
    best_rejected = np.inf
    tried: set[tuple] = set()
    for i, j in zip(*np.nonzero(ok01)):
        for k in np.flatnonzero(ok02[i] & ok12[j]):
            combo = (cands[anchor[0]][i], cands[anchor[1]][j], cands[anchor[2]][k])
            if len(set(combo)) < 3:
                continue
            starts = initial_poses(site.xyz[list(combo)], site.radii[list(combo)],
                                   [snap.ellipses[a] for a in anchor], [0, 1, 2], cam)
            for position, rotation in starts:
                lum = _complete(site, snap, anchor, combo, position, rotation)
                if lum is None or len(set(lum)) < n or tuple(lum) in tried:
                    continue
                r = rms(ellipse_residuals(position, rotation, site.xyz[lum], site.radii[lum], centres, shapes, cam))
                if r > 20 * max_residual_px:
                    best_rejected = min(best_rejected, r)
                    continue
                tried.add(tuple(lum))
                check_geometry(site.xyz[lum])
                fix = locate_perspective(site.xyz[lum], site.radii[lum], snap.ellipses, cam, site.terms)
                if fix.residual_px > max_residual_px:
                    best_rejected = min(best_rejected, fix.residual_px)
                else:
                    found.append(Located(fix, lum))
    return only_place(site, found, best_rejected, max_residual_px, "", ", ".join(map(str, snap.ids)),
                      "the camera intrinsics")


def only_place(site: Site, found: list[Located], best_rejected: float, max_residual_px: float, how: str,
               ids: str, check: str) -> Located:
    """The one fix in ``found``; :class:`PositioningError` naming the IDs (``ids``) and what to ``check``
    when none fits, or both places when two do. ``how`` says how the image was read (" with gravity")."""
    if not found:
        detail = f" (best fit {best_rejected:.1f} px RMS, limit {max_residual_px:g} px)" if np.isfinite(best_rejected) else ""
        raise PositioningError(f"no place on the site explains the image{how}: no luminaires with IDs "
                               f"{ids} are seen this way from any pose{detail}; check the decoded IDs and {check}")
    if len(found) > 1:
        a, b = found[0], found[1]
        raise PositioningError(
            f"the image fits two places: luminaires {', '.join(site.names[i] for i in a.luminaires)} "
            f"at {_fmt(a.fix.position)} and {', '.join(site.names[i] for i in b.luminaires)} at "
            f"{_fmt(b.fix.position)}; run vlp-verify on the plan, or include more LEDs in the image")
    return found[0]


def identify_gravity(site, snap, max_residual_px: float = MAX_RESIDUAL_PX):
    """The one place whose luminaires explain the snapshot, from its two-LED window and gravity.

    Every pair of luminaires carrying the window's two IDs (no farther apart than the plan's window
    length cap, where it has one: a longer pair is no window of the plan) is tried: closed form, the other LEDs
    matched to the same-ID luminaire imaged nearest, a refined fix on all of them; a place counts
    when that fix explains every ellipse within ``max_residual_px``. Exactly one must remain.
    """
    if snap.gravity is None:
        raise PositioningError("the snapshot has no gravity: the two-LED receiver needs the accelerometer's vertical")
    cam, n = snap.camera, len(snap.ids)
    if n < 2:
        raise PositioningError(f"{n} LED{'s' if n != 1 else ''} in the image: a position with gravity needs two")
    centres = np.array([e.centre for e in snap.ellipses])
    first, second = (int(k) for k in window_order(centres, cam)[:2])
    rays = cam.rays(centres)
    found, tried, best_rejected = [], set(), np.inf
    cap = site.window_length_cap_m
    for a in np.flatnonzero(site.ids == snap.ids[first]):
        for b in np.flatnonzero(site.ids == snap.ids[second]):
            if a == b or (cap is not None and np.linalg.norm(site.xyz[a] - site.xyz[b]) > cap + 1e-9):
                continue
            try:  # the closed form, refined on the two (their images' sizes check the spacing)
                start = two_point_pose(site.xyz[[a, b]], rays[[first, second]], snap.gravity)
                position, rotation, _ = refine_gravity(*start, site.xyz[[a, b]], site.radii[[a, b]],
                                                       [snap.ellipses[first], snap.ellipses[second]], snap.gravity,
                                                       snap.gravity_sigma_rad, cam)
            except PositioningError:
                continue
            lum = _complete(site, snap, [first, second], (a, b), position, rotation)
            if lum is None or len(set(lum.tolist())) < n or tuple(lum) in tried:
                continue
            tried.add(tuple(lum))
            order = [first, second] + [k for k in range(n) if k not in (first, second)]
            fix = locate_gravity(site.xyz[lum[order]], site.radii[lum[order]], [snap.ellipses[k] for k in order],
                                 cam, snap.gravity, snap.gravity_sigma_rad, site.terms)
            if fix.residual_px > max_residual_px:
                best_rejected = min(best_rejected, fix.residual_px)
            else:
                found.append(Located(fix, lum))
    return only_place(site, found, best_rejected, max_residual_px, " with gravity",
                      f"{snap.ids[first]} and {snap.ids[second]}", "the camera intrinsics and the gravity vector")


def _fmt(p: np.ndarray) -> str:
    return "(" + ", ".join(f"{v:.2f}" for v in p) + ") m"


def locate(site: Site, snap: Snapshot, method: str = "perspective", max_residual_px: float = MAX_RESIDUAL_PX) -> Located:
    """Identify the luminaires in ``snap`` and position the camera with ``method`` (``paper`` or ``perspective``)."""
    if method not in METHODS:
        raise InputError(f"unknown positioning method {method!r}; use one of: {', '.join(METHODS)}")
    for k, i in enumerate(snap.ids):
        if not np.any(site.ids == i):
            raise InputError(f"leds[{k}]: ID {i} is not in the plan (IDs there run {site.ids.min()}..{site.ids.max()}); "
                             "check the decoding, or that this plan is the site's")
    snap = snap.ideal()
    if snap.gravity is not None:  # the gravity-aided receiver: two-LED window, two points plus gravity
        return identify_gravity(site, snap, max_residual_px)
    found = identify(site, snap, max_residual_px)
    if method == "perspective":
        return found
    lum = found.luminaires
    return Located(locate_paper(site.xyz[lum], site.radii[lum], snap.ellipses, snap.camera), lum)


def refine_on_centres(site: Site, snap: Snapshot, found: Located, max_residual_px: float = MAX_RESIDUAL_PX) -> Located:
    """``found``'s pose refitted to the ellipse centres alone (Levenberg-Marquardt from ``found``, OpenCV's
    iterative PnP): for LEDs whose ellipse sizes read large (a clipped core's rim lies out by the blur) while
    their centres hold (docs/tones.md). Four LEDs or more; ``found`` itself with fewer, or where the centres
    fit no pose within ``max_residual_px`` RMS."""
    import cv2  # here, not at import: commands that never locate skip loading it

    snap = snap.ideal()
    lum = found.luminaires
    if len(lum) < 4:
        return found
    xyz, centres = site.xyz[lum].astype(np.float64), np.array([e.centre for e in snap.ellipses], np.float64)
    to_camera = found.fix.rotation.T
    ok, rvec, tvec = cv2.solvePnP(xyz, centres, snap.camera.intrinsics, None, cv2.Rodrigues(to_camera)[0],
                                  (-to_camera @ found.fix.position).reshape(3, 1), True, cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        return found
    back, _ = cv2.projectPoints(xyz, rvec, tvec, snap.camera.intrinsics, None)
    if rms(back.reshape(-1, 2) - centres) > max_residual_px:
        return found
    to_camera = cv2.Rodrigues(rvec)[0]
    return Located(replace(found.fix, position=-to_camera.T @ tvec.ravel(), rotation=to_camera.T), lum)
