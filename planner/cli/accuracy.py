"""``vlp-accuracy``: the paper's positioning experiment (Table 3) in simulation, both methods side by side.

Prints a table shaped like the paper's Table 3 (mean and 90 % error per tilt) with
the paper's printed figures beside the simulated paper method and the full-perspective
method, and with ``--cdf PNG`` draws the CDF plot (the paper's Fig. 8 and 10). Assumptions (LED radius,
pixel noise, hand jitter) are printed with the table and can be changed by flags.
"""

from __future__ import annotations

import argparse
import json
import math
import sys

from planner._files import write_atomically
from planner.cli import common as cli
from planner.defaults import NOISE_PX, PAPER_RADIUS_M, PAPER_TILTS_DEG
from planner.errors import UsageError


def build_parser() -> argparse.ArgumentParser:
    p = cli.Parser(
        prog="vlp-accuracy",
        description="Reproduce the paper's positioning experiment (Table 2: four LEDs at (0, +-0.3, 2.5) and "
        "(+-0.5, 0, 2.5) m, 50.4 deg field of view, receiver at 0.7 m, 16 test points, tilts 0/20/30/40 deg) in "
        "simulation with the paper's method and the full-perspective method on the same images.",
        epilog="Docs: docs/positioning.md.",
    )
    p.add_argument("--trials", type=cli.positive_int, default=10, metavar="N",
                   help="trials per test point (default 10, as the paper)")
    p.add_argument("--tilts", default=",".join(map(str, PAPER_TILTS_DEG)), metavar="DEG,...",
                   help="tilts to test [deg] (default 0,20,30,40)")
    p.add_argument("--noise-px", type=cli.non_negative_float, default=NOISE_PX, metavar="PX",
                   help=f"edge-point noise before rounding to whole pixels [px] (default {NOISE_PX:g})")
    p.add_argument("--radius", type=cli.positive_float, default=PAPER_RADIUS_M, metavar="M",
                   help=f"LED radius [m] (default {PAPER_RADIUS_M:g}; the paper does not give it)")
    p.add_argument("--seed", type=cli.seed, default=0, help="random seed (default 0)")
    p.add_argument("--cdf", metavar="PNG", help="draw the error CDF plot into this PNG (default: no plot)")
    cli.common_flags(p, "print the figures as JSON instead of the table")
    return p


def _tilts(text: str) -> list[float]:
    try:
        tilts = [float(t) for t in text.split(",") if t.strip()]
    except ValueError:
        tilts = []
    if not tilts or not all(0 <= t < 90 for t in tilts):
        raise UsageError(f"--tilts {text!r}: expected degrees from 0 to below 90, separated by commas")
    return tilts


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    tilts = _tilts(args.tilts)
    cdf = cli.output_file("--cdf", args.cdf)
    from planner.positioning.accuracy import HAND_JITTER_DEG, paper_experiment, plot_cdf, stats_cm, table3_text

    results = paper_experiment(tilts, args.trials, args.noise_px, args.radius, args.seed)
    if cdf is not None:
        write_atomically(cdf, lambda tmp: plot_cdf(results, tmp))
    if args.json:
        print(json.dumps({
            "assumptions": {"led_radius_m": args.radius, "noise_px": args.noise_px, "trials": args.trials,
                            "hand_jitter_deg": dict(zip(("tilt", "azimuth", "roll"), HAND_JITTER_DEG))},
            "tilts": [{"tilt_deg": r.tilt_deg, "unusable_trials": r.unusable,
                       **{m: dict(zip(("mean_cm", "p90_cm"), (round(v, 4) for v in stats_cm(e))))
                          for m, e in r.errors.items()}} for r in results],
            "cdf": str(cdf) if cdf else None}, indent=2, allow_nan=False if all(_finite(r) for r in results) else True))
        return 0
    print(f"vlp-accuracy: the paper's rig in simulation; LED radius {args.radius:g} m, edge noise "
          f"{args.noise_px:g} px then whole pixels, 4000 x 3000 px at 50.4 deg, 16 points x {args.trials} trials, "
          f"hand jitter +-{HAND_JITTER_DEG[0]:g}/{HAND_JITTER_DEG[1]:g}/{HAND_JITTER_DEG[2]:g} deg (tilt/azimuth/roll)")
    print(table3_text(results))
    skipped = sum(r.unusable for r in results)
    if skipped:
        print(f"{skipped} trials saw fewer than three whole LEDs and are not counted")
    if cdf is not None:
        print(f"wrote {cdf}")
    return 0


def _finite(r) -> bool:
    from planner.positioning.accuracy import stats_cm

    return all(math.isfinite(v) for e in r.errors.values() for v in stats_cm(e))


def console_main(argv: list[str] | None = None) -> int:
    return cli.console_main(argv, main, "vlp-accuracy")


if __name__ == "__main__":
    sys.exit(console_main())
