"""Write the site report: ``site-report.html`` (self-contained) and ``site-report.pdf``.

Both are made from the loaded plan, the maps ``vlp-plan`` drew beside it
(``map.png``, ``coverage.png``, ``error.png``) and, once drivers have been
flashed, the as-built journal. Each file is written to a temporary name and
renamed into place, so a reader never sees half a report.
"""

from __future__ import annotations

import base64
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

from planner._files import jinja_environment, write_atomically, write_text_atomically
from planner.report.content import (
    advice_section,
    budget_lines,
    budget_rows,
    checklist,
    error_includes,
    id_bill,
    summary,
    walking_order,
)
from planner.report.figures import (
    advice_lines,
    bill_lines,
    checklist_lines,
    route_figure,
    timing_diagram,
    timing_examples,
    write_pdf,
)

if TYPE_CHECKING:
    from planner.plan.file import PlanFile

HTML_NAME = "site-report.html"
PDF_NAME = "site-report.pdf"

MAPS = (
    ("map", "map.png", "Site map", "IDs on the luminaires; regions shaded and labelled between the luminaires."),
    ("coverage", "coverage.png", "Coverage",
     "Share of sampled camera poses (height, tilt, heading) whose view decodes to one place; dark is bad."),
    ("error", "error.png", "Expected positioning error",
     "Simulated fixes over the site"),
)
"""The maps the report embeds: (anchor, file in the plan's directory, heading, caption)."""




def _render_html(context: dict) -> str:
    from importlib.resources import files

    env = jinja_environment(Path(str(files("planner.report") / "templates")), html=True)
    return env.get_template("site-report.html.j2").render(**context)


def write_report(plan: PlanFile, plan_hash: str, plan_dir: str | Path, outdir: str | Path,
                 journal: dict[str, dict] | None = None, asbuilt: dict | None = None) -> list[Path]:
    """Write the HTML and PDF site report of ``plan`` into ``outdir``; return their paths.

    ``plan_dir`` holds the maps drawn with the plan (missing ones are named in
    their place); ``journal`` maps luminaire names to as-built entries; ``asbuilt`` is the photo
    check (:func:`planner.report.asbuilt.asbuilt_section`), a section of its own. Names in
    scripts the figures' font lacks (CJK) print as boxes in the PNGs and PDF
    without a warning each time; the HTML shows them as they are.
    """
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"Glyph \d+ .* missing from font")
        return _write_report(plan, plan_hash, Path(plan_dir), Path(outdir), journal, asbuilt)


def _write_report(plan: PlanFile, plan_hash: str, plan_dir: Path, outdir: Path, journal: dict[str, dict] | None,
                  asbuilt: dict | None = None) -> list[Path]:
    from planner import __version__
    from planner.positioning.accuracy import method_text

    route, _ = walking_order(plan.xy)
    stops = checklist(plan, journal)
    bill = id_bill(plan)
    head = summary(plan, stops) + ([("as-built check", asbuilt["summary"])] if asbuilt else [])
    advice = advice_section(plan)
    show_class = plan.scheme == "paper"  # odd/even classes mean something only under the paper's region code
    title = f"VLP site report: {plan.source.get('file', plan_dir.name)}"
    figures = []
    budget = budget_rows(plan)
    for anchor, file, name, caption in MAPS:
        png = plan_dir / file
        if anchor == "error" and plan.accuracy is not None:
            caption = f"{caption}, {method_text(plan.accuracy.method)}; {error_includes(plan)}" + \
                ("; the budget below gives each term alone." if budget else ".")
        if anchor == "map" and show_class:
            caption += " Odd class filled, even hollow (the paper's checkerboard: odd IDs on odd luminaires)."
        figures.append((anchor, name, png.read_bytes() if png.is_file() else None, caption,
                        f"{file} was not drawn for this plan (vlp-plan --no-map or --no-verify, or no sampled pose was located)."))
    if plan.modulation is not None:
        figures.append(("timing", "Frame timing", timing_diagram(plan.modulation, timing_examples(plan, route)),
                        "What each driver sends, chip by chip: its frame repeats; the receiver reads at least one "
                        "whole frame within the smallest LED image.", ""))
    figures.append(("route", "Walking route", route_figure(plan, route),
                    "The order of the checklist below: rows by increasing y, alternating direction.", ""))
    times = [e["time"] for e in (journal or {}).values() if e.get("time")]
    journal_note = f"flashing status as of {max(times)}" if times else "no drivers flashed yet"
    generator = plan.generator or f"vlp-plan {__version__}"
    html = _render_html({
        "title": title, "generator": generator, "plan_hash": plan_hash, "journal_note": journal_note,
        "summary": head, "stops": stops, "bill": bill, "advice": advice, "show_class": show_class,
        "contents": [("summary", "Summary")] + ([("advice", "Site advice")] if advice else [])
                    + [(a, n) for a, n, *_ in figures]
                    + [("budget", "Error budget")] * bool(budget) + [("bill", "ID bill"), ("checklist", "Checklist")]
                    + [("asbuilt", "As-built check")] * bool(asbuilt),
        "budget": budget, "error_includes": error_includes(plan), "asbuilt": asbuilt,
        "figures": [{"anchor": a, "name": n, "caption": c, "missing": m,
                     "data": base64.b64encode(png).decode("ascii") if png else None}
                    for a, n, png, c, m in figures],
    })
    outdir.mkdir(parents=True, exist_ok=True)
    html_path, pdf_path = outdir / HTML_NAME, outdir / PDF_NAME
    write_text_atomically(html_path, html)
    sections = [(n, png, m) for _, n, png, _, m in figures]
    if asbuilt:  # here: the photo check's modules (decoder, locator, twin) take 0.7 s to import
        from planner.report.asbuilt import asbuilt_lines
    write_atomically(pdf_path, lambda tmp: write_pdf(
        tmp, title, f"{generator} · plan {plan_hash} · {journal_note}", head, sections,
        bill_lines(bill, show_class=show_class), checklist_lines(stops, show_class=show_class),
        budget_lines(budget) if budget else None, advice_lines(advice) if advice and advice.rows else None,
        asbuilt_lines(asbuilt) if asbuilt else None))
    return [html_path, pdf_path]
