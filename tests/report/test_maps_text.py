"""The maps an installer reads: every text inside the canvas, no region label over an ID, and odd/even
classes drawn only under the paper's scheme (text boxes of the rendered figures, not only PNGs)."""

import matplotlib
import numpy as np
import pytest

from conftest import ROOT
from planner.layout.read import read_layout
from planner.plan.pipeline import PlanOptions, make_plan
from planner.plot_style import RC
from planner.report.maps import coverage_figure, map_figure

matplotlib.use("Agg")


def _boxes(fig):
    """(text, window box, gid) of every drawn text: axes (ticks, labels, titles) via their tight boxes."""
    from matplotlib.text import Text

    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    ticks = {id(t) for ax in fig.axes for t in ax.get_xticklabels() + ax.get_yticklabels()}
    out = [(f"axes {k}", ax.get_tightbbox(r), None) for k, ax in enumerate(fig.axes)]
    for t in fig.findobj(Text):
        if id(t) in ticks or not t.get_visible() or not t.get_text().strip():
            continue
        patch = t.get_bbox_patch()
        out.append((t.get_text(), (patch or t).get_window_extent(r), t.get_gid()))
    return out


def _check(fig) -> list:
    boxes = _boxes(fig)
    canvas = fig.bbox
    for text, b, _ in boxes:
        assert (b.x0 >= canvas.x0 - 0.5 and b.y0 >= canvas.y0 - 0.5 and b.x1 <= canvas.x1 + 0.5
                and b.y1 <= canvas.y1 + 0.5), f"{text!r} leaves the canvas: {b} vs {canvas}"
    ids = [b for _, b, gid in boxes if gid == "id"]
    for text, b, gid in boxes:
        if gid == "region":
            assert not any(b.overlaps(i) for i in ids), f"region label {text} covers an ID"
    return boxes


@pytest.fixture(scope="module")
def plans(grid32_plan):
    def plan(name, leds=None, **kw):
        return make_plan(read_layout(ROOT / "layouts" / name, leds), PlanOptions(**{"error_poses_per_m2": 0, **kw}))

    return {"grid-32": grid32_plan,  # with its error map, planned once per worker (conftest)
            "grid-32 paper": plan("grid-32.yaml", scheme="paper"),
            "office": plan("dialux-office.dxf"),
            "grid-512 paper": plan("grid-512.yaml", 512, scheme="paper", verify=False)}


@pytest.mark.parametrize("name", ["grid-32", "grid-32 paper", "office", "grid-512 paper"])
def test_map_text_stays_inside_and_off_the_ids(plans, name):
    p = plans[name]
    with matplotlib.rc_context(RC):
        boxes = _check(map_figure(p))
        if p.verification is not None:
            _check(coverage_figure(p.verification, p.layout.xy, name))
    ids = [t for t, _, gid in boxes if gid == "id"]
    assert len(ids) == len(p.layout.luminaires)  # every ID is written
    assert sum(gid == "region" for *_, gid in boxes) == int(p.assignment.regions.max()) + 1
    classes = [t for t, *_ in boxes if "odd class" in t or "even class" in t]
    assert (len(classes) == 2) == (p.assignment.scheme == "paper")


def test_coverage_map_of_the_512_grid_keeps_its_legend(plans):
    """The 512 grid's coverage map (its legend was cut off at the bottom), from a coarse verification."""
    from planner.verify.verify import verify_plan

    p = plans["grid-512 paper"]
    radii = [lum.radius for lum in p.layout.luminaires]
    v = verify_plan(p.layout.xyz, np.array(radii), p.assignment.ids, p.layout.outline, p.camera,
                    per_m2=5.0)
    with matplotlib.rc_context(RC):
        boxes = _check(coverage_figure(v, p.layout.xy, "grid-512.yaml: paper scheme"))
    assert any(t == "luminaire" for t, *_ in boxes)  # the legend entry, inside the canvas


def test_window_scheme_draws_no_odd_even_classes(plans):
    p = plans["grid-32"]
    assert p.assignment.scheme == "window"
    with matplotlib.rc_context(RC):
        fig = map_figure(p)
        fills = {tuple(c) for coll in fig.axes[0].collections[2:] for c in coll.get_facecolors()}
    assert fills == {(1.0, 1.0, 1.0, 1.0)}  # every luminaire drawn alike: the classes mean nothing here


def test_report_figures_keep_their_text_inside(plans):
    """The error map, the frame timing and the walking route of the site report."""
    from planner.plan.file import plan_from_document
    from planner.plan.model import plan_document
    from planner.report.content import walking_order
    from planner.report.figures import route_fig, timing_examples, timing_figure
    from planner.report.maps import error_figure

    p = plans["grid-32"]
    loaded = plan_from_document(plan_document(p), "grid-32")
    route, _ = walking_order(loaded.xy)
    assert p.accuracy is not None and loaded.modulation is not None
    with matplotlib.rc_context(RC):
        for fig in (error_figure(p), timing_figure(loaded.modulation, timing_examples(loaded, route)),
                    route_fig(loaded, route)):
            assert len(_check(fig)) > len(fig.axes)  # titles, labels and legends were checked, not only axes


def test_the_check_catches_clipped_text_and_covered_ids():
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(3, 2), layout="constrained")
    ax.text(0.5, 0.5, "12", gid="id", transform=ax.transAxes)
    ax.text(0.5, 0.5, "R0", gid="region", transform=ax.transAxes)
    with pytest.raises(AssertionError, match="covers an ID"):
        _check(fig)
    ax.texts[-1].remove()
    ax.set_title("a title far too long for a figure three inches wide, so it runs off both sides")
    with pytest.raises(AssertionError, match="leaves the canvas"):
        _check(fig)
    plt.close(fig)
