"""Tests of the IFC reader and the annotated IFC: IFC2X3 in feet, IFC4 in millimetres with two storeys."""

from __future__ import annotations

import json

import ifc_models
import ifcopenshell
import ifcopenshell.util.element
import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose

from planner.errors import InputError, UsageError
from planner.layout.ifc import read_ifc
from planner.layout.model import area_m2
from planner.layout.read import ReadOptions, read_layout


@pytest.fixture
def ifc2x3_feet(tmp_path):
    model, expected = ifc_models.model("IFC2X3", "ft")
    return ifc_models.save(model, tmp_path / "revit.ifc"), expected["Level 1"]


@pytest.fixture
def ifc4_two_storeys(tmp_path):
    model, expected = ifc_models.model("IFC4", "mm", {"Ground": (0.0, 4, 3), "First": (3.5, 3, 3)})
    return ifc_models.save(model, tmp_path / "archicad.ifc"), expected


def test_ifc2x3_flow_terminals_typed_as_light_fixtures_in_feet(ifc2x3_feet):
    path, expected = ifc2x3_feet
    layout = read_layout(path, 12)
    assert len(layout.luminaires) == 12  # the air terminal and the proxy are not lights
    assert_allclose(layout.xyz, expected, atol=1e-9)
    assert layout.unit == "ft" and "IFC2X3" in layout.unit_reason
    src = layout.luminaires[0].source
    assert src["entity"] == "IfcFlowTerminal" and src["type"] == "Downlight 150" and src["storey"] == "Level 1"
    assert len({lum.source["global_id"] for lum in layout.luminaires}) == 12
    assert all(lum.source["ifc_name"].startswith("Downlight:") for lum in layout.luminaires)


def test_ifc4_light_fixtures_in_millimetres_need_a_storey(ifc4_two_storeys):
    path, expected = ifc4_two_storeys
    with pytest.raises(InputError, match=r"2 storeys hold light fixtures: 'Ground' \(12 fixtures, floor at 0\.00 m\), "
                                         r"'First' \(9 fixtures, floor at 3\.50 m\); choose one with `storey` NAME"):
        read_layout(path, None)
    first = read_layout(path, 9, ReadOptions(storey="first"))
    assert_allclose(first.xyz, expected["First"], atol=1e-9)  # heights above the first floor, not 6.2 m
    assert first.unit == "mm" and {lum.source["entity"] for lum in first.luminaires} == {"IfcLightFixture"}
    ground = read_layout(path, 12, ReadOptions(storey="0"))  # by elevation [m]
    assert_allclose(ground.xyz, expected["Ground"], atol=1e-9)
    with pytest.raises(InputError, match=r"`storey` 'Roof' holds no light fixtures; storeys with fixtures: 'Ground'"):
        read_layout(path, None, ReadOptions(storey="Roof"))


@pytest.mark.parametrize("schema, unit, body, radius_m", [
    ("IFC4", "mm", ("round", 0.09), 0.09),  # a downlight: its disc's radius
    ("IFC2X3", "ft", ("square", 0.6), 0.3),  # a 600 mm panel mapped from its type: half its side
])
def test_ifc_led_radius_from_the_fixture_body(tmp_path, schema, unit, body, radius_m):
    model, _ = ifc_models.model(schema, unit, body=body)
    layout = read_layout(ifc_models.save(model, tmp_path / "bodies.ifc"), 12)
    assert_allclose([lum.radius for lum in layout.luminaires], radius_m, rtol=1e-4)  # a meshed disc
    assert any(n.startswith(f"LED radius from the fixtures' geometry: {radius_m:g} m") for n in layout.notes)
    given = read_ifc(tmp_path / "bodies.ifc", radius_m=0.05)  # --radius wins
    assert {lum.radius for lum in given.luminaires} == {0.05} and not any("geometry" in n for n in given.notes)


def test_ifc_fixtures_without_geometry_take_the_default_radius(ifc2x3_feet):
    layout = read_layout(ifc2x3_feet[0], 12)
    assert {lum.radius for lum in layout.luminaires} == {0.1}
    assert any(n.startswith("12 fixture(s) have no geometry to measure; LED radius 0.1 m") for n in layout.notes)


@pytest.mark.parametrize("schema, unit", [("IFC4", "mm"), ("IFC2X3", "ft")])
def test_ifc_room_outline_from_the_storeys_spaces(tmp_path, schema, unit):
    model, expected = ifc_models.model(schema, unit, {"Ground": (0.0, 4, 3), "First": (3.5, 3, 3)}, spaces=True)
    path = ifc_models.save(model, tmp_path / "spaces.ifc")
    first = read_layout(path, 9, ReadOptions(storey="First"))
    lo, hi = expected["First"][:, :2].min(axis=0) - 1.0, expected["First"][:, :2].max(axis=0) + 1.0
    outline = np.array(first.outline)  # the two rooms joined: one rectangle, the first storey's
    assert_allclose(outline.min(axis=0), lo, atol=1e-6) and assert_allclose(outline.max(axis=0), hi, atol=1e-6)
    assert abs(area_m2(first.outline) - np.prod(hi - lo)) < 1e-6
    assert any(n.startswith("room outline: the floor joined from 2 space footprints") for n in first.notes)
    without = read_layout(ifc_models.save(ifc_models.model(schema, unit)[0], tmp_path / "none.ifc"), 12)
    assert without.outline is None


def test_ifc_flags_that_do_not_apply(ifc2x3_feet, tmp_path):
    with pytest.raises(UsageError, match="`units` does not apply"):
        read_ifc(ifc2x3_feet[0], units="mm")
    with pytest.raises(UsageError, match="`room` is for .dxf drawings"):
        read_layout(ifc2x3_feet[0], None, ReadOptions(room="A"))
    bad = tmp_path / "bad.ifc"
    bad.write_text("ISO-10303-21;\nthis is not a model\nEND-ISO-10303-21;\n")
    with pytest.raises(InputError, match=r"bad\.ifc: not a readable IFC model.*; vlp-inspect"):
        read_layout(bad, None)
    cut = tmp_path / "cut.ifc"
    data = ifc2x3_feet[0].read_bytes()
    cut.write_bytes(data[: len(data) // 2])  # ifcopenshell would read the first half's fixtures silently
    with pytest.raises(InputError, match=r"cut\.ifc: the model ends before END-ISO-10303-21"):
        read_layout(cut, None)


def test_height_flag_where_the_fixture_sits_on_the_floor(tmp_path):
    model, _ = ifc_models.model("IFC4", "m", height_m=0.0)
    layout = read_ifc(ifc_models.save(model, tmp_path / "floor.ifc"), mount_height_m=3.1)
    assert {lum.z for lum in layout.luminaires} == {3.1}
    assert any("no plausible mounting height; used 3.1 m (given)" in note for note in layout.notes)


def test_vlp_plan_writes_an_annotated_ifc_with_the_ids(ifc4_two_storeys, tmp_path, capsys):
    from planner.cli.plan import main

    path, expected = ifc4_two_storeys
    out = tmp_path / "out"
    argv = [str(path), "--storey", "Ground", "--leds", "12", "-o", str(out), "--json", "--no-map", "--no-report",
            "--no-firmware", "--scheme", "unique", "--poses-per-m2", "20", "--error-poses-per-m2", "0"]
    assert main(argv) in (0, 3)
    summary = json.loads(capsys.readouterr().out)
    assert summary["luminaires"] == 12 and str(out / "archicad-vlp.ifc") in summary["files"]
    plan = yaml.safe_load((out / "plan.yaml").read_text())
    ids = {e["source"]["global_id"]: e["id"] for e in plan["luminaires"]}
    annotated = ifcopenshell.open(str(out / "archicad-vlp.ifc"))
    seen = {}
    for fixture in annotated.by_type("IfcLightFixture"):
        pset = ifcopenshell.util.element.get_pset(fixture, "VLP")
        if pset:
            seen[fixture.GlobalId] = pset["ID"]
            assert pset["Name"].startswith("L") and pset["Parity"] in ("odd", "even")
    assert seen == ids and len(seen) == 12  # the first storey's 9 fixtures carry no IDs
    before = (out / "archicad-vlp.ifc").read_bytes()
    assert main(argv + ["-o", str(tmp_path / "again")]) in (0, 3)
    assert (tmp_path / "again" / "archicad-vlp.ifc").read_bytes() == before  # reproducible


def test_a_fixture_in_a_space_counts_on_its_storey_at_its_composed_position(tmp_path):
    import ifcopenshell.api

    model, expected = ifc_models.model("IFC4", "mm", {"Ground": (0.0, 3, 2)})
    storey = model.by_type("IfcBuildingStorey")[0]
    space = ifcopenshell.api.run("root.create_entity", model, ifc_class="IfcSpace", name="Office")
    ifcopenshell.api.run("aggregate.assign_object", model, products=[space], relating_object=storey)
    ifc_models._placement(model, space, (4000.0, 3000.0, 0.0))
    fixture = ifcopenshell.api.run("root.create_entity", model, ifc_class="IfcLightFixture", name="In the office")
    ifcopenshell.api.run("spatial.assign_container", model, products=[fixture], relating_structure=space)
    ifc_models._placement(model, fixture, (10000.0, 10000.0, 2700.0))  # absolute; stored relative to the space
    assert fixture.ObjectPlacement.PlacementRelTo is not None
    layout = read_ifc(ifc_models.save(model, tmp_path / "space.ifc"))
    assert len(layout.luminaires) == 7
    last = layout.luminaires[-1]
    assert (last.x, last.y, last.z) == pytest.approx((10.0, 10.0, 2.7))
    assert last.source["storey"] == "Ground" and last.source["ifc_name"] == "In the office"
