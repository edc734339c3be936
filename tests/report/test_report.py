"""The site report: walking order, ID bill, checklist, and the HTML and PDF opened by real tools.

The HTML is opened in a real headless Chromium (Debian ``chromium`` and
``chromium-driver``, driven by Selenium); the PDF is rendered page by page with
``pdftoppm`` (Debian ``poppler-utils``). ``.ci/run`` installs both.
"""

import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import ROOT, grid_xy, hex_xy, minimal_plan
from planner.cli.flash import console_main as flash_main
from planner.cli.plan import main as plan_main
from planner.cli.report import console_main as report_main
from planner.cli.report import main as report_cli
from planner.report.content import checklist, id_bill, walking_order

KEY = bytes(range(32))


# --- pure content -------------------------------------------------------------------------------

def test_walking_order_is_a_serpentine_over_rows():
    xy = grid_xy(3, 4)  # rows y = 0, 1, 2; x = 0..3
    route, rows = walking_order(xy[::-1])  # input order must not matter
    path = xy[::-1][route]
    assert path[:, 1].tolist() == [0] * 4 + [1] * 4 + [2] * 4
    assert path[:, 0].tolist() == [0, 1, 2, 3, 3, 2, 1, 0, 0, 1, 2, 3]
    assert rows.tolist() == [0] * 4 + [1] * 4 + [2] * 4


def test_walking_order_keeps_a_surveyed_row_together():
    xy = grid_xy(4, 6, jitter_m=0.04, seed=2)  # +-4 cm survey noise on a 1 m pitch
    _, rows = walking_order(xy)
    assert rows.max() == 3 and np.bincount(rows).tolist() == [6, 6, 6, 6]
    route, rows = walking_order(hex_xy(3, 5))  # staggered rows stay rows
    assert np.bincount(rows).tolist() == [5, 5, 5]


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(-50, 50), st.floats(-50, 50)), min_size=1, max_size=60, unique=True))
def test_walking_order_visits_every_luminaire_once(points):
    xy = np.array(points)
    route, rows = walking_order(xy)
    assert sorted(route.tolist()) == list(range(len(xy)))
    assert np.all(np.diff(rows) >= 0) and np.all(np.diff(rows) <= 1)
    for r in range(rows.max() + 1):  # even rows walk towards +x, odd rows back
        dx = np.diff(xy[route[rows == r], 0])
        assert np.all(dx >= 0) if r % 2 == 0 else np.all(dx <= 0)
    # rows go up in y: every stop of a later row lies above the first stop of an earlier one
    firsts = [xy[route[rows == r], 1].min() for r in range(rows.max() + 1)]
    assert firsts == sorted(firsts)


def _doc(n_rows=2, n_cols=3):
    xy = grid_xy(n_rows, n_cols)
    lums = [{"name": f"L{k}", "x": float(x), "y": float(y), "id": 1 + k % 2, "parity": "odd" if k % 2 == 0 else "even",
             "region": 0} for k, (x, y) in enumerate(xy)]
    return minimal_plan(lums)


def test_id_bill_counts_every_luminaire_once():
    bill = id_bill(_doc())
    assert [(b.id, b.count, b.parity) for b in bill] == [(1, 3, "odd"), (2, 3, "even")]
    assert sorted(n for b in bill for n in b.luminaires) == sorted(f"L{k}" for k in range(6))
    assert bill[0].luminaires == ("L0", "L2", "L4")  # walking order: row 0 left to right, then row 1 right to left


def test_checklist_takes_the_status_from_the_journal():
    journal = {"L0": {"status": "flashed", "verified": True, "driver_serial": "SIM-1", "time": "2026-11-23T10:00:00"},
               "L1": {"status": "failed", "verified": False, "message": "driver did not answer HELLO"},
               "L2": {"status": "current", "verified": False}}
    stops = {s.name: s for s in checklist(_doc(), journal)}
    assert stops["L0"].status == "verified" and "SIM-1" in stops["L0"].detail
    assert stops["L1"].status == "failed" and "HELLO" in stops["L1"].detail
    assert stops["L2"].status == "failed"  # held the image but was not verified: not done
    assert stops["L3"].status == "not flashed"
    assert [s.number for s in checklist(_doc())] == list(range(1, 7))


# --- the files, opened by real tools ------------------------------------------------------------

@pytest.fixture(scope="module")
def site(tmp_path_factory):
    base = tmp_path_factory.mktemp("report")
    (base / "key").write_text(KEY.hex())
    plan_main([str(ROOT / "layouts" / "grid-32.yaml"), "-o", str(base / "plan"), "--json", "--key-file",
               str(base / "key")])  # sealed: vlp-flash flashes no other plan
    return base


def _browser():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    chromium, driver = shutil.which("chromium"), shutil.which("chromedriver")
    assert chromium and driver, "Chromium and ChromeDriver are needed: apt-get install chromium chromium-driver"
    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--window-size=1280,2000"):
        options.add_argument(arg)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    return webdriver.Chrome(service=Service(driver), options=options)


def open_in_chromium(html: Path, screenshot: Path) -> dict:
    """Open ``html`` in headless Chromium: images that failed to load, console errors, headings; screenshot."""
    browser = _browser()
    try:
        browser.get(html.resolve().as_uri())
        broken = browser.execute_script(
            "return Array.from(document.images).filter(i => !i.complete || i.naturalWidth === 0).map(i => i.alt)")
        images = browser.execute_script("return document.images.length")
        headings = browser.execute_script("return Array.from(document.querySelectorAll('h2')).map(h => h.textContent)")
        errors = [e["message"] for e in browser.get_log("browser") if e["level"] == "SEVERE"]
        assert browser.save_screenshot(str(screenshot))
    finally:
        browser.quit()
    return {"broken": broken, "images": images, "errors": errors, "headings": headings}


@pytest.mark.needs_chromium
@pytest.mark.slow
def test_html_report_renders_in_chromium_with_every_image(site, tmp_path):
    html = site / "plan" / "site-report.html"
    text = html.read_text()
    assert not re.search(r"""(src|href)=["'](?!data:|#)""", text)  # self-contained: nothing fetched
    seen = open_in_chromium(html, tmp_path / "report.png")
    assert seen["broken"] == [] and seen["errors"] == []
    assert seen["images"] == 5  # map, coverage, error, timing, route
    assert seen["headings"] == ["Summary", "Site advice", "Site map", "Coverage", "Expected positioning error",
                                "Frame timing", "Walking route", "Error budget", "ID bill", "Installers' checklist"]
    shot = (tmp_path / "report.png").read_bytes()
    assert shot[:8] == b"\x89PNG\r\n\x1a\n" and len(shot) > 20_000
    assert text.count('class="status-not-flashed"') == 32


@pytest.mark.needs_chromium
def test_the_browser_check_catches_a_broken_image(site, tmp_path):
    html = site / "plan" / "site-report.html"
    bad = tmp_path / "bad.html"
    bad.write_text(html.read_text().replace("data:image/png;base64,", "data:image/png;base64,AAAA", 1))
    seen = open_in_chromium(bad, tmp_path / "bad.png")
    assert seen["broken"] == ["Site map"]


def render_pdf(pdf: Path, out: Path) -> list[Path]:
    """Render every page of ``pdf`` with pdftoppm; return the PNGs, checking the count against pdfinfo."""
    assert shutil.which("pdftoppm"), "pdftoppm is needed: apt-get install poppler-utils"
    info = subprocess.run(["pdfinfo", str(pdf)], capture_output=True, text=True, check=True).stdout
    pages = int(re.search(r"^Pages:\s+(\d+)", info, re.M).group(1))
    subprocess.run(["pdftoppm", "-r", "40", "-png", str(pdf), str(out / "page")], check=True, capture_output=True)
    pngs = sorted(out.glob("page-*.png"))
    assert len(pngs) == pages
    return pngs


def blank_pages(pngs: list[Path]) -> list[str]:
    """The rendered pages with (almost) no ink below the title band: a page holding only its title is blank."""
    import matplotlib.image as mpimg

    blank = []
    for png in pngs:
        grey = mpimg.imread(png)[..., :3].mean(axis=2)
        body = grey[int(0.09 * len(grey)):]  # the title sits in the top 5 % of every page
        if (body < 0.5).mean() <= 0.001:
            blank.append(png.name)
    return blank


def pdf_fonts(pdf: Path) -> list[dict[str, str]]:
    """``pdffonts``' table: one dict per font (name, type, emb)."""
    assert shutil.which("pdffonts"), "pdffonts is needed: apt-get install poppler-utils"
    out = subprocess.run(["pdffonts", str(pdf)], capture_output=True, text=True, check=True).stdout.splitlines()
    assert out[1].startswith("---"), out
    columns = [len(c) for c in out[1].split(" ")]  # the dashes give each column's width
    fonts = []
    for row in out[2:]:
        cells, at = [], 0
        for width in columns:
            cells.append(row[at:at + width].strip())
            at += width + 1
        fonts.append({"name": cells[0], "type": cells[1], "emb": cells[3]})
    return fonts


@pytest.mark.needs_poppler
def test_pdf_report_renders_every_page(site, tmp_path):
    pngs = render_pdf(site / "plan" / "site-report.pdf", tmp_path)
    # title, the site advice (grid-32 is below the 90 % goal), 5 figures, the error budget, the bill (1 page for
    # 8 IDs) and the checklist (1 page for 32 stops)
    assert len(pngs) == 10
    assert blank_pages(pngs) == []


@pytest.mark.needs_poppler
def test_pdf_report_embeds_every_font_it_uses(site):
    fonts = pdf_fonts(site / "plan" / "site-report.pdf")
    assert fonts, "pdffonts lists no font"
    assert [f["name"] for f in fonts if f["emb"] != "yes"] == []
    # one typeface: DejaVu Sans for titles and text, its monospaced face for the tables; never a core-14 font
    assert {f["name"].split("+")[-1] for f in fonts} <= {"DejaVuSans", "DejaVuSans-Bold", "DejaVuSansMono",
                                                          "DejaVuSansMono-Bold"}
    assert {f["name"].split("+")[-1] for f in fonts} >= {"DejaVuSansMono", "DejaVuSans-Bold"}


@pytest.mark.needs_poppler
def test_the_blank_page_check_finds_a_page_with_only_its_title(tmp_path):
    from planner.report.figures import write_pdf

    pdf = tmp_path / "thin.pdf"
    summary = [(f"row {k}", "a value long enough to put some ink on the title page " * 2) for k in range(8)]
    stops = [f"[  ]  {k:>4}  L{k:<6}  {k * 0.5:>8.2f}  not flashed" for k in range(30)]
    write_pdf(pdf, "title", "subtitle", summary, [], ("ID  luminaires", []), ("done  stop", stops))
    pngs = render_pdf(pdf, tmp_path)
    assert len(pngs) == 3 and blank_pages(pngs) == ["page-2.png"]  # the bill has no line: only its title


@pytest.mark.needs_chromium
@pytest.mark.slow
def test_vlp_report_shows_the_flashing_status(site, tmp_path, monkeypatch, capsys):
    plan = tmp_path / "plan"
    shutil.copytree(site / "plan", plan)
    # Two drivers answer on the simulated bus (addresses 1 and 2, the plan's first two luminaires);
    # the third luminaire's driver is missing.
    code = flash_main([str(plan / "plan.yaml"), "R01C01", "R01C02", "R01C03", "--bus", "--port",
                       f"sim://?drivers=2&key={KEY.hex()}", "--key-file", str(site / "key")])
    assert code == 3
    capsys.readouterr()
    assert report_cli([str(plan / "plan.yaml"), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert (result["verified"], result["failed"], result["luminaires"]) == (2, 1, 32)
    assert result["journal"] == str(plan / "as-built.json")
    text = (plan / "site-report.html").read_text()
    assert text.count('class="status-verified"') == 2 and text.count('class="status-failed"') == 1
    assert "SIM-000001" in text and "did not answer" in text and KEY.hex() not in text
    seen = open_in_chromium(plan / "site-report.html", tmp_path / "flashed.png")
    assert seen["broken"] == [] and seen["errors"] == []
    (tmp_path / "pages").mkdir()
    assert len(render_pdf(plan / "site-report.pdf", tmp_path / "pages")) == 10  # with the site advice page
    assert not list(plan.glob(".site-report*"))  # no temporary files left behind


def test_report_names_maps_that_were_not_drawn(tmp_path):
    plan_main([str(ROOT / "layouts" / "grid-32.yaml"), "-o", str(tmp_path / "p"), "--no-map", "--no-firmware",
               "--error-poses-per-m2", "0", "--json"])
    text = (tmp_path / "p" / "site-report.html").read_text()
    assert text.count('class="missing"') == 3 and "map.png was not drawn" in text
    assert text.count("<img ") == 2  # timing and route are drawn from the plan itself


def test_report_refuses_a_journal_of_another_plan(site, tmp_path, capsys):
    plan = tmp_path / "plan"
    shutil.copytree(site / "plan", plan)
    (plan / "as-built.json").write_text(json.dumps({"format": "vlp-asbuilt/1", "plan_hash": "0" * 16,
                                                    "luminaires": {}}))
    before = (plan / "site-report.html").read_bytes()
    assert report_main([str(plan / "plan.yaml")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not of this plan" in err[0]
    assert (plan / "site-report.html").read_bytes() == before  # nothing rewritten
    assert report_main([str(plan / "plan.yaml"), "--journal", str(tmp_path / "none.json")]) == 2


def test_replanning_refuses_to_delete_an_as_built_journal(site, tmp_path, capsys):
    plan = tmp_path / "plan"
    shutil.copytree(site / "plan", plan)
    (plan / "as-built.json").write_text("{}")
    from planner.cli.plan import console_main

    assert console_main([str(ROOT / "layouts" / "grid-32.yaml"), "-o", str(plan), "--no-report", "--no-map",
                         "--error-poses-per-m2", "0"]) == 2
    assert "as-built.json" in capsys.readouterr().err and (plan / "as-built.json").read_text() == "{}"


@pytest.mark.needs_poppler
def test_pdf_shows_names_in_other_scripts(tmp_path):
    from planner.report.files import write_report

    doc = minimal_plan([{"name": name, "x": float(k), "y": 0.0, "id": k + 1}
                        for k, name in enumerate(["Светильник-1", "Büro-2", "L3"])],
                       source={"file": "büro.yaml", "unit": "m"}, modulation=None)
    html, pdf = write_report(doc, "0" * 16, tmp_path, tmp_path)
    text = subprocess.run(["pdftotext", str(pdf), "-"], capture_output=True, text=True, check=True).stdout
    assert "Светильник-1" in text and "Büro-2" in text  # real text, not boxes or '?'
    assert "Светильник-1" in html.read_text()
    assert len(render_pdf(pdf, tmp_path)) == 7  # title, 3 "not drawn" map pages, route, bill, checklist
    assert [f["name"] for f in pdf_fonts(pdf) if f["emb"] != "yes"] == []
