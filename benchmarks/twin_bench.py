"""Benchmark: the receiver twin's stages per pose on the bundled 512 plan (render, decode, locate).

Run from the repository root:  python benchmarks/twin_bench.py [--poses 40]

Plans layouts/grid-512.yaml (frames only: no maps, report or firmware), draws
covered poses as ``vlp-twin`` does, and times each stage over them on one core.
"""

from __future__ import annotations

import argparse
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from planner.decode.image import decode_frame  # noqa: E402
from planner.layout.read import read_layout  # noqa: E402
from planner.plan.file import load_plan  # noqa: E402
from planner.plan.pipeline import PlanOptions, make_plan, write_outputs  # noqa: E402
from planner.positioning.locate import locate  # noqa: E402
from planner.twin.render import render_frame  # noqa: E402
from planner.twin.twin import Twin, covered_poses, snapshot  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, default=40)
    args = ap.parse_args()
    print(f"python {platform.python_version()} on {platform.machine()}, {platform.node()}")
    with tempfile.TemporaryDirectory() as tmp:
        plan = make_plan(read_layout(ROOT / "layouts" / "grid-512.yaml", 512), PlanOptions(error_poses_per_m2=0))
        write_outputs(plan, Path(tmp) / "p", with_map=False, with_report=False, firmware=None)
        twin = Twin.from_plan(load_plan(Path(tmp) / "p" / "plan.yaml"))
    poses = covered_poses(twin, args.poses, seed=1)
    rotations = poses.rotation
    times = {"render": [], "decode": [], "locate": []}
    for k in range(len(poses)):
        t0 = time.perf_counter()
        frame = render_frame(twin.site.xyz, twin.site.radii, twin.chips, twin.modulation.chip_rate_hz, twin.camera,
                             poses.position[k], rotations[k], twin.sensor, np.random.default_rng(k))
        t1 = time.perf_counter()
        blobs = decode_frame(frame.image, twin.camera, twin.modulation, blur_px=twin.sensor.blur_px,
                             exposure_s=twin.sensor.exposure_s)
        t2 = time.perf_counter()
        locate(twin.site, snapshot(blobs, twin.camera))
        t3 = time.perf_counter()
        for name, dt in zip(times, (t1 - t0, t2 - t1, t3 - t2)):
            times[name].append(dt)
    w, h = twin.camera.width_px, twin.camera.height_px
    print(f"{len(poses)} covered poses of grid-512, {w} x {h} px frames, one core:")
    for name, dt in times.items():
        print(f"  {name:<7} median {1e3 * np.median(dt):6.1f} ms   90 % {1e3 * np.percentile(dt, 90):6.1f} ms")
    total = np.sum([times[n] for n in times], axis=0)
    print(f"  total   median {1e3 * np.median(total):6.1f} ms per pose ({1 / np.median(total):.2f} poses/s)")


if __name__ == "__main__":
    main()
