"""``vlp-inspect DRAWING``: what a DXF or IFC drawing holds and what ``vlp-plan`` would read from it, and why.

Exit codes: 0 the drawing reads as a plannable layout; 1 it does not (the report says where
the reader stops); 2 usage. Nothing is written except the ``--png`` picture.
"""

from __future__ import annotations

import argparse
import json
import sys

from planner import __version__
from planner.cli import common as cli
from planner.defaults import MAX_LUMINAIRES
from planner.errors import ExitCode, UsageError

SHOWN = 12
"""Rows of each list the text report shows (``--json`` has them all)."""


def build_parser() -> argparse.ArgumentParser:
    p = cli.parser(
        "vlp-inspect",
        "Show what a drawing (DXF or IFC) holds and what vlp-plan would read from it: layers and blocks "
        "(IFC: storeys and classes) with counts, what the reader takes and rejects and why, the unit it chooses and "
        "its evidence, and the luminaires it ends with or the line it would stop with.",
        ok="the drawing reads as a plannable layout", bad_input="(the drawing does not)",
        docs="docs/dxf.md, docs/ifc.md", json="print the whole report as JSON",
    )
    p.add_argument("drawing", metavar="DRAWING", help="a .dxf or .ifc file")
    p.add_argument("--png", metavar="FILE", help="also draw the candidates (taken, rejected) over the drawing")
    p.add_argument("--leds", type=cli.count_up_to(MAX_LUMINAIRES), metavar="N",
                   help="read as vlp-plan --leds N would (the group of N among several)")
    cli.add_reading_flags(p, "reading (as vlp-plan)", "DRAWING")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    png = cli.output_file("--png", args.png)
    from pathlib import Path

    if Path(args.drawing).suffix.lower() not in (".dxf", ".ifc"):
        raise UsageError(f"{args.drawing}: vlp-inspect reads .dxf and .ifc drawings")
    if not Path(args.drawing).is_file():
        raise UsageError(f"{args.drawing}: no such file")
    from planner.layout.survey import draw_survey, survey
    options = cli.read_options(args)
    report = survey(args.drawing, args.leds, options)
    if report["error"] is not None:  # the reader names its parameters; the user gave flags
        report["error"] = cli.worded(report["error"])
    if png is not None and report.get("points"):
        from planner._files import write_atomically

        write_atomically(png, lambda tmp: draw_survey(report, tmp))
    if args.json:
        shown = {k: v for k, v in report.items() if k != "points"}
        print(json.dumps(shown, indent=2))
    else:
        _print(report)
    return ExitCode.OK if report["error"] is None else ExitCode.INPUT


def _listing(rows: list[dict]) -> str:
    text = ", ".join(f"{r['name']} ({r['count']}" + (f", says {r['says']}" if r["says"] else "") + ")"
                     for r in rows[:SHOWN])
    return (text + (f", ... {len(rows) - SHOWN} more" if len(rows) > SHOWN else "")) or "none"


def _decisions(label: str, rows: list[dict]) -> None:
    if not rows:
        print(f"  {label:<8} nothing")
    for k, r in enumerate(rows[:SHOWN]):
        what = f"{r['entity']} {r['name']!r}" if r["name"] else r["entity"]
        print(f"  {label if k == 0 else '':<8} {r['count']:>5} x {what} on {r['layer']!r}: {r['why']}")
    if len(rows) > SHOWN:
        print(f"  {'':<8} ... {len(rows) - SHOWN} more (--json lists all)")


def _print(r: dict) -> None:
    print(f"vlp-inspect {__version__}: {r['file']}" + (f" ({r['kind']}, {r['header']})" if "kind" in r else ""))
    if "kind" in r:
        if r["kind"] == "IFC":
            print(f"  storeys  {_listing(r['storeys'])}")
            print(f"  classes  {_listing(r['blocks'])}")
        else:
            print(f"  layers   {_listing(r['layers'])}")
            print(f"  blocks   {_listing(r['blocks'])}")
        print(f"  select   {r['selection']}")
        _decisions("takes", r["taken"])
        _decisions("rejects", r["rejected"])
        if r["kind"] == "DXF":
            print(f"  outlines {len(r['outlines'])} closed polyline(s) and {r.get('wall_lines', 0)} open line(s) on "
                  "wall/room layers" + (": " + ", ".join(sorted({o['layer'] for o in r['outlines']}))
                                        if r["outlines"] else ""))
        for note in r.get("recovered", []):
            print(f"  note     {note}")
    if r["error"] is not None:
        print(f"  result   vlp-plan would stop: {r['error']}")
        return
    print(f"  unit     {r['unit']} ({r['unit_reason']})")
    print(f"  result   {r['luminaires']} luminaires")
    for note in r["notes"]:
        print(f"  note     {note}")


def console_main(argv: list[str] | None = None) -> int:
    return cli.console_main(argv, main, "vlp-inspect")


if __name__ == "__main__":
    sys.exit(console_main())
