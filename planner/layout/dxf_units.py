"""Drawing units: which unit a DXF drawing's coordinates are in, decided once at the edge.

``$INSUNITS`` is read but not trusted: DIALux, for one, writes inches for drawings
whose coordinates are millimetres. The header unit is kept when the figures it
gives are plausible for a lit ceiling; otherwise the first unit of
:data:`PREFERENCE` that makes them plausible is used, and the reason is recorded.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

from planner.defaults import UNIT_TO_M
from planner.errors import InputError, UsageError

UNIT_NAMES = {"mm": "millimetres", "cm": "centimetres", "m": "metres", "in": "inches", "ft": "feet"}

PREFERENCE = ("mm", "m", "cm", "in", "ft")
"""Order in which units are tried when the header unit is implausible or missing."""

INSUNITS_TO_UNIT = {1: "in", 2: "ft", 4: "mm", 5: "cm", 6: "m"}
"""``$INSUNITS`` codes this tool supports."""

_INSUNITS_OTHER = {
    3: "miles", 7: "kilometres", 8: "microinches", 9: "mils", 10: "yards", 11: "angstroms",
    12: "nanometres", 13: "microns", 14: "decimetres", 15: "decametres", 16: "hectometres",
    17: "gigametres", 18: "astronomical units", 19: "light years", 20: "parsecs",
}

SPACING_RANGE_M = (0.3, 30.0)
"""Plausible typical nearest-neighbour spacing of luminaires [m]."""
HEIGHT_RANGE_M = (1.5, 30.0)
"""Plausible mounting height (nonzero Z) [m]."""
OUTLINE_RANGE_M = (1.0, 2000.0)
"""Plausible side of a room outline's bounding box [m]."""

_ALIASES = {
    "mm": "mm", "millimeter": "mm", "millimeters": "mm", "millimetre": "mm", "millimetres": "mm",
    "cm": "cm", "centimeter": "cm", "centimeters": "cm", "centimetre": "cm", "centimetres": "cm",
    "m": "m", "meter": "m", "meters": "m", "metre": "m", "metres": "m",
    "in": "in", "inch": "in", "inches": "in", "ft": "ft", "foot": "ft", "feet": "ft",
}


@dataclass(frozen=True)
class Figures:
    """What a drawing measures in one candidate unit [m]; ``None`` when it has no such figure."""

    spacing_m: float | None = None
    height_m: float | None = None
    outline_m: tuple[float, float] | None = None

    def problems(self) -> list[str]:
        """Why these figures are implausible (empty when plausible)."""
        out = []
        if self.spacing_m is not None and not _within(self.spacing_m, SPACING_RANGE_M):
            out.append(f"luminaire spacing would be {_fmt(self.spacing_m)} m")
        if self.height_m is not None and not _within(self.height_m, HEIGHT_RANGE_M):
            out.append(f"mounting height would be {_fmt(self.height_m)} m")
        if self.outline_m is not None and not all(_within(s, OUTLINE_RANGE_M) for s in self.outline_m):
            w, h = self.outline_m
            out.append(f"the room would be {_fmt(w)} m x {_fmt(h)} m")
        return out

    def describe(self) -> str:
        """The figures, for the unit reason: ``spacing 2.4 m, height 2.8 m``."""
        parts = []
        if self.spacing_m is not None:
            parts.append(f"spacing {_fmt(self.spacing_m)} m")
        if self.height_m is not None:
            parts.append(f"height {_fmt(self.height_m)} m")
        if self.outline_m is not None and self.spacing_m is None:
            parts.append(f"room {_fmt(self.outline_m[0])} m x {_fmt(self.outline_m[1])} m")
        return ", ".join(parts)

    @property
    def empty(self) -> bool:
        return self.spacing_m is None and self.height_m is None and self.outline_m is None


def _within(value: float, bounds: tuple[float, float]) -> bool:
    return bounds[0] <= value <= bounds[1]


def _fmt(value: float) -> str:
    return f"{value:.3g}"


def parse_unit(text: str) -> str:
    """Normalise a ``--units`` value (``mm``, ``metres``, ``feet``...) to a key of :data:`UNIT_TO_M`."""
    unit = _ALIASES.get(text.strip().lower())
    if unit is None:
        raise UsageError(f"--units {text!r} is not a unit this tool knows; use one of mm, cm, m, in, ft")
    return unit


def choose_unit(
    measure: Callable[[float], Figures], insunits: int, override: str | None, where: str
) -> tuple[str, str, list[str]]:
    """Decide the drawing unit.

    Parameters
    ----------
    measure : callable
        Maps a scale [m per drawing unit] to the drawing's :class:`Figures` in metres.
    insunits : int
        The header's ``$INSUNITS`` code (0 when unset).
    override : str or None
        The ``--units`` value, which wins over everything.
    where : str
        The file, for messages.

    Returns
    -------
    unit, reason, notes
        The unit key, why it was chosen, and extra notes for the layout.
    """
    if override is not None:
        unit = parse_unit(override)
        given = measure(UNIT_TO_M[unit])
        notes = []
        if given.problems():
            notes.append(f"--units {unit}: {'; '.join(given.problems())}, which looks implausible; check the unit")
        return unit, f"given with --units ({UNIT_NAMES[unit]})", notes

    header = INSUNITS_TO_UNIT.get(insunits)
    if header is not None:
        said = f"$INSUNITS says {UNIT_NAMES[header]}"
    elif insunits in _INSUNITS_OTHER:
        said = f"$INSUNITS says {_INSUNITS_OTHER[insunits]} (not supported)"
    else:
        said = "$INSUNITS is unset"

    figures = {unit: measure(UNIT_TO_M[unit]) for unit in UNIT_TO_M}
    if next(iter(figures.values())).empty:
        unit = header or "m"
        how = "used" if header else "assumed"
        return unit, f"{said}; nothing to check it against, {how} {UNIT_NAMES[unit]}", []

    if header is not None and not figures[header].problems():
        return header, f"{said} ({figures[header].describe()})", []

    plausible = [u for u in PREFERENCE if not figures[u].problems()]
    ignored = ""
    if not plausible and any(f.height_m is not None for f in figures.values()):
        # Z plausible in no unit where the spacing is: not a mounting height (a level, noise, a 3D export)
        without = {u: replace(f, height_m=None) for u, f in figures.items()}
        if any(not f.empty and not f.problems() for f in without.values()):
            raw_z = measure(1.0).height_m
            ignored = f"; luminaire Z (typically {_fmt(raw_z or 0.0)} drawing units) is no plausible height in " \
                      "any unit that fits the spacing, taken as no height"
            figures = without
            plausible = sorted((u for u in PREFERENCE if not figures[u].problems()), key=lambda u: u != header)
    if not plausible:
        raw = measure(1.0)
        if raw.spacing_m is not None:
            found = f"luminaire spacing is {_fmt(raw.spacing_m)} drawing units"
        elif raw.height_m is not None:
            found = f"luminaire Z is {_fmt(raw.height_m)} drawing units"
        else:
            assert raw.outline_m is not None  # the figures are not empty (above), in any unit
            found = f"room outline is {_fmt(raw.outline_m[0])} x {_fmt(raw.outline_m[1])} drawing units"
        raise InputError(
            f"{where}: {found}, not plausible in mm, cm, m, in or ft "
            f"(expected {SPACING_RANGE_M[0]}-{SPACING_RANGE_M[1]:g} m between luminaires, "
            f"{HEIGHT_RANGE_M[0]}-{HEIGHT_RANGE_M[1]:g} m high); pass --units"
        )
    unit = plausible[0]
    why = f" but {', '.join(figures[header].problems())}" if header is not None and figures[header].problems() else ""
    reason = f"{said}{why}; used {UNIT_NAMES[unit]} ({figures[unit].describe()}){ignored}"
    if len(plausible) > 1:
        reason += f"; {', '.join(plausible[1:])} would also fit, pass --units if wrong"
    return unit, reason, []
