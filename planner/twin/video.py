"""Read IDs over ``k`` consecutive video frames, as a receiver app does when no LED image holds a whole frame.

1. **Render** ``k`` frames a video period ``T_v = 1 / video_fps`` apart: every
   luminaire's drive runs on, so frame ``j`` starts at phase ``phase_0 + j T_v rate``;
   the brightness factors stay (the same LEDs).
2. **Track**: each LED blob of frame 0 (found by :func:`planner.decode.image.decode_frame`)
   is followed to the nearest blob of every later frame, within its own minor
   semi-axis (neighbouring LEDs lie at least a diameter apart).
3. **Stitch**: each row of a tracked blob gives the drive at a known time,
   ``j T_v + v row_time + exposure / 2``, that is at chip coordinate ``x = rate t``.
   Thresholded halfway, the level crossings give the chips' boundaries, all at
   ``phase + integer``: each frame measures its own sub-chip phase (near the others',
   so drift between the phone's and the driver's clocks shows as a shift, not a
   slip); every chip slot whose centre lies inside a frame's rows (a quarter chip
   in) is read there, at its centre, into cyclic position ``slot mod frame_chips``.
   A slot read in two frames must agree; a slot read in none leaves a gap.
4. **ID**: the cyclic frame (one unknown rotation of the driver's) goes to
   :func:`planner.modulation.frame.decode_stream`, which finds the preamble in it.

The receiver knows the site's chip rate and frame length, its own video rate,
row time and exposure, as an app set up for the site does. docs/twin.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import cv2
import numpy as np

from planner.camera.model import Camera
from planner.decode.image import Blob, FrameFormat, chord_rows, decode_frame, row_levels
from planner.errors import InputError
from planner.modulation.frame import decode_stream

if TYPE_CHECKING:
    from planner.plan.file import PlanFile

SLOT_INSET_CHIPS = 0.25
"""A chip slot is read in a frame if its centre lies this far inside the frame's first and last rows."""

MIN_CONTRAST_DN = 8.0
"""A frame whose rows differ by less (5th to 95th percentile) shows no stripes of that LED."""


@dataclass(frozen=True)
class VideoFormat:
    """How many consecutive video frames a frame is read over, and the video rate."""

    frames: int
    fps: float

    @property
    def period_s(self) -> float:
        return 1.0 / self.fps

    @classmethod
    def from_plan(cls, plan: PlanFile) -> VideoFormat | None:
        """The plan's video reading, or None for a single-frame plan."""
        mod = plan.modulation
        if mod is None or mod.video_frames < 2:
            return None
        assert mod.video_fps is not None  # the plan reader checks it
        return cls(mod.video_frames, mod.video_fps)


def row_signal(image: np.ndarray, blob: Blob, blur_px: float) -> tuple[np.ndarray, np.ndarray]:
    """Image rows (absolute) a blob's drive is read from, and their levels [DN], as the single-frame reader does."""
    assert blob.ellipse is not None
    x, y, w, h = blob.bbox
    pad, margin = 4, 1.0 + blur_px
    x0, y0 = max(0, x - pad), max(0, y - pad)
    roi = image[y0:min(image.shape[0], y + h + pad), x0:min(image.shape[1], x + w + pad)]
    levels = row_levels(roi, blob.ellipse, x0, y0, margin)
    rows = y0 + chord_rows(roi.shape[0], blob.ellipse, y0, margin)
    ok = np.isfinite(levels)
    return rows[ok], levels[ok]


def _circular_phase(x: np.ndarray) -> float:
    """Mean sub-chip phase in [0, 1) of chip boundaries at ``x`` [chips]."""
    angle = 2 * np.pi * x
    return float(np.mod(np.arctan2(np.sin(angle).sum(), np.cos(angle).sum()) / (2 * np.pi), 1.0))


def stitch(signals: list[tuple[np.ndarray, np.ndarray]], frame_chips: int) -> tuple[str, str]:
    """The cyclic frame from each video frame's (chip coordinates [chips], levels) of one LED; and a problem
    ("" when every chip was read, and read alike wherever read twice)."""
    usable, edges = [], []
    for x, level in signals:
        if len(x) < 4:
            continue
        lo, hi = np.percentile(level, [5, 95])
        if hi - lo < MIN_CONTRAST_DN:
            continue
        mid = (lo + hi) / 2
        above = level > mid
        at = np.flatnonzero(above[1:] != above[:-1])
        cross = x[at] + (mid - level[at]) / (level[at + 1] - level[at]) * (x[at + 1] - x[at])
        usable.append((x, level, mid, cross))
        edges.append(cross)
    if not usable or not sum(len(e) for e in edges):
        return "", "no stripes read"
    common = _circular_phase(np.concatenate(edges))
    votes: list[set[str]] = [set() for _ in range(frame_chips)]
    for x, level, mid, cross in usable:
        own = _circular_phase(cross) if len(cross) else common
        phase = common + (own - common + 0.5) % 1.0 - 0.5  # this frame's phase, unwrapped next to the others'
        first = math.ceil(x[0] + SLOT_INSET_CHIPS - phase - 0.5)
        last = math.floor(x[-1] - SLOT_INSET_CHIPS - phase - 0.5)
        for n in range(first, last + 1):
            votes[n % frame_chips].add("1" if np.interp(phase + n + 0.5, x, level) > mid else "0")
    if any(len(v) > 1 for v in votes):
        return "", f"video frames disagree on {sum(len(v) > 1 for v in votes)} chips"
    if any(not v for v in votes):
        return "", f"{sum(not v for v in votes)} of {frame_chips} chips seen in no video frame"
    return "".join(v.pop() for v in votes), ""


def _nearest(blob: Blob, candidates: list[Blob]) -> int | None:
    """Index of the candidate blob nearest ``blob``, within ``blob``'s minor semi-axis."""
    assert blob.ellipse is not None
    best, where = blob.ellipse.minor / 2, None
    for i, other in enumerate(candidates):
        if other.ellipse is not None:
            off = float(np.hypot(*(other.ellipse.centre - blob.ellipse.centre)))
            if off <= best:
                best, where = off, i
    return where


def decode_video(images: list[np.ndarray], camera: Camera, modulation: FrameFormat, video: VideoFormat, *,
                 blur_px: float = 1.0, exposure_s: float = 0.0) -> list[Blob]:
    """Frame 0's blobs, each LED's ID read from its stripes in all ``len(images)`` frames where one frame
    does not hold it (chips: the stitched cyclic frame)."""
    per_frame = [decode_frame(image, camera, modulation, blur_px=blur_px, exposure_s=exposure_s) for image in images]
    readable = [[b for b in blobs if b.ellipse is not None and b.problem in ("", "no whole frame read")]
                for blobs in per_frame]
    frame_chips = len(modulation.code.preamble) + modulation.code.payload_chips(modulation.word_bits)
    rate = modulation.chip_rate_hz
    out = []
    for blob in per_frame[0]:
        if blob.id is not None or blob.ellipse is None or blob.problem != "no whole frame read":
            out.append(blob)
            continue
        signals, last = [], blob
        for j, image in enumerate(images):
            found = _nearest(last, readable[j])
            if found is None:
                continue
            last = readable[j][found]
            rows, levels = row_signal(image, last, blur_px)
            signals.append((rate * (j * video.period_s + rows * camera.row_time_s + exposure_s / 2), levels))
        chips, problem = stitch(signals, frame_chips)
        if problem:
            out.append(replace(blob, problem=f"{problem} (over {len(images)} video frames)"))
            continue
        try:
            word = decode_stream(chips + chips, modulation.word_bits, modulation.code)
        except InputError:
            out.append(replace(blob, chips=chips, problem="no frame in the stitched chips"))
            continue
        led_id = modulation.id_of(word)
        out.append(replace(blob, chips=chips, id=led_id, problem="" if led_id else f"word {word} is not a codeword"))
    return out


def shaken(rotation: np.ndarray, frames: int, shake_rad: float, rng: np.random.Generator) -> list[np.ndarray]:
    """A hand's shake: each frame's camera-to-site rotation turned from the last one's by a normal angle of
    deviation ``shake_rad`` about a random axis (the first frame's is ``rotation``)."""
    out = [rotation]
    for _ in range(1, frames):
        axis = rng.standard_normal(3)
        turn = cv2.Rodrigues(axis / np.linalg.norm(axis) * rng.normal(0.0, shake_rad))[0]
        out.append(out[-1] @ turn)
    return out


