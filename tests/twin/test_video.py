"""IDs read over k video frames: the office with a 110 deg lens plans, and the twin decodes a multi-frame plan.

The twin's site is a small office bay (3 x 4 luminaires of 0.24 m at 1.2 m pitch, 2.8 m
ceiling) filmed by a 1600 x 1200, 110 deg camera: its smallest LED image is about 21
rows, too short for a 12-chip frame at any rate, so the plan reads it over 3 video frames.
"""

import json

import numpy as np
import pytest
import yaml

from conftest import ROOT, vlp
from planner.modulation.frame import frame_chips, line_code
from planner.plan.file import load_plan
from planner.twin.twin import Twin, covered_poses, run_pose
from planner.twin.video import stitch

ROOM = {"unit": "m", "height": 2.8, "radius": 0.12,
        "outline": [[0, 0], [4.8, 0], [4.8, 3.6], [0, 3.6]],
        "luminaires": [{"name": f"L{r}{c}", "x": 0.6 + 1.2 * c, "y": 0.6 + 1.2 * r} for r in range(3) for c in range(4)]}
WIDE = {"width_px": 1600, "height_px": 1200, "hfov_deg": 110}
FAST = ["--no-map", "--no-report", "--no-firmware", "--error-poses-per-m2", "0"]


def _plan(tmp_path, layout, camera, *extra):
    (tmp_path / "cam.yaml").write_text(yaml.safe_dump(camera))
    return vlp("vlp-plan", str(layout), "--camera", str(tmp_path / "cam.yaml"), "-o",
               str(tmp_path / "out"), *FAST, *extra)


@pytest.fixture(scope="module")
def bay(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("bay")
    (tmp / "room.yaml").write_text(yaml.safe_dump(ROOM))
    done = _plan(tmp, tmp / "room.yaml", WIDE, "--json")
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout), tmp / "out" / "plan.yaml"


# --- stitching ------------------------------------------------------------------------------------

def _window(chips: str, start: float, count: int, rows_per_chip: float = 2.5, noise=None):
    """Rows of one video frame's window: chip coordinates and levels (a sharp drive, 6 / 200 DN)."""
    x = start + np.arange(count) / rows_per_chip
    level = np.where(np.array(list(chips))[np.floor(x).astype(int) % len(chips)] == "1", 200.0, 6.0)
    return x, level + (noise.normal(0, 2, count) if noise is not None else 0)


def test_stitch_reassembles_the_cyclic_frame_from_partial_windows():
    chips = frame_chips(9, 4, line_code("manchester"))  # 16 chips
    rng = np.random.default_rng(1)
    phase = 0.37
    # four windows of 7 chips, 4 chips apart on the cycle but 660 chips apart in time (19.8 kHz at 30 fps)
    signals = [_window(chips, phase + j * 660, 18, noise=rng) for j in range(4)]
    got, problem = stitch(signals, 16)
    assert problem == "" and got in chips + chips and len(got) == 16
    two, problem = stitch(signals[:2], 16)  # half the cycle seen: a gap, not a guess
    assert two == "" and "seen in no video frame" in problem
    bad = list(signals)
    x, level = bad[1]
    level = level.copy()
    flip = (np.floor(x).astype(int) % 16) == int(np.floor(x[16]) % 16)  # a chip the next window reads too
    level[flip] = 206.0 - level[flip]  # misread here
    bad[1] = (x, level)
    assert "disagree" in stitch(bad, 16)[1]


# --- the office ------------------------------------------------------------------------------------

def test_the_office_with_a_110_deg_lens_plans_over_video_frames(tmp_path):
    done = _plan(tmp_path, ROOT / "layouts" / "dialux-office.dxf", {"hfov_deg": 110})
    assert done.returncode == 0, done.stderr
    assert "multi-frame" in done.stdout and "consecutive video frames at 30 fps" in done.stdout
    mod = load_plan(tmp_path / "out" / "plan.yaml").modulation
    assert mod is not None and 2 <= mod.video_frames <= 4 and mod.video_fps == 30.0
    assert mod.frames_in_smallest_image < 1  # no image holds a frame: why it is multi-frame
    assert mod.chip_rate_hz <= min(mod.limits_hz["resolution_max"], mod.limits_hz["driver_max"])


def test_a_site_not_even_four_frames_cover_stops_saying_what_would(tmp_path):
    (tmp_path / "room.yaml").write_text(yaml.safe_dump({**ROOM, "radius": 0.06}))
    done = _plan(tmp_path, tmp_path / "room.yaml", WIDE, "--scheme", "unique", "--no-verify")
    assert done.returncode == 1 and not (tmp_path / "out").exists()
    line = done.stderr.strip()
    assert "\n" not in line and "Traceback" not in line
    assert "no chip rate fits" in line and "4 video frames at 30 fps" in line and "what would: LED images of" in line


def test_a_bay_plan_records_k_and_single_frame_is_said(bay, tmp_path):
    summary, path = bay
    assert summary["modulation"]["video_frames"] == 3
    plan = load_plan(path)
    assert plan.modulation.video_frames == 3
    from planner.report.content import summary as report_rows

    row = dict(report_rows(plan, []))["modulation"]  # the site report says how the IDs are read
    assert "read over 3 consecutive video frames at 30 fps" in row
    (tmp_path / "room.yaml").write_text(yaml.safe_dump({**ROOM, "radius": 0.3}))  # big panels: one image holds it
    done = _plan(tmp_path, tmp_path / "room.yaml", WIDE, "--scheme", "unique", "--no-verify")
    assert done.returncode == 0 and "single-frame" in done.stdout
    assert "video_frames" not in (tmp_path / "out" / "plan.yaml").read_text()


# --- the twin --------------------------------------------------------------------------------------

def test_the_twin_reads_ids_over_three_video_frames(bay):
    """30 covered poses of the bay, each rendered as 3 consecutive frames at 30 fps and read by stitching.

    Measured (seed 0): every pose reads at least 3 IDs right, 231 of 231 LEDs found read right (60 of them
    only by stitching), none misread; 29 of 30 located, the other fails later, at identification."""
    twin = Twin.from_plan(load_plan(bay[1]))
    assert twin.video is not None and twin.video.frames == 3
    poses = covered_poses(twin, 30, seed=0)
    results = [run_pose(twin, poses.position[k], poses.rotation[k], (0, 0, 0), np.random.default_rng([0, k]))[0]
               for k in range(len(poses.position))]
    read = [r.read >= 3 and r.misread == 0 for r in results]
    assert sum(read) >= 0.95 * len(results)
    assert sum(r.read for r in results) >= 0.95 * sum(r.found for r in results)
    assert sum(r.ok for r in results) >= 0.9 * len(results)
    # near LEDs hold a whole frame and read alone; the far ones needed stitching (their chips: one cycle)
    stitched = sum(1 for r in results for b in r.blobs if b.id is not None and len(b.chips) == len(twin.chips[0]))
    assert stitched >= 0.15 * sum(r.read for r in results)


def test_vlp_twin_reads_a_multi_frame_plan_over_its_video_frames(bay):
    done = vlp("vlp-twin", str(bay[1]), "--poses", "4", "--jobs", "1", "--json", "--min-success", "0.5")
    assert done.returncode == 0, done.stderr
    s = json.loads(done.stdout)
    assert s["video_frames"] == 3 and s["video_fps"] == 30.0
    assert s["ids_misread"] == 0 and s["ids_read"] >= 0.95 * s["blobs_found"]
