"""A PNG map of a plan: checkerboard classes, IDs and regions.

Readable in grayscale: odd luminaires are filled, even ones hollow; regions
are shaded alternately behind them and labelled. Rendering is deterministic
(no timestamp or version in the PNG metadata).
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.spatial import ConvexHull, QhullError  # noqa: E402

from .plan import Plan  # noqa: E402

LABEL_LIMIT = 2000
"""Above this many luminaires, IDs are not written on the map (unreadable)."""


def render_map(plan: Plan, path: str | Path) -> None:
    """Write the plan's map as PNG to ``path``."""
    xy = plan.layout.xy
    ids, regions, odd = plan.assignment.ids, plan.assignment.regions, plan.graph.odd
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    pad = max(float(np.median([d for *_, d in plan.graph.graph.edges(data="length")] or [1.0])), 0.5)
    span = np.maximum(hi - lo + 2 * pad, 1.0)
    scale = min(16.0 / span[0], 12.0 / span[1], 1.2)
    fig_w, fig_h = max(6.0, span[0] * scale), max(4.5, span[1] * scale + 0.8)
    fig, ax = plt.subplots(figsize=(fig_w, fig_h), dpi=110)
    n_regions = int(regions.max()) + 1
    for r in range(n_regions):
        pts = xy[regions == r]
        shade = "0.88" if r % 2 == 0 else "0.95"
        if len(pts) >= 3:
            try:
                hull = pts[ConvexHull(pts).vertices]
                ax.fill(*hull.T, color=shade, zorder=0, linewidth=0)
            except QhullError:
                pass
        cx, cy = pts.mean(axis=0)
        ax.text(cx, cy, f"R{r}", fontsize=14, color="0.6", ha="center", va="center", zorder=1, weight="bold")
    edges = plan.graph.edges
    if len(edges):
        segs = np.stack([xy[edges[:, 0]], xy[edges[:, 1]]], axis=1)
        from matplotlib.collections import LineCollection

        ax.add_collection(LineCollection(segs, colors="0.7", linewidths=0.5, zorder=2))
    size = max(4.0, min(120.0, 2500.0 / max(1, len(xy)) ** 0.8))
    ax.scatter(*xy[odd].T, s=size * 3, c="0.15", edgecolors="black", zorder=3, label="odd (odd IDs)")
    ax.scatter(*xy[~odd].T, s=size * 3, c="white", edgecolors="black", zorder=3, label="even (even IDs)")
    if len(xy) <= LABEL_LIMIT:
        fs = max(3.0, min(8.0, 300.0 / math.sqrt(len(xy))))
        for (x, y), i, o in zip(xy, ids, odd):
            ax.text(x, y, str(int(i)), fontsize=fs, ha="center", va="center", zorder=4,
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
    ax.legend(loc="upper right", fontsize=8, framealpha=0.9)
    fig.tight_layout()
    fig.savefig(path, format="png", metadata={"Software": None})
    plt.close(fig)
