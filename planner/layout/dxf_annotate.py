"""Write an annotated DXF: each luminaire's ID, parity and region as text on layer ``VLP-ID``.

With a source drawing, the annotations are added to a copy of it, in its own
drawing units (the inverse of the scale the reader used); without one (YAML/CSV
input), a new drawing in metres shows a circle per luminaire. Every text carries
XDATA under appid ``VLP_PLAN``: ``(1000, name), (1071, id), (1000, parity),
(1071, region)``. The output is byte-identical for identical inputs.
"""

from __future__ import annotations

import io
import os
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

import ezdxf
from ezdxf.document import Drawing
from ezdxf.enums import TextEntityAlignment

from planner._files import write_bytes_atomically
from planner.defaults import UNIT_TO_M
from planner.errors import InputError, PlannerWarning
from planner.layout.dxf import load_drawing
from planner.layout.model import Layout

if TYPE_CHECKING:
    from planner.plan.file import Entry

__all__ = ["write_annotated_dxf", "dxf_bytes", "fixed_metadata", "ID_LAYER", "LUM_LAYER", "APPID"]

EMPTY_DXF = "empty-r2010-metres.dxf"
"""An empty R2010 drawing in metres ($INSUNITS = 6), made once by ezdxf.new()."""
ID_LAYER = "VLP-ID"
LUM_LAYER = "VLP-LUM"
OUTLINE_LAYER = "VLP-OUTLINE"
APPID = "VLP_PLAN"
TEXT_HEIGHT_PER_RADIUS = 1.5
"""Text height as a multiple of the LED radius, so labels scale with the luminaires."""
MIN_TEXT_HEIGHT_M = 0.05


@contextmanager
def fixed_metadata() -> Iterator[None]:
    """Make ezdxf write fixed dates, GUIDs and marker strings; restore the option afterwards.

    ezdxf stamps ``$TDCREATE``/``$TDUPDATE``, ``$VERSIONGUID``/``$FINGERPRINTGUID`` and its
    own "written by" marker with the current time; ``ezdxf.new`` stamps "created by". Wrap
    both the creation and the writing of a drawing that must be reproducible.
    """
    previous = ezdxf.options.write_fixed_meta_data_for_testing
    ezdxf.options.write_fixed_meta_data_for_testing = True
    try:
        yield
    finally:
        ezdxf.options.write_fixed_meta_data_for_testing = previous


def dxf_bytes(doc: Drawing) -> bytes:
    """The drawing as ASCII DXF bytes, with fixed metadata (reproducible)."""
    stream = io.StringIO()
    with fixed_metadata():
        doc.write(stream)
    return doc.encode(stream.getvalue())




def _same_file(a: Path, b: Path) -> bool:
    if a.resolve() == b.resolve():
        return True
    return a.exists() and b.exists() and os.path.samefile(a, b)


def write_annotated_dxf(
    dest: str | Path,
    layout: Layout,
    entries: Sequence[Entry],
    *,
    source_path: str | Path | None = None,
    tool_version: str = "",
) -> None:
    """Write the annotated drawing to ``dest``.

    Parameters
    ----------
    dest : str or Path
        Output ``.dxf``; never the source drawing.
    layout : Layout
        The layout the plan was made from; ``layout.unit`` gives the drawing unit.
    entries : sequence of planner.plan.file.Entry
        One per luminaire, as the plan holds them (``name``, position and ``radius`` [m], ``id``,
        ``parity``, ``region``).
    source_path : str or Path, optional
        The source DXF to annotate; ``None`` makes a new drawing in metres.
    tool_version : str
        Written into the ``VLP_PLAN`` XDATA of every text, if given.
    """
    dest = Path(dest)
    if source_path is not None:
        source = Path(source_path)
        if _same_file(dest, source):
            raise InputError(f"{dest}: refusing to overwrite the source drawing; choose another output directory")
        doc, notes = load_drawing(source)
        if any(note.startswith("more than") for note in notes):  # a drawing over the loader's cap
            warnings.warn(PlannerWarning(f"{dest.name} holds the luminaires, texts and walls of {source.name}, not "
                                         f"all of it: {notes[-1]}"), stacklevel=2)
        scale = UNIT_TO_M[layout.unit]
        _remove_layer_entities(doc, (ID_LAYER,))
    else:
        # A shipped empty drawing, not ezdxf.new(): new() allocates handles in an order
        # that depends on PYTHONHASHSEED, which made outputs differ between runs.
        with fixed_metadata(), resources.as_file(resources.files("planner") / "data" / EMPTY_DXF) as empty:
            doc = ezdxf.readfile(empty)
        scale = 1.0
        doc.header["$MEASUREMENT"] = 1
        doc.layers.add(LUM_LAYER, color=3)
        if layout.outline:
            doc.layers.add(OUTLINE_LAYER, color=8)
            doc.modelspace().add_lwpolyline(layout.outline, close=True, dxfattribs={"layer": OUTLINE_LAYER})
    if ID_LAYER not in doc.layers:
        doc.layers.add(ID_LAYER, color=1)
    if APPID not in doc.appids:
        doc.appids.add(APPID)
    msp = doc.modelspace()
    for entry in entries:
        radius_m = entry.radius
        where = (entry.x / scale, entry.y / scale, entry.z / scale)
        if source_path is None:
            msp.add_circle(where, radius_m, dxfattribs={"layer": LUM_LAYER})
        height = max(TEXT_HEIGHT_PER_RADIUS * radius_m, MIN_TEXT_HEIGHT_M) / scale
        text = msp.add_text(label(entry), height=height, dxfattribs={"layer": ID_LAYER})
        text.set_placement(where, align=TextEntityAlignment.MIDDLE_CENTER)
        tags = [(1000, entry.name), (1071, entry.id), (1000, entry.parity), (1071, entry.region)]
        if tool_version:
            tags.append((1000, f"vlp-plan {tool_version}"))
        text.set_xdata(APPID, tags)
    write_bytes_atomically(dest, dxf_bytes(doc))


def label(entry: Entry) -> str:
    """Short text for a luminaire: ID, ``o``/``e`` for odd/even, region (``15 o R3``)."""
    return f"{entry.id} {entry.parity[:1]} R{entry.region}"


def _remove_layer_entities(doc: Drawing, layers: tuple[str, ...]) -> None:
    """Delete earlier annotations, so annotating an annotated drawing does not stack texts."""
    msp = doc.modelspace()
    wanted = {name.upper() for name in layers}
    for entity in [e for e in msp if e.dxf.get("layer", "0").upper() in wanted]:
        msp.delete_entity(entity)
