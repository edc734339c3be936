"""The planner's exceptions: messages are written for the user (what, where, what to do).
A message names a parameter as the library spells it, in backticks (`` `check_distance` 30: ...``), never
as a flag; the command line says it as the flag that sets it (:func:`planner.cli.console.worded`).

The command line turns a ``PlannerError`` into one line on stderr and its
``exit_code``; ``--verbose`` adds the traceback. Every command exits with an
:class:`ExitCode`.
"""

from enum import IntEnum


class ExitCode(IntEnum):
    """What a ``vlp-*`` command's exit status means (the same for every command)."""

    OK = 0
    INPUT = 1
    """Bad input, or no plan possible (and internal errors)."""
    USAGE = 2
    """The command line is wrong, or a port or file it names is missing or busy."""
    CHECK_FAILED = 3
    """The command ran, but its result fails its check: ambiguous plan, failed drivers, failed poses, no fix."""
    INTERRUPTED = 130
    BROKEN_PIPE = 141


class PlannerError(Exception):
    """Base of every error the planner reports to its user."""

    exit_code = ExitCode.INPUT


class UsageError(PlannerError):
    """The command line itself is wrong: a flag, a value, a path that does not exist."""

    exit_code = ExitCode.USAGE


class InputError(PlannerError, ValueError):
    """An input file is unreadable or its content cannot be planned."""


class PlanningError(PlannerError):
    """The input is valid but no plan satisfies the requested constraints."""


class PositioningError(PlannerError):
    """The observation is valid but gives no trustworthy position (too few or collinear
    LEDs, no pose explains the ellipses, more than one place fits)."""

    exit_code = ExitCode.CHECK_FAILED


class PlannerWarning(UserWarning):
    """Something the user should fix that does not stop the run (a key file others may read); the command
    line prints it as ``vlp-NAME: warning: ...`` when the run ends without an error (an error's one line
    stays the only one)."""
