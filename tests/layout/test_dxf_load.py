"""The DXF loader's filter (planner/layout/dxf_load.py): what it skims past, what it keeps, and its cap."""

from __future__ import annotations

import ezdxf
import pytest

import dxf_factory as factory
import planner.layout.dxf_load as dxf_load
from planner.errors import InputError
from planner.layout.dxf import load_drawing, read_dxf, scan_dxf


@pytest.fixture
def drawing(tmp_path):
    """16 luminaires in metres (0.8 m apart) with what the reader does not use around them: furniture lines and a 2D
    polyline (its VERTEX entities go with it), a hatch, a block reference with attributes, a paper-space line."""
    doc = ezdxf.new("R2010")
    doc.header["$INSUNITS"] = 6
    msp = doc.modelspace()
    for k in range(16):
        msp.add_circle((0.8 * (k % 4), 0.8 * (k // 4), 2.8), 0.1, dxfattribs={"layer": "LIGHTS"})
    msp.add_lwpolyline([(-1, -1), (4, -1), (4, 4), (-1, 4)], close=True, dxfattribs={"layer": "WALLS"})
    for k in range(5):
        msp.add_line((k, 0), (k, 1), dxfattribs={"layer": "FURNITURE"})
    msp.add_polyline2d([(0, 0), (1, 0), (1, 1)], dxfattribs={"layer": "FURNITURE"})
    msp.add_polyline2d([(0, 0), (3, 0), (3, 3)], dxfattribs={"layer": "WALLS"})
    msp.add_hatch(dxfattribs={"layer": "FLOOR"}).paths.add_polyline_path([(0, 0), (1, 0), (1, 1)])
    tag = doc.blocks.new("TAG")
    tag.add_attdef("NAME", (0, 0))
    msp.add_blockref("TAG", (5, 5), dxfattribs={"layer": "TAGS"}).add_auto_attribs({"NAME": "Office"})
    doc.paperspace().add_line((0, 0), (1, 1), dxfattribs={"layer": "SHEET"})
    path = tmp_path / "room.dxf"
    doc.saveas(path)
    return path


def test_the_reader_loads_only_what_it_uses_and_counts_the_rest(drawing):
    found, doc, notes = scan_dxf(drawing)
    kinds = sorted(e.dxftype() for e in doc.modelspace())
    assert kinds == ["CIRCLE"] * 16 + ["INSERT", "LWPOLYLINE", "POLYLINE"], kinds
    assert found.layers_seen["FURNITURE"] == 6 and found.layers_seen["FLOOR"] == 1, found.layers_seen
    assert "SHEET" not in found.layers_seen  # paper space is not the plan
    polyline = doc.modelspace().query("POLYLINE")[0]
    assert len(polyline.vertices) == 3  # the wall polyline kept its vertices
    insert = doc.modelspace().query("INSERT")[0]
    assert [a.dxf.text for a in insert.attribs] == ["Office"]
    layout = read_dxf(drawing)
    assert len(layout.luminaires) == 16 and layout.unit == "m" and layout.outline is not None


def test_a_copy_loads_the_whole_drawing(drawing):
    doc, notes = load_drawing(drawing)
    assert notes == []
    assert len(doc.modelspace().query("LINE[layer=='FURNITURE']")) == 5 and len(doc.modelspace().query("HATCH")) == 1
    assert len(doc.paperspace().query("LINE")) == 1


def test_over_the_cap_the_reader_refuses_and_a_copy_keeps_what_the_reader_uses(drawing, monkeypatch):
    counted = dxf_load._Skim(True, 10**9)
    for _ in counted(dxf_load._pairs(str(drawing))):
        pass
    skimmed = dxf_load._Skim(False, 10**9)
    for _ in skimmed(dxf_load._pairs(str(drawing))):
        pass
    assert skimmed.loaded < counted.loaded
    monkeypatch.setattr(dxf_load, "MAX_DXF_ENTITIES", skimmed.loaded)  # the reader's share fits, the whole does not
    doc, notes = load_drawing(drawing)
    assert not doc.modelspace().query("HATCH") and len(doc.modelspace().query("CIRCLE")) == 16
    assert len(notes) == 1 and "only the luminaires, texts and walls were loaded (7 other entities left out)" in notes[0]
    monkeypatch.setattr(dxf_load, "MAX_DXF_ENTITIES", skimmed.loaded - 1)
    with pytest.raises(InputError, match=f"more than {skimmed.loaded - 1:,} block references, circles"):
        read_dxf(drawing)


def test_the_annotated_copy_of_a_drawing_over_the_cap_is_partial_and_says_so(drawing, tmp_path, monkeypatch, capsys):
    from planner.cli import plan

    skimmed = dxf_load._Skim(False, 10**9)
    for _ in skimmed(dxf_load._pairs(str(drawing))):
        pass
    monkeypatch.setattr(dxf_load, "MAX_DXF_ENTITIES", skimmed.loaded)
    assert plan.console_main([str(drawing), "-o", str(tmp_path / "out"), "--scheme", "unique", "--no-verify",
                              "--no-report", "--no-map", "--no-firmware"]) == 0
    warned = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    assert len(warned) == 1 and warned[0].startswith("vlp-plan: warning: room-vlp.dxf holds the luminaires, texts "
                                                     "and walls of room.dxf, not all of it: more than"), warned
    copy = ezdxf.readfile(tmp_path / "out" / "room-vlp.dxf").modelspace()
    assert not copy.query("HATCH") and len(copy.query("TEXT[layer=='VLP-ID']")) == 16


@pytest.mark.parametrize("version", ["R12", "R2000"])
@pytest.mark.parametrize("fmt", ["asc", "bin"])
def test_r12_and_binary_drawings_are_skimmed_alike(version, fmt, tmp_path):
    """R12 polylines carry their VERTEX entities in the ENTITIES section; a binary DXF comes through ezdxf's binary
    tag loader: the same luminaires, outline and layer counts either way."""
    doc = ezdxf.new(version)
    msp = doc.modelspace()
    for k in range(16):
        msp.add_circle((800 * (k % 4), 800 * (k // 4), 2800), 100, dxfattribs={"layer": "LIGHTS"})
    for k in range(50):
        msp.add_line((k, 0), (k, 1), dxfattribs={"layer": "FURNITURE"})
    msp.add_polyline2d([(0, 0), (1, 0), (1, 1)], dxfattribs={"layer": "FURNITURE"})
    msp.add_polyline2d([(-1000, -1000), (4000, -1000), (4000, 4000), (-1000, 4000)], close=True,
                       dxfattribs={"layer": "WALLS"})
    doc.saveas(tmp_path / "r.dxf", fmt=fmt)
    found, loaded, _ = scan_dxf(tmp_path / "r.dxf")
    assert dict(found.layers_seen) == {"LIGHTS": 16, "FURNITURE": 51, "WALLS": 1}
    assert len(loaded.modelspace()) == 17
    layout = read_dxf(tmp_path / "r.dxf")
    assert len(layout.luminaires) == 16 and layout.unit == "mm" and len(layout.outline) == 4


def test_blocks_nesting_blocks_are_walked_within_a_bound(tmp_path, monkeypatch):
    """A 'billion laughs' of blocks: the walk stops at its caps (lowered here; 400,000 parts and 2,000,000 visits
    by default, docs/dxf.md) with one line, instead of running for hours."""
    import planner.layout.dxf_scan as dxf_scan

    monkeypatch.setattr(dxf_scan, "MAX_PARTS", 1_000)
    with pytest.raises(InputError, match=r"more than 1,000 luminaire parts taken .*--layer or --block"):
        read_dxf(factory.nested_blocks(tmp_path / "parts.dxf", "circle"))
    monkeypatch.setattr(dxf_scan, "MAX_VISITS", 5_000)
    with pytest.raises(InputError, match=r"hold more than 5,000 entities \(blocks nested in blocks multiply: B4"):
        read_dxf(factory.nested_blocks(tmp_path / "lines.dxf", "line"))
    monkeypatch.setattr(dxf_scan, "MAX_VISITS", 30_000)  # the same drawing within the caps is walked whole
    found, _, _ = scan_dxf(factory.nested_blocks(tmp_path / "lines.dxf", "line"))
    assert found.visits == 1 + 10 + 100 + 1_000 + 10_000 + 10_000  # the references of each level, then the lines
