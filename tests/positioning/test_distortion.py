"""Lens distortion through every stage: the view, its proof, image rows, observations and vlp-locate.

Issue 18's second "Done when": with a distorted camera YAML, ``vlp-locate`` on observations
simulated with that distortion errs under 1 cm at 40 deg tilt, and ignoring the distortion
makes it worse by a measured factor (docs/positioning.md, "Distortion").
"""

import json
import math
import re

import numpy as np
import pytest
import yaml

from conftest import ROOT, STRONG_WIDE_CAMERA
from planner.camera.ellipse import Ellipse
from planner.camera.file import camera_profile
from planner.camera.model import Camera, disc_image_rows, project_discs_at, rotation_from_angles
from planner.cli.locate import console_main as locate_main
from planner.cli.plan import console_main as plan_main
from planner.cli.verify import console_main as verify_main
from planner.errors import PositioningError
from planner.plan.file import load_plan
from planner.positioning.locate import Site, Snapshot
from planner.positioning.observation import observe, rim_points
from planner.positioning.snapshot_file import snapshot_document
from planner.positioning.undistort import ideal_ellipses
from planner.verify.envelope import NotProvable, proved_view

WIDE = Camera.from_dict(STRONG_WIDE_CAMERA)
PROFILE = camera_profile("wide")

POSES_40_DEG = ["2.0,1.0,1.0,40,30,10", "1.6,0.9,1.4,40,200,75", "2.4,1.2,0.6,40,120,300", "1.8,1.1,1.2,40,300,160"]
"""Camera poses (X,Y,Z [m], tilt, azimuth, roll [deg]) under the 4 x 8 grid, all at the largest tilt."""


def _camera(**kw) -> Camera:
    return Camera.from_dict({**STRONG_WIDE_CAMERA, **kw})


# --- the view and its proof ----------------------------------------------------------------------

@pytest.mark.parametrize("distortion", [(-0.2, 0.05), (0.15,), (-0.1, 0.02, 0.0, 0.0, -0.01)])
def test_the_view_maps_onto_the_sensor_and_is_proved(distortion):
    camera = _camera(distortion=list(distortion))
    proved_view(camera)  # raises if not proved
    u0, u1, v0, v1 = camera.view_px
    t = np.linspace(0, 1, 5001)
    border = np.concatenate([np.column_stack([u0 + (u1 - u0) * t, np.full_like(t, v)]) for v in (v0, v1)]
                            + [np.column_stack([np.full_like(t, u), v0 + (v1 - v0) * t]) for u in (u0, u1)])
    on_sensor = camera.distorted_pixels(border)
    assert on_sensor.min(axis=0).min() >= -1e-6 and (on_sensor <= [4000 + 1e-6, 3000 + 1e-6]).all()
    # tight: the view reaches the sensor's edge (barrel: the edge midpoints; pincushion: the corners)
    assert max(-on_sensor[:, 0].min(), on_sensor[:, 0].max() - 4000, -on_sensor[:, 1].min(),
               on_sensor[:, 1].max() - 3000) > -0.01


def test_an_ideal_camera_views_its_whole_sensor():
    assert Camera().view_px == (0.0, 4000.0, 0.0, 3000.0)


@pytest.mark.parametrize("fields, words", [
    ({"distortion": [-0.2, 0.05, 0.001, 0.0]}, "tangential distortion (p1=0.001"),
    ({"lens": "fisheye", "distortion": [0.02, -0.01], "fx_px": 2400.0, "fy_px": 2400.0}, "fisheye lens is verified by sampling"),
    ({"distortion": [-0.26], "fx_px": 2900.0, "fy_px": 2900.0}, "folds inside the image (in its corners, beyond the view)"),
])
def test_what_the_proof_does_not_cover_says_why(fields, words):
    with pytest.raises(NotProvable, match=re.escape(words)):
        proved_view(_camera(**fields))


def test_an_led_where_the_lens_model_folds_is_refused_not_mislocated():
    folding = _camera(distortion=[-0.26], fx_px=2900.0, fy_px=2900.0)  # folds in the image's corners only
    corner = Ellipse(3950.0, 2950.0, 40.0, 30.0, 0.3)
    with pytest.raises(PositioningError, match="where the camera's lens model folds"):
        ideal_ellipses([Ellipse(2000.0, 1500.0, 40.0, 30.0, 0.0), corner], folding)


def test_a_disc_counted_whole_has_its_whole_distorted_rim_on_the_sensor():
    rng = np.random.default_rng(3)
    n = 400
    position = np.column_stack([rng.uniform(0, 4, n), rng.uniform(0, 2, n), rng.uniform(0.5, 1.5, n)])
    rotation = rotation_from_angles(rng.uniform(0, math.radians(40), n), rng.uniform(0, 2 * np.pi, n),
                                    rng.uniform(0, 2 * np.pi, n))
    xyz = np.column_stack([rng.uniform(-1, 5, (n, 6)), rng.uniform(-1, 3, (n, 6)), np.full((n, 6), 2.5)])
    xyz = xyz.reshape(n, 3, 6).transpose(0, 2, 1).copy()
    radii = np.full((n, 6), 0.1)
    whole = project_discs_at(position, rotation, xyz, radii, WIDE)["inside"]
    assert 100 < whole.sum() < whole.size  # both kinds are tested
    for p, k in zip(*np.nonzero(whole)):
        rim = rim_points(position[p], rotation[p], xyz[p, k][None], radii[p, k][None], WIDE, [256])
        assert (rim >= 0).all() and (rim <= [4000, 3000]).all()


def test_distorted_image_rows_are_a_tight_lower_bound():
    rng = np.random.default_rng(5)
    position = np.array([[1.0, 1.0, 1.0]] * 50)
    rotation = rotation_from_angles(rng.uniform(0, math.radians(40), 50), rng.uniform(0, 2 * np.pi, 50), 0.0)
    centres = np.column_stack([rng.uniform(0, 2, 50), rng.uniform(0, 2, 50), np.full(50, 2.5)])[:, None, :]
    radii = np.full((50, 1), 0.1)
    rows = disc_image_rows(position, rotation, centres, radii, WIDE)[:, 0]
    dense = np.array([np.ptp(rim_points(position[k], rotation[k], centres[k], radii[k], WIDE, [4000])[:, 1])
                      for k in range(50)])
    assert (rows <= dense + 1e-9).all() and (rows >= 0.995 * dense).all()
    ideal = disc_image_rows(position, rotation, centres, radii, WIDE.ideal())[:, 0]
    assert np.abs(rows / ideal - 1).max() > 0.05  # the lens changes image heights: the bound is needed


# --- planning, verifying and locating with a distorted camera YAML --------------------------------

def test_plan_records_the_lens_and_the_proof_holds(wide_plan_dir, capsys):
    plan = load_plan(wide_plan_dir / "plan.yaml")
    assert plan.camera_model() == PROFILE and PROFILE.distorted
    assert verify_main([str(wide_plan_dir / "plan.yaml"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["decodability"] == "proved" and out["window_set"]["proved"]
    assert out["window_set"]["envelope"]["corner_deg"] == pytest.approx(45.66, abs=0.01)  # the view's corner


def test_plan_and_verify_with_a_strongly_distorting_camera_yaml(tmp_path, capsys):
    cam = tmp_path / "strong.yaml"
    cam.write_text(yaml.safe_dump(STRONG_WIDE_CAMERA))
    out = tmp_path / "out"
    assert plan_main([str(ROOT / "layouts" / "grid-32.yaml"), "--camera", str(cam), "-o", str(out), "--no-map",
                      "--no-report", "--no-firmware", "--error-poses-per-m2", "0"]) == 0
    capsys.readouterr()
    assert load_plan(out / "plan.yaml").camera_model() == WIDE
    assert verify_main([str(out / "plan.yaml"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["decodability"] == "proved" and summary["ambiguous"] == 0
    assert summary["window_set"]["envelope"]["corner_deg"] == pytest.approx(44.49, abs=0.01)


def test_verify_with_a_tangential_lens_samples_and_says_why(wide_plan_dir, tmp_path, capsys):
    cam = tmp_path / "tangential.yaml"
    cam.write_text(yaml.safe_dump({**STRONG_WIDE_CAMERA, "distortion": [-0.2, 0.05, 0.002, -0.001]}))
    code = verify_main([str(wide_plan_dir / "plan.yaml"), "--camera", str(cam), "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["decodability"] == "sampled only" and not out["window_set"]["proved"]
    assert "tangential distortion" in out["window_set"]["not_proved_because"]


def test_a_folding_lens_is_refused_in_one_line(tmp_path, capsys):
    cam = tmp_path / "folding.yaml"
    cam.write_text(yaml.safe_dump({**STRONG_WIDE_CAMERA, "distortion": [-0.45]}))
    out = tmp_path / "out"
    code = plan_main([str(ROOT / "layouts" / "grid-32.yaml"), "--camera", str(cam), "-o", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1 and "folds inside the image" in err[0] and "Traceback" not in err[0]
    assert not (out / "plan.yaml").exists()


def _locate(plan: str, observation: dict, tmp_path, capsys, *flags, two_places_ok: bool = False) -> np.ndarray:
    """The position vlp-locate gives; with ``two_places_ok``, infinity where it finds the image fits two places."""
    path = tmp_path / "obs.json"
    path.write_text(json.dumps(observation))
    code = locate_main([plan, str(path), *flags])
    out = capsys.readouterr()
    if two_places_ok and code == 3 and "the image fits two places" in out.err:
        return np.full(3, np.inf)
    assert code == 0, out.err
    return np.array(json.loads(out.out)["position_m"])


def _simulated(plan: str, pose: str, camera: Camera, capsys) -> dict:
    """The observation of ``pose`` through ``camera``: vlp-locate --simulate for the plan's own camera."""
    if camera == load_plan(plan).camera_model():
        assert locate_main([plan, "--simulate", pose, "--seed", "1"]) == 0
        return json.loads(capsys.readouterr().out)
    site = Site.from_plan(load_plan(plan))
    values = [float(v) for v in pose.split(",")]
    rotation = rotation_from_angles(*np.radians(values[3:]))[0]
    seen = observe(np.array(values[:3]), rotation, site.xyz, site.radii, camera, np.random.default_rng(1), 0.5)
    return snapshot_document(Snapshot(camera, [int(site.ids[k]) for k in seen.index], seen.ellipses))


@pytest.mark.parametrize("camera, factor", [(PROFILE, 50), (WIDE, 50)], ids=["wide-profile", "strong-yaml"])
def test_vlp_locate_undistorts_and_ignoring_the_lens_is_far_worse(wide_plan_dir, tmp_path, capsys, camera, factor):
    plan = str(wide_plan_dir / "plan.yaml")
    errors, ignored = [], []
    for pose in POSES_40_DEG:
        obs = _simulated(plan, pose, camera, capsys)
        assert obs["camera"]["distortion"] == list(camera.distortion) and len(obs["leds"]) >= 3
        truth = np.array([float(v) for v in pose.split(",")[:3]])
        errors.append(np.linalg.norm(_locate(plan, obs, tmp_path, capsys) - truth))
        plain = {**obs, "camera": {k: v for k, v in obs["camera"].items() if k not in ("lens", "distortion")}}
        # with a 1,000 px residual limit the wrong lens may also fit another place: no position at all
        ignored.append(np.linalg.norm(_locate(plan, plain, tmp_path, capsys, "--max-residual-px", "1000",
                                              two_places_ok=True) - truth))
    assert max(errors) < 0.01  # issue 18: under 1 cm at 40 deg tilt
    # ignoring the lens: at least ``factor`` times the worst error with it (measured: docs/positioning.md)
    assert min(ignored) > factor * max(errors, default=0.0) and min(ignored) > 0.02
    assert np.isfinite(ignored).sum() >= 1  # a wrong position, not only refusals
