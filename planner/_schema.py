"""The scalar types and the error wording shared by every pydantic model of a file the tools read.

plan.yaml (:mod:`planner.plan.file`), camera YAML (:mod:`planner.camera.file`) and layout
YAML/CSV (:mod:`planner.layout.tables`) are checked by models built from these, and a
failure reads the same everywhere: ``file: field.path: what is allowed (got ...)``.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Annotated, TypeVar

from pydantic import BaseModel, Field, Strict, ValidationError

from planner.defaults import MAX_EXTENT_M
from planner.errors import InputError

# Strict scalars: no '5' for 5 and no true for 1 (an int is still a float); lists may stand for tuples.
Finite = Annotated[float, Strict(), Field(allow_inf_nan=False)]
Coordinate = Annotated[float, Strict(), Field(allow_inf_nan=False, ge=-MAX_EXTENT_M, le=MAX_EXTENT_M)]
Positive = Annotated[float, Strict(), Field(allow_inf_nan=False, gt=0)]
Count = Annotated[int, Strict(), Field(ge=0)]
Text = Annotated[str, Strict()]


def _where(loc: tuple) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def validation_message(exc: ValidationError) -> str:
    """The first problem of a pydantic error, as ``field.path: what``, and how many more there are."""
    errors = exc.errors(include_url=False)
    first = errors[0]
    what = first["msg"].removeprefix("Value error, ")
    if first["type"] in ("dict_type", "model_type", "model_attributes_type"):
        what = "must be a mapping"
    elif first["type"] == "missing":
        what = "is missing"
    elif first["type"] == "extra_forbidden":
        what = "unknown field"
    what = what.replace("Input should be", "must be").replace("String should", "must").replace(
        "List should have", "must have").replace(" after validation", "")
    if first["type"] not in ("missing", "value_error", "extra_forbidden") and "input" in first:
        got = repr(first["input"])
        what += f" (got {got if len(got) <= 40 else got[:37] + '...'})"
    where = _where(tuple(p for p in first["loc"] if not str(p).startswith("function-")))
    more = f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""
    return (f"{where}: " if where else "") + what + more


M = TypeVar("M", bound=BaseModel)


def validated(model: type[M], doc: object, where: str, what: str, *, strict: bool | None = None,
              known: Iterable[str] | None = None, label: str = "known", hint: str = "") -> M:
    """``doc`` checked by ``model``, or one :class:`InputError`: ``where: field.path: what is wrong`` (after an
    unknown field, the ``known`` names under ``label``; then ``hint``), or that it is nested too deeply to be
    ``what``. ``strict`` None keeps each field's own strictness; True or False overrides it. The one way every
    reader turns a pydantic failure into a line for the user."""
    try:
        return model.model_validate(doc, strict=strict)
    except ValidationError as exc:
        names = f"; {label}: {', '.join(known)}" if known is not None and exc.errors()[0]["type"] == "extra_forbidden" \
            else ""
        raise InputError(f"{where}: {validation_message(exc)}{names}{hint}") from None
    except RecursionError:
        raise InputError(f"{where}: nested too deeply to be {what}") from None
