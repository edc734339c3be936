"""Coding efficiency: the paper's table regenerated, the curve, the plot, and vlp-efficiency."""

import json

import pytest

from conftest import ROOT
from planner.cli.efficiency import console_main
from planner.cli.plan import main as plan_main
from planner.defaults import PAPER_LAYOUTS
from planner.layout.read import read_layout
from planner.studies.efficiency import curve, efficiency, lattice_layout, paper_grid, table_row

SMALL = ["--sizes", "16,64,256", "--window-up-to", "64"]


@pytest.fixture(scope="module")
def table():
    """The rows exactly as vlp-efficiency asks for them: ``table_row`` caches, so the command's run is free."""
    return {n: table_row(paper_grid(n), name) for n, name in PAPER_LAYOUTS.items()}


@pytest.mark.parametrize("n", sorted(PAPER_LAYOUTS))
def test_the_grids_built_in_code_are_the_bundled_layouts(n):
    built, bundled = paper_grid(n), read_layout(ROOT / "layouts" / PAPER_LAYOUTS[n], n)
    assert built.luminaires == bundled.luminaires and built.outline == bundled.outline
    assert [lum.source for lum in built.luminaires] == [lum.source for lum in bundled.luminaires]
    assert (built.unit, built.fill_height_m, built.fill_radius_m) == (bundled.unit, bundled.fill_height_m,
                                                                      bundled.fill_radius_m)


@pytest.fixture(scope="module")
def small_json(tmp_path_factory):
    """One small run of the command, shared: its JSON and the plot it drew."""
    plot = tmp_path_factory.mktemp("eff") / "curve.png"
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert console_main([*SMALL, "--json", "--plot", str(plot)]) == 0
    return json.loads(buf.getvalue()), plot


@pytest.mark.slow
def test_table_regenerates_the_papers_bits(table):
    assert {n: (r.naive_bits, r.paper_bits) for n, r in table.items()} == {32: (5, 4), 256: (8, 6), 512: (9, 6)}
    assert all((r.printed_naive_bits, r.printed_bits) == (r.naive_bits, r.paper_bits) for r in table.values())


def test_shortest_scheme_sits_between_its_bound_and_the_paper(table):
    for r in table.values():
        assert r.pair_bound_bits <= r.paper_bits
        assert r.shortest_bound_bits <= r.shortest_bits <= r.paper_bits
        assert r.considered[r.shortest_scheme]["ambiguous_poses"] == 0


def test_efficiency_is_counted_as_the_paper_does(table):
    assert efficiency(6, 9) == pytest.approx(1 / 3)
    assert efficiency(4, 5) == pytest.approx(0.2) and efficiency(9, 9) == 0.0
    assert [round(table[n].paper_efficiency, 2) for n in (32, 256, 512)] == [0.2, 0.25, 0.33]
    assert table[512].printed_efficiency == pytest.approx(table[512].paper_efficiency)


def test_lattice_layout_has_n_luminaires_at_half_metre_pitch():
    lay = lattice_layout(48)
    assert len(lay.luminaires) == 48
    assert {lum.x for lum in lay.luminaires} == {0.5 * k for k in range(8)}  # 8 columns x 6 rows


@pytest.mark.slow
def test_curve_computes_window_bits_only_up_to_the_limit():
    rows = curve([16, 64, 256], window_up_to=64, paper_up_to=64)
    assert [r.window_bits is None for r in rows] == [False, False, True]
    assert [r.paper_bits is None for r in rows] == [False, False, True]
    assert [r.naive_bits for r in rows] == [4, 6, 8]
    for r in rows[:2]:
        assert r.window_bound_bits <= r.window_bits < r.naive_bits and r.window_ambiguous_poses == 0
        assert r.pair_bound_bits <= r.paper_bits


@pytest.mark.slow
def test_json_output_parses_and_marks_not_computed(small_json):
    doc, plot = small_json
    rows = {r["luminaires"]: r for r in doc["curve"]["rows"]}
    assert sorted(rows) == [16, 64, 256]
    assert rows[256]["window_bits"] is None and isinstance(rows[64]["window_bits"], int)
    assert [r["paper_bits"] for r in doc["table"]] == [4, 6, 6] and doc["site"] is None
    assert doc["table"][2]["printed"] == {"naive_bits": 9, "bits": 6, "efficiency": 0.3333}


def test_plot_is_a_png(small_json):
    _, plot = small_json
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert [p.name for p in plot.parent.iterdir()] == ["curve.png"]  # no temporary file left


@pytest.mark.slow  # the paper's table: three grids planned
def test_text_report_says_not_computed_and_adds_the_site(tmp_path, capsys):
    out = tmp_path / "p"
    plan_main([str(ROOT / "layouts" / "grid-32.yaml"), "-o", str(out), "--json", "--no-map", "--no-firmware",
               "--error-poses-per-m2", "0"])
    capsys.readouterr()
    assert console_main([str(out / "plan.yaml"), *SMALL, "--plot", str(tmp_path / "c.png")]) == 0
    text = capsys.readouterr().out
    curve_part = text.split("Curve:")[1].split("This site:")[0]
    lines = {line.split()[0]: line for line in curve_part.splitlines() if line.strip()[:1].isdigit()}
    assert "not computed" in lines["256"] and "not computed" not in lines["64"] + lines["16"]
    assert "This site:" in text and "window scheme: 3 bits (naive 5" in text and "efficiency 40 %" in text
    assert "paper 4 bits (0 ambiguous poses)" in text


@pytest.mark.parametrize("bad", ["16,x", "", "2", "16,,-4"])
def test_bad_sizes_is_a_one_line_usage_error(bad, tmp_path, capsys):
    assert console_main(["--sizes", bad, "--plot", str(tmp_path / "c.png")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("vlp-efficiency: error: argument --sizes") and err.count("\n") == 1


def test_missing_plan_is_an_input_error(tmp_path, capsys):
    assert console_main([str(tmp_path / "none.yaml"), *SMALL, "--plot", str(tmp_path / "c.png")]) == 1
    assert capsys.readouterr().err.count("\n") == 1


@pytest.mark.slow  # the paper's table: three grids planned
def test_vlp_efficiency_writes_no_file_unless_asked(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert console_main(["--sizes", "16", "--window-up-to", "16", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["plot"] is None and list(tmp_path.iterdir()) == []
