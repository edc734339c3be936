"""A PNG map of a plan: checkerboard classes, IDs and regions.

Readable in grayscale: under the paper's scheme odd luminaires are filled, even
ones hollow (the classes mean nothing under the other schemes, which draw all
alike); regions are shaded alternately behind them and labelled in the gaps
between luminaires, never over an ID. Every text stays inside the canvas
(constrained layout, legends below the axes). Rendering is deterministic
(no timestamp or version in the PNG metadata).
"""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib.pyplot as plt
import numpy as np

from planner.plan.model import Plan
from planner.plot_style import save_png, styled

if TYPE_CHECKING:
    from planner.verify.verify import Verification

LABEL_LIMIT = 2000
"""Above this many luminaires, IDs are not written on the map (unreadable)."""


PAD_IN = 0.1
"""Margin the constrained layout keeps between any text and the canvas edge [inch]."""


def _region_colours(edges: np.ndarray, regions: np.ndarray) -> np.ndarray:
    """A shade index (0-3) per luminaire such that neighbouring regions differ where possible."""
    import networkx as nx

    adjacency: nx.Graph[int] = nx.Graph()
    adjacency.add_nodes_from(range(int(regions.max()) + 1))
    for u, v in edges:
        if regions[u] != regions[v]:
            adjacency.add_edge(int(regions[u]), int(regions[v]))
    colour = nx.greedy_color(adjacency, strategy="largest_first")
    return np.array([colour[int(r)] % 4 for r in regions])


def _region_label_points(xy: np.ndarray, regions: np.ndarray, pitch: float) -> np.ndarray:
    """Where each region's label goes: the free point (a corner of a luminaire's cell, farthest from every
    luminaire) nearest the region's centre, so that no label sits on a luminaire or its ID."""
    from scipy.spatial import cKDTree

    tree = cKDTree(xy)
    corners = np.array([(-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)]) * pitch
    out = []
    for r in range(int(regions.max()) + 1):
        members = xy[regions == r]
        centre = members.mean(axis=0)
        cand = (members[:, None, :] + corners[None]).reshape(-1, 2)
        free = np.asarray(tree.query(cand)[0])
        best = cand[free >= free.max() - 1e-9]
        out.append(best[np.argmin(np.hypot(*(best - centre).T))])
    return np.array(out)


def map_figure(plan: Plan):
    """The plan's map as a matplotlib figure (text kept inside the canvas; labels off the luminaires)."""
    from matplotlib.collections import LineCollection, PatchCollection
    from matplotlib.patches import Rectangle

    xy = plan.layout.xy
    ids, regions, odd = plan.assignment.ids, plan.assignment.regions, plan.graph.odd
    paper = plan.assignment.scheme == "paper"  # odd/even classes mean something only under the paper's code
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    lengths = [d["length"] for *_, d in plan.graph.graph.edges(data=True)]
    pitch = float(np.median(lengths)) if lengths else 1.0
    pad = max(pitch, 0.5)
    span = np.maximum(hi - lo + 2 * pad, 1.0)
    inch_per_m = min(16.0 / span[0], 12.0 / span[1], 1.5)
    width_in = max(6.0, span[0] * inch_per_m + 1.2)
    fig, ax = plt.subplots(figsize=(width_in, max(4.5, span[1] * inch_per_m + 1.6)), dpi=110,
                           )
    fig.set_layout_engine("constrained", w_pad=PAD_IN, h_pad=PAD_IN)
    n_regions = int(regions.max()) + 1
    # Regions: a pitch-sized cell behind each luminaire, shaded by region, so groups tile.
    shades = np.array([0.95, 0.84, 0.90, 0.78])[_region_colours(plan.graph.edges, regions)]
    cells = [Rectangle((x - pitch / 2, y - pitch / 2), pitch, pitch) for x, y in xy]
    ax.add_collection(PatchCollection(cells, facecolors=[str(v) for v in shades], edgecolors="none", zorder=0))
    marker_pt = max(2.0, 0.7 * pitch * inch_per_m * 72)  # marker diameter [pt]
    free_pt = (0.707 - 0.35) * pitch * inch_per_m * 72  # from a cell corner to the nearest marker's rim [pt]
    label_pt = min(12.0, 0.8 * free_pt)
    if label_pt >= 4.0:
        for r, (cx, cy) in enumerate(_region_label_points(xy, regions, pitch)):
            ax.text(cx, cy, f"R{r}", fontsize=label_pt, color="0.2", ha="center", va="center", zorder=5,
                    weight="bold", gid="region", bbox={"boxstyle": "round,pad=0.15", "facecolor": "white",
                                                        "alpha": 0.8, "edgecolor": "0.5"})
    edges = plan.graph.edges
    if len(edges):
        segs = np.stack([xy[edges[:, 0]], xy[edges[:, 1]]], axis=1)
        ax.add_collection(LineCollection(list(segs), colors="0.6", linewidths=0.5, zorder=2))
    if paper:
        ax.scatter(xy[odd, 0], xy[odd, 1], s=marker_pt**2, c="0.15", edgecolors="black", zorder=3,
                   label="odd class (odd IDs)")
        ax.scatter(xy[~odd, 0], xy[~odd, 1], s=marker_pt**2, c="white", edgecolors="black", zorder=3,
                   label="even class (even IDs)")
    else:
        ax.scatter(xy[:, 0], xy[:, 1], s=marker_pt**2, c="white", edgecolors="black", zorder=3)
    dark = odd if paper else np.zeros(len(xy), dtype=bool)
    font_pt = min(10.0, 0.42 * marker_pt)
    if len(xy) <= LABEL_LIMIT and font_pt >= 3.0:
        for (x, y), i, o in zip(xy, ids, dark):
            ax.text(x, y, str(int(i)), fontsize=font_pt, ha="center", va="center", zorder=4, gid="id",
                    color="white" if o else "black")
    if plan.layout.outline:
        ring = np.array(plan.layout.outline + plan.layout.outline[:1])
        ax.plot(*ring.T, color="black", linewidth=1.0, zorder=1)
    a = plan.assignment
    shading = "regions shaded" if paper else "shaded: tiles of about one set of IDs"
    title = (f"{Path(plan.layout.source_path).name}: {len(xy)} luminaires, {a.scheme} scheme, "
             f"{a.bits} bits (naive {a.naive_bits}, bound {a.lower_bound_bits}), {n_regions} regions ({shading})")
    ax.set_title("\n".join(textwrap.wrap(title, max(40, int(width_in * 72 / 10 * 1.6)))), fontsize=10)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    if paper:
        fig.legend(loc="outside lower center", ncol=2, fontsize=8, markerscale=12 / marker_pt, frameon=False)
    return fig


@styled
def render_map(plan: Plan, path: str | Path) -> None:
    """Write the plan's map as PNG to ``path``."""
    save_png(map_figure(plan), path)


COVERAGE_BIN_M = 0.25
"""Smallest side of the squares over which the coverage map averages poses [m]; squares grow (in steps of
0.25 m) until the median square holds twice :data:`THIN_POSES` sampled poses."""

THIN_POSES = 10
"""Squares of the coverage and error maps holding fewer poses than this are hatched (and said to be in the
legend): a share or a percentile of so few poses is not a measurement of that square."""


def _hatch_thin(ax, ex: np.ndarray, ey: np.ndarray, count: np.ndarray, what: str):
    """Hatch the squares (edges ``ex``, ``ey`` [m]) whose ``count`` is from 1 to below :data:`THIN_POSES`;
    return a legend handle saying so, or None if no square is thin."""
    from matplotlib.collections import PatchCollection
    from matplotlib.patches import Patch, Rectangle

    thin = np.argwhere((count > 0) & (count < THIN_POSES))
    if not len(thin):
        return None
    label = f"fewer than {THIN_POSES} {what} in the square: too few to read alone"
    squares = [Rectangle((ex[i], ey[j]), ex[i + 1] - ex[i], ey[j + 1] - ey[j]) for i, j in thin]
    ax.add_collection(PatchCollection(squares, facecolor="none", edgecolor="0.5", hatch="////", linewidth=0,
                                      zorder=1))
    return Patch(facecolor="white", edgecolor="0.5", hatch="////", linewidth=0, label=label)


@styled
def render_coverage(v: Verification, xy: np.ndarray, site: str, path: str | Path) -> None:
    """Write the verification's coverage map as PNG (:func:`coverage_figure`)."""
    save_png(coverage_figure(v, xy, site), path)


def coverage_figure(v: Verification, xy: np.ndarray, site: str):
    """The verification's coverage map: share of decodable poses per square.

    ``xy`` are the luminaires (N, 2) [m]; ``site`` begins the title (file and scheme).
    Dark is bad: black squares decode nowhere, white everywhere; ambiguous poses are
    marked with crosses, luminaires drawn as small circles.
    """
    from planner.verify.verify import AMBIGUOUS, DECODABLE

    pos = v.position[:, :2]
    side = COVERAGE_BIN_M
    while True:  # the squares the poses fill hold 2 x THIN_POSES each or more (median)
        lo = np.minimum(pos.min(axis=0), xy.min(axis=0)) - side
        hi = np.maximum(pos.max(axis=0), xy.max(axis=0)) + side
        bins = [np.arange(lo[k], hi[k] + side, side) for k in (0, 1)]
        total, _, _ = np.histogram2d(pos[:, 0], pos[:, 1], bins=bins)
        if not total.any() or np.median(total[total > 0]) >= 2 * THIN_POSES or side >= np.ptp(pos, axis=0).max():
            break
        side += COVERAGE_BIN_M
    good, _, _ = np.histogram2d(pos[v.status == DECODABLE, 0], pos[v.status == DECODABLE, 1], bins=bins)
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(total > 0, good / total, np.nan)
    span = hi - lo
    inch_per_m = min(14.0 / span[0], 10.0 / span[1], 1.5)
    fig, ax = plt.subplots(figsize=(max(6.0, span[0] * inch_per_m + 2.6), max(4.5, span[1] * inch_per_m + 1.6)),
                           dpi=110)
    fig.set_layout_engine("constrained", w_pad=PAD_IN, h_pad=PAD_IN)
    cmap = plt.get_cmap("gray").with_extremes(bad="0.75")
    mesh = ax.pcolormesh(bins[0], bins[1], share.T, cmap=cmap, vmin=0, vmax=1, shading="flat")
    fig.colorbar(mesh, ax=ax, label="decodable share of sampled poses", fraction=0.04)
    thin = _hatch_thin(ax, bins[0], bins[1], total, "sampled poses")
    ax.scatter(xy[:, 0], xy[:, 1], s=12, facecolors="none", edgecolors="0.55", linewidths=0.8, label="luminaire")
    amb = v.status == AMBIGUOUS
    if amb.any():
        ax.scatter(pos[amb, 0], pos[amb, 1], marker="x", s=18, c="black", linewidths=0.8, label="ambiguous pose")
    ax.set_title(
        f"{site}, {v.poses} poses, {100 * v.coverage:.1f} % decodable, {v.count(AMBIGUOUS)} ambiguous; "
        f"{side:g} m squares", fontsize=10)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")
    ax.set_xlim(bins[0][0], bins[0][-1])  # fixed limits: the layout sizes its margins for the ticks drawn
    ax.set_ylim(bins[1][0], bins[1][-1])
    handles = ax.get_legend_handles_labels()[0] + ([thin] if thin else [])
    fig.legend(handles=handles, loc="outside lower center", ncol=2, fontsize=8, frameon=False)
    return fig


@styled
def render_error(plan: Plan, path: str | Path) -> None:
    """Write the expected-error map as PNG (:func:`error_figure`)."""
    save_png(error_figure(plan), path)


def error_figure(plan: Plan):
    """The expected-error map: median and 90th-percentile error per square, side by side.

    Dark is bad (large error); squares where no sampled pose gave a position are light grey.
    """
    from planner.positioning.accuracy import method_text
    from planner.positioning.error_terms import TERM_NAMES

    acc = plan.accuracy
    assert acc is not None  # drawn only for a plan with an error map
    ex, ey, med, p90, count = acc.cells()
    finite = p90[np.isfinite(p90)]
    top = float(finite.max()) if len(finite) else 1.0
    unit, scale = ("mm", 1e3) if top < 0.01 else ("cm", 1e2)
    span = np.array([ex[-1] - ex[0], ey[-1] - ey[0]])
    inch_per_m = min(7.0 / span[0], 8.0 / span[1], 1.0)
    fig, axes = plt.subplots(1, 2, figsize=(max(9.0, 2 * span[0] * inch_per_m + 3.0), max(4.5, span[1] * inch_per_m + 1.6)),
                             dpi=110, sharey=True, layout="constrained")
    cmap = plt.get_cmap("gray_r").with_extremes(bad="0.85")
    xy = plan.layout.xy
    for ax, grid, title in ((axes[0], med, "median"), (axes[1], p90, "90th percentile")):
        mesh = ax.pcolormesh(ex, ey, grid.T * scale, cmap=cmap, vmin=0, vmax=top * scale, shading="flat")
        thin = _hatch_thin(ax, ex, ey, count, "located poses")
        ax.scatter(xy[:, 0], xy[:, 1], s=8, facecolors="none", edgecolors="0.5", linewidths=0.5)
        ax.set_title(f"{title} error per {acc.summary()['cell_m']:g} m square", fontsize=9)
        ax.set_xlabel("x [m]")
        ax.set_aspect("equal")
    axes[0].set_ylabel("y [m]")
    fig.colorbar(mesh, ax=list(axes), label=f"position error [{unit}]", fraction=0.03)
    s = acc.summary()
    title = (f"{Path(plan.layout.source_path).name}: {method_text(s['method'])} with "
             f"{', '.join(TERM_NAMES[k] for k in s['includes']) or 'exact images'}, "
             f"{s['located']} of {s['poses']} sampled poses located, median {np.median(count[count > 0]):.0f} "
             f"a square")
    fig.suptitle(textwrap.fill(title, int(12 * fig.get_figwidth())), fontsize=10)  # about 12 characters per inch
    if thin:
        fig.legend(handles=[thin], loc="outside lower center", fontsize=8, frameon=False)
    return fig
