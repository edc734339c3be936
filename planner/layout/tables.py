"""Read YAML and CSV layout files into a :class:`~planner.layout.model.Layout`.

Both formats are documented in ``docs/layout-files.md``. Each file is checked once by the
pydantic models below (strict types for YAML, numbers parsed from text for CSV), so a bad
field gets one line naming the file, the field and what is allowed. Coordinates are in
``unit`` (default metres) and converted to metres here, once; ranges in metres are
checked afterwards by :func:`~planner.layout.model.check_layout`.
"""

from __future__ import annotations

import csv
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated, Any

from pydantic import AfterValidator, BaseModel, ConfigDict, Field

from planner._files import load_yaml, read_text
from planner._schema import M, validated
from planner.defaults import FLICKER_HZ, MAX_LUMINAIRES, UNIT_TO_M
from planner.errors import InputError
from planner.layout.model import DEFAULT_MOUNT_HEIGHT_M, DEFAULT_RADIUS_M, Layout, Luminaire

# Lengths in the file's unit. YAML is validated strictly (no '5' for 5, no true for 1);
# CSV cells are text, so there the same fields parse numbers from it.
Length = Annotated[float, Field(allow_inf_nan=False)]
PositiveLength = Annotated[float, Field(allow_inf_nan=False, gt=0)]


Point = Annotated[list[Length], Field(min_length=2, max_length=2)]  # [x, y]


def _tone(hz: float) -> float:
    if hz < FLICKER_HZ:
        raise ValueError(f"{hz:g} Hz is below the flicker limit of {FLICKER_HZ:g} Hz (a slower square wave flickers "
                         "visibly, IEEE 802.15.7); retune that luminaire's driver, or leave tone_hz out")
    return hz


Tone = Annotated[float, Field(allow_inf_nan=False, gt=0), AfterValidator(_tone)]  # [Hz], in every unit


def _polygon(points: list[list[float]]) -> list[list[float]]:
    if len(points) < 3:
        raise ValueError(f"needs at least 3 points, got {len(points)}")
    return points


class LuminaireRow(BaseModel):
    """One luminaire of a layout file: ``x``, ``y`` and optionally ``z``, ``radius``, ``name``, ``tone_hz`` (the
    square-wave tone it already broadcasts [Hz]); ``id`` is ignored."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str | None = None
    x: Length
    y: Length
    z: PositiveLength | None = None
    radius: PositiveLength | None = None
    tone_hz: Tone | None = None
    id: Any = None  # IDs are the planner's to give


class LayoutFile(BaseModel):
    """A YAML layout: ``unit``, default ``height``/``radius``, ``outline`` and ``luminaires``; other keys ignored."""

    model_config = ConfigDict(extra="ignore", frozen=True)

    unit: str = "m"
    height: PositiveLength | None = None
    radius: PositiveLength | None = None
    outline: Annotated[list[Point], AfterValidator(_polygon)] | None = None
    luminaires: Annotated[list[LuminaireRow], Field(max_length=MAX_LUMINAIRES)] | None = None


ALLOWED = [f for f in LuminaireRow.model_fields if f != "id"]


def _unit_scale(unit: str, where: str) -> float:
    try:
        return UNIT_TO_M[unit]
    except KeyError:
        raise InputError(f"{where}: unknown unit {unit!r}; use one of {', '.join(UNIT_TO_M)}") from None


def _checked(model: type[M], doc: object, where: str, *, strict: bool) -> M:
    return validated(model, doc, where, "a layout", strict=strict, known=ALLOWED, label="allowed")


def _luminaire(row: LuminaireRow, k: int, scale: float, defaults: dict, source: dict) -> Luminaire:
    return Luminaire((row.name or "").strip() or f"L{k + 1:04d}", row.x * scale, row.y * scale,
                     row.z * scale if row.z is not None else defaults["z"],
                     row.radius * scale if row.radius is not None else defaults["radius"], source, row.tone_hz)


def _defaults(mount_height_m: float | None, radius_m: float | None, height: float | None, radius: float | None,
              scale: float) -> dict:
    return {
        "z": mount_height_m if mount_height_m is not None
        else height * scale if height is not None else DEFAULT_MOUNT_HEIGHT_M,
        "radius": radius_m if radius_m is not None
        else radius * scale if radius is not None else DEFAULT_RADIUS_M,
    }


def read_yaml(path: str | Path, *, units: str | None = None, mount_height_m: float | None = None,
              radius_m: float | None = None) -> Layout:
    """Read a YAML layout: ``unit``, optional ``height``/``radius`` defaults, ``outline``
    (list of [x, y]) and ``luminaires`` (list of mappings with ``x``, ``y`` and optional
    ``z``, ``radius``, ``name``)."""
    path = Path(path)
    doc = load_yaml(path)
    if not isinstance(doc, dict):
        raise InputError(f"{path}: expected a mapping with 'luminaires' or 'outline' at the top level")
    layout: LayoutFile = _checked(LayoutFile, doc, str(path), strict=True)
    unit = units or layout.unit
    scale = _unit_scale(unit, str(path))
    defaults = _defaults(mount_height_m, radius_m, layout.height, layout.radius, scale)
    lums = tuple(_luminaire(row, k, scale, defaults, {"file": path.name, "index": k})
                 for k, row in enumerate(layout.luminaires or []))
    outline = None if layout.outline is None else tuple((x * scale, y * scale) for x, y in layout.outline)
    reason = "given with --units" if units else ("stated in the file" if "unit" in doc else "the default")
    return Layout(lums, outline, str(path), unit, reason,
                  fill_height_m=defaults["z"] if layout.height is not None else None,
                  fill_radius_m=defaults["radius"] if layout.radius is not None else None)


def read_csv(path: str | Path, *, units: str | None = None, mount_height_m: float | None = None,
             radius_m: float | None = None) -> Layout:
    """Read a CSV layout: a header row naming ``x``, ``y`` and optionally ``name``, ``z``,
    ``radius``; lines starting with ``#`` are comments (``# unit: mm`` sets the unit)."""
    path = Path(path)
    text = read_text(path, "CSV file")
    unit_in_file = None
    lines, numbers = [], []
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if stripped.startswith("#"):
            key, _, value = stripped[1:].partition(":")
            if key.strip().lower() == "unit":
                unit_in_file = value.strip()
            continue
        if stripped:
            lines.append(line)
            numbers.append(number)
    if not lines:
        raise InputError(f"{path}: no rows; expected a header with x,y and one row per luminaire")
    reader = csv.DictReader(lines)
    try:
        header = [h.strip().lower() for h in reader.fieldnames or []]
    except csv.Error as exc:  # a field over the csv module's limit (128 KiB), a stray NUL
        raise InputError(f"{path}: line {numbers[0]}: not a CSV row ({exc})") from None
    if "x" not in header or "y" not in header:
        raise InputError(f"{path}: line {numbers[0]}: header must name columns x and y (found {', '.join(header)})")
    if len(lines) - 1 > MAX_LUMINAIRES:
        raise InputError(f"{path}: {len(lines) - 1:,} rows, more than the {MAX_LUMINAIRES:,} luminaires one plan "
                         "holds; split the site into several plans")
    unit = units or unit_in_file or "m"
    scale = _unit_scale(unit, str(path))
    defaults = _defaults(mount_height_m, radius_m, None, None, scale)
    lums = []
    for k, raw in enumerate(_rows(reader, path, numbers)):
        number = numbers[k + 1] if k + 1 < len(numbers) else numbers[-1]
        where = f"{path}: line {number}"
        if None in raw:  # DictReader's key for fields beyond the header: a stray comma, e.g. "1,5" for 1.5
            raise InputError(f"{where}: more fields than the header names ({', '.join(header)}); a decimal comma? "
                             "write 1.5, not 1,5")
        cells = {h.strip().lower(): v.strip() for h, v in raw.items() if h and isinstance(v, str)}
        row = _checked(LuminaireRow, {h: v for h, v in cells.items() if v != ""}, where, strict=False)
        lums.append(_luminaire(row, k, scale, defaults, {"file": path.name, "line": number}))
    reason = "given with --units" if units else ("stated in the file" if unit_in_file else "the default")
    return Layout(tuple(lums), None, str(path), unit, reason)


def _rows(reader: csv.DictReader, path: Path, numbers: list[int]) -> Iterator[dict]:
    """The rows of ``reader``; a row the csv module cannot split (a field over its 128 KiB limit, a NUL)
    raises :class:`InputError` naming its line."""
    while True:
        try:
            row = next(reader)
        except StopIteration:
            return
        except csv.Error as exc:
            line = numbers[min(reader.line_num, len(numbers) - 1)]  # the row that failed is not counted
            raise InputError(f"{path}: line {line}: not a CSV row ({exc})") from None
        yield row
