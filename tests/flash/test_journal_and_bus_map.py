"""The as-built journal and the bus map readers: entries checked field by field, old journals still read, one address per driver."""

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


def _plan(names):
    from types import SimpleNamespace

    return SimpleNamespace(luminaires=[SimpleNamespace(name=n) for n in names])


@pytest.mark.parametrize("text, message", [
    ("A,1\nB,1\n", "line 2: address 1 is already 'A''s; two drivers on one bus need two addresses"),
    ("A,1\nA,2\n", "line 2: 'A' is mapped twice"),
    ("A,0\n", "line 1: address: must be greater than or equal to 1 (got '0')"),
    ("A,65535\n", "line 1: address: must be less than or equal to 65534"),
    ("A,x\n", "line 1: address: must be a valid integer"),
    ("A,1,2\n", "line 1: expected 'name,address'"),
    (",3\n", "line 1: name: must have at least 1 character"),
])
def test_a_bus_map_maps_each_luminaire_to_one_address_of_its_own(tmp_path, text, message):
    from planner.flash.bus_map import read_bus_map

    path = tmp_path / "bus.csv"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        read_bus_map(_plan("AB"), str(path))
    assert str(err.value).startswith(f"{path}: {message}"), str(err.value)


def test_a_good_bus_map_and_the_default_plan_order(tmp_path):
    from planner.flash.bus_map import read_bus_map

    path = tmp_path / "bus.csv"
    path.write_text("# drivers of floor 2\nname,address\nB, 7\nA,12\n")
    assert read_bus_map(_plan("AB"), str(path)) == {"B": 7, "A": 12}
    assert read_bus_map(_plan("AB"), None) == {"A": 1, "B": 2}
