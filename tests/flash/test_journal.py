"""The as-built journal reader: entries are checked field by field, old journals still read."""

from __future__ import annotations

import json

import pytest

from planner.errors import InputError
from planner.flash.journal import FORMAT, Journal

HASH = "0123456789abcdef"
GOOD = {"id": 3, "where": "address 3", "driver_serial": "SIM-000003", "status": "flashed", "verified": True,
        "image_sha256": "ab" * 32, "image_version": 2, "active_version": 2, "active_sha256": "ab" * 32,
        "message": "", "time": "2026-12-03T10:00:00+00:00",
        "last_verified": {"driver_serial": "SIM-000003", "image_version": 2}}


def _journal(tmp_path, entries):
    path = tmp_path / "as-built.json"
    path.write_text(json.dumps({"format": FORMAT, "plan_hash": HASH, "luminaires": entries}))
    return path


def test_a_good_journal_reads_back_as_written_and_an_old_one_reads_too(tmp_path):
    old = {k: GOOD[k] for k in ("id", "where", "driver_serial", "status", "verified", "active_version")}
    j = Journal(_journal(tmp_path, {"R01C01": GOOD, "R01C02": old}), HASH)
    assert j.entries == {"R01C01": GOOD, "R01C02": old}  # nothing added, nothing lost
    assert j.verified("R01C01", 2) == GOOD and Journal.version(j.entries["R01C02"]) == 2
    assert j.last_verified("R01C01") == ("SIM-000003", 2)


@pytest.mark.parametrize("change, where", [
    ({"status": "exploded"}, "luminaires.R01C01.status"),
    ({"id": "3"}, "luminaires.R01C01.id"),
    ({"id": 0}, "luminaires.R01C01.id"),
    ({"verified": "yes"}, "luminaires.R01C01.verified"),
    ({"image_version": -1}, "luminaires.R01C01.image_version"),
    ({"last_verified": {"image_version": 2}}, "luminaires.R01C01.last_verified.driver_serial"),
    ({"message": ["a"]}, "luminaires.R01C01.message"),
])
def test_a_damaged_entry_is_one_line_naming_its_field(tmp_path, change, where):
    path = _journal(tmp_path, {"R01C01": {**GOOD, **change}})
    with pytest.raises(InputError) as err:
        Journal(path, HASH)
    message = str(err.value)
    assert message.startswith(f"{path}: {where}: ") and "move it away to start a new one" in message
    assert "\n" not in message
