"""The planner's exceptions: messages are written for the user (what, where, what to do).

The command line turns a ``PlannerError`` into one line on stderr and its
``exit_code``; ``--verbose`` adds the traceback.
"""


class PlannerError(Exception):
    """Base of every error the planner reports to its user."""

    exit_code = 1


class UsageError(PlannerError):
    """The command line itself is wrong: a flag, a value, a path that does not exist."""

    exit_code = 2


class InputError(PlannerError, ValueError):
    """An input file is unreadable or its content cannot be planned."""


class PlanningError(PlannerError):
    """The input is valid but no plan satisfies the requested constraints."""


class PositioningError(PlannerError):
    """The observation is valid but gives no trustworthy position (too few or collinear
    LEDs, no pose explains the ellipses, more than one place fits)."""

    exit_code = 3
