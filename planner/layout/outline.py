"""The floor outline from a drawing's rooms: one polygon [m] the plan's poses are sampled in.

A drawing holds many closed polylines on wall and room layers: the rooms of a floor, the
walls themselves as thin rectangles, columns. The floor is their union's outer boundary:
rooms a wall apart (up to ``2 * WALL_GAP_M``) are joined by closing (grow, unite, shrink),
holes such as courtyards are dropped, and of separate buildings the largest is kept (a
note names the others). When one polygon already holds all the others it is the floor, as
drawn. A chosen room (``--room``, by layer or by the name written inside it) replaces the
floor by the union of the rooms chosen. Luminaire symbols drawn well off the floor (a legend's,
a title block's) are left out when they are few (:func:`off_floor`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planner.layout.model import area_m2

WALL_GAP_M = 0.3
"""Rooms closer than twice this are one floor (walls up to 0.6 m thick) [m]."""

Polygon = Sequence[tuple[float, float]]


def _inside(inner: Polygon, outer: Polygon) -> bool:
    from matplotlib.path import Path as PolygonPath  # here: a drawing refused early needs no Matplotlib

    return bool(PolygonPath(np.asarray(outer, dtype=float)).contains_points(np.asarray(inner, dtype=float),
                                                                            radius=1e-9).all())


def floor_outline(polygons: Sequence[Polygon], what: str = "closed polylines on wall/room layers",
                  lines: Sequence[Polygon] = ()) -> tuple[tuple[tuple[float, float], ...] | None, list[str]]:
    """The floor from room and wall polygons [m] (``what`` they are, for the note) and from walls drawn as
    open lines [m]: ``(outline, notes)``; ``(None, [])`` without either."""
    polygons = [p for p in polygons if len(p) >= 3 and area_m2(list(p)) > 0]
    lines = [p for p in lines if len(p) >= 2]
    if lines:
        return _floor_from_lines(polygons, lines, what)
    if not polygons:
        return None, []
    largest = max(polygons, key=lambda p: area_m2(list(p)))
    if all(p is largest or _inside(p, largest) for p in polygons):
        return tuple((float(x), float(y)) for x, y in largest), []
    import shapely
    from shapely.geometry import Polygon as ShapelyPolygon
    from shapely.geometry.polygon import orient

    shapes = [ShapelyPolygon(p).buffer(0) for p in polygons]  # buffer(0) mends self-touching rings
    grown = shapely.unary_union([s.buffer(WALL_GAP_M, join_style="mitre") for s in shapes if not s.is_empty])
    floor = grown.buffer(-WALL_GAP_M, join_style="mitre")
    # each part's outer boundary, holes (rooms inside walls, courtyards) filled: the largest is the floor
    parts = [ShapelyPolygon(g.exterior) for g in getattr(floor, "geoms", [floor]) if not g.is_empty and g.area > 0]
    parts.sort(key=lambda g: -g.area)
    if not parts:
        return tuple((float(x), float(y)) for x, y in largest), []
    main = orient(parts[0], 1.0).simplify(1e-6)
    coords = [(round(float(x), 9) + 0.0, round(float(y), 9) + 0.0) for x, y in list(main.exterior.coords)[:-1]]
    notes = [f"room outline: the floor joined from {len(polygons)} {what} "
             f"({main.area:.1f} m2 within its outer boundary, largest single one {area_m2(list(largest)):.1f} m2)"]
    if len(parts) > 1:
        notes.append(f"room outline: {len(parts) - 1} separate part(s) of {sum(g.area for g in parts[1:]):.1f} m2 "
                     "left out (not within 0.6 m of the largest); choose one with --room")
    return tuple(coords), notes


DOOR_GAPS_M = (0.3, 0.6, 1.2)
"""Half the widest gap between wall lines bridged, tried in turn until the walls enclose a floor [m]:
joints (0.6 m), doors (1.2 m), double doors and openings (2.4 m)."""


def _floor_from_lines(polygons: Sequence[Polygon], lines: Sequence[Polygon], what: str
                      ) -> tuple[tuple[tuple[float, float], ...] | None, list[str]]:
    """The floor enclosed by walls drawn as many short lines (and any closed polylines beside them): the
    outer boundary of their closing (grow by ``d``, unite, fill what they enclose, shrink by ``d``), with
    the smallest ``d`` of :data:`DOOR_GAPS_M` at which the walls enclose at least as much floor as they cover."""
    import shapely
    from shapely.geometry import LineString
    from shapely.geometry import Polygon as ShapelyPolygon
    from shapely.geometry.polygon import orient

    # closed polylines count by their edges, as the lines do: rooms drawn closed inside walls drawn open leave
    # the floor between them enclosed, not covered
    shapes = [ShapelyPolygon(p).buffer(0).boundary for p in polygons] + [LineString(p) for p in lines]
    shapes = [g for g in shapes if not g.is_empty and (g.area > 0 or g.length > 0)]  # no zero-length lines
    for gap_m in DOOR_GAPS_M:
        grown = shapely.unary_union([g.buffer(gap_m, join_style="mitre", cap_style="square") for g in shapes])
        parts = sorted((g for g in getattr(grown, "geoms", [grown]) if isinstance(g, ShapelyPolygon) and not g.is_empty),
                       key=lambda g: -ShapelyPolygon(g.exterior).area)
        if not parts:
            break
        filled = ShapelyPolygon(parts[0].exterior)
        if filled.area - parts[0].area < 0.5 * filled.area:
            continue  # the walls are open wider than 2 d: they enclose no floor yet
        floor = filled.buffer(-gap_m, join_style="mitre")
        pieces = sorted(getattr(floor, "geoms", [floor]), key=lambda g: -g.area)
        main = orient(ShapelyPolygon(pieces[0].exterior), 1.0).simplify(1e-6)
        coords = [(round(float(x), 9) + 0.0, round(float(y), 9) + 0.0) for x, y in list(main.exterior.coords)[:-1]]
        count = f"{len(lines)} wall line(s)" + (f" and {len(polygons)} {what}" if polygons else "")
        notes = [f"room outline: the floor enclosed by {count} ({main.area:.1f} m2 within its outer boundary; "
                 f"gaps up to {2 * gap_m:g} m bridged)"]
        apart = [ShapelyPolygon(g.exterior) for g in parts[1:] if not filled.contains(g)]  # not a column inside
        if apart:
            notes.append(f"room outline: {len(apart)} separate wall group(s) covering {sum(g.area for g in apart):.1f} "
                         "m2 left out; choose a room with --room")
        return tuple(coords), notes
    outline, notes = floor_outline(polygons, what) if polygons else (None, [])
    return outline, notes + [f"room outline: {len(lines)} wall line(s) enclose no floor (open wider than "
                             f"{2 * DOOR_GAPS_M[-1]:g} m)"]


OFF_FLOOR_M = 0.5
"""A luminaire symbol farther than this outside the floor outline is drawn off the floor [m]."""

OFF_FLOOR_SHARE = 0.05
"""Symbols off the floor are left out when they are this share of all or fewer (at least 2 may be)."""


def off_floor(members: list[np.ndarray], xy: np.ndarray, outline, expected: int | None, chosen: bool = False
               ) -> tuple[list[np.ndarray], list[str]]:
    """Leave out the few luminaire symbols drawn well outside the floor outline: a legend's or a title
    block's symbols, not luminaires of the room. Many of them mean the outline is incomplete: all are
    kept and a note says so; so are they when ``--leds N`` counts them. An outline holding too few of them
    to be their floor (and not a room ``chosen`` with ``--room``) is left to :func:`own_extent`."""
    if outline is None or not members:
        return members, []
    import shapely

    off = shapely.distance(shapely.Polygon(outline), shapely.points(xy)) > OFF_FLOOR_M
    if not off.any():
        return members, []
    where = ", ".join(f"({x:.2f}, {y:.2f})" for x, y in xy[off][:4]) + (" ..." if off.sum() > 4 else "")
    if expected == len(members):
        return members, [f"{int(off.sum())} luminaire(s) lie more than {OFF_FLOOR_M:g} m outside the room outline, at "
                      f"{where} m: kept, as --leds {expected} counts them"]
    if off.mean() > 1 - FLOOR_SHARE and not chosen:
        return members, []  # no floor of these luminaires: :func:`own_extent` drops it and says so
    if off.sum() > max(2, OFF_FLOOR_SHARE * len(members)):
        return members, [f"{int(off.sum())} of {len(members)} luminaires lie more than {OFF_FLOOR_M:g} m outside the room "
                      f"outline, e.g. at {where} m: kept (so many suggest the outline misses rooms; --room chooses)"]
    kept = [m for m, o in zip(members, off) if not o]
    return kept, [f"left out {int(off.sum())} luminaire symbol(s) drawn more than {OFF_FLOOR_M:g} m outside the room "
                  f"outline, at {where} m (a legend or title block?); to plan them, draw the room around them "
                  f"or pass --leds {len(members)}"]


FLOOR_SHARE = 0.5
"""An outline that holds fewer than this share of the luminaires (within ``OFF_FLOOR_M``) is not the floor."""


def own_extent(outline, xy: np.ndarray) -> tuple[tuple[tuple[float, float], ...] | None, list[str]]:
    """Keep ``outline`` if it is the floor of luminaires ``xy`` [m]; else ``None`` (poses are then sampled over
    the luminaires' own extent, their convex hull: ``planner.verify.windows.working_area``) with a note saying
    so. An outline is the floor when it holds at least :data:`FLOOR_SHARE` of them."""
    if len(xy) < 3:
        return outline, []
    from scipy.spatial import ConvexHull, QhullError

    try:
        hull = f"{ConvexHull(xy).volume:.1f} m2"  # in 2D the hull's volume is its area
    except QhullError:
        hull = "a strip: they stand in a line"
    extent = f"poses are sampled over the luminaires' own extent (their convex hull, {hull})"
    if outline is None:
        return None, [f"room outline: none found on wall/room layers; {extent}; draw the walls on a layer named "
                      "like *WALL* or *ROOM*, or choose a room with --room"]
    import shapely

    inside = shapely.distance(shapely.Polygon(outline), shapely.points(xy)) <= OFF_FLOOR_M
    if inside.mean() >= FLOOR_SHARE:
        return outline, []
    return None, [f"room outline: the outline found ({area_m2(np.asarray(outline)):.1f} m2) holds only "
                  f"{int(inside.sum())} of {len(xy)} luminaires, so it is no floor: {extent}; choose a room "
                  "with --room"]
