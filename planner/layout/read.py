"""Read a layout file (DXF, IFC, YAML or CSV) into a checked :class:`~planner.layout.model.Layout`.

The one entry the commands and the stage runner read layouts through: picks the reader by suffix,
fills an outline-only drawing with ``leds`` luminaires, and checks the result.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from planner.errors import InputError, UsageError
from planner.layout.model import DEFAULT_MOUNT_HEIGHT_M, DEFAULT_RADIUS_M, Layout, check_layout, fill_outline

LAYOUT_SUFFIXES = (".dxf", ".ifc", ".yaml", ".yml", ".csv")
DRAWING_SUFFIXES = (".dxf", ".ifc")
"""Drawings whose failed read points to ``vlp-inspect``."""


@dataclass(frozen=True)
class ReadOptions:
    """How to read a layout (the command line's reading flags)."""

    units: str | None = None
    preset: str = "auto"
    layers: tuple[str, ...] = ()
    blocks: tuple[str, ...] = ()
    mount_height_m: float | None = None
    radius_m: float | None = None
    room: str | None = None
    storey: str | None = None



def read_layout(path: str | Path, leds: int | None, options: ReadOptions = ReadOptions()) -> Layout:
    """Read a DXF, IFC, YAML or CSV layout; with ``leds`` and only an outline, fill it.

    A drawing (DXF, IFC) that cannot be planned raises :class:`InputError` whose line ends
    with a pointer to ``vlp-inspect``.
    """
    path = Path(path)
    if path.suffix.lower() not in LAYOUT_SUFFIXES:
        raise UsageError(f"{path}: unknown layout type {path.suffix!r}; give a .dxf, .ifc, .yaml, .yml or .csv file")
    if not path.is_file():
        raise UsageError(f"{path}: no such file")
    if path.suffix.lower() not in DRAWING_SUFFIXES:
        return _read_layout(path, leds, options)
    try:
        return _read_layout(path, leds, options)
    except InputError as exc:
        from planner.layout.dxf import INSPECT_HINT

        hint = INSPECT_HINT.format(path=path)
        if hint in str(exc):
            raise
        raise InputError(f"{exc}; {hint}") from exc


def _read_layout(path: Path, leds: int | None, options: ReadOptions) -> Layout:
    suffix = path.suffix.lower()
    for param, value, where in (("`room`", options.room, ".dxf"), ("`storey`", options.storey, ".ifc")):
        if value is not None and suffix != where:
            raise UsageError(f"{param} is for {where} drawings, not {path.name}")
    if suffix == ".dxf":
        from planner.layout.dxf import read_dxf

        layout = read_dxf(
            path, units=options.units, preset=options.preset, layers=list(options.layers) or None,
            blocks=list(options.blocks) or None, mount_height_m=options.mount_height_m,
            radius_m=options.radius_m, allow_outline_only=leds is not None, expected=leds, room=options.room,
        )
    elif suffix == ".ifc":
        from planner.layout.ifc import read_ifc

        layout = read_ifc(path, storey=options.storey, mount_height_m=options.mount_height_m,
                          radius_m=options.radius_m, units=options.units)
    else:
        from planner.layout.tables import read_csv, read_yaml

        reader = read_csv if suffix == ".csv" else read_yaml
        layout = reader(path, units=options.units, mount_height_m=options.mount_height_m, radius_m=options.radius_m)
    if not layout.luminaires:
        if layout.outline is None:
            raise InputError(f"{path}: holds neither luminaires nor a room outline; nothing to plan")
        if leds is None:
            raise InputError(f"{path}: holds a room outline but no luminaires; give `leds` N to lay out N of them")
        height = options.mount_height_m or layout.fill_height_m or DEFAULT_MOUNT_HEIGHT_M
        radius = options.radius_m or layout.fill_radius_m or DEFAULT_RADIUS_M
        try:
            lums, description = fill_outline(np.array(layout.outline), leds, height, radius)
        except InputError as exc:
            raise InputError(f"{path}: {exc}") from None
        layout = replace(layout, luminaires=tuple(lums)).with_note(description)
        if options.mount_height_m is None and layout.fill_height_m is None:
            layout = layout.with_note(f"mounting height {height} m (default; set with --height)")
        leds = None  # the fill made exactly that many
    return check_layout(layout, expected=leds)
