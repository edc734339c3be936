"""The advice checks that a change's frames still fit (issue 19): on the README's outline room, the gravity
receiver with the ultra-wide lens reaches the coverage goal but its frames need faster drivers than the bundled
20 kHz ones; the table says so and names the flag, and the planner agrees both ways."""

import json
import subprocess

import numpy as np
import pytest

from conftest import ROOT, vlp

ROOM = str(ROOT / "layouts" / "outline-room.dxf")
FAST = ["--json", "--no-report", "--no-map", "--no-firmware", "--error-poses-per-m2", "0"]


def _plan(*args: str, cwd) -> subprocess.CompletedProcess:
    run = vlp("vlp-plan", ROOM, "--leds", "128", *args, *FAST, cwd=cwd)
    assert "Traceback" not in run.stderr, run.stderr
    return run


@pytest.fixture(scope="module")
def advice(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("room")
    run = _plan("-o", str(tmp / "as-is"), "--receiver", "three", cwd=tmp)  # the advice of a three-LED plan
    assert run.returncode == 3 and "NOT USABLE" in run.stderr
    return tmp, json.loads(run.stdout)["advice"]


def _gravity_row(advice: dict) -> dict:
    return next(c for c in advice["changes"] if c["change"].startswith("receiver mode gravity; camera ultrawide "))


def test_a_change_whose_frames_do_not_fit_says_which_drivers_it_needs(advice):
    _, a = advice
    row = _gravity_row(a)
    # measured 2026-12-03: 91.1 % of 5120 poses see two whole LEDs; smallest LED image 26.4 rows at the
    # ultrawide's 10 us, a 22-chip frame (7-bit unique IDs, Manchester) over 4 video frames needs 34 kHz
    assert row["covers_goal"] and not row["reaches_goal"] and row["coverage"] >= 0.9
    f = row["frame"]
    assert not f["fits"] and f["needs_driver_hz"] > a["driver_max_hz"] == 20000
    assert row["flags"][-2:] == ["--driver-max-hz", f"{f['needs_driver_hz']:.0f}"]
    rec = a["changes"][a["recommended"]]
    assert rec is not row and rec["reaches_goal"] and rec["frame"]["fits"]  # recommended: one that fits as it is
    from planner.advice.advise import table

    remark = next(r for c, _, r in table(a) if c == row["change"])
    assert f"need drivers at >= {f['needs_driver_hz'] / 1e3:g} kHz (these: 20 kHz)" in remark
    assert not remark.startswith("recommended")


@pytest.mark.slow  # two more plans of the room, each proved: about 70 s
def test_the_planner_agrees_the_frames_do_not_fit_without_the_drivers_and_do_with_them(advice):
    tmp, a = advice
    row = _gravity_row(a)
    flags = row["flags"][:-2]
    slow = _plan(*flags, "-o", str(tmp / "slow"), cwd=tmp)
    assert slow.returncode == 3 and "without frames or firmware: no chip rate fits" in slow.stderr
    assert json.loads(slow.stdout)["modulation"] is None  # the plan and its advice are written, with no frames
    fast = _plan(*row["flags"], "-o", str(tmp / "fast"), cwd=tmp)
    assert fast.returncode == 0, fast.stderr
    done = json.loads(fast.stdout)
    # measured 2026-12-03: 91.3 % of 204,800 poses decode, 5 bits (18 chips), 32 kHz over 4 video frames
    assert done["verification"]["coverage"] >= a["goal"] and done["advice"]["meets_goal"]
    assert done["modulation"]["chip_rate_hz"] <= row["frame"]["needs_driver_hz"]
    assert done["modulation"]["frame_chips"] <= row["frame"]["frame_chips"]


def test_a_frame_that_fits_at_no_driver_rate_is_not_recommended():
    """LEDs imaged too small for any rate: the advice keeps the row, says why, and recommends none."""
    from planner.advice.advise import Site, advise, table
    from planner.advice.frames import FrameLimits
    from planner.camera.model import Camera

    xy = np.array([[x, y] for x in np.arange(0.0, 1.81, 0.6) for y in np.arange(0.0, 1.21, 0.6)])
    site = Site(np.column_stack([xy, np.full(len(xy), 2.8)]), np.full(len(xy), 0.005), None, Camera())
    limits = FrameLimits("manchester", 1, 20000.0, 30.0, 1, None)
    got = advise(site, 0.0, frames=limits).summary()
    covering = [c for c in got["changes"] if c["covers_goal"]]
    assert covering and all(not c["frame"]["fits"] and c["frame"]["needs_driver_hz"] is None for c in covering)
    assert got["recommended"] is None
    # measured 2026-12-03: the gravity receiver with the ultrawide lens covers 100 %, its smallest LED image is
    # 4.5 rows: a 16-chip frame needs at least 8 rows at the 2-row chip limit, whatever the driver
    remarks = [r for c, _, r in table(got)[1:] if c in {c["change"] for c in covering}]
    assert remarks and all("at any driver rate: not recommended" in r and "vlp-plan" not in r for r in remarks)
