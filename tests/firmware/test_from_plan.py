"""The edit-verify-flash loop (issue 38, Build 4): an ``id`` edited in plan.yaml, ``vlp-verify`` naming what
disagrees, ``vlp-plan --from-plan`` rebuilding frames and firmware, ``vlp-flash`` flashing simulated drivers.

The installed console scripts run as a user runs them (their entry points, in process: ``conftest.vlp``).
The plan is grid-32 planned once; the edits are found by verifying candidate IDs for its first luminaire
in process (which IDs keep the windows unique depends on the plan the planner makes, so the test finds one
of each kind rather than naming it).
"""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest
import yaml

from conftest import SITE_KEY, grid32_copy, vlp
from planner.firmware.image import parse_config_image
from planner.plan.file import load_plan, plan_from_document
from planner.plan.rebuild import codec, verify_plan_file
from planner.verify.windows import CONGRUENCE_TOLERANCE_M, POSES_PER_M2

KEY = SITE_KEY
FIRST = "R01C01"


def _edit(text: str, new_id: int) -> str:
    """plan.yaml with the first luminaire's ``id`` line changed, as a user edits it."""
    start = text.index(f"- name: {FIRST}\n")
    line = re.compile(r"^  id: \d+$", re.M).search(text, start)
    assert line is not None
    return text[:line.start()] + f"  id: {new_id}" + text[line.end():]


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> dict:
    """grid-32 planned (no maps, no report), and one edit of its first id that verifies and one that does not."""
    base = tmp_path_factory.mktemp("loop")
    (base / "key").write_text(KEY.hex())
    grid32_copy(tmp_path_factory, base / "planned", sealed=True)  # planned once per run (tests/flash share it)
    text = (base / "planned" / "plan.yaml").read_text()
    plan = load_plan(base / "planned" / "plan.yaml")
    old = int(plan.ids[0])
    found: dict = {}

    for new_id in range(1, plan.code.max_id + 1):
        if new_id == old:
            continue
        edited = plan_from_document(yaml.safe_load(_edit(text, new_id)), "edited")
        result, judged = verify_plan_file(edited, edited.camera_model(), poses_per_m2=POSES_PER_M2, seed=0,
                                          tolerance_m=CONGRUENCE_TOLERANCE_M)  # vlp-verify's defaults
        kind = "clean" if result.clean and judged["usable"] else "conflict" if not result.clean else "unusable"
        found.setdefault(kind, new_id)
        if "clean" in found and "conflict" in found:
            break
    assert {"clean", "conflict"} <= set(found), f"no edit of {FIRST}'s id {old} of each kind: {found}"
    return {"base": base, "text": text, "old": old, **found}


def _edited(site: dict, tmp_path: Path, kind: str) -> Path:
    folder = tmp_path / "edited"
    shutil.copytree(site["base"] / "planned", folder)
    (folder / "plan.yaml").write_text(_edit(site["text"], site[kind]))
    return folder / "plan.yaml"


def test_edit_verify_rebuild_and_flash(site, tmp_path):
    """Done when (issue 38, Build 4): one id edited, vlp-verify names the luminaire whose frame sends the old
    ID, --from-plan rebuilds the firmware, and vlp-flash flashes it to simulated drivers."""
    edited, new_id = _edited(site, tmp_path, "clean"), site["clean"]
    checked = vlp("vlp-verify", edited)
    assert checked.returncode == 3, checked.stderr
    assert f"{FIRST} (id {new_id}: its frame sends ID {site['old']})" in checked.stdout
    verdict = next(line for line in checked.stdout.splitlines() if line.startswith("  verdict"))
    assert "NOT READY" in verdict and "usable" not in verdict  # the verdict agrees with exit 3
    # the flasher refuses the edited plan as it stands: it was edited since it was sealed under the site key
    key = ["--key-file", site["base"] / "key"]
    url = f"sim://?key={KEY.hex()}&drivers=32"
    refused = vlp("vlp-flash", edited, "--all", "--bus", "--port", url, *key, "--json")
    assert refused.returncode == 1 and "the plan was edited since it was sealed" in refused.stderr

    out = tmp_path / "rebuilt"
    rebuilt = vlp("vlp-plan", "--from-plan", edited, "-o", out, "--json", *key)  # the key seals the rebuilt plan
    assert rebuilt.returncode == 0, rebuilt.stderr
    summary = json.loads(rebuilt.stdout)
    assert summary["verified"] and summary["sealed"] and summary["frames_made_again"] == [
        f"{FIRST} (id {new_id}: its frame sends ID {site['old']})"]
    assert sorted(p.name for p in out.iterdir()) == ["firmware", "plan.yaml", "plan.yaml.seal"]
    plan = load_plan(out / "plan.yaml")
    assert plan.ids[0] == new_id and codec(plan, "rebuilt").id_of(plan.luminaires[0].frame.chips) == new_id
    image = parse_config_image((out / "firmware" / FIRST / "vlp_config.bin").read_bytes())
    assert image["id"] == new_id and image["chips"] == plan.luminaires[0].frame.chips
    assert any("rebuilt from an edited plan by vlp-plan --from-plan: 1 frame(s)" in n for n in plan.source["notes"])

    again = vlp("vlp-verify", out / "plan.yaml", "--json")
    assert again.returncode == 0 and json.loads(again.stdout)["frame_mismatches"] == []

    flashed = vlp("vlp-flash", out / "plan.yaml", "--all", "--bus", "--port", url, *key, "--journal",
                   tmp_path / "as-built.json", "--json")
    assert flashed.returncode == 0, flashed.stderr
    doc = json.loads(flashed.stdout)
    assert doc["verified"] == 32 and doc["failed"] == 0
    first = next(d for d in doc["drivers"] if d["name"] == FIRST)
    assert first["id"] == new_id and first["status"] == "flashed" and first["verified"]


def test_an_edit_whose_ids_read_alike_is_named_and_refused(site, tmp_path):
    edited, new_id = _edited(site, tmp_path, "conflict"), site["conflict"]
    checked = vlp("vlp-verify", edited)
    assert checked.returncode == 3
    assert "same key: " in checked.stdout and FIRST in checked.stdout
    verdict = next(line for line in checked.stdout.splitlines() if line.startswith("  verdict"))
    assert "usable" not in verdict and "meets the goal" not in verdict

    out = tmp_path / "rebuilt"
    refused = vlp("vlp-plan", "--from-plan", edited, "-o", out)
    assert refused.returncode == 1 and not out.exists()  # nothing written
    err = refused.stderr.strip().splitlines()
    assert len(err) == 1 and "fails verification, so no firmware was written: FAILED" in err[0]
    assert "--allow-unverified" in err[0]

    forced = vlp("vlp-plan", "--from-plan", edited, "-o", out, "--allow-unverified", "--json")
    assert forced.returncode == 3 and not json.loads(forced.stdout)["verified"]
    plan = load_plan(out / "plan.yaml")
    assert plan.ids[0] == new_id
    assert any("FAILED (written with --allow-unverified)" in n for n in plan.source["notes"])
    again = vlp("vlp-verify", out / "plan.yaml", "--json")  # the frames agree, the IDs still read alike
    assert again.returncode == 3
    doc = json.loads(again.stdout)
    assert doc["frame_mismatches"] == [] and not doc["passed"]
    assert doc["verdict"].startswith("FAILED: the IDs do not name one place")  # never "usable" beside exit 3


def test_a_frame_edited_by_hand_is_named_too(site, tmp_path):
    """The other way round: an id left alone but its frame changed sends another ID (or none)."""
    folder = tmp_path / "edited"
    shutil.copytree(site["base"] / "planned", folder)
    text = site["text"]
    start = text.index(f"- name: {FIRST}\n")
    chips = re.compile(r"chips: '([01]+)'").search(text, start)
    assert chips is not None
    flipped = chips.group(1)[:-1] + ("1" if chips.group(1)[-1] == "0" else "0")
    (folder / "plan.yaml").write_text(text[:chips.start(1)] + flipped + text[chips.end(1):])
    checked = vlp("vlp-verify", folder / "plan.yaml", "--json")
    assert checked.returncode == 3
    mismatch = json.loads(checked.stdout)["frame_mismatches"]
    assert [m["name"] for m in mismatch] == [FIRST] and mismatch[0]["frame_sends"] != site["old"]


@pytest.mark.parametrize(("argv", "message"), [
    (["--allow-unverified"], "--allow-unverified is for --from-plan PLAN"),
    (["layouts/grid-32.yaml", "--from-plan", "{plan}"], "LAYOUT does not apply with --from-plan"),
    (["--from-plan", "{plan}", "--camera", "main"], "--camera does not apply with --from-plan"),
    (["--from-plan", "{plan}", "--scheme", "unique"], "--scheme does not apply with --from-plan"),
])
def test_options_that_do_not_apply_are_refused(site, argv, message, capsys):
    from planner.cli.plan import console_main

    plan = str(site["base"] / "planned" / "plan.yaml")
    assert console_main([a.format(plan=plan) for a in argv]) == 2
    assert message in capsys.readouterr().err


def test_a_folder_with_an_as_built_journal_is_not_replaced(site, tmp_path, capsys):
    from planner.cli.plan import console_main

    edited = _edited(site, tmp_path, "clean")
    (edited.parent / "as-built.json").write_text("{}")
    assert console_main(["--from-plan", str(edited)]) == 2  # in place: the journal's folder
    assert "holds as-built.json" in capsys.readouterr().err
    assert (edited.parent / "as-built.json").read_text() == "{}"


@pytest.mark.parametrize(("line", "distance"), [("manchester", 1), ("manchester", 3), ("4b6b", 2)])
def test_frames_made_from_ids_send_those_ids_and_a_swap_is_named(line, distance):
    """In process, over every ID of a 4-bit code: with and without check bits, both line codes."""
    from conftest import minimal_plan
    from planner.codes.check_bits import check_code
    from planner.modulation.frame import line_code
    from planner.plan.rebuild import Codec, derived_frame, frame_mismatches

    check = check_code(16, 4, distance)
    code = line_code(line)
    c = Codec(code, check, check.word_bits, 5000.0)
    sections = {"code": {"bits": 4, "max_id": 16, "naive_bits": 5, "lower_bound_bits": 3, "efficiency": 0.2,
                         "check_distance": distance, "word_bits": check.word_bits},
                "modulation": {"line_code": line, "preamble": code.preamble, "chip_rate_hz": 5000.0,
                               "frame_chips": 8, "frame_period_s": 0.01, "frames_in_smallest_image": 2.0,
                               "smallest_image_rows": 200.0, "row_time_s": 2e-5}}
    rows = [{"name": f"L{k}", "x": float(k), "id": k} for k in range(1, 17)]
    bare = minimal_plan(rows, **sections)
    framed = [{**r, "frame": derived_frame(c, e), **({"codeword": c.word(e.id)} if distance > 1 else {})}
              for r, e in zip(rows, bare.luminaires)]
    assert [c.id_of(f["frame"]["chips"]) for f in framed] == list(range(1, 17))
    assert frame_mismatches(minimal_plan(framed, **sections), "plan") == []
    framed[0]["frame"], framed[1]["frame"] = framed[1]["frame"], framed[0]["frame"]  # L1 and L2 swapped
    named = frame_mismatches(minimal_plan(framed, **sections), "plan")
    assert [(m.name, m.id, m.sends) for m in named] == [("L1", 1, 2), ("L2", 2, 1)]
    if distance > 1:
        framed[0]["frame"], framed[1]["frame"] = framed[1]["frame"], framed[0]["frame"]
        framed[2]["codeword"] = c.word(4)
        named = frame_mismatches(minimal_plan(framed, **sections), "plan")
        assert [m.text() for m in named] == [f"L3 (id 3: its codeword {c.word(4)} is not the one of ID 3)"]
