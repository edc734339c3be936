"""Read YAML and CSV layout files into a :class:`~planner.layout.model.Layout`.

Both formats are documented in ``docs/layout-files.md``. Coordinates are in
``unit`` (default metres) and converted to metres here, once.
"""

from __future__ import annotations

import csv
from pathlib import Path

from planner._files import load_yaml, read_text
from planner.defaults import UNIT_TO_M
from planner.errors import InputError
from planner.layout.model import DEFAULT_MOUNT_HEIGHT_M, DEFAULT_RADIUS_M, Layout, Luminaire

_FIELDS = {"name", "x", "y", "z", "radius"}


def _unit_scale(unit: str, where: str) -> float:
    try:
        return UNIT_TO_M[unit]
    except KeyError:
        raise InputError(f"{where}: unknown unit {unit!r}; use one of {', '.join(UNIT_TO_M)}") from None


def _number(value, where: str, field: str) -> float:
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{where}: field {field!r} must be a number, got {value!r}") from None
    if out != out or out in (float("inf"), float("-inf")):
        raise InputError(f"{where}: field {field!r} must be finite, got {value!r}")
    return out


def _luminaire(row: dict, k: int, scale: float, where: str, defaults: dict, source: dict) -> Luminaire:
    unknown = set(row) - _FIELDS - {"id"}
    if unknown:
        raise InputError(f"{where}: unknown field {sorted(unknown)[0]!r}; allowed: {', '.join(sorted(_FIELDS))}")
    for key in ("x", "y"):
        if row.get(key) in (None, ""):
            raise InputError(f"{where}: missing {key!r}; every luminaire needs x and y")
    z = row.get("z")
    z_m = _number(z, where, "z") * scale if z not in (None, "") else defaults["z"]
    r = row.get("radius")
    r_m = _number(r, where, "radius") * scale if r not in (None, "") else defaults["radius"]
    name = str(row.get("name") or f"L{k + 1:04d}").strip()
    return Luminaire(
        name, _number(row["x"], where, "x") * scale, _number(row["y"], where, "y") * scale, z_m, r_m, source
    )


def _defaults(mount_height_m: float | None, radius_m: float | None, doc: dict, scale: float, where: str):
    z = doc.get("height")
    r = doc.get("radius")
    return {
        "z": mount_height_m if mount_height_m is not None
        else _number(z, where, "height") * scale if z is not None else DEFAULT_MOUNT_HEIGHT_M,
        "radius": radius_m if radius_m is not None
        else _number(r, where, "radius") * scale if r is not None else DEFAULT_RADIUS_M,
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
    unit = units or str(doc.get("unit", "m"))
    scale = _unit_scale(unit, str(path))
    defaults = _defaults(mount_height_m, radius_m, doc, scale, str(path))
    rows = doc.get("luminaires") or []
    if not isinstance(rows, list):
        raise InputError(f"{path}: 'luminaires' must be a list of mappings")
    lums = []
    for k, row in enumerate(rows):
        where = f"{path}: luminaires[{k}]"
        if not isinstance(row, dict):
            raise InputError(f"{where}: expected a mapping with x and y")
        lums.append(_luminaire(row, k, scale, where, defaults, {"file": path.name, "index": k}))
    outline = None
    if doc.get("outline") is not None:
        try:
            outline = tuple((float(x) * scale, float(y) * scale) for x, y in doc["outline"])
        except (TypeError, ValueError):
            raise InputError(f"{path}: 'outline' must be a list of [x, y] points") from None
        if len(outline) < 3:
            raise InputError(f"{path}: 'outline' needs at least 3 points")
    reason = "given with --units" if units else ("stated in the file" if "unit" in doc else "the default")
    return Layout(tuple(lums), outline, str(path), unit, reason,
                  fill_height_m=defaults["z"] if doc.get("height") is not None else None,
                  fill_radius_m=defaults["radius"] if doc.get("radius") is not None else None)


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
    header = [h.strip().lower() for h in reader.fieldnames or []]
    if "x" not in header or "y" not in header:
        raise InputError(f"{path}: line {numbers[0]}: header must name columns x and y (found {', '.join(header)})")
    unit = units or unit_in_file or "m"
    scale = _unit_scale(unit, str(path))
    defaults = _defaults(mount_height_m, radius_m, {}, scale, str(path))
    lums = []
    for k, raw in enumerate(reader):
        number = numbers[k + 1] if k + 1 < len(numbers) else numbers[-1]
        where = f"{path}: line {number}"
        if None in raw:  # DictReader's key for fields beyond the header: a stray comma, e.g. "1,5" for 1.5
            raise InputError(f"{where}: more fields than the header names ({', '.join(header)}); a decimal comma? "
                             "write 1.5, not 1,5")
        row = {h.strip().lower(): (v.strip() if isinstance(v, str) else v) for h, v in raw.items() if h}
        lums.append(_luminaire(row, k, scale, where, defaults, {"file": path.name, "line": number}))
    reason = "given with --units" if units else ("stated in the file" if unit_in_file else "the default")
    return Layout(tuple(lums), None, str(path), unit, reason)
