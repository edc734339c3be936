"""plan.yaml read back: one typed plan, checked once; an edited or damaged plan gets one line from every command."""

import subprocess

import numpy as np
import pytest
import yaml

from conftest import grid32_copy, vlp
from planner.errors import InputError
from planner.plan.file import PlanFile, load_plan

EDITS = {  # what a careless or hostile edit does -> the field the message must name
    "id-text": (lambda d: d["luminaires"][3].update(id="abc"), "luminaires[3].id"),
    "id-bool": (lambda d: d["luminaires"][3].update(id=True), "luminaires[3].id"),
    "id-zero": (lambda d: d["luminaires"][3].update(id=0), "luminaires[3].id"),
    "id-fraction": (lambda d: d["luminaires"][3].update(id=1.5), "luminaires[3].id"),
    "id-above-max": (lambda d: d["luminaires"][3].update(id=100000), "code.max_id"),
    "x-list": (lambda d: d["luminaires"][2].update(x=[1, 2]), "luminaires[2].x"),
    "x-bool": (lambda d: d["luminaires"][2].update(x=True), "luminaires[2].x"),
    "x-nan": (lambda d: d["luminaires"][2].update(x=float("nan")), "luminaires[2].x"),
    "x-far": (lambda d: d["luminaires"][2].update(x=1e6), "luminaires[2].x"),
    "z-huge": (lambda d: d["luminaires"][2].update(z=1e308), "luminaires[2].z"),
    "z-negative": (lambda d: d["luminaires"][2].update(z=-1.0), "luminaires[2].z"),
    "radius-tiny": (lambda d: d["luminaires"][2].update(radius=0.0), "luminaires[2].radius"),
    "radius-missing": (lambda d: d["luminaires"][2].pop("radius"), "luminaires[2].radius: is missing"),
    "name-number": (lambda d: d["luminaires"][1].update(name=123), "luminaires[1].name"),
    "name-twice": (lambda d: d["luminaires"][1].update(name=d["luminaires"][0]["name"]), "used more than once"),
    "parity": (lambda d: d["luminaires"][1].update(parity="both"), "luminaires[1].parity"),
    "chips": (lambda d: d["luminaires"][1]["frame"].update(chips="0120"), "luminaires[1].frame.chips"),
    "one-frame-gone": (lambda d: d["luminaires"][1].pop("frame"), "all or none"),
    "camera-text": (lambda d: d.update(camera="abc"), "camera: must be a mapping"),
    "camera-huge": (lambda d: d["camera"].update(width_px=1_000_000_000), "camera.width_px"),
    "camera-heights": (lambda d: d["camera"].update(receiver_height_m=[2.0, 1.0]), "receiver_height_m"),
    "camera-unknown": (lambda d: d["camera"].update(zoom=2), "camera.zoom"),
    "modulation-text": (lambda d: d.update(modulation="garbage"), "modulation: must be a mapping"),
    "line-code": (lambda d: d["modulation"].update(line_code="morse"), "modulation.line_code"),
    "coverage": (lambda d: d["verification"].update(coverage=2.0), "verification.coverage"),
    "outline-short": (lambda d: d.update(outline=[[0, 0], [1, 1]]), "at least 3 corners"),
    "no-luminaires": (lambda d: d.update(luminaires=[]), "luminaires"),
    "bits-text": (lambda d: d["code"].update(bits="6"), "code.bits"),
}


@pytest.fixture(scope="module")
def plan_doc(tmp_path_factory):
    return grid32_copy(tmp_path_factory, tmp_path_factory.mktemp("pf") / "g32", "--error-poses-per-m2", "0")


def _edited(plan_doc, tmp_path, key):
    doc = yaml.safe_load(plan_doc.read_text("utf-8"))
    EDITS[key][0](doc)
    bad = tmp_path / "plan.yaml"
    bad.write_text(yaml.safe_dump(doc, sort_keys=False), "utf-8")
    return bad


def test_a_written_plan_reads_back_with_its_arrays(plan_doc):
    plan = load_plan(plan_doc)
    raw = yaml.safe_load(plan_doc.read_text("utf-8"))
    assert isinstance(plan, PlanFile) and plan.names == [e["name"] for e in raw["luminaires"]]
    assert np.array_equal(plan.xyz, [[e["x"], e["y"], e["z"]] for e in raw["luminaires"]])
    assert plan.ids.tolist() == [e["id"] for e in raw["luminaires"]] and plan.frames is not None
    assert plan.camera_model().to_dict() == raw["camera"]
    assert plan.document()["code"] == raw["code"]  # keys the reader does not type are kept


@pytest.mark.parametrize("key", sorted(EDITS))
def test_every_bad_edit_is_one_input_error_naming_the_field(plan_doc, tmp_path, key):
    bad = _edited(plan_doc, tmp_path, key)
    with pytest.raises(InputError) as err:
        load_plan(bad)
    text = str(err.value)
    assert text.startswith(f"{bad}: ") and EDITS[key][1] in text and "\n" not in text, text


COMMANDS = {"vlp-verify": [], "vlp-report": [], "vlp-twin": ["--poses", "2"], "vlp-locate": ["--simulate",
            "1,1,1,0,0,0"], "vlp-flash": ["--all", "--dry-run"], "vlp-efficiency": ["--sizes", "16"]}


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("key", ["id-text", "x-list", "camera-text", "modulation-text", "name-number"])
def test_every_command_refuses_an_edited_plan_in_one_line(plan_doc, tmp_path, command, key):
    bad = _edited(plan_doc, tmp_path, key)
    argv = [str(bad), *COMMANDS[command]]
    if key == "id-text":  # the installed script as a user runs it, once per command
        done = subprocess.run([command, *argv], capture_output=True, text=True, timeout=120)
    else:  # the script's entry point in process (a child costs ~0.3 CPU-s of imports): the same code and lines
        done = vlp(command, *argv)
    code, out, err = done.returncode, done.stdout, done.stderr
    assert code == 1, (out, err)
    assert err.count("\n") == 1 and EDITS[key][1].split(":")[0] in err, err
    assert "Traceback" not in err and sorted(p.name for p in tmp_path.iterdir()) == ["plan.yaml"]


def test_a_plan_nested_too_deeply_is_refused(tmp_path):
    bad = tmp_path / "plan.yaml"
    bad.write_text("format: vlp-plan/1\nscheme: x\nsource: " + "[" * 5000 + "]" * 5000 + "\n", "utf-8")
    with pytest.raises(InputError) as err:
        load_plan(bad)
    assert str(err.value).startswith(str(bad))
