"""Which image a simulated driver is given and takes: versions that follow the driver, a rollback refused with its
hint, versions bounded far below 2**32, an image edited on disk or copied from another luminaire, a re-plan, a
protocol 1 driver, and the time BEGIN gets to erase a slot."""

import hashlib
import os
import shutil
import struct
import zlib
from pathlib import Path

import pytest
import serial
from simulated import KEY, booted, bus_url, flash_run, journal_entries, planned_twice

from planner.cli.flash import console_main
from planner.errors import UsageError
from planner.firmware.image import CRC_OFFSET, MAX_IMAGE_VERSION, config_image, parse_config_image
from planner.flash.flasher import Versions, flash_driver, sign_image
from planner.flash.keys import driver_key
from planner.flash.link import Link
from planner.flash.sim import protocol_sim


@pytest.fixture(scope="module")
def plans(tmp_path_factory) -> Path:
    return planned_twice(tmp_path_factory)


def _copy(plans: Path, name: str, tmp_path: Path) -> Path:
    shutil.copytree(plans / name, tmp_path / name)
    return tmp_path / name / "plan.yaml"


def _sim(n: int = 1, flash: Path | None = None, faults: str = "") -> serial.SerialBase:
    protocol_sim.register()
    return serial.serial_for_url(bus_url(n, flash, f"&faults={faults}" if faults else ""), timeout=0.1)


PLAN_IMAGE = config_image("L1", 5, "0111000110011010", 12600.0, "0123456789abcdef")


def test_versions_follow_the_driver_and_a_true_rollback_is_refused_with_a_hint():
    port = _sim(faults="stall=0.05,seed=1")
    link, d = Link(port), port.bus.drivers[0]
    first = flash_driver(link, 1, PLAN_IMAGE, KEY)
    assert (first.status, first.image_version, first.verified) == ("flashed", 1, True)
    assert d.active_sha256 == hashlib.sha256(sign_image(PLAN_IMAGE, driver_key(KEY, "SIM-000001"))).digest()
    replan = config_image("L1", 5, "0111000110011010", 12600.0, "fedcba9876543210")  # another plan hash, version 1
    second = flash_driver(link, 1, replan, KEY)
    assert (second.status, second.image_version, d.active_version) == ("flashed", 2, 2)
    assert flash_driver(link, 1, replan, KEY).status == "current"  # recognised at the version it runs
    assert flash_driver(link, 1, replan, KEY, verify_only=True).status == "verified"
    older = flash_driver(link, 1, PLAN_IMAGE, KEY, Versions(explicit=2))
    assert older.status == "failed" and "ROLLBACK" in older.message and "--image-version 3" in older.message
    stale = flash_driver(link, 1, PLAN_IMAGE, KEY, Versions(journal=("SIM-000001", 1)))
    assert stale.status == "failed" and "older than what the driver runs" in stale.message
    assert "--image-version 3" in stale.message and d.active_version == 2
    wrong = flash_driver(link, 1, replan, b"k" * 32, Versions(explicit=5))  # another site's key: no proof, no image
    assert wrong.status == "failed" and "failed the challenge" in wrong.message and d.active_version == 2
    back = flash_driver(link, 1, PLAN_IMAGE, KEY, Versions(explicit=3))  # the deliberate way back
    assert (back.status, d.active_version) == ("flashed", 3)
    assert (wrong.serial, wrong.active_version, wrong.active_sha256) == ("", 0, "")  # nothing unproved is kept
    port.close()


def test_versions_are_bounded_far_below_2_to_the_32(plans, tmp_path):
    with pytest.raises(UsageError, match="1,000,000"):
        config_image("L1", 5, "01", 100.0, "0123456789abcdef", image_version=4_000_000_000)
    plan = _copy(plans, "a", tmp_path)
    path = plan.parent / "firmware" / "R01C01" / "vlp_config.bin"
    edited = bytearray(path.read_bytes())
    edited[120:124] = struct.pack("<I", 4_000_000_000)  # the image version, CRC made right again
    edited[CRC_OFFSET:] = struct.pack("<I", zlib.crc32(bytes(edited[:CRC_OFFSET])))
    assert parse_config_image(bytes(edited))["image_version"] == 4_000_000_000
    path.write_bytes(bytes(edited))
    common = ["R01C01", "--bus", "--key-file", str(plans / "key"), "--journal", str(tmp_path / "j.json"),
              "--port", bus_url(1)]
    got = flash_run(str(plan), *common)
    assert got.returncode == 1 and len(got.stderr.splitlines()) == 1
    assert f"{path}: image version 4,000,000,000 is above the 1,000,000" in got.stderr
    got = flash_run(str(plans / "a" / "plan.yaml"), *common, "--image-version", "4000000000")
    assert got.returncode == 2 and "--image-version: must be at most 1,000,000" in got.stderr
    assert not (tmp_path / "j.json").exists()  # nothing was flashed
    port = _sim()
    result = flash_driver(Link(port), 1, PLAN_IMAGE, KEY, Versions(floor=MAX_IMAGE_VERSION))
    assert (result.status, result.image_version) == ("flashed", MAX_IMAGE_VERSION)
    replan = config_image("L1", 5, "0111000110011010", 12600.0, "fedcba9876543210")
    beyond = flash_driver(Link(port), 1, replan, KEY, Versions(floor=MAX_IMAGE_VERSION))  # would need 1,000,001
    assert beyond.status == "failed" and "up to 1,000,000" in beyond.message
    port.close()


def test_an_image_edited_on_disk_or_copied_from_another_luminaire_is_refused(plans, tmp_path):
    plan = _copy(plans, "a", tmp_path)
    fw = plan.parent / "firmware"
    edited = bytearray((fw / "R01C01" / "vlp_config.bin").read_bytes())
    edited[44:48] = struct.pack("<I", parse_config_image(bytes(edited))["id"] + 1)  # another ID, CRC redone
    edited[CRC_OFFSET:] = struct.pack("<I", zlib.crc32(bytes(edited[:CRC_OFFSET])))
    parse_config_image(bytes(edited))  # a well-formed image of this plan
    (fw / "R01C01" / "vlp_config.bin").write_bytes(bytes(edited))
    shutil.copy(fw / "R01C03" / "vlp_config.bin", fw / "R01C02" / "vlp_config.bin")
    flash = tmp_path / "flash"
    flash.mkdir()
    for name, why in (("R01C01", "in id:"), ("R01C02", "in name")):
        got = flash_run(str(plan), name, "--bus", "--key-file", str(plans / "key"), "--journal",
                     str(tmp_path / "j.json"), "--port", bus_url(2, flash))
        assert got.returncode == 1 and got.stdout == "" and len(got.stderr.splitlines()) == 1, got.stderr
        assert f"{fw / name / 'vlp_config.bin'}: differs from what plan.yaml gives luminaire {name}" in got.stderr
        assert why in got.stderr and "copied from another luminaire" in got.stderr
    assert os.listdir(flash) == [] and not (tmp_path / "j.json").exists()  # no driver was even opened


def test_a_replan_is_accepted_with_default_options_and_the_old_plan_is_refused_with_its_hint(plans, tmp_path):
    flash = tmp_path / "flash"
    flash.mkdir()
    common = ["R01C01", "R01C02", "--bus", "--key-file", str(plans / "key"), "--port", bus_url(2, flash)]
    old_journal, new_journal = tmp_path / "a.json", tmp_path / "b.json"
    assert flash_run(str(plans / "a" / "plan.yaml"), *common, "--journal", str(old_journal)).returncode == 0
    got = flash_run(str(plans / "b" / "plan.yaml"), *common, "--journal", str(new_journal))
    assert got.returncode == 0, got.stdout + got.stderr
    assert got.stdout.count("flashed, verified (version 2,") == 2
    assert [e["active_version"] for e in journal_entries(new_journal).values()] == [2, 2]
    for _ in range(2):  # the refusal is kept: a second try of the old plan is refused again
        got = flash_run(str(plans / "a" / "plan.yaml"), *common, "--journal", str(old_journal))
        assert got.returncode == 3 and got.stdout.count("this plan is older than what the driver runs") == 2
        assert "give --image-version 3 to put this plan's image back deliberately" in got.stdout
    got = flash_run(str(plans / "a" / "plan.yaml"), *common, "--journal", str(old_journal), "--image-version", "2")
    assert got.returncode == 3 and got.stdout.count("ROLLBACK (active version is 2)") == 2  # the drivers refuse
    assert "leave out --image-version to follow it, or give --image-version 3 or more" in got.stdout
    for k in (1, 2):  # the drivers still run the re-plan's image
        sha = booted(flash / f"SIM-{k:06d}.flash").active_sha256.hex()
        assert sha == journal_entries(new_journal)[f"R01C0{k}"]["image_sha256"] == \
            journal_entries(new_journal)[f"R01C0{k}"]["active_sha256"]


def test_begin_gets_the_time_to_erase_a_whole_slot(monkeypatch):
    """BEGIN may erase the staging slot: its driver time is the slot's blocks plus one at HELLO's block
    write time (the reference AVR driver erases a used 256-byte EEPROM slot in about 1.1 s)."""
    port = _sim()
    link, d = Link(port), port.bus.drivers[0]
    given: dict[str, list[float]] = {}
    real = Link.request

    def spy(self, address, command, payload=b"", **kw):
        given.setdefault(command.name, []).append(kw.get("driver_s", 0.0))
        return real(self, address, command, payload, **kw)

    monkeypatch.setattr(Link, "request", spy)
    assert flash_driver(link, 1, PLAN_IMAGE, KEY).verified
    block_s = d.block_write_us * 1e-6
    blocks = -(-d.slot_size // d.max_block)
    assert given["BEGIN"] == [pytest.approx((blocks + 1) * block_s)]
    assert given["WRITE"] == [pytest.approx(block_s)] * len(given["WRITE"]) and given["COMMIT"] == [pytest.approx(2 * block_s)]


def test_a_protocol_1_driver_is_reported_unauthenticated_and_nothing_is_signed_for_it(plans, tmp_path, capsys):
    journal = tmp_path / "j.json"
    code = console_main([str(plans / "a" / "plan.yaml"), "R01C01", "--bus", "--key-file", str(plans / "key"),
                         "--journal", str(journal), "--port", bus_url(1, extra="&protocol=1")])
    out = capsys.readouterr().out
    assert code == 3 and "R01C01: driver SIM-000001: unauthenticated, NOT verified" in out
    assert "update its firmware to protocol 2" in out and len(out.splitlines()) == 1
    e = journal_entries(journal)["R01C01"]
    assert (e["status"], e["verified"], e["image_sha256"], e["image_version"]) == ("unauthenticated", False, "", 0)
