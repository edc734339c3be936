"""Fuzzing every reader with hypothesis: mutated valid files end in a model or one clear line.

Where tests/cli/test_hostile_input.py enumerates hundreds of chosen mutations, these tests let
hypothesis draw them: a value anywhere in a valid document replaced by an arbitrary one (any
type, non-finite and absurd numbers, nesting), a key deleted, the text cut, bytes flipped or
inserted. Each reader (layout YAML and CSV through ``read_layout``'s checks, DXF, camera YAML,
plan.yaml, observation JSON) must return its model or raise a :class:`PlannerError` whose
message is one line naming the file, within a time bound; ``vlp-plan`` itself must exit 0, 1
or 2 with at most one error line and leave nothing half-written. Seeds are derandomised so a
failure reproduces; hypothesis prints the smallest input it found. ``VLP_FUZZ_EXAMPLES=N`` searches
deeper with random seeds (outside CI).
"""

from __future__ import annotations

import copy
import functools
import json
import os
import time
from pathlib import Path
from tempfile import TemporaryDirectory

import ezdxf
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import grid_xy
from planner.camera.file import read_camera
from planner.cli import plan
from planner.errors import PlannerError
from planner.layout.read import read_layout
from planner.plan.file import load_plan
from planner.positioning.snapshot_file import read_snapshot

TIME_BOUND_S = 20.0
DEEP = int(os.environ.get("VLP_FUZZ_EXAMPLES", "0"))
"""``VLP_FUZZ_EXAMPLES=5000`` runs that many random (not derandomised) examples per test: a deeper search
than CI's fixed 60."""
FUZZ = settings(max_examples=DEEP or 60, deadline=None, derandomize=not DEEP, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

scalars = (st.none() | st.booleans() | st.integers(-10**30, 10**30) | st.floats(allow_nan=True, allow_infinity=True)
           | st.sampled_from([0, -1, 1e-300, 1e308, 2**63, "", "1,5", "nan", "../x", "$\\foo{$", "a\nb", "\x00"])
           | st.text(max_size=12))
values = st.recursive(scalars, lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner,
                                                                                           max_size=3), max_leaves=8)


def _paths(doc, prefix=()):
    """Every place in a document: the path to it (keys and indices)."""
    yield prefix
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from _paths(v, (*prefix, k))
    elif isinstance(doc, list):
        for k, v in enumerate(doc):
            yield from _paths(v, (*prefix, k))


@st.composite
def mutated(draw, doc):
    """``doc`` with one to three places replaced by arbitrary values or deleted."""
    out = copy.deepcopy(doc)
    for _ in range(draw(st.integers(1, 3))):
        places = [p for p in _paths(out) if p]
        if not places:
            break
        path = draw(st.sampled_from(places))
        parent = out
        for key in path[:-1]:
            parent = parent[key]
        if isinstance(parent, dict) and draw(st.booleans()) and draw(st.booleans()):
            del parent[path[-1]]
        else:
            parent[path[-1]] = draw(values)
    return out


@st.composite
def damaged(draw, data: bytes):
    """``data`` cut short, with bytes flipped, or with junk inserted."""
    kind = draw(st.sampled_from(["cut", "flip", "insert"]))
    if kind == "cut":
        return data[: draw(st.integers(0, len(data)))]
    buf = bytearray(data)
    for _ in range(draw(st.integers(1, 8))):
        at = draw(st.integers(0, len(buf) - 1))
        if kind == "flip":
            buf[at] = draw(st.integers(0, 255))
        else:
            buf[at:at] = draw(st.binary(min_size=1, max_size=16))
    return bytes(buf)


def _one_line(call, path: Path) -> None:
    """``call()`` returns a model or raises a PlannerError of one line that names ``path``; quickly."""
    start = time.perf_counter()
    try:
        call()
    except PlannerError as exc:
        message = str(exc)
        assert message and "\n" not in message and "\r" not in message, repr(message)
        assert str(path) in message or path.name in message, message
    assert time.perf_counter() - start < TIME_BOUND_S


def _write(folder: str, name: str, data: bytes | str) -> Path:
    path = Path(folder) / name
    path.write_bytes(data.encode("utf-8", "surrogatepass") if isinstance(data, str) else data)
    return path


LAYOUT = {"unit": "m", "height": 2.5, "radius": 0.1,
          "outline": [[-0.25, -0.25], [1.75, -0.25], [1.75, 1.25], [-0.25, 1.25]],
          "luminaires": [{"name": f"L{k:02d}", "x": float(x), "y": float(y)} for k, (x, y) in enumerate(grid_xy(3, 4, 0.5, 0.5))]}
CAMERA = {"width_px": 4000, "height_px": 3000, "hfov_deg": 50.4, "receiver_height_m": [0.5, 1.5], "max_tilt_deg": 40,
          "row_time_s": 20e-6}
OBSERVATION = {"camera": {"fx": 4250.0, "fy": 4250.0, "cx": 2000.0, "cy": 1500.0, "width": 4000, "height": 3000},
               "leds": [{"id": i, "ellipse": {"cx": 1500.0 + 500 * i, "cy": 1500.0, "major": 400.0, "minor": 380.0,
                                              "angle_deg": 10.0}} for i in (1, 2, 3)]}


def _csv_text() -> str:
    return "# unit: m\nname,x,y,z,radius\n" + "".join(f"{lum['name']},{lum['x']},{lum['y']},2.5,0.1\n"
                                                      for lum in LAYOUT["luminaires"])


def _dxf_bytes() -> bytes:
    with TemporaryDirectory() as folder:
        doc = ezdxf.new("R2010")
        doc.header["$INSUNITS"] = 4
        for lum in LAYOUT["luminaires"]:
            doc.modelspace().add_circle((1000 * lum["x"], 1000 * lum["y"]), 100.0, dxfattribs={"layer": "LIGHTS"})
        doc.saveas(Path(folder) / "a.dxf")
        return (Path(folder) / "a.dxf").read_bytes()


DXF = _dxf_bytes()


@FUZZ
@given(mutated(LAYOUT))
def test_layout_yaml_fields(doc):
    with TemporaryDirectory() as folder:
        path = _write(folder, "site.yaml", yaml.safe_dump(doc, allow_unicode=True))
        _one_line(lambda: read_layout(path, None), path)


@FUZZ
@given(damaged(yaml.safe_dump(LAYOUT).encode()))
def test_layout_yaml_bytes(data):
    with TemporaryDirectory() as folder:
        path = _write(folder, "site.yaml", data)
        _one_line(lambda: read_layout(path, None), path)


@FUZZ
@given(damaged(_csv_text().encode()))
def test_layout_csv_bytes(data):
    with TemporaryDirectory() as folder:
        path = _write(folder, "site.csv", data)
        _one_line(lambda: read_layout(path, None), path)


@FUZZ
@given(st.lists(st.tuples(st.integers(1, 12), st.integers(0, 4), scalars.map(str)), min_size=1, max_size=4))
def test_layout_csv_cells(edits):
    rows = [line.split(",") for line in _csv_text().splitlines()]
    for r, c, text in edits:
        rows[r][c] = text.replace("\n", " ")
    with TemporaryDirectory() as folder:
        path = _write(folder, "site.csv", "\n".join(",".join(row) for row in rows) + "\n")
        _one_line(lambda: read_layout(path, None), path)


@settings(FUZZ, max_examples=DEEP or 40)
@given(damaged(DXF))
def test_dxf_bytes(data):
    with TemporaryDirectory() as folder:
        path = _write(folder, "site.dxf", data)
        _one_line(lambda: read_layout(path, None), path)


@FUZZ
@given(mutated(CAMERA))
def test_camera_yaml_fields(doc):
    with TemporaryDirectory() as folder:
        path = _write(folder, "phone.yaml", yaml.safe_dump(doc, allow_unicode=True))
        _one_line(lambda: read_camera(path), path)


@FUZZ
@given(mutated(OBSERVATION))
def test_observation_json_fields(doc):
    with TemporaryDirectory() as folder:
        path = _write(folder, "obs.json", json.dumps(doc, allow_nan=True))
        _one_line(lambda: read_snapshot(path), path)


@FUZZ
@given(damaged(json.dumps(OBSERVATION).encode()))
def test_observation_json_bytes(data):
    with TemporaryDirectory() as folder:
        path = _write(folder, "obs.json", data)
        _one_line(lambda: read_snapshot(path), path)


@functools.cache
def _plan_doc() -> dict:
    """A plan.yaml to mutate: planned when the test first draws, not at collection (where every xdist worker
    would plan it, compiling the numba kernels side by side in a fresh install)."""
    with TemporaryDirectory() as folder:
        layout = _write(folder, "site.yaml", yaml.safe_dump(LAYOUT))
        assert plan.main([str(layout), "-o", str(Path(folder) / "out"), "--no-report", "--no-map", "--no-firmware",
                          "--json", "--error-poses-per-m2", "0"]) is not None
        return yaml.safe_load((Path(folder) / "out" / "plan.yaml").read_text())


@settings(FUZZ, max_examples=DEEP or 100)
@given(st.deferred(lambda: mutated(_plan_doc())))
def test_plan_yaml_fields(doc):
    with TemporaryDirectory() as folder:
        path = _write(folder, "plan.yaml", yaml.safe_dump(doc, allow_unicode=True))
        _one_line(lambda: load_plan(path), path)


@settings(FUZZ, max_examples=DEEP // 10 or 25)
@given(mutated(LAYOUT))
def test_vlp_plan_ends_in_a_plan_or_one_line_and_leaves_nothing(doc):
    import contextlib
    import io

    with TemporaryDirectory() as folder:
        path = _write(folder, "site.yaml", yaml.safe_dump(doc, allow_unicode=True))
        out = Path(folder) / "out"
        err = io.StringIO()
        start = time.perf_counter()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = plan.console_main([str(path), "-o", str(out), "--scheme", "unique", "--no-verify", "--no-report",
                                      "--no-map", "--no-firmware"])
        assert time.perf_counter() - start < TIME_BOUND_S
        lines = [line for line in err.getvalue().splitlines() if line.strip()]
        assert "Traceback" not in err.getvalue() and "internal error" not in err.getvalue(), err.getvalue()
        if code == 0:
            assert (out / "plan.yaml").is_file()
        else:
            assert code in (1, 2) and len([line for line in lines if ": error:" in line]) == 1, (code, lines)
            assert not out.exists() and not [p for p in Path(folder).iterdir() if p.name.startswith(".out.")]
