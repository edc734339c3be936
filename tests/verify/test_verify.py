"""Verification: windows, keys, coverage, and vlp-verify on real plans."""
import itertools
import json

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from conftest import grid32_copy, grid_xy, nearest_by_the_model, vlp
from planner.camera.model import Camera, Poses, project_discs, rotation_from_angles
from planner.codes.schemes import assign_window
from planner.codes.window import window_keys
from planner.graph import build_graph
from planner.verify.proof import prove_window_set
from planner.verify.rivals import find_rivals
from planner.verify.verify import AMBIGUOUS, DECODABLE, verify_plan
from planner.verify.windows import PoseSample, canonical_windows, find_windows, sample_poses, working_area


def test_disc_images_match_dense_rim_sampling():
    cam = Camera()
    rng = np.random.default_rng(0)
    n, k = 400, 6
    tilt = rng.uniform(0, np.radians(40), n)
    poses = Poses(np.column_stack([rng.uniform(-1, 1, (n, 2)), rng.uniform(0.5, 1.5, n)]),
                  tilt, rng.uniform(0, 6.3, n), rng.uniform(0, 6.3, n))
    centres = np.concatenate([rng.uniform(-3, 3, (n, k, 2)), np.full((n, k, 1), 2.5)], axis=2)
    radii = np.full((n, k), 0.1)
    out = project_discs(poses, centres, radii, cam)
    a = np.linspace(0, 2 * np.pi, 2000, endpoint=False)
    rim = centres[..., None, :] + 0.1 * np.stack([np.cos(a), np.sin(a), 0 * a], -1)
    cam_pts = np.einsum("pji,pkaj->pkai", poses.rotation, rim - poses.position[:, None, None, :])
    u = cam.fx_px * cam_pts[..., 0] / cam_pts[..., 2] + cam.cx_px
    v = cam.fy_px * cam_pts[..., 1] / cam_pts[..., 2] + cam.cy_px
    inside = (cam_pts[..., 2] > 0).all(-1) & (u.min(-1) >= 0) & (u.max(-1) <= 4000) & (v.min(-1) >= 0) & (v.max(-1) <= 3000)
    assert inside.sum() > 50  # the check is not vacuous
    assert np.array_equal(inside, out["inside"])


def test_level_camera_looks_straight_up():
    r = rotation_from_angles(0.0, 0.3, 0.0)[0]
    assert np.allclose(r[:, 2], [0, 0, 1])
    r = rotation_from_angles(np.radians(30), np.radians(90), 1.0)[0]
    assert np.allclose(r[:, 2], [0, np.sin(np.radians(30)), np.cos(np.radians(30))])
    assert np.allclose(r.T @ r, np.eye(3))


def test_window_is_the_three_seen_leds_nearest_the_image_centre():
    xy = grid_xy(6, 6, 0.5, 0.5)
    xyz = np.column_stack([xy, np.full(len(xy), 2.5)])
    cam = Camera()
    poses = Poses(np.array([[1.1, 1.1, 1.0]]), np.zeros(1), np.zeros(1), np.zeros(1))
    pw = find_windows(poses, xyz, np.full(len(xy), 0.1), cam)
    # level camera 1.5 m below the ceiling at (1.1, 1.1): nearest LEDs (1,1), (1.5,1) / (1,1.5) in some order
    centre = np.argmin(np.hypot(*(xy - [1.1, 1.1]).T))
    assert centre in pw.triples[0]
    d = np.sort(np.hypot(*(xy[pw.triples[0]] - [1.1, 1.1]).T))
    assert np.all(d <= np.sort(np.hypot(*(xy - [1.1, 1.1]).T))[3] + 1e-9)


def _nearest_seen_by_the_camera_model(poses, xyz, radii, cam, count):
    """nearest_seen's choice among the same candidates, with the camera model's numpy images (project_discs) and a
    stable sort: the oracle."""
    from scipy.spatial import cKDTree

    from planner.verify.windows import candidates

    cand = candidates(poses, cKDTree(xyz[:, :2]), float(np.median(xyz[:, 2])))
    return nearest_by_the_model(poses, cand, xyz, radii, cam, count)


@pytest.mark.parametrize("seed", range(6))
def test_the_compiled_choice_of_seen_leds_is_the_camera_models_to_the_last_bit(seed):
    """nearest_seen's kernel bounds each disc image and ranks the centres as project_discs' numpy does, term by
    term: on random sites (lattices with exact ties, scattered, mixed radii and heights) through an ideal, a
    fisheye and a barrel lens, the same LEDs seen and chosen at every pose."""
    from planner.verify.windows import nearest_seen

    rng = np.random.default_rng(seed)
    windows = 0
    lenses = [Camera(), Camera.from_fov(np.radians(110), lens="fisheye", distortion=(0.05, -0.01, 0.002, 0.0)),
              Camera.from_fov(np.radians(80), distortion=(-0.2, 0.05, 0.0, 0.0, 0.0))]
    for trial in range(6):
        n = int(rng.integers(3, 200))
        xy = grid_xy(int(np.ceil(np.sqrt(n))), int(np.ceil(np.sqrt(n))), 0.6, 0.6)[:n] if trial % 2 else \
            rng.uniform(0, 0.8 * np.sqrt(n), (n, 2))
        xyz = np.column_stack([xy, np.full(n, 2.8) + (rng.normal(0, 0.2, n) if trial == 4 else 0.0)])
        radii = rng.uniform(0.03, 0.15, n) if trial % 3 == 0 else np.full(n, 0.1)
        cam = lenses[trial % 3]
        poses = sample_poses(np.array([xy.min(0) - 0.5, [xy.max(0)[0] + 0.5, xy.min(0)[1] - 0.5], xy.max(0) + 0.5,
                                       [xy.min(0)[0] - 0.5, xy.max(0)[1] + 0.5]]), cam, 60, seed)
        for count in (2, 3):
            chosen, seen = nearest_seen(poses, xyz, radii, cam, count)
            want, want_seen = _nearest_seen_by_the_camera_model(poses, xyz, radii, cam, count)
            np.testing.assert_array_equal(seen, want_seen)
            np.testing.assert_array_equal(chosen, want)
            windows += int((chosen[:, 0] >= 0).sum())
    assert windows > 1000  # the comparison is about LEDs chosen, not only about poses that see too few


def test_canonical_windows_are_counter_clockwise_and_classed_by_shape():
    xyz = np.array([[0, 0, 2.5], [1, 0, 2.5], [0, 1, 2.5], [5, 5, 2.5], [5, 6, 2.5], [4, 5, 2.5], [9, 0, 2.5],
                    [11, 0, 2.5], [10, 1.7320508, 2.5]])
    ws = canonical_windows(np.array([[0, 1, 2], [3, 4, 5], [6, 7, 8]]), xyz)
    for w in ws.windows:
        p = xyz[w]
        (ax, ay), (bx, by) = p[1, :2] - p[0, :2], p[2, :2] - p[0, :2]
        assert ax * by - ay * bx > 0
    # the two L triangles are congruent (one class), the equilateral one is symmetric
    assert ws.shape[0] == ws.shape[1] != ws.shape[2]
    assert ws.symmetric[ws.shape[2]] and not ws.symmetric[ws.shape[0]]


def test_unique_ids_never_ambiguous_and_repeated_ids_are():
    xy = grid_xy(6, 10, 0.5, 0.5)
    xyz = np.column_stack([xy, np.full(len(xy), 2.5)])
    radii = np.full(len(xy), 0.1)
    unique = verify_plan(xyz, radii, np.arange(1, len(xy) + 1), None, Camera(), per_m2=300)
    assert unique.count(AMBIGUOUS) == 0 and unique.count(DECODABLE) > 0.5 * unique.poses
    same = verify_plan(xyz, radii, np.ones(len(xy), dtype=int), None, Camera(), per_m2=300)
    assert same.count(DECODABLE) == 0 and same.count(AMBIGUOUS) == unique.count(DECODABLE)


@pytest.mark.slow
@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
@given(rows=st.integers(3, 8), cols=st.integers(3, 10), jitter=st.floats(0, 0.12), seed=st.integers(0, 1000))
@example(rows=3, cols=3, jitter=0.0, seed=1)  # no triple shares a window's IDs: the empty case
def test_window_scheme_plans_never_share_a_key(rows, cols, jitter, seed):
    xy = grid_xy(rows, cols, 0.5, 0.5, jitter_m=jitter, seed=seed)
    xyz = np.column_stack([xy, np.full(len(xy), 2.5)])
    radii = np.full(len(xy), 0.1)
    assignment, check = assign_window(xyz, radii, None, build_graph(xy), Camera(), seed=seed, time_budget=1.0,
                                      per_m2=150)
    assert check.conflicts == []
    # By brute force: no sampled window reads like any other triple of the site. Every triple,
    # turned counter-clockwise, in each of its three rotations, indexed by its IDs in that order.
    ids, tol = assignment.ids, check.tolerance_m
    every = np.array(list(itertools.combinations(range(len(xy)), 3)))
    every = every[[ccw(t, xy) or ccw(t[[0, 2, 1]], xy) for t in every]]  # three in a row never decode
    every = np.array([t if ccw(t, xy) else t[[0, 2, 1]] for t in every])
    by_ids: dict = {}
    for r in range(3):
        turned = np.roll(every, -r, axis=1)
        for t, key in zip(turned, map(tuple, ids[turned].tolist())):
            by_ids.setdefault(key, []).append(t)
    def sides(t):
        return np.linalg.norm(xy[np.roll(t, -1, axis=-1)] - xy[t], axis=-1)
    for w in check.windows.windows:
        v = w if ccw(w, xy) else w[[0, 2, 1]]
        same = np.array([u for u in by_ids.get(tuple(ids[v].tolist()), []) if set(u) != set(w)],
                        dtype=np.int64).reshape(-1, 3)
        alike = np.abs(sides(same) - sides(v)).max(axis=1, initial=0.0) <= tol
        assert not alike.any(), (w, same[alike][:3])
    # and on an independent pose sample too: the window set protects what no sample produced
    again = verify_plan(xyz, radii, assignment.ids, None, Camera(), per_m2=150, seed=seed + 7)
    assert again.count(AMBIGUOUS) == 0


def ccw(t, xy) -> bool:
    a, b, c = xy[t]
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]) > 0


@pytest.mark.slow
def test_vlp_verify_passes_a_plan_and_fails_a_swapped_one(tmp_path_factory, tmp_path):
    out = grid32_copy(tmp_path_factory, tmp_path / "out", "--error-poses-per-m2", "0").parent  # planned once per run
    ok = vlp("vlp-verify", str(out / "plan.yaml"))
    assert ok.returncode == 0 and "0 ambiguous" in ok.stdout
    doc = yaml.safe_load((out / "plan.yaml").read_text())
    assert doc["scheme"] == "window"  # the default scheme chooses the window code on grid-32
    lums = doc["luminaires"]
    xyz = np.array([[e["x"], e["y"], e["z"]] for e in lums])
    ids = np.array([e["id"] for e in lums])
    ws = verify_plan(xyz, np.full(len(lums), 0.1), ids, doc["outline"], Camera(), per_m2=400).windows
    swap = None
    for i in range(len(lums)):  # find two luminaires whose swapped IDs make two windows alike
        for j in range(i + 1, len(lums)):
            if ids[i] == ids[j]:
                continue
            trial = ids.copy()
            trial[[i, j]] = trial[[j, i]]
            if len(np.unique(window_keys(ws.windows, ws.shape, ws.symmetric, trial - 1, int(trial.max())))) < len(ws):
                swap = (i, j)
                break
        if swap:
            break
    assert swap is not None
    i, j = swap
    lums[i]["id"], lums[j]["id"] = lums[j]["id"], lums[i]["id"]
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(doc, sort_keys=False))
    result = vlp("vlp-verify", str(bad), "--map", str(tmp_path / "cov.png"))
    assert result.returncode == 3, result.stdout + result.stderr
    named = [line for line in result.stdout.splitlines() if "same key:" in line]
    assert named and any(lums[i]["name"] in line or lums[j]["name"] in line for line in named)
    assert (tmp_path / "cov.png").stat().st_size > 1000


def test_vlp_verify_bad_plan_file(tmp_path):
    bad = tmp_path / "plan.yaml"
    bad.write_text("format: something-else\n")
    result = vlp("vlp-verify", str(bad))
    assert result.returncode == 1 and "not a vlp-plan/1 plan" in result.stderr


def test_a_plans_one_pose_sample_gives_every_lower_density_exactly():
    """make_plan draws once and hands prefixes to verification, timing and the error map: each prefix
    must be what sample_poses and find_windows give at that density on their own."""
    xyz = np.column_stack([grid_xy(5, 7, 0.5, 0.5, jitter_m=0.02, seed=3), np.full(35, 2.5)])
    radii = np.full(35, 0.1)
    cam = Camera()
    area = working_area(xyz[:, :2], None)
    sample = PoseSample.draw(area, xyz, radii, cam, per_m2=400.0, seed=5)
    for per_m2 in (4.0, 37.0, 400.0):
        poses, windows = sample.first(per_m2)
        alone = sample_poses(area, cam, per_m2, seed=5)
        assert len(poses) == len(alone) > 0
        np.testing.assert_array_equal(poses.position, alone.position)
        np.testing.assert_array_equal(poses.roll_rad, alone.roll_rad)
        np.testing.assert_array_equal(windows.triples, find_windows(alone, xyz, radii, cam).triples)
    with pytest.raises(ValueError, match="the sample holds"):
        sample.first(401.0)


def test_working_area_is_the_hull_without_an_outline():
    xy = grid_xy(3, 4)
    area = working_area(xy, None)
    (ax, ay), (bx, by) = area[1] - area[0], area[2] - area[1]
    assert len(area) == 4 and np.isclose(abs(ax * by - ay * bx), 6.0)
    poses = sample_poses(area, Camera(), per_m2=50, seed=3)
    assert abs(len(poses) - 300) <= 1
    assert np.all((poses.position[:, 2] >= 0.5) & (poses.position[:, 2] <= 1.5))
    assert np.all(poses.tilt_rad <= np.radians(40) + 1e-12)


@pytest.mark.slow
def test_vlp_verify_names_a_clash_of_a_window_no_sample_produced(tmp_path_factory, tmp_path):
    out = grid32_copy(tmp_path_factory, tmp_path / "out", "--error-poses-per-m2", "0").parent  # planned once per run
    doc = yaml.safe_load((out / "plan.yaml").read_text())
    lums = doc["luminaires"]
    xyz = np.array([[e["x"], e["y"], e["z"]] for e in lums])
    radii = np.array([e["radius"] for e in lums])
    ids = np.array([e["id"] for e in lums])
    cam = Camera.from_dict(doc["camera"])
    sampled = set()
    for seed in range(3):  # what default samples produce: the planner's and vlp-verify's seeds
        ws = verify_plan(xyz, radii, ids, doc["outline"], cam, seed=seed).windows
        sampled |= {frozenset(t) for t in ws.windows.tolist()}
    assert doc["verification"]["decodability"] == "proved"
    proof = prove_window_set(xyz, radii, cam, 0.03)
    unsampled = [t for t in proof.triangles.tolist() if frozenset(t) not in sampled]
    assert unsampled
    # A triple shaped like an unsampled window, whose IDs differ from it in one place: make them equal.
    clash = None
    def side(x):
        return np.linalg.norm(xyz[np.roll(x, -1)] - xyz[x], axis=1)
    for start in range(0, len(unsampled), 20):  # a few windows at a time: one clash is enough
        chunk = np.array(unsampled[start:start + 20])
        for a, u in find_rivals(chunk, xyz, np.ones(len(lums), np.int64), 0.01):
            for r in range(3):
                t = np.roll(rivals_ccw(chunk[a].tolist(), xyz), -r)
                diff = [k for k in range(3) if ids[t[k]] != ids[u[k]]]
                if np.abs(side(t) - side(np.array(u))).max() <= 0.01 and len(diff) == 1 and not set(t) & set(u):
                    clash = (t.tolist(), list(u), diff[0])
                    break
            if clash:
                break
        if clash:
            break
    assert clash is not None
    t, u, k = clash
    lums[u[k]]["id"] = int(ids[t[k]])
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(doc, sort_keys=False))
    result = vlp("vlp-verify", str(bad), "--json")
    assert result.returncode == 3, result.stdout + result.stderr
    w = json.loads(result.stdout)["window_set"]
    window, rival = ({lums[i]["name"] for i in x} for x in (t, u))
    assert any(window in [set(x) for x in g] and rival in [set(x) for x in g] for g in w["first_conflicts"])
    assert w["complete"] and not w["proved"] and json.loads(result.stdout)["decodability"] == "sampled only"


def rivals_ccw(t, xyz):
    a, b, c = (xyz[v] for v in t)
    return list(t) if (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]) >= 0 else [t[0], t[2], t[1]]
