"""The bad inputs issue 36 lists, each refused with one clear line, a non-zero exit, within its budget and
with nothing half-written: output paths that are folders, files or pipes; a full disk; photo headers claiming
60,000 x 60,000 px; 5,000-digit integers; CSV fields over the csv module's limit; YAML alias bombs in every
YAML a command reads; IFC models with dangling references; unbounded batch sizes; plans that disagree with
themselves or were edited since their verdict; a dense drawing whose unit is guessed; a killed run's staging.

Cheap inputs, in process through each command's ``console_main``; the full disk and the memory cap run in a
child process with a resource limit (``RLIMIT_FSIZE``: writes past 4 KiB fail as on a full disk).
"""

from __future__ import annotations

import json
import os
import re
import resource
import struct
import subprocess
import sys
import time
import zlib
from pathlib import Path

import ezdxf
import pytest
import yaml

from planner.cli import accuracy, calibrate, efficiency, flash, inspect, locate, plan, report, twin, verify

FAST = ["--scheme", "unique", "--no-verify", "--no-report", "--no-map", "--no-firmware"]
TIME_BOUND_S = 60.0
HUGE = "9" * 5000
POSE = "0.75,0.5,1.0,0,0,0"


def _refused(module, argv: list[str], capsys, folder: Path) -> str:
    """Run once: exit 1 or 2, exactly one line ``vlp-NAME: error: ...``, no traceback, in time, and no hidden
    temporary file or staging folder left in ``folder``; returns the line."""
    before = {p.name for p in folder.iterdir()}
    start = time.perf_counter()
    code = module.console_main(argv)
    seconds = time.perf_counter() - start
    _, err = capsys.readouterr()
    name = "vlp-" + module.__name__.rsplit(".", 1)[-1].replace("_", "-")
    lines = [line for line in err.splitlines() if line.strip()]
    assert code in (1, 2), (argv, code, err)
    assert len(lines) == 1 and lines[0].startswith(f"{name}: error: "), (argv, err)
    assert "Traceback" not in err and "internal error" not in err and len(lines[0]) < 600, err[:600]
    assert seconds < TIME_BOUND_S, (argv, seconds)
    left = {p.name for p in folder.iterdir()} - before
    assert not {n for n in left if n.startswith(".")}, (argv, left)
    return lines[0]


def _png(path: Path, width: int, height: int) -> Path:
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0))
                     + chunk(b"IDAT", zlib.compress(b"\0" * 4096)) + chunk(b"IEND", b""))
    return path


def _jpeg(path: Path, width: int, height: int) -> Path:
    app0 = b"\xff\xe0" + struct.pack(">H", 16) + b"JFIF\0\x01\x01\0\0\x01\0\x01\0\0"
    sof = b"\xff\xc0" + struct.pack(">HBHHB", 11, 8, height, width, 1) + b"\x01\x11\x00"
    path.write_bytes(b"\xff\xd8" + app0 + sof + b"\xff\xd9")
    return path


BOMB = "".join([f"l{k}: &l{k} [" + ",".join([f"*l{k - 1}" if k else '"lol"'] * 9) + "]\n" for k in range(10)])
"""Ten levels of nine aliases each: 9^10 (3.5 billion) strings once expanded, 1 kB as text."""


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """A folder with a layout and its verified plan (plan/plan.yaml)."""
    base = tmp_path_factory.mktemp("site")
    doc = {"unit": "m", "height": 2.5, "luminaires": [{"name": f"L{i}{j}", "x": 0.5 * i, "y": 0.5 * j}
                                                      for i in range(4) for j in range(3)]}
    (base / "site.yaml").write_text(yaml.safe_dump(doc))
    (base / "key").write_text(bytes(range(32)).hex())
    assert plan.console_main([str(base / "site.yaml"), "-o", str(base / "plan"), "--no-report", "--no-map",
                              "--allow-unusable", "--poses-per-m2", "100", "--key-file", str(base / "key")]) == 0
    assert plan.console_main([str(base / "site.yaml"), "-o", str(base / "unique"), "--scheme", "unique",
                              "--no-report", "--no-map", "--no-firmware", "--allow-unusable",
                              "--poses-per-m2", "100"]) == 0
    return base


# --- outputs that cannot be files, or folders -----------------------------------------------------------------

FILE_FLAGS = {"verify --map": (verify, lambda s, out: [str(s / "plan" / "plan.yaml"), "--map", out]),
              "twin --png": (twin, lambda s, out: [str(s / "plan" / "plan.yaml"), "--pose", POSE, "--png", out]),
              "inspect --png": (inspect, lambda s, out: [str(s / "site.yaml"), "--png", out]),
              "accuracy --cdf": (accuracy, lambda s, out: ["--trials", "1", "--cdf", out]),
              "efficiency --plot": (efficiency, lambda s, out: ["--sizes", "8", "--plot", out]),
              "calibrate --output": (calibrate, lambda s, out: ["--blink-firmware", str(s / "fw"), "--blink-hz",
                                                                 "100", "--output", out])}
DIR_FLAGS = {"plan -o": (plan, lambda s, out: [str(s / "site.yaml"), "-o", out, *FAST]),
             "report -o": (report, lambda s, out: [str(s / "plan" / "plan.yaml"), "-o", out]),
             "twin --save-failures": (twin, lambda s, out: [str(s / "plan" / "plan.yaml"), "--poses", "2",
                                                           "--save-failures", out]),
             "calibrate --blink-firmware": (calibrate, lambda s, out: ["--blink-firmware", out, "--blink-hz", "100"])}
OUTPUT_CASES = [(flag, kind) for flag in FILE_FLAGS for kind in ("folder", "pipe")] + \
               [(flag, "file") for flag in DIR_FLAGS]


@pytest.mark.parametrize("case", OUTPUT_CASES, ids=[f"{f}-{k}" for f, k in OUTPUT_CASES])
def test_an_output_that_cannot_be_written_is_refused_before_work(case, site, tmp_path, capsys):
    flag, kind = case
    out = tmp_path / "out"
    if kind == "folder":
        out.mkdir()
    elif kind == "pipe":
        os.mkfifo(out)  # a device-like path: never replaced, never opened (a write would block)
    else:
        out.write_text("keep me\n")
    module, argv = (FILE_FLAGS | DIR_FLAGS)[flag]
    line = _refused(module, argv(site, str(out)), capsys, tmp_path)
    assert str(out) in line, line
    assert (out.is_dir() if kind == "folder" else out.is_fifo() if kind == "pipe" else
            out.read_text() == "keep me\n")  # untouched


FULL_DISK = {"plan -o": ["vlp-plan", "{site}/site.yaml", "-o", "{tmp}/out", "--scheme", "unique", "--no-verify"],
             "verify --map": ["vlp-verify", "{site}/plan/plan.yaml", "--map", "{tmp}/out.png", "--poses-per-m2", "20"],
             "twin --png": ["vlp-twin", "{site}/plan/plan.yaml", "--pose", POSE, "--png", "{tmp}/out.png"]}


@pytest.mark.parametrize("what", FULL_DISK)
def test_a_full_disk_is_one_line_and_leaves_nothing(what, site, tmp_path):
    """Writes past 4 KiB fail (RLIMIT_FSIZE, EFBIG: the same OSError path as ENOSPC on a full disk)."""
    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))

    argv = [a.format(site=site, tmp=tmp_path) for a in FULL_DISK[what]]
    bindir = Path(sys.executable).parent
    result = subprocess.run([str(bindir / argv[0]), *argv[1:]], capture_output=True, text=True, timeout=120,
                            preexec_fn=limit)
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert result.returncode == 1 and len(lines) == 1, result.stderr
    assert lines[0].startswith(f"{argv[0]}: error: ") and "too large" in lines[0].lower(), lines[0]
    assert not list(tmp_path.iterdir()), list(tmp_path.iterdir())  # no out/, no .out.*, no temporary file


# --- photos whose header claims a huge image ----------------------------------------------------------------

PHOTO_CASES = [(kind, use) for kind in ("png", "jpeg") for use in ("locate --image", "calibrate IMAGES",
                                                                   "calibrate --row-time", "calibrate --heights")]


@pytest.mark.parametrize("case", PHOTO_CASES, ids=[f"{k}-{u}" for k, u in PHOTO_CASES])
def test_a_photo_header_of_60000_px_is_refused_before_decoding(case, site, tmp_path, capsys):
    kind, use = case
    photo = (_png if kind == "png" else _jpeg)(tmp_path / f"big.{kind}", 60_000, 60_000)
    argv = {"locate --image": (locate, [str(site / "plan" / "plan.yaml"), "--image", str(photo)]),
            "calibrate IMAGES": (calibrate, [str(photo), str(photo), str(photo)]),
            "calibrate --row-time": (calibrate, ["--row-time", str(photo), "--blink-hz", "100"]),
            "calibrate --heights": (calibrate, ["--heights", f"1.0={photo}", f"2.0={photo}", "--led-radius-m",
                                                "0.1"])}[use]
    line = _refused(*argv, capsys, tmp_path)
    assert "60,000 x 60,000 px" in line and str(photo) in line, line


# --- numbers, fields and aliases no reader should swallow ------------------------------------------------------

def _edit_yaml(src: Path, dst: Path, edit) -> Path:
    doc = yaml.safe_load(src.read_text("utf-8"))
    edit(doc)
    dst.write_text(yaml.safe_dump(doc, sort_keys=False))
    return dst


def _text_cases(site: Path, tmp: Path) -> dict[str, tuple[object, list[str], str]]:
    """id -> (command, argv, what the line must name)."""
    plan_yaml = site / "plan" / "plan.yaml"
    layout = yaml.safe_load((site / "site.yaml").read_text())
    cases: dict[str, tuple[object, list[str], str]] = {}
    (tmp / "huge-x.yaml").write_text((site / "site.yaml").read_text().replace("x: 0.0", "x: " + HUGE, 1))
    cases["layout 5000-digit x"] = (plan, [str(tmp / "huge-x.yaml"), "-o", str(tmp / "o"), *FAST], "huge-x.yaml")
    (tmp / "huge.csv").write_text("name,x,y\nA,1,1\nB," + HUGE + ",2\nC,2,2\n")
    cases["csv 5000-digit x"] = (plan, [str(tmp / "huge.csv"), "-o", str(tmp / "o"), *FAST], "line 3")
    (tmp / "wide.csv").write_text("name,x,y\nA,1,1\n" + "B" * 200_000 + ",2,2\nC,2,2\n")
    cases["csv field over the limit"] = (plan, [str(tmp / "wide.csv"), "-o", str(tmp / "o"), *FAST], "line 3")
    (tmp / "wide-head.csv").write_text("name," + "x" * 200_000 + ",y\nA,1,1\n")
    cases["csv header over the limit"] = (plan, [str(tmp / "wide-head.csv"), "-o", str(tmp / "o"), *FAST], "line 1")
    (tmp / "cam.yaml").write_text(f"width_px: {HUGE}\nheight_px: 3000\nhfov_deg: 50\n")
    cases["camera 5000-digit width"] = (plan, [str(site / "site.yaml"), "--camera", str(tmp / "cam.yaml"), "-o",
                                               str(tmp / "o"), *FAST], "cam.yaml")
    (tmp / "plan-huge.yaml").write_text(plan_yaml.read_text().replace("id: 1\n", f"id: {HUGE}\n", 1))
    for name, module, extra in (("verify", verify, ["--poses-per-m2", "20"]), ("report", report, []),
                                ("twin", twin, ["--pose", POSE]), ("locate", locate, ["--simulate", POSE]),
                                ("flash", flash, ["--all", "--dry-run"])):
        cases[f"plan 5000-digit id {name}"] = (module, [str(tmp / "plan-huge.yaml"), *extra], "plan-huge.yaml")
        (tmp / "plan-bomb.yaml").write_text(BOMB + plan_yaml.read_text())
        cases[f"plan alias bomb {name}"] = (module, [str(tmp / "plan-bomb.yaml"), *extra], "aliases")
    obs = tmp / "obs.json"
    obs.write_text('{"camera": {"width": ' + HUGE + ', "height": 3000, "fx": 3000}, "leds": []}')
    cases["observation 5000-digit width"] = (locate, [str(plan_yaml), str(obs)], "obs.json")
    (tmp / "bomb-layout.yaml").write_text(BOMB + "luminaires: *l9\n")
    cases["layout alias bomb"] = (plan, [str(tmp / "bomb-layout.yaml"), "-o", str(tmp / "o"), *FAST], "aliases")
    for field in ("distortion", "name", "receiver_height_m"):
        (tmp / f"bomb-cam-{field}.yaml").write_text(BOMB + f"width_px: 4000\nheight_px: 3000\n{field}: *l9\n")
        cases[f"camera alias bomb {field}"] = (plan, [str(site / "site.yaml"), "--camera",
                                                      str(tmp / f"bomb-cam-{field}.yaml"), "-o", str(tmp / "o"),
                                                      *FAST], "aliases")
    (tmp / "loop.yaml").write_text("luminaires: &a [*a]\n")
    cases["layout alias loop"] = (plan, [str(tmp / "loop.yaml"), "-o", str(tmp / "o"), *FAST], "refers to")
    assert layout  # the layout the edits start from is a mapping
    return cases


TEXT_IDS = ["layout 5000-digit x", "csv 5000-digit x", "csv field over the limit", "csv header over the limit",
            "camera 5000-digit width", "observation 5000-digit width", "layout alias bomb", "layout alias loop",
            *(f"camera alias bomb {f}" for f in ("distortion", "name", "receiver_height_m")),
            *(f"plan {what} {name}" for what in ("5000-digit id", "alias bomb")
              for name in ("verify", "report", "twin", "locate", "flash"))]


@pytest.mark.parametrize("case", TEXT_IDS)
def test_a_number_field_or_alias_no_reader_should_swallow(case, site, tmp_path, capsys):
    cases = _text_cases(site, tmp_path)
    assert set(cases) == set(TEXT_IDS)
    module, argv, named = cases[case]
    line = _refused(module, argv, capsys, tmp_path)
    assert named in line, line
    assert not (tmp_path / "o").exists()


# --- plans that disagree with themselves, or changed since their verdict --------------------------------------

def _plan_edits() -> dict[str, tuple[str, object, str]]:
    """id -> (which plan, edit of its document, what the line says)."""
    def dup(doc):
        doc["luminaires"][1]["id"] = doc["luminaires"][0]["id"]

    def bits(doc):
        doc["code"]["bits"] = 1

    def max_id(doc):
        doc["luminaires"][0]["id"] = 2 ** doc["code"]["bits"] + 1

    def moved(doc):
        doc["luminaires"][0]["x"] += 0.3

    def renumbered(doc):
        a, b = doc["luminaires"][0], doc["luminaires"][-1]
        a["id"], b["id"] = b["id"], a["id"]

    return {"unique plan, one ID twice": ("unique", dup, "used more than once"),
            "bit width below the IDs": ("plan", bits, "disagree"),
            "an ID beyond code.max_id": ("plan", max_id, "exceeds code.max_id"),
            "one ID given to two luminaires": ("plan", dup, "edited since"),
            "a luminaire moved since its verdict": ("plan", moved, "edited since"),
            "two IDs swapped since the verdict": ("plan", renumbered, "edited since")}


EDIT_CASES = [(edit, name) for edit in _plan_edits() for name in ("verify", "report")]


@pytest.mark.parametrize("case", EDIT_CASES, ids=[f"{e}-{n}" for e, n in EDIT_CASES])
def test_an_inconsistent_or_edited_plan_is_refused(case, site, tmp_path, capsys):
    edit, name = case
    which, change, says = _plan_edits()[edit]
    path = _edit_yaml(site / which / "plan.yaml", tmp_path / "plan.yaml", change)
    if name == "verify" and says == "edited since":
        # vlp-verify checks the plan afresh: the old verdict is not shown, so the edit is no reason to refuse
        assert verify.console_main([str(path), "--poses-per-m2", "20"]) in (0, 3)
        assert "error" not in capsys.readouterr().err
        return
    module, extra = (verify, ["--poses-per-m2", "20"]) if name == "verify" else (report, ["-o", str(tmp_path / "r")])
    line = _refused(module, [str(path), *extra], capsys, tmp_path)
    assert says in line, line
    assert not (tmp_path / "r").exists()


# --- work the flags ask, bounded --------------------------------------------------------------------------------

BOUND_CASES = {"twin --poses 1e9": (twin, ["{plan}", "--poses", "1000000000"], "at most 100,000"),
               "twin --blur-px 1e9": (twin, ["{plan}", "--pose", POSE, "--blur-px", "1e9"], "at most 50"),
               "accuracy --trials 1e9": (accuracy, ["--trials", "1000000000"], "at most 10,000"),
               "efficiency --window-up-to 1e12": (efficiency, ["--window-up-to", "1000000000000"], "from 0 to"),
               "plan --leds 1e9": (plan, ["{layout}", "--leds", "1000000000"], "at most 100,000")}


@pytest.mark.parametrize("what", BOUND_CASES)
def test_an_unbounded_batch_is_refused_before_work(what, site, tmp_path, capsys):
    module, argv, says = BOUND_CASES[what]
    argv = [a.format(plan=site / "plan" / "plan.yaml", layout=site / "site.yaml") for a in argv]
    assert says in _refused(module, argv, capsys, tmp_path)


# --- IFC models with dangling references ------------------------------------------------------------------------

@pytest.fixture(scope="module")
def ifc_text(tmp_path_factory) -> str:
    from layout.ifc_models import model, save

    return save(model(storeys={"Ground": (0.0, 3, 3)})[0], tmp_path_factory.mktemp("ifc") / "m.ifc").read_text()


@pytest.mark.parametrize("nth", range(8))
def test_an_ifc_with_a_dangling_reference_is_one_line(nth, ifc_text, tmp_path, capsys):
    """The nth eighth of the model's referenced entities loses its definition; vlp-plan and vlp-inspect say which."""
    ids = [i for i in re.findall(r"^#(\d+)=", ifc_text, flags=re.M)  # those another entity refers to
           if re.search(rf"#{i}\b(?!=)", ifc_text)]
    gone = ids[(2 * nth + 1) * len(ids) // 16]
    path = tmp_path / "damaged.ifc"
    path.write_text(re.sub(rf"^#{gone}=.*\n", "", ifc_text, flags=re.M))
    line = _refused(plan, [str(path), "-o", str(tmp_path / "o"), *FAST], capsys, tmp_path)
    assert f"#{gone}" in line and "does not define" in line, line
    assert inspect.console_main([str(path)]) == 1  # vlp-inspect shows the line it would stop with
    assert f"#{gone}" in capsys.readouterr().out


# --- a dense drawing, and a killed run --------------------------------------------------------------------------

@pytest.mark.slow
def test_a_dense_drawing_in_metres_is_read_in_little_memory(tmp_path):
    """20,164 luminaires 0.6 m apart in metres: guessing the unit measured them as millimetres too, merging
    every part with every other (4.9 GB); now the guess takes a sample when parts lie that close."""
    doc = ezdxf.new("R2010")
    doc.header["$INSUNITS"] = 6
    msp = doc.modelspace()
    for i in range(142):
        for j in range(142):
            msp.add_circle((0.6 * i, 0.6 * j, 2.8), 0.1, dxfattribs={"layer": "LIGHTS"})
    doc.saveas(tmp_path / "dense.dxf")

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))  # the old code needed more than 3 GiB

    result = subprocess.run([str(Path(sys.executable).parent / "vlp-inspect"), str(tmp_path / "dense.dxf")],
                            capture_output=True, text=True, timeout=180, preexec_fn=limit)
    assert result.returncode == 0, result.stderr
    assert "20164 luminaires" in result.stdout and "unit     m" in result.stdout, result.stdout


def test_a_staging_folder_left_by_a_killed_run_is_removed(site, tmp_path, capsys):
    """kill -9 leaves .OUT.stage-PID-XXXX behind; the next run removes those whose process is gone, and keeps a
    live run's."""
    gone = subprocess.Popen(["true"])
    gone.wait()
    stale = tmp_path / f".out.stage-{gone.pid}-abcd1234"
    live = tmp_path / f".out.stage-{os.getpid()}-efgh5678"
    for folder in (stale, live):
        folder.mkdir()
        (folder / "plan.yaml").write_text("half")
    assert plan.console_main([str(site / "site.yaml"), "-o", str(tmp_path / "out"), *FAST]) == 0
    capsys.readouterr()
    assert not stale.exists() and live.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([live.name, "out"])


@pytest.mark.parametrize("mode", [0o644, 0o640, 0o604, 0o600, 0o400])
def test_a_key_file_every_user_may_read_is_warned_about(mode, site, tmp_path, capsys):
    shared = tmp_path / "shared"  # pytest's own folders are private: open the way to the key, as /home often is
    shared.mkdir()
    for folder in (shared, *shared.parents):
        if not folder.stat().st_mode & 0o001:
            folder.chmod(folder.stat().st_mode | 0o001)
    key = shared / "key"
    key.write_text(bytes(range(32)).hex())
    key.chmod(mode)
    assert flash.console_main([str(site / "plan" / "plan.yaml"), "--all", "--dry-run", "--key-file", str(key)]) == 0
    warned = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    assert warned == ([f"vlp-flash: warning: --key-file {key} is readable by every user of this machine: "
                       f"chmod 600 {key}"] if mode & 0o004 else []), warned
    # a run that fails says its error alone (the warning comes again once the error is fixed)
    (tmp_path / "bus.csv").write_text("L00,abc\n")
    assert flash.console_main([str(site / "plan" / "plan.yaml"), "--all", "--bus", "--port",
                               f"sim://?drivers=12&key={bytes(range(32)).hex()}", "--bus-map", str(tmp_path / "bus.csv"),
                               "--key-file", str(key), "--journal", str(tmp_path / "j.json")]) in (1, 2)
    lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("vlp-flash: error: "), lines


def test_an_emulated_eeprom_holding_a_key_is_private(tmp_path):
    from planner.flash.avr.runner import provision

    old = os.umask(0o022)
    try:
        provision(tmp_path / "AVR-0001.eeprom", 1, "AVR-0001", bytes(range(16)))
    finally:
        os.umask(old)
    assert (tmp_path / "AVR-0001.eeprom").stat().st_mode & 0o777 == 0o600


def test_a_site_photo_header_of_60000_px_is_named_in_the_report(site, tmp_path, capsys):
    """vlp-report --photos checks the other photos on (by design): the huge one is named, never decoded."""
    photos = tmp_path / "photos"
    photos.mkdir()
    _png(photos / "L00.png", 60_000, 60_000)
    code = report.console_main([str(site / "plan" / "plan.yaml"), "--photos", str(photos), "-o",
                                str(tmp_path / "r"), "--json"])
    out, err = capsys.readouterr()
    assert code == 0 and "error" not in err, err
    problem = json.loads(out)["asbuilt"]["photos"][0]["problem"]
    assert "60,000 x 60,000 px" in problem and "L00.png" in problem, problem
