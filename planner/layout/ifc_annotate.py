"""Write an annotated IFC: the source model with a property set ``VLP`` on each planned light fixture.

The set holds ``Name`` (the plan's luminaire name, ``L0001``), ``ID``, ``Parity``, ``Region``,
``Label`` (as on the annotated DXF, ``15 o R3``) and ``Tool`` (``vlp-plan <version>``). A
``VLP`` set written by an earlier run is replaced, so annotating an annotated model does not
stack sets. The new entities' GlobalIds are derived from the fixture's, so the output is the
same for the same input.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from planner._files import write_bytes_atomically
from planner.errors import InputError
from planner.layout.dxf_annotate import label
from planner.layout.ifc import open_model
from planner.layout.model import Layout

if TYPE_CHECKING:
    from planner.plan.file import Entry

__all__ = ["write_annotated_ifc", "PSET"]

PSET = "VLP"
"""Name of the property set written on each fixture."""


def _guid(*parts: str) -> str:
    import ifcopenshell.guid

    return ifcopenshell.guid.compress(hashlib.sha256("/".join(parts).encode()).hexdigest()[:32])


def _remove_old(model, fixture) -> None:
    for rel in list(getattr(fixture, "IsDefinedBy", ()) or ()):
        if rel.is_a("IfcRelDefinesByProperties") and getattr(rel.RelatingPropertyDefinition, "Name", None) == PSET:
            pset = rel.RelatingPropertyDefinition
            others = [o for o in rel.RelatedObjects if o != fixture]
            if others:
                rel.RelatedObjects = others
                continue
            model.remove(rel)
            for prop in pset.HasProperties or ():
                model.remove(prop)
            model.remove(pset)


def write_annotated_ifc(dest: str | Path, layout: Layout, entries: Sequence[Entry], *, source_path: str | Path,
                        tool_version: str = "") -> None:
    """Write ``source_path``'s model with a ``VLP`` property set on each fixture the plan holds to ``dest``."""
    dest, source = Path(dest), Path(source_path)
    if dest.resolve() == source.resolve():
        raise InputError(f"{dest}: refusing to overwrite the source model; choose another output directory")
    model = open_model(source)
    by_name = {lum.name: lum.source.get("global_id") for lum in layout.luminaires}
    for entry in entries:
        guid = by_name.get(entry.name)
        if not guid:
            continue
        try:
            fixture = model.by_guid(guid)
        except RuntimeError:
            raise InputError(f"{source}: fixture {guid} ({entry.name}) is no longer in the model; plan it again") from None
        _remove_old(model, fixture)

        def value(kind: str, v):
            return model.create_entity(kind, v)

        props = [("Name", value("IfcLabel", entry.name)), ("ID", value("IfcInteger", int(entry.id))),
                 ("Parity", value("IfcLabel", entry.parity)), ("Region", value("IfcInteger", int(entry.region))),
                 ("Label", value("IfcLabel", label(entry)))]
        if tool_version:
            props.append(("Tool", value("IfcLabel", f"vlp-plan {tool_version}")))
        single = [model.create_entity("IfcPropertySingleValue", Name=n, NominalValue=v) for n, v in props]
        pset = model.create_entity("IfcPropertySet", GlobalId=_guid(guid, PSET, "set"),
                                   OwnerHistory=fixture.OwnerHistory, Name=PSET, HasProperties=single)
        model.create_entity("IfcRelDefinesByProperties", GlobalId=_guid(guid, PSET, "rel"),
                            OwnerHistory=fixture.OwnerHistory, RelatedObjects=[fixture], RelatingPropertyDefinition=pset)
    write_bytes_atomically(dest, model.to_string().encode("utf-8"))
