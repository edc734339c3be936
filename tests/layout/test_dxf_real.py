"""Regression tests of issue 16: drawings as integrators have them, each failure the reader had on real exports.

Every drawing is built with ezdxf here (tests/dxf_factory.py); each one is read through
``read_layout`` (the reader and every layout check vlp-plan applies) with the right count,
positions in metres and heights.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

import dxf_factory as factory
from planner.errors import InputError
from planner.layout.dxf import read_dxf
from planner.layout.dxf_names import LIGHT_WORDS, LUMINAIRE, NEUTRAL, name_class, words
from planner.layout.model import area_m2
from planner.layout.read import ReadOptions, read_layout


def _save(tmp_path, doc, name="site.dxf"):
    return factory.save(doc, tmp_path / name)


# --- names are words ----------------------------------------------------------------------

@pytest.mark.parametrize(("name", "what"), [
    ("COLUMN", NEUTRAL), ("_ClosedFilled", NEUTRAL), ("A-FLOR-TILED", NEUTRAL), ("SATELLITE", NEUTRAL),
    ("CLAMP", NEUTRAL), ("E-LITE", LUMINAIRE), ("E-LITE-EMER", LUMINAIRE), ("DLX_BLD1_FL0_LUM 1", LUMINAIRE),
    ("Downlight - 150mm", LUMINAIRE), ("DownLight2", LUMINAIRE), ("LED PANEL 600", LUMINAIRE),
    ("LIGHT POINT CONTROLLED BY TWO WAY SWITCH", LUMINAIRE), ("E-LITE-SWCH", "switch"),
    ("Lighting Switch", "switch"), ("TWO WAY SWITCH", "switch"), ("CEILING FAN", "fan"),
    ("CEILING FAN WITH LIGHT", "fan"), ("SOCKET 6A", "socket"), ("PIR SENSOR", "sensor"),
    ("EXIT SIGN", "exit sign"), ("EMERGENCY EXIT LIGHT", "exit sign"), ("WALL LIGHT", "wall light"),
    ("CEILINGLIGHT", LUMINAIRE), ("LightFixture-A", LUMINAIRE), ("LEDPANEL600", LUMINAIRE), ("SKYLIGHT", NEUTRAL),
    ("LEDGE", NEUTRAL), ("LIGHTSWITCH", "switch"), ("EXHAUSTFAN", "fan"), ("WALLLIGHT", "wall light"),
    ("WALL MOUNTED LIGHT", "wall light"), ("FLOOR LAMP", "floor or table lamp"), ("E-LITE-CIRC", "annotation"),
])
def test_names_are_matched_as_words(name, what):
    assert name_class(name)[0] == what


_NEUTRAL_WORDS = st.sampled_from(["CEILING", "OFFICE", "2X2", "TYPE", "A", "600", "RECESSED", "COLUMN", "TILED",
                                   "SATELLITE", "CLAMP", "CLOSEDFILLED", "ROOM", "SKYLIGHT", "LEDGE", "LIGHTNING"])
_SEPARATORS = st.sampled_from([" ", "-", "_", "."])


@settings(max_examples=200, deadline=None)
@given(before=st.lists(_NEUTRAL_WORDS, max_size=3), light=st.sampled_from(sorted(LIGHT_WORDS)),
       device=st.sampled_from(["SWITCH", "FAN", "SOCKET", "SENSOR", "DIMMER"]), sep=_SEPARATORS,
       tail=st.lists(_NEUTRAL_WORDS, max_size=2))
def test_the_last_device_word_of_the_head_decides(before, light, device, sep, tail):
    assert name_class(sep.join(before + [light] + tail))[0] == LUMINAIRE
    assert name_class(sep.join(before + [light, device] + tail))[0] != LUMINAIRE  # LIGHT SWITCH is a switch
    assert name_class(sep.join(before + [light, "CONTROLLED", "BY", device] + tail))[0] == LUMINAIRE
    assert name_class(sep.join(before + tail))[0] == NEUTRAL  # words that hold LUM, LED, LITE, LAMP are not them


def test_words_split_case_digits_and_punctuation():
    assert words("DLX_BLD1_FL0_LUM 1") == ["DLX", "BLD", "1", "FL", "0", "LUM", "1"]
    assert words("DownLight-150mm") == ["DOWN", "LIGHT", "150", "MM"]


# --- the residential layout: Z noise, switches, fans, columns, two-way-switch lights -------

def test_z_noise_is_no_height_and_the_unit_check_passes(tmp_path):
    """Regression: Z of 9.9e-13 and -1.5e-4 mm was taken as a height of ~1e-16 m: every unit was refused."""
    doc, expected = factory.residential()
    layout = read_layout(_save(tmp_path, doc), 12)
    assert len(layout.luminaires) == 12 and layout.unit == "mm"
    assert_allclose(layout.xy, expected[:, :2], atol=1e-9)
    assert all(lum.z == 2.5 for lum in layout.luminaires)
    assert any("numerical noise" in note for note in layout.notes)


def test_height_flag_applies_where_z_is_noise(tmp_path):
    """Regression: --height 2.7 was ignored because the drawing's (noise) Z won."""
    doc, _ = factory.residential()
    layout = read_layout(_save(tmp_path, doc), 12, ReadOptions(units="mm", mount_height_m=2.7))
    assert [lum.z for lum in layout.luminaires] == [2.7] * 12


def test_switches_fans_and_other_devices_on_the_lighting_layer_are_not_lights(tmp_path):
    """Regression: a switch block was skipped but entered, and its two circles became two lights (31 -> 62)."""
    doc, expected = factory.residential()
    layout = read_dxf(_save(tmp_path, doc))
    assert len(layout.luminaires) == 12  # the old reader took 55 luminaires from this drawing
    assert {lum.source["block"] for lum in layout.luminaires} == {factory.LIGHT_POINT}
    assert_allclose(layout.xy, expected[:, :2], atol=1e-9)


def test_lights_controlled_by_a_switch_are_lights(tmp_path):
    doc, _ = factory.residential(cols=3, rows=2)
    layout = read_dxf(_save(tmp_path, doc))
    assert [lum.source["block"] for lum in layout.luminaires] == [factory.LIGHT_POINT] * 6


def test_a_converted_residential_file_with_metres_in_the_header(tmp_path):
    doc, expected = factory.residential(insunits=6)
    layout = read_layout(_save(tmp_path, doc), 12)
    assert layout.unit == "mm" and layout.unit_reason.startswith("$INSUNITS says metres but")
    assert_allclose(layout.xy, expected[:, :2], atol=1e-9)


def test_with_leds_the_group_of_that_many_is_used(tmp_path):
    doc, expected = factory.residential(unknown=5)
    path = _save(tmp_path, doc)
    layout = read_layout(path, 12)
    assert_allclose(layout.xy, expected[:, :2], atol=1e-9)
    assert any("'LIGHT POINT CONTROLLED BY TWO WAY SWITCH' has 12, as --leds says" in n for n in layout.notes)
    assert len(read_dxf(path).luminaires) == 17  # without --leds, the unknown symbols on the layer count too
    with pytest.raises(InputError, match=r"found 17 luminaires in 2 groups but --leds says 13.*A\$C1F2 \(5\)"):
        read_layout(path, 13)


def test_dynamic_blocks_are_classified_by_the_name_the_user_sees(tmp_path):
    """An anonymous block *U7 drawing the dynamic block TWO WAY SWITCH is a switch, not a neutral symbol
    taken because its layer (E-POWER-LIGHTING) says lighting."""
    doc, expected = factory.dynamic_blocks()
    layout = read_layout(_save(tmp_path, doc), 6)
    assert_allclose(layout.xyz, expected, atol=1e-9)
    assert {lum.source["block"] for lum in layout.luminaires} == {"CEILING LIGHT"}
    assert all(lum.source["anonymous_block"].startswith("*U") for lum in layout.luminaires)


def test_a_container_on_a_device_layer_is_searched_and_a_symbol_there_is_not(tmp_path):
    doc = factory.new_drawing(6)
    doc.blocks.new("DOWNLIGHT").add_circle((0, 0), 0.08)
    doc.blocks.new("S1").add_circle((0, 0), 0.05)  # a nameless symbol
    plan = doc.blocks.new("ELEC_PLAN")
    for k in range(4):
        plan.add_blockref("DOWNLIGHT", (2.0 * k, 0.0, 2.7))
    msp = doc.modelspace()
    msp.add_blockref("ELEC_PLAN", (0, 0), dxfattribs={"layer": "E-POWER"})  # the plan inserted on the power layer
    msp.add_blockref("S1", (1, 1), dxfattribs={"layer": "E-POWER"})
    layout = read_dxf(_save(tmp_path, doc))
    assert_allclose(layout.xyz, [(2.0 * k, 0.0, 2.7) for k in range(4)])


# --- converted DWG: metres over millimetres, circle-less symbols ---------------------------

def test_metres_header_over_millimetre_geometry_and_circle_less_symbols(tmp_path):
    """Regression: symbols without a circle got 0.1 m, so a panel and its mark 0.12 m apart were two
    luminaires that overlapped (the error named L0201/L0205)."""
    doc, expected = factory.converted_panels()
    layout = read_layout(_save(tmp_path, doc), 20)
    assert layout.unit == "mm" and "$INSUNITS says metres but" in layout.unit_reason
    assert_allclose(layout.xyz, expected, atol=1e-9)
    assert_allclose([lum.radius for lum in layout.luminaires], 0.3)  # half the 600 mm panel
    assert all(lum.source["parts"] == 2 for lum in layout.luminaires)


def test_radius_flag_wins_over_the_symbol_size_but_parts_still_merge_by_it(tmp_path):
    doc, expected = factory.converted_panels()
    layout = read_layout(_save(tmp_path, doc), 20, ReadOptions(radius_m=0.12))
    assert_allclose([lum.radius for lum in layout.luminaires], 0.12)
    assert layout.unit == "mm"  # not 40 luminaires in centimetres, as parts 0.12 m apart would give
    assert_allclose(layout.xyz, expected, atol=1e-9)


# --- the floor outline --------------------------------------------------------------------

def test_the_outline_is_the_floor_not_the_largest_room(tmp_path):
    path = _save(tmp_path, factory.multi_room_floor())
    layout = read_layout(path, 24)
    assert len(layout.luminaires) == 24
    outline = np.array(layout.outline)
    assert area_m2(outline) == pytest.approx(20.2 * 12.2)  # the largest room alone is 101 m2
    assert_allclose(outline.min(axis=0), (0, 0), atol=1e-9)
    assert_allclose(outline.max(axis=0), (20.2, 12.2), atol=1e-9)
    assert any("floor joined from 4 closed polylines" in note for note in layout.notes)


def test_a_room_chosen_by_its_name_or_layer(tmp_path):
    path = _save(tmp_path, factory.multi_room_floor())
    office = read_dxf(path, room="office 2")
    assert_allclose(np.array(office.outline).min(axis=0), (10.2, 0), atol=1e-9)
    assert area_m2(np.array(office.outline)) == pytest.approx(70.0)
    assert area_m2(np.array(read_dxf(path, room="A-WALL").outline)) == pytest.approx(20.2 * 12.2)
    with pytest.raises(InputError, match=r"--room 'LAB' matches no closed polyline.*CORRIDOR \(1\)"):
        read_dxf(path, room="LAB")


# --- vlp-plan on a real drawing -------------------------------------------------------------

def test_vlp_plan_plans_the_residential_layout(tmp_path, capsys):
    from planner.cli.plan import main

    doc, expected = factory.residential(spacing_mm=1200.0)  # close enough for the camera to see three
    out = tmp_path / "out"
    code = main([str(_save(tmp_path, doc)), "--leds", "12", "--height", "2.7", "-o", str(out), "--json", "--no-map",
                 "--no-report", "--no-firmware", "--scheme", "unique", "--poses-per-m2", "20",
                 "--error-poses-per-m2", "0"])
    summary = json.loads(capsys.readouterr().out)
    assert code in (0, 3) and summary["luminaires"] == 12 and summary["unit"] == "mm"
    plan = yaml.safe_load((out / "plan.yaml").read_text())
    xyz = np.array([(e["x"], e["y"], e["z"]) for e in plan["luminaires"]])
    assert_allclose(xyz[:, :2], expected[:, :2], atol=1e-6)
    assert_allclose(xyz[:, 2], 2.7)


def test_a_failed_drawing_read_points_to_vlp_inspect(tmp_path):
    doc, _ = factory.residential()
    path = _save(tmp_path, doc)
    with pytest.raises(InputError, match=r"found 12 luminaires but `leds` says 11.*; vlp-inspect .*site\.dxf lists"):
        read_layout(path, 11)


def test_vlp_plan_on_a_bad_drawing_is_one_line_naming_vlp_inspect(tmp_path, capsys):
    from planner.cli.plan import console_main

    doc, _ = factory.residential()
    path = _save(tmp_path, doc)
    assert console_main([str(path), "--leds", "11", "-o", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("vlp-plan: error: ") and f"vlp-inspect {path} lists" in err[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["site.dxf"]  # nothing half-written


def test_walls_drawn_as_thin_rectangles_give_the_outer_boundary_and_far_parts_are_named():
    from planner.layout.outline import floor_outline

    def rect(x0, y0, x1, y1):
        return [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]

    walls = [rect(0, 0, 12, 0.2), rect(0, 7.8, 12, 8), rect(0, 0, 0.2, 8), rect(11.8, 0, 12, 8)]
    outline, notes = floor_outline(walls + [rect(40, 0, 44, 3)])  # a shed 28 m away
    assert area_m2(np.array(outline)) == pytest.approx(96.0)
    assert_allclose(np.array(outline).max(axis=0), (12, 8), atol=1e-9)
    assert any("1 separate part(s) of 12.0 m2 left out" in note for note in notes)
    assert floor_outline([]) == (None, [])


def test_layer_patterns_do_not_bring_back_the_devices_on_that_layer(tmp_path):
    doc, expected = factory.residential()
    path = _save(tmp_path, doc)
    layout = read_dxf(path, layers=["e-lighting"])
    assert_allclose(layout.xy, expected[:, :2], atol=1e-9)  # switches, fans, sockets... on the layer stay out
    switches = read_dxf(path, blocks=["TWO WAY SWITCH"])  # a --block pattern takes what it names
    assert len(switches.luminaires) == 12 and {lum.source["block"] for lum in switches.luminaires} == {"TWO WAY SWITCH"}


def test_overlapping_luminaires_are_named_with_their_entities(tmp_path):
    """Regression: the overlap error named L0201/L0205, names that appear nowhere in the drawing."""
    doc = factory.new_drawing(6)
    for x in (0.0, 0.12, 3.0, 6.0):
        doc.modelspace().add_circle((x, 0.0, 2.7), 0.1, dxfattribs={"layer": "LIGHTING"})
    with pytest.raises(InputError, match=r"'L0001' and 'L0002' are 0\.120 m apart.*\(L0001: CIRCLE [0-9A-F]+ on "
                                         r"'LIGHTING' at \(0, 0\) m, radius 0\.1 m; L0002: CIRCLE [0-9A-F]+ on "
                                         r"'LIGHTING' at \(0\.12, 0\) m"):
        read_layout(_save(tmp_path, doc), None)
