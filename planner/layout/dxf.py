"""Read luminaires and the room outline from a DXF drawing (DIALux, Revit, AutoCAD).

Luminaires are INSERTs (MINSERT arrays included), CIRCLEs or POINTs whose layer or
block name matches a preset's patterns; INSERTs that do not match are entered, so
luminaires nested in other blocks are found with their composed transform. Every
position is taken in WCS, converted to metres once (:mod:`planner.layout.dxf_units`
decides the unit), parts drawn at one point are merged, and the result is a
:class:`~planner.layout.model.Layout` with luminaires named ``L0001``... in plan order.
``docs/dxf.md`` describes the rules for users.
"""

from __future__ import annotations

import fnmatch
import re
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import cast

import ezdxf
import numpy as np
from ezdxf import recover
from ezdxf.document import Drawing
from ezdxf.lldxf.validator import is_binary_dxf_file, is_dwg_file, is_dxf_file
from ezdxf.math import Matrix44, Vec3
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from planner.defaults import MAX_EXTENT_M, UNIT_TO_M
from planner.errors import InputError, UsageError
from planner.layout.dxf_units import Figures, choose_unit
from planner.layout.model import DEFAULT_MOUNT_HEIGHT_M, DEFAULT_RADIUS_M, Layout, Luminaire, area_m2

__all__ = ["read_dxf", "load_drawing", "PRESETS", "UNIT_TO_M", "OUTLINE_LAYERS"]

_GENERIC = ("*LUM*", "*LITE*", "*LIGHT*", "*LAMP*", "*LED*")
PRESETS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "dialux": (("DLX_*LUM*",), ()),
    "revit": (("E-LITE", "E-LITE-*"), ()),
    "generic": (_GENERIC, _GENERIC),
}
"""Preset name -> (layer patterns, block-name patterns); ``auto`` is their union."""

PRESET_EXCLUDE = ("*-SWCH*", "*SWITCH*", "*-CIRC*", "*-IDEN*", "*-NOTE*", "*-TEXT*", "*-DIMS*", "*-ANNO*")
"""Layers/blocks the presets skip: switches, circuits and labels of the lighting layers."""

OUTLINE_LAYERS = ("*WALL*", "*ROOM*", "*OUTLINE*", "A-AREA*", "DLX_*ROOM*")
"""Layers whose closed polylines are room-outline candidates."""

MERGE_MIN_M = 0.05
"""Parts closer than this (or half the LED radius, if larger) are one luminaire [m]."""

_MAX_DEPTH = 16  # block nesting depth followed; deeper (or cyclic) references are ignored
_REVIT_APPID = "REVIT"


def _match(name: str, patterns: tuple[str, ...]) -> bool:
    upper = name.upper()
    return any(fnmatch.fnmatchcase(upper, p.upper()) for p in patterns)


@dataclass(frozen=True)
class _Selector:
    """Which layers and block names hold luminaires."""

    layers: tuple[str, ...]
    blocks: tuple[str, ...]
    exclude: tuple[str, ...]
    label: str

    def matches(self, layer: str, block: str | None = None) -> bool:
        names = [layer] if block is None else [layer, block]
        if any(_match(n, self.exclude) for n in names):
            return False
        return _match(layer, self.layers) or (block is not None and _match(block, self.blocks))


def _selector(preset: str, layers: list[str] | None, blocks: list[str] | None) -> _Selector:
    key = preset.lower()
    if key == "auto":
        lay = tuple(dict.fromkeys(p for v in PRESETS.values() for p in v[0]))
        blk = tuple(dict.fromkeys(p for v in PRESETS.values() for p in v[1]))
    elif key in PRESETS:
        lay, blk = PRESETS[key]
    else:
        raise UsageError(f"--preset {preset!r} is unknown; use one of auto, {', '.join(PRESETS)}")
    if not layers and not blocks:  # None or [] alike: use the preset
        return _Selector(lay, blk, PRESET_EXCLUDE, f"preset {key}")
    given = [f"--layer {p!r}" for p in layers or ()] + [f"--block {p!r}" for p in blocks or ()]
    return _Selector(tuple(layers or ()), tuple(blocks or ()), (), ", ".join(given) or "no patterns")


def load_drawing(path: str | Path) -> tuple[Drawing, list[str]]:
    """Open a DXF file, recovering a damaged one; returns the drawing and notes on what was fixed."""
    path = Path(path)
    where = str(path)
    if not path.is_file():
        raise InputError(f"{where}: file not found; check the path")
    try:
        is_dxf = is_binary_dxf_file(where) or is_dxf_file(where)
        is_dwg = not is_dxf and is_dwg_file(where)
    except OSError as exc:
        raise InputError(f"{where}: cannot read the file ({exc.strerror or exc}); check its permissions") from exc
    if is_dwg:
        raise InputError(f"{where}: this is a DWG file, not DXF; save it as DXF from the CAD program")
    if not is_dxf:
        raise InputError(f"{where}: not a DXF file; export the drawing as DXF, or give a .yaml/.csv layout")
    try:
        return ezdxf.readfile(where), []
    except OSError as exc:
        raise InputError(f"{where}: cannot read the file ({exc.strerror or exc}); check its permissions") from exc
    except (ezdxf.DXFError, ValueError, KeyError, IndexError, TypeError, EOFError, StopIteration) as exc:  # damaged: recover
        first = exc
    try:
        doc, auditor = recover.readfile(where)
    except Exception as exc:  # recover is the last resort: any failure means unreadable
        raise InputError(f"{where}: damaged DXF that could not be recovered ({exc}); re-export the drawing") from exc
    fixed = [e.message for e in auditor.fixes]
    note = f"recovered a damaged DXF; the auditor fixed {len(fixed)} problem(s)"
    if fixed:
        note += ": " + "; ".join(fixed[:3]) + ("; ..." if len(fixed) > 3 else "")
    else:
        note += f" (read error: {first})"
    if auditor.errors:
        note += f"; {len(auditor.errors)} problem(s) left unfixed: {auditor.errors[0].message}"
    return doc, [note]


@dataclass
class _Part:
    """One matched entity: position and radius in drawing units (WCS)."""

    xyz: tuple[float, float, float]
    radius: float | None
    source: dict


@dataclass
class _Scan:
    """What a walk over the model space found."""

    file: str
    selector: _Selector
    parts: list[_Part] = field(default_factory=list)
    outlines: list[list[tuple[float, float]]] = field(default_factory=list)
    layers_seen: Counter = field(default_factory=Counter)
    blocks_seen: Counter = field(default_factory=Counter)
    block_radius: dict[str, float | None] = field(default_factory=dict)


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


def _source(scan: _Scan, entity, kind: str, layer: str, ancestry: tuple) -> dict:
    src: dict = {"file": scan.file, "handle": entity.dxf.handle, "layer": layer, "entity": kind}
    for holder in (entity, *reversed(ancestry)):
        element = _element_id(holder)
        if element is not None:
            src["element_id"] = element
            break
    if ancestry:
        src["parent"] = ancestry[0].dxf.handle
    return src


def _walk(scan: _Scan, entities, m: Matrix44 | None, inherited: str | None, ancestry: tuple) -> None:
    """Collect luminaire parts and outline candidates; ``m`` maps these entities to WCS."""
    for entity in entities:
        try:
            layer = entity.dxf.get("layer", "0")
        except ezdxf.DXFError:  # an entity type ezdxf does not know (a damaged or foreign file): not ours
            continue
        if inherited is not None and layer == "0":
            layer = inherited  # entities on layer 0 inside a block take the INSERT's layer
        kind = entity.dxftype()
        if not ancestry or kind in ("INSERT", "CIRCLE", "POINT"):
            scan.layers_seen[layer] += 1  # inside blocks, count only what could be a luminaire
        if kind == "INSERT":
            _visit_insert(scan, entity, layer, m, ancestry)
        elif kind in ("CIRCLE", "POINT") and scan.selector.matches(layer):
            if kind == "CIRCLE":
                centre, radius = entity.ocs().to_wcs(entity.dxf.center), entity.dxf.radius * _scale(m)
            else:
                centre, radius = Vec3(entity.dxf.location), None
            centre = m.transform(centre) if m is not None else centre
            scan.parts.append(_Part(centre.xyz, radius, _source(scan, entity, kind, layer, ancestry)))
        elif kind in ("LWPOLYLINE", "POLYLINE") and _match(layer, OUTLINE_LAYERS):
            points = _closed_points(entity)
            if points:
                points = list(m.transform_vertices(points)) if m is not None else points
                scan.outlines.append([(p.x, p.y) for p in points])


def _visit_insert(scan: _Scan, insert, layer: str, m: Matrix44 | None, ancestry: tuple) -> None:
    name = insert.dxf.name
    scan.blocks_seen[name] += 1
    block = insert.block()
    matched = scan.selector.matches(layer, name)
    if not matched and (block is None or len(ancestry) >= _MAX_DEPTH):
        return
    copies = list(insert.multi_insert()) if insert.mcount > 1 else [insert]
    for index, copy in enumerate(copies):
        world = copy.matrix44() if m is None else copy.matrix44() * m
        if not matched:
            _walk(scan, block, world, layer, ancestry + (insert,))
            continue
        base = block.block.dxf.base_point if block is not None else Vec3()
        radius = _block_radius(scan, block)
        src = _source(scan, insert, "INSERT", layer, ancestry)
        src["block"] = name
        if len(copies) > 1:
            src["array_index"] = index
        scan.parts.append(_Part(world.transform(base).xyz, None if radius is None else radius * _scale(world), src))


def _block_radius(scan: _Scan, block) -> float | None:
    """Largest CIRCLE radius drawn directly in a block definition [block units]."""
    if block is None:
        return None
    if block.name not in scan.block_radius:
        radii = [e.dxf.radius for e in block if e.dxftype() == "CIRCLE"]
        scan.block_radius[block.name] = max(radii) if radii else None
    return scan.block_radius[block.name]


def _closed_points(entity) -> list[Vec3]:
    """WCS vertices of a closed 2D/3D polyline (closing duplicate dropped), else []."""
    if entity.dxftype() == "LWPOLYLINE":
        points = list(entity.vertices_in_wcs())
        closed = entity.closed
    elif entity.is_2d_polyline or entity.is_3d_polyline:
        points = list(entity.points_in_wcs())
        closed = entity.is_closed
    else:
        return []
    if len(points) > 1 and points[0].isclose(points[-1]):
        points, closed = points[:-1], True
    return points if closed and len(points) >= 3 else []




def _clusters(xy_m: np.ndarray, radius_m: np.ndarray) -> np.ndarray:
    """Cluster label per part, numbered in order of each cluster's first part."""
    n = len(xy_m)
    if n < 2:
        return np.zeros(n, dtype=int)
    threshold = np.maximum(0.5 * radius_m, MERGE_MIN_M)
    pairs = cKDTree(xy_m).query_pairs(float(threshold.max()), output_type="ndarray")
    if len(pairs):
        i, j = pairs[:, 0], pairs[:, 1]
        close = np.hypot(*(xy_m[i] - xy_m[j]).T) <= np.maximum(threshold[i], threshold[j])
        pairs = pairs[close]
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    _, first, inverse = np.unique(labels, return_index=True, return_inverse=True)
    rank = np.empty(len(first), dtype=int)
    rank[np.argsort(first)] = np.arange(len(first))
    return rank[inverse]


def _groups(labels: np.ndarray) -> list[np.ndarray]:
    """Member indices of each cluster, clusters in label order, members in part order."""
    if not len(labels):
        return []
    order = np.argsort(labels, kind="stable")
    return np.split(order, np.flatnonzero(np.diff(labels[order])) + 1)


@dataclass(frozen=True)
class _Parts:
    """Matched parts as arrays in drawing units; ``radius`` is NaN where the drawing gives none."""

    xyz: np.ndarray
    radius: np.ndarray

    def radius_m(self, scale: float, fallback_m: float) -> np.ndarray:
        return np.where(np.isnan(self.radius), fallback_m, self.radius * scale)

    def figures(self, scale: float, fallback_m: float, outline: list | None) -> Figures:
        """Typical spacing, mounting height and room size if the drawing unit is ``scale`` [m]."""
        spacing = height = None
        if len(self.xyz):
            xy = self.xyz[:, :2] * scale
            labels = _clusters(xy, self.radius_m(scale, fallback_m))
            counts = np.bincount(labels)
            centres = np.column_stack([np.bincount(labels, xy[:, i]) / counts for i in (0, 1)])
            if len(centres) >= 2:
                # many points: arrays (the stubs' return type also allows one point's scalars)
                dist = cast(np.ndarray, cKDTree(centres).query(centres, k=2)[0])
                spacing = float(np.median(dist[:, 1]))
            elif np.ptp(xy, axis=0).any():  # distinct parts all merged: the unit is too small
                spacing = float(np.hypot(*np.ptp(xy, axis=0)))
            z = self.xyz[:, 2][self.xyz[:, 2] != 0] * scale
            height = float(np.median(z)) if len(z) else None
        size = None
        if spacing is None and outline:
            pts = np.asarray(outline) * scale
            width, depth = pts.max(axis=0) - pts.min(axis=0)  # outline points are (x, y)
            size = (float(width), float(depth))
        return Figures(spacing, height, size)


def read_dxf(
    path: str | Path,
    *,
    units: str | None = None,
    preset: str = "auto",
    layers: list[str] | None = None,
    blocks: list[str] | None = None,
    mount_height_m: float | None = None,
    radius_m: float | None = None,
    allow_outline_only: bool = False,
) -> Layout:
    """Read a DXF drawing into a :class:`Layout` (positions [m]).

    Parameters
    ----------
    path : str or Path
        The ``.dxf`` file; a damaged one is recovered and the fixes are noted.
    units : str, optional
        Drawing unit (``mm``, ``cm``, ``m``, ``in``, ``ft``); overrides ``$INSUNITS`` and the check.
    preset : str
        ``auto``, ``dialux``, ``revit`` or ``generic``: which layers/blocks hold luminaires.
    layers, blocks : list of str, optional
        fnmatch patterns (case-insensitive) that replace the preset's layer/block patterns.
    mount_height_m : float, optional
        Mounting height where the drawing's Z is 0 [m]; default ``DEFAULT_MOUNT_HEIGHT_M``.
    radius_m : float, optional
        LED radius where the drawing has no CIRCLE [m]; default ``DEFAULT_RADIUS_M``.
    allow_outline_only : bool
        Return a layout without luminaires when the drawing holds only a room outline.
    """
    path = Path(path)
    where = str(path)
    for flag, value in (("--height", mount_height_m), ("--radius", radius_m)):
        if value is not None and not value > 0:
            raise UsageError(f"{flag} {value} m must be positive")
    selector = _selector(preset, layers, blocks)
    doc, notes = load_drawing(path)
    msp = doc.modelspace()
    if len(msp) == 0:
        damaged = " (after recovering the damaged file)" if notes else ""
        raise InputError(f"{where}: the model space is empty{damaged}; export the plan in model space, not only in a layout")
    scan = _Scan(path.name, selector)
    _walk(scan, msp, None, None, ())
    _check_numbers(scan, where)
    outline = max(scan.outlines, key=area_m2, default=None)
    if not scan.parts and not (allow_outline_only and outline is not None):
        hint = " (or --leds N to fill the room outline)" if outline is not None else ""
        raise InputError(
            f"{where}: no luminaire matched ({selector.label}); layers seen: {_counts(scan.layers_seen)}; "
            f"blocks seen: {_counts(scan.blocks_seen)}; pass --layer or --block{hint}"
        )
    fallback_m = radius_m if radius_m is not None else DEFAULT_RADIUS_M
    parts = _Parts(
        np.array([p.xyz for p in scan.parts], dtype=float).reshape(-1, 3),
        np.array([np.nan if p.radius is None else p.radius for p in scan.parts], dtype=float),
    )
    insunits = int(doc.header.get("$INSUNITS", 0) or 0)
    unit, reason, unit_notes = choose_unit(lambda s: parts.figures(s, fallback_m, outline), insunits, units, where)
    scale = UNIT_TO_M[unit]
    luminaires, lum_notes = _luminaires(scan.parts, parts, scale, fallback_m, mount_height_m)
    outline_m = tuple((x * scale, y * scale) for x, y in outline) if outline is not None else None
    return Layout(tuple(luminaires), outline_m, where, unit, reason, tuple(notes + unit_notes + lum_notes))


def _check_numbers(scan: _Scan, where: str) -> None:
    """Refuse coordinates that are not numbers or lie beyond any building in any unit, and radii <= 0,
    naming the entity, before anything is computed from them."""
    limit = 1e6 * MAX_EXTENT_M / min(UNIT_TO_M.values())  # far beyond any unit: the unit check explains the rest
    for part in scan.parts:
        xyz, r = np.asarray(part.xyz, dtype=float), part.radius
        if not np.isfinite(xyz).all() or np.abs(xyz).max() > limit or (r is not None and not 0 < r < limit):
            src = part.source
            radius = "" if r is None else f", radius {r:g}"
            raise InputError(f"{where}: {src['entity']} {src['handle']} on layer {src['layer']!r} at "
                             f"({', '.join(f'{v:g}' for v in xyz)}){radius}: not a plausible drawing value "
                             f"(finite, within {limit:g} units, radius > 0); fix or delete that entity")
    for corners in scan.outlines:
        pts = np.asarray(corners, dtype=float)
        if not np.isfinite(pts).all() or np.abs(pts).max() > limit:
            raise InputError(f"{where}: a closed polyline on a wall layer has a corner that is not a plausible "
                             f"drawing value (finite, within {limit:g} units); fix or delete it")


def _luminaires(
    found: list[_Part], parts: _Parts, scale: float, fallback_m: float, mount_height_m: float | None
) -> tuple[list[Luminaire], list[str]]:
    """Merge parts at one point, convert to metres, sort by (y, x) and name them."""
    if not found:
        return [], []
    xyz = parts.xyz * scale
    radius = parts.radius_m(scale, fallback_m)
    labels = _clusters(xyz[:, :2], radius)
    height = mount_height_m if mount_height_m is not None else DEFAULT_MOUNT_HEIGHT_M
    rows, no_z = [], 0
    for k, members in enumerate(_groups(labels)):
        x, y = xyz[members, :2].mean(axis=0)
        zs = xyz[members, 2][xyz[members, 2] != 0]
        no_z += not len(zs)
        known = parts.radius[members][~np.isnan(parts.radius[members])]
        source = dict(found[members[0]].source)
        if len(members) > 1:
            source["parts"] = int(len(members))
        r = float(known.max() * scale) if len(known) else fallback_m
        rows.append((round(y * 1000), round(x * 1000), k, float(x), float(y), float(zs[0]) if len(zs) else height, r, source))
    rows.sort(key=lambda row: row[:3])
    luminaires = [Luminaire(f"L{i + 1:04d}", x, y, z, r, src) for i, (*_, x, y, z, r, src) in enumerate(rows)]
    notes = []
    if len(found) > len(luminaires):
        notes.append(f"merged {len(found)} parts drawn at the same point into {len(luminaires)} luminaires")
    if no_z:
        given = "given" if mount_height_m is not None else "default; set with --height"
        notes.append(f"{no_z} luminaire(s) have no height in the drawing (Z = 0); used {height:g} m ({given})")
    return luminaires, notes


def _counts(counter: Counter, limit: int = 8) -> str:
    """``A (12), B (3), ...`` most frequent first, truncated to ``limit`` names."""
    if not counter:
        return "none"
    items = sorted(counter.items(), key=lambda kv: (-kv[1], kv[0]))
    text = ", ".join(f"{name} ({count})" for name, count in items[:limit])
    return text + (f", ... ({len(items) - limit} more)" if len(items) > limit else "")
