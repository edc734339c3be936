"""The work a plan or a verification asks for, estimated before the heavy stages run.

The cost that grows without bound with the flags is the camera poses sampled (density times
floor area: 20,000 per m^2 over a 10 km site would be two trillion). Each sample is counted
here from the layout and the options, exactly as the stages will draw it, and refused
beyond a budget with the numbers and the flag that raises it. Memory and time per pose were
measured on the 2-core VM of docs/performance.md (2026-12-03: a million poses on grid-512
sampled and their windows found in 6.4 s, 370 MB more peak memory).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.defaults import MAX_PLAN_POSES
from planner.errors import UsageError

BYTES_PER_POSE = 400
"""Peak memory per pose of the largest sample [B] (measured 370)."""
SECONDS_PER_POSE = 7e-6
"""Sampling a pose and finding its window [s] (measured 6.4 us on two cores shared)."""


@dataclass(frozen=True)
class Work:
    """Poses of each sample a run draws (name -> count), in the order drawn."""

    samples: dict[str, int]

    @property
    def poses(self) -> int:
        return sum(self.samples.values())

    @property
    def peak_bytes(self) -> int:
        """Estimated peak memory of the samples: samples are drawn one after the other [B]."""
        return BYTES_PER_POSE * max(self.samples.values(), default=0)

    @property
    def seconds(self) -> float:
        """Estimated time to draw every sample and find its windows [s]."""
        return SECONDS_PER_POSE * self.poses

    def text(self) -> str:
        parts = ", ".join(f"{name} {n:,}" for name, n in self.samples.items())
        s = self.seconds
        took = f"{s:.0f} s" if s < 90 else f"{s / 60:.0f} min" if s < 5400 else f"{s / 3600:,.0f} h"
        return f"{self.poses:,} camera poses ({parts}): about {self.peak_bytes / 1e9:,.1f} GB and {took}"


def plan_sample_per_m2(area: np.ndarray, *, verify: bool, poses_per_m2: float, error_poses_per_m2: float) -> float:
    """Density of a plan's one shared pose sample over ``area`` [1/m^2]: the densest of chip timing,
    verification and the error map, which each take a prefix of it."""
    from planner.modulation.timing import timing_per_m2
    from planner.positioning.accuracy import error_per_m2

    densities = [timing_per_m2(area)] + [poses_per_m2] * verify + \
        [error_per_m2(area, error_poses_per_m2)] * (verify and error_poses_per_m2 > 0)
    return max(densities)


def plan_work(xy: np.ndarray, outline, *, scheme: str, verify: bool, poses_per_m2: float,
              error_poses_per_m2: float) -> Work:
    """The samples :func:`planner.plan.pipeline.make_plan` draws for luminaires at ``xy`` [m]: one shared
    sample at the densest of verification, chip timing and the error map, and, for the window scheme
    without a complete proof (an upper bound: a proved site skips it), the design sample."""
    from planner.codes.schemes import design_per_m2
    from planner.layout.model import area_m2
    from planner.verify.windows import pose_count, working_area

    area = working_area(xy, outline)
    per_m2 = plan_sample_per_m2(area, verify=verify, poses_per_m2=poses_per_m2, error_poses_per_m2=error_poses_per_m2)
    samples = {"plan sample": pose_count(area, per_m2)}
    if scheme in ("window", "auto"):
        samples["window design"] = pose_count(area, design_per_m2(poses_per_m2, area_m2(area)))
    return Work(samples)


def verify_work(xy: np.ndarray, outline, poses_per_m2: float) -> Work:
    """The sample ``vlp-verify`` draws over the plan's working area."""
    from planner.verify.windows import pose_count, working_area

    return Work({"verification": pose_count(working_area(xy, outline), poses_per_m2)})


def available_bytes() -> int | None:
    """Memory the system could give this process now (``MemAvailable``) [B], or None where unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def check_work(work: Work, max_poses: int | None) -> None:
    """Refuse ``work`` beyond ``max_poses`` (None: :data:`MAX_PLAN_POSES`, or fewer if the largest sample
    would not fit in the memory available) with the numbers and what to do."""
    if max_poses is not None:
        if work.poses > max_poses:
            raise UsageError(f"this run asks {work.text()}, more than `max_poses` {max_poses:,}; lower "
                             "`poses_per_m2` or raise `max_poses`")
        return
    if work.poses > MAX_PLAN_POSES:
        raise UsageError(f"this run asks {work.text()}, more than the {MAX_PLAN_POSES:,} a run samples by default; "
                         "lower `poses_per_m2`, or raise `max_poses` if the machine has the memory and time")
    free = available_bytes()
    if free is not None and work.peak_bytes > free:
        raise UsageError(f"this run asks {work.text()}, but {free / 1e9:.1f} GB of memory is available; lower "
                         "`poses_per_m2`, or give `max_poses` to run anyway")
