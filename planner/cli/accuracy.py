"""``vlp-accuracy``: the paper's positioning experiment (Table 3) in simulation, both methods side by side.

Prints a table shaped like the paper's Table 3 (mean and 90 % error per tilt) with
the paper's printed figures beside the simulated paper method and the full-perspective
method, each with pixel noise only and with every term of the error budget on, then the
budget (each term alone), and with ``--cdf PNG`` draws the CDF plot (the paper's Fig. 8 and 10;
all terms on). Assumptions (LED radius, the terms, hand jitter) are printed with the table and can
be changed by flags.
"""

from __future__ import annotations

import argparse
import json
import math
import sys

from planner._files import write_atomically
from planner.cli import common as cli
from planner.defaults import MAX_TRIALS, PAPER_RADIUS_M, PAPER_TILTS_DEG
from planner.errors import UsageError


def build_parser() -> argparse.ArgumentParser:
    p = cli.parser(
        "vlp-accuracy",
        "Reproduce the paper's positioning experiment (Table 2: four LEDs at (0, +-0.3, 2.5) and "
        "(+-0.5, 0, 2.5) m, 50.4 deg field of view, receiver at 0.7 m, 16 test points, tilts 0/20/30/40 deg) in "
        "simulation with the paper's method and the full-perspective method on the same images.",
        ok="done", docs="docs/positioning.md", json="print the figures as JSON instead of the table",
    )
    p.add_argument("--trials", type=cli.count_up_to(MAX_TRIALS), default=10, metavar="N",
                   help=f"trials per test point (default 10, as the paper; at most {MAX_TRIALS:,})")
    p.add_argument("--tilts", default=",".join(map(str, PAPER_TILTS_DEG)), metavar="DEG,...",
                   help="tilts to test [deg] (default 0,20,30,40)")
    p.add_argument("--radius", type=cli.positive_float, default=PAPER_RADIUS_M, metavar="M",
                   help=f"LED radius [m] (default {PAPER_RADIUS_M:g}; the paper does not give it)")
    p.add_argument("--seed", type=cli.seed, default=0, help="random seed (default 0)")
    p.add_argument("--png", "--cdf", dest="cdf", metavar="FILE",
                   help="draw the error CDF plot into this PNG (SVG if it ends in .svg; default: no plot; --cdf: the "
                   "old name, kept for a release)")
    cli.add_camera_flag(p, "the phone on the rig; default: the paper's camera (its tilts and heights are the rig's)")
    cli.add_error_budget_flags(p, "the experiment")
    return p


def _tilts(text: str) -> list[float]:
    try:
        tilts = [float(t) for t in text.split(",") if t.strip()]
    except ValueError:
        tilts = []
    if not tilts or not all(0 <= t < 90 for t in tilts):
        raise UsageError(f"--tilts {cli.shown(text)}: expected degrees from 0 to below 90, separated by commas")
    return tilts


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    tilts = _tilts(args.tilts)
    cdf = cli.output_file("--png", args.cdf)
    terms = cli.error_terms(args)
    camera = cli.camera_from_args(args)
    from planner.positioning.accuracy import HAND_JITTER_DEG, budget_text, paper_budget, plot_cdf, stats_cm, table3_text
    from planner.positioning.error_terms import included_text

    runs = paper_budget(tilts, args.trials, terms, args.radius, args.seed, camera)
    pixel = runs.get("edge", runs["exact"])
    if cdf is not None:
        fmt = "svg" if cdf.suffix.lower() == ".svg" else "png"
        write_atomically(cdf, lambda tmp: plot_cdf(runs["all"], tmp, fmt))
    if args.json:
        figures = {name: [{"tilt_deg": r.tilt_deg, "unusable_trials": r.unusable,
                           **{m: dict(zip(("mean_cm", "p90_cm"), (round(v, 4) for v in stats_cm(e))))
                              for m, e in r.errors.items()}} for r in results]
                   for name, results in runs.items()}
        finite = all(math.isfinite(v) for rs in runs.values() for r in rs for e in r.errors.values() for v in stats_cm(e))
        print(json.dumps({
            "assumptions": {"led_radius_m": args.radius, "trials": args.trials, "terms": terms.to_dict(),
                            "camera": camera.to_dict(),
                            "includes": terms.active,
                            "hand_jitter_deg": dict(zip(("tilt", "azimuth", "roll"), HAND_JITTER_DEG))},
            "tilts": figures["all"], "pixel_only": [dict(t) for t in figures.get("edge", figures["exact"])],
            "budget": figures, "cdf": str(cdf) if cdf else None}, indent=2, allow_nan=not finite))
        return 0
    phone = camera.name or "the paper's camera"
    print(f"vlp-accuracy: the paper's rig in simulation; LED radius {args.radius:g} m, {phone} "
          f"{camera.width_px} x {camera.height_px} px at {math.degrees(camera.hfov_rad):.1f} deg, "
          f"16 points x {args.trials} trials, hand jitter +-{HAND_JITTER_DEG[0]:g}/{HAND_JITTER_DEG[1]:g}/"
          f"{HAND_JITTER_DEG[2]:g} deg (tilt/azimuth/roll)")
    print(f"all terms: {included_text(terms)}")
    print(table3_text(pixel, runs["all"]))
    print()
    print(budget_text(runs))
    skipped = max(sum(r.unusable for r in rs) for rs in runs.values())
    if skipped:
        print(f"up to {skipped} trials of a run saw fewer than three whole LEDs and are not counted")
    if cdf is not None:
        print(f"wrote {cdf}")
    return 0


def console_main(argv: list[str] | None = None) -> int:
    return cli.console_main(argv, main, "vlp-accuracy")


if __name__ == "__main__":
    sys.exit(console_main())
