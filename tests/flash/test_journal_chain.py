"""The journal's head and the plan's generation (issue 36, Build 5): a journal with an entry removed, reordered,
put back from an older copy or cut out is refused, naming the entry, by ``vlp-flash`` and ``vlp-report --key-file``;
a plan sealed before the one a journal records as flashed is refused by ``vlp-flash``.

The installed console scripts run as a user runs them (their entry points, in process: ``conftest.vlp``),
against simulated drivers (``sim://``) that keep their flash between runs.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

from conftest import ROOT, vlp
from planner.errors import InputError
from planner.flash.flasher import FlashResult
from planner.flash.journal import FORMAT, OLD_FORMAT, Journal
from planner.flash.seal import seal_text

KEY = bytes(range(32))
NAMES = ["R01C01", "R01C02", "R01C03"]  # bus addresses 1..3, plan order
EARLY = "2026-01-01T00:00:00Z"
DISTRUST = ("so no entry of it is believed: move the journal away; vlp-flash --verify-only rebuilds it from the "
            "drivers' proved answers")




@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """grid-32 planned twice under the site key: ``old`` (seed 2, its seal made on 1 January) and ``new`` (the
    default seed, sealed now); read only."""
    base = tmp_path_factory.mktemp("chain")
    (base / "key").write_text(KEY.hex())
    (base / "key").chmod(0o600)
    for name, seed in (("old", "2"), ("new", "1")):
        done = vlp("vlp-plan", ROOT / "layouts" / "grid-32.yaml", "-o", base / name, "--no-map", "--no-report",
                    "--error-poses-per-m2", "0", "--seed", seed, "--key-file", base / "key", "--json")
        assert done.returncode == 0, done.stderr
    old = (base / "old" / "plan.yaml").read_text()
    assert old != (base / "new" / "plan.yaml").read_text()
    (base / "old" / "plan.yaml.seal").write_text(seal_text(KEY, old, EARLY))  # the key holder sealed it in January
    return base


def _flash(plan: Path, site: Path, flash: Path, *extra: object, drivers: int = 3) -> subprocess.CompletedProcess:
    return vlp("vlp-flash", plan, *NAMES, "--bus", "--key-file", site / "key", "--port",
                f"sim://?drivers={drivers}&key={KEY.hex()}&flash={flash}", *extra)


def _edits(early: dict, now: dict) -> dict[str, tuple[dict | str, str]]:
    """Each edit of the journal ``now`` (``early``: a copy taken before R01C02 failed) and the line it gets."""
    lum = now["luminaires"]
    entries = lambda d: {**now, "luminaires": d}  # noqa: E731
    head = {**now["head"], "entries": [i for i in now["head"]["entries"] if i[0] != "R01C02"]}
    text = json.dumps(now, indent=2)
    middle = text.index('"R01C02"')
    return {
        "removed": (entries({n: e for n, e in lum.items() if n != "R01C02"}),
                    "journal chain broken: the entry of 'R01C02' was removed (the head lists it)"),
        "replayed": (entries({**lum, "R01C02": early["luminaires"]["R01C02"]}),
                     "journal chain broken: the entry of 'R01C02' is not the one vlp-flash wrote last (an older entry "
                     "of it put back"),
        "reordered": (entries({n: lum[n] for n in ("R01C01", "R01C03", "R01C02")}),
                      "journal chain broken: the entries were reordered (the head lists another entry where 'R01C03'"),
        "cut from the head too": ({**entries({n: e for n, e in lum.items() if n != "R01C02"}), "head": head},
                                  "journal head missing or not checking (edited, written by hand, or under another "
                                  "site key)"),
        "bytes cut in the middle": (text[:middle] + text[middle + 400:], "not valid JSON"),
        "old format": ({k: v for k, v in now.items() if k != "head"} | {"format": OLD_FORMAT},
                       f"a {OLD_FORMAT} journal, from a vlp-flash before the journal's head"),
    }


def test_a_journal_with_an_entry_removed_reordered_replayed_or_cut_is_refused_naming_it(site, tmp_path):
    plan, flash = tmp_path / "site" / "plan.yaml", tmp_path / "flash"
    shutil.copytree(site / "new", plan.parent)
    journal = plan.parent / "as-built.json"
    assert _flash(plan, site, flash).returncode == 0
    early = json.loads(journal.read_text())
    assert early["format"] == FORMAT and [i[0] for i in early["head"]["entries"]] == NAMES
    # R01C02's driver is gone: its entry now says failed; the copy taken before says verified
    gone = _flash(plan, site, flash, drivers=1)
    assert gone.returncode == 3, gone.stderr
    now = json.loads(journal.read_text())
    assert [now["luminaires"][n]["verified"] for n in NAMES] == [True, False, False]
    assert early["luminaires"]["R01C02"]["verified"]
    honest = vlp("vlp-report", plan, "--key-file", site / "key", "--json")
    assert honest.returncode == 0, honest.stderr
    assert (json.loads(honest.stdout)["verified"], json.loads(honest.stdout)["failed"]) == (1, 2)
    report = plan.parent / "site-report.html"
    before = report.read_bytes()
    for kind, (edited, why) in _edits(early, now).items():
        text = edited if isinstance(edited, str) else json.dumps(edited, indent=2)
        journal.write_text(text)
        done = _flash(plan, site, flash, "--resume")
        lines = done.stderr.splitlines()
        assert done.returncode == 1 and done.stdout == "" and len(lines) == 1, (kind, done.stdout, done.stderr)
        assert lines[0].startswith(f"vlp-flash: error: {journal}: ") and why in lines[0], (kind, lines[0])
        assert DISTRUST in lines[0] or "move it away to start a new one" in lines[0], (kind, lines[0])
        assert journal.read_text() == text  # refused before anything: no driver flashed, no entry written
        refused = vlp("vlp-report", plan, "--key-file", site / "key", "--json")
        assert refused.returncode == 1 and refused.stdout == "" and len(refused.stderr.splitlines()) == 1, kind
        assert why in refused.stderr and report.read_bytes() == before  # no report counts what the edit says
    journal.write_text(json.dumps(now, indent=2))  # the journal as vlp-flash left it: read, resumed, extended
    resumed = _flash(plan, site, flash, "--resume", "--json", drivers=3)
    assert resumed.returncode == 0, resumed.stderr
    assert [d["status"] for d in json.loads(resumed.stdout)["drivers"]] == ["skipped", "current", "current"]
    assert [i[0] for i in json.loads(journal.read_text())["head"]["entries"]] == NAMES


def test_a_plan_older_than_the_one_the_journal_records_flashed_is_refused(site, tmp_path):
    """The newer plan is flashed; the older one, sealed under the same key, is put in its place (plan, seal and
    images): vlp-flash refuses it before any port; sealed anew (a deliberate choice of the key's holder) it is the
    newest plan, and flashes with a journal of its own."""
    plan, flash = tmp_path / "site" / "plan.yaml", tmp_path / "flash"
    shutil.copytree(site / "new", plan.parent)
    journal = plan.parent / "as-built.json"
    assert _flash(plan, site, flash).returncode == 0
    recorded = json.loads(journal.read_text())
    new_sealed = (site / "new" / "plan.yaml.seal").read_text().splitlines()[2].split()[1]
    assert recorded["plan_sealed"] == new_sealed > EARLY
    for part in ("plan.yaml", "plan.yaml.seal", "firmware"):  # the older plan put in the newer one's place
        (shutil.rmtree if part == "firmware" else Path.unlink)(plan.parent / part)
        (shutil.copytree if part == "firmware" else shutil.copy)(site / "old" / part, plan.parent / part)
    before = journal.read_text()
    for extra in ((), ("--resume",), ("--dry-run",)):
        done = _flash(plan, site, flash, *extra)
        lines = done.stderr.splitlines()
        assert done.returncode == 1 and done.stdout == "" and len(lines) == 1, done.stderr
        assert lines[0].startswith(f"vlp-flash: error: {journal}: this plan (") and f"sealed {EARLY}) is older than " \
            f"plan {recorded['plan_hash']} (sealed {new_sealed}), which this journal records as flashed: vlp-flash " \
            "does not put an older plan back" in lines[0], lines[0]
        assert "seal it anew (vlp-plan --from-plan PLAN -o NEWDIR --key-file FILE)" in lines[0]
        assert journal.read_text() == before
    check = _flash(site / "new" / "plan.yaml", site, flash, "--verify-only", "--journal", tmp_path / "check.json")
    assert check.returncode == 0, check.stdout  # every driver still runs the newer plan's image
    # a plan sealed before seals had times (format 1) counts as older than any sealed with one
    with pytest.raises(InputError, match="sealed without a time\\) is older than plan"):
        Journal(journal, "0123456789abcdef", KEY, "")
    # sealed anew, the older plan is the newest: no longer refused as older, and flashes with a journal of its own
    again = vlp("vlp-plan", "--from-plan", site / "old" / "plan.yaml", "-o", tmp_path / "again", "--key-file",
                 site / "key", "--json")
    assert again.returncode == 0, again.stderr
    other = _flash(tmp_path / "again" / "plan.yaml", site, flash, "--journal", journal)
    assert other.returncode == 1 and "not of this plan" in other.stderr and "is older than" not in other.stderr
    assert _flash(tmp_path / "again" / "plan.yaml", site, flash, "--journal", tmp_path / "again.json").returncode == 0


def _result(serial: str, verified: bool = True) -> FlashResult:
    return FlashResult("flashed" if verified else "failed", serial=serial, image_sha256="ab" * 32, image_version=1,
                       active_version=1, active_sha256="ab" * 32, verified=verified)


def test_the_head_covers_every_entry_in_order_and_the_plan_generation(tmp_path):
    """In process: what the head fixes, and what a journal without it is (read without a key, refused with one)."""
    path, digest = tmp_path / "as-built.json", "0123456789abcdef"
    j = Journal(path, digest, KEY, EARLY)
    for k, name in enumerate(NAMES, 1):
        j.record(name, k, "sim", _result(f"SIM-{k:06d}"))
    doc = json.loads(path.read_text())
    assert doc["plan_sealed"] == EARLY and doc["head"]["entries"] == [
        [n, doc["luminaires"][n]["seal"]] for n in NAMES]
    assert Journal(path, digest, KEY, EARLY).entries == Journal(path, digest).entries  # checked = unchecked
    damaged_heads = ({"head": []}, {"head": {**doc["head"], "entries": [["R01C01"]]}}, {"plan_sealed": 7},
                     {"head": {**doc["head"], "hmac_sha256": None}}, {"head": {"entries": {}, "hmac_sha256": "0"}})
    for edit in damaged_heads:
        path.write_text(json.dumps({**doc, **edit}))
        with pytest.raises(InputError, match="journal head missing or not checking"):
            Journal(path, digest, KEY, EARLY)
    for edit in ({"plan_sealed": "2025-01-01T00:00:00Z"}, {"plan_hash": "f" * 16}):  # fields the head covers
        path.write_text(json.dumps({**doc, **edit}))
        with pytest.raises(InputError, match="journal head missing or not checking|not of this plan"):
            Journal(path, digest, KEY, EARLY)
    # a journal of the old format: read without a key (its entries as they are), refused with one
    path.write_text(json.dumps({k: v for k, v in doc.items() if k != "head"} | {"format": OLD_FORMAT}))
    assert set(Journal(path, digest).entries) == set(NAMES)
    with pytest.raises(InputError, match=f"a {OLD_FORMAT} journal"):
        Journal(path, digest, KEY)
    # a newer plan's journal whose drivers all failed records nothing flashed: an older plan is not "older" than it
    newer = tmp_path / "newer.json"
    Journal(newer, "f" * 16, KEY, "2027-01-01T00:00:00Z").record("R01C01", 1, "sim", _result("SIM-1", False))
    with pytest.raises(InputError, match="not of this plan") as err:
        Journal(newer, digest, KEY, EARLY)
    assert "is older than" not in str(err.value)
