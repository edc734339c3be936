"""Two LEDs plus gravity: the accelerometer's vertical and a window of two whole LEDs
(:mod:`planner.verify.pair_windows`, :mod:`planner.positioning.gravity`); its IDs are the pair code
(:mod:`planner.codes.pair_code`) or the paper's, judged on the two-LED windows and the pair set."""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from planner.camera.model import Camera, Poses, disc_image_rows
from planner.graph import NeighbourGraph
from planner.modulation.timing import timing_per_m2
from planner.parallel import Runner
from planner.positioning.error_terms import ErrorTerms
from planner.positioning.gravity import accelerometer
from planner.receivers.base import Job, Planned, Receiver
from planner.verify.pair_windows import PosePairs, check_pair_set, classify_pairs, find_pairs, window_pairs
from planner.verify.verify import Verification
from planner.verify.windows import CONGRUENCE_TOLERANCE_M, PoseSample, sample_poses, working_area

if TYPE_CHECKING:
    from planner.codes.assignment import Assignment


class TwoLedsGravity(Receiver):
    name = "gravity"
    leds = 2
    title = "two LEDs plus gravity"
    window_words = "two whole LEDs (with gravity)"
    shape = "pairs"
    leds_text = "two"
    extra_error_terms = ("accelerometer",)

    def plan(self, job: Job) -> Planned:
        return plan_gravity(job.xyz, job.radii, job.graph, job.camera, job.sample, scheme=job.scheme,
                            per_m2=job.poses_per_m2, seed=job.seed, time_budget=job.time_budget,
                            tolerance_m=job.tolerance_m, install_tolerance_m=job.install_tolerance_m)

    def verify(self, xyz: np.ndarray, radii: np.ndarray, ids: np.ndarray, outline, camera: Camera, *, per_m2: float,
               seed: int, tolerance_m: float, install_tolerance_m: float, recorded: dict,
               runner: Runner | None = None) -> Verification:
        return verify_gravity(xyz, radii, ids, outline, camera, per_m2=per_m2, seed=seed, tolerance_m=tolerance_m,
                              install_tolerance_m=install_tolerance_m)

    def window_leds(self, poses: Poses, xyz: np.ndarray, radii: np.ndarray, camera: Camera
                    ) -> tuple[np.ndarray, np.ndarray]:
        pp = find_pairs(poses, xyz, radii, camera)
        return pp.pairs, pp.covered

    def decodable(self, poses: Poses, xyz: np.ndarray, radii: np.ndarray, ids: np.ndarray, camera: Camera, *,
                  per_m2: float, seed: int) -> np.ndarray:
        pp = find_pairs(poses, xyz, radii, camera)
        return classify_pairs(poses.position, pp, xyz, ids, per_m2=per_m2, seed=seed,
                              tolerance_m=CONGRUENCE_TOLERANCE_M).status

    def smallest_image_rows(self, xyz: np.ndarray, radii: np.ndarray, camera: Camera, sample: PoseSample
                            ) -> float | None:
        return smallest_pair_image_rows(xyz, radii, camera, sample)

    def vertical(self, rotation: np.ndarray, sigma_rad: float, rng: np.random.Generator) -> np.ndarray | None:
        return accelerometer(rotation, sigma_rad, rng)

    def exact_vertical(self, rotation: np.ndarray) -> np.ndarray | None:
        return rotation.T @ np.array([0.0, 0.0, -1.0])

    def accuracy_method(self, method: str) -> str:
        return "gravity"

    def error_terms(self, terms: ErrorTerms, accelerometer_sigma_rad: float) -> ErrorTerms:
        return replace(terms, gravity_rad=accelerometer_sigma_rad)


def sample_pairs(sample: PoseSample, xyz: np.ndarray, radii: np.ndarray, camera: Camera, per_m2: float
                 ) -> tuple[Poses, PosePairs]:
    """The first poses of ``sample`` at ``per_m2`` and their two-LED windows, found once per sample (windows are
    found pose by pose: a shorter prefix's are the first of a longer one's)."""
    poses, _ = sample.first(per_m2)
    have = sample.found.get("pairs")
    if have is None or len(have.pairs) < len(poses):
        have = sample.found["pairs"] = find_pairs(poses, xyz, radii, camera)
    return poses, have.first(len(poses))


def smallest_pair_image_rows(xyz: np.ndarray, radii: np.ndarray, camera: Camera, sample: PoseSample
                             ) -> float | None:
    """Rows of the smallest LED image in any two-LED window over the timing prefix of ``sample``; None if no
    pose of that prefix sees two whole LEDs."""
    poses, pp = sample_pairs(sample, xyz, radii, camera, timing_per_m2(sample.area))
    if not pp.covered.any():
        return None
    sub = poses.subset(np.flatnonzero(pp.covered))
    t = pp.pairs[pp.covered]
    return float(disc_image_rows(sub.position, sub.rotation, xyz[t], radii[t], camera).min())


def plan_gravity(xyz: np.ndarray, radii: np.ndarray, graph: NeighbourGraph, camera: Camera, sample: PoseSample, *,
                 scheme: str, per_m2: float, seed: int, time_budget: float, tolerance_m: float,
                 install_tolerance_m: float) -> tuple[Assignment, Verification, dict]:
    """IDs for the gravity receiver under ``scheme`` (``auto``: the pair code or the paper's, fewer bits
    that verifies; else unique), each verified on the sample's two-LED windows and the pair set."""
    from planner.codes.assignment import assign_paper  # the design and proof stages: locating needs neither
    from planner.codes.pair_code import assign_pairs
    from planner.codes.schemes import assign_unique
    from planner.verify.pair_proof import prove_pair_set

    poses, pp = sample_pairs(sample, xyz, radii, camera, per_m2)
    proof = prove_pair_set(xyz, radii, camera, install_tolerance_m, sample.area)
    sampled = np.unique(pp.pairs[pp.covered], axis=0).reshape(-1, 2)

    def verified(a: Assignment) -> tuple[Assignment, Verification]:
        v = classify_pairs(poses.position, pp, xyz, a.ids, per_m2=per_m2, seed=seed, tolerance_m=tolerance_m)
        check = check_pair_set(xyz, a.ids, proof.pairs, sampled, tolerance_m=tolerance_m,
                               install_tolerance_m=install_tolerance_m, reason=proof.reason, envelope=proof.envelope)
        return a, replace(v, window_set=check)

    made: dict[str, tuple[Assignment, Verification]] = {}
    if scheme in ("window", "auto"):
        design, _, _ = window_pairs(xyz, proof.pairs, sampled, tolerance_m)  # what the check checks
        made["window"] = verified(assign_pairs(xyz, graph, design, tolerance_m=tolerance_m, seed=seed,
                                               proved=proof.complete, time_budget=time_budget))
    if scheme in ("paper", "auto"):
        made["paper"] = verified(assign_paper(xyz[:, :2], graph, time_budget=time_budget, seed=seed))
    if scheme == "unique":
        made["unique"] = verified(assign_unique(xyz[:, :2], graph))
    if scheme == "auto":
        clean = [k for k, (_, v) in made.items() if v.clean]
        if clean:
            chosen = min(clean, key=lambda k: (made[k][0].bits, k != "window"))
        else:
            made["unique"] = verified(assign_unique(xyz[:, :2], graph))
            chosen = "unique"
    else:
        chosen = scheme
    considered = {k: {"bits": a.bits, "ambiguous_poses": v.count(1),
                      "window_set_conflicts": len(v.window_set.conflicts) if v.window_set else None}
                  for k, (a, v) in made.items()}
    assignment, verification = made[chosen]
    return assignment, verification, considered


def verify_gravity(xyz: np.ndarray, radii: np.ndarray, ids: np.ndarray, outline, camera: Camera, *, per_m2: float,
                   seed: int, tolerance_m: float, install_tolerance_m: float) -> Verification:
    """A gravity plan verified anew (``vlp-verify``): sampled two-LED windows and the pair set, proved where
    the pair proof completes (made from the luminaires and the camera, never read from the plan)."""
    from planner.verify.pair_proof import prove_pair_set

    area = working_area(xyz[:, :2], outline)
    poses = sample_poses(area, camera, per_m2, seed)
    pp = find_pairs(poses, xyz, radii, camera)
    proof = prove_pair_set(xyz, radii, camera, install_tolerance_m, area)
    sampled = np.unique(pp.pairs[pp.covered], axis=0).reshape(-1, 2)
    v = classify_pairs(poses.position, pp, xyz, ids, per_m2=per_m2, seed=seed, tolerance_m=tolerance_m)
    return replace(v, window_set=check_pair_set(xyz, ids, proof.pairs, sampled, tolerance_m=tolerance_m,
                                                install_tolerance_m=install_tolerance_m, reason=proof.reason,
                                                envelope=proof.envelope))
