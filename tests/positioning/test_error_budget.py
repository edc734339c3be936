"""The error budget (issue 18.5): each term simulated, vlp-accuracy's Table 3 with the terms on, the error
map of the bundled 512 plan and the site report saying what the figures include."""

import json
import math
import shutil
import subprocess

import numpy as np
import pytest
import yaml

from conftest import vlp
from planner.camera.model import Camera, rotation_from_angles
from planner.cli.accuracy import console_main as accuracy_main
from planner.cli.report import main as report_main
from planner.plan.file import load_plan
from planner.plan.model import dump_plan
from planner.positioning.accuracy import paper_experiment, site_accuracy, stats_cm
from planner.positioning.error_terms import (
    DEFAULT_TERMS,
    NO_TERMS,
    PIXEL_ONLY,
    TERMS,
    ErrorTerms,
    _image_points,
    _Imaging,
    _rms_r3,
    installed,
)

CAM = Camera()


def test_installed_luminaires_lie_within_the_tolerance_and_keep_their_height():
    xyz = np.column_stack([np.arange(2000.0), np.zeros(2000), np.full(2000, 2.5)])
    moved = installed(xyz, 0.02, np.random.default_rng(0))
    off = np.hypot(*(moved - xyz)[:, :2].T)
    assert off.max() <= 0.02 and off.max() > 0.0199  # uniform over the whole disc
    assert abs(np.median(off) - 0.02 / math.sqrt(2)) < 0.001  # area-uniform: half within r / sqrt(2)
    assert np.array_equal(moved[:, 2], xyz[:, 2])


def test_terms_switch_on_and_off_and_round_trip():
    assert DEFAULT_TERMS.active == [t for t in TERMS if t != "accelerometer"]  # on in gravity plans only
    assert PIXEL_ONLY.active == ["edge"] and NO_TERMS.active == []
    assert DEFAULT_TERMS.only("skew").active == ["skew"]
    assert ErrorTerms.from_dict(DEFAULT_TERMS.to_dict()) == DEFAULT_TERMS
    assert DEFAULT_TERMS.to_dict()["turn_deg_s"] == 5.0 and DEFAULT_TERMS.to_dict()["focal_pct"] == 0.5


def test_rolling_shutter_shifts_each_row_by_the_motion_during_its_readout():
    """A level camera moving along x at v: a point imaged at row r is seen from x = v t, t = (r - cy) row time,
    so its column moves by -f v t / depth (first order; the second iteration makes it exact)."""
    position, rotation = np.array([0.0, 0.0, 1.0]), rotation_from_angles(0.0, 0.0, 0.0)[0]
    rim = np.array([[0.3, 0.4, 2.5], [-0.2, -0.5, 2.5], [0.1, 0.0, 2.5]])
    still = _image_points(rim, position, rotation, _Imaging(CAM, 0.0, np.zeros(3), np.zeros(3)))
    v = 2.0
    moving = _image_points(rim, position, rotation, _Imaging(CAM, 0.0, np.array([v, 0.0, 0.0]), np.zeros(3)))
    depth = (rim - position) @ rotation[:, 2]
    t = (moving[:, 1] - CAM.cy_px) * CAM.row_time_s
    assert np.allclose(moving[:, 0] - still[:, 0], -CAM.fx_px * v * t / depth, atol=1e-6)
    assert np.abs(moving[:2, 0] - still[:2, 0]).min() > 10  # tens of pixels at 2 m/s over +-700 rows


def test_the_distortion_residual_has_the_stated_rms_over_the_image():
    u, v = np.meshgrid(np.linspace(0, CAM.width_px, 41), np.linspace(0, CAM.height_px, 31))
    px = np.column_stack([u.ravel(), v.ravel()])
    rays = np.column_stack([(px - [CAM.cx_px, CAM.cy_px]) / [CAM.fx_px, CAM.fy_px], np.ones(len(px))])
    k1 = 0.3 / (CAM.fx_px * _rms_r3(CAM))
    shifted = _Imaging(CAM, k1, np.zeros(3), np.zeros(3)).project(rays)
    assert math.isclose(np.sqrt(np.mean(np.sum((shifted - px) ** 2, axis=1))), 0.3, rel_tol=1e-6)


@pytest.fixture(scope="module")
def at_20_deg():
    """Each term alone on the paper's rig at 20 deg tilt, 16 trials each, the same poses."""
    runs = {"exact": NO_TERMS, "all": DEFAULT_TERMS, **{k: DEFAULT_TERMS.only(k) for k in TERMS}}
    return {k: paper_experiment((20,), 1, t)[0] for k, t in runs.items()}


def test_each_term_moves_the_fix_and_exact_images_leave_the_perspective_method_exact(at_20_deg):
    mean = {k: stats_cm(r.errors["perspective"])[0] for k, r in at_20_deg.items()}
    assert mean["exact"] < 1e-3  # under 10 um: the method itself is exact
    assert 1e-3 < mean["edge"] < 0.1
    assert mean["calibration"] > 3 * mean["edge"]
    assert mean["install"] > 1.0 and mean["skew"] > 1.0  # centimetres
    assert mean["all"] > max(mean["calibration"], mean["edge"])


def test_a_still_phone_has_no_skew():
    still = paper_experiment((20,), 1, ErrorTerms(speed_m_s=0.0, turn_rad_s=0.0).only("skew"))[0]
    assert stats_cm(still.errors["perspective"])[0] < 1e-3
    fast = paper_experiment((20,), 1, ErrorTerms(speed_m_s=2.0).only("skew"))[0]
    slow = paper_experiment((20,), 1, ErrorTerms(speed_m_s=0.5).only("skew"))[0]
    assert stats_cm(fast.errors["perspective"])[0] > 2 * stats_cm(slow.errors["perspective"])[0]


def test_table3_trend_holds_with_the_terms_on():
    """The paper's method with every term on: error grows with tilt, and level it lands near the paper's
    2.76 cm (pixel noise alone gives well under that)."""
    full = {r.tilt_deg: stats_cm(r.errors["paper"])[0] for r in paper_experiment((0, 20, 40), 2, DEFAULT_TERMS)}
    pixel = {r.tilt_deg: stats_cm(r.errors["paper"])[0] for r in paper_experiment((0,), 2, PIXEL_ONLY)}
    assert full[0] < full[20] < full[40]
    assert 1.5 < full[0] < 6.0 and pixel[0] < 0.5 * full[0]


def test_vlp_accuracy_shows_pixel_noise_only_beside_all_terms(capsys):
    assert accuracy_main(["--trials", "1", "--tilts", "0,40", "--phone-turn", "0", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["assumptions"]["terms"]["turn_deg_s"] == 0.0 and out["assumptions"]["terms"]["install_m"] == 0.02
    assert set(out["budget"]) == {"exact", "all", "install", "calibration", "edge", "skew"}
    assert out["pixel_only"] == out["budget"]["edge"] and out["tilts"] == out["budget"]["all"]
    for pixel, full in zip(out["pixel_only"], out["tilts"]):
        assert full["perspective"]["mean_cm"] > 10 * pixel["perspective"]["mean_cm"]
    assert accuracy_main(["--trials", "1", "--tilts", "20"]) == 0
    text = capsys.readouterr().out
    assert "pixel only" in text and "all terms" in text and "rolling-shutter skew (phone at 0.5 m/s" in text
    assert "error budget, perspective method" in text and "dominant" in text


def test_vlp_accuracy_refuses_a_negative_term(capsys):
    assert accuracy_main(["--phone-speed", "-1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--phone-speed" in err[0] and "non-negative" in err[0]


@pytest.mark.needs_poppler
def test_error_map_of_the_512_plan_is_centimetre_level_and_the_reports_say_what_it_includes(plan512_dir, tmp_path):
    """Done-when 5 of issue 18: the bundled 512 plan, default tolerances (128 poses, 1 per m2, to stay fast)."""
    plan = load_plan(plan512_dir / "plan.yaml")
    acc = site_accuracy(plan.xyz, plan.radii, plan.outline_xy, plan.camera_model(), per_m2=1.0)
    s = acc.summary()
    assert s["located"] > 80 and 0.005 < s["median_m"] < 0.10 and s["median_m"] < s["p90_m"] < 0.3
    three = [t for t in TERMS if t != "accelerometer"]  # the gravity receiver's term is off
    assert s["includes"] == three and set(s["budget"]) == {"exact", "all", *three}
    assert s["budget"]["edge"]["median_m"] < 0.001 < s["budget"][s["dominant"]]["median_m"]  # pixel noise: sub-mm
    site = tmp_path / "p512"
    shutil.copytree(plan512_dir, site)
    doc = yaml.safe_load((site / "plan.yaml").read_text())
    (site / "plan.yaml").write_text(dump_plan({**doc, "accuracy": s}))
    assert report_main([str(site / "plan.yaml"), "--json"]) == 0
    html = (site / "site-report.html").read_text()
    pdf = subprocess.run(["pdftotext", "-layout", str(site / "site-report.pdf"), "-"], capture_output=True,
                         text=True, check=True).stdout
    for text in (html, " ".join(pdf.split())):
        assert "includes luminaire install tolerance (uniform within 2 cm of the drawing)" in text
        assert "rolling-shutter skew (phone at 0.5 m/s turning 5 deg/s)" in text
        assert "Error budget" in text and "dominates" in text
        assert "pixel noise only" not in text


def test_the_dominant_term_is_the_largest_contribution_beyond_the_methods_own_error():
    from planner.positioning.error_terms import dominant

    assert dominant({"exact": 0.0, "install": 5.0, "skew": 4.0, "all": 7.0}) == "install"
    # the paper's method under tilt: every term alone is little more than its own 11 cm bias
    assert dominant({"exact": 11.0, "install": 11.8, "skew": 13.0, "all": 14.0}) == "exact"
    assert dominant({"exact": 3.0, "install": 5.0, "skew": 4.0}) == "install"
    assert dominant({"exact": 0.0, "edge": 0.01}) is None


@pytest.mark.slow
def test_vlp_plan_records_the_terms_it_was_given_and_the_report_names_what_is_left_out(tmp_path, capsys):
    from conftest import ROOT
    from planner.cli.plan import main as plan_main

    out = tmp_path / "p"
    assert plan_main([str(ROOT / "layouts" / "grid-32.yaml"), "-o", str(out), "--no-firmware", "--no-map",
                      "--install-error", "0.01", "--phone-speed", "0", "--phone-turn", "0"]) == 0
    text = capsys.readouterr().out
    assert "including luminaire install tolerance (uniform within 1 cm of the drawing)" in text
    acc = load_plan(out / "plan.yaml").accuracy
    assert acc.terms["install_m"] == 0.01 and acc.terms["speed_m_s"] == 0 and acc.terms["turn_deg_s"] == 0
    assert acc.includes == ["install", "calibration", "edge"] and set(acc.budget) == {"exact", "all", *acc.includes}
    assert acc.dominant in acc.includes and 0.001 < acc.median_m < 0.10
    html = (out / "site-report.html").read_text()
    assert "leaves out rolling-shutter skew" in html and "<h2 id=\"budget\">Error budget</h2>" in html


def test_rotating_about_an_axis_matches_scipy():
    from scipy.spatial.transform import Rotation

    from planner.positioning.error_terms import _rotate

    rng = np.random.default_rng(3)
    v, axis, angle = rng.normal(size=(50, 3)), np.array([0.6, 0.0, 0.8]), rng.normal(scale=0.3, size=50)
    angle[0] = 0.0
    assert np.allclose(_rotate(v, axis, angle), Rotation.from_rotvec(angle[:, None] * axis).apply(v), atol=1e-12)


def test_a_plan_from_before_the_budget_says_its_figures_are_edge_noise_only():
    from conftest import minimal_plan
    from planner.report.content import budget_rows, summary

    old = {"method": "perspective", "noise_px": 0.5, "poses": 10, "located": 8, "median_m": 6e-05, "p90_m": 1.5e-04,
           "max_m": 3e-04, "cell_m": 1.0}
    plan = minimal_plan([{"name": "A", "id": 1}], accuracy=old)
    rows = dict(summary(plan, []))
    assert "median 0.06 mm" in rows["expected error"]
    assert "includes edge noise (0.5 px) only: install, calibration and motion errors come on top" in rows["expected error"]
    assert "error budget" not in rows and budget_rows(plan) == []


def test_vlp_accuracy_takes_a_camera_profile():
    """The rig with another phone: --camera NAME reaches the simulation (its field of view shows) and a wrong
    name is one line, exit 2."""
    run = vlp("vlp-accuracy", "--trials", "1", "--tilts", "0", "--pixel-noise-only", "--camera", "wide", "--json")
    assert run.returncode == 0, run.stderr
    doc = json.loads(run.stdout)
    assert doc["assumptions"]["camera"]["name"] == "wide" and doc["assumptions"]["camera"]["distortion"]
    bad = vlp("vlp-accuracy", "--camera", "nope")
    assert bad.returncode == 2 and len(bad.stderr.splitlines()) == 1 and "profiles: paper" in bad.stderr
