"""Run the stages in order: read a layout, plan it, write the outputs atomically.

The thin chain behind ``vlp-plan``: each stage lives in its own module and can
be used alone; this module only sequences them and owns the output directory.
"""

from __future__ import annotations

import hashlib
import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from planner._files import staging_folder
from planner.advice.advise import COVERAGE_GOAL, Advice, Site, advise
from planner.advice.frames import FrameLimits
from planner.camera.model import Camera
from planner.codes.assignment import Assignment
from planner.codes.check_bits import CheckCode, check_code
from planner.defaults import (
    ACCELEROMETER_SIGMA_DEG,
    INSTALL_TOLERANCE_M,
    MAX_VIDEO_FRAMES,
    MCU_CLOCK_HZ,
    RECEIVERS,
    SCHEMES,
    VIDEO_FPS,
)
from planner.errors import PlanningError, UsageError
from planner.graph import build_graph
from planner.layout.model import Layout
from planner.modulation.frame import line_code
from planner.modulation.timing import DRIVER_MAX_HZ, Modulation, modulate
from planner.parallel import Runner
from planner.plan.budget import plan_sample_per_m2
from planner.plan.file import plan_from_document
from planner.plan.model import Plan, dump_plan, plan_document, plan_hash
from planner.plan.timings import Timings
from planner.positioning.accuracy import ERROR_MAX_POSES, ERROR_POSES_PER_M2, SiteAccuracy, site_accuracy
from planner.positioning.error_terms import DEFAULT_TERMS, ErrorTerms
from planner.receivers.base import Job, Receiver
from planner.receivers.choice import check_receiver, choose
from planner.receivers.modes import AUTO, PAPER
from planner.verify.verify import (
    AMBIGUOUS,
    TOO_FEW,
    Verification,
)
from planner.verify.windows import CONGRUENCE_TOLERANCE_M, POSES_PER_M2, PoseSample, working_area


@dataclass(frozen=True, kw_only=True)
class PlanOptions:
    """How to plan: scheme, search budget [s], seed, camera, verification sampling, frames and the error map;
    built from keywords (``PlanOptions(scheme="window", seed=1)``), one default for each (planner.defaults)."""

    scheme: str = "auto"
    time_budget: float = 10.0
    seed: int = 0
    camera: Camera = field(default_factory=Camera)
    verify: bool = True
    poses_per_m2: float = POSES_PER_M2
    tolerance_m: float = CONGRUENCE_TOLERANCE_M
    check_distance: int = 1
    locate_method: str = "perspective"
    error_poses_per_m2: float = ERROR_POSES_PER_M2
    line_code: str = "manchester"
    driver_max_hz: float = DRIVER_MAX_HZ
    install_tolerance_m: float = INSTALL_TOLERANCE_M
    error_terms: ErrorTerms = DEFAULT_TERMS
    receiver: str = AUTO  # a mode of planner.receivers.modes, or "auto"
    accelerometer_sigma_deg: float = ACCELEROMETER_SIGMA_DEG
    video_fps: float = VIDEO_FPS
    max_video_frames: int = MAX_VIDEO_FRAMES
    mcu_clock_hz: float | None = MCU_CLOCK_HZ  # the drivers' timer clock: a multi-frame rate is one it plays exactly
    coverage_goal: float = COVERAGE_GOAL
    allow_unusable: bool = False  # recorded in the advice: vlp-verify then exits 0 on an unusable plan too
    runner: Runner | None = field(default=None, compare=False)  # where the proof's tiles run (planner.parallel)


def make_plan(layout: Layout, options: PlanOptions = PlanOptions(), timings: Timings | None = None) -> Plan:
    """Plan a checked layout: neighbour graph, IDs for the receiver mode under the chosen scheme, verification,
    frames, error map and advice, each a stage call.

    ``auto`` makes the paper's and the window scheme, verifies both, and keeps the
    one with fewer bits that has no ambiguous pose (the paper's on a tie); if
    neither verifies, one unique ID per luminaire. ``timings`` records each stage's time.
    """
    if layout.tones_hz is not None:  # before the frame options' checks, whose advice does not apply to it
        from planner.plan.tone_site import check_tone_options

        check_tone_options(layout.source_path, options.scheme, options.verify)
    _check_options(options)
    clock = timings or Timings()
    clock.stage("pose sampling", f"{len(layout.luminaires)} luminaires")
    xyz, radii, cam = layout.xyz, np.array([lum.radius for lum in layout.luminaires]), options.camera
    graph = build_graph(layout.xy)
    area = working_area(layout.xy, layout.outline)
    per_m2 = plan_sample_per_m2(area, verify=options.verify, poses_per_m2=options.poses_per_m2,
                                error_poses_per_m2=options.error_poses_per_m2)
    sample = PoseSample.draw(area, xyz, radii, cam, per_m2, options.seed)  # every stage takes a prefix
    job = Job(xyz, radii, layout.outline, graph, cam, sample, {}, options.scheme, options.seed, options.time_budget,
              options.poses_per_m2, options.tolerance_m, options.install_tolerance_m, options.verify, options.runner)
    tones, audit = layout.tones_hz, None
    clock.stage("IDs and verification", "kept tones" if tones is not None else f"{options.scheme} scheme")
    if tones is not None:  # an existing tone site: audited, no frames (docs/tones.md)
        from planner.plan.tone_site import keep_tones

        (assignment, verification, considered), receiver, audit = keep_tones(
            layout, tones, job, options.receiver, options.accelerometer_sigma_deg, options.driver_max_hz)
    else:
        (assignment, verification, considered), receiver = choose(job, options.receiver, options.accelerometer_sigma_deg)
    mode = receiver.mode if receiver is not None else PAPER
    clock.stage("frames")
    check = check_code(assignment.max_id, assignment.bits, options.check_distance if tones is None else 1)
    modulation, no_frames = (None, None) if tones is not None else _frames(
        assignment, check, mode, mode.smallest_image_rows(xyz, radii, cam, sample), options)
    accuracy = _accuracy(layout, radii, mode, sample, options, clock)
    advice = _advice(layout, radii, mode, verification, options, clock)
    return Plan(layout, graph, assignment, cam, verification, considered, check, accuracy, modulation, advice, receiver,
                no_frames, audit)


def _check_options(options: PlanOptions) -> None:
    if options.scheme not in SCHEMES:
        raise UsageError(f"`scheme` {options.scheme}: unknown scheme; use one of {', '.join(SCHEMES)}")
    if options.scheme == "auto" and not options.verify:
        raise UsageError("`verify=False` needs an explicit `scheme`: auto chooses the scheme by verifying it")
    if options.receiver not in RECEIVERS:
        raise UsageError(f"`receiver` {options.receiver}: unknown receiver; use one of {', '.join(RECEIVERS)}")
    check_receiver(options.receiver, options.verify)


def _frames(assignment: Assignment, check: CheckCode, mode: Receiver, rows: float | None, options: PlanOptions
            ) -> tuple[Modulation | None, str | None]:
    """Each luminaire's frame (its ID's codeword), timed for the smallest LED image of a window [rows]; or no
    frames and why, when no sampled pose sees a window (``rows`` None) or no chip rate fits the limits with
    ``verify`` on: the plan is still written, with its verdict and advice, and no firmware."""
    if rows is None:
        why = f"no sampled camera pose sees {mode.window_words}, so there is no LED image to fit a frame into"
        if not options.verify:  # no verdict or advice to write it beside
            raise PlanningError(f"{why}; check the luminaire spacing against the camera (docs/camera.md)")
        return None, why
    index = assignment.ids - 1
    words = check.codewords[index] if check.distance > 1 else index
    try:
        return modulate(np.asarray(words), check.word_bits, line_code(options.line_code), rows, options.camera,
                        driver_max_hz=options.driver_max_hz, video_fps=options.video_fps,
                        max_video_frames=options.max_video_frames, mcu_clock_hz=options.mcu_clock_hz), None
    except PlanningError as exc:
        if not options.verify:  # nothing to advise from: the misfit is the answer
            raise
        return None, str(exc)


def _accuracy(layout: Layout, radii: np.ndarray, mode: Receiver, sample: PoseSample, options: PlanOptions,
              clock: Timings) -> SiteAccuracy | None:
    """The error map of the mode's accuracy model, when verifying with an error-map density."""
    if not (options.verify and options.error_poses_per_m2 > 0):
        return None
    clock.stage("error map", f"at most {ERROR_MAX_POSES} poses")
    sigma_rad = float(np.radians(options.accelerometer_sigma_deg))
    return site_accuracy(layout.xyz, radii, layout.outline, options.camera, mode.accuracy_method(options.locate_method),
                         per_m2=options.error_poses_per_m2, seed=options.seed, sample=sample,
                         terms=mode.error_terms(options.error_terms, sigma_rad), accelerometer_sigma_rad=sigma_rad)


def _advice(layout: Layout, radii: np.ndarray, mode: Receiver, verification: Verification | None,
            options: PlanOptions, clock: Timings) -> Advice | None:
    """What would make the site work, from the verification (None unverified)."""
    if verification is None:
        return None
    clock.stage("advice")
    filled = all(lum.source.get("generated") == "lattice" for lum in layout.luminaires)
    share = [verification.count(k) / max(verification.poses, 1) for k in (TOO_FEW, AMBIGUOUS)]
    frames = None if layout.tones_hz is not None else FrameLimits(  # the changes' frames must fit too
        options.line_code, options.check_distance, options.driver_max_hz, options.video_fps, options.max_video_frames,
        options.mcu_clock_hz)
    advice = advise(Site(layout.xyz, radii, layout.outline, options.camera, mode.name, filled), verification.coverage,
                    *share, goal=options.coverage_goal, seed=options.seed, frames=frames,
                    allow_unusable=options.allow_unusable)
    return replace(advice, tone_site=layout.tones_hz is not None)


def default_outdir(layout_path: str | Path) -> Path:
    """``<layout stem>-vlp/`` next to the layout."""
    p = Path(layout_path)
    return p.with_name(p.stem + "-vlp")


def _sha256(path: str | Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@dataclass(frozen=True)
class FirmwareOptions:
    """How to write the drivers' configuration files (``docs/firmware.md``)."""

    template_dir: Path | None = None
    mcu_clock_hz: float = MCU_CLOCK_HZ
    image_version: int = 1


_REPLAN_HINT = "which replanning would delete; choose another -o, or move as-built.json away first"


def write_outputs(plan: Plan, outdir: str | Path, *, with_map: bool = True,
                  firmware: FirmwareOptions | None = FirmwareOptions(), with_report: bool = True,
                  timings: Timings | None = None, site_key: bytes | None = None) -> list[Path]:
    """Write ``plan.yaml`` (sealed under ``site_key``, if given: ``plan.yaml.seal``), the annotated DXF (and IFC,
    from an IFC model), the maps, the site report and the firmware files into ``outdir``, atomically.

    Everything is written into a temporary directory beside ``outdir`` and moved
    into place at the end: on any error, no partial output is left. An existing
    ``outdir`` is replaced only if it is empty or holds a previous plan that no
    driver has been flashed with (no ``as-built.json``).
    """
    outdir = Path(outdir)
    source = Path(plan.layout.source_path)
    clock = timings or Timings()
    with staged_output(outdir, _REPLAN_HINT) as stage:
        clock.stage("plan.yaml")
        document = plan_document(plan, _sha256(source) if source.is_file() else "")
        text = dump_plan(document)
        (stage / "plan.yaml").write_text(text, encoding="utf-8")
        if site_key is not None:  # vlp-flash flashes only a sealed plan (docs/plan-format.md)
            from planner.flash.seal import seal_path, seal_text

            seal_path(stage / "plan.yaml").write_text(seal_text(site_key, text), encoding="utf-8")
        written = plan_from_document(document, str(outdir / "plan.yaml"))  # what later stages will read back
        if firmware is not None and plan.modulation is not None:
            from planner.firmware.render import write_firmware

            clock.stage("firmware", f"{len(written.luminaires)} drivers")
            write_firmware(written, plan_hash(text), stage, template_dir=firmware.template_dir,
                           mcu_clock_hz=firmware.mcu_clock_hz, image_version=firmware.image_version)
        from planner import __version__
        from planner.layout.dxf_annotate import write_annotated_dxf

        is_dxf = source.suffix.lower() == ".dxf"
        clock.stage("annotated drawing")
        write_annotated_dxf(stage / f"{source.stem}-vlp.dxf", plan.layout, written.luminaires,
                            source_path=source if is_dxf else None, tool_version=__version__)
        if source.suffix.lower() == ".ifc":
            from planner.layout.ifc_annotate import write_annotated_ifc

            write_annotated_ifc(stage / f"{source.stem}-vlp.ifc", plan.layout, written.luminaires,
                                source_path=source, tool_version=__version__)
        if with_map:
            from planner.report.maps import render_coverage, render_error, render_map

            clock.stage("maps")
            render_map(plan, stage / "map.png")
            if plan.verification is not None:
                render_coverage(plan.verification, plan.layout.xy,
                                f"{source.name}: {plan.assignment.scheme} scheme", stage / "coverage.png")
            if plan.accuracy is not None and np.isfinite(plan.accuracy.error_m).any():  # a map of no fix shows nothing
                render_error(plan, stage / "error.png")
        if with_report:
            from planner.report.files import write_report

            clock.stage("site report")
            write_report(written, plan_hash(text), stage, stage)
        clock.stop()
        names = sorted(p.name for p in stage.iterdir())
    return [outdir / name for name in names]


@contextmanager
def staged_output(outdir: Path, journal_hint: str) -> Iterator[Path]:
    """A staging folder beside ``outdir`` to fill, swapped into place when the block ends and removed on any error,
    so no partial output is ever left. ``outdir`` must be new, empty or a vlp-plan output folder without an
    as-built journal (``journal_hint`` ends the refusal: what the user should do instead)."""
    if outdir.exists() and not (outdir.is_dir() and (not any(outdir.iterdir()) or (outdir / "plan.yaml").exists())):
        raise UsageError(f"{outdir}: exists and is not a vlp-plan output directory; choose another -o")
    if (outdir / "as-built.json").exists():
        raise UsageError(f"{outdir}: holds as-built.json, the record of drivers flashed with the plan there, "
                         + journal_hint)
    try:
        outdir.parent.mkdir(parents=True, exist_ok=True)
        stage = staging_folder(outdir)  # removes what a killed run (kill -9) left
    except OSError as exc:
        raise UsageError(f"-o {outdir}: cannot write there ({exc.strerror}); choose another -o") from None
    try:
        stage.chmod(0o755)  # mkdtemp makes it private; outputs are for the whole crew
        yield stage
        if outdir.exists():
            old = outdir.with_name(f".{outdir.name}.old-{os.getpid()}")
            os.replace(outdir, old)
            os.replace(stage, outdir)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(stage, outdir)
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
