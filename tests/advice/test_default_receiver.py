"""The receiver that fits, chosen by vlp-plan without --receiver (issue 38): the paper's three-LED receiver where
its plan is usable, the mode that decodes more where it is not, and a site no mode serves still gets its plan,
map, verdict and advice (exit 3), never a bare error."""

from __future__ import annotations

import json
import subprocess

import pytest
import yaml

from conftest import ROOT, vlp
from dxf_factory import office_48


def _run(args: list[str], cwd) -> subprocess.CompletedProcess:
    done = vlp("vlp-plan", *args, cwd=cwd)
    assert "Traceback" not in done.stderr, done.stderr
    return done


def test_the_48_luminaire_millimetre_office_gets_a_plan_map_and_report_without_a_receiver_flag(tmp_path):
    """The drawing of Done-when 1 (switches and columns on the lighting layer): before, exit 1 and nothing
    written ("no sampled camera pose sees three whole LEDs"); now the planner picks the mode and says why."""
    doc, _ = office_48()
    doc.saveas(tmp_path / "office.dxf")
    done = _run(["office.dxf", "--leds", "48"], tmp_path)
    assert done.returncode in (0, 3), done.stderr
    out = tmp_path / "office-vlp"
    for name in ("plan.yaml", "map.png", "site-report.html", "site-report.pdf"):
        assert (out / name).is_file(), name
    plan = yaml.safe_load((out / "plan.yaml").read_text())
    receiver = plan["receiver"]
    assert set(receiver["coverage"]) == {"three", "gravity"}  # the paper's falls short, so both were planned
    assert receiver["mode"] == max(receiver["coverage"], key=receiver["coverage"].get) == "gravity"
    assert f"receiver {receiver['mode']} (" in done.stdout and "decodes more sampled poses" in done.stdout
    verdict = next(line for line in done.stdout.splitlines() if line.startswith("  verdict"))
    usable = plan["advice"]["usable"]
    assert done.returncode == (0 if usable else 3)
    if not usable:  # the verdict names the trouble and the advice what would fix it
        assert "NOT USABLE" in verdict and plan["advice"]["changes"]
        assert plan["advice"]["recommended"] is not None and "recommended" in done.stdout
    assert plan["modulation"] is not None and (out / "firmware").is_dir()


def _sparse(tmp_path):
    """Twelve small lights 5 m apart on a 2.6 m ceiling, as on a house's electrical drawing."""
    rows = [f"- {{name: L{j}{i}, x: {2 + 5 * i}, y: {2 + 5 * j}}}" for j in range(3) for i in range(4)]
    (tmp_path / "house.yaml").write_text("unit: m\nheight: 2.6\nradius: 0.05\nluminaires:\n" + "\n".join(rows) + "\n")


@pytest.fixture(scope="module")
def house(tmp_path_factory):
    """The sparse house planned once with every output (``vlp-plan house.yaml --json``): the run and its folder."""
    tmp = tmp_path_factory.mktemp("house")
    _sparse(tmp)
    return _run(["house.yaml", "--json"], tmp), tmp


def test_a_site_no_mode_serves_gets_its_plan_verdict_and_advice_without_frames(house):
    done, tmp_path = house
    assert done.returncode == 3, done.stderr
    summary = json.loads(done.stdout)
    assert summary["receiver"]["coverage"] == {"three": 0.0, "gravity": 0.0}
    assert summary["receiver"]["mode"] == "three" and "no mode decodes" in summary["receiver"]["reason"]
    assert summary["modulation"] is None and "no LED image to fit a frame into" in summary["no_frames"]
    assert not summary["advice"]["usable"] and summary["advice"]["changes"]
    out = tmp_path / "house-vlp"
    names = sorted(p.name for p in out.iterdir())
    assert names == ["coverage.png", "house-vlp.dxf", "map.png", "plan.yaml", "site-report.html",
                     "site-report.pdf"]  # no firmware without frames, no error map without a fix
    plan = yaml.safe_load((out / "plan.yaml").read_text())
    assert plan["modulation"] is None and plan["no_frames"] == summary["no_frames"]
    assert all("frame" not in e for e in plan["luminaires"])
    assert "NOT USABLE" in done.stderr


def test_the_frameless_plan_reads_back_and_vlp_verify_judges_it(house):
    _, tmp_path = house  # vlp-verify only reads the plan: the folder stays as the test above reads it
    done = vlp("vlp-verify", "house-vlp/plan.yaml", cwd=tmp_path)
    assert done.returncode == 3 and "Traceback" not in done.stderr, done.stderr
    assert "NOT USABLE" in done.stdout + done.stderr


def test_without_verification_the_default_is_the_papers_receiver_and_no_window_is_an_error(tmp_path):
    _sparse(tmp_path)
    done = _run(["house.yaml", "--no-verify", "--scheme", "paper"], tmp_path)
    assert done.returncode == 1 and done.stderr.count("\n") == 1, done.stderr
    assert "no sampled camera pose sees three whole, non-collinear LEDs" in done.stderr
    assert not (tmp_path / "house-vlp").exists()
    plan = _run([str(ROOT / "layouts" / "grid-32.yaml"), "--no-verify", "--scheme", "paper", "-o", "g", "--json",
                 "--no-report", "--no-map", "--no-firmware", "--error-poses-per-m2", "0"], tmp_path)
    assert plan.returncode == 0, plan.stderr
    assert json.loads(plan.stdout)["receiver"] == {"mode": "three"}
