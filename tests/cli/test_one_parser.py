"""One parser builder for every command, and flags spoken only in ``cli/`` (issue 35).

Every console script's parser comes from :func:`planner.cli.common.parser`: its --help has the
shared formatter and ends with the epilog's exit codes and docs page, --version prints the same
version. Outside ``planner/cli/`` no raised error starts with a flag: the library names its
parameters (`` `check_distance` ``) and the command line says them as flags (:func:`worded`).
"""

from __future__ import annotations

import ast
import importlib
import re
from importlib import metadata
from pathlib import Path

import pytest

import planner
from planner.cli import common as cli
from planner.cli.console import FLAGS, worded

ENTRY_POINTS = {ep.name: ep.value.split(":")[0] for ep in metadata.distribution("vlp-plan").entry_points
                if ep.group == "console_scripts"}
PACKAGE = Path(planner.__file__).parent
EPILOG = re.compile(r"Exit codes: 0 [^,]+.*, 1 bad input[^,]*, 2 usage error[^,]*\. "
                    r"Docs: docs/[^;]+?(; every command: docs/cli\.md)?\.$")

LEFT = {"layout/dxf_names.py", "layout/dxf_units.py"}
"""Modules whose errors still start with a flag: dxfcap's files this session (issue 35 leftover); drop a
name once its errors name the parameter."""


@pytest.mark.parametrize("command", sorted(ENTRY_POINTS))
def test_every_command_builds_its_parser_with_the_one_builder(command, capsys):
    module = importlib.import_module(ENTRY_POINTS[command])
    parser = module.build_parser()
    assert type(parser) is cli.Parser and parser.formatter_class is cli.HelpFormatter and parser.prog == command
    text = " ".join(parser.format_help().split())
    assert EPILOG.search(text), text[-300:]
    assert parser.format_help().rstrip().endswith("docs/cli.md.")
    assert all(flag in text for flag in ("--json", "-v, --verbose", "--version"))
    with pytest.raises(SystemExit) as done:
        parser.parse_args(["--version"])
    assert done.value.code == 0 and capsys.readouterr().out == f"{command} {planner.__version__}\n"


def test_no_command_makes_a_parser_of_its_own():
    """Only ``cli/common.py`` calls argparse's constructor or :class:`cli.Parser`; the commands call the builder."""
    for path in sorted((PACKAGE / "cli").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Call):
                name = getattr(node.func, "attr", getattr(node.func, "id", ""))
                assert name not in ("ArgumentParser", "Parser") or path.name == "common.py", (path.name, node.lineno)


def _raised_strings(path: Path) -> list[tuple[int, str]]:
    """Each string (or an f-string's text) inside a ``raise`` of ``path``, with its line."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Raise) and node.exc is not None:
            found += [(sub.lineno, sub.value) for sub in ast.walk(node.exc)
                      if isinstance(sub, ast.Constant) and isinstance(sub.value, str)]
    return found


def test_only_cli_speaks_of_flags_at_the_start_of_an_error():
    starting = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        where = path.relative_to(PACKAGE).as_posix()
        if not where.startswith("cli/"):
            starting |= {f"{where}:{line}": text for line, text in _raised_strings(path) if re.match(r"--[a-z]", text)}
    assert {key.split(":")[0] for key in starting} == LEFT, starting


def test_every_parameter_the_library_names_has_its_flag():
    """A `name` in a raised error outside cli/ is one :data:`FLAGS` words as a flag, and that flag exists."""
    named = {m for path in PACKAGE.rglob("*.py") if "cli" not in path.relative_to(PACKAGE).parts[:1]
             for _, text in _raised_strings(path) for m in re.findall(r"`([^`\s]+)`", text)}
    assert named and named <= set(FLAGS), named - set(FLAGS)
    offered = {flag for module in set(ENTRY_POINTS.values())
               for action in importlib.import_module(module).build_parser()._actions for flag in action.option_strings}
    assert set(FLAGS.values()) <= offered, set(FLAGS.values()) - offered


def test_worded_says_the_flag_and_leaves_other_text_alone():
    assert worded("`check_distance` 30: 512 IDs need more than 24 bits") == "--check-distance 30: 512 IDs need more than 24 bits"
    assert worded("`verify=False` needs an explicit `scheme`: auto chooses") == "--no-verify needs an explicit --scheme: auto chooses"
    assert worded("layer `TAG` of `mount_height_m`") == "layer `TAG` of --height"


FIGURES = {"vlp-verify": ("--map", ["plan.yaml"]), "vlp-accuracy": ("--cdf", []), "vlp-efficiency": ("--plot", []),
           "vlp-twin": (None, ["plan.yaml"]), "vlp-inspect": (None, ["site.dxf"])}
"""Every command that draws a figure into a file, its flag's old name and what it needs besides."""


@pytest.mark.parametrize("command", sorted(FIGURES))
def test_a_figure_file_is_png_in_every_command_and_the_old_name_still_parses(command):
    """Issue 38: one flag name for one meaning; --map, --cdf and --plot stay aliases for a release."""
    old, positionals = FIGURES[command]
    parser = importlib.import_module(ENTRY_POINTS[command]).build_parser()
    action = next(a for a in parser._actions if "--png" in a.option_strings)
    assert action.option_strings[0] == "--png" and action.metavar == "FILE"
    assert getattr(parser.parse_args([*positionals, "--png", "a.png"]), action.dest) == "a.png"
    if old:
        assert action.option_strings == ["--png", old]
        assert getattr(parser.parse_args([*positionals, old, "b.png"]), action.dest) == "b.png"
    others = {a.option_strings[0] for p in ENTRY_POINTS.values() for a in importlib.import_module(p).build_parser()._actions
              if a.option_strings and a.metavar in ("PNG", "SVG")}
    assert not others, others  # no figure flag under another name
