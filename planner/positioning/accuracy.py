"""Positioning accuracy by simulation: the paper's experiment (Tables 2-3) and a site's error map.

Every trial is a camera pose, the observation model's fitted ellipses for it
(:mod:`planner.positioning.observation`) and a position found by a method (``paper`` or
``perspective``); the error is the distance [m] from the true camera centre.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from planner.camera import Camera, Poses, rotation_from_angles
from planner.defaults import ERROR_POSES_PER_M2, PAPER_RADIUS_M, PAPER_TILTS_DEG
from planner.errors import PositioningError
from planner.plot_style import save_png, styled
from planner.positioning.locate import METHODS
from planner.positioning.observation import NOISE_PX, observe

if TYPE_CHECKING:
    from planner.verify.windows import PoseSample

# The paper's rig (Table 2), metres; its LED radius and tilts are in planner.defaults.
PAPER_LEDS_M = np.array([[0.0, 0.3, 2.5], [0.0, -0.3, 2.5], [0.5, 0.0, 2.5], [-0.5, 0.0, 2.5]])
PAPER_HEIGHT_M = 0.7
PAPER_TABLE3_CM = {0: (2.76, 4.287), 20: (7.16, 11.43), 30: (6.74, 11.63), 40: (11.72, 20.31)}
"""Table 3 as printed: tilt [deg] -> (mean error, 90 % bound) [cm]."""

HAND_JITTER_DEG = (1.0, 5.0, 5.0)
"""Half-widths of the uniform tilt, azimuth and roll jitter of a hand-held phone, per trial [deg]."""


@dataclass(frozen=True)
class Trials:
    """Errors [m] of each method over one tilt's trials (NaN where a method gave no position)."""

    tilt_deg: float
    errors: dict[str, np.ndarray]
    unusable: int  # trials whose image held fewer than three whole LEDs


def paper_test_points() -> tuple[np.ndarray, np.ndarray]:
    """The 16 test points: ceiling points the camera aims at (16 x 2) [m] and tilt azimuths [rad].

    A 4 x 4 grid over x in [-0.3, 0.3] m, y in [-0.15, 0.15] m under the rig; the
    phone is "held away from the LEDs and tilted" towards them, from 16 directions.
    """
    gx, gy = np.meshgrid(np.linspace(-0.3, 0.3, 4), np.linspace(-0.15, 0.15, 4))
    return np.column_stack([gx.ravel(), gy.ravel()]), 2 * np.pi * np.arange(16) / 16


def _trial_pose(aim: np.ndarray, azimuth: float, tilt_deg: float, rng: np.random.Generator):
    jt, ja, jr = (math.radians(j) for j in HAND_JITTER_DEG)
    tilt = abs(math.radians(tilt_deg) + rng.uniform(-jt, jt))
    az = azimuth + rng.uniform(-ja, ja)
    rotation = rotation_from_angles(tilt, az, rng.uniform(-jr, jr))[0]
    drop = PAPER_LEDS_M[0, 2] - PAPER_HEIGHT_M
    position = np.array([*(aim - drop * math.tan(tilt) * np.array([math.cos(az), math.sin(az)])), PAPER_HEIGHT_M])
    return position, rotation


def paper_experiment(tilts_deg=PAPER_TILTS_DEG, trials: int = 10, noise_px: float = NOISE_PX,
                     radius_m: float = PAPER_RADIUS_M, seed: int = 0, camera: Camera | None = None) -> list[Trials]:
    """Table 3 in simulation: 16 test points x ``trials`` at each tilt, both methods on the same images."""
    camera = camera or Camera()
    rng = np.random.default_rng(seed)
    radii = np.full(len(PAPER_LEDS_M), radius_m)
    aims, azimuths = paper_test_points()
    out = []
    for tilt in tilts_deg:
        errors: dict[str, list[float]] = {m: [] for m in METHODS}
        unusable = 0
        for aim, az in zip(aims, azimuths):
            for _ in range(trials):
                position, rotation = _trial_pose(aim, az, tilt, rng)
                seen = observe(position, rotation, PAPER_LEDS_M, radii, camera, rng, noise_px)
                if len(seen.index) < 3:
                    unusable += 1
                    continue
                for name, method in METHODS.items():
                    errors[name].append(_error(method, seen, PAPER_LEDS_M, radii, camera, position))
        out.append(Trials(float(tilt), {m: np.array(v) for m, v in errors.items()}, unusable))
    return out


def _error(method, seen, xyz, radii, camera, truth) -> float:
    try:
        fix = method(xyz[seen.index], radii[seen.index], seen.ellipses, camera)
    except PositioningError:
        return math.nan
    return float(np.linalg.norm(fix.position - truth))


def stats_cm(errors: np.ndarray) -> tuple[float, float]:
    """(mean, 90th percentile) [cm] of the finite errors [m]."""
    e = errors[np.isfinite(errors)]
    return (float(np.mean(e)) * 100, float(np.percentile(e, 90)) * 100) if len(e) else (math.nan, math.nan)


def table3_text(results: list[Trials]) -> str:
    """Table 3 shaped: per tilt, the paper's printed figures and both simulated methods [cm]."""
    lines = ["tilt  paper's Table 3     paper method (sim)   perspective (sim)   ratio",
             "deg   mean     90 %       mean     90 %        mean     90 %       mean",
             ]
    for r in results:
        printed = PAPER_TABLE3_CM.get(int(r.tilt_deg), (math.nan, math.nan))
        paper, persp = stats_cm(r.errors["paper"]), stats_cm(r.errors["perspective"])
        ratio = paper[0] / persp[0] if persp[0] > 0 else math.inf
        lines.append(f"{r.tilt_deg:>4.0f}  {printed[0]:6.2f}  {printed[1]:6.2f}     {paper[0]:7.2f}  {paper[1]:7.2f}"
                     f"     {persp[0]:7.3f}  {persp[1]:7.3f}    {ratio:6.0f}x")
    lines.append("errors in cm; ratio = paper method mean / perspective mean")
    return "\n".join(lines)


@styled
def plot_cdf(results: list[Trials], path) -> None:
    """One panel per tilt: the CDF of each method's error (log axis, cm), as the paper's Fig. 8 and 10."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(results), figsize=(3.2 * len(results), 3.2), sharey=True, squeeze=False)
    styles = {"paper": ("black", "-"), "perspective": ("0.45", "--")}
    for ax, r in zip(axes[0], results):
        for name, err in r.errors.items():
            e = np.sort(err[np.isfinite(err)]) * 100
            colour, ls = styles.get(name, ("0.2", ":"))
            ax.step(e, np.arange(1, len(e) + 1) / len(e), where="post", color=colour, ls=ls, label=name)
        ax.set_xscale("log")
        ax.set_title(f"tilt {r.tilt_deg:.0f} deg")
        ax.set_xlabel("positioning error [cm]")
        ax.grid(True, which="both", color="0.85", lw=0.5)
    axes[0][0].set_ylabel("cumulative fraction of trials")
    axes[0][0].legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    save_png(fig, path)


ERROR_MAX_POSES = 1000
"""Most poses an error map simulates (about 6 s); larger sites get a sparser sample and larger squares."""

ERROR_CELL_M = 1.0
"""Smallest side of the squares over which the error map takes its median and 90th percentile [m];
squares grow (in steps of 0.5 m) so that they hold about eight sampled poses each."""


@dataclass(frozen=True)
class SiteAccuracy:
    """Simulated errors over a site: sampled camera centres (P x 3) [m] and errors (P,) [m], NaN where
    the pose gave no position (fewer than three whole LEDs, or all on one line)."""

    method: str
    noise_px: float
    position: np.ndarray
    error_m: np.ndarray
    cell_m: float = ERROR_CELL_M

    def summary(self) -> dict:
        e = self.error_m[np.isfinite(self.error_m)]
        q = (lambda p: round(float(np.percentile(e, p)), 6)) if len(e) else (lambda p: None)
        return {"method": self.method, "noise_px": self.noise_px, "poses": int(len(self.error_m)),
                "located": int(len(e)), "median_m": q(50), "p90_m": q(90), "max_m": q(100),
                "cell_m": self.cell_m}

    def cells(self, cell_m: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Cell edges in x and y [m] and the median and 90th-percentile error per cell [m] (NaN: no fix)."""
        cell_m = cell_m or self.cell_m
        ok = np.isfinite(self.error_m)
        xy, err = self.position[ok, :2], self.error_m[ok]
        lo = np.floor(self.position[:, :2].min(axis=0) / cell_m) * cell_m
        hi = np.ceil(self.position[:, :2].max(axis=0) / cell_m + 1e-9) * cell_m
        edges = [np.arange(lo[k], hi[k] + cell_m / 2, cell_m) for k in (0, 1)]
        shape = (len(edges[0]) - 1, len(edges[1]) - 1)
        ix = [np.clip(np.searchsorted(edges[k], xy[:, k], side="right") - 1, 0, shape[k] - 1) for k in (0, 1)]
        med, p90 = np.full(shape, np.nan), np.full(shape, np.nan)
        flat = ix[0] * shape[1] + ix[1]
        for cell in np.unique(flat):
            vals = err[flat == cell]
            med.flat[cell], p90.flat[cell] = np.median(vals), np.percentile(vals, 90)
        return edges[0], edges[1], med, p90


def error_per_m2(area: np.ndarray, per_m2: float = ERROR_POSES_PER_M2) -> float:
    """Pose density of the error map over ``area`` [m]: ``per_m2``, but at most :data:`ERROR_MAX_POSES` in all."""
    from planner.layout.model import area_m2

    return min(per_m2, ERROR_MAX_POSES / max(area_m2(area), 1e-6))


def site_accuracy(xyz: np.ndarray, radii: np.ndarray, outline, camera: Camera, method: str = "perspective",
                  per_m2: float = ERROR_POSES_PER_M2, seed: int = 0, noise_px: float = NOISE_PX,
                  sample: PoseSample | None = None) -> SiteAccuracy:
    """Error map of ``method`` over a site: poses sampled as the verification samples them,
    ``per_m2`` of floor but at most :data:`ERROR_MAX_POSES` (the first of ``sample``, a plan's one
    draw with seed ``seed``, if given)."""
    from planner.verify.windows import sample_poses, working_area

    area = working_area(xyz[:, :2], outline) if sample is None else sample.area
    per_m2 = error_per_m2(area, per_m2)
    cell = max(ERROR_CELL_M, math.ceil(2 * math.sqrt(8 / per_m2)) / 2)
    poses = sample_poses(area, camera, per_m2=per_m2, seed=seed) if sample is None else sample.first(per_m2)[0]
    errors = site_errors(xyz, radii, poses, camera, method, noise_px, seed)
    return SiteAccuracy(method, noise_px, poses.position, errors, cell)


def site_errors(xyz: np.ndarray, radii: np.ndarray, poses: Poses, camera: Camera, method: str = "perspective",
                noise_px: float = NOISE_PX, seed: int = 0) -> np.ndarray:
    """Error [m] of ``method`` at every pose (NaN where the pose gives no position), identities known."""
    rng = np.random.default_rng(seed)
    locate = METHODS[method]
    out = np.full(len(poses), np.nan)
    rotations = poses.rotation
    for k in range(len(poses)):
        seen = observe(poses.position[k], rotations[k], xyz, radii, camera, rng, noise_px)
        if len(seen.index) >= 3:
            out[k] = _error(locate, seen, xyz, radii, camera, poses.position[k])
    return out
