"""The proved window set: how large it is against sampled windows, and what it costs to compute.

Run from the repository root:  python benchmarks/window_proof_bench.py [--fresh-seeds 5]
                               python benchmarks/window_proof_bench.py --tolerances 0,0.01,0.03

For the bundled 32/256/512 grids, a staggered 4 x 6 site, a 6 x 8 grid and the
jittered site of issue 13, prints: the windows that fresh samples at 4,000 poses/m2
find together, the proved set (every triple some pose of the envelope could take as
its window, computed without the planner's budget), the fresh windows outside it
(must be 0), and the seconds. With ``--tolerances``: the pairs within reach, the proved
set and the seconds at each install tolerance [m], for the bundled grids and a 32 x 32
lattice at 0.5 m (no samples).
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

from conftest import grid_xy, hex_xy  # noqa: E402
from planner.camera.model import Camera  # noqa: E402
from planner.layout.model import Layout, Luminaire  # noqa: E402
from planner.layout.read import ReadOptions, read_layout  # noqa: E402
from planner.verify.envelope import envelope  # noqa: E402
from planner.verify.proof import TRIANGLE_BUDGET, possible_pairs, possible_windows  # noqa: E402
from planner.verify.verify import observe_site  # noqa: E402
from window_set_bench import jittered_site  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def _site(name: str, xy: np.ndarray) -> Layout:
    return Layout(tuple(Luminaire(f"L{k}", float(x), float(y), 2.5) for k, (x, y) in enumerate(xy)), source_path=name)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fresh-seeds", type=int, default=5)
    ap.add_argument("--tolerances", help="comma-separated install tolerances [m]: the proved set at each")
    args = ap.parse_args()
    if args.tolerances:
        by_tolerance([float(t) for t in args.tolerances.split(",")])
        return
    print(f"# {platform.processor() or platform.machine()}, python {platform.python_version()}, "
          f"{time.strftime('%Y-%m-%d')}; planner budget {TRIANGLE_BUDGET:,} candidates")
    print("| site | luminaires | fresh windows (union) | proved set | fresh outside it | proof [s] |")
    print("|---|---:|---:|---:|---:|---:|")
    sites = [("grid-32", read_layout(ROOT / "layouts" / "grid-32.yaml", None, ReadOptions())),
             ("staggered 4 x 6, 0.6 m", _site("hex", hex_xy(4, 6, 0.6))),
             ("6 x 8 grid, 0.5 m", _site("grid48", grid_xy(6, 8, 0.5, 0.5))),
             ("grid-256", read_layout(ROOT / "layouts" / "grid-256.yaml", None, ReadOptions())),
             ("jittered 30 x 16", jittered_site()),
             ("grid-512", read_layout(ROOT / "layouts" / "grid-512.yaml", None, ReadOptions()))]
    cam = Camera()
    for name, layout in sites:
        xyz, radii = layout.xyz, np.array([lum.radius for lum in layout.luminaires])
        t0 = time.perf_counter()
        proved = possible_windows(xyz, radii, envelope(cam, xyz, radii, 0.03), budget=10**8, pair_budget=10**8)
        seconds = time.perf_counter() - t0
        fresh: set = set()
        for s in range(11, 11 + args.fresh_seeds):
            obs = observe_site(xyz, radii, layout.outline, cam, per_m2=4000, seed=s)
            fresh |= {tuple(sorted(t)) for t in obs.windows.windows.tolist()}
        inside = {tuple(t) for t in proved.tolist()}
        print(f"| {name} | {len(xyz)} | {len(fresh):,} | {len(proved):,} | {len(fresh - inside)} | {seconds:.1f} |",
              flush=True)


def by_tolerance(tolerances: list[float]) -> None:
    """The proved set's size and time at each install tolerance: where the set grows (issue 34)."""
    print(f"# {platform.processor() or platform.machine()}, python {platform.python_version()}, {time.strftime('%Y-%m-%d')}")
    print("| site | luminaires | install tolerance [cm] | pairs within reach kept | proved set | proof [s] |")
    print("|---|---:|---:|---:|---:|---:|")
    sites = [(name, read_layout(ROOT / "layouts" / f"{name}.yaml", None, ReadOptions()))
             for name in ("grid-32", "grid-256", "grid-512")]
    sites.append(("lattice 32 x 32, 0.5 m", _site("lattice1024", grid_xy(32, 32, 0.5, 0.5))))
    cam = Camera()
    for name, layout in sites:
        xyz, radii = layout.xyz, np.array([lum.radius for lum in layout.luminaires])
        for d in tolerances:
            env = envelope(cam, xyz, radii, d)
            pairs = possible_pairs(xyz[:, :2], radii, env, budget=10**8)
            t0 = time.perf_counter()
            proved = possible_windows(xyz, radii, env, budget=10**8, pair_budget=10**8)
            print(f"| {name} | {len(xyz)} | {100 * d:g} | {len(pairs):,} | {len(proved):,} | "
                  f"{time.perf_counter() - t0:.1f} |", flush=True)


if __name__ == "__main__":
    main()
