"""``vlp-plan --from-plan PLAN [-o OUTDIR]``: rebuild the frames and firmware of an edited plan.yaml.

The edit-verify-flash loop: edit an ``id`` in ``plan.yaml``, ``vlp-verify`` it (it names
the luminaires whose frame no longer sends their id), ``vlp-plan --from-plan`` makes
every frame again from its id with the plan's modulation, verifies the IDs anew and
writes ``plan.yaml`` and ``firmware/`` (:func:`planner.plan.rebuild.rebuild`), sealed
under the site key with ``--key-file``, and ``vlp-flash`` flashes them. Exit codes: 0
written, 1 bad input or a plan that fails verification (nothing written), 2 usage, 3
written with ``--allow-unverified`` though it fails.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from planner.errors import ExitCode, UsageError

APPLIES = frozenset({"from_plan", "allow_unverified", "outdir", "poses_per_m2", "max_poses", "tolerance", "seed",
                     "templates", "mcu_clock_hz", "image_version", "key_file", "json", "verbose"})
"""``vlp-plan`` options that apply with ``--from-plan``; any other one given is refused, not ignored."""


def from_plan_command(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    """Run ``vlp-plan --from-plan`` with ``args`` parsed by vlp-plan's ``parser``; the exit code."""
    if not args.from_plan:
        raise UsageError("--allow-unverified is for --from-plan PLAN")
    defaults = vars(parser.parse_args([]))
    for action in parser._actions:
        dest = action.dest
        if dest in APPLIES or dest not in defaults or getattr(args, dest) == defaults[dest]:
            continue
        flag = action.option_strings[-1] if action.option_strings else dest.upper()
        raise UsageError(f"{flag} does not apply with --from-plan: the plan's own layout, scheme, camera and "
                         "modulation are kept; give only the verification and firmware options")
    from planner.cli import common as cli
    from planner.plan.budget import check_work, verify_work
    from planner.plan.file import load_plan
    from planner.plan.rebuild import rebuild

    site_key = cli.site_key(args.key_file, env=False) if args.key_file else None  # seals the rebuilt plan
    plan = load_plan(args.from_plan)
    check_work(verify_work(plan.xyz[:, :2], plan.outline, args.poses_per_m2), args.max_poses)
    cli.progress(f"rebuilding {args.from_plan}")
    summary = rebuild(args.from_plan, args.outdir, allow_unverified=args.allow_unverified,
                      poses_per_m2=args.poses_per_m2, seed=args.seed, tolerance_m=args.tolerance,
                      template_dir=Path(args.templates) if args.templates else None, mcu_clock_hz=args.mcu_clock_hz,
                      image_version=args.image_version, site_key=site_key)
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        made = summary["frames_made_again"]
        print(f"vlp-plan: {args.from_plan}: {len(made)} frame(s) made again from their id"
              + (": " + ", ".join(made[:5]) + (", ..." if len(made) > 5 else "") if made else ""))
        print(f"  verdict  {summary['verdict']}")
        print(f"  wrote    {summary['plan']} and firmware/ for {summary['luminaires']} luminaires "
              f"(plan hash {summary['plan_hash']})" + (f", sealed; flash with vlp-flash {summary['plan']}"
              if summary["sealed"] else "; not sealed: vlp-flash needs it rebuilt with --key-file FILE"))
    return ExitCode.OK if summary["verified"] else ExitCode.CHECK_FAILED
