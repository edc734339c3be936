"""The bundled camera profiles (planner/data/cameras.yaml): what they claim, --camera NAME, --list-cameras."""

import dataclasses
import json
import math

import numpy as np
import pytest
import yaml

from conftest import ROOT, vlp
from planner.camera.file import camera_from, camera_profiles
from planner.camera.model import Camera
from planner.errors import UsageError

PROFILES = camera_profiles()


def test_the_library_holds_the_papers_camera_and_a_main_wide_and_ultra_wide_one():
    assert {"paper", "main", "wide", "ultrawide", "ultrawide-fisheye"} <= set(PROFILES)
    assert PROFILES["paper"].camera == dataclasses.replace(Camera(), name="paper")  # the default, named
    hfov = {n: math.degrees(p.camera.hfov_rad) for n, p in PROFILES.items()}
    assert 60 < hfov["main"] < 70 and 78 <= hfov["wide"] <= 80 and 110 <= hfov["ultrawide"] <= 120
    assert PROFILES["wide"].camera.lens == "pinhole" and PROFILES["wide"].camera.distorted
    assert PROFILES["ultrawide-fisheye"].camera.lens == "fisheye" and PROFILES["ultrawide-fisheye"].camera.distorted


@pytest.mark.parametrize("name", sorted(PROFILES))
def test_every_profile_is_named_sourced_and_invertible_over_its_whole_image(name):
    p = PROFILES[name]
    cam = p.camera
    assert cam.name == name and p.role in ("main", "wide", "ultra-wide") and p.example
    lo, hi = p.row_time_range_s
    assert lo <= cam.row_time_s <= hi and 5e-6 <= lo < hi <= 5e-5
    assert {"row_time_s", "distortion"} <= set(p.sources) and ({"fx_px", "hfov_deg"} & set(p.sources))
    assert all(len(s) > 20 for s in p.sources.values())
    # The lens map must stay one-to-one over the whole image: every pixel has one ray, and it projects back.
    u, v = np.meshgrid(np.linspace(0, cam.width_px, 41), np.linspace(0, cam.height_px, 31))
    px = np.stack([u.ravel(), v.ravel()], axis=1)
    rays = cam.rays(px)
    assert np.isfinite(rays).all() and (rays[:, 2] > 0).all()
    assert np.abs(cam.project(rays) - px).max() < 1e-6
    assert camera_from(name) == cam and Camera.from_dict(cam.to_dict()).name == name


def test_the_diagonal_field_of_view_of_the_ultra_wide_is_the_one_its_makers_quote():
    cam = PROFILES["ultrawide"].camera
    corner = cam.rays(np.array([[0.0, 0.0]]))[0]
    assert 2 * math.degrees(math.acos(corner[2])) == pytest.approx(123, abs=0.5)  # Galaxy S20's quoted 123 deg


def test_an_unknown_name_lists_the_profiles_and_a_camera_file_still_reads(tmp_path):
    with pytest.raises(UsageError) as err:
        camera_from("pixel9")
    assert str(err.value).startswith("`camera` pixel9: no such camera profile or file; profiles: paper, main, wide")
    (tmp_path / "cam.yaml").write_text("hfov_deg: 70\nname: mine\n")
    assert camera_from(str(tmp_path / "cam.yaml")).name == "mine"


def test_vlp_plan_lists_the_cameras_without_a_layout(tmp_path):
    done = vlp("vlp-plan", "--list-cameras", cwd=tmp_path)
    assert done.returncode == 0 and done.stderr == ""
    lines = done.stdout.splitlines()
    assert lines[0].split()[:4] == ["name", "role", "lens", "image"]
    assert any(line.split()[:5] == ["wide", "wide", "pinhole", "4032x3024", "79.0"] for line in lines)
    shown = json.loads(vlp("vlp-plan", "--list-cameras", "--json").stdout)["cameras"]
    assert [c["name"] for c in shown] == list(PROFILES)
    assert all(c["sources"] and c["hfov_deg"] > 0 and c["row_time_range_s"][0] > 0 for c in shown)
    assert list(tmp_path.iterdir()) == []
    bare = vlp("vlp-plan")
    assert bare.returncode == 2 and "required: LAYOUT" in bare.stderr and bare.stderr.count("\n") == 1


@pytest.mark.slow
def test_vlp_plan_and_verify_take_a_profile_by_name(tmp_path):
    out = tmp_path / "out"
    quick = ["--no-report", "--no-map", "--no-firmware", "--error-poses-per-m2", "0", "--poses-per-m2", "20"]
    done = vlp("vlp-plan", str(ROOT / "layouts" / "grid-32.yaml"), "-o", str(out), "--camera", "wide",
               *quick)
    assert done.returncode == 0, done.stderr
    camera = yaml.safe_load((out / "plan.yaml").read_text())["camera"]
    assert camera["name"] == "wide" and camera["distortion"][:2] == [-0.08, 0.02] and camera["fx_px"] == 2561.2
    verify = vlp("vlp-verify", str(out / "plan.yaml"), "--camera", "main", "--poses-per-m2", "20",
                 "--json")
    assert verify.returncode in (0, 3), verify.stderr
    refused = vlp("vlp-verify", str(out / "plan.yaml"), "--camera", "iphone")
    assert refused.returncode == 2 and refused.stderr.count("\n") == 1
    assert "--camera iphone: no such camera profile or file; profiles: paper, main" in refused.stderr


def test_docs_list_every_profile_with_its_figures_and_the_example_file_reads(tmp_path):
    from planner.camera.file import read_camera

    text = (ROOT / "docs" / "camera.md").read_text()
    table = text[text.index("## Profiles"):text.index("## Calibration")]
    rows = {}
    for line in table.splitlines():
        cells = [c.strip() for c in line.strip("|").split("|")]
        if line.startswith("| `") and len(cells) == 7:
            rows[cells[0].split("`")[1]] = cells
    assert set(rows) == set(PROFILES)
    for name, cells in rows.items():
        cam = PROFILES[name].camera
        assert cells[1] == cam.lens and cells[2] == f"{cam.width_px} x {cam.height_px}"
        assert float(cells[3]) == pytest.approx(cam.fx_px, abs=0.05)
        assert float(cells[4].split()[0]) == pytest.approx(math.degrees(cam.hfov_rad), abs=0.05)
        assert float(cells[6].split()[0]) == pytest.approx(1e6 * cam.row_time_s)
    example = tmp_path / "phone.yaml"
    example.write_text(text.split("```yaml\n")[1].split("```")[0])
    assert read_camera(example).distorted
