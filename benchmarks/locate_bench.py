"""Benchmark: positioning fixes per second for a batch of observations.

Run from the repository root:  python benchmarks/locate_bench.py [--poses 500]

Plans the bundled 512-luminaire grid (window scheme, 4-bit IDs that repeat 32
times), simulates a batch of noisy observations over the site (the observation
model: rim points, 0.5 px noise, whole pixels, fitted ellipses) and times, on the
same batch: the paper's method and the full-perspective method with the luminaires
known, and what ``vlp-locate`` does (identify the luminaires from the plan, then
the full-perspective fit). Prints fixes per second and the error figures.
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from planner.errors import PositioningError  # noqa: E402
from planner.layout.read import read_layout  # noqa: E402
from planner.plan.pipeline import PlanOptions, make_plan  # noqa: E402
from planner.positioning.locate import METHODS, Site, Snapshot, identify  # noqa: E402
from planner.positioning.observation import observe  # noqa: E402
from planner.verify.windows import sample_poses, working_area  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=500, help="observations in the batch (default 500)")
    args = parser.parse_args()
    print(f"# {platform.node()} {platform.processor() or platform.machine()}, {platform.python_version()}, "
          f"{time.strftime('%Y-%m-%d')}")
    layout = read_layout(ROOT / "layouts" / "grid-512.yaml", 512)
    plan = make_plan(layout, PlanOptions(error_poses_per_m2=0))
    ids = plan.assignment.ids
    xyz, radii, cam = layout.xyz, np.array([lum.radius for lum in layout.luminaires]), plan.camera
    site = Site([lum.name for lum in layout.luminaires], xyz, radii, np.asarray(ids))
    area = working_area(layout.xy, layout.outline)
    poses = sample_poses(area, cam, per_m2=args.poses / 100.0, seed=7)
    rng = np.random.default_rng(0)
    t0 = time.perf_counter()
    batch = []
    for k in range(len(poses)):
        seen = observe(poses.position[k], poses.rotation[k], xyz, radii, cam, rng)
        if len(seen.index) >= 3 and np.linalg.matrix_rank(xyz[seen.index] - xyz[seen.index].mean(axis=0)) >= 2:
            batch.append((poses.position[k], seen))
        if len(batch) == args.poses:
            break
    t_obs = time.perf_counter() - t0
    print(f"{plan.assignment.scheme} scheme, {plan.assignment.bits}-bit IDs; {len(batch)} observations "
          f"(mean {np.mean([len(s.index) for _, s in batch]):.1f} LEDs each), simulated at "
          f"{len(batch) / t_obs:,.0f} /s")
    for name, method in METHODS.items():
        t0 = time.perf_counter()
        err = [np.linalg.norm(method(xyz[s.index], radii[s.index], s.ellipses, cam).position - p) for p, s in batch]
        dt = time.perf_counter() - t0
        print(f"{name:<12} luminaires known    {len(batch) / dt:8,.0f} fixes/s   median {1e3 * np.median(err):8.3f} mm"
              f"   90 % {1e3 * np.percentile(err, 90):8.3f} mm")
    t0 = time.perf_counter()
    right = failed = 0
    for _p, s in batch:
        try:
            found = identify(site, Snapshot(cam, [int(ids[k]) for k in s.index], s.ellipses))
            right += list(found.luminaires) == list(s.index)
        except PositioningError:
            failed += 1
    dt = time.perf_counter() - t0
    print(f"{'vlp-locate':<12} identify + fit      {len(batch) / dt:8,.0f} fixes/s   "
          f"{right} of {len(batch)} identified right, {failed} refused")


if __name__ == "__main__":
    main()
