"""The receiver twin: render what the phone sees at a pose, decode it, locate, and grade every stage.

A pose's result names the first stage that failed:

``blobs``     fewer than three (two for a gravity plan) of the LEDs wholly in view were found as blobs with an ellipse;
``ids``       fewer than three (two) IDs were read, or a misread ID spoilt identification;
``identify``  the read LEDs were matched to no luminaires, to two places, or to the wrong ones;
``position``  identified right, but the position is off by more than the tolerance.

Poses are drawn as the verification draws them (:func:`planner.verify.windows.sample_poses`)
and kept only where the plan is decodable (three whole, non-collinear LEDs whose
window is unique): the twin checks the pixels, not the plan's coverage.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, TypedDict

import numpy as np

from planner.camera.ellipse import centre_and_shape
from planner.camera.model import Camera, Poses, disc_dual_conic, project_discs_at
from planner.decode.image import Blob, FrameFormat, decode_frame, read_blobs, read_ellipse
from planner.defaults import ACCELEROMETER_SIGMA_DEG
from planner.defaults import TWIN_TOLERANCE_M as TOLERANCE_M
from planner.errors import InputError, PlannerError
from planner.positioning.locate import Site, Snapshot, locate
from planner.positioning.observation import seen_leds
from planner.receivers.base import Receiver
from planner.receivers.modes import PAPER, receiver_for
from planner.twin.render import Frame, Sensor, render_frame
from planner.twin.video import VideoFormat, decode_video, shaken

if TYPE_CHECKING:
    from planner.plan.file import PlanFile

STAGES = ("blobs", "ids", "identify", "position")

MATCH_SHARE = 0.25
"""A blob belongs to an LED if its ellipse centre lies within this share of the LED image's minor axis ..."""

MATCH_FLOOR_PX = 3.0
"""... or within this many pixels: the centroid of an image a few pixels thin (a far LED at a wide lens's edge)
lies up to about a pixel plus the blur from where the lens maps the disc's centre (2.7 px measured)."""


@dataclass(frozen=True)
class Twin:
    """A plan as the twin needs it: the site, each driver's frame, the receiver's knowledge, camera and sensor."""

    site: Site
    chips: list[str]
    modulation: FrameFormat
    camera: Camera
    sensor: Sensor = Sensor()
    outline: list | None = None
    receiver: Receiver = PAPER  # its window rule, and the vertical it reads (planner.receivers)
    accelerometer_sigma_rad: float = math.radians(ACCELEROMETER_SIGMA_DEG)
    video: VideoFormat | None = None  # frames read over several video frames (planner.twin.video)

    @classmethod
    def from_plan(cls, plan: PlanFile, sensor: Sensor = Sensor(),
                  accelerometer_sigma_deg: float = ACCELEROMETER_SIGMA_DEG, camera: Camera | None = None) -> Twin:
        """The plan's site, frames and receiver, seen by ``camera`` (default: the plan's own)."""
        chips = plan.frames
        if chips is None:
            raise InputError("the plan has no frames (no 'modulation', or luminaires without 'frame'); "
                             "make it again with this vlp-plan")
        return cls(Site.from_plan(plan), chips, FrameFormat.from_plan(plan), camera or plan.camera_model(), sensor,
                   plan.outline,
                   receiver=receiver_for(plan.receiver_mode, "receiver.mode"),
                   accelerometer_sigma_rad=math.radians(accelerometer_sigma_deg),
                   video=VideoFormat.from_plan(plan))

    @property
    def window_leds(self) -> int:
        """LEDs the receiver's window needs."""
        return self.receiver.leds


@dataclass(frozen=True)
class PoseResult:
    """How one pose went, stage by stage."""

    position: np.ndarray
    angles_deg: tuple[float, float, float]  # tilt, azimuth, roll
    seen: int  # LEDs wholly in view
    found: int  # of those, found as blobs with an ellipse
    read: int  # of those, ID read right
    misread: int  # blobs (of any LED) whose ID was read wrong
    error_m: float  # position error (NaN without a fix)
    stage: str  # "" if located within tolerance, else the first stage that failed
    detail: str = ""
    blobs: list[Blob] = field(default_factory=list, repr=False, compare=False)

    @property
    def ok(self) -> bool:
        return self.stage == ""


class _Counted(TypedDict):
    """The fields of a :class:`PoseResult` that :func:`grade` knows before it tries to locate."""

    position: np.ndarray
    angles_deg: tuple[float, float, float]
    seen: int
    found: int
    read: int
    misread: int
    blobs: list[Blob]


def _truth(twin: Twin, position: np.ndarray, rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The LEDs in front of the camera: indices, image centres [px], minor semi-axes [px]; and those wholly in view."""
    site = twin.site
    centres, shapes, ok = centre_and_shape(disc_dual_conic(position, rotation, site.xyz, site.radii, twin.camera))
    front = project_discs_at(position[None], rotation[None], site.xyz[None], site.radii[None], twin.camera)["in_front"][0]
    index = np.flatnonzero(ok & front)
    whole = seen_leds(position, rotation, site.xyz, site.radii, twin.camera)
    minor = np.linalg.eigvalsh(shapes[index])[:, 0]
    if twin.camera.distorted:  # the images through the lens: centre moved, minor axis scaled by the local map
        centres, minor = _through_lens(twin.camera, centres[index], minor)
        return index, centres, minor, whole
    return index, centres[index], minor, whole


def _through_lens(camera: Camera, ideal_px: np.ndarray, minor_px: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where the lens puts ideal image centres [px], and minor semi-axes scaled by the map's least stretch there."""
    step = 0.5
    at = camera.distorted_pixels(ideal_px)
    du = (camera.distorted_pixels(ideal_px + [step, 0.0]) - at) / step
    dv = (camera.distorted_pixels(ideal_px + [0.0, step]) - at) / step
    jac = np.stack([du, dv], axis=-1)  # (N, 2, 2): columns d/du, d/dv
    least = np.linalg.svd(jac, compute_uv=False)[:, -1] if len(jac) else np.ones(0)
    return at, minor_px * least


def grade(twin: Twin, position: np.ndarray, rotation: np.ndarray, angles_deg, blobs: list[Blob],
          tolerance_m: float = TOLERANCE_M, gravity: np.ndarray | None = None) -> PoseResult:
    """Grade a decoded frame against the truth of its pose.

    Blobs are matched to any LED in front of the camera (a receiver may read an LED
    whose disc reaches into the sensor's outer half pixel, which the verification
    counts as cut); ``seen`` and ``found`` count the LEDs wholly in view. A gravity twin gives the
    snapshot ``gravity`` (the accelerometer's reading), or draws one seeded by the pose.
    """
    index, centres, minor, whole = _truth(twin, position, rotation)
    owner = {}  # blob number -> luminaire index
    for b, blob in enumerate(blobs):
        if blob.ellipse is None or not len(index):
            continue
        off = np.hypot(*(centres - blob.ellipse.centre).T)
        k = int(np.argmin(off))
        if off[k] <= max(MATCH_SHARE * 2 * minor[k], MATCH_FLOOR_PX):
            owner[b] = int(index[k])
    found = len(set(owner.values()) & set(whole.tolist()))
    wrong = [(b, owner[b]) for b in owner if blobs[b].id is not None and blobs[b].id != twin.site.ids[owner[b]]]
    read = sum(1 for b in owner if owner[b] in set(whole.tolist()) and blobs[b].id == twin.site.ids[owner[b]])
    base = _Counted(position=position, angles_deg=tuple(angles_deg), seen=len(whole), found=found, read=read,
                misread=len(wrong), blobs=blobs)
    misread = "; ".join(f"{twin.site.names[i]} (ID {twin.site.ids[i]}) read as {blobs[b].id}" for b, i in wrong)
    need = twin.window_leds
    if found < need:
        return PoseResult(**base, error_m=np.nan, stage="blobs", detail=f"{found} of {len(whole)} LEDs found")
    snap = snapshot(blobs, twin.camera)
    if gravity is None:
        gravity = twin.receiver.vertical(rotation, twin.accelerometer_sigma_rad,
                                         np.random.default_rng(np.frombuffer(np.asarray(position, float).tobytes(),
                                                                             np.uint32)))
    if gravity is not None:
        snap = replace(snap, gravity=gravity, gravity_sigma_rad=twin.accelerometer_sigma_rad)
    if len(snap.ids) < need:
        problems = sorted({b.problem for b in blobs if b.id is None and b.problem})
        return PoseResult(**base, error_m=np.nan, stage="ids", detail=f"{len(snap.ids)} IDs read ({'; '.join(problems)})")
    try:
        located = locate(twin.site, snap)
    except PlannerError as exc:
        return PoseResult(**base, error_m=np.nan, stage="ids" if wrong else "identify",
                          detail=f"misread {misread}" if wrong else str(exc))
    truth = [owner.get(b, -1) for b in read_blobs(blobs, twin.camera)]
    error = float(np.linalg.norm(located.fix.position - position))
    if list(located.luminaires) != truth:
        return PoseResult(**base, error_m=error, stage="ids" if wrong else "identify",
                          detail=f"misread {misread}" if wrong else "identified the wrong luminaires")
    if error > tolerance_m:
        return PoseResult(**base, error_m=error, stage="position", detail=f"off by {100 * error:.1f} cm")
    return PoseResult(**base, error_m=error, stage="")


def run_pose(twin: Twin, position: np.ndarray, rotation: np.ndarray, angles_deg, rng: np.random.Generator,
             tolerance_m: float = TOLERANCE_M) -> tuple[PoseResult, Frame]:
    """Render the pose's frame (a multi-frame plan's video frames), decode it, locate, and grade the result."""
    if twin.video is not None:
        return run_video_pose(twin, twin.video, position, rotation, angles_deg, rng, tolerance_m)
    frame = render_frame(twin.site.xyz, twin.site.radii, twin.chips, twin.modulation.chip_rate_hz, twin.camera,
                         position, rotation, twin.sensor, rng)
    blobs = decode_frame(frame.image, twin.camera, twin.modulation, blur_px=twin.sensor.blur_px,
                         exposure_s=twin.sensor.exposure_s)
    gravity = twin.receiver.vertical(rotation, twin.accelerometer_sigma_rad, rng)
    return grade(twin, position, rotation, angles_deg, blobs, tolerance_m, gravity), frame


def covered_poses(twin: Twin, count: int, seed: int = 0) -> Poses:
    """``count`` poses, drawn as the verification draws them, where the plan is decodable."""
    from planner.layout.model import area_m2
    from planner.verify.verify import DECODABLE
    from planner.verify.windows import sample_poses, working_area

    xyz = twin.site.xyz
    area = working_area(xyz[:, :2], twin.outline)
    per_m2 = 3.0 * count / max(area_m2(area), 1e-6)
    for _ in range(6):
        poses = sample_poses(area, twin.camera, per_m2, seed)
        status = twin.receiver.decodable(poses, xyz, twin.site.radii, twin.site.ids, twin.camera, per_m2=per_m2,
                                         seed=seed)
        good = np.flatnonzero(status == DECODABLE)
        if len(good) >= count:
            pick = np.sort(np.random.default_rng(seed).choice(good, count, replace=False))
            return poses.subset(pick)
        per_m2 *= 2 * count / max(len(good), 1)
    raise PlannerError(f"the plan is decodable at only {len(good)} of {len(poses)} sampled poses; "
                       f"ask for fewer than {count} poses")


def summary(results: list[PoseResult]) -> dict:
    """Success rate, failures per stage, each stage's own rate, and the position errors."""
    n = len(results)
    seen = sum(r.seen for r in results)
    found = sum(r.found for r in results)
    errors = np.array([r.error_m for r in results if r.ok])
    return {
        "poses": n,
        "located": sum(r.ok for r in results),
        "success_rate": sum(r.ok for r in results) / n if n else 0.0,
        "failed_by_stage": {s: sum(r.stage == s for r in results) for s in STAGES},
        "leds_in_view": seen,
        "blobs_found": found,
        "ids_read": sum(r.read for r in results),
        "ids_misread": sum(r.misread for r in results),
        "blob_rate": found / seen if seen else 0.0,
        "id_rate": sum(r.read for r in results) / found if found else 0.0,
        "error_m": ({"median": float(np.median(errors)), "p90": float(np.percentile(errors, 90)),
                     "max": float(errors.max())} if len(errors) else None),
    }


def snapshot(blobs: list[Blob], camera: Camera) -> Snapshot:
    """The positioning stage's input: the read blobs' IDs and ellipses, nearest the image centre first
    (distorted ellipses and the distorting camera: positioning undistorts them, :meth:`Snapshot.ideal`)."""
    read = [read_ellipse(blobs[k]) for k in read_blobs(blobs, camera)]
    return Snapshot(camera, [led_id for led_id, _ in read], [ellipse for _, ellipse in read])


def render_video(twin: Twin, video: VideoFormat, positions: list[np.ndarray], rotations: list[np.ndarray],
                 rng: np.random.Generator) -> list[Frame]:
    """The ``video.frames`` consecutive frames, the camera at ``positions[j]``, ``rotations[j]`` in frame ``j``."""
    lengths = np.array([len(c) for c in twin.chips], float)
    phase = rng.uniform(0.0, lengths) if len(lengths) else np.zeros(0)
    spread = twin.sensor.led_spread
    gain = 1.0 + rng.uniform(-spread, spread, len(lengths))
    advance = video.period_s * twin.modulation.chip_rate_hz
    site = twin.site
    return [render_frame(site.xyz, site.radii, twin.chips, twin.modulation.chip_rate_hz, twin.camera, positions[j],
                         rotations[j], twin.sensor, rng, phase_chips=np.mod(phase + j * advance, lengths), gain=gain)
            for j in range(video.frames)]


def run_video_pose(twin: Twin, video: VideoFormat, position: np.ndarray, rotation: np.ndarray, angles_deg,
                   rng: np.random.Generator, tolerance_m: float, shake_rad: float = 0.0) -> tuple[PoseResult, Frame]:
    """Render ``video.frames`` frames of a pose (still, or turned by ``shake_rad`` per frame), read the IDs over
    them, locate from frame 0, grade against frame 0's pose."""
    rotations = shaken(rotation, video.frames, shake_rad, rng) if shake_rad > 0 else [rotation] * video.frames
    frames = render_video(twin, video, [position] * video.frames, rotations, rng)
    blobs = decode_video([f.image for f in frames], twin.camera, twin.modulation, video,
                         blur_px=twin.sensor.blur_px, exposure_s=twin.sensor.exposure_s)
    return grade(twin, position, rotation, angles_deg, blobs, tolerance_m), frames[0]
