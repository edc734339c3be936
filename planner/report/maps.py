"""A PNG map of a plan: checkerboard classes, IDs and regions.

Readable in grayscale: odd luminaires are filled, even ones hollow; regions
are shaded alternately behind them and labelled. Rendering is deterministic
(no timestamp or version in the PNG metadata).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib.pyplot as plt
import numpy as np

from planner.plan import Plan
from planner.plot_style import save_png, styled

if TYPE_CHECKING:
    from planner.verify.verify import Verification

LABEL_LIMIT = 2000
"""Above this many luminaires, IDs are not written on the map (unreadable)."""


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


@styled
def render_map(plan: Plan, path: str | Path) -> None:
    """Write the plan's map as PNG to ``path``."""
    xy = plan.layout.xy
    ids, regions, odd = plan.assignment.ids, plan.assignment.regions, plan.graph.odd
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    lengths = [d["length"] for *_, d in plan.graph.graph.edges(data=True)]
    pitch = float(np.median(lengths)) if lengths else 1.0
    pad = max(pitch, 0.5)
    span = np.maximum(hi - lo + 2 * pad, 1.0)
    inch_per_m = min(16.0 / span[0], 12.0 / span[1], 1.5)
    fig, ax = plt.subplots(figsize=(max(6.0, span[0] * inch_per_m + 1.2), max(4.5, span[1] * inch_per_m + 1.2)), dpi=110)
    n_regions = int(regions.max()) + 1
    # Regions: a pitch-sized cell behind each luminaire, shaded by region, so groups tile.
    from matplotlib.collections import LineCollection, PatchCollection
    from matplotlib.patches import Rectangle

    shades = np.array([0.95, 0.84, 0.90, 0.78])[_region_colours(plan.graph.edges, regions)]
    cells = [Rectangle((x - pitch / 2, y - pitch / 2), pitch, pitch) for x, y in xy]
    ax.add_collection(PatchCollection(cells, facecolors=[str(v) for v in shades], edgecolors="none", zorder=0))
    for r in range(n_regions):
        cx, cy = xy[regions == r].mean(axis=0)
        ax.text(cx, cy, f"R{r}", fontsize=12, color="0.2", ha="center", va="center", zorder=5, weight="bold",
                bbox={"boxstyle": "round", "facecolor": "white", "alpha": 0.8, "edgecolor": "0.5"})
    edges = plan.graph.edges
    if len(edges):
        segs = np.stack([xy[edges[:, 0]], xy[edges[:, 1]]], axis=1)
        ax.add_collection(LineCollection(list(segs), colors="0.6", linewidths=0.5, zorder=2))
    marker_pt = max(2.0, 0.7 * pitch * inch_per_m * 72)  # marker diameter [pt]
    paper = plan.assignment.scheme == "paper"
    ax.scatter(xy[odd, 0], xy[odd, 1], s=marker_pt**2, c="0.15", edgecolors="black", zorder=3,
               label="odd class" + (" (odd IDs)" if paper else ""))
    ax.scatter(xy[~odd, 0], xy[~odd, 1], s=marker_pt**2, c="white", edgecolors="black", zorder=3,
               label="even class" + (" (even IDs)" if paper else ""))
    font_pt = min(10.0, 0.42 * marker_pt)
    if len(xy) <= LABEL_LIMIT and font_pt >= 3.0:
        for (x, y), i, o in zip(xy, ids, odd):
            ax.text(x, y, str(int(i)), fontsize=font_pt, ha="center", va="center", zorder=4,
                    color="white" if o else "black")
    if plan.layout.outline:
        ring = np.array(plan.layout.outline + plan.layout.outline[:1])
        ax.plot(*ring.T, color="black", linewidth=1.0, zorder=1)
    a = plan.assignment
    ax.set_title(
        f"{Path(plan.layout.source_path).name}: {len(xy)} luminaires, {a.scheme} scheme, "
        f"{a.bits} bits (naive {a.naive_bits}, bound {a.lower_bound_bits}), {n_regions} regions",
        fontsize=10,
    )
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=2, fontsize=8, markerscale=12 / marker_pt,
              frameon=False)
    fig.tight_layout()
    save_png(fig, path)


COVERAGE_BIN_M = 0.25
"""Side of the squares over which the coverage map averages poses [m]."""


@styled
def render_coverage(v: Verification, xy: np.ndarray, site: str, path: str | Path) -> None:
    """Write the verification's coverage map as PNG: share of decodable poses per square.

    ``xy`` are the luminaires (N, 2) [m]; ``site`` begins the title (file and scheme).
    Dark is bad: black squares decode nowhere, white everywhere; ambiguous poses are
    marked with crosses, luminaires drawn as small circles.
    """
    from planner.verify.verify import AMBIGUOUS, DECODABLE

    pos = v.position[:, :2]
    lo = np.minimum(pos.min(axis=0), xy.min(axis=0)) - COVERAGE_BIN_M
    hi = np.maximum(pos.max(axis=0), xy.max(axis=0)) + COVERAGE_BIN_M
    bins = [np.arange(lo[k], hi[k] + COVERAGE_BIN_M, COVERAGE_BIN_M) for k in (0, 1)]
    total, _, _ = np.histogram2d(pos[:, 0], pos[:, 1], bins=bins)
    good, _, _ = np.histogram2d(pos[v.status == DECODABLE, 0], pos[v.status == DECODABLE, 1], bins=bins)
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(total > 0, good / total, np.nan)
    span = hi - lo
    inch_per_m = min(14.0 / span[0], 10.0 / span[1], 1.5)
    fig, ax = plt.subplots(figsize=(max(6.0, span[0] * inch_per_m + 2.0), max(4.5, span[1] * inch_per_m + 1.2)),
                           dpi=110)
    cmap = plt.get_cmap("gray").with_extremes(bad="0.75")
    mesh = ax.pcolormesh(bins[0], bins[1], share.T, cmap=cmap, vmin=0, vmax=1, shading="flat")
    fig.colorbar(mesh, ax=ax, label="decodable share of sampled poses", fraction=0.04)
    ax.scatter(xy[:, 0], xy[:, 1], s=12, facecolors="none", edgecolors="0.35", linewidths=0.6, label="luminaire")
    amb = v.status == AMBIGUOUS
    if amb.any():
        ax.scatter(pos[amb, 0], pos[amb, 1], marker="x", s=18, c="black", linewidths=0.8, label="ambiguous pose")
    ax.set_title(
        f"{site}, {v.poses} poses, "
        f"{100 * v.coverage:.1f} % decodable, {v.count(AMBIGUOUS)} ambiguous", fontsize=10)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2, fontsize=8, frameon=False)
    fig.tight_layout()
    save_png(fig, path)


@styled
def render_error(plan: Plan, path: str | Path) -> None:
    """Write the expected-error map as PNG: median and 90th-percentile error per square, side by side.

    Dark is bad (large error); squares where no sampled pose gave a position are light grey.
    """
    from planner.positioning.error_terms import TERM_NAMES

    acc = plan.accuracy
    assert acc is not None  # drawn only for a plan with an error map
    ex, ey, med, p90 = acc.cells()
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
        ax.scatter(xy[:, 0], xy[:, 1], s=8, facecolors="none", edgecolors="0.5", linewidths=0.5)
        ax.set_title(f"{title} error per {acc.summary()['cell_m']:g} m square", fontsize=9)
        ax.set_xlabel("x [m]")
        ax.set_aspect("equal")
    axes[0].set_ylabel("y [m]")
    fig.colorbar(mesh, ax=list(axes), label=f"position error [{unit}]", fraction=0.03)
    s = acc.summary()
    fig.suptitle(f"{Path(plan.layout.source_path).name}: {s['method']} method with "
                 f"{', '.join(TERM_NAMES[k] for k in s['includes']) or 'exact images'}, "
                 f"{s['located']} of {s['poses']} sampled poses located", fontsize=10)
    save_png(fig, path)
