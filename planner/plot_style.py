"""One look for every figure the planner draws: grayscale, labelled axes with units, deterministic PNGs.

Every renderer is decorated with :data:`styled`; colours are shades of grey
and lines differ by dash as well as shade, so a report printed on a
black-and-white printer loses nothing.
"""

from __future__ import annotations

import functools
import io
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

from cycler import cycler

if TYPE_CHECKING:  # matplotlib loads when a figure is drawn
    from matplotlib.typing import RcKeyType

RC: dict[RcKeyType, Any] = {
    "font.family": "DejaVu Sans",
    "font.size": 9,
    "axes.titlesize": 10,
    "axes.labelsize": 9,
    "legend.fontsize": 8,
    "xtick.labelsize": 8,
    "ytick.labelsize": 8,
    "axes.edgecolor": "0.2",
    "axes.prop_cycle": cycler(color=["black", "0.45", "0.65", "0.3"], linestyle=["-", "--", ":", "-."]),
    "image.cmap": "gray",
    "grid.color": "0.85",
    "grid.linewidth": 0.5,
    "figure.dpi": 110,
    "savefig.dpi": 110,
    "pdf.fonttype": 42,
    "text.parse_math": False,  # names and file names are text: "$x$" must not become math (or an error)
}
"""Matplotlib settings shared by all figures. With math parsing off, matplotlib's own mathtext tick labels
(log axes: ``$\\mathdefault{10^{1}}$``) would print raw: give log axes :func:`plain_log_ticks`."""


def plain_log_ticks(axis) -> None:
    """Label a log ``axis`` (``ax.xaxis``) in plain numbers (0.1, 1, 10; 2, 3 between close decades), not
    mathtext, which :data:`RC` does not parse."""
    from matplotlib.ticker import LogFormatter

    class Plain(LogFormatter):
        def _num_to_string(self, x, vmin, vmax):
            return f"{x:g}"

    axis.set_major_formatter(Plain(10))
    axis.set_minor_formatter(Plain(10, labelOnlyBase=False))


def styled(draw):
    """Decorator: run ``draw`` with :data:`RC` applied on the headless Agg backend (matplotlib imported lazily)."""

    @functools.wraps(draw)
    def wrapper(*args, **kwargs):
        import matplotlib

        matplotlib.use("Agg")
        with matplotlib.rc_context(RC):
            return draw(*args, **kwargs)

    return wrapper


def save_png(fig, path: str | Path | IO[bytes], fmt: str = "png") -> None:
    """Write ``fig`` as PNG (or ``fmt`` "svg", text kept as text) without a timestamp or version (byte-stable
    output), and close it."""
    import matplotlib
    import matplotlib.pyplot as plt

    if fmt == "svg":
        with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "vlp"}):
            fig.savefig(path, format="svg", metadata={"Date": None, "Creator": None})
    else:
        fig.savefig(path, format="png", metadata={"Software": None})
    plt.close(fig)


def png_bytes(fig) -> bytes:
    """``fig`` as PNG bytes (for embedding), closed afterwards."""
    buffer = io.BytesIO()
    save_png(fig, buffer)
    return buffer.getvalue()
