"""Open a DXF drawing within a memory budget: ezdxf's tag stream, skimmed before ezdxf builds the document.

ezdxf keeps every entity of a drawing in memory (about 2 KB and 70 us each, measured in
``docs/performance.md``), yet the reader uses only a few kinds: block references, circles and
points (luminaires), texts (room names) and lines and polylines on wall and room layers
(the outline). :func:`open_drawing` feeds ezdxf's own tag loader (``ascii_tags_loader`` or
``binary_tags_loader``, as ``ezdxf.readfile`` picks them) through a filter that drops every
other model-space entity as it streams past, counting it by layer, so furniture, hatches,
dimensions and 3D detail cost a pass over their text and no memory. At most
:data:`MAX_DXF_ENTITIES` entities are loaded; a drawing that needs more is refused with one line
naming the count, the cap and what to do. A file over :data:`MAX_DXF_BYTES` is refused before
it is read.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import ezdxf
from ezdxf import recover
from ezdxf.document import Drawing
from ezdxf.filemanagement import dxf_file_info
from ezdxf.lldxf.tagger import ascii_tags_loader, binary_tags_loader
from ezdxf.lldxf.types import DXFTag
from ezdxf.lldxf.validator import is_binary_dxf_file, is_dwg_file, is_dxf_file

from planner.errors import InputError
from planner.layout.dxf_scan import outline_layer

__all__ = ["MAX_DXF_ENTITIES", "MAX_DXF_BYTES", "MAX_RECOVER_BYTES", "Loaded", "open_drawing"]

MAX_DXF_ENTITIES = 400_000
"""Most entities ezdxf loads from one drawing (about 1 GB and 30 s): 100,000 luminaires drawn as 2-3 block
references each, with their texts and walls. Entities the reader does not use do not count."""

MAX_DXF_BYTES = 2 << 30
"""Largest DXF file read [bytes] (2 GiB: about 16 million simple entities, a few minutes to skim)."""

MAX_RECOVER_BYTES = 64 << 20
"""Largest damaged DXF file recovered [bytes]: ``ezdxf.recover`` loads all of it, so the cap is the entity cap's
size (about 500,000 entities of 120 bytes)."""

PRECOUNT_BYTES = 16 << 20
"""ASCII files larger than this [bytes] are counted before ezdxf reads them; in a smaller file ezdxf holds at most
the cap's entities before the filter stops it (a few hundred MB at worst), and is spared the second pass."""

USED = frozenset({"INSERT", "CIRCLE", "POINT", "TEXT", "MTEXT"})
"""Entity kinds the reader takes anywhere in the model space."""
WALLS = frozenset({"LINE", "LWPOLYLINE", "POLYLINE"})
"""Entity kinds the reader takes on wall and room layers (:func:`planner.layout.dxf_scan.outline_layer`)."""
_STRUCTURE = frozenset({"ENDSEC", "SECTION", "EOF"})
"""Tags that end the ENTITIES section (the last two in a file missing its ENDSEC: ezdxf then says so)."""
_FOLLOWERS = frozenset({"VERTEX", "SEQEND", "ATTRIB"})
"""Entities that belong to the POLYLINE or INSERT before them, kept or dropped with it."""


class _TooMany(Exception):
    """More entities to load than the cap allows."""


@dataclass
class Loaded:
    """A drawing as loaded: the document, notes on what was recovered or left out, the model-space entities
    skimmed past per layer, and whether the document holds all of the drawing."""

    doc: Drawing
    notes: list[str] = field(default_factory=list)
    skipped: Counter = field(default_factory=Counter)
    whole: bool = True


class _Skim:
    """The filter over a tag stream: in the ENTITIES section, entities of kinds the reader does not use are
    dropped (``everything`` keeps them) and counted by layer; more than ``cap`` entities loaded (in any section)
    raises :class:`_TooMany`."""

    def __init__(self, everything: bool, cap: int):
        self.everything, self.cap = everything, cap
        self.loaded = 0
        self.skipped: Counter = Counter()
        self._owner_kept = True

    def __call__(self, tags: Iterator[DXFTag]) -> Iterator[DXFTag]:
        in_entities = after_section = False
        entity: list[DXFTag] = []
        for tag in tags:
            code, value = tag
            if code == 0:
                if entity and self._keep(entity):
                    yield from entity
                entity = []
                if in_entities and value not in _STRUCTURE:
                    entity.append(tag)
                    continue
                in_entities = after_section = False
                if value == "SECTION":
                    after_section = True
                else:
                    self._count()
            elif entity:
                entity.append(tag)
                continue
            elif after_section and code == 2:
                in_entities = str(value).strip() == "ENTITIES"
                after_section = False
            yield tag
        if entity:  # a file cut off inside ENTITIES: ezdxf says so
            yield from entity

    def _count(self) -> None:
        self.loaded += 1
        if self.loaded > self.cap:
            raise _TooMany

    def _keep(self, entity: list[DXFTag]) -> bool:
        """Whether to load this entity of the ENTITIES section (VERTEX, SEQEND and ATTRIB go with their owner)."""
        kind = str(entity[0][1]).strip()
        if kind in _FOLLOWERS:
            keep = self._owner_kept
        else:
            layer = next((str(v) for c, v in entity if c == 8), "0")
            keep = self.everything or kind in USED or (kind in WALLS and outline_layer(layer))
            if not keep and not any(c == 67 and str(v).strip() == "1" for c, v in entity):  # 67 = 1: paper space
                self.skipped[layer] += 1
            self._owner_kept = keep
        if keep:
            self._count()
        return keep


def _tags(where: str, binary: bool) -> Iterator[DXFTag]:
    """The file's tags from ezdxf's own loaders, in the encoding ``ezdxf.readfile`` would use."""
    if binary:
        with open(where, "rb") as fp:
            data = fp.read()
        yield from binary_tags_loader(data, errors="surrogateescape")
        return
    info = dxf_file_info(where)
    with open(where, encoding=info.encoding, errors="surrogateescape") as fp:
        yield from ascii_tags_loader(fp)


def _pairs(where: str) -> Iterator[tuple[int, str]]:
    """(group code, value) of every tag of an ASCII DXF, read three times faster than ezdxf's tag loader and
    checked less (decoded as Latin-1, which cannot fail): for counting before ezdxf reads the file."""
    with open(where, encoding="latin-1", newline=None) as fp:
        for code, value in zip(fp, fp):
            try:
                yield int(code), value.rstrip("\n")
            except ValueError:  # no group code: ezdxf's loader names the line
                return


def _load(where: str, size: int, binary: bool, everything: bool) -> tuple[Drawing, _Skim]:
    """Count what would be loaded (ASCII files over :data:`PRECOUNT_BYTES`: a cheap pass, so a drawing over the cap
    costs no memory), then load it through the filter; raises :class:`_TooMany` when over the cap."""
    if not binary and size > PRECOUNT_BYTES:  # a binary DXF is read whole by ezdxf's loader anyway
        for _ in _Skim(everything, MAX_DXF_ENTITIES)(_pairs(where)):  # type: ignore[arg-type]
            pass
    skim = _Skim(everything, MAX_DXF_ENTITIES)
    doc = Drawing.load(skim(_tags(where, binary)))
    doc.filename = where
    return doc, skim


def open_drawing(path: str | Path, *, everything: bool = False) -> Loaded:
    """Open a DXF file, recovering a damaged one, within :data:`MAX_DXF_ENTITIES`.

    ``everything=False`` loads only what the reader uses (the rest is counted in ``skipped``);
    ``everything=True`` loads the whole drawing for a copy or a picture, or, when it holds more than the cap,
    what the reader uses (``whole`` is then False).
    """
    path = Path(path)
    where = str(path)
    if not path.is_file():
        raise InputError(f"{where}: file not found; check the path")
    try:
        binary = is_binary_dxf_file(where)
        is_dxf = binary or is_dxf_file(where)
        is_dwg = not is_dxf and is_dwg_file(where)
        size = path.stat().st_size
    except OSError as exc:
        raise InputError(f"{where}: cannot read the file ({exc.strerror or exc}); check its permissions") from exc
    if is_dwg:
        raise InputError(f"{where}: this is a DWG file, not DXF; save it as DXF from the CAD program")
    if not is_dxf:
        raise InputError(f"{where}: not a DXF file; export the drawing as DXF, or give a .yaml/.csv layout")
    if size > MAX_DXF_BYTES:
        raise InputError(f"{where}: {size:,} bytes, more than the {MAX_DXF_BYTES:,} a drawing may have; split it, "
                         "or delete what the plan does not need (furniture, hatches, 3D) and export again")
    try:
        try:
            doc, skim = _load(where, size, binary, everything)
        except _TooMany:
            if not everything:
                raise
            doc, skim = _load(where, size, binary, False)
            return Loaded(doc, [], skim.skipped, whole=False)
        return Loaded(doc, [], skim.skipped)
    except _TooMany:
        raise InputError(
            f"{where}: more than {MAX_DXF_ENTITIES:,} block references, circles, points, texts and wall lines in the "
            f"drawing, the most this reader loads (about 2 KB of memory each); split the drawing by floor or "
            "area, or delete or freeze the layers the plan does not need and export again") from None
    except OSError as exc:
        raise InputError(f"{where}: cannot read the file ({exc.strerror or exc}); check its permissions") from exc
    except (ezdxf.DXFError, ValueError, KeyError, IndexError, TypeError, EOFError, StopIteration,
            RuntimeError) as exc:  # damaged (a StopIteration inside ezdxf's generators is a RuntimeError)
        first = exc
    return _recovered(where, size, first)


def _recovered(where: str, size: int, first: Exception) -> Loaded:
    """``ezdxf.recover`` of a damaged file (all of it in memory: small files only), with a note on the fixes."""
    if size > MAX_RECOVER_BYTES:
        raise InputError(f"{where}: damaged DXF ({' '.join(str(first).split())}) of {size:,} bytes, more than the "
                         f"{MAX_RECOVER_BYTES:,} this reader recovers; re-export the drawing")
    try:
        doc, auditor = recover.readfile(where)
    except Exception as exc:  # recover is the last resort: any failure means unreadable
        why = " ".join(str(exc).split())  # ezdxf quotes the damaged line, carriage return and all
        raise InputError(f"{where}: damaged DXF that could not be recovered ({why}); re-export the drawing") from exc
    fixed = [e.message for e in auditor.fixes]
    note = f"recovered a damaged DXF; the auditor fixed {len(fixed)} problem(s)"
    if fixed:
        note += ": " + "; ".join(fixed[:3]) + ("; ..." if len(fixed) > 3 else "")
    else:
        note += f" (read error: {first})"
    if auditor.errors:
        note += f"; {len(auditor.errors)} problem(s) left unfixed: {auditor.errors[0].message}"
    return Loaded(doc, [note])
