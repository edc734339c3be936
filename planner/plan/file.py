"""``plan.yaml`` read back: one typed plan, validated once, for every stage after ``vlp-plan``.

:func:`load_plan` checks every field a later stage reads (types, finite numbers, ranges,
unique names, IDs within the code) and returns a :class:`PlanFile`; a stage then takes
arrays and a :class:`~planner.camera.model.Camera` from it and never parses the mapping again.
``docs/plan-format.md`` documents the fields. Sections no stage computes with
(``source``, ``graph``, ``schemes_considered``, ``verification.window_set``) are kept as
mappings; keys this version does not read are kept too.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections import Counter
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, Strict, model_validator

from planner._files import load_yaml, parse_yaml
from planner._schema import Coordinate, Count, Finite, Positive, Text, validated
from planner.camera.file import CameraFields
from planner.defaults import (
    LINE_CODE_NAMES,
    MAX_HEIGHT_M,
    MAX_RADIUS_M,
    MAX_VIDEO_FPS,
    MAX_VIDEO_FRAMES,
    MIN_RADIUS_M,
)
from planner.errors import InputError
from planner.layout.model import name_problem

if TYPE_CHECKING:
    from planner.camera.model import Camera

FORMAT = "vlp-plan/1"
"""The ``format`` key of ``plan.yaml``."""


class _Section(BaseModel):
    """Keys this version does not read are kept."""

    model_config = ConfigDict(extra="allow", frozen=True)


class Frame(_Section):
    chips: Annotated[str, Strict(), Field(pattern=r"^[01]+$", max_length=4096)]
    chip_rate_hz: Positive
    line_code: Literal[LINE_CODE_NAMES]  # type: ignore[valid-type]  # the names, from the light defaults


def _this_format(value: str) -> str:
    if value != FORMAT:
        raise ValueError(f"must be {FORMAT!r}")
    return value


def _valid_name(name: str) -> str:
    problem = name_problem(name)
    if problem:
        raise ValueError(f"the name {problem}")
    return name


class Entry(_Section):
    """One luminaire as ``plan.yaml`` lists it (lengths in metres)."""

    name: Annotated[str, Strict(), AfterValidator(_valid_name)]
    x: Coordinate
    y: Coordinate
    z: Annotated[Positive, Field(le=MAX_HEIGHT_M)]
    radius: Annotated[Positive, Field(ge=MIN_RADIUS_M, le=MAX_RADIUS_M)]
    parity: Literal["odd", "even"]
    region: Count
    id: Annotated[Count, Field(ge=1)]
    codeword: Count | None = None
    tone_hz: Positive | None = None  # the tone it broadcasts on a tone site [Hz]
    frame: Frame | None = None
    source: dict[str, Any] = {}


class Code(_Section):
    bits: Annotated[Count, Field(ge=1, le=32)]
    max_id: Annotated[Count, Field(ge=1)]
    naive_bits: Annotated[Count, Field(ge=1)]
    lower_bound_bits: Count
    efficiency: Finite
    check_distance: Annotated[Count, Field(ge=1)] = 1
    word_bits: Annotated[Count, Field(ge=1, le=64)]
    check_bits: Count = 0
    method: Text = ""


class ModulationFields(_Section):
    """The frames' timing (times in seconds, image sizes in sensor rows)."""

    line_code: Literal[LINE_CODE_NAMES]  # type: ignore[valid-type]
    preamble: Annotated[str, Strict(), Field(pattern=r"^[01]+$", max_length=64)]
    chip_rate_hz: Positive
    frame_chips: Annotated[Count, Field(ge=1)]
    frame_period_s: Positive
    frames_in_smallest_image: Finite
    smallest_image_rows: Positive
    row_time_s: Positive
    # read over video_frames consecutive video frames (docs/modulation.md); absent in single-frame plans
    video_frames: Annotated[int, Strict(), Field(ge=1, le=MAX_VIDEO_FRAMES)] = 1
    video_fps: Annotated[Positive, Field(le=MAX_VIDEO_FPS)] | None = None
    frame_offset_chips: Annotated[Finite, Field(ge=0)] | None = None
    window_chips: Annotated[Finite, Field(ge=0)] | None = None

    @model_validator(mode="after")
    def _video_fps_given(self) -> ModulationFields:
        if self.video_frames > 1 and self.video_fps is None:
            raise ValueError(f"video_frames is {self.video_frames} but video_fps is missing")
        return self


class Verification(_Section):
    """The sampled check's figures the report and ``vlp-verify`` read; the rest stays as written."""

    poses: Count
    coverage: Annotated[Finite, Field(ge=0, le=1)]
    ambiguous: Count
    window_set: dict[str, Any] | None = None


class BudgetRow(_Section):
    located: Count
    median_m: Annotated[Finite, Field(ge=0)] | None = None
    p90_m: Annotated[Finite, Field(ge=0)] | None = None


class Accuracy(_Section):
    method: Text
    poses: Count
    located: Count
    median_m: Annotated[Finite, Field(ge=0)] | None = None
    p90_m: Annotated[Finite, Field(ge=0)] | None = None
    max_m: Annotated[Finite, Field(ge=0)] | None = None
    terms: dict[str, Annotated[Finite, Field(ge=0)]] | None = None  # None: a plan from before the error budget
    includes: list[Text] = ["edge"]
    budget: dict[str, BudgetRow] = {}
    dominant: Text | None = None


Share = Annotated[Finite, Field(ge=0, le=1)]


class AdviceChange(_Section):
    """One row of the site advice: the change, the vlp-plan flags that apply it, its sampled coverage."""

    change: Text
    flags: list[Text] = []
    applicable_by_flags: bool = False
    camera: dict[str, Any] | None = None
    coverage: Share
    reaches_goal: bool


class Advice(_Section):
    """The site advice (``docs/advice.md``): the goal, whether the plan is usable, and the changes tried."""

    goal: Share
    usable_from: Share
    usable: bool
    coverage: Share
    too_few_leds: Share = 0.0
    ambiguous: Share = 0.0
    meets_goal: bool
    poses_per_candidate: Count
    baseline: Share
    changes: list[AdviceChange] = []
    recommended: Annotated[int, Field(ge=0)] | None = None
    allow_unusable: bool = False  # made with vlp-plan --allow-unusable

    @model_validator(mode="after")
    def _recommended_is_a_row(self) -> Advice:
        if self.recommended is not None and self.recommended >= len(self.changes):
            raise ValueError(f"advice.recommended {self.recommended} names no row of advice.changes")
        return self


class PlanFile(_Section):
    """A ``plan.yaml`` as the stages after ``vlp-plan`` read it; arrays are in luminaire order."""

    format: Annotated[str, AfterValidator(_this_format)]
    generator: Text = ""
    source: dict[str, Any] = {}
    scheme: Text
    code: Code
    graph: dict[str, Any] | None = None
    schemes_considered: dict[str, Any] | None = None
    receiver: dict[str, Any] | None = None
    camera: CameraFields = CameraFields()
    verification: Verification | None = None
    advice: Advice | None = None
    modulation: ModulationFields | None = None
    no_frames: Text | None = None  # why a plan verified for its advice has no frames
    accuracy: Accuracy | None = None
    outline: list[tuple[Coordinate, Coordinate]] | None = None
    luminaire_count: Annotated[Count, Field(ge=1)] | None = None  # absent in plans written before 2026-12-03
    luminaires: Annotated[list[Entry], Field(min_length=1, max_length=1_000_000)]

    @model_validator(mode="after")
    def _consistent(self) -> PlanFile:
        names = [e.name for e in self.luminaires]
        if self.luminaire_count is not None and self.luminaire_count != len(names):
            raise ValueError(f"luminaire_count says {self.luminaire_count} luminaires but {len(names)} are listed: "
                             "the file was cut short or edited")
        if len(set(names)) != len(names):
            counts = Counter(names)  # one pass: a million names stay cheap
            dup = next(n for n in names if counts[n] > 1)
            raise ValueError(f"luminaire name {dup!r} is used more than once")
        for k, e in enumerate(self.luminaires):
            if e.id > self.code.max_id:
                raise ValueError(f"luminaires[{k}] ({e.name}): id {e.id} exceeds code.max_id {self.code.max_id}")
        ids = [e.id for e in self.luminaires]
        if self.code.max_id > 2**self.code.bits:
            raise ValueError(f"code.bits {self.code.bits} and code.max_id {self.code.max_id} disagree with the "
                             f"luminaires' IDs (largest {max(ids)}, sent as id - 1 in code.bits bits): the file was "
                             "edited")
        if self.scheme == "unique" and len(set(ids)) != len(ids):  # an edited reuse plan is vlp-verify's to judge
            uses = Counter(ids)
            twice = next(e for e in self.luminaires if uses[e.id] > 1)
            raise ValueError(f"luminaire {twice.name!r}'s id {twice.id} is used more than once in a unique-ID plan")
        toned = sum(e.tone_hz is not None for e in self.luminaires)
        if toned not in (0, len(names)) or (toned and any(e.frame is not None for e in self.luminaires)):
            raise ValueError(f"{toned} of {len(names)} luminaires have a tone_hz: all or none must, and a tone "
                             "site's luminaires have no frame")
        framed = sum(e.frame is not None for e in self.luminaires)
        if framed not in (0, len(names)):
            raise ValueError(f"{framed} of {len(names)} luminaires have a frame: all or none must")
        if self.outline is not None and len(self.outline) < 3:
            raise ValueError("outline must have at least 3 corners")
        return self

    @property
    def names(self) -> list[str]:
        return [e.name for e in self.luminaires]

    @cached_property
    def xyz(self) -> np.ndarray:
        """Luminaire centres, shape (N, 3) [m]."""
        return np.array([[e.x, e.y, e.z] for e in self.luminaires], dtype=float).reshape(-1, 3)

    @property
    def xy(self) -> np.ndarray:
        """Plan positions, shape (N, 2) [m]."""
        return self.xyz[:, :2]

    @cached_property
    def radii(self) -> np.ndarray:
        """LED radii, shape (N,) [m]."""
        return np.array([e.radius for e in self.luminaires], dtype=float)

    @cached_property
    def ids(self) -> np.ndarray:
        return np.array([e.id for e in self.luminaires], dtype=np.int64)

    @cached_property
    def regions(self) -> np.ndarray:
        return np.array([e.region for e in self.luminaires], dtype=np.int64)

    @property
    def frames(self) -> list[str] | None:
        """Each luminaire's chips, or None when the plan has no frames."""
        if self.modulation is None or any(e.frame is None for e in self.luminaires):
            return None
        return [e.frame.chips for e in self.luminaires if e.frame is not None]

    @property
    def outline_xy(self) -> np.ndarray | None:
        """The room outline, shape (M, 2) [m], or None."""
        return None if self.outline is None else np.array(self.outline, dtype=float)

    @property
    def receiver_mode(self) -> str:
        """``three`` (the paper's receiver; no ``receiver`` section) or ``gravity``."""
        return str((self.receiver or {}).get("mode", "three"))

    @property
    def window_length_cap_m(self) -> float | None:
        """The plan's cap on its window's length [m] (``verification.window_set``; a gravity plan's two-LED
        window, which only the gravity receiver's identification reads), or None."""
        window_set = (self.verification.window_set if self.verification else None) or {}
        cap = window_set.get("window_length_cap_m")
        if cap is None:
            return None
        if isinstance(cap, bool) or not isinstance(cap, (int, float)) or not 0 < cap < math.inf:
            raise InputError(f"verification.window_set.window_length_cap_m: {cap!r} is not a length > 0 m; "
                             "re-plan, or restore the value vlp-plan wrote")
        return float(cap)

    def check_verdict_current(self, where: str) -> None:
        """:class:`InputError` if the luminaires (names, positions, IDs) were edited since the plan's verdict was
        written (``verification.luminaires_sha256``; plans written before 2026-12-04 carry none and pass)."""
        recorded = (self.verification.model_extra or {}).get("luminaires_sha256") if self.verification else None
        if recorded is not None and recorded != luminaires_digest(self.scheme, self.luminaires):
            raise InputError(f"{where}: the luminaires were edited since the plan was verified, so its verdict no "
                             "longer holds; run vlp-verify on it, or vlp-plan again")

    def camera_model(self) -> Camera:
        """The camera the plan was made for."""
        return self.camera.to_camera()

    def document(self) -> dict:
        """The plan as a plain mapping (what templates see), with the keys this version does not read."""
        return self.model_dump(mode="python")


def luminaires_digest(scheme: str, luminaires: list) -> str:
    """Short hash of what a verdict depends on: the scheme and each luminaire's name, position, radius, ID and
    tone where it has one (entries as mappings or :class:`Entry`); recorded with the verdict, compared on reading."""
    def row(e: Any) -> list:
        v = e if isinstance(e, dict) else {k: getattr(e, k) for k in ("name", "x", "y", "z", "radius", "id", "tone_hz")}
        tone = v.get("tone_hz")
        return [v["name"], float(v["x"]), float(v["y"]), float(v["z"]), float(v["radius"]), int(v["id"]),
                *([float(tone)] if tone is not None else [])]

    text = json.dumps([scheme, *(row(e) for e in luminaires)], separators=(",", ":"), ensure_ascii=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def plan_from_document(doc: object, where: str) -> PlanFile:
    """A plan mapping checked into a :class:`PlanFile`; :class:`InputError` names ``where`` and the bad field."""
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        got = doc.get("format") if isinstance(doc, dict) else None
        raise InputError(f"{where}: not a {FORMAT} plan (field 'format' is {got!r}); write it with vlp-plan")
    return validated(PlanFile, doc, where, "a plan", hint="; write the plan again with vlp-plan")


def load_plan(path: str | Path, text: str | None = None) -> PlanFile:
    """Read and check a ``plan.yaml`` (``text``: its content, read already, so that the plan checked is the one
    hashed and sealed); raise :class:`InputError` naming the file and the bad field."""
    doc = load_yaml(path, "no such plan file; run vlp-plan first") if text is None else parse_yaml(text, path)
    return plan_from_document(doc, str(path))
