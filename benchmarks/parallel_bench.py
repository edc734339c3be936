"""The tiled proof in process, on 2 local processes and on a 2-worker Dask cluster: time and peak memory.

Run from the repository root:  python benchmarks/parallel_bench.py [--sites grid-512 lattice-1024 ...]
                                                                  [--modes single workers dask1 dask] [--plan]

Sites: ``grid-512`` (the bundled grid), ``lattice-N`` (N luminaires on a 0.5 m lattice) and
``jittered-N`` (a 0.5 m lattice with every luminaire moved up to 0.15 m: irregular). For each site and
mode it prints the proof's time (the tiled window set, :func:`planner.verify.proof.prove_window_set`),
the rival search's (the site's triples that read like a proved window, at 1 cm), with ``--plan`` the
whole ``make_plan``, the proved set's size and tiles, and the peak memory of the largest process
(this one or a worker: each measurement runs in a fresh process). The speed-up is against ``single``; a
``dask`` row's also against ``dask1`` (a 1-worker cluster: the base of issue 34's 2-worker aim) when both ran.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def site(name: str):
    from planner.layout.model import Layout, Luminaire
    from planner.layout.read import ReadOptions, read_layout
    from planner.studies.efficiency import lattice_layout

    if name.startswith("grid-"):
        return read_layout(ROOT / "layouts" / f"{name}.yaml", None, ReadOptions())
    kind, n = name.rsplit("-", 1)
    if kind == "lattice":
        return lattice_layout(int(n))
    rng = np.random.default_rng(0)
    count = int(n)
    cols = math.ceil(math.sqrt(count))
    k = np.arange(count)
    pts = 0.5 * np.stack([k % cols, k // cols], axis=1) + rng.uniform(-0.15, 0.15, (count, 2))
    return Layout(tuple(Luminaire(f"L{i:06d}", float(x), float(y), 2.5) for i, (x, y) in enumerate(pts)),
                  source_path=f"{name}.yaml")


def _peak_mib() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    children = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return max(own, children) / 1024


def one(name: str, mode: str, with_plan: bool) -> dict:
    """Measure one site in one mode (in this process); the figures as a dict."""
    from planner.camera.model import Camera
    from planner.parallel import InProcess, Runner
    from planner.plan.pipeline import PlanOptions, make_plan
    from planner.verify.proof import prove_window_set

    layout = site(name)
    xyz, radii = layout.xyz, np.array([lum.radius for lum in layout.luminaires])
    cluster = None
    run: Runner
    if mode in ("dask", "dask1"):
        from distributed import LocalCluster

        from planner.parallel import DaskCluster

        cluster = LocalCluster(n_workers=2 if mode == "dask" else 1, processes=True, threads_per_worker=1,
                               dashboard_address=None)
        run = DaskCluster(cluster.scheduler_address)
    elif mode == "workers":
        from planner.parallel import LocalProcesses

        run = LocalProcesses(2)
    else:
        run = InProcess()
    out: dict = {"site": name, "luminaires": len(xyz), "mode": mode}
    with run:
        t0 = time.perf_counter()
        proof = prove_window_set(xyz, radii, Camera(), 0.03, run)
        t1 = time.perf_counter()
        out.update(proof_s=round(t1 - t0, 2), proved=proof.complete, reason=proof.reason,
                   windows=len(proof.triangles) if proof.triangles is not None else None,
                   tiles=(proof.envelope or {}).get("tiles"), over_budget=(proof.envelope or {}).get("tiles_over_budget"))
        if proof.complete:
            matches = proof.shape_matches(0.01)
            out.update(rivals_s=round(time.perf_counter() - t1, 2), rival_triples=len(matches))
        if with_plan:
            t2 = time.perf_counter()
            plan = make_plan(layout, PlanOptions(runner=run))
            out.update(plan_s=round(time.perf_counter() - t2, 2), bits=plan.assignment.bits,
                       scheme=plan.assignment.scheme)
    if cluster is not None:
        cluster.close()
    out["peak_mib"] = round(_peak_mib())
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sites", nargs="+", default=["grid-512", "lattice-1024", "jittered-10000", "lattice-100000"])
    ap.add_argument("--modes", nargs="+", default=["single", "workers", "dask"], choices=["single", "workers", "dask1", "dask"])
    ap.add_argument("--plan", action="store_true", help="also time the whole make_plan (long beyond 1,024)")
    ap.add_argument("--one", nargs=2, metavar=("SITE", "MODE"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        print(json.dumps(one(args.one[0], args.one[1], args.plan)))
        return
    print(f"# {platform.node()}, {platform.machine()}, python {platform.python_version()}, "
          f"{time.strftime('%Y-%m-%d', time.gmtime())}; proof at 3 cm install tolerance, rivals at 1 cm")
    print("| site | luminaires | mode | tiles | proved windows | proof [s] | rivals [s] | plan [s] | speed-up | peak [MiB] |")
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|")
    for name in args.sites:
        base = dask1 = None
        for mode in args.modes:
            cmd = [sys.executable, __file__, "--one", name, mode] + (["--plan"] if args.plan else [])
            done = subprocess.run(cmd, capture_output=True, text=True)
            if done.returncode != 0:
                print(f"| {name} | | {mode} | failed: {done.stderr.strip().splitlines()[-1:]} |", flush=True)
                continue
            r = json.loads(done.stdout.strip().splitlines()[-1])
            total = r["proof_s"] + r.get("rivals_s", 0.0)
            base = total if mode == "single" else base
            dask1 = total if mode == "dask1" else dask1
            speed = f"{base / total:.2f}" if base else "-"
            speed += f" ({dask1 / total:.2f} vs dask1)" if mode == "dask" and dask1 else ""
            print(f"| {name} | {r['luminaires']:,} | {mode} | {r['tiles']} | "
                  f"{r['windows'] if r['windows'] is not None else 'not proved'} | {r['proof_s']} | "
                  f"{r.get('rivals_s', '-')} | {r.get('plan_s', '-')} | {speed} | {r['peak_mib']:,} |", flush=True)


if __name__ == "__main__":
    main()
