"""The pair proof (two-LED windows, the gravity receiver): its size against sampled windows, its cost,
and the pair code's bits against it.

Run from the repository root:  python benchmarks/pair_proof_bench.py [--sites grid-32 grid-512 ...]

For each site and camera prints: the pairs within the camera's reach, the proved pair set and the
seconds it took, the distinct two-LED windows of a 400 poses/m2 sample and of a 2,000 poses/m2 one
(seeds 0 and 1), how many of those lie outside the proved set (must be 0), and the pair code's bits
designed against the proved set (with the counting lower bound) and its seconds.
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from planner.camera.file import camera_profile  # noqa: E402
from planner.codes.pair_code import assign_pairs  # noqa: E402
from planner.graph import build_graph  # noqa: E402
from planner.layout.read import read_layout  # noqa: E402
from planner.verify.pair_proof import pair_envelope, possible_window_pairs  # noqa: E402
from planner.verify.pair_windows import find_pairs  # noqa: E402
from planner.verify.windows import sample_poses, working_area  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SITES = {"grid-32": ("grid-32.yaml", "paper"), "grid-256": ("grid-256.yaml", "paper"),
         "grid-512": ("grid-512.yaml", "paper"), "office-wide": ("dialux-office.dxf", "wide"),
         "office-ultrawide": ("dialux-office.dxf", "ultrawide")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sites", nargs="+", default=list(SITES), choices=list(SITES))
    args = ap.parse_args()
    print(f"# {platform.processor() or platform.machine()}, python {platform.python_version()}, {time.strftime('%Y-%m-%d')}")
    print("| site | camera | luminaires | pairs within reach | proved pairs | proof [s] | windows 400/m2 | windows 2,000/m2 "
          "| outside the proved set | pair code bits (lower bound) | code [s] |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---|---:|")
    for name in args.sites:
        path, cam_name = SITES[name]
        lay = read_layout(ROOT / "layouts" / path, None)
        xyz, radii = lay.xyz, np.array([lum.radius for lum in lay.luminaires])
        cam = camera_profile(cam_name)
        area = working_area(lay.xy, lay.outline)
        t0 = time.perf_counter()
        env = pair_envelope(cam, xyz, radii, 0.03, area)
        proved = possible_window_pairs(xyz[:, :2], radii, env, budget=10**8)
        proof_s = time.perf_counter() - t0
        within = len(cKDTree(xyz[:, :2]).query_pairs(env.reach_m + 0.06)) if np.isfinite(env.reach_m) else len(xyz) * (len(xyz) - 1) // 2
        inside = {tuple(p) for p in proved.tolist()}
        counts, outside = [], 0
        for per_m2, seed in ((400, 0), (2000, 1)):
            pp = find_pairs(sample_poses(area, cam, per_m2, seed), xyz, radii, cam)
            seen = {tuple(p) for p in pp.pairs[pp.covered].tolist()}
            counts.append(len(seen))
            outside += len(seen - inside)
        t0 = time.perf_counter()
        code = assign_pairs(xyz, build_graph(lay.xy), proved, tolerance_m=0.05, proved=True)
        code_s = time.perf_counter() - t0
        print(f"| {name} | {cam_name} | {len(xyz)} | {within:,} | {len(proved):,} | {proof_s:.1f} | {counts[0]:,} | {counts[1]:,} "
              f"| {outside} | {code.bits} ({code.lower_bound_bits}) | {code_s:.1f} |", flush=True)


if __name__ == "__main__":
    main()
