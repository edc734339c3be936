"""vlp-verify says NOT USABLE of a plan under the usable coverage, as vlp-plan does, and exits as it does: 3,
unless the plan was made with --allow-unusable (issue 19)."""

import json
import subprocess

import pytest
import yaml

from conftest import ROOT, grid32_copy, vlp

CORRIDOR = str(ROOT / "layouts" / "corridor.csv")  # about 9 % of poses see three whole LEDs: NOT USABLE


def _run(*args: str) -> subprocess.CompletedProcess:
    run = vlp(*args)
    assert "Traceback" not in run.stderr, run.stderr
    return run


@pytest.fixture(scope="module")
def plans(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("corridor")
    out = {}
    for name, extra in (("strict", ()), ("allowed", ("--allow-unusable",))):
        made = _run("vlp-plan", CORRIDOR, "-o", str(tmp / name), "--no-report", "--no-map", "--no-firmware",
                    "--error-poses-per-m2", "0", "--receiver", "three", *extra)
        assert made.returncode == (0 if extra else 3) and "NOT USABLE" in made.stderr
        out[name] = tmp / name / "plan.yaml"
    return out


def test_vlp_verify_says_not_usable_and_exits_3(plans):
    run = _run("vlp-verify", str(plans["strict"]))
    assert run.returncode == 3
    lines = run.stdout.splitlines()
    verdict = next(line for line in lines if line.startswith("  verdict"))
    assert "NOT USABLE: only" in verdict and "see fewer than three whole LEDs" in verdict
    proof = next(line for line in lines if line.startswith("  proof"))
    assert not proof.endswith("proved") and "not an endorsement" in proof  # never a bare "proved"
    assert run.stderr.startswith("vlp-verify: NOT USABLE: only") and len(run.stderr.strip().splitlines()) == 1
    assert "--allow-unusable" not in run.stderr


def test_vlp_verify_json_carries_the_verdict(plans):
    run = _run("vlp-verify", str(plans["strict"]), "--json")
    assert run.returncode == 3
    summary = json.loads(run.stdout)
    assert summary["usable"] is False and summary["verdict"].startswith("NOT USABLE")
    assert summary["coverage"] < 0.5


def test_a_plan_made_with_allow_unusable_verifies_with_exit_0_and_still_says_so(plans):
    assert yaml.safe_load(plans["allowed"].read_text())["advice"]["allow_unusable"] is True
    assert yaml.safe_load(plans["strict"].read_text())["advice"]["allow_unusable"] is False
    run = _run("vlp-verify", str(plans["allowed"]))
    assert run.returncode == 0
    assert "NOT USABLE" in run.stdout and "(the plan was made with --allow-unusable)" in run.stderr


def test_a_usable_plan_verifies_with_exit_0_and_no_warning(tmp_path_factory):
    plan = grid32_copy(tmp_path_factory, tmp_path_factory.mktemp("g") / "g", "--error-poses-per-m2", "0")  # exit 0
    run = _run("vlp-verify", str(plan))
    assert run.returncode == 0 and run.stderr == ""
    verdict = next(line for line in run.stdout.splitlines() if line.startswith("  verdict"))
    assert "NOT USABLE" not in verdict and ("meets the goal" in verdict or "usable, below the goal" in verdict)
