"""Window set against samples: how many windows pose samples find, and how many triangles the planner protects.

Run from the repository root:  python benchmarks/window_set_bench.py [--fresh-seeds 5]

For the bundled 32/256/512 grids and the jittered site of issue 13 (a 0.6 m lattice
of 30 x 16 positions, 20 % left empty, every luminaire moved up to 12 cm), plans with
the default options and prints: windows in the default sample (400 poses/m2), in the
design sample (2,000/m2), in the union of fresh samples at 4,000/m2 with seeds the
planner never used, the triangles of the window set the plan checked (the proved set
where the plan is proved, else the empty-triangle rule's up to the sampled side bound)
and how many fresh windows lie outside it, the bits of the chosen scheme, ambiguous
fresh poses (against every triple of the site) and the plan time.
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from conftest import jittered_xy  # noqa: E402
from planner.camera.model import Camera  # noqa: E402
from planner.layout.model import Layout, Luminaire  # noqa: E402
from planner.layout.read import ReadOptions, read_layout  # noqa: E402
from planner.plan.pipeline import PlanOptions, make_plan  # noqa: E402
from planner.verify.proof import prove_window_set  # noqa: E402
from planner.verify.verify import classify, observe_site  # noqa: E402
from planner.verify.window_set import window_superset  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def jittered_site(seed: int = 7) -> Layout:
    """Issue 13's site (``tests/conftest.py``) under a 2.5 m ceiling."""
    return Layout(tuple(Luminaire(f"J{k:03d}", float(x), float(y), 2.5) for k, (x, y) in enumerate(jittered_xy(seed))),
                  source_path="jittered-30x16.yaml")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fresh-seeds", type=int, default=5)
    args = ap.parse_args()
    print(f"# {platform.processor() or platform.machine()}, python {platform.python_version()}, "
          f"{time.strftime('%Y-%m-%d')}")
    print("| site | luminaires | sampled 400/m2 | design 2,000/m2 | fresh 4,000/m2 (union) | window set "
          "| fresh outside set | scheme | bits | ambiguous fresh poses | plan [s] |")
    print("|---|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|")
    sites = [(name, read_layout(ROOT / "layouts" / f"{name}.yaml", None, ReadOptions())) for name in
             ("grid-32", "grid-256", "grid-512")] + [("jittered 30 x 16", jittered_site())]
    cam = Camera()
    for name, layout in sites:
        xyz, radii = layout.xyz, np.array([lum.radius for lum in layout.luminaires])
        t0 = time.perf_counter()
        plan = make_plan(layout, PlanOptions(error_poses_per_m2=0))
        seconds = time.perf_counter() - t0
        w = plan.verification.window_set
        protected = (prove_window_set(xyz, radii, cam, w.install_tolerance_m).triangles if w.complete else
                     window_superset(xyz, radii, w.max_side_m, w.install_tolerance_m))  # what the plan checked
        tri = {frozenset(t) for t in protected.tolist()}

        def count(per_m2, seed, xyz=xyz, radii=radii, outline=layout.outline):  # this site's, bound now
            return observe_site(xyz, radii, outline, cam, per_m2=per_m2, seed=seed)

        default, design = count(400, 0), count(2000, 1)
        fresh, amb, poses = set(), 0, 0
        for s in range(11, 11 + args.fresh_seeds):
            obs = count(4000, s)
            fresh |= {frozenset(t) for t in obs.windows.windows.tolist()}
            v = classify(obs, plan.assignment.ids)
            amb, poses = amb + v.count(1), poses + v.poses
        print(f"| {name} | {len(xyz)} | {len(default.windows)} | {len(design.windows)} | {len(fresh)} | {len(tri)} "
              f"| {len(fresh - tri)} | {plan.assignment.scheme} | {plan.assignment.bits} | {amb} of {poses:,} "
              f"| {seconds:.0f} |", flush=True)


if __name__ == "__main__":
    main()
