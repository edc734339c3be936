"""One walk over a DXF model space: the luminaire parts taken, what was rejected and why, room candidates.

Each INSERT is classified as a whole by :class:`~planner.layout.dxf_names.Selector`: a
luminaire (one part at its base point; its block is not searched), rejected (nothing
inside it is taken), or a container, entered with the composed transform of every level
(insertion point, base point, scale, rotation, extrusion). Entities on layer ``0`` inside
a block take the layer of the INSERT that places them. Positions stay in drawing units.
"""

from __future__ import annotations

import fnmatch
import re
from collections import Counter
from dataclasses import dataclass, field

import ezdxf
from ezdxf import bbox, dynblkhelper
from ezdxf.math import Matrix44, Vec3

from planner.layout.dxf_names import Selector

OUTLINE_LAYERS = ("*WALL*", "*ROOM*", "*OUTLINE*", "A-AREA*", "DLX_*ROOM*")
"""Layers whose closed polylines are room-outline candidates (fnmatch, case-insensitive)."""

_MAX_DEPTH = 16  # block nesting depth followed; deeper (or cyclic) references are ignored
MAX_VISITS = 2_000_000
"""Most entities one walk visits, those inside blocks once per reference (blocks nesting blocks multiply: ten
levels of ten references are ten billion); about a minute of walking."""
MAX_PARTS = 400_000
"""Most luminaire parts taken: four per luminaire at :data:`planner.defaults.MAX_LUMINAIRES`."""


class WalkTooLong(Exception):
    """The walk passed :data:`MAX_VISITS` or :data:`MAX_PARTS`; the message says which (the caller adds the file)."""
_REVIT_APPID = "REVIT"
_NOT_GEOMETRY = frozenset({"TEXT", "MTEXT", "ATTDEF", "ATTRIB", "DIMENSION", "LEADER", "MULTILEADER", "POINT"})
_TEXTS = frozenset({"TEXT", "MTEXT", "ATTDEF", "ATTRIB"})
_LEADERS = frozenset({"DIMENSION", "LEADER", "MULTILEADER", "MLEADER", "ARC_DIMENSION", "RADIAL_DIMENSION"})


@dataclass
class Part:
    """One taken entity: position, circle radius and symbol size in drawing units (WCS)."""

    xyz: tuple[float, float, float]
    radius: float | None
    """Radius of the CIRCLE (or the largest circle drawn directly in the block), if any."""
    size: float | None
    """Half the smaller side of the block's drawn geometry (no circle needed), if any."""
    source: dict
    group: str
    """What the part is, for choosing among groups: the block name, or ``CIRCLE on LAYER``."""


@dataclass
class Outline:
    """A closed polyline on a wall or room layer [drawing units]."""

    points: list[tuple[float, float]]
    layer: str
    handle: str


@dataclass
class Scan:
    """What a walk over the model space found."""

    file: str
    selector: Selector
    parts: list[Part] = field(default_factory=list)
    outlines: list[Outline] = field(default_factory=list)
    segments: list[list[tuple[float, float]]] = field(default_factory=list)
    """Open polylines and lines on wall and room layers (walls drawn piece by piece) [drawing units]."""
    texts: list[tuple[str, tuple[float, float]]] = field(default_factory=list)
    """Plain text of every TEXT and MTEXT with its WCS position (room names)."""
    layers_seen: Counter = field(default_factory=Counter)
    blocks_seen: Counter = field(default_factory=Counter)
    taken: Counter = field(default_factory=Counter)
    """(what, name, layer, why) -> count of the parts taken."""
    rejected: Counter = field(default_factory=Counter)
    """(what, name, layer, why) -> count of the entities rejected (with all they hold)."""
    rejected_at: list[tuple[float, float, str]] = field(default_factory=list)
    """WCS plan position and name of every rejected entity (for pictures) [drawing units]."""
    visits: int = 0
    _decisions: dict[tuple[str, str | None], tuple[str, str]] = field(default_factory=dict)
    _block_radius: dict[str, float | None] = field(default_factory=dict)
    _block_size: dict[str, float | None] = field(default_factory=dict)
    _holds_blocks: dict[str, bool] = field(default_factory=dict)
    _annotation: dict[str, bool] = field(default_factory=dict)


    def decide(self, layer: str, block: str | None) -> tuple[str, str]:
        """The selector's decision for an INSERT of ``block`` (``None``: a CIRCLE or POINT) on ``layer``, once per
        name pair (a drawing of 100,000 luminaires has a handful)."""
        key = (layer, block)
        if key not in self._decisions:
            self._decisions[key] = self.selector.entity(layer) if block is None else self.selector.insert(layer, block)
        return self._decisions[key]


def scan(file: str, selector: Selector, msp) -> Scan:
    """Walk ``msp`` (the model space) with ``selector``."""
    result = Scan(file, selector)
    _walk(result, msp, None, None, ())
    return result


def outline_layer(layer: str) -> bool:
    """Whether closed polylines on ``layer`` are room-outline candidates."""
    upper = layer.upper()
    return any(fnmatch.fnmatchcase(upper, p) for p in OUTLINE_LAYERS)


def _scale(m: Matrix44 | None) -> float:
    """Mean plan scale of a transform [drawing units per block unit]."""
    if m is None:
        return 1.0
    return 0.5 * (m.transform_direction(Vec3(1, 0, 0)).magnitude + m.transform_direction(Vec3(0, 1, 0)).magnitude)


def _element_id(entity) -> int | str | None:
    """Revit element id from XDATA under appid ``REVIT``, if any."""
    if not entity.has_xdata(_REVIT_APPID):
        return None
    tags = entity.get_xdata(_REVIT_APPID)
    numbers = [int(value) for code, value in tags if code in (1070, 1071)]
    texts = [str(value).strip() for code, value in tags if code == 1000 and str(value).strip()]
    if numbers:
        return numbers[0]
    for text in texts:  # e.g. "123456" or "ElementId 123456"
        digits = re.search(r"(\d+)\s*$", text)
        if digits:
            return int(digits.group(1))
    return texts[0] if texts else None


def _source(s: Scan, entity, kind: str, layer: str, ancestry: tuple) -> dict:
    src: dict = {"file": s.file, "handle": entity.dxf.handle, "layer": layer, "entity": kind}
    for holder in (entity, *reversed(ancestry)):
        element = _element_id(holder)
        if element is not None:
            src["element_id"] = element
            break
    if ancestry:
        src["parent"] = ancestry[0].dxf.handle
    return src


def _walk(s: Scan, entities, m: Matrix44 | None, inherited: str | None, ancestry: tuple) -> None:
    """Collect luminaire parts and outline candidates; ``m`` maps these entities to WCS."""
    for entity in entities:
        s.visits += 1
        if s.visits > MAX_VISITS or len(s.parts) > MAX_PARTS:
            raise WalkTooLong(
                f"more than {MAX_PARTS:,} luminaire parts taken (4 per luminaire at the limit)" if len(s.parts) > MAX_PARTS
                else f"its blocks, each reference walked, hold more than {MAX_VISITS:,} entities (blocks nested in "
                     f"blocks multiply: {ancestry[0].dxf.name if ancestry else 'the model space'} ...)")
        try:
            layer = entity.dxf.get("layer", "0")
        except ezdxf.DXFError:  # an entity type ezdxf does not know (a damaged or foreign file): not ours
            continue
        if inherited is not None and layer == "0":
            layer = inherited  # entities on layer 0 inside a block take the INSERT's layer
        kind = entity.dxftype()
        if not ancestry or kind in ("INSERT", "CIRCLE", "POINT"):
            s.layers_seen[layer] += 1  # inside blocks, count only what could be a luminaire
        if kind == "INSERT":
            _visit_insert(s, entity, layer, m, ancestry)
        elif kind in ("CIRCLE", "POINT"):
            action, why = s.decide(layer, None)
            if action == "reject":
                s.rejected[(kind, "", layer, why)] += 1
                at = Vec3(entity.dxf.center if kind == "CIRCLE" else entity.dxf.location)
                at = m.transform(at) if m is not None else at
                s.rejected_at.append((at.x, at.y, f"{kind} on {layer}"))
            if action != "take":
                continue
            if kind == "CIRCLE":
                centre, radius = entity.ocs().to_wcs(entity.dxf.center), entity.dxf.radius * _scale(m)
            else:
                centre, radius = Vec3(entity.dxf.location), None
            centre = m.transform(centre) if m is not None else centre
            s.taken[(kind, "", layer, why)] += 1
            s.parts.append(Part(centre.xyz, radius, None, _source(s, entity, kind, layer, ancestry),
                                f"{kind} on {layer}"))
        elif kind in ("TEXT", "MTEXT"):
            _text(s, entity, kind, m)
        elif kind in ("LWPOLYLINE", "POLYLINE", "LINE") and outline_layer(layer):
            points, closed = _polyline_points(entity)
            points = list(m.transform_vertices(points)) if m is not None else points
            if closed:
                s.outlines.append(Outline([(p.x, p.y) for p in points], layer, entity.dxf.handle))
            elif len(points) >= 2:
                s.segments.append([(p.x, p.y) for p in points])


def _text(s: Scan, entity, kind: str, m: Matrix44 | None) -> None:
    try:
        text = entity.plain_text() if kind == "MTEXT" else entity.dxf.text
        at = entity.ocs().to_wcs(Vec3(entity.dxf.insert)) if kind == "TEXT" else Vec3(entity.dxf.insert)
    except (ezdxf.DXFError, AttributeError, TypeError, ValueError):
        return
    at = m.transform(at) if m is not None else at
    s.texts.append((" ".join(str(text).split()), (at.x, at.y)))


def _effective_name(insert) -> str:
    """The block name a user sees: for an anonymous block (``*U12``) drawing a dynamic block, the dynamic
    block's name (AutoCAD's EffectiveName), else the referenced name."""
    name = insert.dxf.name
    if not name.startswith("*"):
        return name
    try:
        definition = dynblkhelper.get_dynamic_block_definition(insert)
    except (ezdxf.DXFError, AttributeError, KeyError):
        return name
    return definition.name if definition is not None else name


def _visit_insert(s: Scan, insert, layer: str, m: Matrix44 | None, ancestry: tuple) -> None:
    name = _effective_name(insert)
    s.blocks_seen[name] += 1
    block = insert.block()
    action, why = s.decide(layer, name)
    if action == "take" and not why.startswith("block matches") and _annotation_only(s, block):
        action, why = "reject", "block draws only text, leaders or arrowheads"
    if action == "reject" and why.startswith("layer") and _holds_blocks(s, block):
        action, why = "enter", ""  # a neutral block holding blocks is a container, whatever its layer says
    if action == "reject":
        s.rejected[("INSERT", name, layer, why)] += max(1, insert.mcount)
        at = m.transform(Vec3(insert.dxf.insert)) if m is not None else Vec3(insert.dxf.insert)
        s.rejected_at.append((at.x, at.y, name))
        return
    if action == "enter" and (block is None or len(ancestry) >= _MAX_DEPTH):
        return
    copies = list(insert.multi_insert()) if insert.mcount > 1 else [insert]
    for index, copy in enumerate(copies):
        world = copy.matrix44() if m is None else copy.matrix44() * m
        if action == "enter":
            _walk(s, block, world, layer, ancestry + (insert,))
            continue
        base = block.block.dxf.base_point if block is not None else Vec3()
        radius, size = _block_radius(s, block), _block_size(s, block)
        src = _source(s, insert, "INSERT", layer, ancestry)
        src["block"] = name
        if name != insert.dxf.name:
            src["anonymous_block"] = insert.dxf.name
        if len(copies) > 1:
            src["array_index"] = index
        scale = _scale(world)
        s.taken[("INSERT", name, layer, why)] += 1
        s.parts.append(Part(world.transform(base).xyz, None if radius is None else radius * scale,
                            None if size is None else size * scale, src, name))


def _holds_blocks(s: Scan, block) -> bool:
    """Whether a block definition holds INSERTs (it groups other symbols)."""
    if block is None:
        return False
    if block.name not in s._holds_blocks:
        s._holds_blocks[block.name] = any(e.dxftype() == "INSERT" for e in block)
    return s._holds_blocks[block.name]


def _arrowhead(entity) -> bool:
    """A filled triangle (``SOLID``/``TRACE`` with its last two corners equal) or a tapered polyline: an arrow's head."""
    kind = entity.dxftype()
    if kind in ("SOLID", "TRACE"):
        third = entity.dxf.get("vtx2")
        return third is not None and Vec3(third).isclose(Vec3(entity.dxf.get("vtx3", third)))
    if kind == "LWPOLYLINE":
        return any(start != end for _, _, start, end, _ in entity.get_points("xyseb"))
    return False


def _annotation_only(s: Scan, block, depth: int = 0) -> bool:
    """Whether a block draws only annotation: texts alone, or leaders, arrowheads, lines and texts with no
    closed shape (a tag's arrow). Nested blocks count by what they draw."""
    if block is None or depth > _MAX_DEPTH:
        return False
    if block.name not in s._annotation:
        s._annotation[block.name] = False  # a cyclic reference is no annotation
        kinds, marks = set(), False
        for e in block:
            kind = e.dxftype()
            if kind == "INSERT":
                nested = _annotation_only(s, e.block(), depth + 1)
                kinds.add("TEXT" if nested else "INSERT")
                marks |= nested
                continue
            kinds.add(kind)
            marks |= kind in _LEADERS or _arrowhead(e)
        texts_only = bool(kinds) and kinds <= _TEXTS
        leader = marks and kinds <= _TEXTS | _LEADERS | {"LINE", "SOLID", "TRACE", "LWPOLYLINE"} and not any(
            e.dxftype() == "LWPOLYLINE" and e.closed and not _arrowhead(e) for e in block)
        s._annotation[block.name] = texts_only or leader
    return s._annotation[block.name]


def _block_radius(s: Scan, block) -> float | None:
    """Largest CIRCLE radius drawn directly in a block definition [block units]."""
    if block is None:
        return None
    if block.name not in s._block_radius:
        radii = [e.dxf.radius for e in block if e.dxftype() == "CIRCLE"]
        s._block_radius[block.name] = max(radii) if radii else None
    return s._block_radius[block.name]


def _block_size(s: Scan, block) -> float | None:
    """Half the smaller side of the bounding box of a block's drawn geometry (texts left out), or half
    the larger side when the geometry is a line [block units]; None when nothing is drawn."""
    if block is None:
        return None
    if block.name not in s._block_size:
        size = None
        try:
            box = bbox.extents((e for e in block if e.dxftype() not in _NOT_GEOMETRY), fast=True)
        except Exception:  # damaged or unsupported geometry: no size, the default applies
            box = None
        if box is not None and box.has_data:
            w, h = box.size.x, box.size.y
            side = min(w, h) if min(w, h) > 0 else max(w, h)
            size = 0.5 * side if side > 0 else None
        s._block_size[block.name] = size
    return s._block_size[block.name]


def _polyline_points(entity) -> tuple[list[Vec3], bool]:
    """WCS vertices of a line or 2D/3D polyline and whether it is closed (closing duplicate dropped; a
    closed one has at least 3 corners); ``([], False)`` for other polylines (meshes)."""
    if entity.dxftype() == "LINE":
        return [Vec3(entity.dxf.start), Vec3(entity.dxf.end)], False
    if entity.dxftype() == "LWPOLYLINE":
        points = list(entity.vertices_in_wcs())
        closed = entity.closed
    elif entity.is_2d_polyline or entity.is_3d_polyline:
        points = list(entity.points_in_wcs())
        closed = entity.is_closed
    else:
        return [], False
    if len(points) > 1 and points[0].isclose(points[-1]):
        points, closed = points[:-1], True
    return points, closed and len(points) >= 3
