"""Benchmark: label all L windows of square-grid sites at the fewest bits the search reaches.

Run from the repository root:  python benchmarks/window_code_bench.py [--grids 16x32 100x100 316x316]

For each grid: every unit cell gives four L windows (right-angle corner, arm, arm +90
degrees, counter-clockwise from the corner), all of one non-symmetric shape. Prints
one line per grid: windows, labels K, bits, counting lower bound (labels and bits), the
method and the wall time [s] of :func:`planner.codes.window.assign_window_code`.
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from planner.codes.window import assign_window_code, count_conflicts  # noqa: E402


def l_windows(rows: int, cols: int) -> np.ndarray:
    """The 4 L windows of every unit cell of a rows x cols grid (luminaire r * cols + c at (c, r))."""
    r, c = np.meshgrid(np.arange(rows - 1), np.arange(cols - 1), indexing="ij")
    r, c = r.ravel(), c.ravel()
    square = np.stack([r * cols + c, r * cols + c + 1, (r + 1) * cols + c + 1, (r + 1) * cols + c], axis=1)
    return np.concatenate([square[:, [k, (k + 1) % 4, (k + 3) % 4]] for k in range(4)])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grids", nargs="+", default=["16x32", "100x100", "316x316"])
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    print(f"# {platform.processor() or platform.machine()}, python {platform.python_version()}")
    for spec in args.grids:
        rows, cols = (int(v) for v in spec.lower().split("x"))
        w = l_windows(rows, cols)
        shape, sym = np.zeros(len(w), np.int64), np.array([False])
        t0 = time.perf_counter()
        code = assign_window_code(rows * cols, w, shape, sym, seed=args.seed)
        dt = time.perf_counter() - t0
        assert count_conflicts(w, shape, sym, code.labels, code.K) == 0
        print(f"grid {spec:>8}: luminaires {rows * cols:6d}  windows {len(w):7d}  K {code.K:4d}  bits {code.bits}"
              f"  lower bound {code.lower_bound_labels} labels / {code.lower_bound_bits} bits"
              f"  optimal {code.optimal}  {code.method:14s}  {dt:7.2f} s", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
