"""The registry of receiver modes: each mode's class, registered once; a name is turned into its mode here
and nowhere else (``--receiver``, a plan's ``receiver.mode``)."""

from __future__ import annotations

from planner.errors import InputError
from planner.receivers.base import Receiver
from planner.receivers.gravity import TwoLedsGravity
from planner.receivers.three import ThreeLeds

PAPER = ThreeLeds()
"""The paper's receiver: a plan without a ``receiver`` section is made for it."""

RECEIVERS: dict[str, Receiver] = {mode.name: mode for mode in (PAPER, TwoLedsGravity())}
"""Every receiver mode by name, in the order the advice and ``--receiver auto`` try them."""

AUTO = "auto"
"""Not a mode: plan the paper's receiver and, where it falls short, the others; keep the best."""


def receiver_for(name: str, where: str = "receiver") -> Receiver:
    """The mode called ``name``; :class:`InputError` naming ``where`` (the parameter or plan field) if none is."""
    try:
        return RECEIVERS[name]
    except (KeyError, TypeError):
        raise InputError(f"{where}: unknown receiver mode {name!r}; use one of {', '.join(RECEIVERS)}") from None


def extra_error_terms(accuracy_method: str) -> tuple[str, ...]:
    """Error terms that only the mode simulating ``accuracy_method`` has (its accelerometer)."""
    return next((m.extra_error_terms for m in RECEIVERS.values() if m.accuracy_method("") == accuracy_method), ())
