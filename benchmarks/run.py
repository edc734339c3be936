"""Benchmarks: time planning sites of 512 and 10,000 luminaires (and more on request).

Run from the repository root:  python benchmarks/run.py [--sizes 512 10000 100000]

Prints one line per stage and size: wall time [s] and peak memory of the process.
Each size is a square-ish lattice site (the paper's grids and larger) plus, for
the smaller sizes, an irregular site (random positions) that exercises the search.
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

from planner.camera import Camera  # noqa: E402
from planner.layout import Layout, Luminaire, check_layout  # noqa: E402
from planner.pipeline import PlanOptions, make_plan, write_outputs  # noqa: E402


def lattice_site(n: int) -> Layout:
    cols = 2 ** math.ceil(math.log2(math.sqrt(n)))
    cols = cols if n % cols == 0 else math.ceil(math.sqrt(n))
    lums = tuple(Luminaire(f"L{k:06d}", (k % cols) * 0.6, (k // cols) * 0.6, 2.5) for k in range(n))
    return Layout(lums, source_path=f"lattice-{n}.yaml")


def irregular_site(n: int, seed: int = 0) -> Layout:
    """A lattice of 1 m pitch with every luminaire moved up to 0.35 m: no longer a lattice."""
    rng = np.random.default_rng(seed)
    cols = math.ceil(math.sqrt(n))
    k = np.arange(n)
    pts = np.stack([k % cols, k // cols], axis=1) + rng.uniform(-0.35, 0.35, (n, 2))
    lums = tuple(Luminaire(f"L{i:06d}", float(x), float(y), 2.5) for i, (x, y) in enumerate(pts))
    return Layout(lums, source_path=f"irregular-{n}.yaml")


def peak_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def bench(layout: Layout, label: str, with_outputs: bool, time_budget: float) -> None:
    t0 = time.perf_counter()
    check_layout(layout)
    plan = make_plan(layout, PlanOptions("paper", time_budget, 0, Camera()))
    t1 = time.perf_counter()
    line = (f"{label:<22} n={len(layout.luminaires):>6}  plan {t1 - t0:7.2f} s  "
            f"bits {plan.assignment.bits} (naive {plan.assignment.naive_bits}, bound "
            f"{plan.assignment.lower_bound_bits}, {plan.assignment.method})")
    if with_outputs:
        with tempfile.TemporaryDirectory() as tmp:
            write_outputs(plan, Path(tmp) / "out")
        line += f"  outputs {time.perf_counter() - t1:6.2f} s"
    print(line + f"  peak {peak_mib():7.0f} MiB", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[512, 10000])
    parser.add_argument("--time-limit", type=float, default=10.0, help="search budget for irregular sites")
    args = parser.parse_args()
    print(f"# {platform.node()} {platform.processor() or platform.machine()}, {platform.python_version()}, "
          f"{time.strftime('%Y-%m-%d')}")
    for n in args.sizes:
        bench(lattice_site(n), "lattice", n <= 20000, args.time_limit)
    for n in args.sizes:
        if n <= 10000:
            bench(irregular_site(n), "irregular", n <= 20000, args.time_limit)


if __name__ == "__main__":
    main()
