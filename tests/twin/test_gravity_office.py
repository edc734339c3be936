"""Issue 19, Done-when 1: the DIALux office with a listed phone profile, planned for the gravity receiver.

The listed ``ultrawide-fisheye`` profile (150 deg diagonal, Realme GT 2 Pro class) at 50 kHz drivers:
>= 90 % of sampled poses decodable, proved, read over video frames, and the twin (rendered through the
fisheye lens, 1 deg accelerometer noise, IDs stitched over 4 video frames) locates >= 99 % within 10 cm.
The suite runs 30 poses with the same bounds (all 30 located); the Done-when's 300 (two jobs, about 6 minutes)
run under ``--acceptance`` (``benchmarks/acceptance.py``).
"""

import json
import math
import subprocess

import pytest
import yaml

from conftest import shared_vlp_plan, vlp


@pytest.mark.slow
@pytest.mark.parametrize("poses", [30, pytest.param(300, marks=pytest.mark.acceptance)])
def test_office_with_a_listed_fisheye_phone_is_proved_and_the_twin_locates_it(tmp_path_factory, poses):
    # the README's command, planned once per run (tests/advice/test_advice.py checks it too)
    done = shared_vlp_plan(tmp_path_factory, "layouts/dialux-office.dxf", "--camera", "ultrawide-fisheye",
                           "--receiver", "gravity", "--driver-max-hz", "50000",
                           "--json", "--no-report", "--no-map", "--error-poses-per-m2", "0")
    out = done.outdir
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    v, code = summary["verification"], yaml.safe_load((out / "plan.yaml").read_text())["code"]
    # measured 2026-12-03: 90.8 % of 110,592 sampled poses, proved (the 152 pairs up to the window rule's cap of
    # 3.44 m, of 1,127 the proof keeps); 4 bits, optimal; 16 chips at 49,080 Hz read over 4 video frames
    assert summary["receiver"]["mode"] == "gravity"
    assert v["coverage"] >= 0.9 and v["decodability"] == "proved"
    assert v["window_set"]["window_length_cap_m"] == pytest.approx(2.4 * math.sqrt(2) + 0.05, abs=1e-3)
    assert summary["bits"] == code["bits"] == 4 and code["optimal"] and summary["lower_bound_bits"] == 4
    assert 2 <= summary["modulation"]["video_frames"] <= 4
    twin = subprocess.run(["vlp-twin", str(out / "plan.yaml"), "--poses", str(poses), "--jobs", "2", "--json"],
                          capture_output=True, text=True)
    assert twin.returncode in (0, 3), twin.stderr
    result = json.loads(twin.stdout)
    assert result["poses"] == poses and result["video_frames"] == summary["modulation"]["video_frames"]
    # measured 2026-12-05 (300 poses): 300 of 300 located, median 5.9 mm, max 5.8 cm (docs/twin.md)
    assert result["located"] >= math.ceil(0.99 * poses) and result["error_m"]["max"] < 0.10
    assert result["ids_misread"] == 0
    print(f"fisheye office twin: {result['located']} of {poses} located, error median {result['error_m']['median']:.4f} m,"
          f" max {result['error_m']['max']:.4f} m")
    # a pose whose far-edge LEDs the two-LED start misplaces by more than their images (ideal pixels at 70 deg
    # off axis): identified only by matching them again from the refitted pose (failed on seeds 0-2 and 38 of 40 seeds before)
    one = vlp("vlp-twin", str(out / "plan.yaml"), "--pose", "13.08,17.09,0.52,10.1,202.8,139.6",
              "--seed", "0", "--json")
    assert one.returncode == 0, one.stderr
    pose = json.loads(one.stdout)
    # measured 2026-12-04: 1.03 cm, under 1 cm before the fit weighed each ellipse by its uncertainty under the full
    # error budget (docs/positioning.md): it now discounts the centres, exact in this ideal render, at 70 deg off axis
    assert pose["located"] and pose["error_m"] < 0.02 and pose["ids_read"] == pose["leds_in_view"] >= 5
