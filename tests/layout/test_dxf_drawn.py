"""Drawings read as the architect drew them (issue 38): tags and arrows named like lights are no lights,
columns and switches on the lighting layer are no lights, and walls drawn as many short lines give the floor.

Every drawing is built here with ezdxf, in millimetres, as electrical plans are drawn.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose

import dxf_factory as factory
from planner.layout.dxf import read_dxf, scan_dxf
from planner.layout.dxf_names import name_class
from planner.layout.model import area_m2
from planner.layout.read import read_layout

ROOM_MM = (14_400.0, 9_600.0)
"""The house's outer wall face [mm]: 138.24 m2."""

WALL_MM = 200.0
PIECE_MM = 1_200.0
"""Walls are drawn as open polylines at most this long [mm]."""


def _pieces(msp, a, b, layer="A-WALL", gap=None):
    """Draw the wall face from ``a`` to ``b`` as open two-vertex polylines of at most PIECE_MM, leaving
    out the stretch ``gap`` = (from, to) [mm along the face] (a door)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    length = float(np.hypot(*(b - a)))
    cuts = list(np.arange(0.0, length, PIECE_MM)) + [length]
    for s0, s1 in zip(cuts[:-1], cuts[1:]):
        if gap is not None:
            if s1 <= gap[0] or s0 >= gap[1]:
                pass
            elif s0 < gap[0]:
                s1 = gap[0]
            elif s1 > gap[1]:
                s0 = gap[1]
            else:
                continue
        p0, p1 = a + (b - a) * s0 / length, a + (b - a) * s1 / length
        msp.add_lwpolyline([tuple(p0), tuple(p1)], dxfattribs={"layer": layer})


def house(arrow_layer: str = "E-ANNO-TAG", walls: bool = True, column: bool = True, pitch_mm=(3600.0, 3200.0)):
    """A 14.4 m x 9.6 m house, millimetres: 12 ``CEILING LIGHT`` blocks (a 100 mm circle) on ``E-LIGHTING``,
    a ``TAG-LED-ARROW`` (a leader line, a filled arrowhead and a tag text) on ``arrow_layer`` pointing at
    one of them, switches on the lighting layer, and (``walls``) 200 mm walls drawn as both faces in open
    polylines of at most 1.2 m, a 0.9 m door in the outer wall and one in a partition, on ``A-WALL``, with
    (``column``) a 0.7 m square column as the only closed polyline there (0.49 m2: what the old reader
    took as the floor). Returns the drawing and the lights' centres [m]."""
    doc = factory.new_drawing(4, "R2013")
    for layer in {"E-LIGHTING", "A-WALL", arrow_layer} - {"0"}:
        doc.layers.add(layer)
    light = doc.blocks.new("CEILING LIGHT")
    light.add_circle((0, 0), 100)
    light.add_line((-100, -100), (100, 100))
    arrow = doc.blocks.new("TAG-LED-ARROW")
    arrow.add_line((0, 0), (600, 400))
    arrow.add_solid([(0, 0), (120, 20), (60, 90)])
    arrow.add_text("L1", height=150, dxfattribs={"insert": (650, 420)})
    doc.blocks.new("LIGHT SWITCH").add_circle((0, 0), 40)
    msp = doc.modelspace()
    w, d = ROOM_MM
    centres = []
    for j in range(3):
        for i in range(4):
            x, y = 1800 + pitch_mm[0] * i, 1600 + pitch_mm[1] * j
            msp.add_blockref("CEILING LIGHT", (x, y), dxfattribs={"layer": "E-LIGHTING"})
            msp.add_blockref("LIGHT SWITCH", (x + 900, y - 1000), dxfattribs={"layer": "E-LIGHTING"})
            centres.append((x / 1000, y / 1000))
    msp.add_blockref("TAG-LED-ARROW", (1800 + 700, 1600 + 700), dxfattribs={"layer": arrow_layer})
    if walls:
        t = WALL_MM
        door = (3000.0, 3900.0)
        _pieces(msp, (0, 0), (w, 0), gap=door)  # outer face, door in the bottom wall
        _pieces(msp, (w, 0), (w, d))
        _pieces(msp, (w, d), (0, d))
        _pieces(msp, (0, d), (0, 0))
        _pieces(msp, (t, t), (w - t, t), gap=(door[0] - t, door[1] - t))  # inner face
        _pieces(msp, (w - t, t), (w - t, d - t))
        _pieces(msp, (w - t, d - t), (t, d - t))
        _pieces(msp, (t, d - t), (t, t))
        for x in door:  # door jambs
            msp.add_line((x, 0), (x, t), dxfattribs={"layer": "A-WALL"})
        mid = w / 2
        _pieces(msp, (mid, t), (mid, d - t), gap=(4000.0, 4900.0))  # a partition with a door
        _pieces(msp, (mid + 100, t), (mid + 100, d - t), gap=(4000.0, 4900.0))
    if column:
        c = 700.0
        msp.add_lwpolyline([(w - 2500, 2500), (w - 2500 + c, 2500), (w - 2500 + c, 2500 + c), (w - 2500, 2500 + c)],
                           close=True, dxfattribs={"layer": "A-WALL"})
    return doc, np.array(sorted(centres, key=lambda p: (p[1], p[0])))


def _save(tmp_path, doc, name="house.dxf"):
    return factory.save(doc, tmp_path / name)


def test_lights_are_read_the_arrow_is_not_and_the_outline_covers_the_floor(tmp_path):
    """Done when (issue 38, Build 3): lights, an annotation arrow named like a light on an annotation layer,
    walls as many short polylines."""
    doc, centres = house()
    path = _save(tmp_path, doc)
    layout = read_dxf(path)
    assert len(layout.luminaires) == 12
    assert {lum.source["block"] for lum in layout.luminaires} == {"CEILING LIGHT"}
    assert_allclose(layout.xy, centres, atol=1e-9)
    found, _, _ = scan_dxf(path)
    rejected = {name: why for (_, name, _, why) in found.rejected}
    assert rejected["TAG-LED-ARROW"] == "block name says annotation (TAG)"
    outline = np.array(layout.outline)
    room_m2 = ROOM_MM[0] * ROOM_MM[1] / 1e6
    assert area_m2(outline) == pytest.approx(room_m2, rel=0.03)  # not the 0.49 m2 column
    assert_allclose(outline.min(axis=0), (0, 0), atol=0.05)
    assert_allclose(outline.max(axis=0), np.array(ROOM_MM) / 1000, atol=0.05)
    assert any("floor enclosed by" in note and "wall line(s)" in note for note in layout.notes)


@pytest.mark.parametrize("layer", ["E-ANNO-TAG", "0", "E-LIGHTING", "G-ANNO-SYMB", "E-LITE-TEXT", "A-DIM"])
def test_the_arrow_is_no_light_on_any_layer(tmp_path, layer):
    """The tag word in the name, the annotation layer or the drawing (a leader and an arrowhead) says so."""
    doc, centres = house(arrow_layer=layer)
    layout = read_dxf(_save(tmp_path, doc))
    assert_allclose(layout.xy, centres, atol=1e-9)


def test_a_light_symbol_on_an_annotation_layer_is_no_light(tmp_path):
    """A legend's downlight symbol drawn on the annotation layer, or on the dimensions layer: the layer says
    what it is. On a lighting layer for dimmable lights it is a light."""
    doc, centres = house(walls=False)
    for layer in ("G-ANNO-SYMB", "A-DIM", "E-LITE-DIM"):
        doc.layers.add(layer)
    msp = doc.modelspace()
    msp.add_blockref("CEILING LIGHT", (20_000, 3000), dxfattribs={"layer": "G-ANNO-SYMB"})
    msp.add_circle((20_000, 6000), 100, dxfattribs={"layer": "A-DIM"})
    msp.add_blockref("CEILING LIGHT", (5400, 8000 + 3200), dxfattribs={"layer": "E-LITE-DIM"})
    path = _save(tmp_path, doc)
    layout = read_dxf(path)
    assert_allclose(layout.xy, np.vstack([centres, [(5.4, 11.2)]]), atol=1e-9)
    found, _, _ = scan_dxf(path)
    assert found.rejected[("INSERT", "CEILING LIGHT", "G-ANNO-SYMB", "layer says annotation (ANNO)")] == 1
    assert found.rejected[("CIRCLE", "", "A-DIM", "layer says annotation (DIM)")] == 1


@pytest.mark.parametrize(("name", "what"), [
    ("TAG-LED-ARROW", "annotation"), ("LIGHT TAG", "annotation"), ("LED-LABEL-A", "annotation"),
    ("LIGHTING ANNOTATION", "annotation"), ("LED PANEL DIM", "luminaire"), ("DOWNLIGHT WITH TAG", "luminaire"),
])
def test_annotation_words_anywhere_in_the_head_say_annotation(name, what):
    assert name_class(name)[0] == what


def test_blocks_that_draw_only_text_or_a_leader_are_no_lights(tmp_path):
    """Named like lights, on the lighting layer, but drawn as a tag text or an arrow: annotation."""
    doc, centres = house(walls=False)
    tag = doc.blocks.new("LIGHT TYPE A")
    tag.add_attdef("TYPE", (0, 0), dxfattribs={"height": 150})
    tag.add_text("A", height=150)
    pointer = doc.blocks.new("LED POINTER")
    pointer.add_lwpolyline([(0, 0, 0, 80), (200, 0, 80, 0)], format="xyse")  # a tapered arrowhead
    pointer.add_line((200, 0), (800, 0))
    msp = doc.modelspace()
    for k in range(3):
        msp.add_blockref("LIGHT TYPE A", (2400 + 3600 * k, 2400), dxfattribs={"layer": "E-LIGHTING"})
        msp.add_blockref("LED POINTER", (1000 + 3600 * k, 4000), dxfattribs={"layer": "E-LIGHTING"})
    path = _save(tmp_path, doc)
    assert_allclose(read_dxf(path).xy, centres, atol=1e-9)
    found, _, _ = scan_dxf(path)
    rejected = {name: (n, why) for (_, name, _, why), n in found.rejected.items()}
    assert rejected["LIGHT TYPE A"] == (3, "block draws only text, leaders or arrowheads")
    assert rejected["LED POINTER"] == (3, "block draws only text, leaders or arrowheads")


def test_a_block_with_a_circle_and_a_label_is_still_a_light(tmp_path):
    doc, centres = house(walls=False)
    doc.blocks.get("CEILING LIGHT").add_text("L", height=100)
    assert_allclose(read_dxf(_save(tmp_path, doc)).xy, centres, atol=1e-9)


def test_the_48_luminaire_office_reads_as_its_48_luminaires(tmp_path):
    """Switch and column blocks on the lighting layer are no lights, without --leds to choose a group."""
    doc, centres = factory.office_48()
    path = _save(tmp_path, doc, "office.dxf")
    layout = read_dxf(path)
    assert len(layout.luminaires) == 48 and layout.unit == "mm"
    assert_allclose(layout.xy, centres, atol=1e-9)
    assert_allclose([lum.z for lum in layout.luminaires], 2.8)
    found, _, _ = scan_dxf(path)
    rejected = {name: (n, why) for (_, name, _, why), n in found.rejected.items()}
    assert rejected["COLUMN"] == (8, "block name says building element (COLUMN)")
    assert rejected["COL-2"] == (1, "block name says building element (COL)")
    assert rejected["SWITCH 2G"][0] == 4
    assert len(read_layout(path, 48).luminaires) == 48


def test_no_walls_means_the_luminaires_own_extent_and_the_notes_say_so(tmp_path):
    doc, _ = house(walls=False, column=False)
    layout = read_dxf(_save(tmp_path, doc))
    assert layout.outline is None
    assert any("none found on wall/room layers; poses are sampled over the luminaires' own extent "
               "(their convex hull, 69.1 m2)" in note for note in layout.notes)


def test_an_outline_that_holds_few_luminaires_is_no_floor(tmp_path):
    """The old reader's residential failure: a 0.49 m2 column was the floor and 12 lights lay outside it."""
    doc, _ = house(walls=False, column=True)
    layout = read_dxf(_save(tmp_path, doc))
    assert layout.outline is None
    assert any("the outline found (0.5 m2) holds only 0 of 12 luminaires, so it is no floor: poses are sampled "
               "over the luminaires' own extent" in note for note in layout.notes)


def test_walls_open_wider_than_any_door_enclose_nothing():
    from planner.layout.outline import floor_outline

    lines = [[(0, 0), (10, 0)], [(10, 0), (10, 3)], [(0, 0), (0, 3)]]  # a U open 10 m wide
    outline, notes = floor_outline([], lines=lines)
    assert outline is None and notes == ["room outline: 3 wall line(s) enclose no floor (open wider than 2.4 m)"]


def test_vlp_plan_samples_poses_over_the_floor_the_walls_enclose(tmp_path, capsys):
    from planner.cli.plan import main

    doc, centres = house(pitch_mm=(1200.0, 1200.0))  # close enough for the camera to see three
    out = tmp_path / "out"
    code = main([str(_save(tmp_path, doc)), "--height", "2.7", "-o", str(out), "--json", "--no-map", "--no-report",
                 "--no-firmware", "--scheme", "unique", "--poses-per-m2", "5", "--error-poses-per-m2", "0"])
    summary = json.loads(capsys.readouterr().out)
    assert code in (0, 3) and summary["luminaires"] == 12
    assert any("floor enclosed by" in note for note in summary["notes"])
    plan = yaml.safe_load((out / "plan.yaml").read_text())
    floor_m2 = area_m2(np.array(plan["outline"]))
    assert floor_m2 == pytest.approx(138.24, rel=0.03)
    assert summary["verification"]["poses"] == round(5 * floor_m2)  # sampled over the floor, not the lights' hull
    xy = np.array([(e["x"], e["y"]) for e in plan["luminaires"]])
    assert_allclose(xy, centres, atol=1e-6)


def test_vlp_inspect_counts_the_wall_lines(tmp_path, capsys):
    from planner.cli.inspect import main

    doc, _ = house()
    path = _save(tmp_path, doc)
    assert main([str(path)]) == 0
    assert "outlines 1 closed polyline(s) and 98 open line(s) on wall/room layers: A-WALL" in capsys.readouterr().out
    assert main([str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["wall_lines"] == 98


def test_a_room_chosen_with_room_stays_whatever_it_holds(tmp_path):
    path = factory.save(factory.multi_room_floor(), tmp_path / "floor.dxf")
    layout = read_dxf(path, room="OFFICE 2")  # 8 of the 24 downlights are in it
    assert area_m2(np.array(layout.outline)) == pytest.approx(70.0)
    assert any("luminaires lie more than 0.5 m outside the room outline" in n for n in layout.notes)
    assert not any("own extent" in n for n in layout.notes)
