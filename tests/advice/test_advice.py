"""Site advice: the table's recommended change, applied with vlp-plan, reaches the coverage goal; plans
below 50 % say NOT USABLE and exit 3; every README vlp-plan command is usable or says it is not."""

import json
import re
import shlex

import pytest
import yaml

from conftest import ROOT, shared_vlp_plan, vlp

LAYOUTS = ROOT / "layouts"


FAST = ("--json", "--no-report", "--no-map", "--error-poses-per-m2", "0")


def _plan(args: list[str], cwd) -> tuple[int, dict, str]:
    """Run the installed vlp-plan with ``--json``: exit code, JSON summary, stderr."""
    run = vlp("vlp-plan", *args, *FAST, cwd=cwd)
    assert "Traceback" not in run.stderr, run.stderr
    return run.returncode, json.loads(run.stdout), run.stderr


def _apply(row: dict, tmp_path) -> list[str]:
    """The vlp-plan flags of an advice row."""
    flags = list(row["flags"])
    assert row["applicable_by_flags"] and flags
    return flags


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    """The paper's rig planned once with its site report (no maps): exit code, JSON summary, stderr, folder."""
    tmp = tmp_path_factory.mktemp("rig")
    run = vlp("vlp-plan", str(LAYOUTS / "paper-rig.yaml"), "-o", str(tmp / "rig"), "--json", "--no-map", cwd=tmp)
    assert "Traceback" not in run.stderr, run.stderr
    return run.returncode, json.loads(run.stdout), run.stderr, tmp / "rig"


def test_recommended_change_applied_reaches_the_goal(rig, tmp_path):
    code, before, err, _ = rig
    advice = before["advice"]
    assert code == 3 and "NOT USABLE" in err
    assert not advice["usable"] and advice["coverage"] < advice["usable_from"] <= advice["goal"] == 0.9
    assert advice["method"] == "sampled" and advice["coverage"] == before["verification"]["coverage"]
    row = advice["changes"][advice["recommended"]]
    assert row["reaches_goal"] and row["coverage"] >= 0.9
    code, after, err = _plan([str(LAYOUTS / "paper-rig.yaml"), "-o", str(tmp_path / "after"),
                              *_apply(row, tmp_path)], tmp_path)
    assert code == 0, err
    assert after["verification"]["coverage"] >= advice["goal"]
    assert after["advice"]["usable"] and after["advice"]["meets_goal"] and after["advice"]["changes"] == []


def test_outline_room_advice_needs_two_changes_and_the_gravity_receiver_is_one():
    """The README's 2 m lattice: no single change tried reaches 90 %; the recommended pair does, on the
    advice's sample and on a sample as dense as the plan's. The gravity receiver is a candidate (it needs
    two whole LEDs, not three) and is in the recommended pair, beside a wider lens, by coverage alone (no
    frame limits given: with the bundled drivers' it needs faster ones, tests/advice/test_advice_frames.py)."""
    import numpy as np

    from planner.advice.advise import RECEIVERS, Site, advise
    from planner.camera.model import Camera
    from planner.layout.read import read_layout

    layout = read_layout(LAYOUTS / "outline-room.dxf", 128)
    site = Site(layout.xyz, np.array([lum.radius for lum in layout.luminaires]), layout.outline,
                Camera(), filled=True)
    advice = advise(site, 0.0)
    rec = advice.recommended
    assert rec is not None and len(rec.changes) == 2 and {c.knob for c in rec.changes} == {"camera", "receiver"}
    assert all(not r.reaches for r in advice.rows if len(r.changes) == 1)
    changed = site
    for c in rec.changes:
        changed = c.apply(changed)
    assert changed.receiver == "gravity"
    assert RECEIVERS["gravity"](changed, 100.0, 1) >= 0.9  # a fresh, denser sample agrees
    assert RECEIVERS["three"](changed, 100.0, 1) < 0.9  # the three-LED receiver with that lens does not reach it
    assert advice.summary()["measure"].endswith("three whole, non-collinear LEDs")  # the plan's own mode


def _readme_commands() -> list[list[str]]:
    text = (ROOT / "README.md").read_text()
    found = re.findall(r"(?:^|\$ |`|&& )vlp-plan (layouts/[^`\n]*)", text, flags=re.M)
    commands = sorted({tuple(shlex.split(c.strip())) for c in found})
    assert commands, "no vlp-plan command found in README.md"
    return [list(c) for c in commands]


@pytest.mark.parametrize("args", [a for a in _readme_commands() if "layouts/grid-512.yaml" not in a],
                         ids=lambda a: " ".join(a))
def test_readme_command_is_usable_or_says_it_is_not(args, tmp_path_factory):
    if "-o" in args:  # write into a shared folder instead
        args = args[:args.index("-o")] + args[args.index("-o") + 2:]
    # run once per test run: tests/twin/test_gravity_office.py reads the office command's plan
    run = shared_vlp_plan(tmp_path_factory, *args, *FAST)
    assert "Traceback" not in run.stderr, run.stderr
    code, summary, err = run.returncode, json.loads(run.stdout), run.stderr
    advice = summary["advice"]
    if advice["usable"]:
        assert code == 0
    else:
        assert code == 3 and "NOT USABLE" in err
        assert advice["recommended"] is not None  # and says what would work


def test_readme_grid_512_is_usable(plan512_dir):
    assert any("layouts/grid-512.yaml" in a for a in _readme_commands())
    doc = yaml.safe_load((plan512_dir / "plan.yaml").read_text())
    assert doc["advice"]["usable"] and doc["verification"]["coverage"] >= 0.5


def test_not_usable_summary_text_is_not_an_endorsement(tmp_path):
    run = vlp("vlp-plan", str(LAYOUTS / "corridor.csv"), "-o", str(tmp_path / "o"), "--no-report",
              "--no-map", "--error-poses-per-m2", "0")
    assert run.returncode == 3
    lines = run.stdout.splitlines()
    verdict = next(line for line in lines if line.startswith("  verdict"))
    # neither mode serves the corridor; the planner keeps the one that decodes more and says so
    receiver = next(line for line in lines if line.startswith("  receiver"))
    assert receiver.startswith("  receiver gravity (decodes more sampled poses")
    assert "NOT USABLE" in verdict and "see fewer than two whole LEDs" in verdict
    assert not any("verified" in line for line in lines if line.startswith("  schemes"))
    assert "not an endorsement" in next(line for line in lines if line.startswith("  proof"))
    table = lines[lines.index(next(line for line in lines if line.startswith("  advice"))) + 1:]
    assert table[0].split()[:3] == ["as", "planned", "(this"]
    again = vlp("vlp-plan", str(LAYOUTS / "corridor.csv"), "-o", str(tmp_path / "o"), "--no-report",
                "--no-map", "--error-poses-per-m2", "0", "--allow-unusable")
    assert again.returncode == 0 and "NOT USABLE" in again.stderr


def test_site_report_shows_the_advice_and_no_classes_under_the_window_scheme(rig, tmp_path):
    import shutil

    code, _, _, planned = rig
    assert code == 3
    out = tmp_path / "rig"
    shutil.copytree(planned, out)  # edited below
    html = (out / "site-report.html").read_text()
    section = html[html.index('<h2 id="advice">'):html.index("<h2", html.index('<h2 id="advice">') + 1)]
    assert "NOT USABLE" in section and "Sampled figures, not proved" in section
    assert "--camera ultrawide" in section and "recommended: reaches the goal" in section
    doc = yaml.safe_load((out / "plan.yaml").read_text())
    assert doc["scheme"] == "window" and "<th>class</th>" not in html  # odd/even means nothing here
    doc["advice"]["recommended"] = 99  # a hand-edited plan naming no row: one line, exit 1
    (out / "plan.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    bad = vlp("vlp-report", str(out / "plan.yaml"))
    assert bad.returncode == 1 and "Traceback" not in bad.stderr
    assert len(bad.stderr.strip().splitlines()) == 1 and "advice.recommended 99" in bad.stderr
