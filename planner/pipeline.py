"""Run the stages in order: read a layout, plan it, write the outputs atomically.

The thin chain behind ``vlp-plan``: each stage lives in its own module and can
be used alone; this module only sequences them and owns the output directory.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from planner.advice import COVERAGE_GOAL, Site, advise
from planner.advice_frames import FrameLimits
from planner.budget import plan_sample_per_m2
from planner.camera import Camera
from planner.codes.assignment import assign_paper
from planner.codes.check_bits import check_code
from planner.codes.schemes import assign_unique, assign_window, window_set_bound
from planner.defaults import (
    ACCELEROMETER_SIGMA_DEG,
    INSTALL_TOLERANCE_M,
    MAX_VIDEO_FRAMES,
    RECEIVERS,
    SCHEMES,
    VIDEO_FPS,
)
from planner.errors import InputError, UsageError
from planner.frame import line_code
from planner.graph import build_graph
from planner.layout.model import DEFAULT_MOUNT_HEIGHT_M, DEFAULT_RADIUS_M, Layout, check_layout, fill_outline
from planner.modulation import DRIVER_MAX_HZ, modulate, smallest_window_image_rows
from planner.plan import Plan, dump_plan, plan_document, plan_hash
from planner.plan_file import plan_from_document
from planner.positioning.accuracy import ERROR_POSES_PER_M2, site_accuracy
from planner.positioning.error_terms import DEFAULT_TERMS, ErrorTerms
from planner.verify.proof import prove_window_set
from planner.verify.verify import (
    AMBIGUOUS,
    TOO_FEW,
    Verification,
    check_window_set,
    classify,
    observe_poses,
    side_bound,
)
from planner.verify.windows import CONGRUENCE_TOLERANCE_M, POSES_PER_M2, PoseSample, working_area

LAYOUT_SUFFIXES = (".dxf", ".ifc", ".yaml", ".yml", ".csv")
DRAWING_SUFFIXES = (".dxf", ".ifc")
"""Drawings whose failed read points to ``vlp-inspect``."""


@dataclass(frozen=True)
class ReadOptions:
    """How to read a layout (the command line's reading flags)."""

    units: str | None = None
    preset: str = "auto"
    layers: tuple[str, ...] = ()
    blocks: tuple[str, ...] = ()
    mount_height_m: float | None = None
    radius_m: float | None = None
    room: str | None = None
    storey: str | None = None


@dataclass(frozen=True)
class PlanOptions:
    """How to plan: scheme, search budget, seed, camera, and verification sampling."""

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
    receiver: str = "three"
    accelerometer_sigma_deg: float = ACCELEROMETER_SIGMA_DEG
    video_fps: float = VIDEO_FPS
    max_video_frames: int = MAX_VIDEO_FRAMES
    mcu_clock_hz: float | None = 16e6  # the drivers' timer clock: a multi-frame rate is one it plays exactly
    coverage_goal: float = COVERAGE_GOAL
    allow_unusable: bool = False  # recorded in the advice: vlp-verify then exits 0 on an unusable plan too


def read_layout(path: str | Path, leds: int | None, options: ReadOptions = ReadOptions()) -> Layout:
    """Read a DXF, IFC, YAML or CSV layout; with ``leds`` and only an outline, fill it.

    A drawing (DXF, IFC) that cannot be planned raises :class:`InputError` whose line ends
    with a pointer to ``vlp-inspect``.
    """
    path = Path(path)
    if path.suffix.lower() not in LAYOUT_SUFFIXES:
        raise UsageError(f"{path}: unknown layout type {path.suffix!r}; give a .dxf, .ifc, .yaml, .yml or .csv file")
    if not path.is_file():
        raise UsageError(f"{path}: no such file")
    if path.suffix.lower() not in DRAWING_SUFFIXES:
        return _read_layout(path, leds, options)
    try:
        return _read_layout(path, leds, options)
    except InputError as exc:
        from planner.layout.dxf import INSPECT_HINT

        hint = INSPECT_HINT.format(path=path)
        if hint in str(exc):
            raise
        raise InputError(f"{exc}; {hint}") from exc


def _read_layout(path: Path, leds: int | None, options: ReadOptions) -> Layout:
    suffix = path.suffix.lower()
    for flag, value, where in (("--room", options.room, ".dxf"), ("--storey", options.storey, ".ifc")):
        if value is not None and suffix != where:
            raise UsageError(f"{flag} is for {where} drawings, not {path.name}")
    if suffix == ".dxf":
        from planner.layout.dxf import read_dxf

        layout = read_dxf(
            path, units=options.units, preset=options.preset, layers=list(options.layers) or None,
            blocks=list(options.blocks) or None, mount_height_m=options.mount_height_m,
            radius_m=options.radius_m, allow_outline_only=leds is not None, expected=leds, room=options.room,
        )
    elif suffix == ".ifc":
        from planner.layout.ifc import read_ifc

        layout = read_ifc(path, storey=options.storey, mount_height_m=options.mount_height_m,
                          radius_m=options.radius_m, units=options.units)
    else:
        from planner.layout.tables import read_csv, read_yaml

        reader = read_csv if suffix == ".csv" else read_yaml
        layout = reader(path, units=options.units, mount_height_m=options.mount_height_m, radius_m=options.radius_m)
    if not layout.luminaires:
        if layout.outline is None:
            raise InputError(f"{path}: holds neither luminaires nor a room outline; nothing to plan")
        if leds is None:
            raise InputError(f"{path}: holds a room outline but no luminaires; give --leds N to lay out N of them")
        height = options.mount_height_m or layout.fill_height_m or DEFAULT_MOUNT_HEIGHT_M
        radius = options.radius_m or layout.fill_radius_m or DEFAULT_RADIUS_M
        try:
            lums, description = fill_outline(np.array(layout.outline), leds, height, radius)
        except InputError as exc:
            raise InputError(f"{path}: {exc}") from None
        layout = replace(layout, luminaires=tuple(lums)).with_note(description)
        if options.mount_height_m is None and layout.fill_height_m is None:
            layout = layout.with_note(f"mounting height {height} m (default; set with --height)")
        leds = None  # the fill made exactly that many
    return check_layout(layout, expected=leds)


def make_plan(layout: Layout, options: PlanOptions = PlanOptions()) -> Plan:
    """Plan a checked layout: neighbour graph, IDs under the chosen scheme, verification, frames, error map.

    ``auto`` makes the paper's and the window scheme, verifies both, and keeps the
    one with fewer bits that has no ambiguous pose (the paper's on a tie); if
    neither verifies, one unique ID per luminaire.
    """
    if options.scheme not in SCHEMES:
        raise UsageError(f"--scheme {options.scheme}: unknown scheme; use one of {', '.join(SCHEMES)}")
    if options.scheme == "auto" and not options.verify:
        raise UsageError("--no-verify needs an explicit --scheme: auto chooses the scheme by verifying it")
    if options.receiver not in RECEIVERS:
        raise UsageError(f"--receiver {options.receiver}: unknown receiver; use one of {', '.join(RECEIVERS)}")
    if options.receiver != "three" and not options.verify:
        raise UsageError(f"--receiver {options.receiver} needs verification: the two-LED receiver is judged by "
                         "verifying it; drop --no-verify")
    xy, xyz = layout.xy, layout.xyz
    radii = np.array([lum.radius for lum in layout.luminaires])
    graph = build_graph(xy)
    cam = options.camera

    area = working_area(xy, layout.outline)
    with_error_map = options.verify and options.error_poses_per_m2 > 0
    per_m2 = plan_sample_per_m2(area, verify=options.verify, poses_per_m2=options.poses_per_m2,
                                error_poses_per_m2=options.error_poses_per_m2)
    sample = PoseSample.draw(area, xyz, radii, cam, per_m2, options.seed)  # every stage takes a prefix
    observations: dict = {}  # seed -> what the camera sees; shared by every scheme checked
    if options.verify:
        poses, windows = sample.first(options.poses_per_m2)
        observations[options.seed] = observe_poses(poses, xyz, radii, cam, per_m2=options.poses_per_m2,
                                                    seed=options.seed, tolerance_m=options.tolerance_m, windows=windows)

    def verify_ids(ids: np.ndarray) -> Verification | None:
        return classify(observations[options.seed], ids) if options.verify else None

    def plan_three():
        proof = prove_window_set(xyz, radii, cam, options.install_tolerance_m) if options.verify else None
        made = {}
        if options.scheme in ("paper", "auto"):
            paper = assign_paper(xy, graph, time_budget=options.time_budget, seed=options.seed)
            made["paper"] = (paper, verify_ids(paper.ids))
        if options.scheme in ("window", "auto"):
            made["window"] = assign_window(xyz, radii, layout.outline, graph, cam, seed=options.seed,
                                           time_budget=options.time_budget, per_m2=options.poses_per_m2,
                                           tolerance_m=options.tolerance_m, install_tolerance_m=options.install_tolerance_m,
                                           observations=observations, proof=proof)
        if options.scheme == "unique":
            unique = assign_unique(xy, graph)
            made["unique"] = (unique, verify_ids(unique.ids))
        bound = max([side_bound(v.windows, xyz, options.tolerance_m) for _, v in made.values() if v]
                    + [float(a.detail.get("max_side_m", 0.0)) for a, _ in made.values()], default=0.0)

        def judged(a, v):  # every scheme is also judged on the window set, up to one side bound
            return a, (v and replace(v, window_set=check_window_set(xyz, radii, a.ids, bound,
                                                                      tolerance_m=options.tolerance_m,
                                                                      install_tolerance_m=options.install_tolerance_m,
                                                                      proof=proof)))

        made = {k: judged(a, v) for k, (a, v) in made.items()}
        if options.scheme == "auto":
            clean = [k for k, (_, v) in made.items() if v is not None and v.clean]  # auto verifies: never None
            if clean:
                chosen = min(clean, key=lambda k: (made[k][0].bits, k != "paper"))
            else:
                unique = assign_unique(xy, graph)
                made["unique"] = judged(unique, verify_ids(unique.ids))
                chosen = "unique"
        else:
            chosen = options.scheme
        assignment, verification = made[chosen]
        counted = (window_set_bound(proof, xyz, made.get("window", (None, None))[0], options.tolerance_m)
                   if proof is not None else None)
        if counted is not None:  # the counting bound of the window set, proved or sampled, beside the width
            assignment = replace(assignment, detail={**assignment.detail, "window_set": counted})
        considered = {k: {"bits": a.bits, "ambiguous_poses": (v.count(1) if v else None),
                          "window_set_conflicts": (len(v.window_set.conflicts) if v and v.window_set else None)}
                      for k, (a, v) in made.items()}
        return assignment, verification, considered

    def plan_two():
        from planner.receivers import plan_gravity

        return plan_gravity(xyz, radii, graph, cam, sample, scheme=options.scheme, per_m2=options.poses_per_m2,
                            seed=options.seed, time_budget=options.time_budget, tolerance_m=options.tolerance_m,
                            install_tolerance_m=options.install_tolerance_m)

    receiver = None
    if options.receiver == "three":
        assignment, verification, considered = plan_three()
    else:
        from planner.receivers import AUTO_GOAL, ReceiverChoice, seen_shares

        planned = {}
        if options.receiver == "auto":
            planned["three"] = plan_three()
        if options.receiver == "gravity" or planned["three"][1].coverage < AUTO_GOAL:
            planned["gravity"] = plan_two()
        coverage = {k: float(v.coverage) for k, (_, v, _) in planned.items()}
        mode = max(coverage, key=lambda k: (coverage[k], k == "three"))
        reason = ("asked for (--receiver gravity)" if options.receiver == "gravity" else
                  f"three-LED receiver decodes {100 * coverage['three']:.1f} % of sampled poses, at least the goal "
                  f"of {100 * AUTO_GOAL:.0f} %" if len(planned) == 1 else
                  f"decodes more sampled poses ({100 * coverage[mode]:.1f} % against "
                  f"{100 * min(coverage.values()):.1f} %)")
        assignment, verification, considered = planned[mode]
        receiver = ReceiverChoice(mode, coverage, seen_shares(sample.first(options.poses_per_m2)[1]), reason,
                                  options.accelerometer_sigma_deg)
    check = check_code(assignment.max_id, assignment.bits, options.check_distance)
    code = line_code(options.line_code)
    index = assignment.ids - 1
    words = check.codewords[index] if check.distance > 1 else index
    if receiver is not None and receiver.mode == "gravity":
        from planner.receivers import smallest_pair_image_rows

        rows = smallest_pair_image_rows(xyz, radii, cam, sample)
    else:
        rows = smallest_window_image_rows(xyz, radii, cam, sample)
    modulation = modulate(np.asarray(words), check.word_bits, code, rows, cam, driver_max_hz=options.driver_max_hz,
                          video_fps=options.video_fps, max_video_frames=options.max_video_frames,
                          mcu_clock_hz=options.mcu_clock_hz)
    accuracy = None
    if with_error_map:
        gravity = receiver is not None and receiver.mode == "gravity"  # its accelerometer's error: one more term
        sigma_rad = float(np.radians(options.accelerometer_sigma_deg))
        accuracy = site_accuracy(xyz, radii, layout.outline, cam, "gravity" if gravity else options.locate_method,
                                 per_m2=options.error_poses_per_m2, seed=options.seed, sample=sample,
                                 terms=replace(options.error_terms, gravity_rad=sigma_rad) if gravity else
                                 options.error_terms, accelerometer_sigma_rad=sigma_rad)
    advice = None
    if verification is not None:
        filled = all(lum.source.get("generated") == "lattice" for lum in layout.luminaires)
        share = [verification.count(k) / max(verification.poses, 1) for k in (TOO_FEW, AMBIGUOUS)]
        mode = receiver.mode if receiver is not None else "three"
        frames = FrameLimits(options.line_code, options.check_distance, options.driver_max_hz, options.video_fps,
                             options.max_video_frames, options.mcu_clock_hz)  # the changes' frames must fit too
        advice = advise(Site(xyz, radii, layout.outline, cam, mode, filled), verification.coverage, *share,
                        goal=options.coverage_goal, seed=options.seed, frames=frames,
                        allow_unusable=options.allow_unusable)
    return Plan(layout, graph, assignment, cam, verification, considered, check, accuracy, modulation, advice, receiver)


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
    mcu_clock_hz: float = 16e6
    image_version: int = 1


def write_outputs(plan: Plan, outdir: str | Path, *, with_map: bool = True,
                  firmware: FirmwareOptions | None = FirmwareOptions(), with_report: bool = True) -> list[Path]:
    """Write ``plan.yaml``, the annotated DXF (and IFC, from an IFC model), the maps, the site report and the
    firmware files into ``outdir``, atomically.

    Everything is written into a temporary directory beside ``outdir`` and moved
    into place at the end: on any error, no partial output is left. An existing
    ``outdir`` is replaced only if it is empty or holds a previous plan that no
    driver has been flashed with (no ``as-built.json``).
    """
    outdir = Path(outdir)
    if outdir.exists() and not (outdir.is_dir() and (not any(outdir.iterdir()) or (outdir / "plan.yaml").exists())):
        raise UsageError(f"{outdir}: exists and is not a vlp-plan output directory; choose another -o")
    if (outdir / "as-built.json").exists():
        raise UsageError(f"{outdir}: holds as-built.json, the record of drivers flashed with the plan there, which "
                         "replanning would delete; choose another -o, or move as-built.json away first")
    try:
        outdir.parent.mkdir(parents=True, exist_ok=True)
        stage = Path(tempfile.mkdtemp(prefix=f".{outdir.name}.", dir=outdir.parent))
    except OSError as exc:
        raise UsageError(f"-o {outdir}: cannot write there ({exc.strerror}); choose another -o") from None
    source = Path(plan.layout.source_path)
    try:
        stage.chmod(0o755)  # mkdtemp makes it private; outputs are for the whole crew
        document = plan_document(plan, _sha256(source) if source.is_file() else "")
        text = dump_plan(document)
        (stage / "plan.yaml").write_text(text, encoding="utf-8")
        written = plan_from_document(document, str(outdir / "plan.yaml"))  # what later stages will read back
        if firmware is not None and plan.modulation is not None:
            from planner.firmware.render import write_firmware

            write_firmware(written, plan_hash(text), stage, template_dir=firmware.template_dir,
                           mcu_clock_hz=firmware.mcu_clock_hz, image_version=firmware.image_version)
        from planner import __version__
        from planner.layout.dxf_annotate import write_annotated_dxf

        is_dxf = source.suffix.lower() == ".dxf"
        write_annotated_dxf(stage / f"{source.stem}-vlp.dxf", plan.layout, written.luminaires,
                            source_path=source if is_dxf else None, tool_version=__version__)
        if source.suffix.lower() == ".ifc":
            from planner.layout.ifc_annotate import write_annotated_ifc

            write_annotated_ifc(stage / f"{source.stem}-vlp.ifc", plan.layout, written.luminaires,
                                source_path=source, tool_version=__version__)
        if with_map:
            from planner.report.maps import render_coverage, render_error, render_map

            render_map(plan, stage / "map.png")
            if plan.verification is not None:
                render_coverage(plan.verification, plan.layout.xy,
                                f"{source.name}: {plan.assignment.scheme} scheme", stage / "coverage.png")
            if plan.accuracy is not None:
                render_error(plan, stage / "error.png")
        if with_report:
            from planner.report.files import write_report

            write_report(written, plan_hash(text), stage, stage)
        names = sorted(p.name for p in stage.iterdir())
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
    return [outdir / name for name in names]
