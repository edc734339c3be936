"""The CDF plot of ``vlp-accuracy --cdf`` is legible: its log-axis ticks are numbers, not raw mathtext.

The installed console script draws the plot as SVG with text kept as text, and the test reads the tick
labels back from it (matplotlib's log ticks are ``$\\mathdefault{10^{1}}$`` strings, which the shared
style does not parse as math: drawn as they are, they print raw).
"""

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from conftest import vlp

SVG = "{http://www.w3.org/2000/svg}"


def tick_labels(svg: Path) -> dict[str, list[str]]:
    """The text of every tick label in a matplotlib SVG, by axis ("x", "y"), in drawing order."""
    labels: dict[str, list[str]] = {"x": [], "y": []}
    for group in ET.parse(svg).getroot().iter(f"{SVG}g"):
        gid = group.get("id", "")
        if gid.startswith(("xtick_", "ytick_")):
            labels[gid[0]] += ["".join(t.itertext()) for t in group.iter(f"{SVG}text")]
    return labels


@pytest.mark.slow
def test_vlp_accuracy_cdf_ticks_are_plain_numbers(tmp_path):
    svg = tmp_path / "cdf.svg"
    done = vlp("vlp-accuracy", "--trials", "1", "--tilts", "0,40", "--cdf", str(svg))
    assert done.returncode == 0, done.stderr
    labels = tick_labels(svg)
    texts = [t for t in labels["x"] + labels["y"] if t]
    assert len([t for t in labels["x"] if t]) >= 4  # two panels, each with at least two labelled ticks
    assert not [t for t in texts if "$" in t or "\\" in t], texts
    for t in texts:
        float(t.replace("\u2212", "-"))  # every label reads as a number (matplotlib writes a real minus sign)
    every = [("".join(t.itertext())) for t in ET.parse(svg).getroot().iter(f"{SVG}text")]
    assert "positioning error [cm]" in every and not [t for t in every if "mathdefault" in t]


def test_the_tick_reader_sees_raw_mathtext(tmp_path):
    """The check above can fail: a log axis drawn with matplotlib's own ticks under the shared style."""
    import matplotlib.pyplot as plt

    from planner.plot_style import save_png, styled

    @styled
    def draw(path):
        fig, ax = plt.subplots()
        ax.plot([0.5, 50], [0, 1])
        ax.set_xscale("log")
        save_png(fig, path, "svg")

    draw(tmp_path / "raw.svg")
    assert any("mathdefault" in t for t in tick_labels(tmp_path / "raw.svg")["x"])
