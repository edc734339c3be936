"""vlp-flash's batches against simulated drivers: a real pseudo-terminal with faults, resume after an interruption
or a lost port, concurrent runs, bad ports and journals, the installer's session on a terminal; and no key anywhere
it writes or says. Which image a driver is given and takes: test_flash_images.py."""

import hashlib
import hmac
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
import serial
from simulated import KEY, NAMES32, booted, bus_url, flash_run, journal_entries, planned_twice

from planner.cli.flash import console_main, shown_port
from planner.firmware.image import CRC_OFFSET, SIGNATURE_OFFSET, parse_config_image
from planner.flash.flasher import at_version, sign_image
from planner.flash.keys import driver_key

BIN = Path(sys.executable).parent  # the installed console scripts


@pytest.fixture(scope="module")
def site(tmp_path_factory, plan512_dir):
    base = tmp_path_factory.mktemp("site")
    (base / "p512").symlink_to(plan512_dir, target_is_directory=True)
    (base / "key").write_text(KEY.hex())
    return base


@pytest.fixture(scope="module")
def plans(tmp_path_factory) -> Path:
    return planned_twice(tmp_path_factory)


def _sim_process(key: Path, flash: Path, faults: str = "", drivers: int = 32) -> tuple[subprocess.Popen, str]:
    """The installed ``vlp-driver-sim`` serving ``drivers`` simulated drivers on a pseudo-terminal: it and the port."""
    proc = subprocess.Popen([str(BIN / "vlp-driver-sim"), "--drivers", str(drivers), "--key-file", str(key),
                             "--flash-dir", str(flash), *(["--faults", faults] if faults else [])],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    return proc, proc.stdout.readline().strip()


NAMES512 = [f"R{r:02d}C{c:02d}" for r in range(1, 17) for c in range(1, 33)]  # grid-512 in plan order


@pytest.mark.slow
@pytest.mark.parametrize("drivers", [32, pytest.param(512, marks=pytest.mark.acceptance)])
def test_every_driver_on_a_faulty_bus_ends_verified_or_failed_and_never_corrupt(drivers, request, tmp_path, capsys):
    """Every driver of a whole site flashed over one bus that corrupts, resets and cuts power: each ends verified or
    failed, holding a whole image signed with its own key (the suite: grid-32's 32 drivers; the 512 grid's under
    ``--acceptance``)."""
    if drivers == 512:
        site, plan, names = request.getfixturevalue("site"), "p512/plan.yaml", NAMES512
    else:
        site, plan, names = request.getfixturevalue("plans"), "a/plan.yaml", NAMES32
    flash_dir, journal = tmp_path / "flash", tmp_path / "as-built.json"
    sim, pty = _sim_process(site / "key", flash_dir, "corrupt=0.001,reset=0.01,power=0.01,seed=3", drivers=drivers)
    try:
        code = console_main([str(site / plan), "--all", "--bus", "--port", pty, "--key-file",
                             str(site / "key"), "--journal", str(journal)])
    finally:
        sim.terminate()
        sim.wait(timeout=20)
    out, err = capsys.readouterr()
    assert KEY.hex() not in out + err + journal.read_text()  # the site key never shows
    entries = journal_entries(journal)
    assert len(entries) == drivers and code in (0, 3)
    verified = [n for n, e in entries.items() if e["verified"]]
    assert len(verified) >= drivers - drivers // 40  # faults cost retries, not drivers (at most 12 of 512)
    print(f"{len(verified)} of {drivers} drivers verified over the faulty bus")
    for k in range(1, drivers + 1):
        driver = booted(flash_dir / f"SIM-{k:06d}.flash")
        e = entries[names[k - 1]]
        assert e["where"].endswith(f"@{k}")
        if e["verified"]:
            assert e["driver_serial"] == f"SIM-{k:06d}" and driver.active_sha256.hex() == e["image_sha256"]
        if driver.active_slot:  # whatever it holds is a whole image, signed with that driver's own key
            image = driver.flash.read(driver.flash.area(driver.active_slot), 168)
            parse_config_image(image)
            mac = hmac.new(driver_key(KEY, f"SIM-{k:06d}"), image[:SIGNATURE_OFFSET], hashlib.sha256).digest()
            assert hmac.compare_digest(image[SIGNATURE_OFFSET:CRC_OFFSET], mac)


def test_two_concurrent_runs_on_one_plan_end_with_a_complete_journal(plans, tmp_path):
    journal = tmp_path / "j.json"
    runs = []
    for names in (NAMES32[0::2], NAMES32[1::2]):
        url = bus_url(32, extra="&paced=1")  # each its own bus, at the line's pace so the two runs overlap
        runs.append(subprocess.Popen([str(BIN / "vlp-flash"), str(plans / "a" / "plan.yaml"), *names, "--bus",
                                      "--baud", "57600", "--key-file", str(plans / "key"), "--journal", str(journal),
                                      "--port", url], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True))
    outs = [run.communicate(timeout=120) for run in runs]
    assert [run.returncode for run in runs] == [0, 0], outs
    entries = journal_entries(journal)
    assert sorted(entries) == sorted(NAMES32) and all(e["verified"] for e in entries.values())


def test_a_port_lost_mid_batch_ends_in_one_line_and_resume_completes_the_journal(plans, tmp_path):
    journal, flash = tmp_path / "j.json", tmp_path / "flash"
    sim, pty = _sim_process(plans / "key", flash, "stall=0.2,stall_s=0.03,seed=2")  # late answers: a slower run
    args = [str(plans / "a" / "plan.yaml"), "--all", "--bus", "--key-file", str(plans / "key"), "--journal",
            str(journal)]
    run = subprocess.Popen([str(BIN / "vlp-flash"), *args, "--port", pty], stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and not (journal.exists() and len(journal_entries(journal)) >= 3):
            time.sleep(0.005)
    finally:
        sim.kill()  # the far end of the port vanishes mid-batch
        sim.wait()
    out, err = run.communicate(timeout=60)
    assert run.returncode == 2 and len(err.splitlines()) == 1, err
    assert f"--port {pty}: lost while flashing" in err and "rerun with --resume" in err and "internal" not in err
    done = [n for n, e in journal_entries(journal).items() if e["verified"]]
    assert 3 <= len(done) < 32
    sim, pty = _sim_process(plans / "key", flash)
    try:
        got = flash_run(*args, "--resume", "--port", pty)
    finally:
        sim.terminate()
        sim.wait()
    assert got.returncode == 0, got.stdout + got.stderr
    assert got.stdout.count("skipped (journal: verified)") == len(done)
    entries = journal_entries(journal)
    assert sorted(entries) == sorted(NAMES32) and all(e["verified"] for e in entries.values())
    for k, name in enumerate(NAMES32, 1):
        assert booted(flash / f"SIM-{k:06d}.flash").active_sha256.hex() == entries[name]["image_sha256"]


def test_the_journal_agrees_with_every_driver_after_a_faulted_run(plans, tmp_path, capsys):
    journal, flash = tmp_path / "j.json", tmp_path / "flash"
    flash.mkdir()
    url = bus_url(32, flash, "&faults=corrupt=0.003,reset=0.1,power=0.1,seed=5")
    code = console_main([str(plans / "a" / "plan.yaml"), "--all", "--bus", "--key-file", str(plans / "key"),
                         "--journal", str(journal), "--port", url])
    capsys.readouterr()
    entries = journal_entries(journal)
    assert code in (0, 3) and sorted(entries) == sorted(NAMES32)
    plan_images = {}
    for k, name in enumerate(NAMES32, 1):
        serial_ = f"SIM-{k:06d}"
        d, e = booted(flash / f"{serial_}.flash"), entries[name]
        plain = (plans / "a" / "firmware" / name / "vlp_config.bin").read_bytes()
        runs_plan = d.active_slot and d.active_sha256 == hashlib.sha256(
            sign_image(at_version(plain, d.active_version), driver_key(KEY, serial_))).digest()
        plan_images[name] = bool(runs_plan)
        if e["active_sha256"] or e["verified"]:  # what it last reported is what it holds, and never "failed"
            assert e["verified"] == bool(runs_plan), (name, e)  # for a driver running the new image
            assert (e["active_sha256"], e["active_version"]) == (d.active_sha256.hex(), d.active_version), name
        if e["verified"]:
            assert e["image_sha256"] == d.active_sha256.hex() and e["driver_serial"] == serial_
    assert sum(plan_images.values()) >= 28 and sum(not e["active_sha256"] for e in entries.values()) <= 1


def test_no_key_appears_in_any_journal_or_message(plans, tmp_path, capsys):
    keys = [KEY.hex(), KEY.hex().upper(), *(driver_key(KEY, f"SIM-{k:06d}").hex() for k in (1, 2))]
    journal = tmp_path / "j.json"
    common = [str(plans / "a" / "plan.yaml"), "R01C01", "R01C02", "--bus", "--key-file", str(plans / "key"),
              "--journal", str(journal)]
    spelled = bus_url(2).replace("key=", "k%65y=")  # the same parameter, spelled as a URL may spell it
    codes = [console_main([*common, "--port", bus_url(2), "--json"]),
             console_main([*common, "--port", spelled, "--verify-only"]),
             console_main([*common, "--port", bus_url(2, extra="&bogus=1")]),  # refused: the message shows the URL
             console_main([*common, "--port", bus_url(1), "-v"])]  # the second driver is missing: failed
    out, err = capsys.readouterr()
    assert codes == [0, 3, 2, 3] and "bogus" in err
    assert "key=<hidden>" in err and "k%65y" not in out + err + journal.read_text()
    said = out + err + journal.read_text() + "".join(p.read_text() for p in tmp_path.iterdir() if p.is_file())
    assert not [k for k in keys if k in said]
    assert shown_port("sim://?drivers=2&KEY=ab&key=cd&flash=x") == "sim://?drivers=2&key=<hidden>&key=<hidden>&flash=x"


def test_a_journal_that_cannot_be_written_is_refused_before_anything_is_flashed(plans, tmp_path, capsys):
    flash = tmp_path / "flash"
    flash.mkdir()
    (tmp_path / "file").write_text("")
    for where in (tmp_path / "missing" / "j.json", tmp_path / "file" / "j.json", tmp_path):
        code = console_main([str(plans / "a" / "plan.yaml"), "R01C01", "--bus", "--key-file", str(plans / "key"),
                             "--journal", str(where), "--port", bus_url(1, flash)])
        err = capsys.readouterr().err
        assert code == 2 and len(err.splitlines()) == 1 and f"--journal {where}" in err
    assert os.listdir(flash) == []  # no driver was opened, so none was flashed


def test_missing_and_busy_ports_and_no_terminal_give_one_clear_line(plans, capsys):
    plan = str(plans / "a" / "plan.yaml")
    key = ["--key-file", str(plans / "key")]
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


def test_interrupted_batch_resumes_and_skips_finished_drivers(plans, tmp_path, capsys):
    plan = str(plans / "a" / "plan.yaml")
    journal = tmp_path / "j.json"
    names = ["R01C01", "R01C02", "R01C03", "R01C04"]
    flash = tmp_path / "flash"
    flash.mkdir()
    common = [plan, *names, "--bus", "--key-file", str(plans / "key"), "--journal", str(journal)]
    # the first batch reaches only the first two drivers (the others are not on the bus yet)
    assert console_main([*common, "--port", bus_url(2, flash)]) == 3
    first = capsys.readouterr()
    assert "did not answer" in first.out and "R01C03" in first.err
    assert console_main([*common, "--resume", "--port", bus_url(4, flash)]) == 0
    out = capsys.readouterr().out
    assert out.count("skipped (journal: verified)") == 2 and out.count("flashed, verified") == 2
    assert all(e["verified"] for e in journal_entries(journal).values())
    assert console_main([*common, "--verify-only", "--port", bus_url(4, flash)]) == 0
    assert capsys.readouterr().out.count("verified, verified") == 4
    elsewhere = bus_url(4, flash, "&first=3")
    assert console_main([plan, "R01C01", "R01C02", "--bus", "--verify-only", "--key-file", str(plans / "key"),
                         "--journal", str(tmp_path / "other.json"), "--port", elsewhere]) == 3
    assert "did not answer" in capsys.readouterr().out  # nobody at addresses 1 and 2 on that bus


def test_dry_run_opens_nothing_and_says_what_it_would_do(plans, capsys):
    assert console_main([str(plans / "a" / "plan.yaml"), "R01C01", "R01C02", "--bus", "--dry-run"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 2 and "address 1" in out[0] and out[0].endswith("flash")


def test_interactive_mode_asks_for_each_driver_on_a_terminal(plans, tmp_path):
    """The installer's session, with a real pseudo-terminal as stdin: Enter flashes, s skips."""
    master, slave = os.openpty()
    os.write(master, b"\ns\n")  # plug the first driver and press Enter; skip the second
    proc = subprocess.run([str(BIN / "vlp-flash"), str(plans / "a" / "plan.yaml"), "R01C01", "R01C02", "--port",
                           f"sim://?key={KEY.hex()}", "--key-file", str(plans / "key"),
                           "--journal", str(tmp_path / "j.json")], stdin=slave, capture_output=True, text=True,
                          timeout=60)
    os.close(master)
    os.close(slave)
    assert proc.returncode == 0, proc.stderr
    assert "plug the driver of R01C01 (ID" in proc.stdout and "plug the driver of R01C02" in proc.stdout
    assert "driver SIM-000001 answered (proved its key; runs version 0); R01C01 has no driver bound yet" in proc.stdout
    assert proc.stdout.count("flashed, verified") == 1
    assert list(journal_entries(tmp_path / "j.json")) == ["R01C01"]
