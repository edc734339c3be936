"""Issue 19, Done-when 1: the DIALux office with an ultra-wide lens, planned for the gravity receiver."""

import json
import subprocess

import pytest

from conftest import ROOT

# The ultrawide profile's intrinsics without its distortion: the twin's renderer does not distort yet
# (issue 18.1), so the listed profile's barrel would be undistorted by a receiver that sees a pinhole image.
CAMERA = "hfov_deg: 110\nwidth_px: 4032\nheight_px: 3024\nrow_time_s: 1.0e-5\n"


@pytest.mark.slow
def test_office_with_ultrawide_lens_is_proved_and_the_twin_locates_it(tmp_path):
    camera = tmp_path / "ultrawide-ideal.yaml"
    camera.write_text(CAMERA)
    out = tmp_path / "office"
    done = subprocess.run(["vlp-plan", str(ROOT / "layouts" / "dialux-office.dxf"), "--receiver", "auto",
                           "--camera", str(camera), "--driver-max-hz", "40000", "-o", str(out), "--json",
                           "--no-report", "--no-map", "--error-poses-per-m2", "0"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    r, v = summary["receiver"], summary["verification"]
    assert r["mode"] == "gravity" and r["coverage"]["gravity"] > r["coverage"]["three"]
    # measured 2026-12-03: gravity 90.5 %, three-LED 61.8 % of 110,592 sampled poses; proved, 1,124 pairs
    assert v["coverage"] >= 0.9 and v["decodability"] == "proved"
    twin = subprocess.run(["vlp-twin", str(out / "plan.yaml"), "--poses", "30", "--jobs", "2", "--json"],
                          capture_output=True, text=True)
    assert twin.returncode in (0, 3), twin.stderr
    result = json.loads(twin.stdout)
    # rendered frames, IDs over 4 video frames, 1 deg accelerometer noise: measured 29 of 30, median
    # 0.24 mm (296 of 300 with --poses 300, 2026-12-03)
    assert result["located"] >= 29 and result["error_m"]["max"] < 0.10
