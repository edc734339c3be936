"""The proof and the rival search per tile (planner.verify.tiles) and where the tiles run (planner.parallel):
the same triples as the untiled computation, and byte-identical plans in process, on 2 local processes and
on a 2-worker Dask cluster (issue 34)."""


import numpy as np
import pytest
import yaml
from scipy.spatial import cKDTree

from conftest import ROOT, grid_xy, vlp
from planner.camera.model import Camera
from planner.parallel import InProcess, LocalProcesses, runner
from planner.verify.envelope import envelope
from planner.verify.exclusion import windows_kept
from planner.verify.proof import possible_pairs
from planner.verify.rivals import shape_matches, triples_of_pairs
from planner.verify.tiles import tiled_shape_matches, tiled_windows, tiling
from planner.verify.window_set import empty_triangles, may_be_decoded


def _jittered(n_side: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    xy = grid_xy(n_side, n_side, 0.6, 0.6) + rng.uniform(-0.15, 0.15, (n_side * n_side, 2))
    return np.column_stack([xy, np.full(len(xy), 2.5)]), np.full(len(xy), 0.05)


def _untiled(xyz, radii, env) -> np.ndarray:
    """The proof over the whole site at once, as it ran before tiles: every pair, every candidate, one tree."""
    xy = xyz[:, :2]
    cand = triples_of_pairs(possible_pairs(xy, radii, env, budget=10**9), len(xy))
    cand = cand[may_be_decoded(xy[cand])]
    cand = cand[empty_triangles(cand, xyz, radii, env.install_m)]
    return cand[windows_kept(xy, radii, env, cKDTree(xy), cand)]


def test_tiles_own_every_luminaire_once():
    xyz, _ = _jittered(15, 1)
    t = tiling(xyz[:, :2], leds_per_tile=16)
    owned = np.concatenate(t.members)
    assert len(t.members) > 8 and np.array_equal(np.sort(owned), np.arange(len(xyz)))
    assert len({tuple(c) for c in t.cells.tolist()}) == len(t.members)  # one tile per cell


def test_tiled_proof_is_the_untiled_proof_same_order():
    xyz, radii = _jittered(11, 2)  # 121 luminaires: 2 tiles
    env = envelope(Camera(), xyz, radii, 0.03)
    tiled = tiled_windows(xyz, radii, env, None, 10**9, 10**9)
    assert tiled.tiles >= 2 and not tiled.over_budget
    assert len(tiled.triangles) > 1000
    assert np.array_equal(tiled.triangles, _untiled(xyz, radii, env))


def test_tiled_rival_search_is_the_untiled_one_same_order():
    xyz, radii = _jittered(11, 3)
    env = envelope(Camera(), xyz, radii, 0.03)
    windows = tiled_windows(xyz, radii, env, None, 10**9, 10**9).triangles
    expected = shape_matches(windows, xyz, 0.01)
    assert len(expected) >= len(windows)
    assert np.array_equal(tiled_shape_matches(windows, xyz, 0.01), expected)


def test_a_tile_over_its_budget_keeps_its_cheap_candidates_only():
    xyz, radii = _jittered(11, 4)
    radii = np.full(len(xyz), 0.005)  # at 3 cm, or with LEDs as large as their crossing rule's reach, the proof
    env = envelope(Camera(), xyz, radii, 0.0)  # removes nothing the cheap tests leave: 5 mm LEDs, exact drawing
    proved = tiled_windows(xyz, radii, env, None, 10**9, 10**9)
    loose = tiled_windows(xyz, radii, env, None, 0, 10**9)  # every tile over a budget of 0 candidates
    assert loose.over_budget == tuple(range(loose.tiles))
    assert {tuple(t) for t in proved.triangles.tolist()} < {tuple(t) for t in loose.triangles.tolist()}


def test_two_local_processes_give_the_same_proof():
    xyz, radii = _jittered(11, 5)
    env = envelope(Camera(), xyz, radii, 0.03)
    with runner(2) as two:
        assert isinstance(two, LocalProcesses) and two.workers == 2
        parallel = tiled_windows(xyz, radii, env, two, 10**9, 10**9).triangles
    assert np.array_equal(parallel, tiled_windows(xyz, radii, env, InProcess(), 10**9, 10**9).triangles)


def test_unreachable_scheduler_is_one_line_exit_1_nothing_written(tmp_path):
    out = tmp_path / "out"
    done = vlp("vlp-plan", str(ROOT / "layouts" / "grid-32.yaml"), "-o", str(out), "--scheduler", "tcp://127.0.0.1:9")
    assert done.returncode == 1, done.stderr
    assert done.stderr.count("\n") == 1 and "--scheduler tcp://127.0.0.1:9" in done.stderr, done.stderr
    assert "refused" in done.stderr  # said at once, not after Dask's connect timeout
    assert "Traceback" not in done.stderr and not out.exists() and list(tmp_path.iterdir()) == []


def test_workers_and_scheduler_together_are_a_usage_error(tmp_path):
    done = vlp("vlp-plan", str(ROOT / "layouts" / "grid-32.yaml"), "-o", str(tmp_path / "o"), "--workers", "2",
                     "--scheduler", "tcp://127.0.0.1:9")
    assert done.returncode == 2 and "exclude each other" in done.stderr, done.stderr


@pytest.mark.slow
def test_plan_is_byte_identical_in_process_on_two_workers_and_on_a_dask_cluster(tmp_path):
    from distributed import LocalCluster

    layout = tmp_path / "lattice-100.yaml"  # 4 tiles of about 64 luminaires (tiles.TILE_LEDS), planned in seconds
    rows = [f"- {{name: L{i:02d}{j:02d}, x: {0.25 + 0.5 * i}, y: {0.25 + 0.5 * j}}}" for i in range(10) for j in range(10)]
    layout.write_text("unit: m\nheight: 2.5\nradius: 0.1\noutline: [[0, 0], [5, 0], [5, 5], [0, 5]]\nluminaires:\n"
                      + "\n".join(rows) + "\n")
    common = ["--json", "--error-poses-per-m2", "0"]  # the error map is sampled in this process either way
    with LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None) as cluster:
        runs = {"single": [], "workers": ["--workers", "2"], "dask": ["--scheduler", cluster.scheduler_address]}
        for name, extra in runs.items():
            done = vlp("vlp-plan", str(layout), "-o", str(tmp_path / name), *common, *extra)
            assert done.returncode == 0, done.stderr
    doc = yaml.safe_load((tmp_path / "single" / "plan.yaml").read_text())
    ws = doc["verification"]["window_set"]
    assert ws["proved"] and ws["envelope"]["tiles"] >= 4 and ws["envelope"]["tiles_over_budget"] == 0
    files = sorted(p.relative_to(tmp_path / "single") for p in (tmp_path / "single").rglob("*") if p.is_file())
    assert {"plan.yaml", "lattice-100-vlp.dxf", "site-report.pdf", "site-report.html"} <= {f.name for f in files}
    assert sum(f.parts[0] == "firmware" for f in files) >= 100
    for other in ("workers", "dask"):
        mine = sorted(p.relative_to(tmp_path / other) for p in (tmp_path / other).rglob("*") if p.is_file())
        assert mine == files
        for name in files:
            assert (tmp_path / other / name).read_bytes() == (tmp_path / "single" / name).read_bytes(), (other, name)
