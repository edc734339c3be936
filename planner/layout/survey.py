"""What a drawing holds and what the readers make of it, for ``vlp-inspect``: one plain report per file.

:func:`survey` reads a DXF or IFC drawing as ``vlp-plan`` would and returns a dict (the JSON
``vlp-inspect --json`` prints): layers and blocks (or storeys and entity classes) with counts and
what their names say, what the reader takes and rejects and why, the room outlines, the unit it
chooses with its evidence, and the luminaires it ends with, or the one line it would stop with.
:func:`draw_survey` pictures the candidates over the drawing.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np

from planner.errors import PlannerError
from planner.layout.dxf_names import LUMINAIRE, NEUTRAL, layer_class, name_class
from planner.plot_style import save_png, styled

__all__ = ["survey", "draw_survey"]


def _says(name: str, layer: bool = False) -> str:
    what, word = layer_class(name) if layer else name_class(name)
    return "" if what == NEUTRAL else f"{what} ({word})"


def _named(counter: Counter, layers: bool = False) -> list[dict]:
    return [{"name": name, "count": n, "says": _says(name, layers)}
            for name, n in sorted(counter.items(), key=lambda kv: (-kv[1], kv[0]))]


def _rows(counter: Counter) -> list[dict]:
    return [{"entity": what, "name": name, "layer": layer, "why": why, "count": n}
            for (what, name, layer, why), n in sorted(counter.items(), key=lambda kv: (-kv[1], kv[0]))]


def _read(report: dict, path: Path, leds: int | None, options) -> None:
    """What ``vlp-plan`` would read: the unit, the luminaires and notes, or the error it stops with."""
    from planner.layout.dxf import INSPECT_HINT
    from planner.layout.read import read_layout

    try:
        layout = read_layout(path, leds, options)
    except PlannerError as exc:
        report["error"] = str(exc).replace("; " + INSPECT_HINT.format(path=path), "")
        return
    report.update(unit=layout.unit, unit_reason=layout.unit_reason, luminaires=len(layout.luminaires),
                  notes=list(layout.notes), outline_m=[list(p) for p in layout.outline] if layout.outline else None)


def survey(path: str | Path, leds: int | None = None, options=None) -> dict:
    """The report on ``path`` (``.dxf`` or ``.ifc``) read with ``options`` (a ``planner.layout.read.ReadOptions``)."""
    from planner.layout.read import ReadOptions

    path = Path(path)
    options = options or ReadOptions()
    report: dict = {"file": str(path), "unit": None, "unit_reason": None, "luminaires": None, "notes": [],
                    "error": None}
    try:
        if path.suffix.lower() == ".ifc":
            _survey_ifc(report, path, options)
        else:
            _survey_dxf(report, path, options)
    except PlannerError as exc:  # the file itself cannot be opened: that is the whole report
        report["error"] = str(exc)
        return report
    _read(report, path, leds, options)
    return report


def _survey_dxf(report: dict, path: Path, options) -> None:
    from planner.layout.dxf import scan_dxf
    from planner.layout.dxf_units import INSUNITS_TO_UNIT, UNIT_NAMES

    found, doc, notes = scan_dxf(path, preset=options.preset, layers=list(options.layers) or None,
                                 blocks=list(options.blocks) or None)
    code = int(doc.header.get("$INSUNITS", 0) or 0)
    unit = INSUNITS_TO_UNIT.get(code)
    report.update(
        kind="DXF", header=f"$INSUNITS {code}" + (f" = {UNIT_NAMES[unit]}" if unit else ""),
        selection=found.selector.label, layers=_named(found.layers_seen, layers=True), blocks=_named(found.blocks_seen),
        taken=_rows(found.taken), rejected=_rows(found.rejected), recovered=notes,
        outlines=[{"layer": o.layer, "handle": o.handle, "corners": len(o.points)} for o in found.outlines],
        wall_lines=len(found.segments), coordinates="drawing units",
        points={"taken": [list(p.xyz[:2]) for p in found.parts], "rejected": [[x, y] for x, y, _ in found.rejected_at],
                "outlines": [[list(p) for p in o.points] for o in found.outlines]},
    )


def _survey_ifc(report: dict, path: Path, options) -> None:
    import ifcopenshell.util.element as element
    import ifcopenshell.util.placement as placement
    import ifcopenshell.util.unit as ifc_unit

    from planner.layout.ifc import light_fixtures, open_model, pick_storey, storey_key, storey_of

    model = open_model(path)
    scale = float(ifc_unit.calculate_unit_scale(model))
    fixtures = light_fixtures(model)
    groups: dict[str, list] = {}
    for f in fixtures:
        home = storey_of(f)
        groups.setdefault(storey_key(home), []).append((f, home))
    storeys = Counter({key: len(items) for key, items in groups.items()})
    all_storeys = [s.Name or s.GlobalId for s in model.by_type("IfcBuildingStorey")]
    try:  # the storey read_ifc would read (by name or elevation), if any
        chosen = pick_storey(groups, options.storey, scale, str(path)) if groups else None
    except PlannerError:
        chosen = None
    taken: Counter = Counter()
    rejected: Counter = Counter()
    points: dict = {"taken": [], "rejected": [], "outlines": []}

    def at(entity) -> list[float]:
        if entity.ObjectPlacement is None:
            return [float("nan"), float("nan")]
        return [float(v) * scale for v in placement.get_local_placement(entity.ObjectPlacement)[:2, 3]]

    for f in fixtures:
        key = storey_key(storey_of(f))
        kind = element.get_type(f)
        name = str(kind.Name) if kind is not None and kind.Name else ""
        if key == chosen:
            taken[(f.is_a(), name, key, "light fixture on the chosen storey")] += 1
            points["taken"].append(at(f))
        else:
            why = f"on storey {key!r}, not chosen" if chosen is not None else f"on storey {key!r}: choose with --storey"
            rejected[(f.is_a(), name, key, why)] += 1
            points["rejected"].append(at(f))
    for terminal in model.by_type("IfcFlowTerminal"):
        if terminal in fixtures:
            continue
        kind = element.get_type(terminal)
        why = (f"a flow terminal typed {kind.is_a() if kind is not None else 'by nothing'}, not IfcLightFixtureType"
               if terminal.is_a("IfcFlowTerminal") and terminal.is_a() == "IfcFlowTerminal"
               else f"an {terminal.is_a()}, not a light fixture")
        rejected[(terminal.is_a(), str(terminal.Name or ""), storey_key(storey_of(terminal)), why)] += 1
        points["rejected"].append(at(terminal))
    for proxy in model.by_type("IfcBuildingElementProxy"):
        if name_class(str(proxy.Name or ""))[0] not in (NEUTRAL,):
            rejected[("IfcBuildingElementProxy", str(proxy.Name), storey_key(storey_of(proxy)),
                      "a proxy, not a light fixture (export lights as IfcLightFixture)"
                      if name_class(str(proxy.Name))[0] == LUMINAIRE else f"a proxy named as {_says(str(proxy.Name))}")] += 1
            points["rejected"].append(at(proxy))
    classes = Counter(e.is_a() for e in model.by_type("IfcProduct"))
    report.update(
        kind="IFC", header=f"{model.schema}, length unit {scale:g} m", selection=f"storey {chosen!r}" if chosen else
        "no storey chosen", storeys=[{"name": k, "count": storeys.get(k, 0), "says": ""} for k in
                                     dict.fromkeys(all_storeys + list(storeys))],
        layers=[], blocks=[{"name": k, "count": n, "says": ""} for k, n in sorted(classes.items(), key=lambda kv: -kv[1])],
        taken=_rows(taken), rejected=_rows(rejected), recovered=[], outlines=[], coordinates="m", points=points,
    )


@styled
def draw_survey(report: dict, path: str | Path) -> None:
    """Picture the candidates over the drawing: outlines, taken (black dots) and rejected (grey crosses)."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 6.5), dpi=110)
    if report.get("kind") == "DXF":
        _draw_drawing(ax, Path(report["file"]))
    pts = report.get("points") or {}
    for k, corners in enumerate(pts.get("outlines", [])):
        ring = np.asarray(corners + corners[:1], dtype=float)
        ax.plot(ring[:, 0], ring[:, 1], color="0.6", linewidth=0.8, label="room / wall outline" if k == 0 else None)
    for key, marker, shade, size in (("rejected", "x", "0.55", 18), ("taken", "o", "black", 14)):
        xy = np.asarray(pts.get(key, []), dtype=float).reshape(-1, 2)
        if len(xy):
            ax.scatter(xy[:, 0], xy[:, 1], marker=marker, color=shade, s=size, label=f"{key} ({len(xy)})", zorder=3)
    ax.set_aspect("equal", adjustable="datalim")
    unit = report.get("coordinates", "drawing units")
    ax.set_xlabel(f"x [{unit}]")
    ax.set_ylabel(f"y [{unit}]")
    result = (f"{report['luminaires']} luminaires, unit {report['unit']}" if report.get("luminaires") is not None
              else "vlp-plan would stop")
    ax.set_title(f"{Path(report['file']).name}: {result}")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="best")
    save_png(fig, path)


_MAX_PRIMITIVES = 200_000
"""Most drawing primitives pictured under the candidates (a huge drawing is cut there)."""


def _draw_drawing(ax, path: Path) -> None:
    """The DXF's model space (blocks exploded) as thin grey lines under the candidates; skipped if it fails."""
    try:
        from itertools import islice

        from ezdxf import disassemble
        from matplotlib.collections import LineCollection

        from planner.layout.dxf import load_drawing

        doc, _ = load_drawing(path)
        primitives = disassemble.to_primitives(disassemble.recursive_decompose(doc.modelspace()))
        lines = []
        for primitive in islice(primitives, _MAX_PRIMITIVES):
            points = [(v.x, v.y) for v in primitive.vertices()]
            if len(points) >= 2:
                lines.append(points)
        ax.add_collection(LineCollection(lines, colors="0.78", linewidths=0.4, zorder=1))
        ax.autoscale_view()
    except Exception:  # the picture is a help: a drawing that cannot be exploded still gets its candidates drawn
        pass
