"""``vlp-calibrate``: a camera YAML from chessboard photos, and the rolling shutter's row time from a blinking LED.

``vlp-calibrate IMAGES... --board 9x6 --square-m 0.025 -o phone.yaml`` fits intrinsics and
distortion (:mod:`planner.calibration.chessboard`); ``--row-time PHOTO --blink-hz F`` measures
the row time (:mod:`planner.calibration.row_time`), alone or into the same file;
``--blink-firmware DIR --blink-hz F`` writes the test luminaire's firmware; ``--heights M=PHOTO...``
keeps the paper's focal-length-versus-distance fit (:mod:`planner.calibration.heights`). Exit codes: 0 done,
1 bad input (unreadable photo, board never found, mixed image sizes, no stripes), 2 usage.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from planner._files import write_text_atomically
from planner.cli import common as cli
from planner.defaults import MCU_CLOCK_HZ
from planner.errors import InputError, UsageError

if TYPE_CHECKING:
    import numpy as np

    from planner.calibration.chessboard import Board
    from planner.camera.model import Camera


def build_parser() -> argparse.ArgumentParser:
    p = cli.parser(
        "vlp-calibrate",
        "Calibrate a phone camera: intrinsics and lens distortion from photos of a printed chessboard "
        "(OpenCV), and the rolling shutter's row time from a photo of a luminaire blinking a square wave; write "
        "a camera YAML (docs/camera.md) for --camera.",
        ok="done", docs="docs/camera.md#calibration", json="print the result as JSON",
    )
    p.add_argument("images", nargs="*", metavar="IMAGES", help="chessboard photos (JPEG/PNG), all the same size")
    g = p.add_argument_group("chessboard")
    g.add_argument("--board", default="9x6", metavar="COLSxROWS",
                   help="inner corners of the board, across x down (default 9x6: a board of 10 x 7 squares)")
    g.add_argument("--square-m", type=cli.positive_float, default=0.025, metavar="M",
                   help="side of one square [m] (default 0.025; sets the board poses, not the intrinsics)")
    g.add_argument("--charuco", metavar="DICT",
                   help="the board is ChArUco with markers of this OpenCV ArUco dictionary (e.g. DICT_5X5_100; "
                   "--board still counts inner corners), which may be partly out of view")
    g.add_argument("--marker-m", type=cli.positive_float, metavar="M",
                   help="with --charuco: side of one marker [m] (default 0.7 x --square-m)")
    g.add_argument("--lens", choices=["pinhole", "fisheye"], default="pinhole",
                   help="distortion model: pinhole (k1 k2 p1 p2 k3, default) or fisheye (k1..k4, lenses past about "
                   "110 deg)")
    g = p.add_argument_group("rolling shutter")
    g.add_argument("--row-time", metavar="PHOTO",
                   help="photo of a luminaire blinking a square wave at --blink-hz: the stripes give the row time")
    g.add_argument("--blink-hz", type=cli.positive_float, metavar="HZ", help="the luminaire's blink rate [Hz]")
    g.add_argument("--blink-firmware", metavar="DIR",
                   help="write the blinking test luminaire's firmware (AVR C, ATmega328P) for --blink-hz into DIR")
    g.add_argument("--mcu-clock-hz", type=cli.positive_float, default=MCU_CLOCK_HZ, metavar="HZ",
                   help="the test driver's clock, for --blink-firmware (default 16e6)")
    g = p.add_argument_group("the paper's focal-length fit (section 2.4)")
    g.add_argument("--heights", nargs="+", metavar="M=PHOTO",
                   help="level photos of one steady LED, each at a known distance [m] below it: fits f = f0 + k "
                   "distance (put IMAGES before this flag)")
    g.add_argument("--led-radius-m", type=cli.positive_float, metavar="M", help="that LED's radius [m], for --heights")
    g = p.add_argument_group("output")
    g.add_argument("-o", "--output", metavar="YAML", help="write the camera YAML here (atomically)")
    cli.add_camera_flag(g, "with --row-time and no IMAGES: the camera whose row time is measured, written to -o")
    g.add_argument("--name", default="", metavar="NAME", help="the camera's name in the YAML (default: none)")
    return p


def parse_board(text: str, square_m: float, charuco: str | None = None, marker_m: float | None = None) -> Board:
    from planner.calibration.chessboard import Board

    m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text)
    if not m or min(int(m[1]), int(m[2])) < 2 or max(int(m[1]), int(m[2])) > 100:
        raise UsageError(f"--board {text}: give the inner corners as COLSxROWS, each 2-100 (e.g. 9x6)")
    if not charuco:
        return Board(int(m[1]), int(m[2]), square_m)
    import cv2

    names = sorted(n for n in dir(cv2.aruco) if re.fullmatch(r"DICT_\d+X\d+_\d+", n))
    if charuco not in names:
        raise UsageError(f"--charuco {charuco}: not an ArUco dictionary; known: {', '.join(names)}")
    marker = marker_m or 0.7 * square_m
    if marker >= square_m:
        raise UsageError(f"--marker-m {marker:g}: a marker must be smaller than its square ({square_m:g} m)")
    return Board(int(m[1]), int(m[2]), square_m, charuco, marker)


def read_gray(path: str) -> np.ndarray:
    """The photo at ``path`` as 8-bit grey, as the sensor saw it; one line if it is missing or not an image."""
    import cv2
    import numpy as np

    p = Path(path)
    if not p.is_file():
        raise InputError(f"{path}: no such file" if not p.exists() else f"{path}: not a file")
    try:
        data = np.frombuffer(p.read_bytes(), np.uint8)
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    # The sensor's own orientation (EXIF rotation ignored): its rows are the rolling shutter's, and the app's frames
    # come unrotated.
    from planner.photo.read import check_size

    check_size(data.tobytes(), path)
    try:
        image = cv2.imdecode(data, cv2.IMREAD_GRAYSCALE | cv2.IMREAD_IGNORE_ORIENTATION) if data.size else None
    except cv2.error:  # OpenCV's own pixel cap or a corrupt stream
        image = None
    if image is None:
        raise InputError(f"{path}: not an image OpenCV reads (give JPEG or PNG photos)")
    return image


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if not args.images and not args.row_time and not args.blink_firmware and not args.heights:
        raise UsageError("give chessboard photos (IMAGES...), --row-time PHOTO, --heights M=PHOTO... or "
                         "--blink-firmware DIR (see vlp-calibrate --help)")
    if args.heights and not args.led_radius_m:
        raise UsageError("--heights needs --led-radius-m, the photographed LED's radius")
    heights = [_height_shot(item) for item in args.heights or []]
    if (args.row_time or args.blink_firmware) and not args.blink_hz:
        raise UsageError("--row-time and --blink-firmware need --blink-hz, the luminaire's blink rate")
    output = cli.output_file("--output", args.output)
    if output and output.is_dir():
        raise UsageError(f"--output {args.output}: is a folder; give the camera file's name (e.g. phone.yaml)")
    if output and not args.images and not args.camera and (args.row_time or args.heights):
        raise UsageError(f"{'--row-time' if args.row_time else '--heights'} without IMAGES writes -o only with "
                         "--camera NAME|YAML, the camera it measures")
    board = parse_board(args.board, args.square_m, args.charuco, args.marker_m)
    result: dict = {}
    camera = cli.camera_from_args(args) if args.camera and not args.images else None
    if args.blink_firmware:
        result["blink_firmware"] = _blink_firmware(args)
    if args.images:
        calibration, result["calibration"] = _calibrate(args.images, board, args.lens, args.name)
        camera = calibration.camera
    if heights:
        result["heights"] = _heights(heights, args.led_radius_m, camera)
        if camera is not None and not args.images:  # a chessboard calibration outranks the paper's fit
            from dataclasses import replace

            f = result["heights"]["focal_at_mean_px"]
            camera = replace(camera, fx_px=f, fy_px=f)
    if args.row_time:
        result["row_time"] = _row_time(args.row_time, args.blink_hz, camera)
        if camera is not None:
            from dataclasses import replace

            camera = replace(camera, row_time_s=result["row_time"]["row_time_s"])
    if output and camera is not None:
        write_text_atomically(output, camera_yaml(camera, result))
        result["output"] = str(output)
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(_text(result))
    return 0


def _calibrate(paths: list[str], board: Board, lens: str, name: str):
    from planner.calibration.chessboard import calibrate, find_view

    views, used, refused, size = [], [], [], None
    for path in paths:
        gray = read_gray(path)
        here = (gray.shape[1], gray.shape[0])
        if size is None:
            size, first = here, path
        elif here != size:
            raise InputError(f"{path}: {here[0]} x {here[1]} px, but {first} is {size[0]} x {size[1]}; calibrate one "
                             "camera mode (resolution) at a time")
        cli.progress(f"finding the board in {path}")
        found = find_view(gray, board)
        if found is None:
            refused.append(path)
        else:
            views.append(found)
            used.append(path)
    if not views:
        kind = f"ChArUco board ({board.dictionary}) of" if board.dictionary else "chessboard of"
        raise InputError(f"no {kind} {board.cols}x{board.rows} inner corners found in any of the {len(paths)} "
                         "photo(s); check --board (inner corners: a board of 10 x 7 squares has 9x6) and that the "
                         "whole board, with its white margin, is in each photo")
    assert size is not None
    calibration = calibrate(views, size, lens, name)
    c = calibration.camera
    summary = {"images": len(paths), "used": len(used), "refused": refused, "lens": lens,
               "width_px": c.width_px, "height_px": c.height_px, "fx_px": c.fx_px, "fy_px": c.fy_px,
               "cx_px": c.cx_px, "cy_px": c.cy_px, "distortion": list(c.distortion),
               "hfov_deg": math.degrees(c.hfov_rad), "rms_px": calibration.rms_px,
               "pattern": f"charuco {board.dictionary}" if board.dictionary else "chessboard",
               "per_image": [{"image": p, "rms_px": e, "corners": len(v[1])}
                             for p, e, v in zip(used, calibration.per_view_rms_px, views)]}
    return calibration, summary


def _row_time(path: str, blink_hz: float, camera: Camera | None) -> dict:
    from planner.calibration.row_time import measure_stripes

    gray = read_gray(path)
    if camera is not None and camera.height_px != gray.shape[0]:
        raise InputError(f"{path}: {gray.shape[0]} rows, but the camera has {camera.height_px}; take the photo in "
                         "the camera's own mode")
    stripes = measure_stripes(gray, path)
    return {"photo": path, "blink_hz": blink_hz, "period_rows": stripes.period_rows, "edges": stripes.edges,
            "led_rows": list(stripes.rows), "led_columns": list(stripes.columns),
            "edge_residual_rows": stripes.residual_rows, "row_time_s": stripes.row_time_s(blink_hz)}


def _height_shot(item: str) -> tuple[float, str]:
    """``M=PHOTO``: the distance below the LED [m] and the photo."""
    distance, sep, path = item.partition("=")
    try:
        value = float(distance)
    except ValueError:
        value = math.nan
    if not sep or not path or not math.isfinite(value) or value <= 0:
        raise UsageError(f"--heights {item}: give DISTANCE=PHOTO, the distance below the LED in metres (e.g. 1.2=a.jpg)")
    return value, path


def _heights(shots: list[tuple[float, str]], led_radius_m: float, camera: Camera | None) -> dict:
    from planner.calibration.heights import fit_heights, led_image_radius_px

    radii = []
    for _, path in shots:
        gray = read_gray(path)
        if camera is not None and (gray.shape[1], gray.shape[0]) != (camera.width_px, camera.height_px):
            raise InputError(f"{path}: {gray.shape[1]} x {gray.shape[0]} px, but the camera has {camera.width_px} x "
                             f"{camera.height_px}; take the photos in the camera's own mode")
        radii.append(led_image_radius_px(gray, path))
    try:
        fit = fit_heights([d for d, _ in shots], radii, led_radius_m)
    except InputError as exc:
        raise InputError(f"--heights: {exc}") from None
    mean = sum(fit.distances_m) / len(fit.distances_m)
    return {"f0_px": fit.f0_px, "k_px_per_m": fit.k_px_per_m, "led_radius_m": led_radius_m, "mean_distance_m": mean,
            "focal_at_mean_px": fit.focal_at(mean),
            "shots": [{"photo": p, "distance_m": d, "radius_px": a, "focal_px": f}
                      for (d, p), a, f in zip(shots, fit.radii_px, fit.focal_px)]}


def _blink_firmware(args) -> dict:
    from planner.calibration.blink import blink_timer, write_blink_firmware

    timer = blink_timer(args.blink_hz, args.mcu_clock_hz)
    try:
        files = write_blink_firmware(Path(args.blink_firmware), timer)
    except UsageError as exc:
        raise UsageError(f"--blink-firmware {exc}") from None
    return {"dir": args.blink_firmware, "files": files, "blink_hz": timer.actual_hz, "prescaler": timer.prescaler,
            "compare": timer.compare, "mcu_clock_hz": timer.mcu_clock_hz}


def camera_yaml(camera: Camera, result: dict) -> str:
    """The camera YAML ``-o`` writes: the fields ``read_camera`` takes, and how they were measured as comments."""
    import yaml

    fields = {k: v for k, v in camera.to_dict().items() if k not in ("hfov_deg", "receiver_height_m", "max_tilt_deg")}
    if camera.distortion and not camera.distorted:
        fields.update(lens=camera.lens, distortion=[float(k) for k in camera.distortion])
    notes = ["# Camera file written by vlp-calibrate (docs/camera.md), from:"]
    used = [line for line in _measured(result) if not line.startswith("  ") or "RMS" in line]
    if result.get("calibration"):  # the chessboard's focal length is the file's, not the heights' fit
        used = [line for line in used if not line.startswith("focal length fit")]
    notes += [f"#   {line.strip()}" for line in used]
    if not result.get("row_time"):
        notes.append("# row_time_s: not measured (the default); measure it with --row-time PHOTO --blink-hz F.")
    return "\n".join(notes) + "\n" + yaml.safe_dump(fields, sort_keys=False, default_flow_style=None)


def _text(result: dict) -> str:
    lines = []
    fw = result.get("blink_firmware")
    if fw:
        lines.append(f"blink firmware: {fw['dir']} ({', '.join(fw['files'])}): {fw['blink_hz']:.6g} Hz square wave "
                     f"on PB1 (timer 1, prescaler {fw['prescaler']}, compare {fw['compare']} at "
                     f"{fw['mcu_clock_hz']:g} Hz); photograph it with --row-time PHOTO --blink-hz {fw['blink_hz']:.6g}")
    lines += _measured(result)
    if result.get("output"):
        lines.append(f"wrote {result['output']}")
    return "\n".join(lines)


def _measured(result: dict) -> list[str]:
    """What was measured, a headline per measurement and its details indented: the summary, and the camera
    file's comments (headlines and the RMS line)."""
    lines = []
    cal = result.get("calibration")
    if cal:
        lines.append(f"chessboard: {cal['used']} of {cal['images']} photos used ({cal['width_px']} x {cal['height_px']} "
                     f"px, {cal['lens']} lens): fx {cal['fx_px']:.2f} px, fy {cal['fy_px']:.2f} px, principal point "
                     f"({cal['cx_px']:.1f}, {cal['cy_px']:.1f}) px, hfov {cal['hfov_deg']:.2f} deg")
        lines.append(f"  distortion {' '.join(f'{k:.5g}' for k in cal['distortion'])}; RMS reprojection error "
                     f"{cal['rms_px']:.3f} px")
        for e in cal["per_image"]:
            lines.append(f"  {e['image']}: {e['rms_px']:.3f} px")
        for path in cal["refused"]:
            lines.append(f"  {path}: refused (no board found)")
    ht = result.get("heights")
    if ht:
        lines.append(f"focal length fit (paper, section 2.4): f = {ht['f0_px']:.2f} px + {ht['k_px_per_m']:.3f} px/m x "
                     f"distance; {ht['focal_at_mean_px']:.2f} px at the mean {ht['mean_distance_m']:.2f} m")
        for e in ht["shots"]:
            lines.append(f"  {e['photo']}: {e['distance_m']:g} m below, image radius {e['radius_px']:.2f} px, "
                         f"f {e['focal_px']:.2f} px")
    rt = result.get("row_time")
    if rt:
        lines.append(f"row time: {1e6 * rt['row_time_s']:.3f} us (stripes {rt['period_rows']:.2f} rows apart at "
                     f"{rt['blink_hz']:g} Hz, {rt['edges']} edges in rows {rt['led_rows'][0]}-{rt['led_rows'][1]})")
    return lines


def console_main(argv: list[str] | None = None) -> int:
    return cli.console_main(argv, main, "vlp-calibrate")


if __name__ == "__main__":
    sys.exit(console_main())
