"""Read the light fixtures of one building storey from an IFC model (Revit, ArchiCAD, any BIM tool).

A light fixture is an ``IfcLightFixture`` (IFC4) or an ``IfcFlowTerminal`` typed by an
``IfcLightFixtureType`` (IFC2X3, and IFC4 models written the old way). Its position is the
origin of its placement, composed through every relative placement to the world, converted
from the project's length unit (feet, millimetres...) to metres once; its mounting height is
that Z above the storey's own placement (the floor it stands on); its radius is half the
smaller plan side of its body's bounding box (ifcopenshell's geometry, in its own axes), as a
DXF symbol's. Fixtures are grouped by the storey that contains them; when more than one
storey holds fixtures, ``storey`` chooses.
``docs/ifc.md`` describes the rules for users.
"""

from __future__ import annotations

import re
from collections import defaultdict
from pathlib import Path

import numpy as np

from planner.defaults import MAX_HEIGHT_M, UNIT_TO_M
from planner.errors import InputError, UsageError
from planner.layout.dxf_units import HEIGHT_RANGE_M
from planner.layout.ifc_geometry import BodySizes, space_outline
from planner.layout.model import DEFAULT_MOUNT_HEIGHT_M, DEFAULT_RADIUS_M, Layout, Luminaire

__all__ = ["read_ifc", "open_model", "light_fixtures", "storey_of", "storey_key", "pick_storey"]

_NO_STOREY = "(no storey)"

def open_model(path: str | Path):
    """The IFC model of ``path``; a file ifcopenshell cannot parse raises :class:`InputError`."""
    import ifcopenshell

    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise InputError(f"{path}: cannot read the file ({exc.strerror or exc}); check its permissions") from None
    if data.strip() and b"END-ISO-10303-21" not in data[-256:].upper():  # ifcopenshell reads a cut-off file silently
        raise InputError(f"{path}: the model ends before END-ISO-10303-21; (cut off in a copy or a download?); "
                         "export or copy it again")
    _check_references(data, path)
    try:
        return ifcopenshell.open(str(path))
    except Exception as exc:  # ifcopenshell raises its own and plain errors alike: not an IFC we can read
        raise InputError(f"{path}: not a readable IFC model ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__}); "
                         "export the model as IFC2X3 or IFC4 (STEP, .ifc)") from None


def _check_references(data: bytes, path: str | Path) -> None:
    """:class:`InputError` if an entity refers to one the file does not define (``#12`` with no ``#12=``):
    ifcopenshell reads such a file and hands back None where the placement or shape should be."""
    body = re.sub(rb"'(?:[^']|'')*'", b"''", data)  # references inside text ('Room #4') are no references
    defined = set(re.findall(rb"^\s*#(\d+)\s*=", body, re.M))
    dangling = set(re.findall(rb"#(\d+)", body)) - defined
    if dangling:
        first = min(dangling, key=int).decode()
        raise InputError(f"{path}: refers to #{first}, which the model does not define ({len(dangling)} such "
                         "reference(s)); the file was damaged or edited by hand; export the model again")


def light_fixtures(model) -> list:
    """Every light fixture of the model: ``IfcLightFixture``, and ``IfcFlowTerminal`` typed by ``IfcLightFixtureType``."""
    import ifcopenshell.util.element as element

    found = []
    try:
        found += list(model.by_type("IfcLightFixture"))
    except RuntimeError:  # IFC2X3 has no such entity
        pass
    for terminal in model.by_type("IfcFlowTerminal"):
        kind = element.get_type(terminal)
        if kind is not None and kind.is_a("IfcLightFixtureType") and not terminal.is_a("IfcLightFixture"):
            found.append(terminal)
    return sorted(found, key=lambda e: e.id())


def storey_of(entity):
    """The ``IfcBuildingStorey`` that contains ``entity`` (directly or through its space), or None."""
    import ifcopenshell.util.element as element

    return element.get_container(entity, ifc_class="IfcBuildingStorey") or element.get_container(entity)


def storey_key(storey) -> str:
    """A storey's name in messages and sources (its GlobalId if unnamed; ``(no storey)`` for None)."""
    return _NO_STOREY if storey is None else (storey.Name or storey.GlobalId)


def _storey_z(storey, scale: float) -> float:
    """World Z of a storey's floor [m]: its placement, else its Elevation attribute, else 0."""
    import ifcopenshell.util.placement as placement

    if storey is None:
        return 0.0
    if getattr(storey, "ObjectPlacement", None) is not None:
        return float(placement.get_local_placement(storey.ObjectPlacement)[2, 3]) * scale
    return float(storey.Elevation or 0.0) * scale


def pick_storey(groups: dict, storey: str | None, scale: float, where: str) -> str:
    """The storey key to read: the one ``storey`` names (name or elevation [m]), or the only one with fixtures."""
    def listing() -> str:
        return ", ".join(f"{key!r} ({len(items)} fixtures, floor at {_storey_z(items[0][1], scale):.2f} m)"
                         for key, items in sorted(groups.items(), key=lambda kv: _storey_z(kv[1][0][1], scale)))

    if storey is None:
        if len(groups) == 1:
            return next(iter(groups))
        raise InputError(f"{where}: {len(groups)} storeys hold light fixtures: {listing()}; choose one with `storey` NAME")
    wanted = storey.strip().casefold()
    for key in groups:
        if key.casefold() == wanted:
            return key
    try:
        elevation = float(storey)
    except ValueError:
        elevation = None
    if elevation is not None:
        for key, items in groups.items():
            if abs(_storey_z(items[0][1], scale) - elevation) < 0.01:
                return key
    raise InputError(f"{where}: `storey` {storey!r} holds no light fixtures; storeys with fixtures: {listing()}")


def read_ifc(path: str | Path, *, storey: str | None = None, mount_height_m: float | None = None,
             radius_m: float | None = None, units: str | None = None) -> Layout:
    """Read one storey's light fixtures into a :class:`Layout` (positions [m]).

    Parameters
    ----------
    path : str or Path
        The ``.ifc`` file (IFC2X3 or IFC4).
    storey : str, optional
        The storey's name (case-insensitive) or floor elevation [m]; needed when several hold fixtures.
    mount_height_m : float, optional
        Mounting height where a fixture's height above its storey is not plausible (below 1.5 m) [m].
    radius_m : float, optional
        LED radius [m]; default: the fixture body's (:func:`planner.layout.ifc_geometry.body_radius_m`), else ``DEFAULT_RADIUS_M``.
    units : str, optional
        Not accepted: an IFC model states its units.
    """
    import ifcopenshell.util.placement as placement
    import ifcopenshell.util.unit as ifc_unit

    path = Path(path)
    where = str(path)
    if units is not None:
        raise UsageError(f"`units` does not apply to {path.name}: an IFC model states its own length unit")
    for param, value in (("`mount_height_m`", mount_height_m), ("`radius_m`", radius_m)):
        if value is not None and not value > 0:
            raise UsageError(f"{param} {value} m must be positive")
    model = open_model(path)
    scale = float(ifc_unit.calculate_unit_scale(model))
    if not scale > 0:
        raise InputError(f"{where}: the project's length unit is not usable (scale {scale:g}); fix the model's units")
    fixtures = light_fixtures(model)
    if not fixtures:
        counts = {name: len(model.by_type(name)) for name in ("IfcFlowTerminal", "IfcBuildingElementProxy")}
        raise InputError(f"{where}: no light fixture (IfcLightFixture, or IfcFlowTerminal typed by IfcLightFixtureType) "
                         f"in this {model.schema} model; it holds {counts['IfcFlowTerminal']} other flow terminals and "
                         f"{counts['IfcBuildingElementProxy']} proxies; export the lighting as light fixtures")
    groups: dict[str, list] = defaultdict(list)
    for fixture in fixtures:
        home = storey_of(fixture)
        groups[storey_key(home)].append((fixture, home))
    key = pick_storey(groups, storey, scale, where)
    chosen = groups[key]
    floor_z = _storey_z(chosen[0][1], scale)
    height = mount_height_m if mount_height_m is not None else DEFAULT_MOUNT_HEIGHT_M
    sizes = BodySizes()
    rows, implausible = [], []
    for fixture, _ in chosen:
        if fixture.ObjectPlacement is None:
            raise InputError(f"{where}: light fixture #{fixture.id()} {fixture.GlobalId} has no placement; place it "
                             "in the model")
        at = placement.get_local_placement(fixture.ObjectPlacement)[:3, 3] * scale
        if not np.isfinite(at).all():
            raise InputError(f"{where}: light fixture {fixture.GlobalId} has a placement that is not a number")
        z = float(at[2]) - floor_z
        if not HEIGHT_RANGE_M[0] <= z <= MAX_HEIGHT_M:
            implausible.append(z)
            z = height
        source = {"file": path.name, "global_id": fixture.GlobalId, "entity": fixture.is_a(), "storey": key}
        if fixture.Name:
            source["ifc_name"] = str(fixture.Name)
        kind = _type_name(fixture)
        if kind:
            source["type"] = kind
        body = sizes.radius_m(fixture) if radius_m is None else None
        rows.append((round(float(at[1]) * 1000), round(float(at[0]) * 1000), fixture.GlobalId, float(at[0]),
                     float(at[1]), z, radius_m if radius_m is not None else body or DEFAULT_RADIUS_M, source))
    rows.sort(key=lambda row: row[:3])
    luminaires = tuple(Luminaire(f"L{i + 1:04d}", x, y, z, r, src) for i, (*_, x, y, z, r, src) in enumerate(rows))
    unit = next((u for u, m in UNIT_TO_M.items() if abs(m - scale) < 1e-9 * m), "m")
    reason = f"stated by the {model.schema} model ({scale:g} m per unit)"
    notes = [f"storey {key!r}: {len(chosen)} light fixtures, floor at {floor_z:.3f} m"]
    if len(groups) > 1:
        notes.append("other storeys left out: " + ", ".join(f"{k!r} ({len(v)})" for k, v in groups.items() if k != key))
    if implausible:
        given = "given" if mount_height_m is not None else "default; set with --height"
        notes.append(f"{len(implausible)} fixture(s) sit {implausible[0]:.3g} m above the storey's floor, no plausible "
                     f"mounting height; used {height:g} m ({given})")
    if radius_m is None and sizes.measured:
        radii = sorted({round(r, 4) for r in sizes.measured})
        notes.append(f"LED radius from the fixtures' geometry: {', '.join(f'{r:g}' for r in radii[:4])}"
                     f"{' ...' if len(radii) > 4 else ''} m (half the smaller side of each body; set with --radius)")
    if radius_m is None and sizes.missing:
        notes.append(f"{sizes.missing} fixture(s) have no geometry to measure; LED radius {DEFAULT_RADIUS_M:g} m "
                     "(default; set with --radius)")
    outline, outline_notes = space_outline(model, chosen[0][1])
    return Layout(luminaires, outline, where, unit, reason, tuple(notes + outline_notes))


def _type_name(fixture) -> str | None:
    import ifcopenshell.util.element as element

    kind = element.get_type(fixture)
    return str(kind.Name) if kind is not None and kind.Name else None
