"""The verification stage: is the plan decodable wherever the camera may be?

For poses sampled over the working area (:func:`planner.verify.windows.sample_poses`),
each pose's window is found and read as the receiver reads it: IDs in
counter-clockwise order plus the shape of the triangle. A pose is *covered* when
it sees three non-collinear LEDs, and *ambiguous* when another set of luminaires
anywhere on the site reads the same (PRODUCT.md, "What decodable means"): every
physical triple is searched (:mod:`planner.verify.rivals`), not only the windows the
sample produced. The statistics are those of a sample, and are labelled so; what
is proved for every pose is the window-set check (:class:`WindowSetCheck`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from planner.camera.model import Camera, Poses
from planner.defaults import INSTALL_TOLERANCE_M
from planner.verify.proof import Proof
from planner.verify.rivals import find_rivals, longest_side, shape_matches, site_triples
from planner.verify.window_set import window_superset
from planner.verify.windows import (
    CONGRUENCE_TOLERANCE_M,
    POSES_PER_M2,
    PoseWindows,
    WindowSet,
    canonical_windows,
    find_windows,
    sample_poses,
    working_area,
)

# Pose status codes, as in ``Verification.status``.
DECODABLE, AMBIGUOUS, COLLINEAR, TOO_FEW = 0, 1, 2, 3
STATUS_NAMES = ("decodable", "ambiguous", "collinear", "fewer than 3 LEDs seen")


@dataclass(frozen=True)
class WindowSetCheck:
    """Every triangle that may be a window, checked against every triple of the site.

    When ``complete``, the triangles are every triple that some pose of the envelope
    could take as its window (:mod:`planner.verify.proof`), and a check without
    conflicts proves decodability. Otherwise they are those the empty-triangle rule
    allows (:mod:`planner.verify.window_set`) with sides up to ``max_side_m``, a bound taken
    from pose samples, and ``reason`` says why there is no proof (docs/verification.md).
    """

    triangles: int
    conflicts: list
    max_side_m: float
    install_tolerance_m: float
    tolerance_m: float
    complete: bool = False
    reason: str = ""
    envelope: dict | None = None

    @property
    def proved(self) -> bool:
        """Every pose of the envelope that sees a window decodes to one place."""
        return self.complete and not self.conflicts

    def summary(self, names: list[str], limit: int = 5) -> dict:
        out: dict[str, object] = {
            "rule": "spindle, axis disc and empty triangle" if self.complete else "empty triangle",
            "max_side_m": round(self.max_side_m, 4),
            "max_side_from": "proof" if self.complete else "pose samples",
            "install_tolerance_m": self.install_tolerance_m,
            "congruence_tolerance_m": self.tolerance_m,
            "triangles": self.triangles,
            "read_alike": len(self.conflicts),
            "first_conflicts": [[[names[i] for i in t] for t in group] for group in self.conflicts[:limit]],
            "complete": self.complete,
            "proved": self.proved,
        }
        if self.envelope:
            out["envelope"] = self.envelope
        if self.reason:
            out["not_proved_because"] = self.reason
        return out


def check_window_set(xyz: np.ndarray, radii: np.ndarray, ids: np.ndarray, max_side_m: float, *,
                     tolerance_m: float = CONGRUENCE_TOLERANCE_M,
                     install_tolerance_m: float = INSTALL_TOLERANCE_M, proof: Proof | None = None) -> WindowSetCheck:
    """Find, for every triangle that may be a window, the triples that read like it.

    With a complete ``proof`` (:func:`planner.verify.proof.prove_window_set`) its triangles
    are checked; otherwise those the empty-triangle rule allows up to ``max_side_m``.
    """
    if proof is not None and proof.triangles is not None:  # a complete proof
        tri = proof.triangles
        max_side_m = longest_side(tri, xyz)
        site = proof.shape_matches(tolerance_m)
    else:
        tri = window_superset(xyz, radii, max_side_m, install_tolerance_m)
        site = shape_matches(tri, xyz, tolerance_m)
    rivals: dict[int, list] = {}
    for row, triple in find_rivals(tri, xyz, np.asarray(ids), tolerance_m, site=site):
        rivals.setdefault(row, []).append(triple)
    groups = sorted(([tuple(int(v) for v in tri[r])] + found for r, found in rivals.items()), key=lambda g: (-len(g), g))
    complete = proof is not None and proof.complete
    return WindowSetCheck(len(tri), groups, max_side_m, install_tolerance_m, tolerance_m, complete,
                          proof.reason if proof is not None else "no proof attempted",
                          proof.envelope if proof is not None else None)


class Windows(Protocol):
    """Distinct windows seen, one row of luminaire indices each: a :class:`WindowSet` (three LEDs) or a
    :class:`planner.verify.pair_windows.PairSet` (two LEDs with gravity)."""

    @property
    def windows(self) -> np.ndarray: ...

    def __len__(self) -> int: ...


def side_bound(ws: Windows, xyz: np.ndarray, tolerance_m: float) -> float:
    """Longest side of the windows ``ws`` plus the tolerance [m]: the sampled side bound."""
    return longest_side(ws.windows, xyz) + tolerance_m if len(ws) else 0.0


@dataclass(frozen=True)
class Verification:
    """Result of verifying a plan over sampled poses.

    Attributes
    ----------
    position : numpy.ndarray, shape (P, 3)
        Sampled camera positions [m].
    status : numpy.ndarray of int, shape (P,)
        ``DECODABLE``, ``AMBIGUOUS``, ``COLLINEAR`` or ``TOO_FEW`` for each pose.
    windows : Windows
        The distinct non-collinear windows seen (triples, or pairs for the two-LED receiver).
    conflicts : list of list of tuple
        A sampled window (luminaire index triple) followed by the triples of the site that read
        like it, one group per such window, largest first.
    per_m2, seed, tolerance_m : float, int, float
        How the poses were sampled and how congruence was judged.
    """

    position: np.ndarray
    status: np.ndarray
    windows: Windows
    conflicts: list
    per_m2: float
    seed: int
    tolerance_m: float
    window_set: WindowSetCheck | None = None

    @property
    def clean(self) -> bool:
        """No sampled pose is ambiguous and no triangle of the window set reads like another triple."""
        return not self.conflicts and not (self.window_set and self.window_set.conflicts)

    @property
    def poses(self) -> int:
        return len(self.status)

    def count(self, code: int) -> int:
        return int(np.count_nonzero(self.status == code))

    @property
    def coverage(self) -> float:
        """Share of sampled poses that decode uniquely."""
        return self.count(DECODABLE) / self.poses if self.poses else 0.0

    @property
    def decodability(self) -> str:
        """``proved`` when the window set is proved complete and no window reads like another triple (nor
        any sampled pose is ambiguous), else ``sampled only``."""
        proved = bool(self.window_set and self.window_set.proved and not self.conflicts)
        return "proved" if proved else "sampled only"

    def summary(self, names: list[str], limit: int = 5) -> dict:
        """The ``verification`` mapping of ``plan.yaml``."""
        covered = self.count(DECODABLE) + self.count(AMBIGUOUS)
        return {
            "decodability": self.decodability,
            "method": "sampled",
            "poses": self.poses,
            "poses_per_m2": self.per_m2,
            "seed": self.seed,
            "congruence_tolerance_m": self.tolerance_m,
            "covered": covered,
            "ambiguous": self.count(AMBIGUOUS),
            "collinear": self.count(COLLINEAR),
            "too_few_leds": self.count(TOO_FEW),
            "coverage": round(self.coverage, 6),
            "windows": len(self.windows),
            "conflicting_keys": len(self.conflicts),
            "first_conflicts": [[[names[i] for i in triple] for triple in group] for group in self.conflicts[:limit]],
            "window_set": self._window_set_summary(names, limit),
        }

    def _window_set_summary(self, names: list[str], limit: int) -> dict | None:
        """The window-set check, with how tight the set is: its size beside the distinct windows of this sample."""
        if self.window_set is None:
            return None
        out = self.window_set.summary(names, limit)
        if "triangles" not in out or not len(self.windows):
            return out
        tight = {"sampled_windows": len(self.windows), "over_sampled": round(out["triangles"] / len(self.windows), 2)}
        return {k: v for key, value in out.items() for k, v in ((key, value), *(tight.items() if key == "triangles" else ()))}


@dataclass(frozen=True)
class Observation:
    """What the camera sees over one pose sample: geometry only, independent of the IDs.

    Computed once per sample and reused for every ID assignment checked on it.
    ``site`` are the physical triples short enough to read like a sampled window.
    """

    position: np.ndarray
    windows_per_pose: PoseWindows
    windows: WindowSet
    per_m2: float
    seed: int
    tolerance_m: float
    xyz: np.ndarray
    site: np.ndarray


def observe_poses(poses: Poses, xyz: np.ndarray, radii: np.ndarray, camera: Camera, *, per_m2: float, seed: int,
                  tolerance_m: float = CONGRUENCE_TOLERANCE_M, windows: PoseWindows | None = None) -> Observation:
    """Find each pose's window (unless ``windows`` has them), and the site's triples that could read like one."""
    pw = find_windows(poses, xyz, radii, camera) if windows is None else windows
    ws = canonical_windows(pw.triples[pw.covered], xyz, tolerance_m)
    site = site_triples(xyz[:, :2], side_bound(ws, xyz, tolerance_m) + 1e-9) if len(ws) else np.empty((0, 3), np.int64)
    return Observation(poses.position, pw, ws, per_m2, seed, tolerance_m, xyz, site)


def observe_site(xyz: np.ndarray, radii: np.ndarray, outline, camera: Camera, *, per_m2: float = POSES_PER_M2,
            seed: int = 0, tolerance_m: float = CONGRUENCE_TOLERANCE_M) -> Observation:
    """Sample poses over the working area and find each pose's window."""
    poses = sample_poses(working_area(xyz[:, :2], outline), camera, per_m2, seed)
    return observe_poses(poses, xyz, radii, camera, per_m2=per_m2, seed=seed, tolerance_m=tolerance_m)


def conflict_groups(obs: Observation, ids: np.ndarray) -> tuple[list, np.ndarray]:
    """Sampled windows that some other triple of the site reads like under ``ids``.

    Returns the groups (window first, then its rivals; largest first) and a per-window flag.
    """
    ws = obs.windows
    shared = np.zeros(len(ws), dtype=bool)
    rivals: dict[int, list] = {}
    for row, triple in find_rivals(ws.windows, obs.xyz, np.asarray(ids), obs.tolerance_m, site=obs.site):
        rivals.setdefault(row, []).append(triple)
    groups = []
    for row, found in rivals.items():
        shared[row] = True
        groups.append([tuple(int(v) for v in ws.windows[row])] + found)
    return sorted(groups, key=lambda g: (-len(g), g)), shared


def classify(obs: Observation, ids: np.ndarray) -> Verification:
    """Each pose of an observation as decodable, ambiguous, collinear or too few LEDs seen, under ``ids``."""
    pw = obs.windows_per_pose
    status = np.full(len(pw.triples), TOO_FEW, dtype=np.int64)
    status[pw.collinear] = COLLINEAR
    covered = pw.covered
    status[covered] = DECODABLE
    groups, shared = conflict_groups(obs, np.asarray(ids))
    if shared.any():
        bad = {tuple(sorted(w)) for w in obs.windows.windows[shared].tolist()}
        idx = np.flatnonzero(covered)
        hit = np.array([tuple(t) in bad for t in pw.triples[idx].tolist()], dtype=bool)
        status[idx[hit]] = AMBIGUOUS
    return Verification(obs.position, status, obs.windows, groups, obs.per_m2, obs.seed, obs.tolerance_m)


def verify_plan(xyz: np.ndarray, radii: np.ndarray, ids: np.ndarray, outline, camera: Camera, *,
                per_m2: float = POSES_PER_M2, seed: int = 0,
                tolerance_m: float = CONGRUENCE_TOLERANCE_M) -> Verification:
    """Sample poses and classify each as decodable, ambiguous, collinear or too few LEDs seen."""
    obs = observe_site(xyz, radii, outline, camera, per_m2=per_m2, seed=seed, tolerance_m=tolerance_m)
    return classify(obs, ids)


def design_windows(xyz: np.ndarray, radii: np.ndarray, outline, camera: Camera, *,
                   per_m2: float = 2 * POSES_PER_M2, seed: int = 1,
                   tolerance_m: float = CONGRUENCE_TOLERANCE_M) -> WindowSet:
    """Windows to make unique when choosing IDs: from a denser pose sample than verification's."""
    poses = sample_poses(working_area(xyz[:, :2], outline), camera, per_m2, seed)
    pw = find_windows(poses, xyz, radii, camera)
    return canonical_windows(pw.triples[pw.covered], xyz, tolerance_m)
