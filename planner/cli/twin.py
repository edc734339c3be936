"""``vlp-twin PLAN``: render the camera frames a plan gives, decode them like a receiver app, and grade each stage.

One pose (``--pose X,Y,Z,TILT,AZ,ROLL``, optionally ``--png`` to keep the frame)
or a batch of random covered poses (``--poses N``), with the success rate, each
stage's own rate, the position errors and every failure named by its stage.
Exit codes: 0 the success rate reached ``--min-success`` (one pose: it located),
3 it did not, 1 bad input, 2 usage.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from planner._files import write_bytes_atomically
from planner.cli import common as cli
from planner.defaults import (
    ACCELEROMETER_SIGMA_DEG,
    MAX_BLUR_PX,
    MAX_TWIN_POSES,
    SENSOR_BLUR_PX,
    SENSOR_EXPOSURE_S,
    SENSOR_READ_NOISE_DN,
)
from planner.defaults import TWIN_TOLERANCE_M as TOLERANCE_M
from planner.errors import ExitCode, UsageError

if TYPE_CHECKING:  # the stages (OpenCV, SciPy) load when the command runs, not when it parses
    import numpy as np

    from planner.camera.model import Camera
    from planner.plan.file import PlanFile
    from planner.twin.render import Sensor
    from planner.twin.twin import PoseResult



def build_parser() -> argparse.ArgumentParser:
    p = cli.parser(
        "vlp-twin",
        "Receiver twin: render the frame a rolling-shutter camera captures of the plan's luminaires "
        "(each LED striped by its own frame), decode it as a receiver app does (blobs, ellipses, stripes, "
        "preamble, ID), identify the luminaires from the plan and locate; report every stage.",
        ok="success rate reached --min-success (one pose: located)", check_failed="it did not",
        docs="docs/twin.md", json="print the result as JSON",
    )
    p.add_argument("plan", metavar="PLAN", help="a plan.yaml written by vlp-plan")
    g = p.add_argument_group("poses")
    g.add_argument("--pose", metavar="X,Y,Z,TILT,AZ,ROLL", help="one pose: position [m], tilt, azimuth, roll [deg]")
    g.add_argument("--png", metavar="FILE", help="with --pose: write the rendered frame as PNG")
    g.add_argument("--poses", type=cli.count_up_to(MAX_TWIN_POSES), default=300, metavar="N",
                   help=f"batch: N random poses where the plan is decodable (default 300, at most {MAX_TWIN_POSES:,})")
    g.add_argument("--seed", type=cli.seed, default=0, help="seed of the poses, phases and noise (default 0)")
    g.add_argument("--jobs", type=cli.positive_int, default=os.cpu_count() or 1, metavar="J",
                   help="worker processes for a batch (default: one per core)")
    g.add_argument("--save-failures", metavar="DIR", help="batch: write each failed pose's frame as PNG into DIR")
    g = p.add_argument_group("camera and sensor")
    cli.add_camera_flag(g, "the phone that films the ceiling (a phone other than the plan's shows what it would "
                        "read); default: the plan's camera")
    g.add_argument("--exposure-us", type=cli.positive_float, default=SENSOR_EXPOSURE_S * 1e6, metavar="US",
                   help=f"row exposure [us] (default {SENSOR_EXPOSURE_S * 1e6:g})")
    g.add_argument("--blur-px", type=cli.at_most(MAX_BLUR_PX, strict=False), default=SENSOR_BLUR_PX, metavar="PX",
                   help=f"optics blur, Gaussian sigma [px] (default {SENSOR_BLUR_PX:g}, at most {MAX_BLUR_PX:g})")
    g.add_argument("--read-noise-dn", type=cli.at_most(255.0, strict=False), default=SENSOR_READ_NOISE_DN, metavar="DN",
                   help=f"read noise sigma [DN of 255] (default {SENSOR_READ_NOISE_DN:g})")
    g.add_argument("--off-level", type=cli.share, default=0.0, metavar="SHARE",
                   help="light of an 'off' chip as a share of 'on' (default 0)")
    g.add_argument("--accelerometer-deg", type=cli.non_negative_float, default=ACCELEROMETER_SIGMA_DEG, metavar="DEG",
                   help="gravity plans: RMS error of the accelerometer's vertical, in degrees "
                   f"(default {ACCELEROMETER_SIGMA_DEG:g})")
    g = p.add_argument_group("grading")
    g.add_argument("--max-error", type=cli.positive_float, default=TOLERANCE_M, metavar="M",
                   help=f"a fix this close to the truth counts as located [m] (default {TOLERANCE_M:g})")
    g.add_argument("--min-success", type=cli.share, default=0.99, metavar="SHARE",
                   help="batch: exit 3 below this success rate (default 0.99)")
    return p


def _sensor(args) -> Sensor:
    from planner.twin.render import Sensor

    return Sensor(exposure_s=args.exposure_us * 1e-6, blur_px=args.blur_px, read_noise_dn=args.read_noise_dn,
                  off_level=args.off_level)


_WORKER: dict = {}


def _init(plan: PlanFile, sensor: Sensor, tolerance_m: float, accelerometer_deg: float, camera: Camera) -> None:
    from planner.twin.twin import Twin

    _WORKER.update(twin=Twin.from_plan(plan, sensor, accelerometer_deg, camera), tolerance_m=tolerance_m)


def _one(task) -> PoseResult:
    import numpy as np

    from planner.twin.twin import run_pose

    k, seed, position, rotation, angles = task
    twin = _WORKER["twin"]
    result, _ = run_pose(twin, position, rotation, angles, np.random.default_rng([seed, k]), _WORKER["tolerance_m"])
    return result


def _write_png(path: Path, image: np.ndarray) -> None:
    import cv2

    ok, data = cv2.imencode(".png", image)
    write_bytes_atomically(path, data.tobytes())


def _pose_text(r: PoseResult) -> str:
    x, y, z = r.position
    tilt, az, roll = r.angles_deg
    return f"({x:.2f}, {y:.2f}, {z:.2f}) m, tilt {tilt:.1f} az {az:.1f} roll {roll:.1f} deg"


def run_batch(plan: PlanFile, args, sensor: Sensor) -> list[PoseResult]:
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    import numpy as np

    from planner.twin.twin import Twin, covered_poses, run_pose

    camera = cli.camera_from_args(args, plan.camera_model())
    twin = Twin.from_plan(plan, sensor, args.accelerometer_deg, camera)
    poses = covered_poses(twin, args.poses, args.seed)
    rotations = poses.rotation
    angles = np.degrees(np.column_stack([poses.tilt_rad, poses.azimuth_rad, poses.roll_rad]))
    tasks = [(k, args.seed, poses.position[k], rotations[k], tuple(angles[k])) for k in range(len(poses))]
    show = sys.stderr.isatty()
    results = []
    init = (plan, sensor, args.max_error, args.accelerometer_deg, camera)
    stream: Iterator[PoseResult]
    if args.jobs == 1:
        _init(*init)
        stream = map(_one, tasks)
    else:
        # spawned, as planner.parallel's pool: a forked child of a threaded process (a test runner, a caller's
        # thread pool) can inherit a lock held by another thread and hang
        pool = ProcessPoolExecutor(args.jobs, mp_context=multiprocessing.get_context("spawn"), initializer=_init,
                                   initargs=init)
        stream = pool.map(_one, tasks, chunksize=4)
    try:
        for k, r in enumerate(stream, 1):
            results.append(r)
            if show:
                print(f"\rvlp-twin: pose {k}/{len(tasks)}, {sum(not x.ok for x in results)} failed", end="",
                      file=sys.stderr, flush=True)
    finally:
        if args.jobs != 1:
            pool.shutdown(cancel_futures=True)
        if show:
            print(file=sys.stderr)
    if args.save_failures:
        out = Path(args.save_failures)  # checked by main() before any frame is rendered
        out.mkdir(parents=True, exist_ok=True)
        for k, r in enumerate(results):
            if not r.ok:
                _, frame = run_pose(twin, *tasks[k][2:4], tasks[k][4], np.random.default_rng([args.seed, k]))
                _write_png(out / f"pose-{k:04d}-{r.stage}.png", frame.image)
    return results


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.png and not args.pose:
        raise UsageError("--png needs --pose (a batch writes failed frames with --save-failures DIR)")
    cli.output_file("--png", args.png)  # its folder must exist before any frame is rendered
    cli.output_dir("--save-failures", args.save_failures)
    if args.blur_px < 0 or args.read_noise_dn < 0 or not 0 <= args.off_level < 1:
        raise UsageError("--blur-px and --read-noise-dn must be >= 0, --off-level in [0, 1)")
    from planner.plan.file import load_plan

    plan = load_plan(args.plan)
    sensor = _sensor(args)  # the renderer (OpenCV, SciPy) loads only for a plan that reads
    from planner.twin.twin import summary

    if args.pose:
        return _single(plan, args, sensor)
    results = run_batch(plan, args, sensor)
    s = summary(results)
    mod = plan.modulation
    if mod is not None and mod.video_frames > 1:  # a multi-frame plan: each pose was read over video frames
        s = {**s, "video_frames": mod.video_frames, "video_fps": mod.video_fps}
    failures = [{"pose": k, "stage": r.stage, "detail": r.detail, "where": _pose_text(r)}
                for k, r in enumerate(results) if not r.ok]
    if args.json:
        print(json.dumps({**s, "seed": args.seed, "failures": failures}, indent=2))
    else:
        _print_batch(args, s, failures)
    return 0 if s["success_rate"] >= args.min_success else ExitCode.CHECK_FAILED


def _print_batch(args, s: dict, failures: list[dict]) -> None:
    from planner.report.content import length_text

    tol = length_text(args.max_error)
    print(f"vlp-twin: {args.plan}: {s['poses']} covered poses (seed {args.seed}); exposure {args.exposure_us:g} us, "
          f"blur {args.blur_px:g} px, read noise {args.read_noise_dn:g} DN"
          + (f"; IDs read over {s['video_frames']} video frames at {s['video_fps']:g} fps" if "video_frames" in s
             else ""))
    print(f"  blobs    {s['blobs_found']} of {s['leds_in_view']} LEDs in view found ({100 * s['blob_rate']:.1f} %)")
    print(f"  ids      {s['ids_read']} of {s['blobs_found']} read right ({100 * s['id_rate']:.1f} %), "
          f"{s['ids_misread']} misread")
    e = s["error_m"]
    err = f": median {length_text(e['median'])}, 90 % {length_text(e['p90'])}, max {length_text(e['max'])}" if e else ""
    print(f"  located  {s['located']} of {s['poses']} poses within {tol} ({100 * s['success_rate']:.1f} %){err}")
    print("  failed   " + ", ".join(f"{st} {n}" for st, n in s["failed_by_stage"].items()))
    for f in failures:
        print(f"    pose {f['pose']} {f['where']}: {f['stage']}: {f['detail']}")


def _single(plan: PlanFile, args, sensor: Sensor) -> int:
    import numpy as np

    from planner.cli.locate import _pose
    from planner.report.content import length_text
    from planner.twin.twin import Twin, run_pose

    position, rotation = _pose(args.pose, "--pose")
    twin = Twin.from_plan(plan, sensor, args.accelerometer_deg, cli.camera_from_args(args, plan.camera_model()))
    angles = tuple(float(v) for v in args.pose.split(",")[3:])
    r, frame = run_pose(twin, position, rotation, angles, np.random.default_rng(args.seed), args.max_error)
    if args.png:
        _write_png(Path(args.png), frame.image)
    blobs: list[dict[str, Any]] = [{"centre_px": [round(b.ellipse.cx, 2), round(b.ellipse.cy, 2)] if b.ellipse else None,
              "axes_px": [round(b.ellipse.major, 2), round(b.ellipse.minor, 2)] if b.ellipse else None,
              "id": b.id, "chips": b.chips, "problem": b.problem} for b in r.blobs]
    result = {"pose": _pose_text(r), "located": r.ok, "stage": r.stage or None, "detail": r.detail,
              "error_m": None if math.isnan(r.error_m) else round(r.error_m, 6),
              "leds_in_view": r.seen, "blobs_found": r.found, "ids_read": r.read, "ids_misread": r.misread,
              "blobs": blobs}
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"vlp-twin: {args.plan}: pose {result['pose']}")
        for b in blobs:
            where = f"({b['centre_px'][0]:7.1f}, {b['centre_px'][1]:7.1f}) px" if b["centre_px"] else "(no ellipse)"
            print(f"  blob {where}  ID {b['id'] if b['id'] is not None else '-':>4}  {b['problem']}")
        state = (f"located within {length_text(args.max_error)} (error {length_text(r.error_m)})" if r.ok
                 else f"failed at {r.stage}: {r.detail}")
        print(f"  {r.found} of {r.seen} LEDs in view found, {r.read} IDs read, {r.misread} misread; {state}")
    return 0 if r.ok else ExitCode.CHECK_FAILED


def console_main(argv: list[str] | None = None) -> int:
    return cli.console_main(argv, main, "vlp-twin")


if __name__ == "__main__":
    raise SystemExit(console_main())
