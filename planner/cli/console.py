"""How every command runs: ``console_main`` turns a command's errors into one line and an exit code.

A command's ``main(argv)`` raises :class:`~planner.errors.PlannerError` so tests can call it in
process; :func:`console_main` prints one line per error with the exit code it carries
(:class:`~planner.errors.ExitCode`), the traceback only under ``--verbose``, and unwinds
SIGTERM and SIGHUP like Ctrl-C so nothing is left half-written.

The library names its parameters in errors, in backticks (`` `check_distance` 30: ...``);
:func:`worded` says them as the flags that set them (``--check-distance 30: ...``): only
``cli/`` speaks of flags.
"""

from __future__ import annotations

import os
import re
import signal
import sys
import traceback
import warnings
from collections.abc import Callable
from typing import Any, NoReturn

from planner.errors import ExitCode, PlannerError, PlannerWarning

FLAGS = {
    "allow_unverified": "--allow-unverified",
    "blink_hz": "--blink-hz",
    "camera": "--camera",
    "check_distance": "--check-distance",
    "eeprom_dir": "--eeprom-dir",
    "journal": "--journal",
    "leds": "--leds",
    "max_poses": "--max-poses",
    "mount_height_m": "--height",
    "poses_per_m2": "--poses-per-m2",
    "radius_m": "--radius",
    "receiver": "--receiver",
    "room": "--room",
    "scheduler": "--scheduler",
    "scheme": "--scheme",
    "storey": "--storey",
    "units": "--units",
    "verify=False": "--no-verify",
    "workers": "--workers",
}
"""The library's parameters (as its errors name them, in backticks) and the flags that set them."""


def worded(text: str) -> str:
    """An error of the library as the command line says it: each `parameter` it names as its flag
    (:data:`FLAGS`); a name not listed keeps its backticks."""
    return re.sub(r"`([^`\s]+)`", lambda m: FLAGS.get(m[1], m[0]), text)


def one_line(text: str) -> str:
    """``text`` with every non-printable character (newlines, controls, undecodable bytes) escaped,
    so that what a hostile file holds cannot split, forge or break an error line."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else _escaped(c) for c in text)


def _escaped(c: str) -> str:
    """One non-printable character as an escape: an undecodable byte (kept by ``surrogateescape``) as ``\\xNN``."""
    if 0xDC80 <= ord(c) <= 0xDCFF:
        return f"\\x{ord(c) - 0xDC00:02x}"
    return c.encode("unicode_escape").decode("ascii")


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP arrived: raised like Ctrl-C, so every half-written output is removed on the way out."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def _terminate(signum: int, frame) -> NoReturn:
    raise Terminated(signum)


def console_main(argv: list[str] | None, command: Callable[[list[str] | None], int], name: str) -> int:
    """Run ``command(argv)`` as the script ``name``: its exit code, or one line per error and the error's code.

    SIGTERM and SIGHUP (a closed terminal, ``kill``, a CI timeout) unwind like Ctrl-C, so
    staging folders and temporary files are removed; the exit code is 128 + the signal.
    """
    verbose = "-v" in (argv or sys.argv[1:]) or "--verbose" in (argv or sys.argv[1:])
    before: dict[signal.Signals, Any] = {}  # the handlers to give back
    try:
        for sig in (signal.SIGTERM, signal.SIGHUP):
            before[sig] = signal.signal(sig, _terminate)
    except ValueError:  # not the main thread (a test calling main() from a worker): leave the defaults
        pass
    try:
        return _run(argv, command, name, verbose)
    finally:  # a caller in the same process (a test, a script) gets its own handlers back
        for old, handler in before.items():
            signal.signal(old, handler)


def _run(argv: list[str] | None, command: Callable[[list[str] | None], int], name: str, verbose: bool) -> int:
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", PlannerWarning)
            code = command(argv)
        for w in caught:  # after the run: a run that fails prints its one error line alone
            if issubclass(w.category, PlannerWarning):
                print(f"{name}: warning: {one_line(worded(str(w.message)))}", file=sys.stderr)
            else:
                warnings.showwarning(w.message, w.category, w.filename, w.lineno)
        return code
    except PlannerError as exc:
        if verbose:
            traceback.print_exc()
        print(f"{name}: error: {one_line(worded(str(exc)))}", file=sys.stderr)
        return exc.exit_code
    except BrokenPipeError:  # the reader went away (``| head``): stop quietly, as Unix tools do
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return ExitCode.BROKEN_PIPE
    except Terminated as exc:
        print(f"{name}: stopped by {exc}; no output was written", file=sys.stderr)
        return 128 + exc.signum
    except KeyboardInterrupt:
        print(f"{name}: interrupted; no output was written", file=sys.stderr)
        return ExitCode.INTERRUPTED
    except OSError as exc:  # the system refused a read or write the checks could not foresee (a full disk)
        if verbose:
            traceback.print_exc()
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"{name}: error: {one_line(where)}{exc.strerror or exc}; nothing was written there (free space or "
              "choose another place)", file=sys.stderr)
        return ExitCode.INPUT
    except Exception as exc:  # a bug: still one line, unless asked for more
        if verbose:
            traceback.print_exc()
        print(f"{name}: internal error: {type(exc).__name__}: {one_line(str(exc))} (rerun with --verbose and report it)",
              file=sys.stderr)
        return ExitCode.INPUT

