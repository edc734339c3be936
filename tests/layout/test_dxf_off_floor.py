"""Luminaire symbols drawn off the floor (a legend, a title block) are not luminaires of the room."""

from __future__ import annotations

import json

import ezdxf

from conftest import vlp


def _drawing(path, extra: list[tuple[float, float]]) -> str:
    """A 10 m room on A-WALL, 16 downlights 2.5 m apart inside it, and ``extra`` downlights elsewhere [m]."""
    doc = ezdxf.new()
    doc.header["$INSUNITS"] = 6
    msp = doc.modelspace()
    doc.blocks.new("DOWNLIGHT").add_circle((0, 0), 0.1)
    msp.add_lwpolyline([(0, 0), (10, 0), (10, 10), (0, 10)], close=True, dxfattribs={"layer": "A-WALL"})
    inside = [(1.25 + 2.5 * i, 1.25 + 2.5 * j) for i in range(4) for j in range(4)]
    for at in inside + extra:
        msp.add_blockref("DOWNLIGHT", at, dxfattribs={"layer": "E-LIGHTING"})
    msp.add_text("LEGEND: DOWNLIGHT 15 W", dxfattribs={"layer": "E-LIGHTING"}).set_placement((13.5, 2))
    doc.saveas(path)
    return str(path)


def _inspect(path: str, *flags: str) -> dict:
    done = vlp("vlp-inspect", path, "--json", *flags)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_a_legend_symbol_is_left_out_and_said(tmp_path):
    found = _inspect(_drawing(tmp_path / "legend.dxf", [(13.0, 2.0)]))
    assert found["luminaires"] == 16
    note = next(n for n in found["notes"] if n.startswith("left out"))
    assert "1 luminaire symbol(s)" in note and "(13.00, 2.00)" in note and "--leds 17" in note


def test_leds_that_count_it_keep_it(tmp_path):
    found = _inspect(_drawing(tmp_path / "legend.dxf", [(13.0, 2.0)]), "--leds", "17")
    assert found["luminaires"] == 17
    assert any("kept, as --leds 17 counts them" in n for n in found["notes"])


def test_a_luminaire_at_the_wall_is_kept(tmp_path):
    found = _inspect(_drawing(tmp_path / "wall.dxf", [(10.3, 5.0)]))  # 0.3 m past the wall line: a drawing slip
    assert found["luminaires"] == 17 and not any("outside the room" in n for n in found["notes"])


def test_many_outside_mean_the_outline_is_incomplete(tmp_path):
    next_room = [(11.25 + 2.5 * i, 1.25 + 2.5 * j) for i in range(2) for j in range(2)]
    found = _inspect(_drawing(tmp_path / "rooms.dxf", next_room))
    assert found["luminaires"] == 20
    assert any("4 of 20 luminaires lie more than 0.5 m outside" in n and "kept" in n for n in found["notes"])
