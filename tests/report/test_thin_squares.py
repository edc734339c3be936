"""Maps built from few poses say so: squares of the coverage and error maps holding fewer than THIN_POSES
poses are hatched and the legend names them; the squares grow until a typical one holds enough."""

from types import SimpleNamespace

import matplotlib
import numpy as np

from planner.plot_style import RC
from planner.positioning.accuracy import ERROR_CELL_POSES, SiteAccuracy
from planner.positioning.error_terms import DEFAULT_TERMS
from planner.report.maps import THIN_POSES, coverage_figure, error_figure

matplotlib.use("Agg")


def hatched_squares(ax) -> list[tuple[float, float]]:
    """Lower-left corners [m] of the squares an axes hatches."""
    return [tuple(np.round(p.vertices.min(axis=0), 6)) for c in ax.collections if c.get_hatch()
            for p in c.get_paths()]


def legend_texts(fig) -> list[str]:
    return [t.get_text() for legend in fig.legends for t in legend.get_texts()]


def _error_plan(position, error_m, cell_m):
    acc = SiteAccuracy("perspective", DEFAULT_TERMS, position, error_m, cell_m)
    layout = SimpleNamespace(xy=np.array([[1.0, 1.0], [9.0, 9.0]]), source_path="site.yaml")
    return SimpleNamespace(accuracy=acc, layout=layout)


def test_error_map_hatches_the_square_with_few_located_poses():
    rng = np.random.default_rng(1)
    position = np.column_stack([rng.uniform(0, 10, 800), rng.uniform(0, 10, 800), np.full(800, 1.2)])
    error = rng.uniform(0.01, 0.05, 800)
    corner = (position[:, 0] > 7.5) & (position[:, 1] > 7.5)
    error[np.flatnonzero(corner)[3:]] = np.nan  # the top-right square: 3 located poses
    with matplotlib.rc_context(RC):
        fig = error_figure(_error_plan(position, error, 2.5))
        fig.canvas.draw()
    assert [hatched_squares(ax) for ax in fig.axes[:2]] == [[(7.5, 7.5)]] * 2  # median and 90th percentile
    assert legend_texts(fig) == [f"fewer than {THIN_POSES} located poses in the square: too few to read alone"]
    assert "median 50 a square" in fig._suptitle.get_text()  # 800 poses over 16 squares


def test_error_map_of_enough_poses_hatches_nothing():
    rng = np.random.default_rng(2)
    position = np.column_stack([rng.uniform(0, 10, 800), rng.uniform(0, 10, 800), np.full(800, 1.2)])
    with matplotlib.rc_context(RC):
        fig = error_figure(_error_plan(position, rng.uniform(0.01, 0.05, 800), 2.5))
    assert [hatched_squares(ax) for ax in fig.axes[:2]] == [[], []] and fig.legends == []


def test_error_map_squares_hold_enough_sampled_poses(grid32_plan):
    """The squares site_accuracy chooses hold ERROR_CELL_POSES sampled poses on average (were about 8): grid-32's
    error map at 4 poses per m2."""
    p = grid32_plan
    assert p.accuracy is not None
    assert p.accuracy.cell_m ** 2 * 4.0 >= ERROR_CELL_POSES
    *_, count = p.accuracy.cells()
    assert count.sum() == np.isfinite(p.accuracy.error_m).sum()  # every located pose in one square


def _verification(position: np.ndarray):
    """What coverage_figure reads of a Verification: every pose decodable."""
    from planner.verify.verify import DECODABLE

    status = np.full(len(position), DECODABLE)
    return SimpleNamespace(position=position, status=status, poses=len(position), coverage=1.0, count=lambda s: 0)


def test_coverage_map_grows_its_squares_for_a_sparse_sample_and_hatches_thin_ones():
    rng = np.random.default_rng(3)
    xy = np.array([[0.0, 0.0], [8.0, 8.0]])
    sparse = np.column_stack([rng.uniform(0, 8, 256), rng.uniform(0, 8, 256), np.full(256, 1.2)])  # 4 per m2
    with matplotlib.rc_context(RC):
        fig = coverage_figure(_verification(sparse), xy, "site.yaml")
    side = float(fig.axes[0].get_title().rsplit("; ", 1)[1].split(" m squares")[0])
    assert side >= 2.0  # 4 poses per m2: 20 poses need 5 m2 squares at least
    dense = np.column_stack([rng.uniform(0, 8, 25600), rng.uniform(0, 8, 25600), np.full(25600, 1.2)])
    with matplotlib.rc_context(RC):
        fig = coverage_figure(_verification(dense), xy, "site.yaml")
    assert fig.axes[0].get_title().endswith("; 0.25 m squares")  # 400 per m2: 25 a square
    assert hatched_squares(fig.axes[0])  # the margin squares a few poses reach are hatched...
    assert any("fewer than" in t for t in legend_texts(fig))  # ...and the legend says why
