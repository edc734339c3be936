"""``vlp-verify PLAN``: verify an existing (perhaps hand-edited) plan.

Exit codes: 0 every luminaire's ``frame`` sends its ``id``, every sampled pose that
sees a window decodes uniquely, no triangle that may be a window reads like another
triple of the site, and the plan is usable; 3 otherwise (the luminaires whose frame
sends another ID and the first conflicting luminaire triples are named; a plan under
the usable coverage says NOT USABLE, as ``vlp-plan`` does, and exits 3 unless it was
made with ``--allow-unusable``; with ``--key-file``, a plan whose seal does not check
exits 3 too); 1 bad input; 2 usage. The verdict line never reads
usable beside exit 3. The triangles are
proved anew (:mod:`planner.verify.proof`) where the site is within the proof's
reach; the summary says whether decodability is proved or sampled only.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from planner._files import write_atomically
from planner.cli import common as cli
from planner.errors import ExitCode


def build_parser() -> argparse.ArgumentParser:
    p = cli.parser(
        "vlp-verify",
        "Verify a plan.yaml: sample camera poses over the site, and find every triangle of luminaires "
        "that may be a window (the three LEDs the camera uses); check that each names exactly one place, "
        "against every other triple of the site; and check that every luminaire's frame sends its id.",
        ok="every frame sends its luminaire's id, decodable everywhere sampled, no triangle that may be a window "
        "reads like another triple and the plan usable (at least 50 % of sampled poses decode)",
        check_failed="otherwise (the luminaires and triples at fault are named; NOT USABLE exits 0 when the plan was "
        "made with vlp-plan --allow-unusable; with --key-file, a seal that does not check)",
        note="After editing ids: vlp-plan --from-plan PLAN.",
        docs="docs/cli.md", json="print the verification summary as JSON",
    )
    p.add_argument("plan", metavar="PLAN", help="a plan.yaml written by vlp-plan (format vlp-plan/1)")
    cli.add_verify_flags(p)
    cli.add_parallel_flags(p)
    p.add_argument("--seed", type=cli.seed, default=0, help="seed of the pose sample (default 0)")
    p.add_argument("--png", "--map", dest="map", metavar="FILE",
                   help="also write the coverage map to this PNG (--map: the old name, kept for a release)")
    p.add_argument("--key-file", metavar="FILE", help="site key: also check the plan's seal (plan.yaml.seal); one that "
                   "does not check fails the plan (exit 3)")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    map_path = cli.output_file("--png", args.map)

    from planner._files import read_text
    from planner.flash.seal import SEAL_HINT, seal_problem
    from planner.plan.file import load_plan
    from planner.plan.rebuild import failed_verdict, frame_mismatches, verify_plan_file

    text = read_text(args.plan, "plan", "no such plan file; run vlp-plan first")  # one read: sealed and checked
    unsealed = seal_problem(args.plan, text, cli.site_key(args.key_file, env=False)) if args.key_file else None
    plan = load_plan(args.plan, text)
    mismatches = frame_mismatches(plan, args.plan)  # checked before the long part: a bad plan says so at once
    from planner.plan.budget import check_work, verify_work

    check_work(verify_work(plan.xyz[:, :2], plan.outline, args.poses_per_m2), args.max_poses)
    camera = cli.camera_from_args(args, plan.camera_model())
    from planner.parallel import runner

    with runner(args.workers, args.scheduler) as tiles:  # where the proof's tiles run
        result, judged = verify_plan_file(plan, camera, poses_per_m2=args.poses_per_m2, seed=args.seed,
                                          tolerance_m=args.tolerance, install_tolerance_m=args.install_tolerance,
                                          runner=tiles)
    allowed = plan.advice is not None and plan.advice.allow_unusable
    passed = result.clean and (judged["usable"] or allowed) and not mismatches and not unsealed
    summary = result.summary(plan.names, limit=10)
    from planner.advice.advise import verdict

    said = verdict(judged)
    if mismatches:  # the verdict never contradicts the exit code
        said = (f"NOT READY: {len(mismatches)} luminaire(s) broadcast another ID than their id: "
                + ", ".join(m.text() for m in mismatches[:5]) + (", ..." if len(mismatches) > 5 else "")
                + f"; make their frames again with vlp-plan --from-plan {args.plan}")
    elif not result.clean:
        said = failed_verdict(result)
    elif unsealed and (judged["usable"] or allowed):
        said = f"NOT SEALED: {unsealed}; {SEAL_HINT.format(plan=args.plan)}"
    elif not judged["usable"] and allowed:
        said += " (allowed: the plan was made with --allow-unusable)"
    summary.update(usable=judged["usable"], verdict=said, passed=passed,
                   frame_mismatches=[{"name": m.name, "id": m.id, "frame_sends": m.sends, "why": m.what}
                                     for m in mismatches],
                   seal=None if not args.key_file else unsealed or "checks")
    if map_path is not None:
        from planner.report.maps import render_coverage

        site = f"{plan.source.get('file', Path(args.plan).name)}: {plan.scheme} scheme"
        write_atomically(map_path, lambda tmp: render_coverage(result, plan.xyz[:, :2], site, tmp))
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        line = cli.verification_line(summary)
        if not judged["usable"] and line.endswith(": proved"):
            line += f" (but only {100 * result.coverage:.1f} % of sampled poses see a window: not an endorsement)"
        print(f"vlp-verify: {args.plan}: {line}\n  verdict  {said}")
        for group in summary["first_conflicts"] + summary["window_set"]["first_conflicts"]:
            print("  same key: " + " = ".join("(" + ", ".join(t) + ")" for t in group))
        for m in mismatches:
            print(f"  frame    {m.text()}")
        if args.key_file:
            print(f"  seal     {unsealed or 'checks under the site key'}")
    if not judged["usable"]:
        print(f"vlp-verify: NOT USABLE: only {100 * result.coverage:.1f} % of sampled poses decode"
              + (" (the plan was made with --allow-unusable)" if allowed else
                 "; see the advice in the plan's site report"), file=sys.stderr)
    return 0 if passed else ExitCode.CHECK_FAILED


def console_main(argv: list[str] | None = None) -> int:
    return cli.console_main(argv, main, "vlp-verify")


if __name__ == "__main__":
    sys.exit(console_main())
