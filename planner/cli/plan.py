"""``vlp-plan LAYOUT [--leds N] [-o OUTDIR] ...``: read a drawing, plan its IDs, write the outputs."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from planner import __version__
from planner.cli import common as cli
from planner.defaults import (
    ACCELEROMETER_SIGMA_DEG,
    COVERAGE_GOAL,
    DRIVER_MAX_HZ,
    ERROR_POSES_PER_M2,
    LINE_CODE_NAMES,
    LOCATE_METHODS,
    MAX_IMAGE_VERSION,
    MAX_LUMINAIRES,
    MAX_MCU_CLOCK_HZ,
    MAX_POSES_PER_M2,
    MAX_TIME_LIMIT_S,
    MAX_VIDEO_FPS,
    MAX_VIDEO_FRAMES,
    MCU_CLOCK_HZ,
    RECEIVERS,
    SCHEMES,
    VIDEO_FPS,
)
from planner.errors import ExitCode, UsageError


def build_parser() -> argparse.ArgumentParser:
    p = cli.parser(
        "vlp-plan",
        "Plan LED IDs for camera-based visible light positioning: read a building drawing "
        "(DXF) or a luminaire list (YAML/CSV), give every luminaire a short ID (the paper's region code, "
        "or shorter IDs that keep every camera window unique), verify the plan under a tilted camera, and "
        "write plan.yaml, an annotated DXF, map.png, coverage.png, error.png, the site report (HTML and PDF) and each luminaire's driver "
        "configuration (firmware/) into OUTDIR.",
        ok="done", check_failed="plan written but some sampled pose is ambiguous (only with an explicit --scheme), "
        "two luminaires of one tone share a window (a tone site: docs/tones.md), "
        "or the plan is NOT USABLE (under 50 % of sampled poses decode; --allow-unusable exits 0)",
        bad_input="or no plan possible", docs="docs/cli.md", json="print a JSON summary on stdout instead of text",
    )
    p.add_argument("layout", metavar="LAYOUT", nargs="?",
                   help="drawing or layout file: .dxf, .ifc, .yaml/.yml or .csv")
    p.add_argument("--from-plan", metavar="PLAN",
                   help="instead of planning a LAYOUT: make every frame of an edited plan.yaml again from its id, "
                   "verify it, and write plan.yaml and firmware/ into OUTDIR (default: PLAN's folder); refused "
                   "if it fails verification, unless --allow-unverified (docs/cli.md)")
    p.add_argument("--allow-unverified", action="store_true",
                   help="with --from-plan: write the firmware even when the edited plan fails verification")
    p.add_argument("--list-cameras", action="store_true",
                   help="list the bundled camera profiles (--camera NAME) with their sources, and exit")
    p.add_argument("--leds", type=cli.count_up_to(MAX_LUMINAIRES), metavar="N",
                   help="expected luminaire count (a mismatch is an error); with only a room outline, "
                   "lay out N luminaires on a lattice inside it (at most 100,000)")
    p.add_argument("-o", "--outdir", metavar="OUTDIR", help="output directory (default: <layout>-vlp next to LAYOUT)")
    cli.add_reading_flags(p, "reading", "LAYOUT")
    g = p.add_argument_group("planning")
    g.add_argument("--scheme", choices=list(SCHEMES), default="auto",
                   help="ID scheme: paper (the paper's region code), window (shortest IDs with every camera window "
                   "unique), unique (one ID per luminaire), auto (default: the shortest that verifies)")
    g.add_argument("--receiver", choices=list(RECEIVERS), default="auto",
                   help="receiver the plan is made for: three (the paper's, three whole LEDs in view), gravity (two "
                   "whole LEDs plus the phone's accelerometer), auto (default: three wherever its plan is usable, "
                   "else the mode that decodes more poses; with --no-verify three); docs/schemes.md")
    g.add_argument("--time-limit", type=cli.at_most(MAX_TIME_LIMIT_S, strict=False), default=10.0, metavar="S",
                   help="search budget for irregular layouts, in CP-SAT deterministic seconds (default 10, at most "
                   f"{MAX_TIME_LIMIT_S:g})")
    g.add_argument("--seed", type=cli.seed, default=0, help="random seed of the search and the pose sample (default 0)")
    g.add_argument("--check-distance", type=cli.positive_int, default=1, metavar="D",
                   help="send IDs as codewords at Hamming distance D, so that up to D-1 misread bits are "
                   "detected (default 1: no check bits)")
    cli.add_verify_flags(p)
    cli.add_parallel_flags(p)
    g = p.add_argument_group("advice")
    g.add_argument("--coverage-goal", type=cli.at_most(100.0), default=100 * COVERAGE_GOAL, metavar="PCT",
                   help="share of sampled poses that should decode, in percent (default %(default)g); below it the "
                   "summary and the site report show which changes would reach it (sampled)")
    g.add_argument("--allow-unusable", action="store_true",
                   help="exit 0 even when the plan is NOT USABLE (under 50 %% of sampled poses decode)")
    g = p.add_argument_group("modulation")
    g.add_argument("--line-code", choices=list(LINE_CODE_NAMES), default="manchester",
                   help="line code of the frames: manchester (2 chips per bit, runs <= 3) or 4b6b (IEEE 802.15.7, "
                   "1.5 chips per bit, runs <= 5); default manchester")
    g.add_argument("--driver-max-hz", type=cli.positive_float, default=DRIVER_MAX_HZ, metavar="HZ",
                   help=f"fastest chip rate the luminaire drivers switch (default {DRIVER_MAX_HZ:g})")
    g.add_argument("--video-fps", type=cli.at_most(MAX_VIDEO_FPS), default=VIDEO_FPS, metavar="FPS",
                   help=f"the receiver's video frame rate, for frames read over several video frames "
                   f"(default {VIDEO_FPS:g})")
    g.add_argument("--max-video-frames", type=cli.count_up_to(MAX_VIDEO_FRAMES), default=MAX_VIDEO_FRAMES,
                   metavar="K", help="when no LED image holds a whole frame, read it over at most K consecutive "
                   f"video frames (default {MAX_VIDEO_FRAMES}, the most; 1: one image only)")
    g = p.add_argument_group("accuracy")
    g.add_argument("--locate-method", choices=list(LOCATE_METHODS), default="perspective",
                   help="positioning method the error map of a three-LED plan simulates (default perspective; "
                   "paper: the paper's weak-perspective method); a gravity plan's is the gravity method")
    g.add_argument("--accelerometer-deg", type=cli.at_most(45, strict=False), default=ACCELEROMETER_SIGMA_DEG,
                   metavar="DEG", help="gravity plans: RMS error of the phone's measured vertical [deg], one more "
                   f"term of the error map and what its fixes weigh gravity by (default {ACCELEROMETER_SIGMA_DEG:g})")
    g.add_argument("--error-poses-per-m2", type=cli.at_most(MAX_POSES_PER_M2, strict=False),
                   default=ERROR_POSES_PER_M2, metavar="N",
                   help=f"camera poses per square metre the error map simulates (default {ERROR_POSES_PER_M2:g}; "
                   "0 skips the map)")
    cli.add_error_budget_flags(p, "the error map")
    g = p.add_argument_group("firmware")
    g.add_argument("--templates", metavar="DIR",
                   help="render every *.j2 template in DIR per luminaire instead of the bundled ones (docs/firmware.md)")
    g.add_argument("--mcu-clock-hz", type=cli.at_most(MAX_MCU_CLOCK_HZ), default=MCU_CLOCK_HZ, metavar="HZ",
                   help="clock of the drivers' microcontroller, for the timer reload in the header (default 16e6, "
                        "at most 1e9)")
    g.add_argument("--image-version", type=cli.count_up_to(MAX_IMAGE_VERSION), default=1, metavar="N",
                   help=f"version written into every configuration image, at most {MAX_IMAGE_VERSION:,}; drivers "
                   "refuse older ones (default 1)")
    g.add_argument("--no-firmware", action="store_true", help="do not write OUTDIR/firmware/")
    g.add_argument("--key-file", metavar="FILE", help="site key (as vlp-flash's): seal plan.yaml under it "
                   "(plan.yaml.seal); vlp-flash flashes only a sealed plan (docs/plan-format.md)")
    g = p.add_argument_group("output")
    g.add_argument("--no-map", action="store_true", help="do not draw map.png, coverage.png and error.png")
    g.add_argument("--no-report", action="store_true",
                   help="do not write site-report.html and site-report.pdf (vlp-report writes them later)")
    g.add_argument("--timings", action="store_true",
                   help="after the summary, print each stage's wall-clock time on stderr, one line per stage")
    return p


def main(argv: list[str] | None = None) -> int:
    """Run ``vlp-plan``: the exit code (:class:`~planner.errors.ExitCode`); raises PlannerError on failure."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.list_cameras:
        return _list_cameras(args.json)
    if args.from_plan or args.allow_unverified:
        from planner.cli.rebuild import from_plan_command

        return from_plan_command(args, parser)
    if not args.layout:
        parser.error("the following arguments are required: LAYOUT")
    from planner.layout.read import read_layout
    from planner.plan.timings import Timings

    if args.templates and not any(Path(args.templates).glob("*.j2")):
        raise UsageError(f"--templates {args.templates}: no *.j2 templates there"
                         if Path(args.templates).is_dir() else f"--templates {args.templates}: no such directory")
    camera = cli.camera_from_args(args)  # a bad --camera is refused before any work
    site_key = cli.site_key(args.key_file, env=False) if args.key_file else None  # and a bad key
    from planner.parallel import runner

    tiles = runner(args.workers, args.scheduler)  # and a scheduler that does not answer
    t0 = time.perf_counter()
    read_opts = cli.read_options(args)
    clock = Timings(None if args.json else cli.progress)  # progress on a terminal, never with --json
    clock.stage("reading", str(args.layout))
    layout = read_layout(args.layout, args.leds, read_opts)
    from planner.plan.budget import check_work, plan_work

    work = plan_work(layout.xy, layout.outline, scheme=args.scheme, verify=not args.no_verify,
                     poses_per_m2=args.poses_per_m2, error_poses_per_m2=args.error_poses_per_m2)
    check_work(work, args.max_poses)
    # The stages (ortools, networkx, scipy, cv2, matplotlib) load only now: every refusal above is quick.
    from planner.plan.pipeline import FirmwareOptions, PlanOptions, default_outdir, make_plan, write_outputs
    from planner.receivers.modes import PAPER

    with tiles:
        plan = make_plan(layout, PlanOptions(scheme=args.scheme, time_budget=args.time_limit, seed=args.seed,
                                             camera=camera, verify=not args.no_verify, poses_per_m2=args.poses_per_m2,
                                             tolerance_m=args.tolerance, check_distance=args.check_distance,
                                             locate_method=args.locate_method, error_poses_per_m2=args.error_poses_per_m2,
                                             line_code=args.line_code, driver_max_hz=args.driver_max_hz,
                                             install_tolerance_m=args.install_tolerance, error_terms=cli.error_terms(args),
                                             video_fps=args.video_fps, max_video_frames=args.max_video_frames,
                                             mcu_clock_hz=args.mcu_clock_hz, receiver=args.receiver,
                                             accelerometer_sigma_deg=args.accelerometer_deg,
                                             coverage_goal=args.coverage_goal / 100, allow_unusable=args.allow_unusable,
                                             runner=tiles),
                         clock)
    outdir = Path(args.outdir) if args.outdir else default_outdir(args.layout)
    firmware = None if args.no_firmware else FirmwareOptions(Path(args.templates) if args.templates else None,
                                                             args.mcu_clock_hz, args.image_version)
    written = write_outputs(plan, outdir, with_map=not args.no_map, firmware=firmware, with_report=not args.no_report,
                            timings=clock, site_key=site_key)
    clock.stop()
    a, g = plan.assignment, plan.graph
    check = plan.check
    assert check is not None  # make_plan always sets the check code
    summary = {
        "layout": str(args.layout),
        "luminaires": len(layout.luminaires),
        "unit": layout.unit,
        "unit_reason": layout.unit_reason,
        "notes": list(layout.notes),
        "neighbour_pairs": g.graph.number_of_edges(),
        "bipartite": g.bipartite,
        "odd_cycle": [layout.luminaires[v].name for v in g.odd_cycle] if g.odd_cycle else None,
        "scheme": a.scheme,
        "method": a.method,
        "bits": a.bits,
        "naive_bits": a.naive_bits,
        "lower_bound_bits": a.lower_bound_bits,
        "window_set": a.detail.get("window_set"),
        "efficiency": round(a.efficiency, 4),
        "regions": int(a.regions.max()) + 1,
        "max_id": a.max_id,
        "check_distance": check.distance,
        "word_bits": check.word_bits,
        "verification": (plan.verification.summary([lum.name for lum in layout.luminaires])
                         if plan.verification is not None else None),
        "schemes_considered": plan.considered,
        "receiver": plan.receiver.summary() if plan.receiver is not None else {"mode": PAPER.name},
        "advice": plan.advice.summary() if plan.advice is not None else None,
        "modulation": plan.modulation.summary() if plan.modulation is not None else None,
        "no_frames": plan.no_frames,
        "tones": plan.tones.summary([lum.name for lum in layout.luminaires]) if plan.tones is not None else None,
        "accuracy": plan.accuracy.summary() if plan.accuracy is not None else None,
        "outdir": str(outdir),
        "files": [str(p) for p in written],
        "sealed": site_key is not None,
        "seconds": round(time.perf_counter() - t0, 3),
    }
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        _print_summary(summary)
    if args.timings:
        for name, seconds in [*clock.seconds.items(), ("total", summary["seconds"])]:
            print(f"vlp-plan: timing {seconds:8.2f} s  {name}", file=sys.stderr)
    v = plan.verification
    unusable = plan.advice is not None and not plan.advice.usable
    mode = plan.receiver.mode if plan.receiver is not None else PAPER
    few = mode.leds
    if v is not None and unusable:
        print(f"vlp-plan: plan written, but NOT USABLE: only {100 * v.coverage:.1f} % of sampled poses decode "
              f"({v.count(3)} of {v.poses} see fewer than {few} whole LEDs); see the advice in the summary and "
              "the site report", file=sys.stderr)
    if plan.no_frames and not unusable:
        print(f"vlp-plan: plan written, but without frames or firmware: {plan.no_frames}; see the advice",
              file=sys.stderr)
        return ExitCode.CHECK_FAILED
    if plan.tones is not None and plan.tones.clashes:  # an existing tone site's clashes (docs/tones.md)
        print(f"vlp-plan: plan written, but {plan.tones.first_clash([lum.name for lum in layout.luminaires])}",
              file=sys.stderr)
        return ExitCode.CHECK_FAILED
    if v is not None and v.conflicts:
        print(f"vlp-plan: plan written, but {v.count(1)} sampled poses are ambiguous under the {plan.assignment.scheme} "
              "scheme; see coverage.png and vlp-verify", file=sys.stderr)
        return ExitCode.CHECK_FAILED
    elif v is not None and not v.clean:
        assert v.window_set is not None  # no ambiguous pose, so the window set is what is not clean
        first = v.window_set.conflicts[0]
        names = [lum.name for lum in plan.layout.luminaires]
        shape = mode.shape
        print(f"vlp-plan: plan written, but {len(v.window_set.conflicts)} {shape} that may be windows read like "
              f"other luminaires under the {plan.assignment.scheme} scheme, first "
              + " vs ".join("(" + ", ".join(names[i] for i in t) + ")" for t in first[:2]) + "; see vlp-verify",
              file=sys.stderr)
        return ExitCode.CHECK_FAILED
    return ExitCode.CHECK_FAILED if unusable and not args.allow_unusable else ExitCode.OK


def _set_bound(w: dict | None, lower: int) -> str:
    """The counting bound of the window set beside the width's ``lower`` bound, saying whether the set is proved
    or sampled; said once where the two agree."""
    if not w:
        return ""
    counted = f"counted over the {w['windows']:,} {w['set']} windows"
    return f", {counted}" if w["lower_bound_bits"] == lower else f"; {w['lower_bound_bits']} {counted}"


def _print_summary(s: dict) -> None:
    from planner.report.content import length_text

    print(f"vlp-plan {__version__}: {s['layout']}")
    print(f"  layout   {s['luminaires']} luminaires; unit {s['unit']} ({s['unit_reason']})")
    for note in s["notes"]:
        print(f"           note: {note}")
    shape = "bipartite" if s["bipartite"] else f"NOT bipartite (odd cycle {' - '.join(s['odd_cycle'])})"
    print(f"  graph    {s['neighbour_pairs']} neighbour pairs, {shape}")
    print(f"  code     {s['scheme']} scheme by {s['method']}: {s['bits']} bit{'s' if s['bits'] != 1 else ''} "
          f"(naive {s['naive_bits']}, lower bound {s['lower_bound_bits']}{_set_bound(s.get('window_set'), s['lower_bound_bits'])}), "
          f"efficiency {100 * s['efficiency']:.0f} %, IDs 1..{s['max_id']}, "
          f"{s['regions']} region{'s' if s['regions'] != 1 else ''}")
    if s["check_distance"] > 1:
        print(f"  check    sent as {s['word_bits']}-bit codewords ({s['word_bits'] - s['bits']} check bits, "
              f"Hamming distance {s['check_distance']}: up to {s['check_distance'] - 1} misread bits detected)")
    advice = s["advice"]
    usable = advice is None or advice["usable"]
    if s["schemes_considered"] and len(s["schemes_considered"]) > 1:
        parts = []
        for name, c in s["schemes_considered"].items():
            eff = 1 - c["bits"] / s["naive_bits"] if s["naive_bits"] else 0.0
            amb = c["ambiguous_poses"]
            clash = c.get("window_set_conflicts")
            state = ("not verified" if amb is None else f"{amb} ambiguous poses" if amb else
                     f"{clash} triangles read alike" if clash else "verified" if usable else "unambiguous")
            parts.append(f"{name} {c['bits']} bits ({100 * eff:.0f} %, {state})")
        print(f"  schemes  {'; '.join(parts)}; naive {s['naive_bits']} bits")
    r = s["receiver"]
    if "coverage" in r:
        shares = ", ".join(f"{k} {100 * c:.1f} %" for k, c in r["coverage"].items())
        print(f"  receiver {r['mode']} ({r['reason']}); decodable poses by mode: {shares}; "
              f"{100 * r['poses_seeing']['exactly_one_led']:.1f} % of poses see exactly one whole LED")
    v = s["verification"]
    if v:
        line = cli.verification_line(v)
        if not usable and line.endswith(": proved"):
            line += f" (but only {100 * v['coverage']:.1f} % of sampled poses see a window: not an endorsement)"
        print(f"  verify   {line}")
    if advice:
        _print_advice(advice)
    m = s["modulation"]
    if m:
        print(f"  frame    {m['line_code']}, {m['frame_chips']} chips at {m['chip_rate_hz'] / 1e3:g} kHz "
              f"({m['frame_period_s'] * 1e3:.2f} ms); {m['frames_in_smallest_image']:.1f} frames in the smallest LED "
              f"image ({m['smallest_image_rows']:.0f} rows)")
        if "video_frames" in m:
            print(f"           multi-frame: no LED image holds a whole frame, so the receiver reads it over "
                  f"{m['video_frames']} consecutive video frames at {m['video_fps']:g} fps (each shows "
                  f"{m['window_chips']:.1f} chips, advancing {m['frame_offset_chips']:.1f}); hold the phone still")
        else:
            print("           single-frame: one LED image holds a whole frame")
    elif s["no_frames"]:
        print(f"  frame    none: {s['no_frames']}; no firmware written")
    if s.get("tones"):
        from planner.advice.tones import tone_lines

        print("\n".join(tone_lines(s["tones"])))
    a = s["accuracy"]
    if a and a["located"]:
        from planner.positioning.accuracy import method_text
        from planner.positioning.error_terms import TERM_NAMES, ErrorTerms, included_text

        print(f"  accuracy {method_text(a['method'])}: median {length_text(a['median_m'])}, 90 % {length_text(a['p90_m'])}, "
              f"max {length_text(a['max_m'])} over {a['located']} simulated poses, including "
              f"{included_text(ErrorTerms.from_dict(a['terms']))}")
        if a["dominant"]:
            b = a["budget"]
            alone = ", ".join(f"{k} {length_text(v['median_m'])}" for k, v in b.items()
                              if k not in ("all", "exact") and v["median_m"] is not None)
            exact = b["exact"]["median_m"]
            print(f"  budget   median with exact images {length_text(exact) if exact is not None else '-'}; each term "
                  f"alone: {alone}; {TERM_NAMES[a['dominant']]} dominates")
    print(f"  wrote    {', '.join(s['files'])}  ({s['seconds']:.2f} s)")



def _print_advice(a: dict) -> None:
    from planner.advice.advise import table, verdict

    print(f"  verdict  {verdict(a)}")
    if a["changes"]:
        print(f"  advice   what would reach {100 * a['goal']:.0f} % (sampled: {a['poses_per_candidate']} poses each, "
              f"{a.get('measure', 'share of sampled poses whose camera sees three whole LEDs')}):")
        rows = table(a)
        w = max(len(r[0]) for r in rows)
        for change, cov, remark in rows:
            print(f"           {change:<{w}}  {cov:>7}  {remark}".rstrip())


def _list_cameras(as_json: bool) -> int:
    """``--list-cameras``: the bundled profiles, as a table or JSON."""
    from planner.camera.file import profile_rows

    rows = profile_rows()
    if as_json:
        print(json.dumps({"cameras": rows}, indent=2))
        return ExitCode.OK
    print(f"{'name':<18} {'role':<10} {'lens':<8} {'image px':<10} {'hfov deg':>8}  {'row time us':<12} example")
    for r in rows:
        lo, hi = (1e6 * t for t in r["row_time_range_s"])
        size, row = f"{r['width_px']}x{r['height_px']}", f"{1e6 * r['row_time_s']:g} ({lo:g}-{hi:g})"
        print(f"{r['name']:<18} {r['role']:<10} {r['lens']:<8} {size:<10} {r['hfov_deg']:>8.1f}  {row:<12} "
              f"{r['example']}")
    print("\nsources (--json lists every figure's):")
    for r in rows:
        print(f"  {r['name']}: " + "; ".join(f"{k}: {v}" for k, v in r["sources"].items()))
    return ExitCode.OK


def console_main(argv: list[str] | None = None) -> int:
    return cli.console_main(argv, main, "vlp-plan")


if __name__ == "__main__":
    sys.exit(console_main())
