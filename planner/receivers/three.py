"""The paper's receiver: a window of three whole, non-collinear LEDs (:mod:`planner.verify.windows`),
IDs by the paper's regions, the window code or unique IDs, proved on the window set."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from planner.camera.model import Camera, Poses
from planner.modulation.timing import smallest_window_image_rows
from planner.parallel import Runner
from planner.receivers.base import Job, Planned, Receiver
from planner.verify.verify import Verification, check_window_set, classify, observe_poses, side_bound, verify_plan
from planner.verify.windows import PoseSample, find_windows


class ThreeLeds(Receiver):
    name = "three"
    leds = 3
    title = "three LEDs"
    window_words = "three whole, non-collinear LEDs"
    shape = "triangles"
    leds_text = "three"

    def plan(self, job: Job) -> Planned:
        # the code design and proof stages load here: locating with a plan needs neither
        from planner.codes.assignment import assign_paper
        from planner.codes.proved import window_set_bound
        from planner.codes.schemes import assign_unique, assign_window
        from planner.verify.proof import prove_window_set

        xyz, radii, graph, xy = job.xyz, job.radii, job.graph, job.xyz[:, :2]
        observations = job.observations
        if job.verify:
            poses, windows = job.sample.first(job.poses_per_m2)
            observations[job.seed] = observe_poses(poses, xyz, radii, job.camera, per_m2=job.poses_per_m2,
                                                   seed=job.seed, tolerance_m=job.tolerance_m, windows=windows)

        def verify_ids(ids: np.ndarray) -> Verification | None:
            return classify(observations[job.seed], ids) if job.verify else None

        proof = prove_window_set(xyz, radii, job.camera, job.install_tolerance_m, job.runner) if job.verify else None
        made = {}
        if job.scheme in ("paper", "auto"):
            paper = assign_paper(xy, graph, time_budget=job.time_budget, seed=job.seed)
            made["paper"] = (paper, verify_ids(paper.ids))
        if job.scheme in ("window", "auto"):
            made["window"] = assign_window(xyz, radii, job.outline, graph, job.camera, seed=job.seed,
                                           time_budget=job.time_budget, per_m2=job.poses_per_m2,
                                           tolerance_m=job.tolerance_m, install_tolerance_m=job.install_tolerance_m,
                                           observations=observations, proof=proof)
        if job.scheme == "unique":
            unique = assign_unique(xy, graph)
            made["unique"] = (unique, verify_ids(unique.ids))
        bound = max([side_bound(v.windows, xyz, job.tolerance_m) for _, v in made.values() if v]
                    + [float(a.detail.get("max_side_m", 0.0)) for a, _ in made.values()], default=0.0)

        def judged(a, v):  # every scheme is also judged on the window set, up to one side bound
            return a, (v and replace(v, window_set=check_window_set(xyz, radii, a.ids, bound,
                                                                      tolerance_m=job.tolerance_m,
                                                                      install_tolerance_m=job.install_tolerance_m,
                                                                      proof=proof)))

        made = {k: judged(a, v) for k, (a, v) in made.items()}
        if job.scheme == "auto":
            clean = [k for k, (_, v) in made.items() if v is not None and v.clean]  # auto verifies: never None
            if clean:
                chosen = min(clean, key=lambda k: (made[k][0].bits, k != "paper"))
            else:
                unique = assign_unique(xy, graph)
                made["unique"] = judged(unique, verify_ids(unique.ids))
                chosen = "unique"
        else:
            chosen = job.scheme
        assignment, verification = made[chosen]
        counted = (window_set_bound(proof, xyz, made.get("window", (None, None))[0], job.tolerance_m)
                   if proof is not None else None)
        if counted is not None:  # the counting bound of the window set, proved or sampled, beside the width
            assignment = replace(assignment, detail={**assignment.detail, "window_set": counted})
        considered = {k: {"bits": a.bits, "ambiguous_poses": (v.count(1) if v else None),
                          "window_set_conflicts": (len(v.window_set.conflicts) if v and v.window_set else None)}
                      for k, (a, v) in made.items()}
        return assignment, verification, considered

    def verify(self, xyz: np.ndarray, radii: np.ndarray, ids: np.ndarray, outline, camera: Camera, *, per_m2: float,
               seed: int, tolerance_m: float, install_tolerance_m: float, recorded: dict,
               runner: Runner | None = None) -> Verification:
        from planner.verify.proof import prove_window_set

        result = verify_plan(xyz, radii, ids, outline, camera, per_m2=per_m2, seed=seed, tolerance_m=tolerance_m)
        # The proof is made anew from the luminaires and the camera, never read from the plan; without
        # one, only the sampled side bound may come from the plan.
        proof = prove_window_set(xyz, radii, camera, install_tolerance_m, runner)
        bound = max(side_bound(result.windows, xyz, tolerance_m), float(recorded.get("max_side_m", 0.0))
                    if recorded.get("max_side_from") != "proof" else 0.0)
        return replace(result, window_set=check_window_set(xyz, radii, ids, bound, tolerance_m=tolerance_m,
                                                           install_tolerance_m=install_tolerance_m, proof=proof))

    def window_leds(self, poses: Poses, xyz: np.ndarray, radii: np.ndarray, camera: Camera
                    ) -> tuple[np.ndarray, np.ndarray]:
        w = find_windows(poses, xyz, radii, camera)
        return w.triples, w.covered

    def decodable(self, poses: Poses, xyz: np.ndarray, radii: np.ndarray, ids: np.ndarray, camera: Camera, *,
                  per_m2: float, seed: int) -> np.ndarray:
        return classify(observe_poses(poses, xyz, radii, camera, per_m2=per_m2, seed=seed), ids).status

    def smallest_image_rows(self, xyz: np.ndarray, radii: np.ndarray, camera: Camera, sample: PoseSample
                            ) -> float | None:
        return smallest_window_image_rows(xyz, radii, camera, sample)
