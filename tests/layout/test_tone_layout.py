"""A layout's tones (``tone_hz``): read in hertz whatever the length unit, all or none, within the flicker limit;
every refusal one line naming the file and the field (docs/layout-files.md, docs/tones.md)."""

import numpy as np
import pytest

from planner.errors import InputError
from planner.layout.read import read_layout


def _yaml(tmp_path, body: str, name: str = "site.yaml"):
    path = tmp_path / name
    path.write_text(body)
    return path


def test_yaml_tones_are_read_in_hertz_in_any_unit(tmp_path):
    path = _yaml(tmp_path, "unit: cm\nluminaires:\n- {x: 0, y: 0, tone_hz: 2000}\n- {x: 60, y: 0, tone_hz: 2500.5}\n"
                           "- {x: 0, y: 60, tone_hz: 3000}\n")
    layout = read_layout(path, None)
    assert layout.tones_hz is not None
    np.testing.assert_array_equal(layout.tones_hz, [2000.0, 2500.5, 3000.0])
    assert [lum.x for lum in layout.luminaires] == [0.0, 0.6, 0.0]  # lengths scaled, tones not


def test_csv_tone_column(tmp_path):
    path = tmp_path / "site.csv"
    path.write_text("name,x,y,tone_hz\nA,0,0,2000\nB,1,0,2500\nC,0,1,3000\n")
    np.testing.assert_array_equal(read_layout(path, None).tones_hz, [2000, 2500, 3000])


def test_a_site_without_tones_has_none(tmp_path):
    path = _yaml(tmp_path, "luminaires:\n- {x: 0, y: 0}\n- {x: 1, y: 0}\n- {x: 0, y: 1}\n")
    layout = read_layout(path, None)
    assert layout.tones_hz is None
    assert all(lum.tone_hz is None for lum in layout.luminaires)


def test_mixed_site_is_refused_naming_a_luminaire_without_tone(tmp_path):
    path = _yaml(tmp_path, "luminaires:\n- {name: A, x: 0, y: 0, tone_hz: 2000}\n- {name: B, x: 1, y: 0}\n"
                           "- {name: C, x: 0, y: 1, tone_hz: 3000}\n")
    with pytest.raises(InputError) as exc:
        read_layout(path, None)
    text = str(exc.value)
    assert text.startswith(f"{path}: luminaire 'B' has no tone_hz but 2 of the 3 luminaires carry one")
    assert "or none" in text and "\n" not in text


@pytest.mark.parametrize("value, words", [
    ("150", "tone_hz: 150 Hz is below the flicker limit of 200 Hz"),
    ("0", "tone_hz: must be greater than 0"),
    ("-2000", "tone_hz: must be greater than 0"),
    (".nan", "tone_hz: must be a finite number"),
    ("'2000'", "tone_hz: must be a valid number"),
    ("true", "tone_hz: must be a valid number"),
])
def test_bad_tones_are_refused_with_the_field(tmp_path, value, words):
    path = _yaml(tmp_path, f"luminaires:\n- {{x: 0, y: 0, tone_hz: 2000}}\n- {{x: 1, y: 0, tone_hz: {value}}}\n"
                           "- {x: 0, y: 1, tone_hz: 3000}\n")
    with pytest.raises(InputError) as exc:
        read_layout(path, None)
    assert str(exc.value).startswith(f"{path}: luminaires[1].{words}")


def test_csv_bad_tone_names_its_line(tmp_path):
    path = tmp_path / "site.csv"
    path.write_text("x,y,tone_hz\n0,0,2000\n1,0,100\n0,1,3000\n")
    with pytest.raises(InputError, match=r"site.csv: line 3: tone_hz: 100 Hz is below the flicker limit"):
        read_layout(path, None)
