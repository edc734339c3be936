"""The blinking test luminaire's firmware: a square wave at a known rate for ``vlp-calibrate --row-time``.

Timer 1 of an ATmega328P in CTC mode toggles the LED pin every ``prescaler * (compare + 1)``
clock cycles; :func:`blink_timer` picks the smallest prescaler whose compare value fits 16 bits
(the finest rate steps) and gives the rate the timer really makes, which is the one to pass
as ``--blink-hz``. The C source is a template (``firmware_templates/blink/blink.c.j2``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from planner._files import jinja_environment, write_text_atomically
from planner.defaults import MCU_CLOCK_HZ
from planner.errors import UsageError
from planner.firmware.render import default_template_dir

PRESCALERS = {1: "_BV(CS10)", 8: "_BV(CS11)", 64: "_BV(CS11) | _BV(CS10)", 256: "_BV(CS12)",
              1024: "_BV(CS12) | _BV(CS10)"}
"""Timer 1's prescalers and the clock-select bits that choose them."""
MIN_TOGGLE_CYCLES = 200
"""Fewest clock cycles between two toggles: the interrupt's entry, toggle and return take about 40."""


@dataclass(frozen=True)
class BlinkTimer:
    """Timer 1's setting for a blink rate: the pin toggles every ``prescaler * (compare + 1)`` cycles."""

    prescaler: int
    compare: int
    mcu_clock_hz: float

    @property
    def actual_hz(self) -> float:
        """The square wave's rate the timer makes [Hz]."""
        return self.mcu_clock_hz / (2 * self.prescaler * (self.compare + 1))


def blink_timer(blink_hz: float, mcu_clock_hz: float = MCU_CLOCK_HZ) -> BlinkTimer:
    """The setting closest to ``blink_hz`` [Hz]; :class:`UsageError` if the MCU cannot make it."""
    half_cycles = mcu_clock_hz / (2 * blink_hz)
    if half_cycles < MIN_TOGGLE_CYCLES:
        raise UsageError(f"`blink_hz` {blink_hz:g}: at most {mcu_clock_hz / (2 * MIN_TOGGLE_CYCLES):g} Hz at a "
                         f"{mcu_clock_hz:g} Hz clock")
    for prescaler in PRESCALERS:
        compare = round(half_cycles / prescaler) - 1
        if compare <= 0xFFFF:
            return BlinkTimer(prescaler, compare, mcu_clock_hz)
    raise UsageError(f"`blink_hz` {blink_hz:g}: at least {mcu_clock_hz / (2 * 1024 * 65536):.3g} Hz at a "
                     f"{mcu_clock_hz:g} Hz clock")


def blink_source(timer: BlinkTimer) -> str:
    """The firmware's C source for ``timer``."""
    env = jinja_environment(default_template_dir() / "blink", html=False)
    return env.get_template("blink.c.j2").render(blink_hz=timer.actual_hz, mcu_clock_hz=timer.mcu_clock_hz,
                                                 prescaler=timer.prescaler, compare=timer.compare,
                                                 clock_select=PRESCALERS[timer.prescaler])


def write_blink_firmware(folder: Path, timer: BlinkTimer) -> list[str]:
    """``folder/blink.c`` for ``timer`` (the folder is made if missing); the names written."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"{folder}: cannot make the folder ({exc.strerror or exc})") from None
    write_text_atomically(folder / "blink.c", blink_source(timer))
    return ["blink.c"]
