"""The console scripts, as installed: --help answers at once (the stages load only when a command runs)."""

import json
import shutil
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path

import pytest

import planner
from conftest import ROOT, vlp

COMMANDS = tuple(sorted(ep.name for ep in metadata.distribution("vlp-plan").entry_points if ep.group == "console_scripts"))


def test_the_suite_tests_the_installed_package_and_its_eleven_scripts():
    """A plain ``pip install .`` must be what the tests import (``python -m pytest`` would put
    the source tree first on the path); a developer's ``pip install -e .`` is the source tree."""
    installs = [json.loads(d.read_text("direct_url.json") or "{}") for d in metadata.distributions(name="vlp-plan")]
    imported = Path(planner.__file__).resolve()
    if any(i.get("dir_info", {}).get("editable") for i in installs):
        assert imported == ROOT / "planner" / "__init__.py"
    else:
        # CI's virtual environment lies inside the checkout (.venv/), so test the source folder itself
        assert ROOT / "planner" not in imported.parents, f"the tests import the source tree ({imported}), not the installed package"
    assert len(COMMANDS) == 11 and all(name.startswith("vlp-") for name in COMMANDS)
    scripts = {Path(shutil.which(name) or "").parent for name in COMMANDS}
    assert scripts == {Path(sys.executable).parent}, f"the scripts on PATH are not this environment's: {scripts}"


def test_no_test_runs_a_command_from_the_source_tree():
    """``python -m planner.cli...`` run from the checkout imports its source tree, not the installed package (and
    compiles that tree's numba kernels a second time): the tests run the installed console scripts by path."""
    module = "planner"  # written apart, so that this line is not found
    found = [f"{path.relative_to(ROOT)}:{n}" for path in sorted((ROOT / "tests").rglob("*.py"))
             for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
             if f'"-m", "{module}' in line or f"'-m', '{module}" in line]
    assert found == []


def _best_of(argv: list[str], runs: int = 3) -> tuple[float, subprocess.CompletedProcess]:
    best, done = float("inf"), None
    for _ in range(runs):
        t0 = time.perf_counter()
        done = subprocess.run(argv, capture_output=True, text=True, timeout=60)
        best = min(best, time.perf_counter() - t0)
    return best, done


@pytest.mark.parametrize("command", COMMANDS)
def test_help_returns_within_half_a_second_of_a_bare_python(command):
    script = shutil.which(command)
    assert script, f"{command} is not installed as a console script"
    bare, _ = _best_of([sys.executable, "-c", "pass"])
    took, done = _best_of([script, "--help"])
    assert done.returncode == 0 and done.stdout.startswith("usage: "), done.stderr
    assert took - bare < 0.5, f"{command} --help took {took:.2f} s, a bare python {bare:.2f} s"


def test_the_parsers_offer_exactly_what_the_stages_hold():
    from planner import defaults
    from planner.modulation.frame import LINE_CODES
    from planner.positioning.locate import METHODS

    assert set(defaults.LINE_CODE_NAMES) == set(LINE_CODES)
    assert set(defaults.LOCATE_METHODS) == set(METHODS)


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_has_json_verbose_and_version(command):
    from planner import __version__

    shown = subprocess.run([command, "--version"], capture_output=True, text=True, timeout=60)
    assert shown.returncode == 0 and shown.stdout.strip() == f"{command} {__version__}"
    text = subprocess.run([command, "--help"], capture_output=True, text=True, timeout=60).stdout
    assert all(flag in text for flag in ("--json", "-v, --verbose", "--version"))


@pytest.mark.slow
def test_vlp_flash_json_is_the_only_thing_on_stdout(plan512_dir):
    plan = str(plan512_dir / "plan.yaml")
    done = subprocess.run(["vlp-flash", plan, "R01C01", "R01C02", "--bus", "--dry-run", "--json"],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    doc = json.loads(done.stdout)  # the per-driver lines went to stderr
    assert doc["dry_run"] is True and [d["name"] for d in doc["drivers"]] == ["R01C01", "R01C02"]
    assert [d["address"] for d in doc["drivers"]] == [1, 2] and {d["action"] for d in doc["drivers"]} == {"flash"}
    assert "R01C01" in done.stderr
    refused = subprocess.run(["vlp-flash", plan, "R01C01", "--port", "sim://", "--json"], capture_output=True,
                             text=True, timeout=60)
    assert refused.returncode == 2 and "--json needs --bus or --dry-run" in refused.stderr


def test_vlp_flash_json_of_a_bus_run_records_each_driver_and_hides_the_key(plan512_dir, tmp_path):
    key = bytes(range(32)).hex()
    (tmp_path / "key").write_text(key)
    done = subprocess.run(["vlp-flash", str(plan512_dir / "plan.yaml"), "R01C01", "R01C02", "--bus", "--port",
                           f"sim://?key={key}&drivers=2", "--key-file", str(tmp_path / "key"), "--journal",
                           str(tmp_path / "as-built.json"), "--json"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    doc = json.loads(done.stdout)
    assert doc["verified"] == 2 and doc["failed"] == 0 and doc["port"] == "sim://?key=<hidden>&drivers=2"
    assert [(d["name"], d["address"], d["status"]) for d in doc["drivers"]] == [("R01C01", 1, "flashed"),
                                                                               ("R01C02", 2, "flashed")]
    assert key not in done.stdout + done.stderr + (tmp_path / "as-built.json").read_text()


@pytest.mark.parametrize("argv", [
    ["vlp-plan", "--version"],
    ["vlp-verify", "--seed", "-1", "plan.yaml"],  # refused by the parser: exit 2, usage on stderr
    ["vlp-plan", "no-such-layout.yaml", "-o", "out"],  # refused by the command: one line, exit 1
    ["vlp-flash", "plan.yaml", "R01C01", "--port", "sim://", "--json"],
    ["vlp-locate", "--help"],
], ids=lambda argv: " ".join(argv[:2]))
def test_a_command_run_in_process_gives_what_the_script_gives(argv, tmp_path):
    """Most tests run a command through ``conftest.vlp`` (the installed script's entry point, in the test's process):
    its exit code, stdout and stderr are the script's, byte for byte, on what parses, what is refused and --help."""
    script = subprocess.run(argv, capture_output=True, text=True, timeout=60, cwd=tmp_path)
    inside = vlp(*argv, cwd=tmp_path)
    assert (inside.returncode, inside.stdout, inside.stderr) == (script.returncode, script.stdout, script.stderr)
    assert script.stdout or script.stderr
    assert list(tmp_path.iterdir()) == []
