"""What a receiver mode is: the rules one kind of phone receiver decodes and locates by.

A mode is one class (:mod:`planner.receivers.three`, :mod:`planner.receivers.gravity`), registered
once (:mod:`planner.receivers.modes`) and chosen once by name (``--receiver``, a plan's
``receiver.mode``). It owns its window rule (what a pose must see), its proof and code design, its
identification (the vertical a snapshot carries) and its accuracy model; the other stages ask the
mode, never compare its name.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar, TypeAlias

import numpy as np

from planner.camera.model import Camera, Poses
from planner.graph import NeighbourGraph
from planner.parallel import Runner
from planner.positioning.error_terms import ErrorTerms
from planner.verify.verify import Verification
from planner.verify.windows import PoseSample, sample_poses, working_area

if TYPE_CHECKING:
    from planner.codes.assignment import Assignment


@dataclass(frozen=True)
class Job:
    """What a mode plans IDs for: the site [m], its graph and camera, the plan's one pose sample (every
    stage takes a prefix), what the camera sees per seed when verifying (shared by every scheme
    checked), and the search's and the verification's settings."""

    xyz: np.ndarray
    radii: np.ndarray
    outline: object
    graph: NeighbourGraph
    camera: Camera
    sample: PoseSample
    observations: dict
    scheme: str
    seed: int
    time_budget: float
    poses_per_m2: float
    tolerance_m: float
    install_tolerance_m: float
    verify: bool
    runner: Runner | None = None  # where the proof's tiles run (planner.parallel); None: in process


Planned: TypeAlias = "tuple[Assignment, Verification | None, dict]"
"""The IDs, their verification (None unverified) and every scheme considered."""


class Receiver:
    """One receiver mode. Subclasses set the class attributes and implement the methods."""

    name: ClassVar[str]  # as --receiver and plan.yaml's receiver.mode write it
    leds: ClassVar[int]  # whole LEDs a window holds
    leds_text: ClassVar[str]  # the same, in words
    title: ClassVar[str]  # for summaries and the report
    window_words: ClassVar[str]  # what a pose must see to decode
    shape: ClassVar[str]  # what the window set is made of ("triangles", "pairs")
    extra_error_terms: ClassVar[tuple[str, ...]] = ()  # error terms only this mode's accuracy model has

    def plan(self, job: Job) -> Planned:
        """IDs for this mode under ``job.scheme``, verified on its windows when ``job.verify``."""
        raise NotImplementedError

    def verify(self, xyz: np.ndarray, radii: np.ndarray, ids: np.ndarray, outline, camera: Camera, *, per_m2: float,
               seed: int, tolerance_m: float, install_tolerance_m: float, recorded: dict,
               runner: Runner | None = None) -> Verification:
        """A plan verified anew (``vlp-verify``): sampled windows and the window set, proved where the proof
        completes (made from the luminaires and the camera, its tiles on ``runner``; ``recorded``: the plan's
        window-set section)."""
        raise NotImplementedError

    def coverage(self, xyz: np.ndarray, radii: np.ndarray, outline, camera: Camera, per_m2: float, seed: int) -> float:
        """Share of sampled poses that see a window of this mode."""
        poses = sample_poses(working_area(xyz[:, :2], outline), camera, per_m2, seed)
        return float(self.window_leds(poses, xyz, radii, camera)[1].mean())

    def window_leds(self, poses: Poses, xyz: np.ndarray, radii: np.ndarray, camera: Camera
                    ) -> tuple[np.ndarray, np.ndarray]:
        """Each pose's window under this mode's rule: its LEDs (P, leds) luminaire indices and whether the pose
        sees one (P,) bool; pose by pose, so the windows of a prefix of ``poses`` are a prefix of these."""
        raise NotImplementedError

    def decodable(self, poses: Poses, xyz: np.ndarray, radii: np.ndarray, ids: np.ndarray, camera: Camera, *,
                  per_m2: float, seed: int) -> np.ndarray:
        """Each pose's status under ``ids`` (:data:`planner.verify.verify.DECODABLE` where it decodes)."""
        raise NotImplementedError

    def smallest_image_rows(self, xyz: np.ndarray, radii: np.ndarray, camera: Camera, sample: PoseSample
                            ) -> float | None:
        """Rows of the smallest LED image in any window over the timing prefix of ``sample`` (the frame must fit);
        None if no pose of that prefix sees a window."""
        raise NotImplementedError

    def vertical(self, rotation: np.ndarray, sigma_rad: float, rng: np.random.Generator) -> np.ndarray | None:
        """The measured down direction the snapshot carries (camera frame), or None: this mode reads none."""
        return None

    def exact_vertical(self, rotation: np.ndarray) -> np.ndarray | None:
        """The true down direction in the camera frame, for a made-up observation; None if this mode reads none."""
        return None

    def accuracy_method(self, method: str) -> str:
        """The positioning method the accuracy model simulates, given the one asked for."""
        return method

    def error_terms(self, terms: ErrorTerms, accelerometer_sigma_rad: float) -> ErrorTerms:
        """The error terms at work for this mode (a mode with an accelerometer adds its error)."""
        return terms
