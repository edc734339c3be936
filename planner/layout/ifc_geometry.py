"""What an IFC model's geometry says: a fixture body's LED radius and a storey's room outline.

Both come from ifcopenshell's geometry kernel (``ifcopenshell.geom``): a fixture's body meshed in
its own axes (half the smaller plan side, as a DXF symbol's size), and the storey's ``IfcSpace``
meshes seen from above, joined into the floor as a DXF's rooms are. Results in metres.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from planner.layout.outline import floor_outline

MESH_ANGLE_RAD = 0.02
"""The mesh of a fixture's body turns by at most this between facets: a disc's extent is 0.005 % short."""

MAX_BODY_SIDE_M = 10.0
"""A fixture body whose smaller plan side is this long or longer is no luminaire's size: the default applies."""


def space_outline(model, storey) -> tuple[tuple[tuple[float, float], ...] | None, list[str]]:
    """The floor [m] from the storey's ``IfcSpace`` footprints (their meshes seen from above, joined as a DXF's
    rooms are: :func:`planner.layout.outline.floor_outline`); ``(None, [])`` when the storey has no space."""
    import ifcopenshell.geom
    import ifcopenshell.util.element as element
    import shapely

    spaces = [sp for sp in model.by_type("IfcSpace") if storey is not None and
              storey in (element.get_aggregate(sp), element.get_container(sp))]
    if not spaces:
        return None, []
    settings = ifcopenshell.geom.settings()
    settings.set("use-world-coords", True)
    footprints, failed = [], 0
    for space in spaces:
        try:
            shape: Any = ifcopenshell.geom.create_shape(settings, space)
            verts = np.asarray(shape.geometry.verts, dtype=float).reshape(-1, 3)[:, :2]
            faces = np.asarray(shape.geometry.faces, dtype=np.int64).reshape(-1, 3)
        except Exception:  # a space the kernel cannot mesh: left out, counted in the note
            failed += 1
            continue
        tri = shapely.polygons(verts[faces])
        area = shapely.area(tri)
        joined = shapely.unary_union(tri[area > 1e-9 * max(float(area.max(initial=0.0)), 1e-12)])
        for part in getattr(joined, "geoms", [joined]):
            if part.geom_type == "Polygon" and part.area > 0:
                footprints.append([(float(x), float(y)) for x, y in list(part.exterior.coords)[:-1]])
    outline, notes = floor_outline(footprints, "space footprints")
    if outline is None:
        return None, [f"the storey's {len(spaces)} IfcSpace(s) have no footprint the geometry kernel can mesh: "
                      "poses are sampled over the fixtures' hull"]
    lost = [f"room outline: {failed} of the storey's {len(spaces)} IfcSpaces could not be meshed and are left out"]
    return outline, (lost if failed else []) + (notes or ["room outline: the storey's IfcSpace footprint"])


class BodySizes:
    """Fixture body radii [m], measured once per shared shape (a type's representation map)."""

    def __init__(self) -> None:
        self._known: dict[tuple, float | None] = {}
        self.measured: list[float] = []
        self.missing = 0

    def radius_m(self, fixture) -> float | None:
        key = _shape_key(fixture)
        if key not in self._known:
            self._known[key] = body_radius_m(fixture) if key else None
        r = self._known[key]
        if r is None:
            self.missing += 1
        else:
            self.measured.append(r)
        return r


def _shape_key(fixture) -> tuple:
    """What a fixture's body is built from: equal keys, equal bodies in the fixture's own axes."""
    shape = getattr(fixture, "Representation", None)
    if shape is None:
        return ()
    key: list[tuple] = []
    for rep in shape.Representations or ():
        for item in rep.Items or ():
            if item.is_a("IfcMappedItem"):
                target = item.MappingTarget
                scale = [getattr(target, a, None) for a in ("Scale", "Scale2", "Scale3")] if target else []
                key.append((item.MappingSource.id(), tuple(scale)))
            else:
                key.append((item.id(),))
    return tuple(key)


def body_radius_m(fixture) -> float | None:
    """Half the smaller plan side of the bounding box of the fixture's body in its own axes [m] (a round
    downlight: its radius; a 600 mm square panel: 0.3 m); None without geometry ifcopenshell can mesh."""
    import ifcopenshell.geom

    settings = ifcopenshell.geom.settings()
    settings.set("mesher-angular-deflection", MESH_ANGLE_RAD)
    try:
        shape: Any = ifcopenshell.geom.create_shape(settings, fixture)
        verts = np.asarray(shape.geometry.verts, dtype=float).reshape(-1, 3)
    except Exception:  # no representation, or one the geometry kernel cannot mesh: the default applies
        return None
    if not len(verts) or not np.isfinite(verts).all():
        return None
    sides = np.ptp(verts[:, :2], axis=0)
    side = float(sides.min()) if sides.min() > 0 else float(sides.max())
    return 0.5 * side if 0 < side < MAX_BODY_SIDE_M else None
