"""``vlp-plan`` on an existing tone site (issue 37, docs/tones.md), through the installed console scripts: the
tones are kept, two luminaires of one tone close together are reported as ambiguous where they are, with a
retune; no frames or firmware are written; bad tones are refused in one line."""

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from conftest import vlp
from planner.modulation.tones import tones_apart

ROOT = Path(__file__).resolve().parents[2]
FAST = ["--no-map", "--no-report", "--error-poses-per-m2", "0"]


def grid_site(path: Path, same: tuple[int, int] | None) -> dict:
    """The paper's 32-LED grid (4 x 8, 0.5 m pitch) with tones 1,000, 1,250, ... Hz; luminaire ``same[1]`` given
    ``same[0]``'s tone."""
    lums = [{"name": f"R{r + 1}C{c + 1}", "x": (c + 0.5) * 0.5, "y": (r + 0.5) * 0.5, "tone_hz": 1000.0 + 250 * (8 * r + c)}
            for r in range(4) for c in range(8)]
    if same:
        lums[same[1]]["tone_hz"] = lums[same[0]]["tone_hz"]
    doc = {"unit": "m", "height": 2.5, "radius": 0.1, "outline": [[0, 0], [4, 0], [4, 2], [0, 2]], "luminaires": lums}
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return doc


@pytest.fixture(scope="module")
def clash(tmp_path_factory):
    """R2C2 and R2C3, neighbours 0.5 m apart, both at 3,500 Hz."""
    base = tmp_path_factory.mktemp("clash")
    doc = grid_site(base / "site.yaml", (10, 9))
    done = vlp("vlp-plan", str(base / "site.yaml"), "-o", str(base / "out"), "--json", *FAST)
    return doc, done, base / "out"


def test_two_close_luminaires_of_one_tone_are_reported_ambiguous_where_they_are(clash):
    doc, done, out = clash
    assert done.returncode == 3, done.stderr
    err = done.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(
        "vlp-plan: plan written, but AMBIGUOUS R2C2 (3500 Hz) and R2C3 (3500 Hz) share the window of ")
    assert "a tone receiver cannot tell them apart there; retune R2C3 to " in err[0]
    tones = json.loads(done.stdout)["tones"]
    (c,) = tones["clashes"]
    assert c["luminaires"] == ["R2C2", "R2C3"] and c["poses"] > 0 and tones["ambiguous_poses"] == c["poses"]
    # where: the poses that see both lie around the pair (midpoint (1.0, 0.75) m), within the area that sees them
    assert np.hypot(c["around_m"][0] - 1.0, c["around_m"][1] - 0.75) < 0.5
    assert c["from_m"][0] <= 0.75 and c["to_m"][0] >= 1.25
    # the advice: a tone the camera tells apart from every tone of the site, with a factor 2 to spare
    to = c["retune"]["to_hz"]
    others = np.array([lum["tone_hz"] for lum in doc["luminaires"] if lum["name"] != "R2C3"])
    assert c["retune"]["apart_from"] == "every tone of the site"
    assert np.all(tones_apart(to, others, tones["smallest_image_rows"] / 2))


def test_a_tone_plan_keeps_every_tone_and_has_no_frames(clash):
    doc, done, out = clash
    plan = yaml.safe_load((out / "plan.yaml").read_text())
    assert plan["scheme"] == "tones" and plan["modulation"] is None and "no_frames" not in plan
    assert [e["tone_hz"] for e in plan["luminaires"]] == [lum["tone_hz"] for lum in doc["luminaires"]]
    assert not any("frame" in e for e in plan["luminaires"])
    ids = {e["name"]: e["id"] for e in plan["luminaires"]}
    assert ids["R2C2"] == ids["R2C3"] and len(set(ids.values())) == 31  # one tone class for the pair
    assert "configured outside vlp-plan" in plan["tones"]["drivers"]
    assert sorted(p.name for p in out.iterdir()) == ["plan.yaml", "site-vlp.dxf"]  # no firmware
    assert vlp("vlp-verify", str(out / "plan.yaml")).returncode == 0  # later stages read the plan


def test_distinct_tones_have_no_clash(tmp_path):
    grid_site(tmp_path / "site.yaml", None)
    done = vlp("vlp-plan", str(tmp_path / "site.yaml"), "-o", str(tmp_path / "out"), *FAST)
    assert done.returncode == 0, done.stderr
    assert "no two luminaires of one tone class share a sampled window" in done.stdout
    assert "31 tones in 31 classes" not in done.stdout and "32 tones in 32 classes" in done.stdout


def test_bundled_tone_rig(tmp_path):
    done = vlp("vlp-plan", str(ROOT / "layouts" / "tone-rig.yaml"), "-o", str(tmp_path / "out"), "--json", *FAST)
    s = json.loads(done.stdout)
    assert s["scheme"] == "tones" and s["tones"]["tone_classes"] == 5 and s["tones"]["clashes"] == []
    plan = yaml.safe_load((tmp_path / "out" / "plan.yaml").read_text())
    assert [e["tone_hz"] for e in plan["luminaires"]] == [2000, 2500, 3000, 3500, 4000]
    assert [e["radius"] for e in plan["luminaires"]] == [0.01] * 5 and plan["luminaires"][0]["z"] == 2.46
    assert done.returncode == 3 and "NOT USABLE" in done.stderr  # five LEDs: the advice says what would work


@pytest.mark.parametrize("body, args, code, words", [
    ("- {name: A, x: 0, y: 0, tone_hz: 2000}\n- {name: B, x: 1, y: 0}\n- {name: C, x: 0, y: 1, tone_hz: 3000}\n",
     (), 1, "site.yaml: luminaire 'B' has no tone_hz but 2 of the 3 luminaires carry one"),
    ("- {name: A, x: 0, y: 0, tone_hz: 2000}\n- {name: B, x: 1, y: 0, tone_hz: 15000}\n"
     "- {name: C, x: 0, y: 1, tone_hz: 3000}\n", (), 1,
     "site.yaml: luminaire 'B''s tone_hz 15000 Hz is above 10,000 Hz: the drivers switch at most 20,000 times"),
    ("- {name: A, x: 0, y: 0, tone_hz: 2000}\n- {name: B, x: 1, y: 0, tone_hz: 2500}\n"
     "- {name: C, x: 0, y: 1, tone_hz: 3000}\n", ("--scheme", "window"), 2,
     "--scheme window: site.yaml is a tone site"),
    # not the frame sites' "--no-verify needs an explicit --scheme", which --scheme would then refuse
    ("- {name: A, x: 0, y: 0, tone_hz: 2000}\n- {name: B, x: 1, y: 0, tone_hz: 2500}\n"
     "- {name: C, x: 0, y: 1, tone_hz: 3000}\n", ("--no-verify",), 2,
     "site.yaml is a tone site: it is audited by verifying it; drop --no-verify"),
])
def test_refusals_are_one_line(tmp_path, body, args, code, words):
    (tmp_path / "site.yaml").write_text("luminaires:\n" + body)
    done = vlp("vlp-plan", "site.yaml", "-o", "out", *args, cwd=tmp_path)
    assert done.returncode == code
    assert done.stderr.count("\n") == 1 and words in done.stderr and "Traceback" not in done.stderr
    assert not (tmp_path / "out").exists()


def test_an_edited_tone_plan_is_refused_where_it_breaks_the_rule(clash, tmp_path):
    from planner.errors import InputError
    from planner.plan.file import load_plan

    _, _, out = clash
    plan = yaml.safe_load((out / "plan.yaml").read_text())
    assert load_plan(out / "plan.yaml").luminaires[0].tone_hz == 1000.0
    del plan["luminaires"][3]["tone_hz"]
    (tmp_path / "plan.yaml").write_text(yaml.safe_dump(plan, sort_keys=False))
    with pytest.raises(InputError, match="31 of 32 luminaires have a tone_hz: all or none must"):
        load_plan(tmp_path / "plan.yaml")
    plan["luminaires"][3]["tone_hz"] = 1800.0  # retuned by hand since the verdict (it was 1,750 Hz)
    (tmp_path / "plan.yaml").write_text(yaml.safe_dump(plan, sort_keys=False))
    with pytest.raises(InputError, match="the luminaires were edited since the plan was verified"):
        load_plan(tmp_path / "plan.yaml").check_verdict_current("plan.yaml")


def test_a_tone_site_for_the_two_led_receiver(clash, tmp_path):
    doc, _, _ = clash
    (tmp_path / "site.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    done = vlp("vlp-plan", str(tmp_path / "site.yaml"), "-o", str(tmp_path / "out"), "--receiver", "gravity", "--json",
               *FAST)
    s = json.loads(done.stdout)
    assert done.returncode == 3 and s["receiver"]["mode"] == "gravity"
    assert [c["luminaires"] for c in s["tones"]["clashes"]] == [["R2C2", "R2C3"]]


def test_the_site_report_of_a_tone_site_shows_the_clash_and_no_flashing(clash, tmp_path):
    import shutil

    _, _, out = clash
    shutil.copy(out / "plan.yaml", tmp_path / "plan.yaml")
    done = vlp("vlp-report", str(tmp_path / "plan.yaml"))
    assert done.returncode == 0, done.stderr
    text = (tmp_path / "site-report.html").read_text()
    assert "AMBIGUOUS R2C2 (3500 Hz) and R2C3 (3500 Hz)" in text and "tone drivers are configured outside" in text
    assert "drivers verified" not in text


def test_from_plan_on_a_tone_plan_says_why_there_is_nothing_to_rebuild(clash, tmp_path):
    _, _, out = clash
    done = vlp("vlp-plan", "--from-plan", str(out / "plan.yaml"), "-o", str(tmp_path / "again"))
    assert done.returncode == 1 and not (tmp_path / "again").exists()
    assert "a tone site's plan (docs/tones.md) has no frames to check or rebuild" in done.stderr
    assert done.stderr.count("\n") == 1


def test_repeated_tones_that_read_alike_everywhere_are_not_usable_and_the_verdict_says_retune(tmp_path):
    # the 32-LED grid in 2 x 2 tiles of four tones: every window repeats 1 m away, so none names one place
    doc = grid_site(tmp_path / "site.yaml", None)
    for k, lum in enumerate(doc["luminaires"]):
        lum["tone_hz"] = 2000.0 + 500 * ((k // 8) % 2 * 2 + k % 2)
    (tmp_path / "site.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    done = vlp("vlp-plan", str(tmp_path / "site.yaml"), "-o", str(tmp_path / "out"), *FAST)
    assert done.returncode == 3
    assert "verdict  NOT USABLE: only 0.0 % of sampled poses decode" in done.stdout
    assert "are ambiguous: repeated tones read alike, retune some (docs/tones.md)" in done.stdout
    assert "--scheme auto" not in done.stdout + done.stderr
