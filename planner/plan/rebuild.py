"""An edited plan closes the loop: its frames checked against its IDs, re-derived, verified, and its firmware rebuilt.

A luminaire broadcasts its ``frame``, not its ``id``: after an ``id`` is edited in
``plan.yaml`` the two disagree until the frame is made again. :func:`frame_mismatches`
names the luminaires whose frame sends another ID (``vlp-verify`` refuses them);
:func:`derived_frame` makes a luminaire's frame from its ID with the plan's own
modulation (line code, check code, chip rate), as ``vlp-plan`` made it; :func:`verify_plan_file`
is the verification ``vlp-verify`` runs; :func:`rebuild` (``vlp-plan --from-plan PLAN``)
re-derives every frame, re-verifies and writes ``plan.yaml`` and ``firmware/`` atomically.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from planner.camera.model import Camera
from planner.codes.check_bits import CheckCode, check_code
from planner.defaults import INSTALL_TOLERANCE_M, MCU_CLOCK_HZ
from planner.errors import InputError
from planner.modulation.frame import LineCode, decode_stream, frame_chips, line_code
from planner.parallel import Runner
from planner.plan.file import Entry, PlanFile


@dataclass(frozen=True)
class Codec:
    """How a plan turns an ID into chips: line code, check code, word width [bits] and chip rate [Hz]."""

    code: LineCode
    check: CheckCode
    word_bits: int
    chip_rate_hz: float

    def word(self, luminaire_id: int) -> int:
        """The word a luminaire sends: ``id - 1``, or its codeword when the plan has check bits."""
        return int(self.check.codewords[luminaire_id - 1]) if self.check.distance > 1 else luminaire_id - 1

    def id_of(self, chips: str) -> int | None:
        """The ID a frame sends, or None when it holds no whole frame or no codeword."""
        try:
            word = decode_stream(chips + chips, self.word_bits, self.code)
        except InputError:
            return None
        if self.check.distance == 1:
            return word + 1
        hit = np.flatnonzero(self.check.codewords == word)
        return int(hit[0]) + 1 if len(hit) else None


def codec(plan: PlanFile, where: str) -> Codec:
    """The plan's own modulation; :class:`InputError` when it has none or this version would make other frames."""
    m = plan.modulation
    if m is None and (plan.model_extra or {}).get("tones"):
        raise InputError(f"{where}: a tone site's plan (docs/tones.md) has no frames to check or rebuild: its tones "
                         "are the layout's, played by drivers configured outside vlp-plan; run vlp-plan on the layout")
    if m is None:
        raise InputError(f"{where}: the plan has no modulation section, so no frames to check or rebuild; "
                         "make it with vlp-plan LAYOUT (without --no-firmware)")
    code = line_code(m.line_code)
    check = check_code(plan.code.max_id, plan.code.bits, plan.code.check_distance)
    if code.preamble != m.preamble or check.word_bits != plan.code.word_bits:
        raise InputError(f"{where}: its frames (preamble {m.preamble}, {plan.code.word_bits}-bit words) are not "
                         f"what this vlp-plan makes (preamble {code.preamble}, {check.word_bits}-bit words); "
                         "re-plan the site with vlp-plan LAYOUT")
    return Codec(code, check, check.word_bits, m.chip_rate_hz)


def derived_frame(c: Codec, entry: Entry) -> dict:
    """The ``frame`` mapping of ``entry`` made from its ``id`` (``plan.yaml``'s form)."""
    return {"chips": frame_chips(c.word(entry.id), c.word_bits, c.code), "chip_rate_hz": c.chip_rate_hz,
            "line_code": c.code.name}


@dataclass(frozen=True)
class Mismatch:
    """A luminaire whose frame (or codeword) does not send its ``id``."""

    name: str
    id: int
    sends: int | None
    """The ID its frame sends; None when the frame sends none."""
    what: str

    def text(self) -> str:
        return f"{self.name} (id {self.id}: {self.what})"


def frame_mismatches(plan: PlanFile, where: str) -> list[Mismatch]:
    """The luminaires whose ``frame`` or ``codeword`` disagrees with their ``id``, in plan order; [] when the
    plan has no frames."""
    if plan.frames is None:
        return []
    c = codec(plan, where)
    out = []
    for e in plan.luminaires:
        assert e.frame is not None  # plan.frames is not None: every entry has one
        want = derived_frame(c, e)
        if e.frame.chips != want["chips"]:
            sends = c.id_of(e.frame.chips)
            out.append(Mismatch(e.name, e.id, sends, "its frame sends no ID" if sends is None else
                                f"its frame sends ID {sends}"))
        elif e.frame.chip_rate_hz != c.chip_rate_hz or e.frame.line_code != c.code.name:
            out.append(Mismatch(e.name, e.id, e.id, f"its frame runs at {e.frame.chip_rate_hz:g} Hz "
                                f"{e.frame.line_code}, the plan's modulation at {c.chip_rate_hz:g} Hz {c.code.name}"))
        elif e.codeword is not None and c.check.distance > 1 and e.codeword != c.word(e.id):
            out.append(Mismatch(e.name, e.id, e.id, f"its codeword {e.codeword} is not the one of ID {e.id}"))
    return out


def verify_plan_file(plan: PlanFile, camera: Camera, *, poses_per_m2: float, seed: int, tolerance_m: float,
                     install_tolerance_m: float | None = None, runner: Runner | None = None):
    """Verify a plan's IDs anew (sampled poses; the window set, proved where the proof completes): ``(result,
    standing)`` where ``standing`` holds what :func:`planner.advice.verdict` reads."""
    from planner.advice.advise import standing
    from planner.defaults import COVERAGE_GOAL
    from planner.receivers.modes import receiver_for
    from planner.verify.verify import AMBIGUOUS, TOO_FEW

    xyz, radii, ids = plan.xyz, plan.radii, plan.ids
    recorded = (plan.verification.window_set if plan.verification else None) or {}
    install = install_tolerance_m if install_tolerance_m is not None else \
        float(recorded.get("install_tolerance_m", INSTALL_TOLERANCE_M))
    mode = receiver_for(plan.receiver_mode, "receiver.mode")  # its windows and proof (planner.receivers)
    result = mode.verify(xyz, radii, ids, plan.outline, camera, per_m2=poses_per_m2, seed=seed,
                         tolerance_m=tolerance_m, install_tolerance_m=install, recorded=recorded,
                         runner=runner)
    n = max(result.poses, 1)
    judged = standing(result.coverage, result.count(TOO_FEW) / n, result.count(AMBIGUOUS) / n,
                      plan.advice.goal if plan.advice is not None else COVERAGE_GOAL, plan.receiver_mode)
    return result, judged


def rebuild(path: str | Path, outdir: str | Path | None, *, allow_unverified: bool = False,
            poses_per_m2: float, seed: int = 0, tolerance_m: float, template_dir: Path | None = None,
            mcu_clock_hz: float = MCU_CLOCK_HZ, image_version: int = 1, site_key: bytes | None = None) -> dict:
    """``vlp-plan --from-plan PATH``: every frame made again from its ``id``, the IDs verified, and ``plan.yaml``
    and ``firmware/`` written into ``outdir`` (default: the plan's folder), atomically, with ``plan.yaml.seal``
    under ``site_key`` when given. A plan that fails verification (IDs that read alike, or NOT USABLE) is refused
    unless ``allow_unverified``. Returns the summary."""
    from planner import __version__
    from planner._files import load_yaml
    from planner.advice.advise import verdict
    from planner.firmware.render import write_firmware
    from planner.plan.file import plan_from_document
    from planner.plan.model import dump_plan, plan_hash
    from planner.plan.pipeline import staged_output

    path = Path(path)
    where = str(path)
    doc = load_yaml(path, "no such plan file; run vlp-plan first")
    plan = plan_from_document(doc, where)
    c = codec(plan, where)
    changed = [m.text() for m in frame_mismatches(plan, where)]  # [] for a plan written without frames
    for entry, raw in zip(plan.luminaires, doc["luminaires"]):
        raw["frame"] = derived_frame(c, entry)
        if c.check.distance > 1:
            raw["codeword"] = c.word(entry.id)
    plan = plan_from_document(doc, where)
    result, judged = verify_plan_file(plan, plan.camera_model(), poses_per_m2=poses_per_m2, seed=seed,
                                      tolerance_m=tolerance_m)
    allowed = plan.advice is not None and plan.advice.allow_unusable
    passed = result.clean and (judged["usable"] or allowed)
    said = failed_verdict(result) if not result.clean else verdict(judged)
    if not passed and not allow_unverified:
        raise InputError(f"{where}: fails verification, so no firmware was written: {said}; run vlp-verify {where} "
                         "for the conflicts, fix the ids, or pass `allow_unverified` to write it anyway")
    names = plan.names
    doc["generator"] = f"vlp-plan {__version__}"
    doc["verification"] = result.summary(names)
    if isinstance(doc.get("advice"), dict):  # the measure anew; the advice's table of changes stays as planned
        doc["advice"].update({k: judged[k] for k in ("coverage", "usable", "too_few_leds", "ambiguous", "meets_goal")})
    notes = doc.setdefault("source", {}).setdefault("notes", [])
    notes.append(f"rebuilt from an edited plan by vlp-plan --from-plan: {len(changed)} frame(s) made again from "
                 "their id, IDs verified anew" + ("" if passed else " and FAILED (written with --allow-unverified)"))
    text = dump_plan(doc)
    written = plan_from_document(doc, where)
    out = Path(outdir) if outdir is not None else path.parent
    with staged_output(out, "which a new plan would orphan; write the rebuilt plan into another -o") as stage:
        (stage / "plan.yaml").write_text(text, encoding="utf-8")
        if site_key is not None:  # the edit, verified anew, sealed: vlp-flash takes it
            from planner.flash.seal import seal_path, seal_text

            seal_path(stage / "plan.yaml").write_text(seal_text(site_key, text), encoding="utf-8")
        write_firmware(written, plan_hash(text), stage, template_dir=template_dir, mcu_clock_hz=mcu_clock_hz,
                       image_version=image_version)
    return {"plan": str(out / "plan.yaml"), "luminaires": len(names), "frames_made_again": changed,
            "verified": bool(passed), "verdict": said, "coverage": round(float(result.coverage), 6),
            "plan_hash": plan_hash(text), "sealed": site_key is not None}


def failed_verdict(result) -> str:
    """The verdict of IDs that read alike: never a usable one."""
    from planner.verify.verify import AMBIGUOUS

    alike = len(result.window_set.conflicts) if result.window_set is not None else 0
    what = [f"{result.count(AMBIGUOUS)} sampled pose(s) ambiguous"] if result.conflicts else []
    what += [f"{alike} window(s) read like another"] if alike else []
    return "FAILED: the IDs do not name one place (" + ", ".join(what) + "); fix the ids the conflicts name"

