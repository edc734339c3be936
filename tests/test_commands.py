"""The nine console scripts, as installed: --help answers at once (the stages load only when a command runs)."""

import shutil
import subprocess
import sys
import time

import pytest

COMMANDS = ("vlp-plan", "vlp-verify", "vlp-locate", "vlp-accuracy", "vlp-efficiency", "vlp-flash", "vlp-report",
            "vlp-twin", "vlp-driver-sim")


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
    from planner.frame import LINE_CODES
    from planner.locate import METHODS

    assert set(defaults.LINE_CODE_NAMES) == set(LINE_CODES)
    assert set(defaults.LOCATE_METHODS) == set(METHODS)
