"""vlp-inspect on the drawings of issue 16: it names what the reader takes and what it rejects, and why."""

from __future__ import annotations

import json

import ifc_models
import pytest

import dxf_factory as factory
from planner.cli.inspect import main


def _report(argv, capsys) -> tuple[int, dict]:
    code = main(argv + ["--json"])
    return code, json.loads(capsys.readouterr().out)


def _why(rows: list[dict]) -> dict[str, tuple[int, str]]:
    return {row["name"] or f"{row['entity']} on {row['layer']}": (row["count"], row["why"]) for row in rows}


def test_inspect_names_what_it_takes_and_rejects_in_a_residential_layout(tmp_path, capsys):
    path = factory.save(factory.residential()[0], tmp_path / "house.dxf")
    code, report = _report([str(path)], capsys)
    assert code == 0 and report["luminaires"] == 12 and report["unit"] == "mm"
    assert _why(report["taken"]) == {factory.LIGHT_POINT: (12, "block name says luminaire (LIGHT)")}
    rejected = _why(report["rejected"])
    assert rejected["TWO WAY SWITCH"] == (12, "block name says switch (SWITCH)")
    assert rejected["CEILING FAN"] == (6, "block name says fan (FAN)")
    assert rejected["WALL LIGHT"][1] == "block name says wall light (WALL LIGHT)"
    assert {"EXIT SIGN", "SOCKET 6A", "PIR SENSOR"} <= set(rejected)
    assert "COLUMN" not in rejected and "COLUMN" not in _why(report["taken"])  # neither: a column is no candidate
    layers = {row["name"]: row for row in report["layers"]}
    assert layers["E-LIGHTING"]["says"] == "luminaire (LIGHTING)" and layers["A-COLUMN"]["says"] == ""
    assert any("numerical noise" in note for note in report["notes"])


def test_inspect_text_report_and_picture(tmp_path, capsys):
    path = factory.save(factory.converted_panels()[0], tmp_path / "converted.dxf")
    png = tmp_path / "candidates.png"
    assert main([str(path), "--png", str(png)]) == 0
    text = capsys.readouterr().out
    assert "takes       20 x INSERT 'LED PANEL 600' on 'E-LITE': block name says luminaire (LED)" in text
    assert "unit     mm ($INSUNITS says metres but luminaire spacing would be" in text
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_inspect_of_a_drawing_vlp_plan_would_refuse(tmp_path, capsys):
    path = factory.save(factory.residential(unknown=5)[0], tmp_path / "house.dxf")
    code, report = _report([str(path), "--leds", "13"], capsys)
    assert code == 1 and "found 17 luminaires in 2 groups but --leds says 13" in report["error"]
    assert "vlp-inspect" not in report["error"]  # the pointer to itself is left out
    code, report = _report([str(path), "--leds", "12"], capsys)
    assert code == 0 and report["luminaires"] == 12


def test_inspect_of_a_floor_plan_names_its_outlines(tmp_path, capsys):
    path = factory.save(factory.multi_room_floor(), tmp_path / "floor.dxf")
    code, report = _report([str(path)], capsys)
    assert code == 0 and len(report["outlines"]) == 4 and {o["layer"] for o in report["outlines"]} == {"A-WALL"}
    assert any("floor joined from 4 closed polylines" in note for note in report["notes"])


@pytest.mark.parametrize(("schema", "unit"), [("IFC2X3", "ft"), ("IFC4", "mm")])
def test_inspect_ifc_names_storeys_and_what_is_not_a_light(tmp_path, capsys, schema, unit):
    model, _ = ifc_models.model(schema, unit, {"Ground": (0.0, 4, 3), "First": (3.5, 3, 3)})
    path = ifc_models.save(model, tmp_path / "model.ifc")
    code, report = _report([str(path)], capsys)
    assert code == 1 and "2 storeys hold light fixtures" in report["error"]
    assert [(s["name"], s["count"]) for s in report["storeys"]] == [("Ground", 12), ("First", 9)]
    code, report = _report([str(path), "--storey", "3.5"], capsys)  # First, by its elevation [m]
    assert code == 0 and report["luminaires"] == 9 and report["unit"] == unit
    taken, rejected = report["taken"], _why(report["rejected"])
    assert sum(r["count"] for r in taken) == 9 and {r["why"] for r in taken} == {"light fixture on the chosen storey"}
    assert any(count == 12 and "on storey 'Ground', not chosen" in why for count, why in rejected.values())
    assert rejected["Diffuser"][1] in ("a flow terminal typed IfcAirTerminalType, not IfcLightFixtureType",
                                       "an IfcAirTerminal, not a light fixture")
    assert "Desk lamp" in rejected


def test_inspect_refuses_other_files(tmp_path):
    from planner.errors import UsageError

    (tmp_path / "a.yaml").write_text("luminaires: []\n")
    with pytest.raises(UsageError, match="reads .dxf and .ifc"):
        main([str(tmp_path / "a.yaml")])
