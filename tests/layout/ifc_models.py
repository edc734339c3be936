"""Build IFC test models with ifcopenshell, the way Revit and ArchiCAD hand them over.

``model(schema, unit, storeys)`` returns ``(ifc_file, expected)`` where ``expected`` maps a storey
name to the ``(N, 3)`` array of its fixtures' positions in metres (x, y, height above the storey's
floor), sorted by (y, x) like the reader names them. Coordinates are written in the project's unit
(``is_si=False``), so the reader's conversion is what the tests check.
"""

from __future__ import annotations

from pathlib import Path

import ifcopenshell
import ifcopenshell.api
import ifcopenshell.api.owner.settings
import numpy as np

PER_M = {"ft": 1 / 0.3048, "mm": 1000.0, "m": 1.0}


def _placement(model, product, xyz_units) -> None:
    matrix = np.eye(4)
    matrix[:3, 3] = xyz_units
    ifcopenshell.api.run("geometry.edit_object_placement", model, product=product, matrix=matrix, is_si=False)


def _body(f, context, per_m: float, body: tuple[str, float]):
    """A fixture body 5 cm deep: ("round", radius [m]) a disc, ("square", side [m]) a panel; SweptSolid."""
    kind, size_m = body
    centre = f.createIfcAxis2Placement2D(f.createIfcCartesianPoint((0.0, 0.0)))  # IFC2X3 requires it
    if kind == "round":
        profile = f.createIfcCircleProfileDef("AREA", None, centre, size_m * per_m)
    else:
        profile = f.createIfcRectangleProfileDef("AREA", None, centre, size_m * per_m, size_m * per_m)
    return _extrusion(f, context, profile, 0.05 * per_m)


def _extrusion(f, context, profile, depth):
    """A body: ``profile`` extruded up by ``depth`` [model units]."""
    solid = f.createIfcExtrudedAreaSolid(profile, f.createIfcAxis2Placement3D(f.createIfcCartesianPoint((0.0, 0.0, 0.0))),
                                         f.createIfcDirection((0.0, 0.0, 1.0)), depth)
    return f.createIfcShapeRepresentation(context, "Body", "SweptSolid", [solid])


def model(schema: str = "IFC4", unit: str = "mm", storeys: dict[str, tuple[float, int, int]] | None = None,
          spacing_m: float = 1.5, height_m: float = 2.7, extras: bool = True, body: tuple[str, float] | None = None,
          spaces: bool = False):
    """A model with ``storeys``: name -> (floor elevation [m], columns, rows) of light fixtures.

    IFC4 fixtures are ``IfcLightFixture``; IFC2X3 ones ``IfcFlowTerminal`` typed by an
    ``IfcLightFixtureType``. ``extras`` adds what is not a light: a flow terminal typed as an air
    terminal and a furniture proxy on the first storey.
    """
    storeys = storeys or {"Level 1": (0.0, 4, 3)}
    per_m = PER_M[unit]
    f = ifcopenshell.file(schema=schema)
    if schema == "IFC2X3":  # every rooted entity needs an owner history, made from a user and an application
        person = ifcopenshell.api.run("owner.add_person", f)
        org = ifcopenshell.api.run("owner.add_organisation", f)
        ifcopenshell.api.run("owner.add_person_and_organisation", f, person=person, organisation=org)
        ifcopenshell.api.run("owner.add_application", f)
        ifcopenshell.api.owner.settings.get_user = lambda file: (file.by_type("IfcPersonAndOrganization") or [None])[0]
        ifcopenshell.api.owner.settings.get_application = lambda file: (file.by_type("IfcApplication") or [None])[0]
    project = ifcopenshell.api.run("root.create_entity", f, ifc_class="IfcProject", name="VLP test")
    if unit == "ft":
        length = ifcopenshell.api.run("unit.add_conversion_based_unit", f, name="foot")
    else:
        length = ifcopenshell.api.run("unit.add_si_unit", f, unit_type="LENGTHUNIT", prefix="MILLI" if unit == "mm" else None)
    ifcopenshell.api.run("unit.assign_unit", f, units=[length])
    context = ifcopenshell.api.run("context.add_context", f, context_type="Model")
    site = ifcopenshell.api.run("root.create_entity", f, ifc_class="IfcSite", name="Site")
    building = ifcopenshell.api.run("root.create_entity", f, ifc_class="IfcBuilding", name="Building")
    ifcopenshell.api.run("aggregate.assign_object", f, products=[site], relating_object=project)
    ifcopenshell.api.run("aggregate.assign_object", f, products=[building], relating_object=site)
    for product in (site, building):
        _placement(f, product, (0, 0, 0))
    light_type = None
    if schema == "IFC2X3":
        light_type = ifcopenshell.api.run("root.create_entity", f, ifc_class="IfcLightFixtureType", name="Downlight 150")
    shape = _body(f, context, per_m, body) if body else None
    if shape is not None and light_type is not None:  # the type holds the shape; assign_type maps it to each fixture
        ifcopenshell.api.run("geometry.assign_representation", f, product=light_type, representation=shape)
    expected = {}
    for s_index, (name, (elevation_m, cols, rows)) in enumerate(storeys.items()):
        storey = ifcopenshell.api.run("root.create_entity", f, ifc_class="IfcBuildingStorey", name=name)
        storey.Elevation = elevation_m * per_m
        ifcopenshell.api.run("aggregate.assign_object", f, products=[storey], relating_object=building)
        _placement(f, storey, (0, 0, elevation_m * per_m))
        xyz = []
        for j in range(rows):
            for i in range(cols):
                x, y = 1.0 + i * spacing_m, 1.0 + j * spacing_m + 0.25 * s_index
                cls = "IfcLightFixture" if schema != "IFC2X3" else "IfcFlowTerminal"
                fixture = ifcopenshell.api.run("root.create_entity", f, ifc_class=cls, name=f"Downlight:{s_index}{j}{i}")
                ifcopenshell.api.run("spatial.assign_container", f, products=[fixture], relating_structure=storey)
                _placement(f, fixture, (x * per_m, y * per_m, (elevation_m + height_m) * per_m))
                if light_type is not None:
                    ifcopenshell.api.run("type.assign_type", f, related_objects=[fixture], relating_type=light_type)
                if shape is not None and light_type is None:
                    fixture.Representation = f.createIfcProductDefinitionShape(None, None, [shape])
                xyz.append((x, y, height_m))
        arr = np.array(xyz)
        expected[name] = arr[np.lexsort((arr[:, 0], arr[:, 1]))]
        if spaces:
            lo, hi = arr[:, :2].min(axis=0) - 1.0, arr[:, :2].max(axis=0) + 1.0
            middle = 0.5 * (lo[0] + hi[0])
            for k, (x0, x1) in enumerate(((lo[0], middle), (middle, hi[0]))):
                room = ifcopenshell.api.run("root.create_entity", f, ifc_class="IfcSpace", name=f"Room {k + 1}")
                ifcopenshell.api.run("aggregate.assign_object", f, products=[room], relating_object=storey)
                _placement(f, room, (x0 * per_m, lo[1] * per_m, elevation_m * per_m))
                room.Representation = f.createIfcProductDefinitionShape(None, None, [_extrusion(
                    f, context, f.createIfcRectangleProfileDef(
                        "AREA", None, f.createIfcAxis2Placement2D(f.createIfcCartesianPoint(
                            ((x1 - x0) / 2 * per_m, (hi[1] - lo[1]) / 2 * per_m))), (x1 - x0) * per_m,
                        (hi[1] - lo[1]) * per_m), 3.0 * per_m)])
        if extras and s_index == 0:
            if schema == "IFC2X3":
                terminal = ifcopenshell.api.run("root.create_entity", f, ifc_class="IfcFlowTerminal", name="Diffuser")
                air = ifcopenshell.api.run("root.create_entity", f, ifc_class="IfcAirTerminalType", name="Diffuser")
                ifcopenshell.api.run("type.assign_type", f, related_objects=[terminal], relating_type=air)
            else:
                terminal = ifcopenshell.api.run("root.create_entity", f, ifc_class="IfcAirTerminal", name="Diffuser")
            proxy = ifcopenshell.api.run("root.create_entity", f, ifc_class="IfcBuildingElementProxy", name="Desk lamp")
            for product in (terminal, proxy):
                ifcopenshell.api.run("spatial.assign_container", f, products=[product], relating_structure=storey)
                _placement(f, product, (0.5 * per_m, 0.5 * per_m, (elevation_m + 2.7) * per_m))
    return f, expected


def save(ifc_file, path: str | Path) -> Path:
    path = Path(path)
    ifc_file.write(str(path))
    return path
