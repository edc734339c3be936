"""``vlp-locate PLAN OBSERVATION.json`` or ``--image PHOTO``: a receiver's position from the LEDs it saw.

Prints JSON: position [m], method, RMS ellipse residual [px], the luminaires used and
the camera's orientation. ``--image`` decodes a phone photo first (:mod:`planner.photo`;
with ``--json`` every LED blob found is listed, read or not; a tone site's LEDs by their tones). ``--simulate`` writes the
observation a pose would give instead (the receiver twin's reference output). Exit codes: 0 position found,
3 no trustworthy position (too few or collinear LEDs, no pose explains the image,
two places fit), 1 bad input (unreadable file, ID not in the plan), 2 usage.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import TYPE_CHECKING

from planner.cli import common as cli
from planner.defaults import LOCATE_METHODS, MAX_RESIDUAL_PX, NOISE_PX
from planner.errors import UsageError

if TYPE_CHECKING:  # the stages load when the command runs, not when it parses
    import numpy as np

    from planner.plan.file import PlanFile
    from planner.positioning.locate import Site, Snapshot


def build_parser() -> argparse.ArgumentParser:
    p = cli.parser(
        "vlp-locate",
        "Locate a receiver on a planned site from the LED ellipses it saw (IDs decoded, ellipses "
        "fitted; format in docs/positioning.md), or from a phone photo of the ceiling (--image; docs/photos.md). "
        "Luminaires are identified from the plan as the receiver would.",
        ok="position found", check_failed="no trustworthy position", docs="docs/positioning.md, docs/photos.md",
        json="with --image: add every LED blob found (ellipse, stripe period, ID or why none), also "
        "when no position is found; otherwise the output is JSON with or without it",
    )
    p.add_argument("plan", metavar="PLAN", help="a plan.yaml written by vlp-plan")
    p.add_argument("observation", metavar="OBSERVATION.json", nargs="?",
                   help="the receiver's camera and LED ellipses (JSON)")
    p.add_argument("--image", metavar="PHOTO",
                   help="instead of OBSERVATION.json, a photo of the ceiling (JPEG or PNG, as the phone saved it; a "
                   "portrait file with turned pixels is turned back): every LED blob is found and its frame or tone "
                   "read, then located (docs/photos.md, docs/tones.md)")
    cli.add_camera_flag(p, "with --image: the camera that took the photo; default: the plan's camera")
    p.add_argument("--method", choices=list(LOCATE_METHODS), default="perspective",
                   help="perspective: exact pose fit over every LED (default); paper: the paper's weak-perspective "
                   "distances and trilateration (Eq. 1-14)")
    p.add_argument("--max-residual-px", type=cli.positive_float, default=MAX_RESIDUAL_PX, metavar="PX",
                   help=f"largest RMS ellipse residual of a pose that explains the image (default {MAX_RESIDUAL_PX:g})")
    p.add_argument("--simulate", metavar="X,Y,Z,TILT,AZ,ROLL",
                   help="instead of locating, print the observation a camera at X,Y,Z [m] with tilt, azimuth "
                   "and roll [deg] makes of the plan, using the plan's camera")
    p.add_argument("--noise-px", type=cli.non_negative_float, default=NOISE_PX, metavar="PX",
                   help=f"with --simulate: edge-point noise [px] (default {NOISE_PX:g}; 0 gives exact ellipses)")
    p.add_argument("--seed", type=cli.seed, default=0, help="with --simulate: noise seed (default 0)")
    return p


def _pose(text: str, flag: str = "--simulate") -> tuple[np.ndarray, np.ndarray]:
    import numpy as np

    from planner.camera.model import rotation_from_angles

    try:
        vals = [float(v) for v in text.split(",")]
    except ValueError:
        vals = []
    if len(vals) != 6 or not all(map(math.isfinite, vals)):
        raise UsageError(f"{flag} {cli.shown(text)}: expected six numbers X,Y,Z,TILT,AZ,ROLL (metres, degrees)")
    return np.array(vals[:3]), rotation_from_angles(*np.radians(vals[3:]))[0]


def simulate(plan: PlanFile, pose: str, noise_px: float, seed: int) -> dict:
    import numpy as np

    from planner.positioning.locate import Site, Snapshot
    from planner.positioning.observation import observe
    from planner.positioning.snapshot_file import snapshot_document
    from planner.receivers.modes import receiver_for

    site = Site.from_plan(plan)
    camera = plan.camera_model()
    position, rotation = _pose(pose)
    rng = np.random.default_rng(seed) if noise_px > 0 else None
    seen = observe(position, rotation, site.xyz, site.radii, camera, rng, noise_px)
    gravity = receiver_for(plan.receiver_mode, "receiver.mode").exact_vertical(rotation)
    return snapshot_document(Snapshot(camera, [int(site.ids[k]) for k in seen.index], seen.ellipses, gravity))


def result_document(site: Site, snap: Snapshot | None, found, max_residual_px: float = MAX_RESIDUAL_PX) -> dict:
    from planner.positioning.fix import angles_of

    fix = found.fix
    tilt, az, roll = (math.degrees(a) for a in angles_of(fix.rotation))
    return {
        "position_m": [round(float(v), 4) for v in fix.position],
        "method": fix.method,
        "residual_px": round(fix.residual_px, 3),
        "explains_image": bool(fix.residual_px <= max_residual_px),
        "luminaires": [site.names[found.luminaires[k]] for k in fix.used],
        "identified": [site.names[k] for k in found.luminaires],
        "orientation_deg": {"tilt": round(tilt, 2), "azimuth": round(az, 2), "roll": round(roll, 2)},
    }


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    from planner.plan.file import load_plan

    if args.image and (args.observation or args.simulate):
        raise UsageError("--image locates a photo: give it without OBSERVATION.json and --simulate")
    if args.camera and not args.image:
        raise UsageError("--camera goes with --image (an observation file carries its own camera)")
    plan = load_plan(args.plan)
    if args.simulate:
        print(json.dumps(simulate(plan, args.simulate, args.noise_px, args.seed), indent=2))
        return 0
    if args.image:
        return locate_image(plan, args)
    if not args.observation:
        raise UsageError("give an OBSERVATION.json or --image PHOTO to locate, or --simulate a pose "
                         "(see vlp-locate --help)")
    from planner.positioning.locate import Site, locate  # the solvers (SciPy, OpenCV) load for a plan that reads
    from planner.positioning.snapshot_file import read_snapshot

    site, snap = Site.from_plan(plan), read_snapshot(args.observation)
    found = locate(site, snap, args.method, args.max_residual_px)
    result = result_document(site, snap, found, args.max_residual_px)
    print(json.dumps(result, indent=2))
    if not result["explains_image"]:
        print(f"vlp-locate: warning: the {args.method} method's position leaves {result['residual_px']:g} px RMS "
              f"(limit {args.max_residual_px:g} px): no orientation at this position explains the image; "
              "expect an error of centimetres or more (the perspective method fits it exactly)", file=sys.stderr)
    return 0


def locate_image(plan: PlanFile, args: argparse.Namespace) -> int:
    """``--image``: decode the photo, locate it, print the result (with ``--json``, every blob)."""
    from planner.decode.tones import ToneFormat
    from planner.errors import PositioningError
    from planner.photo.asbuilt import blob_documents, locate_photo
    from planner.photo.read import read_photo, site_format
    from planner.positioning.locate import Site

    camera = cli.camera_from_args(args, plan.camera_model())
    site, fmt = Site.from_plan(plan), site_format(plan)
    blobs, note = read_photo(args.image, camera, fmt)
    if note:
        print(f"vlp-locate: note: {args.image}: {note}", file=sys.stderr)
    fix = locate_photo(site, blobs, camera, args.method, args.max_residual_px)
    doc: dict = result_document(site, None, fix.located, args.max_residual_px) if fix.located else {
        "position_m": None, "problem": fix.problem}
    if fix.on_centres:
        doc["position_from"] = "centres"
    if args.json:
        doc["photo"] = {"file": args.image, "camera": camera.name or None, "width_px": camera.width_px,
                        "height_px": camera.height_px, "turned": note or None,
                        **({"tones_hz": list(fmt.tones_hz)} if isinstance(fmt, ToneFormat) else
                           {"rows_per_chip": round(1 / (fmt.chip_rate_hz * camera.row_time_s), 3)}),
                        "blobs": blob_documents(site, blobs, fix)}
    if fix.located is None and not args.json:
        raise PositioningError(f"{args.image}: {fix.problem} (--json lists every blob and why)")
    print(json.dumps(doc, indent=2))
    if fix.located is None:
        raise PositioningError(f"{args.image}: {fix.problem}")
    wrong = [b for b in blob_documents(site, blobs, fix) if b.get("verdict") == "wrong"]
    for b in wrong:
        print(f"vlp-locate: warning: luminaire {b['luminaire']} plays ID {b['id']}, planned {b['planned_id']}; "
              "located on the others (vlp-report --photos checks a site)", file=sys.stderr)
    return 0


def console_main(argv: list[str] | None = None) -> int:
    return cli.console_main(argv, main, "vlp-locate")


if __name__ == "__main__":
    sys.exit(console_main())
