"""``vlp-report PLAN``: rebuild the site report, with the flashing status from the as-built journal.

``vlp-plan`` writes ``site-report.html`` and ``site-report.pdf`` with every
driver "not flashed"; after (or during) flashing, this command rewrites them
from ``plan.yaml``, the maps beside it and ``as-built.json``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from planner.cli import common as cli
from planner.errors import ExitCode, UsageError


def build_parser() -> argparse.ArgumentParser:
    p = cli.Parser(
        prog="vlp-report",
        description="Rebuild a plan's site report (site-report.html, self-contained, and site-report.pdf): "
        "summary, site map, coverage, expected error, frame timing, walking route, ID bill and the installers' "
        "checklist with each driver's flashing status from the as-built journal.",
        epilog="Exit codes: 0 report written, 1 bad input, 2 usage error.",
    )
    p.add_argument("plan", metavar="PLAN", help="a plan.yaml written by vlp-plan; its maps are read from beside it")
    p.add_argument("--journal", metavar="JSON",
                   help="as-built journal written by vlp-flash (default: as-built.json beside PLAN, if present)")
    p.add_argument("-o", "--outdir", metavar="DIR", help="where to write the report (default: PLAN's directory)")
    cli.common_flags(p, "print what was written and the flashing counts as JSON")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    from planner.flash.journal import Journal
    from planner.plan import plan_hash
    from planner.plan_file import load_plan
    from planner.report.content import checklist
    from planner.report.files import write_report

    plan_path = Path(args.plan)
    plan = load_plan(plan_path)
    digest = plan_hash(plan_path.read_text("utf-8"))
    journal_path = Path(args.journal) if args.journal else plan_path.with_name("as-built.json")
    if args.journal and not journal_path.is_file():
        raise UsageError(f"--journal {journal_path}: no such file; give the as-built.json vlp-flash wrote")
    entries = Journal(journal_path, digest).entries if journal_path.is_file() else None
    outdir = Path(args.outdir) if args.outdir else plan_path.parent
    if outdir.exists() and not outdir.is_dir():
        raise UsageError(f"-o {outdir}: exists and is not a directory")
    written = write_report(plan, digest, plan_path.parent, outdir, entries)
    statuses = [s.status for s in checklist(plan, entries)]
    result: dict[str, Any] = {
        "written": [str(p) for p in written],
        "journal": str(journal_path) if entries is not None else None,
        "luminaires": len(plan.luminaires),
        "verified": statuses.count("verified"),
        "failed": statuses.count("failed"),
    }
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        where = f"journal {journal_path}" if entries is not None else "no journal yet"
        print(f"vlp-report: wrote {', '.join(result['written'])} ({result['verified']} of {result['luminaires']} "
              f"drivers verified, {result['failed']} failed; {where})")
    return ExitCode.OK


def console_main(argv: list[str] | None = None) -> int:
    return cli.console_main(argv, main, "vlp-report")


if __name__ == "__main__":
    raise SystemExit(console_main())
