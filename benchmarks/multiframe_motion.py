"""Measurement: IDs read over k video frames on a multi-frame plan, still and with a shaking hand, and at a
video rate off the plan's.

Run from the repository root:  python benchmarks/multiframe_motion.py PLAN [--poses 40] [--shake-deg 0 0.1 0.5]
    [--fps 30 29.97]

PLAN is a multi-frame plan.yaml (``vlp-plan layouts/dialux-office.dxf --camera`` a 110 deg camera). For each
shake (standard deviation of the turn between consecutive frames, about a random axis) and each real video
rate (the receiver knows its own), prints the share of poses reading at least three IDs right with none
misread, the IDs read of the LEDs found, and the poses located within 10 cm.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from planner.defaults import TWIN_TOLERANCE_M  # noqa: E402
from planner.plan.file import load_plan  # noqa: E402
from planner.twin.twin import Twin, covered_poses, run_video_pose  # noqa: E402
from planner.twin.video import VideoFormat  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("plan")
    p.add_argument("--poses", type=int, default=40)
    p.add_argument("--shake-deg", type=float, nargs="+", default=[0.0, 0.1, 0.5])
    p.add_argument("--fps", type=float, nargs="+", default=[30.0])
    args = p.parse_args()
    twin = Twin.from_plan(load_plan(args.plan))
    if twin.video is None:
        sys.exit(f"{args.plan}: a single-frame plan; give a multi-frame one")
    poses = covered_poses(twin, args.poses, seed=0)
    print(f"{args.plan}: {twin.video.frames} video frames at {twin.video.fps:g} fps, {args.poses} poses (seed 0)")
    for fps in args.fps:
        video = VideoFormat(twin.video.frames, fps)
        for shake in args.shake_deg:
            results = [run_video_pose(twin, video, poses.position[k], poses.rotation[k], (0, 0, 0),
                                      np.random.default_rng([0, k]), TWIN_TOLERANCE_M, math.radians(shake))[0]
                       for k in range(args.poses)]
            ids = sum(r.read >= 3 and r.misread == 0 for r in results)
            print(f"  fps {fps:g} shake {shake:g} deg/frame: {ids} of {args.poses} poses read >= 3 IDs, "
                  f"{sum(r.read for r in results)} of {sum(r.found for r in results)} IDs, "
                  f"{sum(r.misread for r in results)} misread, {sum(r.ok for r in results)} located")


if __name__ == "__main__":
    main()
