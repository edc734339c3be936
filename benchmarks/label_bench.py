"""Benchmark: the window scheme's labels against the window set of large sites (issue 34).

Run from the repository root:  python benchmarks/label_bench.py [--sites grid-512 lattice-1024 hex jittered]
[--tolerances 0 0.03]

For each site and install tolerance: the window set of every pose (:func:`planner.verify.proof.possible_windows`
with the proof's budgets lifted, as the sites over them are not proved by ``vlp-plan`` today), then
:func:`planner.codes.proved.proved_labels` against it. Prints one line per case: luminaires, windows,
the counting bound (bits), the bits found, the widths tried with the conflicts each left, whether the
result is within 2 bits of the bound (issue 34's Done-when), the proof's and the label search's wall
time [s] and the process's peak RSS. Every labelling is checked independently
(:func:`planner.verify.rivals.find_rivals`). The sites are those of ``tests/codes/sites.py``.
"""

from __future__ import annotations

import argparse
import platform
import resource
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests" / "codes"))

from sites import hexagonal_site, jittered_site, square_lattice  # noqa: E402

from planner.camera.model import Camera  # noqa: E402
from planner.codes.assignment import bits_for  # noqa: E402
from planner.codes.proved import proved_labels  # noqa: E402
from planner.studies.efficiency import paper_grid  # noqa: E402
from planner.verify.envelope import NotProvable, envelope  # noqa: E402
from planner.verify.proof import possible_windows  # noqa: E402
from planner.verify.rivals import find_rivals  # noqa: E402
from planner.verify.windows import CONGRUENCE_TOLERANCE_M  # noqa: E402

SITES = {"grid-512": lambda: paper_grid(512), "lattice-1024": lambda: square_lattice(1024),
         "hex": hexagonal_site, "jittered": jittered_site}
BUDGET = 10 ** 7


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sites", nargs="+", default=list(SITES), choices=list(SITES))
    ap.add_argument("--tolerances", nargs="+", type=float, default=[0.0, 0.03], metavar="M")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    print(f"# {platform.machine()}, python {platform.python_version()}, {time.strftime('%Y-%m-%d', time.gmtime())}")
    for name in args.sites:
        lay = SITES[name]()
        xyz, radii = lay.xyz, np.array([lum.radius for lum in lay.luminaires])
        for tol in args.tolerances:
            t0 = time.perf_counter()
            try:
                windows = possible_windows(xyz, radii, envelope(Camera(), xyz, radii, tol), BUDGET, BUDGET)
            except NotProvable as exc:
                print(f"{name:>12} {tol * 100:3.0f} cm: {len(xyz)} luminaires, {exc}", flush=True)
                continue
            t1 = time.perf_counter()
            got = proved_labels(windows, xyz, CONGRUENCE_TOLERANCE_M, seed=args.seed)
            t2 = time.perf_counter()
            if got is None:
                print(f"{name:>12} {tol * 100:3.0f} cm: {len(xyz)} luminaires, {len(windows):,} windows: over the "
                      f"budgets of the pairs and the shape groups ({t2 - t1:.1f} s)", flush=True)
                continue
            ids = (got.labels if got.labels is not None else np.arange(len(xyz))) + 1
            assert find_rivals(windows, xyz, ids, CONGRUENCE_TOLERANCE_M) == []
            rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
            print(f"{name:>12} {tol * 100:3.0f} cm: {len(xyz)} luminaires, {len(windows):,} windows, bound "
                  f"{got.bound_bits} bits, found {got.bits} bits (naive {bits_for(len(xyz))}), widths "
                  f"{got.detail['widths_tried']} left {got.detail['conflicts_left']}, within 2 bits: "
                  f"{got.bits <= got.bound_bits + 2}; window set {t1 - t0:.1f} s, labels {t2 - t1:.1f} s, "
                  f"peak RSS {rss_mb:.0f} MB", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
