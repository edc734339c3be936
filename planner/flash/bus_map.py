"""The ``--bus-map`` file: which bus address each luminaire's driver answers at.

A CSV of ``name,address`` rows (a ``name,address`` header and ``#`` comments allowed); each
row is checked by :class:`BusMapRow`, and names and addresses must be unique: two drivers
at one address would both take, or garble, the same image.
"""

from __future__ import annotations

import csv
from typing import TYPE_CHECKING, Annotated

from pydantic import BaseModel, ConfigDict, Field

from planner._files import read_text
from planner._schema import validated
from planner.errors import InputError

if TYPE_CHECKING:
    from planner.plan.file import PlanFile

MAX_BYTES = 8 << 20
"""Most bytes of a bus map read (65,534 rows of a 100-character name fit)."""


class BusMapRow(BaseModel):
    """One ``--bus-map`` row: a luminaire of the plan and its driver's bus address."""

    model_config = ConfigDict(frozen=True)

    name: Annotated[str, Field(min_length=1)]
    address: Annotated[int, Field(ge=1, le=0xFFFE)]


def read_bus_map(plan: PlanFile, path: str | None) -> dict[str, int]:
    """Bus address of each luminaire: plan order from 1, or the ``--bus-map`` CSV (``name,address`` rows, a
    header and ``#`` comments allowed), each row checked by :class:`BusMapRow`, names and addresses unique."""
    if not path:
        return {e.name: k + 1 for k, e in enumerate(plan.luminaires)}
    out: dict[str, int] = {}
    text = read_text(path, "bus map", "no such bus map (--bus-map)", max_bytes=MAX_BYTES)
    for n, row in enumerate(csv.reader(text.splitlines()), 1):
        if not row or row[0].startswith("#") or row[0] == "name":
            continue
        if len(row) != 2:
            raise InputError(f"{path}: line {n}: expected 'name,address' with address 1..65534")
        entry = validated(BusMapRow, {"name": row[0].strip(), "address": row[1].strip()}, f"{path}: line {n}",
                          "a bus map row")
        if entry.name in out:
            raise InputError(f"{path}: line {n}: {entry.name!r} is mapped twice; give each luminaire one address")
        if entry.address in out.values():
            other = next(k for k, v in out.items() if v == entry.address)
            raise InputError(f"{path}: line {n}: address {entry.address} is already {other!r}'s; two drivers on "
                             "one bus need two addresses")
        out[entry.name] = entry.address
    return out
