import numpy as np
import pytest
from matplotlib.path import Path as PolygonPath
from scipy.spatial import cKDTree

from planner.errors import InputError
from planner.layout.model import Layout, Luminaire, check_layout, fill_outline


def lums(points, radius=0.1):
    return tuple(Luminaire(f"L{k}", x, y, 2.5, radius) for k, (x, y) in enumerate(points))


def test_check_accepts_a_plain_grid():
    layout = Layout(lums([(0, 0), (1, 0), (0, 1)]), source_path="x.yaml")
    assert check_layout(layout, expected=3) is layout


@pytest.mark.parametrize("points,expected,message", [
    ([(0, 0), (1, 0)], None, "only 2 luminaire"),
    ([(0, 0), (1, 0), (2, 0)], 4, "found 3 luminaires but `leds` says 4"),
    ([(0, 0), (1, 0), (1.15, 0)], None, "closer than their diameters"),
])
def test_check_rejects_bad_layouts_with_one_clear_line(points, expected, message):
    with pytest.raises(InputError) as err:
        check_layout(Layout(lums(points), source_path="site.dxf"), expected=expected)
    assert message in str(err.value)
    assert str(err.value).startswith("site.dxf")
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("x,z,radius", [(1e6, 2.5, 0.1), (-2e4, 2.5, 0.1), (0, 1e308, 0.1), (0, -1, 0.1),
                                         (0, 0, 0.1), (0, 2.5, 50.0)])
def test_luminaires_no_building_holds_are_refused(x, z, radius):
    odd = Luminaire("odd one", x, 0.0, z, radius)
    with pytest.raises(InputError) as err:
        check_layout(Layout(lums([(100, 100), (101, 100), (100, 101)]) + (odd,), source_path="site.dxf"))
    assert str(err.value).startswith("site.dxf: luminaire 'odd one'") and "outside what a building holds" in str(err.value)


def test_duplicate_names_are_refused():
    layout = Layout(tuple(Luminaire("A", x, 0, 2.5) for x in (0, 1, 2)), source_path="s.csv")
    with pytest.raises(InputError, match="'A' is used more than once"):
        check_layout(layout)


def test_fill_rectangle_uses_the_widest_spacing():
    outline = np.array([[0, 0], [16, 0], [16, 8], [0, 8]], dtype=float)
    placed, description = fill_outline(outline, 512, 2.5)
    xy = np.array([(p.x, p.y) for p in placed])
    assert len(placed) == 512
    assert "32 x 16 lattice" in description
    d, _ = cKDTree(xy).query(xy, k=2)
    assert np.allclose(d[:, 1], 0.5)
    assert xy.min() == pytest.approx(0.25) and xy[:, 0].max() == pytest.approx(15.75)


def test_fill_l_shaped_room_stays_inside_and_is_exact():
    outline = np.array([[0, 0], [10, 0], [10, 5], [5, 5], [5, 10], [0, 10]], dtype=float)
    placed, _ = fill_outline(outline, 30, 3.0)
    xy = np.array([(p.x, p.y) for p in placed])
    assert len(placed) == 30 and len({p.name for p in placed}) == 30
    assert PolygonPath(outline).contains_points(xy).all()
    assert all(p.z == 3.0 for p in placed)


def test_fill_rotated_room_aligns_to_the_walls():
    angle = np.radians(30)
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    outline = np.array([[0, 0], [12, 0], [12, 6], [0, 6]], dtype=float) @ rot.T
    placed, description = fill_outline(outline, 18, 2.5)
    xy = np.array([(p.x, p.y) for p in placed])
    assert "30.0 deg" in description
    d, idx = cKDTree(xy).query(xy, k=2)
    v = xy[idx[:, 1]] - xy
    ang = np.degrees(np.arctan2(v[:, 1], v[:, 0])) % 90
    assert np.allclose(ang, 30, atol=1e-6)


def test_fill_refuses_too_few():
    with pytest.raises(InputError, match="at least 3"):
        fill_outline(np.array([[0, 0], [1, 0], [1, 1]], dtype=float), 2, 2.5)


def test_the_atomic_writer_leaves_the_old_file_on_failure_and_no_temporary_file(tmp_path):
    from planner._files import write_atomically, write_text_atomically

    target = tmp_path / "plan.yaml"
    write_text_atomically(target, "old\n")

    def fail(tmp):
        tmp.write_text("half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_atomically(target, fail)
    assert target.read_text() == "old\n" and [p.name for p in tmp_path.iterdir()] == ["plan.yaml"]
    write_text_atomically(target, "new\n")
    assert target.read_text() == "new\n" and oct(target.stat().st_mode & 0o777) == oct(0o666 & ~_umask())


def _umask() -> int:
    import os

    mask = os.umask(0)
    os.umask(mask)
    return mask
