"""vlp-flash against simulated drivers: a real pseudo-terminal with faults, tampering, resume, bad ports."""

import hashlib
import hmac
import json
import os
import signal
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import pytest
import serial

from planner.cli.flash import console_main
from planner.firmware.image import SIGNATURE_OFFSET, config_image, parse_config_image
from planner.flash.flasher import flash_driver, sign_image
from planner.flash.link import Link
from planner.flash.sim import protocol_sim
from planner.flash.sim.driver import Flash, SimulatedDriver

ROOT = Path(__file__).resolve().parents[1]
KEY = bytes(range(32))


@pytest.fixture(scope="module")
def site(tmp_path_factory, plan512_dir):
    base = tmp_path_factory.mktemp("site")
    (base / "p512").symlink_to(plan512_dir, target_is_directory=True)
    (base / "key").write_text(KEY.hex())
    return base


def _booted(path: Path) -> SimulatedDriver:
    """A driver booted from a flash file, as after a power cycle."""
    return SimulatedDriver(1, "check", KEY, Flash(4096, path))


@pytest.mark.slow
def test_every_512_driver_ends_verified_or_failed_and_never_corrupt(site, tmp_path, capsys):
    flash_dir = tmp_path / "flash"
    sim = subprocess.Popen([sys.executable, "-m", "planner.cli.driver_sim", "--drivers", "512", "--key-file",
                            str(site / "key"), "--flash-dir", str(flash_dir), "--faults",
                            "corrupt=0.001,reset=0.01,power=0.01,seed=3"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        pty = sim.stdout.readline().strip()
        journal = tmp_path / "as-built.json"
        code = console_main([str(site / "p512" / "plan.yaml"), "--all", "--bus", "--port", pty, "--key-file",
                             str(site / "key"), "--journal", str(journal)])
    finally:
        sim.send_signal(signal.SIGTERM)
        sim.wait(timeout=20)
    out, err = capsys.readouterr()
    assert KEY.hex() not in out + err + journal.read_text()  # the site key never shows
    entries = json.loads(journal.read_text())["luminaires"]
    assert len(entries) == 512 and code in (0, 3)
    verified = [n for n, e in entries.items() if e["verified"]]
    assert len(verified) >= 500  # faults cost retries, not drivers
    for k in range(1, 513):
        driver = _booted(flash_dir / f"SIM-{k:06d}.flash")
        e = entries[f"R{(k - 1) // 32 + 1:02d}C{(k - 1) % 32 + 1:02d}"]
        assert e["where"].endswith(f"@{k}")
        if e["verified"]:
            assert e["driver_serial"] == f"SIM-{k:06d}" and driver.active_sha256.hex() == e["image_sha256"]
        if driver.active_slot:  # whatever it holds is a whole, signed image
            image = driver.flash.read(driver.flash.area(driver.active_slot), 168)
            parse_config_image(image)
            assert hmac.compare_digest(image[132:164], hmac.new(KEY, image[:SIGNATURE_OFFSET], hashlib.sha256).digest())


def _sim(n: int = 1, flash: Path | None = None, faults: str = "") -> serial.SerialBase:
    protocol_sim.register()
    url = f"sim://?drivers={n}&key={KEY.hex()}" + (f"&flash={flash}" if flash else "") + (
        f"&faults={faults}" if faults else "")
    return serial.serial_for_url(url, timeout=0.1)


def _image(version: int, key: bytes = KEY) -> bytes:
    return sign_image(config_image("L1", 5, "0111000110011010", 12600.0, "0123456789abcdef",
                                   image_version=version), key)


def test_tampered_foreign_and_replayed_images_are_refused_and_the_driver_keeps_its_image():
    port = _sim(faults="stall=0.05,seed=1")
    link = Link(port)
    assert flash_driver(link, 1, _image(2)).status == "flashed"
    good = hashlib.sha256(_image(2)).hexdigest()
    tampered = bytearray(_image(3))
    tampered[50] ^= 0x01  # chip rate altered after signing; CRC made right again
    tampered[164:168] = struct.pack("<I", zlib.crc32(bytes(tampered[:164])))
    for image, why in ((bytes(tampered), "AUTH"), (_image(3, key=b"k" * 32), "AUTH"), (_image(1), "ROLLBACK"),
                       (config_image("L1", 5, "01110001", 12600.0, "0123456789abcdef", image_version=4), "AUTH")):
        result = flash_driver(link, 1, image)
        assert result.status == "failed" and why in result.message
        assert port.bus.drivers[0].active_sha256.hex() == good
    port.close()


@pytest.mark.slow
def test_interrupted_batch_resumes_and_skips_finished_drivers(site, tmp_path, capsys, monkeypatch):
    plan = str(site / "p512" / "plan.yaml")
    journal = tmp_path / "j.json"
    names = ["R01C01", "R01C02", "R01C03", "R01C04"]
    flash = tmp_path / "flash"
    flash.mkdir()
    common = [plan, *names, "--bus", "--key-file", str(site / "key"), "--journal", str(journal)]
    # the first batch reaches only the first two drivers (the others are not on the bus yet)
    assert console_main([*common, "--port", f"sim://?drivers=2&key={KEY.hex()}&flash={flash}"]) == 3
    first = capsys.readouterr()
    assert "did not answer" in first.out and "R01C03" in first.err
    assert console_main([*common, "--resume", "--port", f"sim://?drivers=4&key={KEY.hex()}&flash={flash}"]) == 0
    out = capsys.readouterr().out
    assert out.count("skipped (journal: verified)") == 2 and out.count("flashed, verified") == 2
    assert all(e["verified"] for e in json.loads(journal.read_text())["luminaires"].values())
    sim4 = f"sim://?drivers=4&key={KEY.hex()}&flash={flash}"
    assert console_main([*common, "--verify-only", "--port", sim4]) == 0
    assert capsys.readouterr().out.count("verified, verified") == 4
    elsewhere = sim4.replace("drivers=4", "drivers=4&first=3")
    assert console_main([plan, "R01C01", "R01C02", "--bus", "--verify-only", "--key-file", str(site / "key"),
                         "--journal", str(tmp_path / "other.json"), "--port", elsewhere]) == 3
    assert "did not answer" in capsys.readouterr().out  # nobody at addresses 1 and 2 on that bus


def test_missing_and_busy_ports_and_no_terminal_give_one_clear_line(site, tmp_path, capsys):
    plan = str(site / "p512" / "plan.yaml")
    key = ["--key-file", str(site / "key")]
    assert console_main([plan, "R01C01", "--bus", "--port", "/dev/ttyNOSUCH9", *key]) == 2
    assert "cannot open" in capsys.readouterr().err
    master, slave = os.openpty()
    held = serial.Serial(os.ttyname(slave), exclusive=True)
    try:
        assert console_main([plan, "R01C01", "--bus", "--port", os.ttyname(slave), *key]) == 2
        assert "busy" in capsys.readouterr().err
    finally:
        held.close()
        os.close(master)
        os.close(slave)
    assert console_main([plan, "R01C01", "--port", "sim://", *key]) == 2  # interactive, but stdin is no terminal
    assert "needs a terminal" in capsys.readouterr().err
    assert console_main([plan, "--all", "--bus", "--port", "sim://"]) == 2
    assert "no site key" in capsys.readouterr().err


def test_dry_run_opens_nothing_and_says_what_it_would_do(site, capsys):
    assert console_main([str(site / "p512" / "plan.yaml"), "R01C01", "R01C02", "--bus", "--dry-run"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 2 and "address 1" in out[0] and out[0].endswith("flash")


def test_interactive_mode_asks_for_each_driver_on_a_terminal(site, tmp_path):
    """The installer's session, with a real pseudo-terminal as stdin: Enter flashes, s skips."""
    master, slave = os.openpty()
    os.write(master, b"\ns\n")  # plug the first driver and press Enter; skip the second
    proc = subprocess.run([sys.executable, "-m", "planner.cli.flash", str(site / "p512" / "plan.yaml"), "R01C01",
                           "R01C02", "--port", f"sim://?key={KEY.hex()}", "--key-file", str(site / "key"),
                           "--journal", str(tmp_path / "j.json")], stdin=slave, capture_output=True, text=True,
                          cwd=ROOT, timeout=60)
    os.close(master)
    os.close(slave)
    assert proc.returncode == 0, proc.stderr
    assert "plug the driver of R01C01 (ID" in proc.stdout and "plug the driver of R01C02" in proc.stdout
    assert proc.stdout.count("flashed, verified") == 1
    assert list(json.loads((tmp_path / "j.json").read_text())["luminaires"]) == ["R01C01"]
