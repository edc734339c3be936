"""Shared test helpers: synthetic layouts, the bundled 512 grid planned once per run, the ``slow`` marker
(``pytest -m "not slow"`` is the fast subset: see the README) and the ``acceptance`` marker (an issue's Done-when
run at full size, deselected unless ``--acceptance``: ``benchmarks/acceptance.py`` runs them)."""

import hashlib
import io
import json
import math
import os
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager, redirect_stdout
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
"""Where the installed console scripts are: run them by path, never ``python -m planner...`` from the checkout
(its working directory would put the source tree ahead of the installed package)."""

SCRIPTS = {ep.name: ep for ep in metadata.distribution("vlp-plan").entry_points if ep.group == "console_scripts"}
"""The installed console scripts' entry points, by command name (what each script's wrapper calls)."""


def vlp(command: str, *args: object, cwd: str | Path | None = None) -> subprocess.CompletedProcess[str]:
    """The installed console script ``command`` run on ``args`` in this process: the function its wrapper calls,
    with ``sys.argv``, the working directory (``cwd``, if given) and the standard streams its own; stdin is empty
    and not a terminal. The exit code, stdout and stderr, as ``subprocess.run(capture_output=True, text=True)``
    gives them.

    A command run so costs no interpreter start and no imports (0.3 to 1.3 s a process, docs/performance.md).
    What only a process shows stays a process: the scripts themselves, their start-up time, hash seeds, signals,
    terminals, resource limits (tests/cli/test_commands.py, test_startup.py, test_hostile_files.py...)."""
    main = SCRIPTS[command].load()
    raw = io.BytesIO(), io.BytesIO()
    out, err = (io.TextIOWrapper(b, encoding="utf-8", newline="\n") for b in raw)
    saved, cwd_was = (sys.argv, sys.stdin, sys.stdout, sys.stderr), os.getcwd()
    try:
        sys.argv, sys.stdin, sys.stdout, sys.stderr = [command, *map(str, args)], io.StringIO(), out, err
        if cwd is not None:
            os.chdir(cwd)
        try:
            code = main()
        except SystemExit as done:  # argparse's errors, --help and --version, as the script's sys.exit sees them
            code = done.code if isinstance(done.code, int) or done.code is None else 1
            if isinstance(done.code, str):
                print(done.code, file=err)
    finally:
        sys.argv, sys.stdin, sys.stdout, sys.stderr = saved
        os.chdir(cwd_was)
    out.flush()
    err.flush()
    return subprocess.CompletedProcess([command, *map(str, args)], code or 0, *(b.getvalue().decode() for b in raw))


SLOW_FIXTURES = {"plan512_dir", "plan256_dir", "test_efficiency.py:table",
                 "test_efficiency.py:small_json", "test_accuracy.py:table3"}
"""Fixtures that plan a large site or run a whole study (tens of seconds): every test using one is ``slow``."""


SLOW_MODULES = {"test_plan_seal.py", "test_flash_host.py", "test_flash_images.py", "test_journal_chain.py", "test_driver_avr.py",
                "test_photo.py", "test_phone_photos.py", "test_video.py", "test_advice.py", "test_advice_frames.py",
                "test_default_receiver.py", "test_verify_verdict.py", "test_tone_site.py", "test_parallel.py",
                "test_gravity.py", "test_from_plan.py", "test_timings.py", "test_hostile_dxf.py"}
"""Test files whose tests run the installed commands end to end (plans sealed and flashed over simulated buses, photos
rendered and located, advice and tone sites planned, emulated drivers): seconds per test, so every test in them is
``slow`` and the fast subset keeps the checks of one stage at a time."""


def pytest_addoption(parser):
    parser.addoption("--acceptance", action="store_true",
                     help="also collect the tests marked acceptance: the issues' Done-when runs at full size (300-pose "
                          "twins, 20-photo sets, issue 34's large sites), about 25 minutes on 2 cores; the suite runs each "
                          "smaller with the same assertions. benchmarks/acceptance.py runs them and prints their figures")


def pytest_collection_modifyitems(config, items):
    for item in items:
        names = set(getattr(item, "fixturenames", ()))
        if (names & SLOW_FIXTURES or {f"{item.path.name}:{n}" for n in names} & SLOW_FIXTURES
                or item.path.name in SLOW_MODULES):
            item.add_marker(pytest.mark.slow)
        if item.get_closest_marker("acceptance"):
            item.add_marker(pytest.mark.slow)
    if not config.getoption("--acceptance"):
        full = [item for item in items if item.get_closest_marker("acceptance")]
        if full:  # reported as deselected, never as passed
            config.hook.pytest_deselected(items=full)
            items[:] = [item for item in items if not item.get_closest_marker("acceptance")]


@contextmanager
def _shared_folder(tmp_path_factory, name: str) -> Iterator[Path]:
    """``shared-plans/<name>`` of this run, held under a lock: the first xdist worker to ask fills it, the
    others wait and read it."""
    import fcntl

    base = tmp_path_factory.getbasetemp()
    # Under xdist each worker's basetemp sits in the run's own directory; without xdist the parent
    # is shared by every run on the machine (and every checkout), so the plan would go stale.
    root = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base
    (root / "shared-plans").mkdir(exist_ok=True)
    with open(root / "shared-plans" / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield root / "shared-plans" / name


def _shared_plan(tmp_path_factory, name: str, leds: int | None, *extra: str, stem: str = "") -> Path:
    """``layouts/<name>`` planned with default options (firmware and report, no maps, no error map), once
    for the whole run: the first xdist worker to ask plans it, the others wait on a lock and read it."""
    from planner.cli.plan import main as plan_main

    with _shared_folder(tmp_path_factory, stem or Path(name).stem) as out:
        if not (out / "plan.yaml").is_file():
            with redirect_stdout(io.StringIO()):  # the JSON summary: the tests read the files
                plan_main([str(ROOT / "layouts" / name), *(["--leds", str(leds)] if leds else []), "-o", str(out),
                           "--no-map", "--json", "--error-poses-per-m2", "0", *extra])
    return out


@dataclass(frozen=True)
class PlanRun:
    """One run of the installed ``vlp-plan``: exit code, stdout, stderr and its output folder (read it only)."""

    returncode: int
    stdout: str
    stderr: str
    outdir: Path


def shared_vlp_plan(tmp_path_factory, *args: str) -> PlanRun:
    """The installed ``vlp-plan args -o <folder>`` run once for the whole run (from the checkout's root, so
    ``layouts/...`` names the bundled layouts): tests in several files asking the same ``args`` share it."""
    key = hashlib.sha256("\0".join(args).encode()).hexdigest()[:16]
    with _shared_folder(tmp_path_factory, f"run-{key}") as out:
        record = out.with_name(f"{out.name}.json")
        if not record.is_file():
            done = vlp("vlp-plan", *args, "-o", str(out), cwd=ROOT)
            record.write_text(json.dumps([done.returncode, done.stdout, done.stderr]))
        code, stdout, stderr = json.loads(record.read_text())
    return PlanRun(code, stdout, stderr, out)


SITE_KEY = bytes(range(32))
"""The tests' site key (vlp-flash's sim:// drivers take it): the sealed shared plans are sealed under it."""


def grid32_copy(tmp_path_factory, dest: Path, *extra: str, sealed: bool = False) -> Path:
    """Fill the new folder ``dest`` with what ``vlp-plan layouts/grid-32.yaml -o dest --no-map --no-report --json
    *extra`` writes (with ``--key-file`` holding :data:`SITE_KEY` if ``sealed``): planned in process once for the
    whole run, copied for each caller, which may write beside it. Returns ``dest / "plan.yaml"``."""
    import shutil

    from planner.cli.plan import main as plan_main

    key = hashlib.sha256("\0".join([*extra, str(sealed)]).encode()).hexdigest()[:16]
    with _shared_folder(tmp_path_factory, f"grid-32-{key}") as out:
        if not (out / "plan.yaml").is_file():
            site_key = out.with_name(f"{out.name}.key")
            site_key.write_text(SITE_KEY.hex())
            site_key.chmod(0o600)
            with redirect_stdout(io.StringIO()):  # the JSON summary: the tests read the files
                code = plan_main([str(ROOT / "layouts" / "grid-32.yaml"), "-o", str(out), "--no-map", "--no-report",
                                  "--json", *extra, *(["--key-file", str(site_key)] if sealed else [])])
            assert code == 0 and (out / "plan.yaml").is_file(), code
        shutil.copytree(out, dest)
    return dest / "plan.yaml"


@pytest.fixture(scope="session", autouse=True)
def _kernels_compiled_once():
    """In a fresh install each numba kernel compiles on its first use, then every later process loads it from the
    cache. Both xdist workers start with tests that plan, so they compiled the same kernels side by side (15 of the
    fast subset's 41 CPU-s of compiling, docs/performance.md). The first worker now begins by planning grid-32 (a
    plan's kernels), the second by running the pair proof and the certificate on a small lattice (theirs): each
    loads the other's from the cache when it needs them. Nothing is asserted; with the caches written, about a
    second."""
    worker = os.environ.get("PYTEST_XDIST_WORKER")
    if worker == "gw0":
        from planner.layout.read import read_layout
        from planner.plan.pipeline import PlanOptions, make_plan

        make_plan(read_layout(ROOT / "layouts" / "grid-32.yaml", None), PlanOptions(error_poses_per_m2=0.0))
    elif worker == "gw1":
        from planner.camera.model import Camera
        from planner.verify.certify import certify_windows
        from planner.verify.envelope import envelope
        from planner.verify.pair_proof import prove_pair_set
        from planner.verify.proof import possible_windows

        xyz, radii = np.column_stack([grid_xy(4, 4, 0.5, 0.5), np.full(16, 2.5)]), np.full(16, 0.1)
        prove_pair_set(xyz, radii, Camera(), 0.03)
        env = envelope(Camera(), xyz, radii, 0.03)
        certify_windows(xyz, radii, Camera(), 0.03, possible_windows(xyz, radii, env), min_width=0.08,
                        budget=2_000, tiles=[middle_tile(xyz[:, :2], env)[0]])


def middle_tile(xy: np.ndarray, env) -> tuple[int, tuple[float, float, float, float]]:
    """The certificate's tile of axis points at the site's middle: its number and bounds (x0, x1, y0, y1) [m]."""
    from planner.verify.certify import tile_grid

    origin, side, nx, _ = tile_grid(xy, env)
    ix, iy = ((xy.mean(axis=0) + 0.01 - origin) // side).astype(int)
    x0, y0 = origin + side * np.array([ix, iy])
    return int(iy * nx + ix), (x0, x0 + side, y0, y0 + side)


@pytest.fixture(scope="session")
def plan512_dir(tmp_path_factory) -> Path:
    """``grid-512.yaml`` planned once for the whole run (default IDs; firmware and report, no map; sealed under
    ``bytes(range(32))``); read it, never write into it."""
    key = tmp_path_factory.getbasetemp() / "site.key"  # sealed under bytes 0..31, the tests' site key: vlp-flash takes it
    key.write_text(SITE_KEY.hex())
    key.chmod(0o600)  # else vlp-plan warns that every user can read it
    return _shared_plan(tmp_path_factory, "grid-512.yaml", 512, "--key-file", str(key))


@pytest.fixture(scope="session")
def plan256_dir(tmp_path_factory) -> Path:
    """``grid-256.yaml`` planned once for the whole run, as :func:`plan512_dir`."""
    return _shared_plan(tmp_path_factory, "grid-256.yaml", None)


@pytest.fixture(scope="session")
def grid32_plan():
    """``grid-32.yaml`` planned in process with default options and the error map (4 poses per m2), once per
    worker: the :class:`planner.plan.model.Plan` that tests of the maps and figures read; never change it."""
    from planner.layout.read import read_layout
    from planner.plan.pipeline import PlanOptions, make_plan

    return make_plan(read_layout(ROOT / "layouts" / "grid-32.yaml", None), PlanOptions(error_poses_per_m2=4.0))


STRONG_WIDE_CAMERA = {"width_px": 4000, "height_px": 3000, "fx_px": 2800.0, "fy_px": 2800.0, "lens": "pinhole",
                      "distortion": [-0.2, 0.05]}
"""A camera YAML's fields for a strongly distorting wide lens, stronger than the ``wide`` profile's: 77.3 deg
horizontal field of view through the lens, barrel k1 = -0.2, k2 = 0.05 (the corner drawn 16 % inwards)."""


@pytest.fixture(scope="session")
def wide_plan_dir(tmp_path_factory) -> Path:
    """``grid-32.yaml`` planned once for the whole run with ``--camera wide`` (the profile); read it only."""
    return _shared_plan(tmp_path_factory, "grid-32.yaml", None, "--camera", "wide", stem="grid-32-wide")


def nearest_by_the_model(poses, cand, xyz, radii, cam, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Of the candidate LEDs ``cand`` (P, K) of each pose, the ``count`` wholly seen nearest the image centre by
    the camera model's numpy images (``project_discs``), ties in candidate order, sorted (P, count; -1 where fewer
    are seen), and how many are wholly seen (P,)."""
    from planner.camera.model import project_discs

    img = project_discs(poses, xyz[cand], radii[cand], cam)
    d2 = np.where(img["inside"], (img["u"] - cam.cx_px) ** 2 + (img["v"] - cam.cy_px) ** 2, np.inf)
    order = np.argsort(d2, axis=1, kind="stable")[:, :count]
    ok = np.isfinite(np.take_along_axis(d2, order, axis=1)).all(axis=1)
    chosen = np.full((len(poses), count), -1)
    chosen[ok] = np.sort(np.take_along_axis(cand, order, axis=1)[ok], axis=1)
    return chosen, img["inside"].sum(axis=1)


def exact_nearest(xyz, radii, cam, poses, count: int) -> np.ndarray:
    """The ``count`` wholly seen LEDs nearest the image centre with every LED projected (no candidate
    shortcut), sorted, for the poses that see that many: the paper's window (3), the two-LED window (2)."""
    every = np.broadcast_to(np.arange(len(xyz)), (len(poses), len(xyz)))
    chosen, _ = nearest_by_the_model(poses, every, xyz, radii, cam, count)
    return chosen[chosen[:, 0] >= 0]


def accepted(windows: np.ndarray, drawn: np.ndarray, installed: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """The rows of ``windows`` (from :func:`exact_nearest` on the ``installed`` site) the three-LED receiver takes:
    not collinear as drawn in the plan, and no other installed LED's disc over one of their sides."""
    from planner.verify.windows import MIN_FLATNESS, crossed, flatness

    windows = np.asarray(windows, dtype=np.int64).reshape(-1, 3)
    if len(windows) == 0:
        return windows
    return windows[(flatness(drawn[windows]) >= MIN_FLATNESS) & ~crossed(windows, installed, radii)]


def grid_xy(rows: int, cols: int, sx: float = 1.0, sy: float = 1.0, angle_rad: float = 0.0,
            jitter_m: float = 0.0, seed: int = 0) -> np.ndarray:
    """Plan positions of a rows x cols lattice, optionally rotated and jittered [m]."""
    pts = np.array([(c * sx, r * sy) for r in range(rows) for c in range(cols)], dtype=float)
    pts += np.random.default_rng(seed).normal(0.0, jitter_m, pts.shape)
    cos, sin = np.cos(angle_rad), np.sin(angle_rad)
    return pts @ np.array([[cos, sin], [-sin, cos]])


def jittered_xy(seed: int = 7) -> np.ndarray:
    """Issue 13's site: a 0.6 m lattice of 30 x 16 positions, 20 % left empty, the rest moved up to 12 cm [m]."""
    rng = np.random.default_rng(seed)
    r, c = np.meshgrid(np.arange(16), np.arange(30), indexing="ij")
    pts = 0.6 * np.column_stack([c.ravel(), r.ravel()]).astype(float)
    keep = rng.random(len(pts)) >= 0.2
    return pts[keep] + rng.uniform(-0.12, 0.12, (int(keep.sum()), 2))


def poisson_xy(n: int, spacing: float, seed: int) -> np.ndarray:
    """Dart throwing: up to n points at least ``spacing`` apart in a square sized for about n."""
    rng, side, pts = np.random.default_rng(seed), spacing * math.sqrt(n) * 1.1, []
    for p in rng.uniform(0, side, (40 * n, 2)):
        if all(np.hypot(*(p - q)) >= spacing for q in pts):
            pts.append(p)
    return np.array(pts[:n])


def hex_xy(rows: int, cols: int, pitch: float = 1.0) -> np.ndarray:
    """Staggered rows (every other row shifted half a pitch): a triangular lattice."""
    return np.array([(c * pitch + 0.5 * pitch * (r % 2), r * pitch * 0.866) for r in range(rows) for c in range(cols)])


def minimal_plan(luminaires: list[dict], **sections):
    """A small checked plan (as ``load_plan`` returns it) holding ``luminaires``; ``sections`` replace top-level keys."""
    from planner.plan.file import plan_from_document

    ids = [e.get("id") for e in luminaires]
    doc = {"format": "vlp-plan/1", "generator": "vlp-plan 0.1.0",
           "scheme": "unique" if len(set(ids)) == len(ids) else "window",  # a unique plan's IDs are distinct
           "code": {"bits": 8, "max_id": 255, "naive_bits": 8, "lower_bound_bits": 8, "efficiency": 0.0,
                    "word_bits": 8},
           "modulation": {"line_code": "manchester", "preamble": "01110001", "chip_rate_hz": 4470.0, "frame_chips": 8,
                          "frame_period_s": 8 / 4470, "frames_in_smallest_image": 2.0, "smallest_image_rows": 200.0,
                          "row_time_s": 2e-5},
           "luminaires": [{"x": 0.0, "y": 0.0, "z": 2.5, "radius": 0.1, "parity": "odd", "region": 0, **e}
                          for e in luminaires], **sections}
    return plan_from_document(doc, "test plan")
