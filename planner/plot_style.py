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
"""Matplotlib settings shared by all figures."""



def styled(draw):
    """Decorator: run ``draw`` with :data:`RC` applied on the headless Agg backend (matplotlib imported lazily)."""

    @functools.wraps(draw)
    def wrapper(*args, **kwargs):
        import matplotlib

        matplotlib.use("Agg")
        with matplotlib.rc_context(RC):
            return draw(*args, **kwargs)

    return wrapper


def save_png(fig, path: str | Path | IO[bytes]) -> None:
    """Write ``fig`` as PNG without a timestamp or version (byte-stable output), and close it."""
    import matplotlib.pyplot as plt

    fig.savefig(path, format="png", metadata={"Software": None})
    plt.close(fig)


def png_bytes(fig) -> bytes:
    """``fig`` as PNG bytes (for embedding), closed afterwards."""
    buffer = io.BytesIO()
    save_png(fig, buffer)
    return buffer.getvalue()
