"""Read luminaires and the room outline from a DXF drawing (DIALux, Revit, AutoCAD, converted DWG).

:mod:`planner.layout.dxf_scan` walks the model space and classifies every INSERT, CIRCLE
and POINT by its names (:mod:`planner.layout.dxf_names`); this module turns the parts it
took into luminaires: Z noise is no height, the unit is decided once
(:mod:`planner.layout.dxf_units`), positions are converted to metres, parts drawn at one
point are merged, with ``--leds N`` the one group of N is chosen among several, and the
floor outline is joined from the rooms (:mod:`planner.layout.outline`). The result is a
:class:`~planner.layout.model.Layout` with luminaires named ``L0001``... in plan order.
``docs/dxf.md`` describes the rules for users.
"""

from __future__ import annotations

import fnmatch
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np
from ezdxf.document import Drawing

from planner.defaults import MAX_EXTENT_M, MAX_HEIGHT_M, UNIT_TO_M
from planner.errors import InputError, UsageError
from planner.layout.dxf_load import MAX_DXF_ENTITIES, open_drawing
from planner.layout.dxf_names import PRESETS, selector
from planner.layout.dxf_scan import OUTLINE_LAYERS, Scan, WalkTooLong, scan
from planner.layout.dxf_units import HEIGHT_RANGE_M, UNIT_NAMES, Figures, choose_unit
from planner.layout.model import DEFAULT_MOUNT_HEIGHT_M, DEFAULT_RADIUS_M, Layout, Luminaire, area_m2
from planner.layout.outline import floor_outline, off_floor, own_extent

__all__ = ["read_dxf", "scan_dxf", "load_drawing", "PRESETS", "UNIT_TO_M", "OUTLINE_LAYERS"]

INSPECT_HINT = "vlp-inspect {path} lists what the drawing holds and what the reader took and why"
"""Pointer printed after a failed read of a drawing."""

MERGE_MIN_M = 0.05
"""Parts closer than this (or half the LED radius, if larger) are one luminaire [m]."""

Z_NOISE = 1e-6
"""A Z within this fraction of the drawing's plan extent is numerically zero: no height."""


def load_drawing(path: str | Path) -> tuple[Drawing, list[str]]:
    """Open a whole DXF file (for a copy or a picture), recovering a damaged one; returns the drawing and notes on
    what was fixed. A drawing over :data:`~planner.layout.dxf_load.MAX_DXF_ENTITIES` comes back holding what the
    reader uses (luminaires, texts, walls), with a note saying so."""
    loaded = open_drawing(path, everything=True)
    if not loaded.whole:
        loaded.notes.append(f"more than {MAX_DXF_ENTITIES:,} entities: only the luminaires, texts and walls were "
                            f"loaded ({sum(loaded.skipped.values()):,} other entities left out)")
    return loaded.doc, loaded.notes


DENSE_PAIRS_PER_PART = 50
"""Parts closer than their merge size, per part, beyond which a unit guess does not merge (a luminaire is a
handful of parts, never 50)."""


def _too_dense(xy_m: np.ndarray, radius_m: np.ndarray) -> bool:
    """Whether the parts lie so close for their merge size that merging them would list more than
    ``DENSE_PAIRS_PER_PART`` pairs per part (counted, not listed: linear memory)."""
    if len(xy_m) <= DENSE_PAIRS_PER_PART:
        return False
    from scipy.spatial import cKDTree  # here: a drawing refused before its parts are merged needs no SciPy

    tree = cKDTree(xy_m)
    reach = float(np.maximum(0.5 * radius_m, MERGE_MIN_M).max())
    return bool(tree.count_neighbors(tree, reach) > DENSE_PAIRS_PER_PART * len(xy_m))


def _clusters(xy_m: np.ndarray, radius_m: np.ndarray) -> np.ndarray:
    """Cluster label per part, numbered in order of each cluster's first part (callers check
    :func:`_too_dense` first: the pairs listed are then at most ``DENSE_PAIRS_PER_PART`` per part)."""
    n = len(xy_m)
    if n < 2:
        return np.zeros(n, dtype=int)
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

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
    """Taken parts as arrays in drawing units; ``radius`` (circles) and ``size`` (symbol geometry) are NaN
    where the drawing gives none."""

    xyz: np.ndarray
    radius: np.ndarray
    size: np.ndarray

    def merge_radius_m(self, scale: float, given_m: float | None) -> np.ndarray:
        """The size parts are merged by: circle radius, else the drawn symbol's size, else ``--radius``, else the
        default [m] (``--radius`` gives the LED, not the symbol drawn around it)."""
        fallback = given_m if given_m is not None else DEFAULT_RADIUS_M
        other = np.where(np.isnan(self.size), fallback, self.size * scale)
        return np.where(np.isnan(self.radius), other, self.radius * scale)

    def figures(self, scale: float, given_m: float | None, outline: list | None) -> Figures:
        """Typical spacing, mounting height and room size if the drawing unit is ``scale`` [m]."""
        from scipy.spatial import cKDTree

        spacing = height = None
        if len(self.xyz):
            xy = self.xyz[:, :2] * scale
            radius = self.merge_radius_m(scale, given_m)
            if _too_dense(xy, radius):
                # At this scale the parts lie far closer than the size they merge by: no unit the drawing is in.
                # Merging would list billions of pairs (gigabytes); the parts' own spacing, on a sample, says so.
                tree = cKDTree(xy)
                sample = xy[np.random.default_rng(0).choice(len(xy), min(len(xy), 2_000), replace=False)]
                dist = cast(np.ndarray, tree.query(sample, k=2)[0])
                z = self.xyz[:, 2][self.xyz[:, 2] != 0] * scale
                return Figures(float(np.median(dist[:, 1])), float(np.median(z)) if len(z) else None, None)
            labels = _clusters(xy, radius)
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


def scan_dxf(path: str | Path, *, preset: str = "auto", layers: list[str] | None = None,
             blocks: list[str] | None = None) -> tuple[Scan, Drawing, list[str]]:
    """Open a drawing and walk its model space: what it holds, what the reader takes and rejects (and why)."""
    path = Path(path)
    chosen = selector(preset, layers, blocks)
    loaded = open_drawing(path)
    doc, notes = loaded.doc, loaded.notes
    msp = doc.modelspace()
    if len(msp) == 0 and not loaded.skipped:
        damaged = " (after recovering the damaged file)" if notes else ""
        raise InputError(f"{path}: the model space is empty{damaged}; export the plan in model space, not only in a layout")
    try:
        found = scan(path.name, chosen, msp)
    except WalkTooLong as exc:
        raise InputError(f"{path}: {exc}; select the luminaires with --layer or --block, explode or purge nested "
                         "blocks, or split the drawing") from None
    found.layers_seen.update(loaded.skipped)  # entities skimmed past unloaded (dxf_load) still count by layer
    _check_numbers(found, str(path))
    return found, doc, notes


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
    expected: int | None = None,
    room: str | None = None,
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
        fnmatch patterns (case-insensitive) that replace the preset's layer/block rules.
    mount_height_m : float, optional
        Mounting height where the drawing gives no plausible Z [m]; default ``DEFAULT_MOUNT_HEIGHT_M``.
    radius_m : float, optional
        LED radius where the drawing has no CIRCLE [m]; default: the symbol's size, else ``DEFAULT_RADIUS_M``.
    allow_outline_only : bool
        Return a layout without luminaires when the drawing holds only a room outline.
    expected : int, optional
        The ``--leds`` count: when the candidates are more, the one group (block name, or circles
        on a layer) of exactly this many is used.
    room : str, optional
        fnmatch pattern of the room outline: its layer, or the name written inside it.
    """
    path = Path(path)
    where = str(path)
    for flag, value in (("--height", mount_height_m), ("--radius", radius_m)):
        if value is not None and not value > 0:
            raise UsageError(f"{flag} {value} m must be positive")
    found, doc, notes = scan_dxf(path, preset=preset, layers=layers, blocks=blocks)
    biggest = max((o.points for o in found.outlines), key=area_m2, default=None)
    if not found.parts and not (allow_outline_only and biggest is not None):
        hint = " (or --leds N to fill the room outline)" if biggest is not None else ""
        rejected = f"; rejected: {_counts(_by_name(found.rejected), 4)}" if found.rejected else ""
        raise InputError(
            f"{where}: no luminaire matched ({found.selector.label}); layers seen: {_counts(found.layers_seen)}; "
            f"blocks seen: {_counts(found.blocks_seen)}{rejected}; pass --layer or --block{hint}"
        )
    xyz = np.array([p.xyz for p in found.parts], dtype=float).reshape(-1, 3)
    notes += _zero_z_noise(xyz)
    parts = _Parts(xyz, np.array([np.nan if p.radius is None else p.radius for p in found.parts], dtype=float),
                   np.array([np.nan if p.size is None else p.size for p in found.parts], dtype=float))
    insunits = int(doc.header.get("$INSUNITS", 0) or 0)
    unit, reason, unit_notes = choose_unit(lambda s: parts.figures(s, radius_m, biggest), insunits, units, where)
    scale = UNIT_TO_M[unit]
    if _too_dense(xyz[:, :2] * scale, parts.merge_radius_m(scale, radius_m)):
        fix = f"--units {units} looks wrong" if units is not None else "pass the drawing's unit with --units"
        raise InputError(f"{where}: in {UNIT_NAMES[unit]}, the {len(xyz):,} luminaire parts lie far closer together "
                         f"than their size (more than {DENSE_PAIRS_PER_PART} within merging reach of each): no lit "
                         f"ceiling looks like that; {fix}")
    outline, outline_notes = _outline(found, scale, room, where)
    luminaires, lum_notes = _luminaires(found, parts, scale, radius_m, mount_height_m, expected, where, outline,
                                        room is not None)
    if room is None:  # a room the user chose stays, whatever it holds
        outline, extent_notes = own_extent(outline, np.array([(lum.x, lum.y) for lum in luminaires]).reshape(-1, 2))
        outline_notes += extent_notes
    return Layout(tuple(luminaires), outline, where, unit, reason,
                  tuple(notes + unit_notes + lum_notes + outline_notes))


def _zero_z_noise(xyz: np.ndarray) -> list[str]:
    """Set Z values within ``Z_NOISE`` of the plan extent to 0 (in place): numerical noise, not heights."""
    if not len(xyz):
        return []
    floor = max(1e-9, Z_NOISE * float(np.ptp(xyz[:, :2], axis=0).max()))
    noise = (xyz[:, 2] != 0) & (np.abs(xyz[:, 2]) <= floor)
    if not noise.any():
        return []
    example = xyz[noise, 2][np.argmax(np.abs(xyz[noise, 2]))]
    xyz[noise, 2] = 0.0
    return [f"{int(noise.sum())} Z value(s) within {floor:.3g} drawing units of 0 (up to {example:.3g}) are "
            "numerical noise: taken as no height"]


def _check_numbers(found: Scan, where: str) -> None:
    """Refuse coordinates that are not numbers or lie beyond any building in any unit, and radii <= 0,
    naming the entity, before anything is computed from them."""
    limit = 1e6 * MAX_EXTENT_M / min(UNIT_TO_M.values())  # far beyond any unit: the unit check explains the rest
    for part in found.parts:
        xyz, r = np.asarray(part.xyz, dtype=float), part.radius
        if not np.isfinite(xyz).all() or np.abs(xyz).max() > limit or (r is not None and not 0 < r < limit):
            src = part.source
            radius = "" if r is None else f", radius {r:g}"
            raise InputError(f"{where}: {src['entity']} {src['handle']} on layer {src['layer']!r} at "
                             f"({', '.join(f'{v:g}' for v in xyz)}){radius}: not a plausible drawing value "
                             f"(finite, within {limit:g} units, radius > 0); fix or delete that entity")
        if part.size is not None and not 0 < part.size < limit:
            part.size = None  # a symbol of no or absurd size: the radius falls back
    for kind, shapes in (("a closed polyline", [o.points for o in found.outlines]), ("a line", found.segments)):
        for points in shapes:
            pts = np.asarray(points, dtype=float)
            if not np.isfinite(pts).all() or np.abs(pts).max() > limit:
                raise InputError(f"{where}: {kind} on a wall layer has a corner that is not a plausible drawing value "
                                 f"(finite, within {limit:g} units); fix or delete it")


def _choose_group(found: Scan, members: list[np.ndarray], expected: int | None, where: str
                  ) -> tuple[list[np.ndarray], list[str]]:
    """With ``--leds N`` and more or fewer candidates, keep the one group of exactly N luminaires."""
    if expected is None or len(members) == expected:
        return members, []
    per_group: Counter = Counter()
    for m in members:
        for g in {found.parts[i].group for i in m}:
            per_group[g] += 1
    if len(per_group) < 2:
        return members, []  # check_layout names the mismatch
    listed = _counts(per_group)
    matching = [g for g, n in per_group.items() if n == expected]
    if len(matching) != 1:
        why = "none" if not matching else f"{len(matching)}"
        raise InputError(f"{where}: found {len(members)} luminaires in {len(per_group)} groups but --leds says "
                         f"{expected}, and {why} of the groups has {expected}: {listed}; choose with --block or "
                         f"--layer, or fix --leds; {INSPECT_HINT.format(path=where)}")
    chosen = matching[0]
    kept = [m for m in members if any(found.parts[i].group == chosen for i in m)]
    return kept, [f"{len(members)} candidates in {len(per_group)} groups ({listed}); {chosen!r} has {expected}, "
                  f"as --leds says: used it, left the others out"]


def _luminaires(found: Scan, parts: _Parts, scale: float, radius_m: float | None, mount_height_m: float | None,
                expected: int | None, where: str, outline=None, chosen: bool = False
                ) -> tuple[list[Luminaire], list[str]]:
    """Merge parts at one point, keep the group --leds names, leave out the few symbols drawn off the floor
    (:func:`planner.layout.outline.off_floor`), convert to metres, sort by (y, x) and name them."""
    if not found.parts:
        return [], []
    xyz = parts.xyz * scale
    merge = parts.merge_radius_m(scale, radius_m)
    members_of, notes = _choose_group(found, _groups(_clusters(xyz[:, :2], merge)), expected, where)
    members_of, off_notes = off_floor(members_of, np.array([xyz[m, :2].mean(axis=0) for m in members_of]), outline,
                                       expected, chosen)
    notes += off_notes
    height = mount_height_m if mount_height_m is not None else DEFAULT_MOUNT_HEIGHT_M
    rows, no_z, low_z = [], 0, []
    for k, members in enumerate(members_of):
        x, y = xyz[members, :2].mean(axis=0)
        z = xyz[members, 2][xyz[members, 2] != 0]
        plausible = z[(z >= HEIGHT_RANGE_M[0]) & (z <= MAX_HEIGHT_M)]
        no_z += not len(z)
        if len(z) and not len(plausible):
            low_z.append(float(z[0]))
        known = parts.radius[members][~np.isnan(parts.radius[members])]
        size = parts.size[members][~np.isnan(parts.size[members])]
        source = dict(found.parts[members[0]].source)
        if len(members) > 1:
            source["parts"] = int(len(members))
        r = (float(known.max() * scale) if len(known) else radius_m if radius_m is not None
             else float(size.max() * scale) if len(size) else DEFAULT_RADIUS_M)
        rows.append((round(y * 1000), round(x * 1000), k, float(x), float(y),
                     float(plausible[0]) if len(plausible) else height, r, source))
    rows.sort(key=lambda row: row[:3])
    luminaires = [Luminaire(f"L{i + 1:04d}", x, y, z, r, src) for i, (*_, x, y, z, r, src) in enumerate(rows)]
    merged = sum(len(m) for m in members_of)
    if merged > len(luminaires):
        notes.append(f"merged {merged} parts drawn at the same point into {len(luminaires)} luminaires")
    given = "given" if mount_height_m is not None else "default; set with --height"
    if no_z:
        notes.append(f"{no_z} luminaire(s) have no height in the drawing (Z = 0); used {height:g} m ({given})")
    if low_z:
        notes.append(f"{len(low_z)} luminaire(s) have a Z that is no plausible mounting height (e.g. {low_z[0]:.3g} m, "
                     f"outside {HEIGHT_RANGE_M[0]:g}-{MAX_HEIGHT_M:g} m); used {height:g} m ({given})")
    return luminaires, notes


def _outline(found: Scan, scale: float, room: str | None, where: str
             ) -> tuple[tuple[tuple[float, float], ...] | None, list[str]]:
    """The floor outline [m], or the rooms ``--room`` names (by layer, or by a text inside)."""
    rooms = [[(x * scale, y * scale) for x, y in o.points] for o in found.outlines]
    if room is None:
        return floor_outline(rooms, lines=[[(x * scale, y * scale) for x, y in s] for s in found.segments])
    from matplotlib.path import Path as PolygonPath

    pattern = room.upper()
    chosen = []
    for candidate, metres in zip(found.outlines, rooms):
        path = PolygonPath(np.asarray(candidate.points, dtype=float))
        names = [t for t, at in found.texts if path.contains_point(at)]
        if fnmatch.fnmatchcase(candidate.layer.upper(), pattern) or any(fnmatch.fnmatchcase(t.upper(), pattern)
                                                                       for t in names):
            chosen.append(metres)
    if not chosen:
        named = Counter(t for t, at in found.texts for o in found.outlines
                        if PolygonPath(np.asarray(o.points, dtype=float)).contains_point(at))
        layers = Counter(o.layer for o in found.outlines)
        raise InputError(f"{where}: --room {room!r} matches no closed polyline on a wall/room layer by layer or by "
                         f"a name inside it; layers: {_counts(layers)}; names inside rooms: {_counts(named)}")
    outline, notes = floor_outline(chosen)
    return outline, [f"room outline: {len(chosen)} room(s) chosen by --room {room!r}"] + notes


def _by_name(counter: Counter) -> Counter:
    """(what, name, layer, why) -> count, as ``NAME: why`` -> count."""
    out: Counter = Counter()
    for (what, name, layer, why), n in counter.items():
        out[f"{name or what + ' on ' + layer}: {why}"] += n
    return out


def _counts(counter: Counter, limit: int = 8) -> str:
    """``A (12), B (3), ...`` most frequent first, truncated to ``limit`` names."""
    if not counter:
        return "none"
    items = sorted(counter.items(), key=lambda kv: (-kv[1], kv[0]))
    text = ", ".join(f"{name} ({count})" for name, count in items[:limit])
    return text + (f", ... ({len(items) - limit} more)" if len(items) > limit else "")
