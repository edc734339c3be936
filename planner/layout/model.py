"""The layout stage: luminaires with positions in metres, and the room they light.

Readers (``dxf``, ``ifc``, ``tables``) build a :class:`Layout`; this module
holds the data type, the checks every layout must pass, and the lattice fill
that places ``N`` luminaires inside a room outline.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field, replace
from typing import cast

import numpy as np

from planner.defaults import MAX_EXTENT_M, MAX_HEIGHT_M, MAX_LUMINAIRES, MAX_RADIUS_M, MIN_RADIUS_M
from planner.errors import InputError

DEFAULT_RADIUS_M = 0.1
"""LED radius when the drawing or layout does not give one [m] (PRODUCT.md)."""

DEFAULT_MOUNT_HEIGHT_M = 2.5
"""Ceiling height when neither drawing nor flags give one [m] (the paper's rig)."""


MAX_NAME_CHARS = 64
"""Longest luminaire name accepted [characters]."""


def name_problem(name: str) -> str | None:
    """What is wrong with a luminaire name, or None: the one rule every reader applies.

    A name is 1-64 printable characters (letters of any script, digits, punctuation,
    inner spaces; no newline, tab or other control character) without spaces at either
    end. Each output escapes what its format needs: folder names are sanitised with a hash
    where the name is not a portable file name (``planner.firmware.render.file_name``), C and
    JSON get escaped literals, HTML is autoescaped, DXF XDATA and figures take it as plain
    text.
    """
    if not name:
        return "is empty"
    if len(name) > MAX_NAME_CHARS:
        return f"has {len(name)} characters, more than {MAX_NAME_CHARS}"
    if not name.isprintable():
        bad = next(c for c in name if not c.isprintable())
        return f"holds the control character U+{ord(bad):04X}"
    if name != name.strip():
        return "starts or ends with a space"
    return None


@dataclass(frozen=True)
class Luminaire:
    """One ceiling luminaire.

    Attributes
    ----------
    name : str
        Unique name on the site (from the drawing, the layout file, or generated).
    x, y, z : float
        Centre of the LED disc in site coordinates [m]; ``z`` is the mounting height.
    radius : float
        Radius of the circular LED [m].
    source : dict
        Where it came from: ``{"file": ..., "handle": ..., "layer": ..., "block": ...,
        "element_id": ..., "line": ...}``; only the keys that apply are present.
    tone_hz : float or None
        The square-wave tone an existing luminaire already broadcasts [Hz] (a tone site, docs/tones.md),
        or None: the planner gives it a frame ID.
    """

    name: str
    x: float
    y: float
    z: float
    radius: float = DEFAULT_RADIUS_M
    source: dict = field(default_factory=dict, compare=False)
    tone_hz: float | None = None


@dataclass(frozen=True)
class Layout:
    """Luminaires of one site, all in metres.

    Attributes
    ----------
    luminaires : tuple of Luminaire
        In a deterministic order (as read, after merging duplicates).
    outline : tuple of (x, y) or None
        Room outline polygon [m], if the input had one.
    source_path : str
        The input file.
    unit : str
        Unit the input's coordinates were in (``"mm"``, ``"m"``, ...).
    unit_reason : str
        Why that unit was used, for the summary.
    notes : tuple of str
        What the reader fixed or decided (merged parts, recovered entities, ...).
    fill_height_m, fill_radius_m : float or None
        Mounting height and LED radius the file states for luminaires laid out by
        ``--leds`` in its outline [m].
    """

    luminaires: tuple[Luminaire, ...]
    outline: tuple[tuple[float, float], ...] | None = None
    source_path: str = ""
    unit: str = "m"
    unit_reason: str = "stated by the layout"
    notes: tuple[str, ...] = ()
    fill_height_m: float | None = None
    fill_radius_m: float | None = None

    @property
    def xy(self) -> np.ndarray:
        """Positions in plan, shape (N, 2) [m]."""
        return np.array([(lum.x, lum.y) for lum in self.luminaires], dtype=float).reshape(-1, 2)

    @property
    def xyz(self) -> np.ndarray:
        """Positions, shape (N, 3) [m]."""
        return np.array([(lum.x, lum.y, lum.z) for lum in self.luminaires], dtype=float).reshape(-1, 3)

    @property
    def tones_hz(self) -> np.ndarray | None:
        """Each luminaire's tone, shape (N,) [Hz], on a tone site (every luminaire carries one); else None."""
        tones = [lum.tone_hz for lum in self.luminaires]
        return None if not tones or None in tones else np.array(tones, dtype=float)

    def with_note(self, note: str) -> Layout:
        return replace(self, notes=self.notes + (note,))


def check_layout(layout: Layout, expected: int | None = None) -> Layout:
    """Check what every plannable layout must satisfy, or raise :class:`InputError`.

    At least three luminaires (a fix needs three), unique names, the expected
    count when ``--leds`` gave one, and no two luminaires closer than the sum of
    their radii (they would overlap: usually a unit or duplication error).
    """
    where = layout.source_path or "layout"
    n = len(layout.luminaires)
    if expected is not None and n != expected:
        raise InputError(
            f"{where}: found {n} luminaires but `leds` says {expected}; "
            "fix the drawing's layer/block selection or the `leds` count"
        )
    if n > MAX_LUMINAIRES:
        raise InputError(f"{where}: {n:,} luminaires, more than the {MAX_LUMINAIRES:,} one plan holds; "
                         "split the site into parts (by floor or wing) and plan each")
    if n < 3:
        raise InputError(
            f"{where}: only {n} luminaire(s) found; positioning needs at least 3 "
            "(check the layer and block patterns, or use `leds` N with a room outline)"
        )
    names = [lum.name for lum in layout.luminaires]
    for name in names:
        problem = name_problem(name)
        if problem:
            raise InputError(f"{where}: luminaire name {name!r} {problem}; names are 1-{MAX_NAME_CHARS} printable "
                             "characters without control characters or spaces at either end")
    if len(set(names)) != n:
        dup = sorted(name for name, count in Counter(names).items() if count > 1)[0]
        raise InputError(f"{where}: luminaire name {dup!r} is used more than once; names must be unique")
    check_tones_all_or_none(layout.luminaires, where)
    xy = layout.xy
    radii = np.array([lum.radius for lum in layout.luminaires])
    if not np.all(np.isfinite(xy)) or not np.all(radii > 0):
        raise InputError(f"{where}: a luminaire has a non-finite position or a radius <= 0")
    for lum in layout.luminaires:  # the bounds plan.yaml's reader holds every plan to (planner.plan.file)
        if (max(abs(lum.x), abs(lum.y)) > MAX_EXTENT_M or not 0 < lum.z <= MAX_HEIGHT_M
                or not MIN_RADIUS_M <= lum.radius <= MAX_RADIUS_M):
            raise InputError(
                f"{where}: luminaire {lum.name!r} at ({lum.x:g}, {lum.y:g}, {lum.z:g}) m, radius {lum.radius:g} m: "
                f"outside what a building holds (|x|, |y| <= {MAX_EXTENT_M:g} m, 0 < z <= {MAX_HEIGHT_M:g} m, "
                f"{MIN_RADIUS_M:g} m <= radius <= {MAX_RADIUS_M:g} m); check the units (`units`), the height "
                "(`mount_height_m`) or the radius (`radius_m`)")
    if layout.outline is not None:
        corners = np.asarray(layout.outline, dtype=float)
        if not np.isfinite(corners).all() or np.abs(corners).max(initial=0.0) > MAX_EXTENT_M:
            raise InputError(f"{where}: the room outline has a corner that is not a number or beyond "
                             f"{MAX_EXTENT_M:g} m; fix the outline's coordinates or its units (`units`)")
    from scipy.spatial import cKDTree  # here, not at import: reading a file and refusing it needs no scipy

    tree = cKDTree(xy)
    # many points and k=2: arrays (the stubs' return type also allows one point's scalars)
    dist, idx = cast("tuple[np.ndarray, np.ndarray]", tree.query(xy, k=2))
    gap = dist[:, 1] - (radii + radii[idx[:, 1]])
    worst = int(np.argmin(gap))
    if gap[worst] < 0:
        a, b = layout.luminaires[worst], layout.luminaires[int(idx[worst, 1])]
        raise InputError(
            f"{where}: luminaires {a.name!r} and {b.name!r} are {dist[worst, 1]:.3f} m apart, "
            f"closer than their diameters; check the units (`units`) or remove the duplicate "
            f"({describe(a)}; {describe(b)})"
        )
    return layout


def check_tones_all_or_none(luminaires: tuple[Luminaire, ...], where: str) -> None:
    """:class:`InputError` unless every luminaire carries ``tone_hz`` (an existing tone site) or none does (the
    planner gives frame IDs): a receiver reads one kind of signal on a site (docs/tones.md)."""
    toned = [lum for lum in luminaires if lum.tone_hz is not None]
    if toned and len(toned) < len(luminaires):
        bare = next(lum for lum in luminaires if lum.tone_hz is None)
        raise InputError(f"{where}: luminaire {bare.name!r} has no tone_hz but {len(toned)} of the "
                         f"{len(luminaires)} luminaires carry one (first {toned[0].name!r}); give every luminaire its "
                         "tone (an existing tone site) or none (the planner then gives frame IDs)")


def describe(lum: Luminaire) -> str:
    """Where a luminaire is and where it came from, for messages: ``L0201: INSERT 1A2 'LED PANEL' on 'E-LITE'
    at (12.3, 4.5) m, radius 0.1 m`` (a DXF entity, a table line or an IFC GlobalId, whichever the source has)."""
    src = lum.source
    if "handle" in src:
        origin = f"{src.get('entity', 'entity')} {src['handle']}" + (f" {src['block']!r}" if "block" in src else "") \
            + (f" on {src['layer']!r}" if "layer" in src else "")
    elif "global_id" in src:
        origin = f"{src.get('entity', 'IFC entity')} {src['global_id']}"
    elif "line" in src:
        origin = f"line {src['line']}"
    else:
        origin = "generated" if src.get("generated") else "given"
    return f"{lum.name}: {origin} at ({lum.x:.3g}, {lum.y:.3g}) m, radius {lum.radius:.3g} m"


def principal_angle_rad(outline: np.ndarray) -> float:
    """Direction of the outline's longest edge [rad], folded into [0, pi/2)."""
    edges = np.diff(np.vstack([outline, outline[:1]]), axis=0)
    lengths = np.hypot(edges[:, 0], edges[:, 1])
    e = edges[int(np.argmax(lengths))]
    return float(math.atan2(e[1], e[0]) % (math.pi / 2))


def fill_outline(
    outline: np.ndarray, count: int, mount_height_m: float, radius_m: float = DEFAULT_RADIUS_M
) -> tuple[list[Luminaire], str]:
    """Lay out ``count`` luminaires on a regular lattice inside a room outline.

    The lattice is aligned to the outline's longest wall and cell-centred (half a
    spacing from the walls). Among lattices of ``c`` columns by ``r`` rows over the
    outline's aligned bounding box, the one with the widest smaller spacing that
    puts at least ``count`` sites inside the outline wins; surplus sites, if any,
    are dropped farthest from the room's centroid first.

    Returns the luminaires (named ``L0001``...) and a one-line description.
    """
    if count < 3:
        raise InputError(f"`leds` {count}: at least 3 luminaires are needed for positioning")
    theta = principal_angle_rad(outline)
    rot = np.array([[math.cos(theta), math.sin(theta)], [-math.sin(theta), math.cos(theta)]])
    local = outline @ rot.T
    lo, hi = local.min(axis=0), local.max(axis=0)
    width, height = hi - lo
    if width <= 0 or height <= 0:
        raise InputError("room outline has no area; draw it as a closed polyline")
    room_m2 = area_m2(outline)
    if count * (2 * radius_m) ** 2 > room_m2:  # even a perfect packing could not keep the discs apart
        raise InputError(f"`leds` {count}: {count:,} luminaires of radius {radius_m:g} m do not fit in the "
                         f"room's {room_m2:.1f} m2; ask for fewer (at most {int(room_m2 / (2 * radius_m) ** 2):,})")
    from matplotlib.path import Path as PolygonPath

    polygon = PolygonPath(local)
    best = None
    for cols in range(1, count + 1):
        sx = width / cols
        if best is not None and sx <= best[0]:
            break
        rows = max(1, math.ceil(count / cols))
        while True:
            sy = height / rows
            spacing = min(sx, sy)
            if best is not None and spacing <= best[0]:
                break
            gx = lo[0] + sx * (np.arange(cols) + 0.5)
            gy = lo[1] + sy * (np.arange(rows) + 0.5)
            pts = np.array([(x, y) for y in gy for x in gx])
            inside = pts[polygon.contains_points(pts)]
            if len(inside) >= count:
                best = (spacing, cols, rows, inside)
                break
            rows += 1
            if rows > 4 * count:
                break
    if best is None:
        raise InputError(f"room outline cannot hold {count} luminaires on a lattice")
    spacing, cols, rows, sites = best
    centre = local.mean(axis=0)
    surplus = len(sites) - count
    if surplus:
        order = np.lexsort((sites[:, 0], sites[:, 1], np.round(np.hypot(*(sites - centre).T), 9)))
        sites = sites[np.sort(order[:count])]
    world = sites @ rot
    lums = [
        Luminaire(f"L{k + 1:04d}", float(x), float(y), mount_height_m, radius_m, {"generated": "lattice"})
        for k, (x, y) in enumerate(world)
    ]
    desc = (
        f"laid out {count} luminaires on a {cols} x {rows} lattice "
        f"({width / cols:.3f} m x {height / rows:.3f} m spacing, {math.degrees(theta):.1f} deg)"
    )
    if surplus:
        desc += f", {surplus} surplus site(s) left empty"
    return lums, desc


def area_m2(polygon: np.ndarray | list[tuple[float, float]]) -> float:
    """Area of a simple polygon (N x 2) [m] [m2] (shoelace formula)."""
    xy = np.asarray(polygon, dtype=float)
    x, y = xy[:, 0], xy[:, 1]
    return float(0.5 * abs(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1))))
