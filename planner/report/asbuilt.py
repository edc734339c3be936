"""The site report's as-built check: which luminaires site photos show playing their planned ID, and which a wrong one.

Made by ``vlp-report PLAN --photos DIR`` from :mod:`planner.photo.asbuilt`'s checks:
one table of the photos (located where, or why not) and one of the luminaires seen,
those playing a wrong ID first. The same mapping is the command's ``--json`` and the
HTML section's context; :func:`asbuilt_lines` gives the PDF's text pages.
"""

from __future__ import annotations

import math
from typing import Any

from planner.photo.asbuilt import PhotoCheck, luminaire_status, sightings
from planner.positioning.fix import angles_of
from planner.positioning.locate import Site
from planner.report.figures import LINE_CHARS

STATUS_TEXT = {"wrong": "plays a wrong ID", "right": "plays its planned ID", "unread": "seen, ID not read"}


def asbuilt_section(site: Site, checks: list[PhotoCheck]) -> dict:
    """The check as plain data: ``photos``, ``luminaires`` (wrong first), the counts and a one-line ``summary``."""
    photos, seen = [], []
    for c in checks:
        row: dict = {"file": c.file, "blobs": len(c.blobs), "read": sum(b.id is not None for b in c.blobs),
                     "located": c.fix is not None and c.fix.located is not None, "problem": c.problem}
        if c.fix is not None and c.fix.located is not None:
            fix = c.fix.located.fix
            row["position_m"] = [round(float(v), 3) for v in fix.position]
            row["tilt_deg"] = round(math.degrees(angles_of(fix.rotation)[0]), 1)
            seen += sightings(c.file, site, c.blobs, c.fix)
        photos.append(row)
    lums: list[dict[str, Any]] = []
    for k, (status, mine) in luminaire_status(seen).items():
        plays = sorted({s.plays for s in mine if s.plays is not None and s.plays != s.planned})
        lums.append({"name": site.names[k], "planned_id": int(site.ids[k]), "status": status,
                     "plays": plays, "photos": sorted({s.photo for s in mine}),
                     "why_unread": next((s.problem for s in mine if s.problem), "") if status == "unread" else ""})
    lums.sort(key=lambda r: (r["status"] != "wrong", r["status"] != "unread", r["name"]))
    counts = {s: sum(r["status"] == s for r in lums) for s in STATUS_TEXT}
    located = sum(p["located"] for p in photos)
    wrong = [f"{r['name']} plays {', '.join(map(str, r['plays']))} (planned {r['planned_id']})"
             for r in lums if r["status"] == "wrong"]
    line = (f"{located} of {len(photos)} photos located; {counts['right']} luminaires seen playing their planned ID, "
            f"{counts['wrong']} a wrong one" + (f": {'; '.join(wrong)}" if wrong else ""))
    return {"photos": photos, "luminaires": lums, "counts": counts, "located_photos": located, "summary": line,
            "status_text": STATUS_TEXT}


def asbuilt_lines(section: dict) -> tuple[str, list[str]]:
    """The check as a header and fixed-width text lines for the PDF: the luminaires seen, then the photos."""
    w = max([len(r["name"]) for r in section["luminaires"]] + [9])
    header = f"{'luminaire':<{w}} {'ID':>4}  {'status':<24} photos"
    lines = [f"{r['name']:<{w}} {r['planned_id']:>4}  "
             f"{STATUS_TEXT[r['status']] + (' ' + ','.join(map(str, r['plays'])) if r['plays'] else ''):<24} "
             f"{' '.join(r['photos'])}" + (f" ({r['why_unread']})" if r["why_unread"] else "")
             for r in section["luminaires"]]
    lines += ["", section["summary"], ""]
    for p in section["photos"]:
        where = (f"at ({', '.join(f'{v:.2f}' for v in p['position_m'])}) m, tilt {p['tilt_deg']:g} deg"
                 if p["located"] else f"not located: {p['problem']}")
        lines.append(f"{p['file']}: {p['read']} of {p['blobs']} LEDs read, {where}")
    return header, [line if len(line) <= LINE_CHARS else line[:LINE_CHARS - 1] + "…" for line in lines]
