"""Tests of the DXF reader: presets, units, merging, nesting, outline, recover, errors."""

from __future__ import annotations

import math

import ezdxf
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

import dxf_factory as factory
from conftest import ROOT
from planner.defaults import UNIT_TO_M
from planner.errors import InputError, UsageError
from planner.layout.dxf import read_dxf
from planner.layout.dxf_units import PREFERENCE, SPACING_RANGE_M
from planner.layout.model import DEFAULT_MOUNT_HEIGHT_M

LAYOUTS = ROOT / "layouts"


@pytest.fixture
def dialux(tmp_path):
    doc, expected = factory.dialux_office()
    return factory.save(doc, tmp_path / "office.dxf"), expected


# --- DIALux -------------------------------------------------------------------------------

def test_dialux_office_positions_in_metres(dialux):
    path, expected = dialux
    layout = read_dxf(path)
    assert len(layout.luminaires) == 48
    assert_allclose(layout.xyz, expected, atol=1e-9)
    assert layout.unit == "mm"
    assert "inches" in layout.unit_reason and "millimetres" in layout.unit_reason
    assert "spacing 2.4 m" in layout.unit_reason
    assert "merged 102 parts drawn at the same point into 48 luminaires" in layout.notes
    assert [lum.name for lum in layout.luminaires] == [f"L{k:04d}" for k in range(1, 49)]
    assert all(lum.radius == pytest.approx(0.125) for lum in layout.luminaires)  # circle in the block


def test_dialux_stray_table_and_text_are_not_luminaires(dialux):
    layout = read_dxf(dialux[0])
    assert layout.xy.max() < 20.0  # the table at 150 m and the text at 1000 m are ignored
    assert {lum.source["layer"] for lum in layout.luminaires} == {factory.DLX_LAYER, factory.DLX_NESTED_LAYER}


def test_dialux_nested_block_and_minsert_sources(dialux):
    layout = read_dxf(dialux[0])
    first_row = layout.luminaires[:6]
    assert [lum.source["array_index"] for lum in first_row] == [0, 1, 2, 3, 4, 5]
    assert len({lum.source["handle"] for lum in first_row}) == 1  # one MINSERT
    nested = layout.luminaires[6:12]
    assert all(lum.source["layer"] == factory.DLX_NESTED_LAYER and "parent" in lum.source for lum in nested)
    assert_allclose(layout.xy[6:12, 1], 3.6)
    assert_allclose(layout.xy[6:12, 0], [1.2, 3.6, 6.0, 8.4, 10.8, 13.2], atol=1e-9)
    merged = layout.luminaires[12]
    assert merged.source["entity"] == "INSERT" and merged.source["parts"] in (2, 3)
    assert merged.source["file"] == "office.dxf"


def test_dialux_outline_is_the_room(dialux):
    layout = read_dxf(dialux[0])
    assert_allclose(np.array(layout.outline), [(0, 0), (14.4, 0), (14.4, 19.2), (0, 19.2)], atol=1e-9)


def test_presets_select_their_layers(dialux):
    assert len(read_dxf(dialux[0], preset="dialux").luminaires) == 48
    assert len(read_dxf(dialux[0], preset="generic").luminaires) == 48  # *LUM* on layers and blocks
    with pytest.raises(InputError, match=r"no luminaire matched \(preset revit\)"):
        read_dxf(dialux[0], preset="revit")
    with pytest.raises(UsageError, match="--preset 'lux'"):
        read_dxf(dialux[0], preset="lux")


def test_layer_and_block_patterns_replace_the_preset(dialux):
    tables = read_dxf(dialux[0], layers=["furniture"])  # case-insensitive; the table 150 m away is off the floor
    assert len(tables.luminaires) == 2
    assert any("left out 1 luminaire symbol(s)" in n and "(150.00, 0.00)" in n for n in tables.notes)
    assert {lum.source["block"] for lum in tables.luminaires} == {"TABLE"}
    symbols = read_dxf(dialux[0], blocks=["dlx_lum_1_s*"])
    assert len(symbols.luminaires) == 36  # rows 2..7 only: no symbol in the MINSERT or nested rows
    # the symbol has no circle: its size is its geometry's (two crossed 600 mm lines), not the default
    assert_allclose([lum.radius for lum in symbols.luminaires], 0.3)


def test_read_is_deterministic(dialux):
    a, b = read_dxf(dialux[0]), read_dxf(dialux[0])
    assert a == b
    assert [lum.source for lum in a.luminaires] == [lum.source for lum in b.luminaires]


# --- Revit --------------------------------------------------------------------------------

def test_revit_feet_with_element_ids(tmp_path):
    doc, expected = factory.revit_office("ft")
    layout = read_dxf(factory.save(doc, tmp_path / "revit.dxf"))
    assert len(layout.luminaires) == 20  # the switch on E-LITE-SWCH is not a luminaire
    assert_allclose(layout.xy, expected[:, :2], atol=1e-9)
    assert layout.unit == "ft" and layout.unit_reason.startswith("$INSUNITS says feet")
    assert sorted(lum.source["element_id"] for lum in layout.luminaires) == list(range(300000, 300020))
    assert 999999 not in [lum.source["element_id"] for lum in layout.luminaires]
    assert_allclose([lum.radius for lum in layout.luminaires], 0.075, atol=1e-12)
    assert all(lum.z == DEFAULT_MOUNT_HEIGHT_M for lum in layout.luminaires)
    assert any("Z = 0" in note and "default" in note for note in layout.notes)


def test_revit_metres_height_from_z(tmp_path):
    doc, expected = factory.revit_office("m", height_m=2.7)
    layout = read_dxf(factory.save(doc, tmp_path / "revit.dxf"), preset="revit", mount_height_m=4.0)
    assert_allclose(layout.xyz, expected, atol=1e-9)  # drawing Z wins over the flag
    assert not any("Z = 0" in note for note in layout.notes)


def test_mount_height_and_radius_flags_fill_gaps(tmp_path):
    doc = factory.new_drawing(6)
    for k in range(4):
        doc.modelspace().add_point((2.0 * k, 1.0, 0.0), dxfattribs={"layer": "LIGHTS"})
    layout = read_dxf(factory.save(doc, tmp_path / "p.dxf"), mount_height_m=3.3, radius_m=0.07)
    assert [lum.source["entity"] for lum in layout.luminaires] == ["POINT"] * 4
    assert all(lum.z == 3.3 and lum.radius == 0.07 for lum in layout.luminaires)
    assert any("used 3.3 m (given)" in note for note in layout.notes)
    with pytest.raises(UsageError, match="--height"):
        read_dxf(tmp_path / "p.dxf", mount_height_m=0.0)


def test_layer_0_inside_a_block_takes_the_insert_layer(tmp_path):
    """A block on a luminaire layer is one luminaire; inside other blocks, layer 0 is inherited."""
    doc = factory.new_drawing(6)
    doc.blocks.new("DOWNLIGHT").add_circle((0, 0), 0.08)
    row = doc.blocks.new("ROW")
    for x in (0.0, 1.5, 3.0):
        row.add_blockref("DOWNLIGHT", (x, 0.0))  # layer 0
    msp = doc.modelspace()
    msp.add_blockref("ROW", (10.0, 5.0, 3.0), dxfattribs={"layer": "A-CEIL"})
    msp.add_blockref("ROW", (10.0, 8.0, 3.0), dxfattribs={"layer": "E-LITE"})  # the whole row: one
    layout = read_dxf(factory.save(doc, tmp_path / "n.dxf"))
    assert_allclose(layout.xyz, [(10, 5, 3), (11.5, 5, 3), (13, 5, 3), (10, 8, 3)])
    assert [lum.source["layer"] for lum in layout.luminaires] == ["A-CEIL"] * 3 + ["E-LITE"]
    assert [lum.source["block"] for lum in layout.luminaires] == ["DOWNLIGHT"] * 3 + ["ROW"]
    # no circle directly in ROW: its size is its geometry's (the three 0.16 m downlights in a row)
    assert_allclose([lum.radius for lum in layout.luminaires], [0.08] * 3 + [0.08])


def test_element_id_as_text(tmp_path):
    doc = factory.new_drawing(6)
    doc.appids.add("REVIT")
    for k in range(3):
        ref = doc.modelspace().add_circle((2.0 * k, 0, 3), 0.1, dxfattribs={"layer": "E-LITE"})
        ref.set_xdata("REVIT", [(1000, f"ElementId {4711 + k}")])
    layout = read_dxf(factory.save(doc, tmp_path / "t.dxf"))
    assert [lum.source["element_id"] for lum in layout.luminaires] == [4711, 4712, 4713]


# --- geometry -----------------------------------------------------------------------------

def test_mirrored_circles_use_ocs(tmp_path):
    doc, expected = factory.circles_grid(6, 1.0, 2.4, height_m=3.0, mirrored=True)
    layout = read_dxf(factory.save(doc, tmp_path / "m.dxf"))
    assert_allclose(layout.xyz, expected, atol=1e-9)
    assert layout.luminaires[0].source["entity"] == "CIRCLE"


@pytest.mark.parametrize(("gap_m", "radius_m", "count"), [(0.04, 0.1, 2), (0.3, 0.1, 4), (0.08, 0.2, 2), (0.12, 0.2, 4)])
def test_merge_threshold(tmp_path, gap_m, radius_m, count):
    """Parts merge within max(0.5 * radius, 5 cm): two pairs, each pair `gap_m` apart."""
    doc = factory.new_drawing(6)
    for x in (0.0, 2.0):
        for dx in (0.0, gap_m):
            doc.modelspace().add_circle((x + dx, 0.0, 3.0), radius_m, dxfattribs={"layer": "LED"})
    layout = read_dxf(factory.save(doc, tmp_path / "g.dxf"), units="m")
    assert len(layout.luminaires) == count
    if count == 2:
        assert_allclose(layout.xy[:, 0], [gap_m / 2, 2.0 + gap_m / 2])


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    angle=st.floats(0, 360),
    offset=st.tuples(st.floats(-1e4, 1e4), st.floats(-1e4, 1e4)),
    scale=st.floats(0.2, 5.0),
    base=st.tuples(st.floats(-50, 50), st.floats(-50, 50)),
    inner_angle=st.floats(0, 360),
)
def test_nested_transforms_compose(tmp_path, angle, offset, scale, base, inner_angle):
    """Two levels of blocks, rotated, scaled, with base points: positions match the maths."""
    doc = factory.new_drawing(6)
    lum = doc.blocks.new("FIXTURE_A", base_point=(0.5, 0.5))
    lum.add_circle((0.5, 0.5), 0.1)
    inner = doc.blocks.new("PAIR")
    inner_points = [(0.0, 0.0), (3.0, 0.0)]
    for p in inner_points:
        inner.add_blockref("FIXTURE_A", p, dxfattribs={"layer": "LUM"})
    outer = doc.blocks.new("GROUP", base_point=(*base, 0))
    outer_at = [(base[0], base[1]), (base[0] + 10.0, base[1] + 4.0)]
    for p in outer_at:
        outer.add_blockref("PAIR", p, dxfattribs={"rotation": inner_angle})
    doc.modelspace().add_blockref("GROUP", (*offset, 0), dxfattribs={"rotation": angle, "xscale": scale,
                                                                      "yscale": scale})

    def rot(deg, v):
        c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
        return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])

    expected = []
    for p_outer in outer_at:
        for p_inner in inner_points:
            in_group = np.array(p_outer) + rot(inner_angle, p_inner)
            expected.append(np.array(offset) + scale * rot(angle, in_group - np.array(base)))
    expected = np.array(expected)
    layout = read_dxf(factory.save(doc, tmp_path / "nest.dxf"), units="m", mount_height_m=3.0)
    got = layout.xy
    assert len(got) == 4
    order = np.lexsort((np.round(expected[:, 0], 3), np.round(expected[:, 1], 3)))
    assert_allclose(got, expected[order], atol=1e-6)
    assert_allclose([lum.radius for lum in layout.luminaires], 0.1 * scale, rtol=1e-9)


# --- units --------------------------------------------------------------------------------

def test_units_override(dialux):
    layout = read_dxf(dialux[0], units="cm")
    assert layout.unit == "cm" and layout.unit_reason.startswith("given with --units")
    assert_allclose(layout.xyz, dialux[1] * 10, atol=1e-9)
    metres = read_dxf(dialux[0], units="m")
    assert any("--units m" in note and "implausible" in note for note in metres.notes)
    with pytest.raises(UsageError, match="--units 'furlong'"):
        read_dxf(dialux[0], units="furlong")


def test_unset_insunits_prefers_millimetres(tmp_path):
    doc, expected = factory.circles_grid(0, 1000.0, 2.4, height_m=2.8)
    layout = read_dxf(factory.save(doc, tmp_path / "u.dxf"))
    assert layout.unit == "mm" and layout.unit_reason.startswith("$INSUNITS is unset")
    assert_allclose(layout.xyz, expected, atol=1e-9)


def test_implausible_units_without_fix(tmp_path):
    doc, _ = factory.circles_grid(4, 1.0, 1e7)  # 10,000 km apart in any unit
    with pytest.raises(InputError, match=r"u\.dxf: luminaire spacing is 1e\+07 drawing units.*pass --units"):
        read_dxf(factory.save(doc, tmp_path / "u.dxf"))


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    true_unit=st.sampled_from(sorted(UNIT_TO_M)),
    header=st.sampled_from([0, 1, 2, 4, 5, 6]),
    spacing_m=st.floats(0.8, 6.0),
    height_m=st.sampled_from([0.0, 2.5, 4.0]),
)
def test_chosen_unit_is_plausible(tmp_path, true_unit, header, spacing_m, height_m):
    """Whatever the header says, the result is plausible; a true header is kept."""
    per_m = 1.0 / UNIT_TO_M[true_unit]
    doc, expected = factory.circles_grid(header, per_m, spacing_m, height_m=height_m)
    layout = read_dxf(factory.save(doc, tmp_path / "p.dxf"))
    assert layout.unit in PREFERENCE
    nn = np.sort(np.hypot(*(layout.xy[:, None, :] - layout.xy[None, :, :]).transpose(2, 0, 1)), axis=1)[:, 1]
    assert SPACING_RANGE_M[0] <= np.median(nn) <= SPACING_RANGE_M[1]
    if factory.INSUNITS[true_unit] == header:
        assert layout.unit == true_unit
        assert_allclose(layout.xy, expected[:, :2], rtol=1e-9, atol=1e-9)


# --- outline ------------------------------------------------------------------------------

def test_outline_only(tmp_path):
    path = factory.save(factory.outline_room(), tmp_path / "room.dxf")
    layout = read_dxf(path, allow_outline_only=True)
    assert layout.luminaires == ()
    assert_allclose(np.array(layout.outline), [(0, 0), (32, 0), (32, 16), (0, 16)])  # not the column
    assert layout.unit == "m" and "room 32 m x 16 m" in layout.unit_reason
    with pytest.raises(InputError, match=r"no luminaire matched.*--leds N to fill the room outline"):
        read_dxf(path)


def test_outline_only_unit_from_room_size(tmp_path):
    doc = factory.outline_room(unit="mm")
    doc.header["$INSUNITS"] = 0
    layout = read_dxf(factory.save(doc, tmp_path / "room.dxf"), allow_outline_only=True)
    assert layout.unit == "mm"
    assert_allclose(np.array(layout.outline).max(axis=0), (32, 16))


# --- bad input ----------------------------------------------------------------------------

def test_not_a_dxf(tmp_path):
    path = tmp_path / "notes.dxf"
    path.write_text("this is not a drawing\n")
    with pytest.raises(InputError, match=r"notes\.dxf: not a DXF file") as err:
        read_dxf(path)
    assert "\n" not in str(err.value)


def test_missing_file_and_dwg(tmp_path):
    with pytest.raises(InputError, match="file not found"):
        read_dxf(tmp_path / "nope.dxf")
    dwg = tmp_path / "plan.dxf"
    dwg.write_bytes(b"AC1032" + bytes(64))
    with pytest.raises(InputError, match="DWG file"):
        read_dxf(dwg)


def test_empty_drawing(tmp_path):
    with pytest.raises(InputError, match="model space is empty"):
        read_dxf(factory.save(factory.new_drawing(6), tmp_path / "empty.dxf"))


def test_no_luminaire_lists_layers_and_blocks(tmp_path):
    path = factory.save(factory.no_luminaires(), tmp_path / "office.dxf")
    with pytest.raises(InputError) as err:
        read_dxf(path)
    assert str(err.value) == (
        f"{path}: no luminaire matched (preset auto); layers seen: 0 (12), FURNITURE (3), WALLS (1); "
        "blocks seen: TABLE (3); pass --layer or --block (or --leds N to fill the room outline)"
    )


def test_no_luminaire_message_is_truncated(tmp_path):
    doc = factory.new_drawing(6)
    for k in range(20):
        doc.modelspace().add_line((0, k), (1, k), dxfattribs={"layer": f"LAYER{k:02d}"})
    with pytest.raises(InputError, match=r"LAYER07 \(1\), \.\.\. \(12 more\); blocks seen: none") as err:
        read_dxf(factory.save(doc, tmp_path / "many.dxf"))
    assert "LAYER08" not in str(err.value) and "\n" not in str(err.value)


def test_damaged_dxf_is_recovered(tmp_path, dialux):
    damaged = factory.corrupt_missing_endsec(dialux[0], tmp_path / "damaged.dxf")
    with pytest.raises(ezdxf.DXFStructureError):
        ezdxf.readfile(damaged)  # the corruption is real
    layout = read_dxf(damaged)
    assert len(layout.luminaires) == 48
    assert_allclose(layout.xyz, dialux[1], atol=1e-9)
    note = layout.notes[0]
    assert note.startswith("recovered a damaged DXF; the auditor fixed 1 problem(s)") and "missing ENDSEC" in note


# --- bundled examples ---------------------------------------------------------------------

def test_bundled_examples_read():
    office = read_dxf(LAYOUTS / "dialux-office.dxf")
    assert len(office.luminaires) == 48 and office.unit == "mm"
    _, expected = factory.dialux_office()
    assert_allclose(office.xyz, expected, atol=1e-9)
    room = read_dxf(LAYOUTS / "outline-room.dxf", allow_outline_only=True)
    assert room.luminaires == () and len(room.outline) == 4
