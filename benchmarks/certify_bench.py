"""The certificate over pose boxes on one tile of a site: how much of the proved set it removes, at what cost.

Run from the repository root:  python benchmarks/certify_bench.py [--site grid-512] [--budget 60000]
                                                                  [--min-width 0.02] [--poses 200000]

Computes the proved set (planner/verify/proof.py, 3 cm install tolerance, the paper's camera), picks the
tile of axis points nearest the site's middle (a lattice cell: an interior tile), and certifies it
(planner/verify/certify.py) on one core. Prints the tile's candidates (proved triangles whose luminaires
its poses may see), what the certificate keeps, whether the tile finished or fell back to its candidates
(box budget), boxes and seconds; and, for tightness, the distinct windows of ``--poses`` poses with their
axis point in the tile (every height, tilt, roll), each batch on a fresh installation (luminaires moved up
to 3 cm), with how many of them the certificate kept (must be all).
"""

from __future__ import annotations

import argparse
import math
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from planner.camera.model import Camera  # noqa: E402
from planner.layout.read import ReadOptions, read_layout  # noqa: E402
from planner.verify import certify as ce  # noqa: E402
from planner.verify import certify_witness as cw  # noqa: E402
from planner.verify.envelope import envelope  # noqa: E402
from planner.verify.proof import possible_windows  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--site", default="grid-512")
    ap.add_argument("--budget", type=int, default=60_000, help="boxes for the tile")
    ap.add_argument("--min-width", type=float, default=0.02)
    ap.add_argument("--poses", type=int, default=200_000)
    args = ap.parse_args()
    layout = read_layout(ROOT / "layouts" / f"{args.site}.yaml", None, ReadOptions())
    xyz, radii = layout.xyz, np.array([lum.radius for lum in layout.luminaires])
    cam, d = Camera(), 0.03
    env = envelope(cam, xyz, radii, d)
    print(f"# {platform.processor() or platform.machine()}, python {platform.python_version()}, "
          f"{time.strftime('%Y-%m-%d %H:%M')}; {args.site}, min width {args.min_width}, budget {args.budget:,} boxes")
    t0 = time.perf_counter()
    cand = possible_windows(xyz, radii, env, budget=10**8, pair_budget=10**8)
    print(f"proved set: {len(cand):,} triangles in {time.perf_counter() - t0:.1f} s")
    xy = xyz[:, :2]
    origin, tile_m, nx, ny = ce.tile_grid(xy, env)
    middle = 0.5 * (xy.min(axis=0) + xy.max(axis=0))
    ix, iy = ((middle - origin) // tile_m).astype(int)
    number = int(iy * nx + ix)
    x0, y0 = origin + tile_m * np.array([ix, iy])
    cert = ce.certify_windows(xyz, radii, cam, d, cand, min_width=args.min_width, budget=args.budget, tiles=[number])
    res = cert.per_tile[0] if cert.per_tile else None
    local_cand = _tile_candidates(cand, xy, env, np.array([x0 + tile_m / 2, y0 + tile_m / 2]), tile_m)
    print(f"tile {number} (axis points x {x0:.2f}-{x0 + tile_m:.2f}, y {y0:.2f}-{y0 + tile_m:.2f} m): "
          f"{local_cand:,} candidates, kept {len(cert.triangles):,}, "
          f"{'FELL BACK (budget)' if res is None or res.fallback else 'certified'}, {cert.boxes:,} boxes, "
          f"{cert.seconds:.1f} s (numba compile included on a first run)")
    rng = np.random.default_rng(1)
    view, _ = ce.view_bounds(cam, env)
    found: set[tuple[int, int, int]] = set()
    t0 = time.perf_counter()
    for batch in range(0, args.poses, 20_000):
        shift = rng.normal(size=xy.shape)
        shift *= d * rng.uniform(0, 1, (len(xy), 1)) / np.linalg.norm(shift, axis=1, keepdims=True)
        box = np.array([x0, x0 + tile_m, y0, y0 + tile_m, env.near_m, env.far_m, 0.0, env.tilt_rad, 0, 2 * math.pi])
        buf = np.empty((20_008, 3), dtype=np.int64)
        k = cw.box_witnesses(box, xy + shift, radii, view, min(20_000, args.poses - batch), batch, buf,
                             np.empty(0, dtype=np.int64), d)
        found |= set(map(tuple, buf[:k].tolist()))
    kept = set(map(tuple, cert.triangles.tolist()))
    inside = found & set(map(tuple, cand.tolist()))
    print(f"sampled: {len(inside):,} distinct windows (of the proved set) in {args.poses:,} poses "
          f"({time.perf_counter() - t0:.1f} s); kept by the certificate: {len(inside & kept):,}; "
          f"ratio kept / sampled: {len(kept) / max(len(inside), 1):.2f}, candidates / sampled: "
          f"{local_cand / max(len(inside), 1):.2f}")


def _tile_candidates(cand: np.ndarray, xy: np.ndarray, env, centre: np.ndarray, tile_m: float) -> int:
    """Proved triangles whose three luminaires lie within reach of the tile (those its poses may take)."""
    reach = env.axis_reach_m + env.install_m + tile_m / math.sqrt(2) + 0.01
    near = np.linalg.norm(xy - centre, axis=1) <= reach
    return int(near[cand].all(axis=1).sum())


if __name__ == "__main__":
    main()
