"""The verification stage: is the plan decodable wherever the camera may be?

For poses sampled over the working area (:func:`planner.windows.sample_poses`),
each pose's window is found and keyed as the receiver reads it: IDs in
counter-clockwise order plus the congruence class of the triangle. A pose is
*covered* when it sees three non-collinear LEDs, and *ambiguous* when another set
of luminaires has the same key (PRODUCT.md, "What decodable means").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .camera import Camera
from .window_code import window_keys
from .windows import CONGRUENCE_TOLERANCE_M, POSES_PER_M2, PoseWindows, WindowSet, canonical_windows, \
    find_windows, sample_poses, working_area

# Pose status codes, as in ``Verification.status``.
DECODABLE, AMBIGUOUS, COLLINEAR, TOO_FEW = 0, 1, 2, 3
STATUS_NAMES = ("decodable", "ambiguous", "collinear", "fewer than 3 LEDs seen")


@dataclass(frozen=True)
class Verification:
    """Result of verifying a plan over sampled poses.

    Attributes
    ----------
    position : numpy.ndarray, shape (P, 3)
        Sampled camera positions [m].
    status : numpy.ndarray of int, shape (P,)
        ``DECODABLE``, ``AMBIGUOUS``, ``COLLINEAR`` or ``TOO_FEW`` for each pose.
    windows : WindowSet
        The distinct non-collinear windows seen.
    conflicts : list of list of tuple
        Groups of windows (luminaire index triples) sharing one key, largest first.
    per_m2, seed, tolerance_m : float, int, float
        How the poses were sampled and how congruence was judged.
    """

    position: np.ndarray
    status: np.ndarray
    windows: WindowSet
    conflicts: list
    per_m2: float
    seed: int
    tolerance_m: float

    @property
    def poses(self) -> int:
        return len(self.status)

    def count(self, code: int) -> int:
        return int(np.count_nonzero(self.status == code))

    @property
    def coverage(self) -> float:
        """Share of sampled poses that decode uniquely."""
        return self.count(DECODABLE) / self.poses if self.poses else 0.0

    def summary(self, names: list[str], limit: int = 5) -> dict:
        """The ``verification`` mapping of ``plan.yaml``."""
        covered = self.count(DECODABLE) + self.count(AMBIGUOUS)
        return {
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
        }


def conflict_groups(ws: WindowSet, ids: np.ndarray) -> tuple[list, np.ndarray]:
    """Windows that share a key under ``ids`` (1-based): groups of triples, and a per-window flag."""
    if len(ws) == 0:
        return [], np.zeros(0, dtype=bool)
    keys = window_keys(ws.windows, ws.shape, ws.symmetric, ids - 1, int(ids.max()))
    uniq, inverse, counts = np.unique(keys, return_inverse=True, return_counts=True)
    shared = counts[inverse] > 1
    groups = {}
    for m in np.flatnonzero(shared):
        groups.setdefault(int(inverse[m]), []).append(tuple(int(v) for v in ws.windows[m]))
    ordered = sorted(groups.values(), key=lambda g: (-len(g), g))
    return ordered, shared


@dataclass(frozen=True)
class Observation:
    """What the camera sees over one pose sample: geometry only, independent of the IDs.

    Computed once per sample and reused for every ID assignment checked on it.
    """

    position: np.ndarray
    windows_per_pose: "PoseWindows"
    windows: WindowSet
    per_m2: float
    seed: int
    tolerance_m: float


def observe(xyz: np.ndarray, radii: np.ndarray, outline, camera: Camera, *, per_m2: float = POSES_PER_M2,
            seed: int = 0, tolerance_m: float = CONGRUENCE_TOLERANCE_M) -> Observation:
    """Sample poses over the working area and find each pose's window."""
    poses = sample_poses(working_area(xyz[:, :2], outline), camera, per_m2, seed)
    pw = find_windows(poses, xyz, radii, camera)
    ws = canonical_windows(pw.triples[pw.covered], xyz, tolerance_m)
    return Observation(poses.position, pw, ws, per_m2, seed, tolerance_m)


def classify(obs: Observation, ids: np.ndarray) -> Verification:
    """Each pose of an observation as decodable, ambiguous, collinear or too few LEDs seen, under ``ids``."""
    pw = obs.windows_per_pose
    status = np.full(len(pw.triples), TOO_FEW, dtype=np.int64)
    status[pw.collinear] = COLLINEAR
    covered = pw.covered
    status[covered] = DECODABLE
    groups, shared = conflict_groups(obs.windows, np.asarray(ids))
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
    obs = observe(xyz, radii, outline, camera, per_m2=per_m2, seed=seed, tolerance_m=tolerance_m)
    return classify(obs, ids)


def design_windows(xyz: np.ndarray, radii: np.ndarray, outline, camera: Camera, *,
                   per_m2: float = 2 * POSES_PER_M2, seed: int = 1,
                   tolerance_m: float = CONGRUENCE_TOLERANCE_M) -> WindowSet:
    """Windows to make unique when choosing IDs: from a denser pose sample than verification's."""
    poses = sample_poses(working_area(xyz[:, :2], outline), camera, per_m2, seed)
    pw = find_windows(poses, xyz, radii, camera)
    return canonical_windows(pw.triples[pw.covered], xyz, tolerance_m)
