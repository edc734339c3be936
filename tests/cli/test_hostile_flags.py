"""Hostile flag values, for every numeric flag of every command (issue 36): each is refused by the parser,
before any file is read or any work is done, with one line naming the flag, and exit 2.

The flags are found from each command's parser, so a flag added later is covered too; values are those
that ran until killed (1e999, 9 x 5,000 digits), crashed or were taken as nonsense (nan, inf) before.
"""

from __future__ import annotations

import argparse
import importlib
import time

import pytest

from planner.errors import ExitCode

COMMANDS = ["plan", "verify", "locate", "accuracy", "flash", "efficiency", "report", "twin", "inspect", "calibrate"]
"""Every command with a ``build_parser()`` (vlp-driver-sim, a test double for drivers, has its own tests)."""

BAD_NUMBERS = ["abc", "nan", "inf", "-inf", "1e999", "-1", "", "0x10", "9" * 5000]
TIME_BOUND_S = 10.0  # a parse: milliseconds; the bound catches work started before the check


def _numeric_flags(name: str) -> list[str]:
    parser = importlib.import_module(f"planner.cli.{name}").build_parser()
    return [a.option_strings[-1] for a in parser._actions
            if a.option_strings and a.type is not None and a.type is not str and a.nargs is None]


FLAG_CASES = [(name, flag, value) for name in COMMANDS for flag in _numeric_flags(name) for value in BAD_NUMBERS]
"""(command, flag, value): one refused run each."""


def _positionals(name: str, tmp_path) -> list[str]:
    """What a command needs besides the flag (a plan that does not exist: the parser refuses first)."""
    if name in ("verify", "locate", "report", "twin", "flash"):
        return [str(tmp_path / "plan.yaml")]
    if name in ("plan", "inspect"):
        return [str(tmp_path / "site.dxf")]
    return []


@pytest.mark.parametrize("case", FLAG_CASES, ids=[f"{c[0]}{c[1]}-{k % len(BAD_NUMBERS)}" for k, c in
                                                  enumerate(FLAG_CASES)])
def test_a_bad_number_is_refused_by_the_parser(case, tmp_path, capsys):
    name, flag, value = case
    module = importlib.import_module(f"planner.cli.{name}")
    start = time.perf_counter()
    code = module.console_main([*_positionals(name, tmp_path), f"{flag}={value}"])
    seconds = time.perf_counter() - start
    out, err = capsys.readouterr()
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == ExitCode.USAGE, (case[:2], value[:20], err)
    assert len(lines) == 1 and lines[0].startswith(f"vlp-{name}: error: argument {flag}"), (case[:2], err)
    assert "Traceback" not in err and "internal error" not in err and len(lines[0]) < 400, lines[0][:400]
    assert seconds < TIME_BOUND_S and not list(tmp_path.iterdir()), (case[:2], seconds)


def test_every_command_has_its_numeric_flags_covered():
    """The count the hostile input tests report (test_hostile_input.py) takes these; a command whose parser
    lost its numbers would make it shrink silently."""
    per_command = {name: len(_numeric_flags(name)) for name in COMMANDS}
    assert {name for name, n in per_command.items() if n == 0} == {"report"}, per_command  # report: files only
    assert len(FLAG_CASES) == len(BAD_NUMBERS) * sum(per_command.values())
    for name in COMMANDS:
        for action in importlib.import_module(f"planner.cli.{name}").build_parser()._actions:
            if action.option_strings and action.type is float:  # a bare float takes nan and inf
                raise AssertionError(f"vlp-{name} {action.option_strings[-1]}: type=float takes nan and inf")
    assert argparse  # the parsers are argparse's; their error() raises (cli.common.Parser)
