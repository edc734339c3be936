"""Benchmarks: planning and verification times for sites of 512 to 100,000 luminaires.

Run from the repository root:  python benchmarks/run.py [--sizes 512 10000 100000] [--scheme auto]

Prints, per site: plan time (layout check, graph, IDs and verification, as
``vlp-plan`` runs it), output-writing time, bits, verification throughput in poses
per second, and the process's peak memory. Sites are lattices of 0.5 m pitch and,
up to 10,000 luminaires, irregular sites (a lattice jittered beyond recognition).
"""

from __future__ import annotations

import argparse
import math
import platform
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from planner.camera.model import Camera  # noqa: E402
from planner.layout.model import Layout, Luminaire, check_layout  # noqa: E402
from planner.plan.pipeline import PlanOptions, make_plan, write_outputs  # noqa: E402
from planner.studies.efficiency import lattice_layout  # noqa: E402


def irregular_site(n: int, seed: int = 0) -> Layout:
    """A lattice of 0.5 m pitch with every luminaire moved up to 0.3 pitch: no longer a lattice."""
    rng = np.random.default_rng(seed)
    cols = math.ceil(math.sqrt(n))
    k = np.arange(n)
    pts = 0.5 * (np.stack([k % cols, k // cols], axis=1) + rng.uniform(-0.3, 0.3, (n, 2)))
    lums = tuple(Luminaire(f"L{i:06d}", float(x), float(y), 2.5) for i, (x, y) in enumerate(pts))
    return Layout(lums, source_path=f"irregular-{n}.yaml")


def peak_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def bench(layout: Layout, label: str, with_outputs: bool, args) -> None:
    from planner.verify.verify import verify_plan

    t0 = time.perf_counter()
    check_layout(layout)
    plan = make_plan(layout, PlanOptions(scheme=args.scheme, time_budget=args.time_limit, seed=0, camera=Camera()))
    t1 = time.perf_counter()
    a = plan.assignment
    line = (f"{label:<9} n={len(layout.luminaires):>6}  plan+verify {t1 - t0:7.2f} s  {a.scheme} {a.bits} bits "
            f"(naive {a.naive_bits}, bound {a.lower_bound_bits})")
    if with_outputs:
        with tempfile.TemporaryDirectory() as tmp:
            write_outputs(plan, Path(tmp) / "out")
        line += f"  outputs {time.perf_counter() - t1:6.2f} s"
    v = plan.verification
    t2 = time.perf_counter()
    radii = np.array([lum.radius for lum in layout.luminaires])
    again = verify_plan(layout.xyz, radii, a.ids, layout.outline, Camera(), seed=1)
    rate = again.poses / (time.perf_counter() - t2)
    line += (f"  verify {v.poses} poses, {100 * v.coverage:.1f} % decodable, {v.count(1)} ambiguous,"
             f" {rate:,.0f} poses/s")
    print(line + f"  peak {peak_mib():6.0f} MiB", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[512, 10000])
    parser.add_argument("--time-limit", type=float, default=10.0, help="search budget for irregular sites")
    parser.add_argument("--scheme", default="auto", choices=["auto", "paper", "window", "unique"])
    args = parser.parse_args()
    print(f"# {platform.node()} {platform.processor() or platform.machine()}, {platform.python_version()}, "
          f"{time.strftime('%Y-%m-%d')}")
    for n in args.sizes:
        bench(lattice_layout(n), "lattice", n <= 20000, args)
    for n in args.sizes:
        if n <= 10000:
            bench(irregular_site(n), "irregular", n <= 20000, args)


if __name__ == "__main__":
    main()
