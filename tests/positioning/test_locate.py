"""vlp-locate: identifying luminaires from a plan whose IDs repeat, then positioning; its errors."""

import json

import numpy as np
import pytest

from planner.camera.ellipse import Ellipse
from planner.camera.model import Camera, rotation_from_angles
from planner.cli.locate import console_main
from planner.errors import InputError, PositioningError
from planner.plan.file import load_plan
from planner.positioning.locate import Site, Snapshot, identify, locate
from planner.positioning.observation import observe
from planner.positioning.snapshot_file import parse_snapshot
from planner.verify.windows import sample_poses, working_area


@pytest.fixture(scope="module")
def plan_path(plan256_dir):
    return plan256_dir / "plan.yaml"


@pytest.fixture(scope="module")
def site(plan_path):
    return Site.from_plan(load_plan(plan_path))


def snapshot_at(site, position, rotation, rng=None):
    seen = observe(position, rotation, site.xyz, site.radii, Camera(), rng)
    return seen, Snapshot(Camera(), [int(site.ids[k]) for k in seen.index], seen.ellipses)


@pytest.mark.slow
def test_ids_repeat_and_every_covered_pose_is_identified_and_located(site, plan_path):
    assert len(set(site.ids)) <= len(site.ids) / 4  # a short code: each ID names four luminaires or more (6-bit proved plan of 256)
    poses = sample_poses(working_area(site.xyz[:, :2], load_plan(plan_path).outline), Camera(), per_m2=1, seed=4)
    rng = np.random.default_rng(0)
    located = 0
    for k in range(len(poses)):
        seen, snap = snapshot_at(site, poses.position[k], poses.rotation[k], rng)
        if len(seen.index) < 3:
            continue
        try:
            found = identify(site, snap)
        except PositioningError as exc:
            assert "one line" in str(exc)  # the only refusal a covered pose may get
            continue
        assert list(found.luminaires) == list(seen.index)
        assert np.linalg.norm(found.fix.position - poses.position[k]) < 2e-3
        located += 1
    assert located >= 30


def test_paper_method_uses_the_three_leds_nearest_the_centre(site):
    position, rotation = np.array([3.1, 2.2, 1.0]), rotation_from_angles(np.radians(30), 1.0, 0.3)[0]
    seen, snap = snapshot_at(site, position, rotation)
    found = locate(site, snap, "paper")
    assert list(found.fix.used) == [0, 1, 2] and found.fix.method == "paper"
    assert 0.001 < np.linalg.norm(found.fix.position - position) < 0.5


def test_an_image_that_fits_two_places_is_refused():
    block = np.array([[x, y, 2.5] for x in (0.0, 0.5, 1.0) for y in (0.0, 0.5, 1.0)])
    xyz = np.vstack([block, block + [10.0, 0.0, 0.0]])
    twin = Site([f"L{k}" for k in range(18)], xyz, np.full(18, 0.1), np.tile(np.arange(1, 10), 2))
    _, snap = snapshot_at(twin, np.array([0.5, 0.5, 1.2]), rotation_from_angles(0.2, 0.5, 0.1)[0])
    with pytest.raises(PositioningError, match="fits two places"):
        identify(twin, snap)


def test_ellipses_no_pose_explains_are_refused(site):
    _, snap = snapshot_at(site, np.array([3.1, 2.2, 1.0]), rotation_from_angles(0.3, 2.0, 0.0)[0])
    e = snap.ellipses[1]
    bent = snap.ellipses[:1] + [Ellipse(e.cx, e.cy, 1.6 * e.major, 1.6 * e.minor, e.angle_rad)] + snap.ellipses[2:]
    with pytest.raises(PositioningError, match="no place on the site explains"):
        locate(site, Snapshot(snap.camera, snap.ids, bent))


def _run(args, capsys):
    code = console_main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def test_vlp_locate_round_trip_with_both_methods(plan_path, tmp_path, capsys):
    code, out, _ = _run([plan_path, "--simulate", "3.1,2.2,1.0,30,60,20", "--seed", "2"], capsys)
    assert code == 0
    obs = tmp_path / "obs.json"
    obs.write_text(out)
    code, out, _ = _run([plan_path, obs], capsys)
    result = json.loads(out)
    assert code == 0 and result["method"] == "perspective" and result["residual_px"] < 1.0
    assert np.allclose(result["position_m"], [3.1, 2.2, 1.0], atol=2e-3)
    assert result["orientation_deg"]["tilt"] == pytest.approx(30, abs=0.1)
    assert len(result["luminaires"]) == len(json.loads(obs.read_text())["leds"])
    assert result["explains_image"] is True
    code, out, err = _run([plan_path, obs, "--method", "paper"], capsys)
    paper = json.loads(out)
    assert code == 0 and paper["method"] == "paper" and len(paper["luminaires"]) == 3
    assert paper["explains_image"] is False and "warning" in err  # weak perspective under a 30 deg tilt


def _observation(leds):
    return {"camera": {"fx": 4250.0, "fy": 4250.0, "cx": 2000.0, "cy": 1500.0, "width": 4000, "height": 3000},
            "leds": leds}


def _led(i, cx=2000.0):
    return {"id": i, "ellipse": {"cx": cx, "cy": 1500.0, "major": 400.0, "minor": 380.0, "angle_deg": 10.0}}


@pytest.mark.parametrize("content, code, message", [
    (None, 1, "no such observation file"),
    ("{\"camera\": ", 1, "line 1: not valid JSON"),
    (_observation([{"id": 1}]), 1, "leds[0].ellipse: is missing"),
    (_observation([_led(1), _led(2, 2500.0), _led(999, 1500.0)]), 1, "ID 999 is not in the plan"),
    (_observation([_led(1), _led(2, 2500.0)]), 3, "2 LEDs in the image: a position needs at least three"),
    (_observation([_led(1), _led(2, 2500.0), _led(3, 3000.0)]), 3, "lie on one line"),
    (_observation([_led(1, 4200.0)]), 1, "lies outside the 4000 x 3000 px image"),
])
def test_bad_observations_give_one_line_and_an_exit_code(plan_path, tmp_path, capsys, content, code, message):
    obs = tmp_path / "obs.json"
    if content is not None:
        obs.write_text(content if isinstance(content, str) else json.dumps(content))
    got, out, err = _run([plan_path, obs], capsys)
    assert got == code and out == "" and message in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("change, message", [
    (lambda d: d["leds"][0].update(id=True), "leds[0].id: must be a valid integer (got True)"),
    (lambda d: d["leds"][0].update(id=-1), "leds[0].id: must be greater than or equal to 0 (got -1)"),
    (lambda d: d["camera"].update(fx="4250"), "camera.fx: must be a valid number (got '4250')"),
    (lambda d: d["camera"].update(width=1e9), "camera.width: must be a valid integer (got 1000000000.0)"),
    (lambda d: d["leds"][0]["ellipse"].update(minor=500.0), "minor axis 500 px is longer than major 400 px"),
    (lambda d: d.update(leds=[_led(1)] * 2001), "leds: must have at most 2000 items, not 2001"),
])
def test_observation_fields_are_checked_by_path(change, message):
    doc = _observation([_led(1), _led(2, 2500.0), _led(3, 3000.0)])
    change(doc)
    with pytest.raises(InputError) as err:
        parse_snapshot(doc, "obs.json")
    assert str(err.value).startswith("obs.json: ") and message in str(err.value)


def test_locate_needs_an_observation_or_a_pose(plan_path, capsys):
    code, _, err = _run([plan_path], capsys)
    assert code == 2 and "OBSERVATION.json" in err
    code, _, err = _run([plan_path, "--simulate", "1,2,3"], capsys)
    assert code == 2 and "six numbers" in err



def test_anchor_triple_looks_past_a_row_of_leds_listed_first():
    """Regression (found by the receiver twin): the anchor triple was sought among the first six
    LEDs only, so a snapshot in scan order, one collinear row first, was refused as "one line"."""
    from planner.positioning.fix import anchor_triple

    row = [(100.0 + 300 * k, 200.0) for k in range(6)]
    centres = np.array(row + [(400.0, 900.0), (1300.0, 950.0)])
    best = anchor_triple(centres)
    assert 6 in best or 7 in best
    with pytest.raises(PositioningError, match="one line"):
        anchor_triple(np.array(row + [(2000.0, 200.0)]))  # all on one line: still refused
