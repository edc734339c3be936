"""The site report's content: summary figures, the ID bill and the installers' checklist in walking order.

Pure computation on a loaded plan (:class:`~planner.plan.file.PlanFile`) and, once
drivers have been flashed, the as-built journal's entries; the figures are
drawn by :mod:`planner.report.figures` and the files written by
:mod:`planner.report.files`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

import numpy as np

if TYPE_CHECKING:
    from planner.plan.file import Entry, PlanFile

ROW_TOLERANCE = 0.5
"""Luminaires whose y differs from a row's first by less than this share of the pitch walk in that row."""


def walking_order(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A serpentine route: rows by increasing y, walked left to right, then right to left, and so on.

    A row gathers the luminaires whose y lies within :data:`ROW_TOLERANCE` times
    the median nearest-neighbour distance of the row's first (lowest) one, so a
    slightly staggered or surveyed row stays one row. Returns the luminaire
    indices in walking order and each stop's row number.
    """
    n = len(xy)
    if n == 0:
        return np.zeros(0, int), np.zeros(0, int)
    if n > 1:
        from scipy.spatial import cKDTree

        # many points: arrays (the stubs' return type also allows one point's scalars)
        d = cast(np.ndarray, cKDTree(xy).query(xy, k=2)[0])
        pitch = float(np.median(d[:, 1]))
    else:
        pitch = 1.0
    tol = ROW_TOLERANCE * pitch
    by_y = np.lexsort((xy[:, 0], xy[:, 1]))
    order: list[list[int]] = []
    row: list[int] = []
    start = xy[by_y[0], 1]
    for i in by_y:
        if xy[i, 1] - start > tol:
            order.append(row)
            row, start = [], xy[i, 1]
        row.append(i)
    order.append(row)
    route: list[int] = []
    row_of: list[int] = []
    for r, members in enumerate(order):
        members = sorted(members, key=lambda i: xy[i, 0], reverse=bool(r % 2))
        route += members
        row_of += [r] * len(members)
    return np.array(route, int), np.array(row_of, int)


@dataclass(frozen=True)
class BillLine:
    """One ID of the bill: how many drivers carry it, and which luminaires."""

    id: int
    parity: str
    count: int
    luminaires: tuple[str, ...]


def id_bill(plan: PlanFile) -> list[BillLine]:
    """The ID bill: every ID used, with its class, count and luminaires (in walking order)."""
    lums = plan.luminaires
    route, _ = walking_order(plan.xy)
    by_id: dict[int, list[Entry]] = {}
    for i in route:
        by_id.setdefault(lums[i].id, []).append(lums[i])
    return [BillLine(k, "/".join(sorted({e.parity for e in v})), len(v), tuple(e.name for e in v))
            for k, v in sorted(by_id.items())]


@dataclass(frozen=True)
class Stop:
    """One stop of the installers' checklist."""

    number: int
    row: int
    name: str
    x_m: float
    y_m: float
    id: int
    parity: str
    region: int
    firmware: str
    status: str
    detail: str


STATUS_OK = ("flashed", "current", "verified")
"""Journal statuses meaning the driver holds this plan's image, verified."""


def _status(entry: dict | None) -> tuple[str, str]:
    if entry is None:
        return "not flashed", ""
    detail = ", ".join(s for s in (entry.get("driver_serial") and f"driver {entry['driver_serial']}",
                                   entry.get("time")) if s)
    if entry.get("status") in STATUS_OK and entry.get("verified"):
        return "verified", detail
    return "failed", "; ".join(s for s in (entry.get("message"), detail) if s)


def checklist(plan: PlanFile, journal: dict[str, dict] | None = None) -> list[Stop]:
    """The installers' checklist: every luminaire in walking order, with its flashing status from ``journal``."""
    from planner.firmware.render import file_name

    route, rows = walking_order(plan.xy)
    journal = journal or {}
    stops = []
    for k, (i, r) in enumerate(zip(route, rows), 1):
        e = plan.luminaires[i]
        status, detail = _status(journal.get(e.name))
        stops.append(Stop(k, int(r) + 1, e.name, e.x, e.y, e.id, e.parity, e.region,
                          f"firmware/{file_name(e.name)}/", status, detail))
    return stops


def summary(plan: PlanFile, stops: list[Stop]) -> list[tuple[str, str]]:
    """The report's headline figures as (label, value) pairs, from the plan."""
    from planner.positioning.accuracy import method_text
    from planner.receivers.modes import RECEIVERS

    code, mod, ver, acc = plan.code, plan.modulation, plan.verification, plan.accuracy
    regions = len(set(plan.regions.tolist()))
    rows = [
        ("layout", f"{plan.source.get('file', '?')} ({len(plan.luminaires)} luminaires, "
                   f"unit {plan.source.get('unit', '?')})"),
        ("scheme", f"{plan.scheme}: {code.bits} bits per ID (naive {code.naive_bits}, lower bound "
                   f"{code.lower_bound_bits}), IDs 1..{code.max_id}, {regions} regions"),
    ]
    if ver:
        rows.append(("verification", f"{100 * ver.coverage:.1f} % of {ver.poses} sampled poses decodable, "
                                     f"{ver.ambiguous} ambiguous"))
        if plan.advice:
            from planner.advice.advise import verdict

            rows.append(("verdict", verdict(plan.advice.model_dump())))
    else:
        rows.append(("verification", "not verified (--no-verify)"))
    if plan.receiver:  # --receiver gravity or auto: coverage per receiver mode planned
        r = plan.receiver
        modes = {name: mode.title for name, mode in RECEIVERS.items()}
        per = "; ".join(f"{modes.get(k, k)} {100 * float(c):.1f} %" for k, c in (r.get("coverage") or {}).items())
        one = (r.get("poses_seeing") or {}).get("exactly_one_led")
        rows.append(("receiver", f"{modes.get(str(r.get('mode')), r.get('mode'))} ({r.get('reason', '')}); sampled "
                                 f"poses decodable by mode: {per}" + (f"; {100 * float(one):.1f} % of poses see exactly "
                                                                      "one whole LED" if one is not None else "")))
    if acc and acc.located and acc.median_m is not None and acc.p90_m is not None:
        rows.append(("expected error", f"{method_text(acc.method)}: median {length_text(acc.median_m)}, 90 % "
                                       f"{length_text(acc.p90_m)} ({acc.located} of {acc.poses} poses located); "
                                       f"{error_includes(plan)}"))
    elif acc:
        rows.append(("expected error", f"{method_text(acc.method)}: none of {acc.poses} sampled poses located"))
    if acc and acc.dominant:
        alone = ", ".join(f"{_term_name(k)} {length_text(b.median_m)}" for k, b in acc.budget.items()
                          if k not in ("all", "exact") and b.median_m is not None)
        exact = acc.budget["exact"].median_m if "exact" in acc.budget else None
        rows.append(("error budget", (f"median with exact images {length_text(exact)}; " if exact is not None else "")
                     + f"each term alone: {alone}; {_term_name(acc.dominant)} dominates"))
    if mod:
        rows.append(("modulation", f"{mod.line_code}, {mod.chip_rate_hz:g} chips/s, {mod.frame_chips} chips "
                                   f"per frame ({1e3 * mod.frame_period_s:.3f} ms), "
                                   f"{mod.frames_in_smallest_image:.1f} frames in the smallest LED image"
                                   + (f"; read over {mod.video_frames} consecutive video frames at "
                                      f"{mod.video_fps:g} fps (multi-frame: hold the phone still)"
                                      if mod.video_frames > 1 else "")))
    tones = (plan.model_extra or {}).get("tones")
    if tones:  # an existing tone site (docs/tones.md): audited, nothing to flash
        from planner.advice.tones import tone_lines

        rows.append(("tones", "; ".join(line.strip() for line in tone_lines(tones)).removeprefix("tones").strip()))
        return rows
    done = sum(s.status == "verified" for s in stops)
    failed = sum(s.status == "failed" for s in stops)
    rows.append(("flashing", f"{done} of {len(stops)} drivers verified" + (f", {failed} failed" if failed else "")))
    return rows


def _term_name(term: str) -> str:
    from planner.positioning.error_terms import TERM_NAMES

    return TERM_NAMES.get(term, term)


def error_includes(plan: PlanFile) -> str:
    """What the plan's expected-error figures include, in a sentence (pixel noise only for plans made before
    the error budget)."""
    from planner.positioning.error_terms import ErrorTerms, included_text
    from planner.receivers.modes import extra_error_terms

    acc = plan.accuracy
    if acc is None:
        return ""
    noise = getattr(acc, "noise_px", None)
    if acc.terms is None:
        return (f"includes edge noise ({noise:g} px) only: " if noise is not None else "includes pixel noise only: ") + \
            "install, calibration and motion errors come on top (the plan predates the error budget)"
    terms = ErrorTerms.from_dict(acc.terms)
    kinds = ("install", "calibration", "edge", "skew", *extra_error_terms(acc.method))
    left = [name for name in kinds if name not in terms.active]
    return f"includes {included_text(terms)}" + (f"; leaves out {', '.join(_term_name(n) for n in left)}" if left else "")


def budget_rows(plan: PlanFile) -> list[tuple[str, str, str, int, str]]:
    """The error budget, each term alone then all together: (term, median, 90 %, poses located, values);
    empty for a plan without one."""
    from planner.positioning.error_terms import ErrorTerms, describe

    acc = plan.accuracy
    if acc is None or not acc.budget or acc.terms is None:
        return []
    values = describe(ErrorTerms.from_dict(acc.terms))
    rows = []
    for k in [*(k for k in acc.budget if k != "all"), "all"]:
        b = acc.budget[k]
        name = "all together" if k == "all" else _term_name(k) + (" (dominates)" if k == acc.dominant else "")
        med, p90 = (length_text(v) if v is not None else "-" for v in (b.median_m, b.p90_m))
        rows.append((name, med, p90, b.located, values.get(k, "exact images, no error source" if k == "exact" else "")))
    return rows


def budget_lines(rows: list[tuple[str, str, str, int, str]]) -> tuple[str, list[str]]:
    """:func:`budget_rows` as a header and fixed-width text lines (the PDF's page)."""
    header = f"{'term':<38} {'median':>9} {'90 %':>9} {'located':>8}  values"
    return header, [f"{n:<38} {m:>9} {p:>9} {k:>8}  {v}" for n, m, p, k, v in rows]


def length_text(metres: float) -> str:
    """A length for people: millimetres below 1 cm, else centimetres."""
    return f"{metres * 1e3:.2f} mm" if metres < 0.01 else f"{metres * 1e2:.1f} cm"


@dataclass(frozen=True)
class AdviceSection:
    """The report's site advice: the verdict, how the figures were sampled, and the table of changes."""

    verdict: str
    note: str
    rows: list[tuple[str, str, str]]


def advice_section(plan: PlanFile) -> AdviceSection | None:
    """The site advice of a verified plan (``plan.yaml``'s ``advice``), or None."""
    from planner.advice.advise import table, verdict

    if plan.advice is None:
        return None
    a = plan.advice.model_dump()
    measure = a.get("measure") or "share of sampled poses whose camera sees three whole, non-collinear LEDs"
    frames = (f" A change that reaches it is also checked to fit its frames with drivers of "
              f"{a['driver_max_hz'] / 1e3:g} kHz." if a.get("driver_max_hz") else "")
    note = (f"Changes tried to reach {100 * a['goal']:.0f} % of sampled poses, each measured on a coarse sample "
            f"({a['poses_per_candidate']} poses, {a['poses_per_m2']:g} per m2) as the {measure}.{frames} "
            "Sampled figures, not proved; plan the changed site to verify it."
            if a["changes"] else "")
    return AdviceSection(verdict(a), note, table(a) if a["changes"] else [])
