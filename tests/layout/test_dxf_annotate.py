"""Tests of the annotated-DXF writer: positions in drawing units, XDATA, safety, determinism."""

from __future__ import annotations

import ezdxf
import numpy as np
import pytest
from numpy.testing import assert_allclose

import dxf_factory as factory
from planner.errors import InputError
from planner.layout.dxf import read_dxf
from planner.layout.dxf_annotate import APPID, ID_LAYER, LUM_LAYER, label, write_annotated_dxf
from planner.layout.model import Layout, Luminaire
from planner.plan.file import Entry


def _entries(layout: Layout) -> list[Entry]:
    return [
        Entry(name=lum.name, x=lum.x, y=lum.y, z=lum.z, radius=lum.radius, id=10 + k,
              parity="odd" if k % 2 else "even", region=k % 4)
        for k, lum in enumerate(layout.luminaires)
    ]


def _texts(path) -> list:
    return list(ezdxf.readfile(path).modelspace().query(f'TEXT[layer=="{ID_LAYER}"]'))


@pytest.fixture
def office(tmp_path):
    doc, _ = factory.dialux_office(3, 4)
    path = factory.save(doc, tmp_path / "office.dxf")
    return path, read_dxf(path)


def test_texts_at_luminaires_in_drawing_units(tmp_path, office):
    source, layout = office
    entries = _entries(layout)
    dest = tmp_path / "out" / "office-vlp.dxf"
    dest.parent.mkdir()
    write_annotated_dxf(dest, layout, entries, source_path=source, tool_version="0.1.0")
    texts = _texts(dest)
    assert len(texts) == len(entries) == 12
    by_name = {t.get_xdata(APPID)[0].value: t for t in texts}
    for entry in entries:
        text = by_name[entry.name]
        assert_allclose(text.dxf.align_point, (entry.x * 1000, entry.y * 1000, entry.z * 1000), atol=1e-6)
        assert text.dxf.text == label(entry)
        assert 100 < text.dxf.height < 400  # mm: legible next to a 125 mm LED
    assert label(entries[1]) == "11 o R1"
    assert [p.name for p in dest.parent.iterdir()] == [dest.name]  # no temporary file left beside it


def test_xdata_reads_back(tmp_path, office):
    source, layout = office
    entries = _entries(layout)
    write_annotated_dxf(tmp_path / "a.dxf", layout, entries, source_path=source, tool_version="9.9")
    got = {}
    for text in _texts(tmp_path / "a.dxf"):
        tags = [(t.code, t.value) for t in text.get_xdata(APPID)]
        got[tags[0][1]] = tags
    for entry in entries:
        assert got[entry.name] == [(1000, entry.name), (1071, entry.id), (1000, entry.parity),
                                      (1071, entry.region), (1000, "vlp-plan 9.9")]


def test_source_is_kept_and_never_overwritten(tmp_path, office):
    source, layout = office
    before = source.read_bytes()
    dest = tmp_path / "copy.dxf"
    write_annotated_dxf(dest, layout, _entries(layout), source_path=source)
    assert source.read_bytes() == before
    original = ezdxf.readfile(source).modelspace()
    annotated = ezdxf.readfile(dest).modelspace()
    assert len(annotated) == len(original) + 12  # everything kept, texts added
    for same in (source, tmp_path / "." / "office.dxf"):
        with pytest.raises(InputError, match="refusing to overwrite the source drawing"):
            write_annotated_dxf(same, layout, _entries(layout), source_path=source)
    assert source.read_bytes() == before


def test_output_is_byte_identical_and_ezdxf_option_restored(tmp_path, office):
    source, layout = office
    for state in (False, True):
        ezdxf.options.write_fixed_meta_data_for_testing = state
        try:
            write_annotated_dxf(tmp_path / "a.dxf", layout, _entries(layout), source_path=source)
            write_annotated_dxf(tmp_path / "b.dxf", layout, _entries(layout), source_path=source)
            assert ezdxf.options.write_fixed_meta_data_for_testing is state
        finally:
            ezdxf.options.write_fixed_meta_data_for_testing = False
        assert (tmp_path / "a.dxf").read_bytes() == (tmp_path / "b.dxf").read_bytes()
    write_annotated_dxf(tmp_path / "c.dxf", layout, [], source_path=None)
    write_annotated_dxf(tmp_path / "d.dxf", layout, [], source_path=None)
    assert (tmp_path / "c.dxf").read_bytes() == (tmp_path / "d.dxf").read_bytes()


def test_annotating_twice_does_not_stack_texts(tmp_path, office):
    source, layout = office
    write_annotated_dxf(tmp_path / "once.dxf", layout, _entries(layout), source_path=source)
    write_annotated_dxf(tmp_path / "twice.dxf", layout, _entries(layout), source_path=tmp_path / "once.dxf")
    assert len(_texts(tmp_path / "twice.dxf")) == 12


def test_feet_drawing(tmp_path):
    doc, _ = factory.revit_office("ft")
    source = factory.save(doc, tmp_path / "revit.dxf")
    layout = read_dxf(source)
    write_annotated_dxf(tmp_path / "out.dxf", layout, _entries(layout), source_path=source)
    texts = sorted(_texts(tmp_path / "out.dxf"), key=lambda t: t.get_xdata(APPID)[0].value)
    assert_allclose([t.dxf.align_point.x for t in texts], [lum.x / 0.3048 for lum in layout.luminaires], atol=1e-9)


def test_recovered_source_is_annotated(tmp_path, office):
    source, layout = office
    damaged = factory.corrupt_missing_endsec(source, tmp_path / "damaged.dxf")
    write_annotated_dxf(tmp_path / "out.dxf", layout, _entries(layout), source_path=damaged)
    assert len(_texts(tmp_path / "out.dxf")) == 12


def test_yaml_input_makes_a_drawing_in_metres(tmp_path):
    lums = tuple(Luminaire(f"L{k + 1:04d}", 1.0 + 2.0 * (k % 3), 1.0 + 2.0 * (k // 3), 2.7, 0.08) for k in range(6))
    layout = Layout(lums, outline=((0, 0), (6, 0), (6, 4), (0, 4)), source_path="site.yaml")
    dest = tmp_path / "site-vlp.dxf"
    write_annotated_dxf(dest, layout, _entries(layout))
    doc = ezdxf.readfile(dest)
    assert doc.header["$INSUNITS"] == 6
    circles = list(doc.modelspace().query(f'CIRCLE[layer=="{LUM_LAYER}"]'))
    assert_allclose(sorted((c.dxf.center.x, c.dxf.center.y) for c in circles), sorted(layout.xy.tolist()))
    assert all(c.dxf.radius == pytest.approx(0.08) for c in circles)
    texts = _texts(dest)
    assert_allclose(sorted((t.dxf.align_point.x, t.dxf.align_point.y) for t in texts), sorted(layout.xy.tolist()))
    again = read_dxf(dest)  # the drawing is a valid layout itself: VLP-LUM matches *LUM*
    assert_allclose(again.xyz, layout.xyz)
    assert again.outline is not None and np.array(again.outline).max() == pytest.approx(6.0)
