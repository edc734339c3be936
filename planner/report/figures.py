"""The site report's figures: the frame timing diagram, the walking route, and the PDF's pages.

All drawn with the shared style (:mod:`planner.plot_style`): grayscale, axes
labelled with units. The maps (map, coverage, expected error) are drawn by
:mod:`planner.report.maps` when the plan is made; this module places them on pages.
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from planner.plot_style import png_bytes, styled
from planner.report.content import AdviceSection, BillLine, Stop

if TYPE_CHECKING:
    from planner.plan.file import Entry, ModulationFields, PlanFile

TIMING_LUMINAIRES = 4
"""How many luminaires (with distinct IDs) the timing diagram shows."""

TIMING_FRAMES = 2
"""How many frame periods the timing diagram spans at least (more if the smallest LED image lasts longer)."""

PAGE_IN = (11.69, 8.27)
"""PDF page size [inch]: A4 landscape."""

LINE_CHARS = 170
"""Longest text line on a PDF page; longer checklist lines are cut (the HTML report has them whole)."""


def timing_examples(plan: PlanFile, route: np.ndarray) -> list[Entry]:
    """Up to :data:`TIMING_LUMINAIRES` luminaires with distinct IDs, first met along the walking route."""
    seen, chosen = set(), []
    for i in route:
        e = plan.luminaires[i]
        if e.frame is not None and e.id not in seen:
            seen.add(e.id)
            chosen.append(e)
        if len(chosen) == TIMING_LUMINAIRES:
            break
    return chosen


@styled
def timing_diagram(mod: ModulationFields, examples: list[Entry]) -> bytes:
    """PNG of :func:`timing_figure`."""
    return png_bytes(timing_figure(mod, examples))


def timing_figure(mod: ModulationFields, examples: list[Entry]):
    """Each example's LED drive (on/off) over a few frames, preamble shaded, with the smallest LED image's span.

    Time runs left to right in milliseconds; phases are aligned for reading (on
    site every driver starts at its own phase, and the receiver finds the
    preamble wherever it falls).
    """
    import matplotlib.pyplot as plt

    chip_s = 1.0 / mod.chip_rate_hz
    preamble = len(mod.preamble)
    image_s = mod.smallest_image_rows * mod.row_time_s
    frames = max(TIMING_FRAMES, math.ceil(image_s / mod.frame_period_s + 0.25))
    fig, ax = plt.subplots(figsize=(9.0, 1.2 + 0.9 * len(examples)), layout="constrained")
    for k, e in enumerate(examples):
        assert e.frame is not None  # timing_examples keeps luminaires with frames
        chips = e.frame.chips * frames
        level = np.array([int(c) for c in chips] + [int(chips[-1])], float)
        t = np.arange(len(level)) * chip_s * 1e3
        base = (len(examples) - 1 - k) * 1.6
        for f in range(frames):
            t0 = f * len(e.frame.chips) * chip_s * 1e3
            ax.axvspan(t0, t0 + preamble * chip_s * 1e3, ymin=0, ymax=1, color="0.9", lw=0, zorder=0)
        ax.step(t, base + level, where="post", color="black", ls="-", lw=1.2)
    top = (len(examples) - 1) * 1.6 + 1.5
    ax.annotate("", xy=(0, top), xytext=(image_s * 1e3, top),
                arrowprops={"arrowstyle": "<->", "color": "0.3", "lw": 1.0})
    ax.text(image_s * 1e3 / 2, top + 0.1, f"smallest LED image: {mod.smallest_image_rows:.0f} rows = "
            f"{image_s * 1e3:.2f} ms", ha="center", va="bottom", fontsize=8, color="0.2")
    ax.set_yticks([(len(examples) - 1 - k) * 1.6 + 0.5 for k in range(len(examples))],
                  [f"{e.name}\nID {e.id}" for e in examples])
    ax.set_ylim(-0.4, top + 0.7)
    ax.set_xlim(0, frames * mod.frame_chips * chip_s * 1e3)
    ax.set_xlabel("time [ms]  (shaded: preamble)")
    ax.set_ylabel("LED drive per luminaire (high = on)")
    ax.set_title(f"LED drive: {mod.line_code} at {mod.chip_rate_hz:g} chips/s, {mod.frame_chips} chips "
                 f"per frame ({mod.frame_period_s * 1e3:.3f} ms), preamble {mod.preamble}")
    return fig


@styled
def route_figure(plan: PlanFile, route: np.ndarray) -> bytes:
    """PNG of :func:`route_fig`."""
    return png_bytes(route_fig(plan, route))


def route_fig(plan: PlanFile, route: np.ndarray):
    """The installers' serpentine route over the luminaires, with stop numbers."""
    import matplotlib.pyplot as plt

    xy = plan.xy
    path = xy[route]
    span = np.maximum(np.ptp(xy, axis=0) if len(xy) else np.ones(2), 1.0) + 2.0
    inch_per_m = min(10.0 / span[0], 7.0 / span[1], 1.5)
    fig, ax = plt.subplots(figsize=(max(6.0, span[0] * inch_per_m + 1.0), max(4.0, span[1] * inch_per_m + 1.0)),
                           layout="constrained")
    ring = plan.outline_xy
    if ring is not None:
        ax.plot(*np.vstack([ring, ring[:1]]).T, color="black", lw=1.0)
    ax.plot(*path.T, color="0.45", lw=0.8, ls="-")
    ax.scatter(xy[:, 0], xy[:, 1], s=14, facecolors="white", edgecolors="black", linewidths=0.6, zorder=3)
    ax.scatter(path[:1, 0], path[:1, 1], s=90, marker=">", color="black", zorder=4, label="start (stop 1)")
    ax.scatter(path[-1:, 0], path[-1:, 1], s=70, marker="s", color="black", zorder=4, label=f"end (stop {len(path)})")
    step = 1 if len(path) <= 120 else max(1, len(path) // 60)
    for k in range(0, len(path), step):
        ax.annotate(str(k + 1), path[k], xytext=(3, 3), textcoords="offset points", fontsize=6, color="0.25")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"Walking route: {len(path)} stops, rows by y, alternating direction"
                 + ("" if step == 1 else f" (every {step}th stop numbered)"))
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2, frameon=False)
    return fig


def bill_lines(bill: list[BillLine], width: int = LINE_CHARS - 10, *, show_class: bool = True) -> tuple[str, list[str]]:
    """The ID bill as a header and fixed-width text lines (luminaire names wrapped); the odd/even class
    column only with ``show_class`` (the paper's scheme)."""
    cls = (lambda text: f"{text:<8} ") if show_class else (lambda text: "")
    header = f"{'ID':>4}  {cls('class')}{'count':>5}  luminaires (in walking order)"
    indent = 14 + len(cls(""))
    lines = []
    for b in bill:
        names = textwrap.wrap(" ".join(b.luminaires), width - indent) or [""]
        lines.append(f"{b.id:>4}  {cls(b.parity)}{b.count:>5}  {names[0]}")
        lines += [" " * indent + n for n in names[1:]]
    return header, lines


def checklist_lines(stops: list[Stop], *, show_class: bool = True) -> tuple[str, list[str]]:
    """The checklist as a header and fixed-width text lines, one per stop, with a tick box; the odd/even
    class column only with ``show_class``."""
    w = max([len(s.name) for s in stops] + [9])
    cls = (lambda text: f"{text:<5} ") if show_class else (lambda text: "")
    header = (f"done  {'stop':>4} {'row':>3}  {'luminaire':<{w}}  {'x [m]':>8} {'y [m]':>8}  {'ID':>4}  "
              f"{cls('class')}{'region':>6}  flashing")
    lines = [f"[  ]  {s.number:>4} {s.row:>3}  {s.name:<{w}}  {s.x_m:>8.2f} {s.y_m:>8.2f}  {s.id:>4}  "
             f"{cls(s.parity)}{s.region:>6}  {s.status}{': ' + s.detail if s.detail else ''}" for s in stops]
    return header, [line if len(line) <= LINE_CHARS else line[:LINE_CHARS - 1] + "…" for line in lines]


def advice_lines(advice: AdviceSection) -> tuple[str, list[str]]:
    """The site advice as a header and fixed-width text lines: verdict, note, then the table."""
    w = max([len(r[0]) for r in advice.rows] + [6])
    lines = [*textwrap.wrap(advice.note, LINE_CHARS - 10), ""]
    if advice.rows:
        lines += [f"{'change':<{w}}  {'coverage':>8}  remark"]
        lines += [f"{c:<{w}}  {v:>8}  {r}"[:LINE_CHARS] for c, v, r in advice.rows]
    return advice.verdict, lines


MONO = "DejaVu Sans Mono"
"""The text pages' table font: shipped with matplotlib, embedded (``pdf.fonttype`` 42 in the shared style),
so every page looks the same whatever fonts the reading machine has; it has Latin, Greek and Cyrillic."""

MONO_ADVANCE_EM = 0.602
"""Advance width of every DejaVu Sans Mono glyph [em] (1233/2048)."""

BODY_PT = (7.5, 10.0)
"""Smallest and largest table font size [pt]: the size makes the section's longest line fill the page width
(a :data:`LINE_CHARS` line needs the smallest)."""

TOP, BOTTOM, LEFT, WIDTH = 0.91, 0.04, 0.04, 0.92
"""Where the text pages' table sits [share of the page]: below the title (placed as on the figure pages)."""


def _page_title(fig, title: str) -> None:
    """The title every PDF page after the first carries, at one place and in one font."""
    fig.text(LEFT, 0.955, title, fontsize=12, weight="bold")


def _text_pages(pdf, title: str, header: str, lines: list[str]) -> None:
    """Fixed-width table pages in the embedded :data:`MONO`, sized to fill the width, alternate lines shaded."""
    import matplotlib.pyplot as plt

    longest = max(map(len, [header, *lines]))
    width_pt = WIDTH * PAGE_IN[0] * 72
    size = min(BODY_PT[1], max(BODY_PT[0], width_pt / (MONO_ADVANCE_EM * max(longest, 1))))
    step = 1.45 * size / (PAGE_IN[1] * 72)  # line pitch [share of the page height]
    per_page = int((TOP - BOTTOM) / step) - 2
    pages = max(1, -(-len(lines) // per_page))
    for p in range(pages):
        fig = plt.figure(figsize=PAGE_IN)
        _page_title(fig, title + (f"  (page {p + 1} of {pages})" if pages > 1 else ""))
        fig.text(LEFT, TOP, header, family=MONO, fontsize=size, weight="bold", va="top")
        for k, line in enumerate(lines[p * per_page:(p + 1) * per_page]):
            y = TOP - (k + 1.5) * step
            if k % 2:
                fig.patches.append(plt.Rectangle((LEFT - 0.005, y - 0.5 * step), WIDTH + 0.01, step, color="0.92",
                                                 transform=fig.transFigure, zorder=0))
            fig.text(LEFT, y, line, family=MONO, fontsize=size, va="center")
        pdf.savefig(fig)
        plt.close(fig)


def _image_page(pdf, title: str, png: bytes | None, missing: str) -> None:
    import io

    import matplotlib.image as mpimg
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=PAGE_IN)
    _page_title(fig, title)
    ax = fig.add_axes((0.03, 0.03, 0.94, 0.89))
    ax.set_axis_off()
    if png is None:
        ax.text(0.5, 0.5, missing, ha="center", va="center", fontsize=11, color="0.3")
    else:
        ax.imshow(mpimg.imread(io.BytesIO(png), format="png"), interpolation="antialiased")
    pdf.savefig(fig)
    plt.close(fig)


@styled
def write_pdf(path: str | Path, title: str, subtitle: str, summary: list[tuple[str, str]], sections: list[tuple[str, bytes | None, str]],
              bill: tuple[str, list[str]], checklist: tuple[str, list[str]],
              budget: tuple[str, list[str]] | None = None, advice: tuple[str, list[str]] | None = None,
              asbuilt: tuple[str, list[str]] | None = None) -> None:
    """Write the report as PDF: a title page with the summary, the site advice (if any), one page per figure, the
    error budget (if any), then the bill and checklist (and the as-built photo check, if given)."""
    import matplotlib.pyplot as plt
    from matplotlib.backends.backend_pdf import PdfPages

    with PdfPages(path, metadata={"Title": title, "Creator": "vlp-plan", "CreationDate": None}) as pdf:
        fig = plt.figure(figsize=PAGE_IN)
        fig.text(0.06, 0.88, title, fontsize=18, weight="bold")
        fig.text(0.06, 0.84, subtitle, fontsize=10, color="0.3")
        y = 0.78
        for label, value in summary:  # a long value wraps, and the next row starts below it
            wrapped = textwrap.wrap(value, 95)
            fig.text(0.06, y, label, fontsize=11, weight="bold", va="top")
            fig.text(0.24, y, "\n".join(wrapped), fontsize=11, va="top")
            y -= 0.055 + 0.026 * (len(wrapped) - 1)
        pdf.savefig(fig)
        plt.close(fig)
        if advice is not None:
            _text_pages(pdf, "Site advice", *advice)
        for name, png, missing in sections:
            _image_page(pdf, name, png, missing)
        if budget is not None:
            _text_pages(pdf, "Error budget: each term alone, then all together", *budget)
        _text_pages(pdf, "ID bill", *bill)
        _text_pages(pdf, "Installers' checklist", *checklist)
        if asbuilt:
            _text_pages(pdf, "As-built check", *asbuilt)
