"""The paper's experiment in simulation (Table 3), vlp-accuracy, and the error map in plans."""


import numpy as np
import pytest

from conftest import ROOT
from planner.cli.accuracy import console_main
from planner.cli.plan import main as plan_main
from planner.plan.file import load_plan
from planner.positioning.accuracy import PAPER_LEDS_M, paper_experiment, paper_test_points, stats_cm


@pytest.fixture(scope="module")
def table3():
    return {r.tilt_deg: r for r in paper_experiment()}  # the paper's protocol: 16 points x 10 trials


@pytest.mark.slow
def test_every_trial_sees_three_whole_leds(table3):
    aims, azimuths = paper_test_points()
    assert len(aims) == len(azimuths) == 16 and len(PAPER_LEDS_M) == 4
    for r in table3.values():
        assert r.unusable == 0
        assert all(len(e) == 160 and np.isfinite(e).all() for e in r.errors.values())


def test_paper_method_error_grows_with_tilt(table3):
    mean = {t: stats_cm(r.errors["paper"])[0] for t, r in table3.items()}
    assert mean[0] < mean[20] < mean[40]
    assert 3 < mean[20] < 30 and 3 < mean[40] < 30  # the paper's 7-12 cm, same order


def test_perspective_method_is_ten_times_better_at_40_degrees(table3):
    r = table3[40.0]
    paper, persp = stats_cm(r.errors["paper"])[0], stats_cm(r.errors["perspective"])[0]
    assert persp * 10 <= paper
    assert all(stats_cm(t.errors["perspective"])[1] < 0.5 for t in table3.values())  # 90 % under 5 mm


def test_vlp_accuracy_prints_table3_and_draws_the_cdf(tmp_path, capsys):
    cdf = tmp_path / "cdf.png"
    assert console_main(["--trials", "1", "--tilts", "0,40", "--cdf", str(cdf)]) == 0
    out = capsys.readouterr().out
    assert "paper's Table 3" in out and "11.72" in out and "LED radius 0.1 m" in out
    assert cdf.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert console_main(["--tilts", "95", "--cdf", str(cdf)]) == 2


@pytest.mark.slow
def test_plans_carry_an_error_map(tmp_path):
    out = tmp_path / "p"
    plan_main([str(ROOT / "layouts" / "grid-32.yaml"), "-o", str(out), "--json", "--error-poses-per-m2", "20",
               "--locate-method", "paper"])
    acc = load_plan(out / "plan.yaml").accuracy
    assert acc.method == "paper" and acc.located > 20 and acc.poses >= acc.located
    assert 0 < acc.median_m <= acc.p90_m <= acc.max_m < 1.0
    assert (out / "error.png").read_bytes()[:4] == b"\x89PNG"


def test_vlp_accuracy_writes_no_file_unless_asked(tmp_path, monkeypatch, capsys):
    import json

    monkeypatch.chdir(tmp_path)
    assert console_main(["--trials", "1", "--tilts", "0", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["cdf"] is None and list(tmp_path.iterdir()) == []
