"""``vlp-report PLAN``: rebuild the site report, with the flashing status from the as-built journal.

``vlp-plan`` writes ``site-report.html`` and ``site-report.pdf`` with every
driver "not flashed"; after (or during) flashing, this command rewrites them
from ``plan.yaml``, the maps beside it and ``as-built.json``. With ``--photos DIR``
it adds the as-built check: each site photo in DIR is decoded and located, and the
luminaires seen are marked playing their planned ID or a wrong one (docs/photos.md).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

from planner.cli import common as cli
from planner.errors import ExitCode, UsageError

if TYPE_CHECKING:
    from planner.plan.file import PlanFile


def build_parser() -> argparse.ArgumentParser:
    p = cli.parser(
        "vlp-report",
        "Rebuild a plan's site report (site-report.html, self-contained, and site-report.pdf): "
        "summary, site map, coverage, expected error, frame timing, walking route, ID bill and the installers' "
        "checklist with each driver's flashing status from the as-built journal; with --photos, the as-built "
        "check of which luminaires play their planned ID.",
        ok="report written", check_failed="report written but --photos shows a luminaire playing a wrong ID",
        docs="docs/report.md, docs/photos.md",
        json="print what was written, the flashing counts and the as-built check as JSON",
    )
    p.add_argument("plan", metavar="PLAN", help="a plan.yaml written by vlp-plan; its maps are read from beside it")
    p.add_argument("--journal", metavar="JSON",
                   help="as-built journal written by vlp-flash (default: as-built.json beside PLAN, if present)")
    p.add_argument("--photos", metavar="DIR",
                   help="as-built check: decode and locate every photo (.jpg, .jpeg, .png) in DIR and mark the "
                   "luminaires seen playing their planned ID or a wrong one (docs/photos.md)")
    cli.add_camera_flag(p, "with --photos: the camera that took them; default: the plan's camera")
    p.add_argument("--key-file", metavar="FILE", help="site key: check the plan's seal and the journal's, and refuse "
                   "either if it does not check (without it the journal's verified counts are its own word)")
    p.add_argument("-o", "--outdir", metavar="DIR", help="where to write the report (default: PLAN's directory)")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    from planner._files import read_text
    from planner.flash.journal import Journal
    from planner.flash.seal import check_seal
    from planner.plan.file import load_plan
    from planner.plan.model import plan_hash

    plan_path = Path(args.plan)
    text = read_text(plan_path, "plan", "no such plan file; run vlp-plan first")  # one read: checked and hashed
    key = cli.site_key(args.key_file, env=False) if args.key_file else None
    if key is not None:
        check_seal(plan_path, text, key)
    plan = load_plan(plan_path, text)
    plan.check_verdict_current(str(plan_path))
    digest = plan_hash(text)
    journal_path = Path(args.journal) if args.journal else plan_path.with_name("as-built.json")
    if args.journal and not journal_path.is_file():
        raise UsageError(f"--journal {journal_path}: no such file; give the as-built.json vlp-flash wrote")
    entries = Journal(journal_path, digest, key).entries if journal_path.is_file() else None  # seals checked with key
    outdir = Path(args.outdir) if args.outdir else plan_path.parent
    if outdir.exists() and not outdir.is_dir():
        raise UsageError(f"-o {outdir}: exists and is not a directory")
    if args.camera and not args.photos:
        raise UsageError("--camera goes with --photos (the camera that took them)")
    from planner.report.content import checklist  # the report's stages load only once the inputs are checked
    from planner.report.files import write_report

    asbuilt = photo_check(plan, args) if args.photos else None
    written = write_report(plan, digest, plan_path.parent, outdir, entries, asbuilt)
    statuses = [s.status for s in checklist(plan, entries)]
    result: dict[str, Any] = {
        "written": [str(p) for p in written],
        "journal": str(journal_path) if entries is not None else None,
        "seals_checked": key is not None,
        "luminaires": len(plan.luminaires),
        "verified": statuses.count("verified"),
        "failed": statuses.count("failed"),
    }
    if asbuilt is not None:
        result["asbuilt"] = {k: asbuilt[k] for k in ("summary", "counts", "located_photos", "luminaires", "photos")}
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        where = (f"journal {journal_path}, " + ("its seals checked" if key else "seals not checked: give --key-file")
                 if entries is not None else "no journal yet")
        print(f"vlp-report: wrote {', '.join(result['written'])} ({result['verified']} of {result['luminaires']} "
              f"drivers verified, {result['failed']} failed; {where})")
        if asbuilt is not None:
            print(f"vlp-report: as-built check: {asbuilt['summary']}")
    return ExitCode.CHECK_FAILED if asbuilt and asbuilt["counts"]["wrong"] else ExitCode.OK


def photo_check(plan: PlanFile, args: argparse.Namespace) -> dict:
    """``--photos``: decode and locate every photo in the folder; the report's as-built section."""
    from planner.errors import InputError
    from planner.photo.asbuilt import PhotoCheck, check_photo
    from planner.photo.read import SUFFIXES, photo_blobs, site_format
    from planner.positioning.locate import Site
    from planner.report.asbuilt import asbuilt_section

    folder = Path(args.photos)
    if not folder.is_dir():
        raise UsageError(f"--photos {folder}: no such folder; give the folder holding the site photos")
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in SUFFIXES and p.is_file())
    if not files:
        raise UsageError(f"--photos {folder}: no {', '.join(SUFFIXES)} photos in it")
    camera = cli.camera_from_args(args, plan.camera_model())
    site, fmt = Site.from_plan(plan), site_format(plan)
    checks = []
    for k, path in enumerate(files, 1):
        cli.progress(f"photo {k} of {len(files)}: {path.name}")
        try:
            blobs = photo_blobs(path, camera, fmt)
        except InputError as exc:  # one unreadable photo does not stop the check of the others
            checks.append(PhotoCheck(path.name, [], None, str(exc)))
            continue
        checks.append(check_photo(site, path.name, blobs, camera))
    return asbuilt_section(site, checks)


def console_main(argv: list[str] | None = None) -> int:
    return cli.console_main(argv, main, "vlp-report")


if __name__ == "__main__":
    raise SystemExit(console_main())
