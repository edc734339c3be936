"""The plan: every stage's result for one site, and its file form ``plan.yaml``.

``plan.yaml`` (format ``vlp-plan/1``) is the contract between stages and with
other tools; ``docs/plan-format.md`` documents every field. Serialisation is
deterministic: keys in a fixed order, lengths rounded to 1 um.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import yaml

from planner import __version__
from planner.plan.file import FORMAT, luminaires_digest

if TYPE_CHECKING:  # types only: loading a plan needs none of the stages
    from planner.advice.advise import Advice
    from planner.advice.tones import ToneAudit
    from planner.camera.model import Camera
    from planner.codes.assignment import Assignment
    from planner.codes.check_bits import CheckCode
    from planner.graph import NeighbourGraph
    from planner.layout.model import Layout
    from planner.modulation.timing import Modulation
    from planner.positioning.accuracy import SiteAccuracy
    from planner.receivers.choice import ReceiverChoice
    from planner.verify.verify import Verification

_DECIMALS_M = 6


@dataclass(frozen=True)
class Plan:
    """A planned site: layout, neighbour graph, IDs and the camera they were made for."""

    layout: Layout
    graph: NeighbourGraph
    assignment: Assignment
    camera: Camera
    verification: Verification | None = None
    considered: dict | None = None
    check: CheckCode | None = None
    accuracy: SiteAccuracy | None = None
    modulation: Modulation | None = None
    advice: Advice | None = None
    receiver: ReceiverChoice | None = None
    no_frames: str | None = None  # why the plan has no frames (modulation None although planned with them)
    tones: ToneAudit | None = None  # an existing tone site's audit (docs/tones.md); it has no frames

    def entries(self) -> list[dict]:
        """One mapping per luminaire, as in ``plan.yaml``."""
        a = self.assignment
        out = []
        for k, lum in enumerate(self.layout.luminaires):
            out.append({
                "name": lum.name,
                "x": round(lum.x, _DECIMALS_M),
                "y": round(lum.y, _DECIMALS_M),
                "z": round(lum.z, _DECIMALS_M),
                "radius": round(lum.radius, _DECIMALS_M),
                "parity": "odd" if self.graph.odd[k] else "even",
                "region": int(a.regions[k]),
                "id": int(a.ids[k]),
                **({"tone_hz": float(lum.tone_hz)} if lum.tone_hz is not None else {}),
                **({"codeword": int(self.check.codewords[a.ids[k] - 1])}
                   if self.check is not None and self.check.distance > 1 else {}),
                **({"frame": {"chips": self.modulation.frames[k], "chip_rate_hz": self.modulation.timing.chip_rate_hz,
                              "line_code": self.modulation.code.name}} if self.modulation is not None else {}),
                "source": dict(lum.source),
            })
        return out


def _round_pairs(points) -> list[list[float]] | None:
    if points is None:
        return None
    return [[round(float(x), _DECIMALS_M), round(float(y), _DECIMALS_M)] for x, y in points]


def plan_document(plan: Plan, source_sha256: str = "") -> dict:
    """The ``plan.yaml`` mapping of a plan."""
    a, g, lay = plan.assignment, plan.graph, plan.layout
    cross = len(g.cross_edges)
    entries = plan.entries()
    return {
        "format": FORMAT,
        "generator": f"vlp-plan {__version__}",
        "units": {"length": "m", "angle": "deg", "time": "s"},
        "source": {
            "file": Path(lay.source_path).name,
            "sha256": source_sha256,
            "unit": lay.unit,
            "unit_reason": lay.unit_reason,
            "notes": list(lay.notes),
        },
        "scheme": a.scheme,
        "code": {
            "bits": a.bits,
            "max_id": a.max_id,
            "alphabet": a.alphabet,
            "naive_bits": a.naive_bits,
            "lower_bound_bits": a.lower_bound_bits,
            "efficiency": round(a.efficiency, 4),
            "check_distance": plan.check.distance if plan.check else 1,
            "word_bits": plan.check.word_bits if plan.check else a.bits,
            "check_bits": plan.check.check_bits if plan.check else 0,
            "method": a.method,
            **{k: v for k, v in a.detail.items()},
        },
        "graph": {
            "edges": g.graph.number_of_edges(),
            "cross_edges": cross,
            "bipartite": g.bipartite,
            "odd_cycle": [plan.layout.luminaires[v].name for v in g.odd_cycle] if g.odd_cycle else None,
            "lattice": g.lattice is not None,
        },
        "schemes_considered": plan.considered,
        **({"receiver": plan.receiver.summary()} if plan.receiver is not None else {}),
        "camera": plan.camera.to_dict(),
        "verification": ({**plan.verification.summary([lum.name for lum in lay.luminaires]),
                          "luminaires_sha256": luminaires_digest(a.scheme, entries)}  # an edit since is caught
                         if plan.verification is not None else None),
        "advice": plan.advice.summary() if plan.advice is not None else None,
        "modulation": plan.modulation.summary() if plan.modulation is not None else None,
        **({"no_frames": plan.no_frames} if plan.no_frames else {}),
        **({"tones": plan.tones.summary([lum.name for lum in lay.luminaires])} if plan.tones is not None else {}),
        "accuracy": plan.accuracy.summary() if plan.accuracy is not None else None,
        "outline": _round_pairs(lay.outline),
        "luminaire_count": len(lay.luminaires),  # written before the list: a file cut short is caught
        "luminaires": entries,
    }


_DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)  # libyaml: same text, about 4x faster


def dump_plan(document: dict) -> str:
    """``plan.yaml`` text: block style, one flow mapping per luminaire's source."""
    return yaml.dump(document, Dumper=_DUMPER, sort_keys=False, default_flow_style=None, width=120,
                     allow_unicode=True)


def plan_hash(text: str) -> str:
    """Short hash naming a plan's content (first 16 hex digits of SHA-256)."""
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]
