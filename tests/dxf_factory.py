"""Build test drawings with ezdxf, the way DIALux, Revit and an architect's CAD draw them.

Each builder returns ``(doc, expected)`` where ``expected`` is an ``(N, 3)`` array of the
luminaire centres in metres, sorted by (y, x) like the reader names them. ``save`` writes a
drawing reproducibly. ``python tests/dxf_factory.py`` rewrites the bundled examples in
``layouts/``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import ezdxf
import numpy as np
from ezdxf.document import Drawing

from planner.layout.dxf_annotate import dxf_bytes, fixed_metadata

INSUNITS = {"in": 1, "ft": 2, "mm": 4, "cm": 5, "m": 6}
DLX_LAYER = "DLX_BLD1_FL0_LUM 1"
DLX_NESTED_LAYER = "DLX_BLD1_FL0_LUM 2"


def new_drawing(insunits: int, version: str = "R2000") -> Drawing:
    """An empty drawing with fixed metadata and the given ``$INSUNITS`` code."""
    with fixed_metadata():
        doc = ezdxf.new(version)
    doc.header["$INSUNITS"] = insunits
    return doc


def save(doc: Drawing, path: str | Path) -> Path:
    """Write ``doc`` to ``path`` byte-reproducibly."""
    path = Path(path)
    path.write_bytes(dxf_bytes(doc))
    return path


def _sorted(xyz: list) -> np.ndarray:
    arr = np.array(xyz, dtype=float).reshape(-1, 3)
    return arr[np.lexsort((arr[:, 0], arr[:, 1]))]


def _rectangle(block, w: float, h: float) -> None:
    block.add_lwpolyline([(-w / 2, -h / 2), (w / 2, -h / 2), (w / 2, h / 2), (-w / 2, h / 2)], close=True)


def dialux_office(
    cols: int = 6, rows: int = 8, spacing_mm: float = 2400.0, height_mm: float = 2800.0, *, extras: bool = True
) -> tuple[Drawing, np.ndarray]:
    """A DIALux-style office: millimetre coordinates with ``$INSUNITS`` = 1 (inches, a lie).

    Row 0 is a MINSERT array; row 1 sits in a block ``ZONE_A`` (base point (1000, 500),
    inserted rotated by 180 degrees); the other rows are drawn as 2 or 3 INSERTs at one
    point (housing with a 125 mm LED circle, symbol, and every other one a direction
    mark). ``extras`` adds a room outline, a table 150 m away and a text far away.
    """
    s, z = spacing_mm, height_mm
    doc = new_drawing(1)
    for layer in (DLX_LAYER, DLX_NESTED_LAYER, "DLX_BLD1_FL0_ROOM 1", "FURNITURE", "TEXT"):
        doc.layers.add(layer)
    housing = doc.blocks.new("DLX_LUM_1")
    _rectangle(housing, 600, 600)
    housing.add_circle((0, 0), 125)
    symbol = doc.blocks.new("DLX_LUM_1_SYM")
    symbol.add_line((-300, -300), (300, 300))
    symbol.add_line((-300, 300), (300, -300))
    direction = doc.blocks.new("DLX_LUM_1_DIR")
    direction.add_line((0, 0), (400, 0))
    zone = doc.blocks.new("ZONE_A", base_point=(1000, 500))
    for i in range(cols):
        zone.add_blockref("DLX_LUM_1", (1000 + i * s, 500), dxfattribs={"layer": DLX_NESTED_LAYER})
    msp = doc.modelspace()
    expected = []
    msp.add_blockref("DLX_LUM_1", (s / 2, s / 2, z), dxfattribs={"layer": DLX_LAYER}).grid(
        size=(1, cols), spacing=(s, s)
    )
    expected += [(s / 2 + i * s, s / 2, z) for i in range(cols)]
    if rows > 1:
        corner = (s / 2 + (cols - 1) * s, s / 2 + s, z)
        msp.add_blockref("ZONE_A", corner, dxfattribs={"rotation": 180})
        expected += [(s / 2 + i * s, s / 2 + s, z) for i in range(cols)]
    for j in range(2, rows):
        for i in range(cols):
            at = (s / 2 + i * s, s / 2 + j * s, z)
            names = ["DLX_LUM_1", "DLX_LUM_1_SYM"] + (["DLX_LUM_1_DIR"] if (i + j) % 2 else [])
            for name in names:
                msp.add_blockref(name, at, dxfattribs={"layer": DLX_LAYER})
            expected.append(at)
    if extras:
        msp.add_lwpolyline(
            [(0, 0), (cols * s, 0), (cols * s, rows * s), (0, rows * s)],
            close=True,
            dxfattribs={"layer": "DLX_BLD1_FL0_ROOM 1"},
        )
        table = doc.blocks.new("TABLE")
        _rectangle(table, 1600, 800)
        for at in ((s, s), (3 * s, s), (150_000, 0)):
            msp.add_blockref("TABLE", at, dxfattribs={"layer": "FURNITURE"})
        msp.add_text("DIALux evo export", height=500, dxfattribs={"layer": "TEXT", "insert": (1e6, 1e6)})
    return doc, _sorted(expected) / 1000.0


def revit_office(
    unit: str = "ft", cols: int = 5, rows: int = 4, spacing_m: float = 2.4, height_m: float = 0.0
) -> tuple[Drawing, np.ndarray]:
    """A Revit-style plan: downlights on ``E-LITE``/``E-LITE-EMER`` with element ids in XDATA.

    Coordinates are in ``unit``; a light switch on ``E-LITE-SWCH`` must not count. The
    element id of luminaire ``k`` (in drawing order) is ``300000 + k``: integers as
    1071 tags, every third one as a string tag.
    """
    per_m = 1.0 / {"ft": 0.3048, "m": 1.0, "mm": 0.001, "in": 0.0254}[unit]
    doc = new_drawing(INSUNITS[unit], "R2013")
    doc.appids.add("REVIT")
    for layer in ("E-LITE", "E-LITE-EMER", "E-LITE-SWCH", "A-WALL"):
        doc.layers.add(layer)
    light = doc.blocks.new("Downlight - 150mm")
    light.add_circle((0, 0), 0.075 * per_m)
    switch = doc.blocks.new("Lighting Switch")
    switch.add_circle((0, 0), 0.05 * per_m)
    msp = doc.modelspace()
    expected = []
    for k in range(cols * rows):
        i, j = k % cols, k // cols
        x, y = (1.2 + i * spacing_m), (1.2 + j * spacing_m)
        layer = "E-LITE-EMER" if k % 7 == 3 else "E-LITE"
        ref = msp.add_blockref("Downlight - 150mm", (x * per_m, y * per_m, height_m * per_m), dxfattribs={"layer": layer})
        ref.set_xdata("REVIT", [(1000, str(300000 + k))] if k % 3 == 2 else [(1071, 300000 + k)])
        expected.append((x, y, height_m))
    sw = msp.add_blockref("Lighting Switch", (0.3 * per_m, 0.3 * per_m, 1.1 * per_m), dxfattribs={"layer": "E-LITE-SWCH"})
    sw.set_xdata("REVIT", [(1071, 999999)])
    return doc, _sorted(expected)


def outline_room(width_m: float = 32.0, depth_m: float = 16.0, unit: str = "m") -> Drawing:
    """A room outline only: walls as a closed polyline on ``A-WALL``, a column, a door line."""
    per_m = 1.0 / {"m": 1.0, "mm": 0.001, "ft": 0.3048}[unit]
    doc = new_drawing(INSUNITS[unit])
    for layer in ("A-WALL", "A-DOOR"):
        doc.layers.add(layer)
    msp = doc.modelspace()
    w, d = width_m * per_m, depth_m * per_m
    msp.add_lwpolyline([(0, 0), (w, 0), (w, d), (0, d)], close=True, dxfattribs={"layer": "A-WALL"})
    c = 0.4 * per_m
    msp.add_lwpolyline([(w / 2, d / 2), (w / 2 + c, d / 2), (w / 2 + c, d / 2 + c), (w / 2, d / 2 + c)],
                       close=True, dxfattribs={"layer": "A-WALL"})
    msp.add_line((w / 4, 0), (w / 4 + 0.9 * per_m, 0), dxfattribs={"layer": "A-DOOR"})
    return doc


def no_luminaires() -> Drawing:
    """12 lines on layer 0, 3 tables on FURNITURE, 1 closed polyline on WALLS: nothing to light."""
    doc = new_drawing(6)
    doc.layers.add("FURNITURE")
    doc.layers.add("WALLS")
    table = doc.blocks.new("TABLE")
    _rectangle(table, 1.6, 0.8)
    msp = doc.modelspace()
    for k in range(12):
        msp.add_line((k, 0), (k, 5))
    for k in range(3):
        msp.add_blockref("TABLE", (2 + 3 * k, 2), dxfattribs={"layer": "FURNITURE"})
    msp.add_lwpolyline([(0, 0), (12, 0), (12, 6), (0, 6)], close=True, dxfattribs={"layer": "WALLS"})
    return doc


def circles_grid(
    insunits: int, per_m: float, spacing_m: float, cols: int = 4, rows: int = 3, height_m: float = 0.0,
    layer: str = "LIGHTING", radius_m: float = 0.1, mirrored: bool = False,
) -> tuple[Drawing, np.ndarray]:
    """Luminaires as CIRCLEs; ``per_m`` drawing units per metre. ``mirrored`` draws them
    with extrusion (0, 0, -1), as mirrored CAD geometry is: OCS (x, y, z) is WCS (-x, y, -z)."""
    doc = new_drawing(insunits)
    msp = doc.modelspace()
    expected = []
    for j in range(rows):
        for i in range(cols):
            x, y, z = (i + 0.5) * spacing_m, (j + 0.5) * spacing_m, height_m
            attribs = {"layer": layer}
            centre = (x * per_m, y * per_m, z * per_m)
            if mirrored:
                attribs["extrusion"] = (0, 0, -1)
                centre = (-x * per_m, y * per_m, -z * per_m)
            msp.add_circle(centre, radius_m * per_m, dxfattribs=attribs)
            expected.append((x, y, z))
    return doc, _sorted(expected)


LIGHT_POINT = "LIGHT POINT CONTROLLED BY TWO WAY SWITCH"


def residential(z_noise: tuple[float, ...] = (9.9e-13, -1.5e-4), insunits: int = 4, cols: int = 4, rows: int = 3,
                spacing_mm: float = 3000.0, unknown: int = 0) -> tuple[Drawing, np.ndarray]:
    """A residential electrical layout as real ones are drawn (millimetres), with what misled the reader.

    ``cols x rows`` ceiling lights, blocks ``LIGHT POINT CONTROLLED BY TWO WAY SWITCH`` on layer
    ``E-LIGHTING`` with a 100 mm circle, Z = the ``z_noise`` values in turn. On the same layer: two-way
    switches (two circles each), ceiling fans (a circle and blades), a wall light, an exit sign, a socket
    and a PIR sensor, each with circles inside. Elsewhere: ``COLUMN`` blocks, ``_ClosedFilled`` arrows,
    ``SATELLITE`` and ``CLAMP`` blocks, a circle on ``A-FLOR-TILED``. ``unknown`` adds that many blocks
    of a meaningless name (``A$C1F2``) with a circle on the lighting layer, between the lights.
    Expected: the lights only, at Z = 0 (no height in the drawing).
    """
    doc = new_drawing(insunits, "R2013")
    for layer in ("E-LIGHTING", "A-COLUMN", "A-FLOR-TILED", "A-ANNO-DIMS", "E-EQPM"):
        doc.layers.add(layer)
    light = doc.blocks.new(LIGHT_POINT)
    light.add_circle((0, 0), 100)
    light.add_line((-100, -100), (100, 100))
    switch = doc.blocks.new("TWO WAY SWITCH")
    switch.add_circle((0, 0), 40)
    switch.add_circle((120, 0), 40)
    fan = doc.blocks.new("CEILING FAN")
    fan.add_circle((0, 0), 150)
    for angle in (0, 120, 240):
        fan.add_line((0, 0), (600 * np.cos(np.radians(angle)), 600 * np.sin(np.radians(angle))))
    for name in ("WALL LIGHT", "EXIT SIGN", "SOCKET 6A", "PIR SENSOR", "SATELLITE", "CLAMP", "COLUMN", "_ClosedFilled"):
        doc.blocks.new(name).add_circle((0, 0), 80)
    mystery = doc.blocks.new("A$C1F2")
    mystery.add_circle((0, 0), 60)
    msp = doc.modelspace()
    expected = []
    for k in range(cols * rows):
        i, j = k % cols, k // cols
        x, y = 1500 + i * spacing_mm, 1500 + j * spacing_mm
        msp.add_blockref(LIGHT_POINT, (x, y, z_noise[k % len(z_noise)]), dxfattribs={"layer": "E-LIGHTING"})
        expected.append((x / 1000, y / 1000, 0.0))
        msp.add_blockref("TWO WAY SWITCH", (x + 1400, y - 1400, 1.2e-12), dxfattribs={"layer": "E-LIGHTING"})
        if k % 2:
            msp.add_blockref("CEILING FAN", (x + 1500, y, 0), dxfattribs={"layer": "E-LIGHTING"})
        if k < unknown:
            msp.add_blockref("A$C1F2", (x + 700, y + 700, 0), dxfattribs={"layer": "E-LIGHTING"})
    for k, name in enumerate(("WALL LIGHT", "EXIT SIGN", "SOCKET 6A", "PIR SENSOR")):
        msp.add_blockref(name, (k * 2000.0 + 700, 100.0, 0), dxfattribs={"layer": "E-LIGHTING"})
    for k in range(6):
        msp.add_blockref("COLUMN", (k * 4000.0, 9000.0), dxfattribs={"layer": "A-COLUMN"})
        msp.add_blockref("_ClosedFilled", (k * 4000.0 + 500, 9500.0), dxfattribs={"layer": "A-ANNO-DIMS"})
    msp.add_blockref("SATELLITE", (500.0, 9800.0), dxfattribs={"layer": "E-EQPM"})
    msp.add_blockref("CLAMP", (900.0, 9800.0), dxfattribs={"layer": "E-EQPM"})
    msp.add_circle((3000.0, 9800.0), 300, dxfattribs={"layer": "A-FLOR-TILED"})
    return doc, _sorted(expected)


def office_48(spacing_mm: float = 2400.0):
    """A millimetre office of 48 ``LED PANEL 600`` luminaires at 2.4 m (6 x 8) on ``E-LIGHTING``, with
    light switches, ``COLUMN`` blocks (a 400 mm square) and a ``COL-2`` block on the same layer, and
    a room outline on ``A-WALL``. Returns the drawing and the luminaires' centres [m]."""
    doc = new_drawing(4, "R2013")
    for layer in ("E-LIGHTING", "A-WALL"):
        doc.layers.add(layer)
    panel = doc.blocks.new("LED PANEL 600")
    _rectangle(panel, 600, 600)
    doc.blocks.new("SWITCH 2G").add_circle((0, 0), 40)
    _rectangle(doc.blocks.new("COLUMN"), 400, 400)
    _rectangle(doc.blocks.new("COL-2"), 500, 500)
    msp = doc.modelspace()
    s = spacing_mm
    centres = []
    for j in range(8):
        for i in range(6):
            x, y = s / 2 + i * s, s / 2 + j * s
            msp.add_blockref("LED PANEL 600", (x, y, 2800), dxfattribs={"layer": "E-LIGHTING"})
            centres.append((x / 1000, y / 1000))
    for j in range(1, 8, 2):
        msp.add_blockref("SWITCH 2G", (100, j * s), dxfattribs={"layer": "E-LIGHTING"})
        for i in (2, 4):
            msp.add_blockref("COLUMN", (i * s, j * s), dxfattribs={"layer": "E-LIGHTING"})
    msp.add_blockref("COL-2", (3 * s, 4 * s), dxfattribs={"layer": "E-LIGHTING"})
    msp.add_lwpolyline([(0, 0), (6 * s, 0), (6 * s, 8 * s), (0, 8 * s)], close=True, dxfattribs={"layer": "A-WALL"})
    return doc, np.array(sorted(centres, key=lambda p: (p[1], p[0])))


def nested_blocks(path: str | Path, inner: str = "circle", levels: int = 4) -> Path:
    """Blocks nesting blocks, ten references a level: ``10**levels`` copies of one ``inner`` entity (a luminaire
    CIRCLE or a LINE) from one reference in the model space."""
    doc = ezdxf.new("R2010")
    doc.header["$INSUNITS"] = 4
    b = doc.blocks.new("B0")
    if inner == "circle":
        b.add_circle((0, 0), 100, dxfattribs={"layer": "LIGHTS"})
    else:
        b.add_line((0, 0), (100, 0))
    for level in range(1, levels + 1):
        blk = doc.blocks.new(f"B{level}")
        for k in range(10):
            blk.add_blockref(f"B{level - 1}", (k * 2400 * 10 ** (level - 1), 0))
    doc.modelspace().add_blockref(f"B{levels}", (0, 0))
    doc.saveas(path)
    return path


def converted_panels(cols: int = 5, rows: int = 4, spacing_mm: float = 2400.0, offset_mm: float = 120.0
                     ) -> tuple[Drawing, np.ndarray]:
    """A DWG converted to DXF: ``$INSUNITS`` = metres over millimetre geometry, circle-less symbols.

    Each luminaire is a 600 mm square panel ``LED PANEL 600`` (no circle) on ``E-LITE`` with its lamp
    mark ``LED PANEL 600 MARK`` (two crossed lines) drawn ``offset_mm`` off the panel's base point.
    Expected: one luminaire per panel, radius 0.3 m (half the panel), heights from Z = 2800 mm.
    """
    doc = new_drawing(6, "R2013")
    doc.layers.add("E-LITE")
    panel = doc.blocks.new("LED PANEL 600")
    _rectangle(panel, 600, 600)
    mark = doc.blocks.new("LED PANEL 600 MARK")
    mark.add_line((-200, -200), (200, 200))
    mark.add_line((-200, 200), (200, -200))
    msp = doc.modelspace()
    expected = []
    for j in range(rows):
        for i in range(cols):
            x, y = 1200 + i * spacing_mm, 1200 + j * spacing_mm
            msp.add_blockref("LED PANEL 600", (x, y, 2800), dxfattribs={"layer": "E-LITE"})
            msp.add_blockref("LED PANEL 600 MARK", (x + offset_mm, y, 2800), dxfattribs={"layer": "E-LITE"})
            expected.append(((x + offset_mm / 2) / 1000, y / 1000, 2.8))
    return doc, _sorted(expected)


FLOOR_ROOMS = {  # name -> (x0, y0, x1, y1) [m]: two offices and a corridor, 0.2 m walls between
    "OFFICE 1": (0.0, 0.0, 10.0, 7.0),
    "OFFICE 2": (10.2, 0.0, 20.2, 7.0),
    "CORRIDOR": (0.0, 7.2, 20.2, 12.2),
}


def multi_room_floor(unit: str = "mm") -> Drawing:
    """A floor plan of three rooms on ``A-WALL`` (each its own closed polyline, walls 0.2 m thick), a
    column inside one, room names as TEXT, and 24 downlights (``DOWNLIGHT`` blocks) 2.5 m apart."""
    per_m = 1.0 / {"m": 1.0, "mm": 0.001}[unit]
    doc = new_drawing(INSUNITS[unit], "R2013")
    for layer in ("A-WALL", "A-AREA-IDEN", "E-LITE"):
        doc.layers.add(layer)
    msp = doc.modelspace()
    for name, (x0, y0, x1, y1) in FLOOR_ROOMS.items():
        corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
        msp.add_lwpolyline([(x * per_m, y * per_m) for x, y in corners], close=True, dxfattribs={"layer": "A-WALL"})
        msp.add_text(name, height=0.3 * per_m, dxfattribs={"layer": "A-AREA-IDEN",
                                                            "insert": ((x0 + 1) * per_m, (y0 + 1) * per_m)})
    c = 0.4 * per_m
    msp.add_lwpolyline([(5 * per_m, 3 * per_m), (5 * per_m + c, 3 * per_m), (5 * per_m + c, 3 * per_m + c),
                        (5 * per_m, 3 * per_m + c)], close=True, dxfattribs={"layer": "A-WALL"})
    down = doc.blocks.new("DOWNLIGHT")
    down.add_circle((0, 0), 0.08 * per_m)
    for j in range(3):
        for i in range(8):
            msp.add_blockref("DOWNLIGHT", ((1.25 + 2.5 * i) * per_m, (1.5 + 2.5 * j + 0.7 * (j == 2)) * per_m, 0),
                             dxfattribs={"layer": "E-LITE"})
    return doc


def dynamic_blocks(count: int = 6) -> tuple[Drawing, np.ndarray]:
    """Dynamic blocks as AutoCAD saves them: each insert references an anonymous block (``*U1``...) whose
    block record points (XDATA ``AcDbBlockRepBTag``) to the dynamic block it draws, ``CEILING LIGHT`` or
    ``TWO WAY SWITCH``; all on layer ``E-POWER-LIGHTING`` with a circle inside. Expected: the lights."""
    doc = new_drawing(6, "R2013")
    for appid in ("AcDbDynamicBlockGUID", "AcDbBlockRepBTag"):
        doc.appids.add(appid)
    doc.layers.add("E-POWER-LIGHTING")
    msp = doc.modelspace()
    expected = []
    for name, per_block in (("CEILING LIGHT", 1.0), ("TWO WAY SWITCH", 0.0)):
        dynamic = doc.blocks.new(name)
        dynamic.add_circle((0, 0), 0.1)
        dynamic.block_record.set_xdata("AcDbDynamicBlockGUID", [(1000, "{00000000-0000-0000-0000-000000000001}")])
        for k in range(count):
            anonymous = doc.blocks.new_anonymous_block("U")
            anonymous.add_circle((0, 0), 0.1)
            anonymous.block_record.set_xdata("AcDbBlockRepBTag", [(1070, 1), (1005, dynamic.block_record.dxf.handle)])
            at = (2.0 * k, 3.0 if per_block else 1.0, 2.8)
            msp.add_blockref(anonymous.name, at, dxfattribs={"layer": "E-POWER-LIGHTING"})
            if per_block:
                expected.append(at)
    return doc, _sorted(expected)


def corrupt_missing_endsec(src: str | Path, dst: str | Path) -> Path:
    """Copy a DXF, dropping the ENDSEC that closes its ENTITIES section.

    ``ezdxf.readfile`` rejects that with ``DXFStructureError: missing ENDSEC tag``;
    ``ezdxf.recover`` reads it and its auditor reports the fix.
    """
    lines = Path(src).read_text(encoding="utf-8").splitlines(keepends=True)
    start = next(k for k in range(len(lines) - 1) if lines[k].strip() == "2" and lines[k + 1].strip() == "ENTITIES")
    end = next(k for k in range(start, len(lines) - 1) if lines[k].strip() == "0" and lines[k + 1].strip() == "ENDSEC")
    del lines[end:end + 2]
    Path(dst).write_text("".join(lines), encoding="utf-8")
    return Path(dst)


def write_examples(folder: str | Path) -> None:
    """Write the bundled examples ``dialux-office.dxf`` and ``outline-room.dxf``."""
    folder = Path(folder)
    doc, _ = dialux_office()
    save(doc, folder / "dialux-office.dxf")
    save(outline_room(), folder / "outline-room.dxf")


if __name__ == "__main__":
    write_examples(Path(__file__).resolve().parents[1] / "layouts")
    print("wrote layouts/dialux-office.dxf and layouts/outline-room.dxf", file=sys.stderr)
