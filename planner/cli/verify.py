"""``vlp-verify PLAN``: verify an existing (perhaps hand-edited) plan.

Exit codes: 0 every sampled pose that sees a window decodes uniquely, no
triangle that may be a window reads like another triple of the site, and the plan
is usable; 3 otherwise (the first conflicting luminaire triples are named; a plan
under the usable coverage says NOT USABLE, as ``vlp-plan`` does, and exits 3 unless
it was made with ``--allow-unusable``); 1 bad input; 2 usage. The triangles are
proved anew (:mod:`planner.verify.proof`) where the site is within the proof's
reach; the summary says whether decodability is proved or sampled only.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

from planner._files import write_atomically
from planner.cli import common as cli
from planner.defaults import INSTALL_TOLERANCE_M
from planner.errors import ExitCode


def build_parser() -> argparse.ArgumentParser:
    p = cli.Parser(
        prog="vlp-verify",
        description="Verify a plan.yaml: sample camera poses over the site, and find every triangle of luminaires "
        "that may be a window (the three LEDs the camera uses); check that each names exactly one place, "
        "against every other triple of the site.",
        epilog="Exit codes: 0 decodable everywhere sampled, no triangle that may be a window reads like another "
        "triple and the plan usable (at least 50 % of sampled poses decode), 3 otherwise (NOT USABLE exits 0 when "
        "the plan was made with vlp-plan --allow-unusable), 1 bad input, 2 usage error.",
    )
    p.add_argument("plan", metavar="PLAN", help="a plan.yaml written by vlp-plan (format vlp-plan/1)")
    cli.add_verify_flags(p)
    cli.add_parallel_flags(p)
    p.add_argument("--seed", type=cli.seed, default=0, help="seed of the pose sample (default 0)")
    p.add_argument("--map", metavar="PNG", help="also write the coverage map to this file")
    cli.common_flags(p, "print the verification summary as JSON")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    map_path = cli.output_file("--map", args.map)

    from planner.plan_file import load_plan

    plan = load_plan(args.plan)
    from planner.budget import check_work, verify_work

    check_work(verify_work(plan.xyz[:, :2], plan.outline, args.poses_per_m2), args.max_poses)
    xyz, radii, ids = plan.xyz, plan.radii, plan.ids
    camera = cli.camera_from_args(args, plan.camera_model())
    recorded = (plan.verification.window_set if plan.verification else None) or {}
    install = args.install_tolerance if args.install_tolerance is not None else \
        float(recorded.get("install_tolerance_m", INSTALL_TOLERANCE_M))
    if plan.receiver_mode == "gravity":  # two-LED windows (planner.receivers)
        from planner.receivers import verify_gravity

        result = verify_gravity(xyz, radii, ids, plan.outline, camera, per_m2=args.poses_per_m2, seed=args.seed,
                                tolerance_m=args.tolerance, install_tolerance_m=install)
    else:
        result = _verify_three(xyz, radii, ids, plan, camera, args, recorded, install)
    summary = result.summary(plan.names, limit=10)
    from planner.advice import verdict

    judged = _standing(result, plan)
    summary.update(usable=judged["usable"], verdict=verdict(judged))
    if map_path is not None:
        from planner.report.maps import render_coverage

        site = f"{plan.source.get('file', Path(args.plan).name)}: {plan.scheme} scheme"
        write_atomically(map_path, lambda tmp: render_coverage(result, xyz[:, :2], site, tmp))
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        line = cli.verification_line(summary)
        if not judged["usable"] and line.endswith(": proved"):
            line += f" (but only {100 * result.coverage:.1f} % of sampled poses see a window: not an endorsement)"
        print(f"vlp-verify: {args.plan}: {line}\n  verdict  {summary['verdict']}")
        for group in summary["first_conflicts"] + summary["window_set"]["first_conflicts"]:
            print("  same key: " + " = ".join("(" + ", ".join(t) + ")" for t in group))
    allowed = plan.advice is not None and plan.advice.allow_unusable
    if not judged["usable"]:
        print(f"vlp-verify: NOT USABLE: only {100 * result.coverage:.1f} % of sampled poses decode"
              + (" (the plan was made with --allow-unusable)" if allowed else
                 "; see the advice in the plan's site report"), file=sys.stderr)
    return 0 if result.clean and (judged["usable"] or allowed) else ExitCode.CHECK_FAILED


def _standing(result, plan) -> dict:
    """The verdict's inputs from this verification: coverage, shares too few and ambiguous, the plan's goal."""
    from planner.advice import standing
    from planner.defaults import COVERAGE_GOAL
    from planner.verify.verify import AMBIGUOUS, TOO_FEW

    n = max(result.poses, 1)
    return standing(result.coverage, result.count(TOO_FEW) / n, result.count(AMBIGUOUS) / n,
                    plan.advice.goal if plan.advice is not None else COVERAGE_GOAL, plan.receiver_mode)


def _verify_three(xyz, radii, ids, plan, camera, args, recorded: dict, install: float):
    """The three-LED receiver's verification: sampled windows and the window set, proved where the proof completes."""
    from planner.verify.proof import prove_window_set
    from planner.verify.verify import check_window_set, side_bound, verify_plan

    result = verify_plan(xyz, radii, ids, plan.outline, camera, per_m2=args.poses_per_m2, seed=args.seed,
                         tolerance_m=args.tolerance)
    # The proof is made anew from the luminaires and the camera, never read from the plan; without
    # one, only the sampled side bound may come from the plan.
    bound = max(side_bound(result.windows, xyz, args.tolerance), float(recorded.get("max_side_m", 0.0))
                if recorded.get("max_side_from") != "proof" else 0.0)
    from planner.parallel import runner

    with runner(args.workers, args.scheduler) as tiles:
        proof = prove_window_set(xyz, radii, camera, install, tiles)
        return replace(result, window_set=check_window_set(xyz, radii, ids, bound, tolerance_m=args.tolerance,
                                                           install_tolerance_m=install, proof=proof))


def console_main(argv: list[str] | None = None) -> int:
    return cli.console_main(argv, main, "vlp-verify")


if __name__ == "__main__":
    sys.exit(console_main())
