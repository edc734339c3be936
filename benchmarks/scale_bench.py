"""The proof at scale (issue 34): time, peak memory and tightness of the proved window set, site by site.

Run from the repository root:  python benchmarks/scale_bench.py [--sites grid-512 lattice-1024 ...]
                                                                [--poses 1000000] [--plan] [--limit-gib 10]

Sites: ``grid-512`` (bundled), ``lattice-N`` (:func:`planner.studies.efficiency.lattice_layout`, 0.5 m),
``hex-1088`` and ``jittered-2040`` (``tests/codes/sites.py``: the issue's hexagonal and jittered sites) and
``jittered-N`` otherwise (``benchmarks/parallel_bench.py``: a 0.5 m lattice, each luminaire moved up to 15 cm),
and :data:`SMALL`'s ``small-...`` sites (the largest of the irregular families the tests draw with hypothesis).

Each site runs in a child process (its peak memory is its own; ``--limit-gib`` caps its address space).
The child proves the window set at the default 3 cm install tolerance in process
(:func:`planner.verify.proof.prove_window_set`) and records the proof's CPU and wall seconds and the peak
RSS after it. Then the **tightness**: ``--installs`` installations, each luminaire displaced uniformly in a
disc of the install tolerance (seeded), share ``--poses`` fresh poses (Sobol seeds the planner never uses);
the windows the receiver accepts at them (:func:`planner.verify.windows.find_windows` on the installed site,
then ``tests/conftest.accepted``: not collinear as drawn, no installed LED's disc over a side) are the
*found* windows. Every found window must be in the proved set (``outside`` must be 0); the tightness ratio
is the proved set over the found windows. On a site larger than ``--patch-m2`` the poses cover a central
square of that area and both sets are counted over the windows wholly inside that square shrunk by
``PATCH_MARGIN_M`` (same pose density as a small site, the ratio is local). ``--plan`` adds the whole
``make_plan`` (default options): its seconds, bits, scheme and the counting bound.
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
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

INSTALL_M = 0.03
"""The default install tolerance [m] (planner.defaults), proved and sampled."""
PATCH_MARGIN_M = 3.0
"""Windows counted in a patch lie wholly this far inside it [m]: poses outside the patch see none of them
less often than poses inside it would."""
FRESH_SEED = 90_000
"""First Sobol seed of the fresh poses: far from the planner's (0) and the tests' (10,000-30,000)."""


SMALL = ("small-grid-9x9-j0.12-s5", "small-hex-8x8", "small-poisson-60-0.4-s3")
"""The largest members of the irregular families the tests draw with hypothesis (``tests/verify/test_window_set.sites``:
a 0.5 m lattice moved by a normal jitter, a 0.6 m triangular lattice, dart throwing), at 2.5 m."""


def small_site(name: str):
    """One site of :data:`SMALL`'s families, its parameters in its name."""
    from conftest import grid_xy, hex_xy, poisson_xy
    from planner.layout.model import Layout, Luminaire

    kind, *args = name.split("-")[1:]
    if kind == "grid":
        rows, cols = map(int, args[0].split("x"))
        xy = grid_xy(rows, cols, 0.5, 0.5, jitter_m=float(args[1][1:]), seed=int(args[2][1:]))
    elif kind == "hex":
        xy = hex_xy(*map(int, args[0].split("x")), 0.6)
    else:
        xy = poisson_xy(int(args[0]), float(args[1]), int(args[2][1:]))
    return Layout(tuple(Luminaire(f"L{k}", float(x), float(y), 2.5) for k, (x, y) in enumerate(xy)),
                  source_path=f"{name}.yaml")


def site(name: str):
    from parallel_bench import site as bench_site

    if name.startswith("small-"):
        return small_site(name)
    if name == "hex-1088":
        from codes.sites import hexagonal_site

        return hexagonal_site()
    if name == "jittered-2040":
        from codes.sites import jittered_site

        return jittered_site()
    return bench_site(name)


def _cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _peak_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _square(xy: np.ndarray, area_m2: float | None) -> np.ndarray | None:
    """A square of ``area_m2`` centred on the site (corners, counter-clockwise), or None for the whole site."""
    if area_m2 is None:
        return None
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    half, mid = math.sqrt(area_m2) / 2, (lo + hi) / 2
    return mid + half * np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=float)


def _inside(triples: np.ndarray, xy: np.ndarray, square: np.ndarray | None) -> np.ndarray:
    """The rows of ``triples`` whose three luminaires lie PATCH_MARGIN_M inside ``square`` (all without one)."""
    if square is None or len(triples) == 0:
        return triples
    lo, hi = square.min(axis=0) + PATCH_MARGIN_M, square.max(axis=0) - PATCH_MARGIN_M
    p = xy[triples]
    return triples[((p >= lo) & (p <= hi)).all(axis=(1, 2))]


def found_windows(layout, poses_total: int, installs: int, square: np.ndarray | None) -> tuple[np.ndarray, int]:
    """The distinct windows the receiver accepts at ``poses_total`` fresh poses over ``installs`` displaced
    installations (sorted triples), and the poses drawn."""
    from conftest import accepted
    from planner.camera.model import Camera
    from planner.layout.model import area_m2
    from planner.verify.windows import find_windows, sample_poses, working_area

    cam, drawn = Camera(), layout.xyz
    radii = np.array([lum.radius for lum in layout.luminaires])
    area = working_area(drawn[:, :2], layout.outline) if square is None else square
    per_m2 = poses_total / installs / area_m2(area)
    found, drawn_poses = [], 0
    for k in range(installs):
        rng = np.random.default_rng(FRESH_SEED + k)
        angle, reach = rng.uniform(0, 2 * math.pi, len(drawn)), INSTALL_M * np.sqrt(rng.uniform(0, 1, len(drawn)))
        installed = drawn + np.column_stack([reach * np.cos(angle), reach * np.sin(angle), np.zeros(len(drawn))])
        poses = sample_poses(area, cam, per_m2, FRESH_SEED + k)
        drawn_poses += len(poses)
        pw = find_windows(poses, installed, radii, cam)
        w = np.unique(pw.triples[pw.triples[:, 0] >= 0], axis=0)
        found.append(accepted(w, drawn, installed, radii))
    return np.unique(np.concatenate(found), axis=0), drawn_poses


def one(name: str, poses: int, installs: int, patch_m2: float, with_plan: bool) -> dict:
    """Measure one site in this process; the figures as a dict."""
    from planner.camera.model import Camera
    from planner.layout.model import area_m2
    from planner.verify.proof import prove_window_set
    from planner.verify.windows import working_area

    layout = site(name)
    xyz, radii = layout.xyz, np.array([lum.radius for lum in layout.luminaires])
    out: dict = {"site": name, "luminaires": len(xyz)}
    c0, t0 = _cpu_s(), time.perf_counter()
    proof = prove_window_set(xyz, radii, Camera(), INSTALL_M)
    out.update(proof_cpu_s=round(_cpu_s() - c0, 1), proof_wall_s=round(time.perf_counter() - t0, 1),
               proof_peak_mib=round(_peak_mib()), proved=proof.complete, reason=proof.reason,
               windows=len(proof.triangles) if proof.triangles is not None else None,
               tiles=(proof.envelope or {}).get("tiles"), over_budget=(proof.envelope or {}).get("tiles_over_budget"))
    print(json.dumps(out), file=sys.stderr, flush=True)  # the proof's figures survive a later failure
    if poses and proof.triangles is not None:
        site_m2 = area_m2(working_area(xyz[:, :2], layout.outline))
        square = _square(xyz[:, :2], patch_m2) if site_m2 > 2 * patch_m2 else None
        t1 = time.perf_counter()
        found, drawn = found_windows(layout, poses, installs, square)
        proved = np.sort(proof.triangles, axis=1)
        found_set = {tuple(t) for t in found.tolist()}
        proved_set = {tuple(t) for t in proved.tolist()}
        local = _inside(proved, xyz[:, :2], square)
        local_found = _inside(found, xyz[:, :2], square)
        out.update(poses=drawn, installs=installs, patch_m2=patch_m2 if square is not None else None,
                   found=len(local_found), found_all=len(found_set), outside=len(found_set - proved_set),
                   proved_counted=len(local), ratio=round(len(local) / max(len(local_found), 1), 3),
                   sample_s=round(time.perf_counter() - t1, 1))
        print(json.dumps(out), file=sys.stderr, flush=True)
    if with_plan:
        from planner.plan.pipeline import make_plan

        c2, t2 = _cpu_s(), time.perf_counter()
        plan = make_plan(layout)
        a = plan.assignment
        out.update(plan_cpu_s=round(_cpu_s() - c2, 1), plan_wall_s=round(time.perf_counter() - t2, 1), bits=a.bits,
                   bound=a.lower_bound_bits, scheme=a.scheme, plan_proved=plan.verification.window_set.proved)
    out["peak_mib"] = round(_peak_mib())
    return out


def _cell(r: dict, key: str, fmt: str = "{:,}") -> str:
    return "-" if r.get(key) is None else fmt.format(r[key])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sites", nargs="+", default=[*SMALL, "grid-512", "lattice-1024", "hex-1088", "jittered-2040",
                                                   "jittered-10000", "lattice-100000"])
    ap.add_argument("--poses", type=int, default=1_000_000, help="fresh poses per site (0: no tightness)")
    ap.add_argument("--installs", type=int, default=10, help="displaced installations sharing the poses")
    ap.add_argument("--patch-m2", type=float, default=400.0, help="larger sites are sampled in a central square")
    ap.add_argument("--plan", action="store_true", help="also time make_plan (default options)")
    ap.add_argument("--limit-gib", type=float, default=10.0, help="address-space cap of each site's process")
    ap.add_argument("--one", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        print(json.dumps(one(args.one, args.poses, args.installs, args.patch_m2, args.plan)))
        return
    print(f"# {platform.node()}, {platform.machine()}, python {platform.python_version()}, "
          f"{time.strftime('%Y-%m-%d', time.gmtime())}; install tolerance {100 * INSTALL_M:g} cm, "
          f"{args.installs} displaced installations, cap {args.limit_gib:g} GiB per site")
    print("| site | luminaires | proof CPU [s] | proof wall [s] | proof peak [MiB] | proved set | poses | "
          "found | outside | tightness | plan wall [s] | bits (bound) | peak [MiB] |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    limit = int(args.limit_gib * 2**30)
    for name in args.sites:
        cmd = [sys.executable, __file__, "--one", name, "--poses", str(args.poses), "--installs", str(args.installs),
               "--patch-m2", str(args.patch_m2)] + (["--plan"] if args.plan else [])
        done = subprocess.run(cmd, capture_output=True, text=True,
                              preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_AS, (limit, limit)))
        if done.returncode != 0:
            lines = done.stderr.strip().splitlines()
            why = [x for x in lines if not x.startswith("{")][-1:]
            got = [x for x in lines if x.startswith("{")][-1:]  # the figures measured before it failed
            print(f"| {name} | failed (exit {done.returncode}): {' '.join(why)} | {' '.join(got)} |", flush=True)
            continue
        r = json.loads(done.stdout.strip().splitlines()[-1])
        where = f" in {r['patch_m2']:g} m2" if r.get("patch_m2") else ""
        bits = f"{r['bits']} ({r['bound']}, {r['scheme']})" if r.get("bits") is not None else "-"
        windows = f"{r['windows']:,}" if r["proved"] else f"not proved: {r['reason']}"
        counted = f" ({r['proved_counted']:,} counted)" if r.get("patch_m2") else ""
        print(f"| {name} | {r['luminaires']:,} | {r['proof_cpu_s']} | {r['proof_wall_s']} | {r['proof_peak_mib']:,} | "
              f"{windows}{counted} | {_cell(r, 'poses')}{where} | {_cell(r, 'found')} | {_cell(r, 'outside')} | "
              f"{_cell(r, 'ratio', '{:.2f}')} | {_cell(r, 'plan_wall_s')} | {bits} | {r['peak_mib']:,} |", flush=True)
        assert not r.get("outside"), f"{name}: {r['outside']} found windows outside the proved set"


if __name__ == "__main__":
    main()
