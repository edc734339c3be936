import pytest

from planner.errors import InputError
from planner.layout.tables import read_csv, read_yaml


def test_yaml_in_centimetres_is_converted_to_metres(tmp_path):
    path = tmp_path / "rig.yaml"
    path.write_text("unit: cm\nradius: 10\nluminaires:\n- {name: N, x: 0, y: 30, z: 250}\n- {x: 50, y: 0}\n")
    layout = read_yaml(path, mount_height_m=2.4)
    a, b = layout.luminaires
    assert (a.name, a.x, a.y, a.z, a.radius) == ("N", 0.0, 0.3, 2.5, pytest.approx(0.1))
    assert (b.name, b.z) == ("L0002", 2.4)
    assert layout.unit == "cm" and layout.unit_reason == "stated in the file"


def test_yaml_units_flag_overrides(tmp_path):
    path = tmp_path / "a.yaml"
    path.write_text("unit: m\nluminaires:\n- {x: 1000, y: 2000}\n")
    layout = read_yaml(path, units="mm")
    assert (layout.luminaires[0].x, layout.luminaires[0].y) == (1.0, 2.0)
    assert layout.unit_reason == "given with --units"


def test_yaml_outline_only(tmp_path):
    path = tmp_path / "room.yaml"
    path.write_text("outline: [[0, 0], [4, 0], [4, 3]]\n")
    layout = read_yaml(path)
    assert layout.luminaires == () and layout.outline == ((0, 0), (4, 0), (4, 3))


@pytest.mark.parametrize("text,message", [
    ("luminaires:\n- {x: 1}\n", "luminaires[0].y: is missing"),
    ("luminaires:\n- {x: 1, y: two}\n", "luminaires[0].y: must be a valid number (got 'two')"),
    ("luminaires:\n- {x: 1, y: 2, colour: red}\n", "luminaires[0].colour: unknown field; allowed: name, x, y, z, radius"),
    ("unit: furlong\nluminaires: []\n", "unknown unit 'furlong'"),
    ("- 1\n- 2\n", "expected a mapping"),
    ("luminaires: [\n", "not valid YAML"),
])
def test_yaml_errors_name_the_place(tmp_path, text, message):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        read_yaml(path)
    assert message in str(err.value) and str(err.value).startswith(str(path))


@pytest.mark.parametrize("row,message", [
    ("{x: true, y: 0}", "luminaires[0].x: must be a valid number (got True)"),
    ("{x: '1', y: 0}", "luminaires[0].x: must be a valid number (got '1')"),
    ("{x: 0, y: 0, name: [a, b]}", "luminaires[0].name: must be a valid string (got ['a', 'b'])"),
    ("{x: 0, y: 0, name: 123}", "luminaires[0].name: must be a valid string (got 123)"),
    ("{x: 0, y: 0, z: -1}", "luminaires[0].z: must be greater than 0 (got -1)"),
    ("{x: 0, y: 0, radius: 0}", "luminaires[0].radius: must be greater than 0 (got 0)"),
    ("{x: .nan, y: 0}", "luminaires[0].x: must be a finite number"),
])
def test_yaml_type_confusions_are_refused_by_field(tmp_path, row, message):
    """Wrong types and impossible values no longer pass as numbers or names (issue 15's "accepted as if
    they made sense"): each is named by its field path."""
    path = tmp_path / "bad.yaml"
    path.write_text(f"luminaires:\n- {row}\n")
    with pytest.raises(InputError) as err:
        read_yaml(path)
    assert str(err.value).startswith(f"{path}: {message}")


@pytest.mark.parametrize("text,message", [
    ("outline: [[0, 0, 0], [1, 0], [1, 1]]\n", "outline[0]: must have at most 2 items, not 3"),
    ("outline: [[0, 0], [1, 0]]\n", "outline: needs at least 3 points, got 2"),
    ("luminaires: {x: 1}\n", "luminaires: must be a valid list"),
    ("height: true\nluminaires: []\n", "height: must be a valid number (got True)"),
])
def test_yaml_top_level_fields_are_checked(tmp_path, text, message):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        read_yaml(path)
    assert message in str(err.value)


def test_csv_cells_are_numbers_or_refused(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("x,y,z\n0,0,2.5\n1,0,true\n")
    with pytest.raises(InputError, match=r"bad.csv: line 3: z: must be a valid number"):
        read_csv(path)
    path.write_text("x,y\n0,0\ninf,0\n")
    with pytest.raises(InputError, match=r"bad.csv: line 3: x: must be a finite number"):
        read_csv(path)


def test_csv_with_unit_comment_and_defaults(tmp_path):
    path = tmp_path / "site.csv"
    path.write_text("# unit: mm\nname,x,y\nA,0,0\nB,1200,0\n\nC,0,1200\n")
    layout = read_csv(path)
    assert [(p.name, p.x, p.y, p.z, p.radius) for p in layout.luminaires] == [
        ("A", 0, 0, 2.5, 0.1), ("B", 1.2, 0, 2.5, 0.1), ("C", 0, 1.2, 2.5, 0.1)]
    assert layout.luminaires[2].source == {"file": "site.csv", "line": 6}  # real file lines


def test_csv_errors_give_the_line(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("# a comment\nx,y\n1,2\n3,oops\n")
    with pytest.raises(InputError, match=r"bad.csv: line 4: y: must be a valid number"):
        read_csv(path)
    path.write_text("a,b\n1,2\n")
    with pytest.raises(InputError, match="header must name columns x and y"):
        read_csv(path)
