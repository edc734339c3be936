"""Positioning accuracy by simulation: the paper's experiment (Tables 2-3) and a site's error map.

Every trial is a camera pose, the ellipses fitted to its image with the error terms at work
(:mod:`planner.positioning.error_terms`; pixel noise alone is the observation model of
:mod:`planner.positioning.observation`) and a position found by a method (``paper`` or
``perspective`` from three LEDs; on a site also ``gravity``, two LEDs plus the accelerometer's
vertical, :mod:`planner.positioning.gravity`); the error is the distance [m] from the true camera
centre. The budget runs each term alone and all together on the same poses.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from planner.camera.model import Camera, Poses, rotation_from_angles
from planner.defaults import ACCELEROMETER_SIGMA_DEG, ERROR_POSES_PER_M2, PAPER_RADIUS_M, PAPER_TILTS_DEG
from planner.errors import PositioningError
from planner.plot_style import plain_log_ticks, save_png, styled
from planner.positioning.error_terms import (
    DEFAULT_TERMS,
    NO_TERMS,
    PIXEL_ONLY,
    ErrorTerms,
    dominant,
    installed,
    observe_with,
    streams,
)
from planner.positioning.gravity import accelerometer, locate_gravity, window_order  # the twin's accelerometer too
from planner.positioning.locate import METHODS
from planner.positioning.observation import Sighting
from planner.positioning.perspective import locate_perspective

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


def paper_experiment(tilts_deg=PAPER_TILTS_DEG, trials: int = 10, terms: ErrorTerms = PIXEL_ONLY,
                     radius_m: float = PAPER_RADIUS_M, seed: int = 0, camera: Camera | None = None,
                     model: ErrorTerms | None = None) -> list[Trials]:
    """Table 3 in simulation: 16 test points x ``trials`` at each tilt, both methods on the same images.

    The rig is installed afresh for every trial (``terms.install_m``); the poses depend on
    ``seed`` only, so runs with other terms see the same poses. The perspective fit weighs its
    residuals by ``model`` (default ``terms``; :func:`solver`).
    """
    fits = {name: solver(name, model or terms) for name in METHODS}
    camera = camera or Camera()
    rngs = streams(seed)
    radii = np.full(len(PAPER_LEDS_M), radius_m)
    aims, azimuths = paper_test_points()
    out = []
    for tilt in tilts_deg:
        errors: dict[str, list[float]] = {m: [] for m in METHODS}
        unusable = 0
        for aim, az in zip(aims, azimuths):
            for _ in range(trials):
                position, rotation = _trial_pose(aim, az, tilt, rngs["pose"])
                leds = installed(PAPER_LEDS_M, terms.install_m, rngs["install"])
                seen = observe_with(position, rotation, leds, radii, camera, terms, rngs)
                if len(seen.index) < 3:
                    unusable += 1
                    continue
                for name, fit in fits.items():
                    errors[name].append(_error(fit, seen, PAPER_LEDS_M, radii, camera.ideal(), position))
        out.append(Trials(float(tilt), {m: np.array(v) for m, v in errors.items()}, unusable))
    return out


def budget_runs(terms: ErrorTerms) -> dict[str, ErrorTerms]:
    """The runs of a budget: ``exact`` images (no term: the method's own error), ``all`` (every term of
    ``terms``), then each active term alone."""
    return {"exact": NO_TERMS, "all": terms, **{name: terms.only(name) for name in terms.active}}


def paper_budget(tilts_deg=PAPER_TILTS_DEG, trials: int = 10, terms: ErrorTerms = DEFAULT_TERMS,
                 radius_m: float = PAPER_RADIUS_M, seed: int = 0,
                 camera: Camera | None = None) -> dict[str, list[Trials]]:
    """:func:`paper_experiment` for every run of :func:`budget_runs`, on the same poses and with the same
    receiver (weighing by ``terms`` in every run: only the world changes); runs with the same terms, such as
    ``all`` and the one term switched on, are simulated once."""
    done: dict[ErrorTerms, list[Trials]] = {}
    for t in budget_runs(terms).values():
        if t not in done:
            done[t] = paper_experiment(tilts_deg, trials, t, radius_m, seed, camera, terms)
    return {name: done[t] for name, t in budget_runs(terms).items()}


def solver(method: str, terms: ErrorTerms):
    """A three-LED method of :data:`~planner.positioning.locate.METHODS` as a simulation runs it: the
    perspective fit weighs its residuals by ``terms`` (it is told the budget's model, never its draws)."""
    return functools.partial(locate_perspective, terms=terms) if method == "perspective" else METHODS[method]


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


def table3_text(pixel: list[Trials], full: list[Trials]) -> str:
    """Table 3 shaped: per tilt, the paper's printed figures and both simulated methods with pixel noise only
    and with every term on, mean / 90 % [cm]."""
    lines = ["tilt  paper's Table 3   paper method (sim)              perspective (sim)",
             "deg   mean    90 %      pixel only     all terms        pixel only     all terms"]
    for p, f in zip(pixel, full):
        printed = PAPER_TABLE3_CM.get(int(p.tilt_deg), (math.nan, math.nan))
        cells = ["{:6.2f} {:6.2f}".format(*stats_cm(r.errors[m])) for m in ("paper", "perspective") for r in (p, f)]
        lines.append(f"{p.tilt_deg:>4.0f}  {printed[0]:6.2f} {printed[1]:6.2f}    " + "   ".join(cells))
    lines.append("errors in cm, mean and 90th percentile")
    return "\n".join(lines)


def dominant_term(runs: dict[str, list[Trials]], method: str, k: int) -> str | None:
    """The largest contributor (:func:`~planner.positioning.error_terms.dominant`, on means) at tilt number ``k``."""
    alone = {n: stats_cm(rs[k].errors[method])[0] for n, rs in runs.items()}
    return dominant({n: v for n, v in alone.items() if math.isfinite(v)})


def budget_text(runs: dict[str, list[Trials]]) -> str:
    """The error budget per method and tilt: mean error [cm] with exact images, each term alone, all together."""
    names = [*(n for n in runs if n != "all"), "all"]
    lines = []
    for method in METHODS:
        lines += [f"error budget, {method} method: mean error [cm] with exact images, each term alone, all together",
                  "tilt " + "".join(
            f"{'exact images' if n == 'exact' else n:>13}" for n in names) + "  dominant"]
        for k, r in enumerate(runs["all"]):
            lines.append(f"{r.tilt_deg:>4.0f} " + "".join(f"{stats_cm(runs[n][k].errors[method])[0]:13.3f}"
                                                          for n in names) + f"  {dominant_term(runs, method, k)}")
    return "\n".join(lines)


@styled
def plot_cdf(results: list[Trials], path, fmt: str = "png") -> None:
    """One panel per tilt: the CDF of each method's error (log axis, cm), as the paper's Fig. 8 and 10; written
    as PNG or (``fmt`` "svg") SVG."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(results), figsize=(3.2 * len(results), 3.2), sharey=True, squeeze=False)
    styles = {"paper": ("black", "-"), "perspective": ("0.45", "--")}
    for ax, r in zip(axes[0], results):
        for name, err in r.errors.items():
            e = np.sort(err[np.isfinite(err)]) * 100
            colour, ls = styles.get(name, ("0.2", ":"))
            ax.step(e, np.arange(1, len(e) + 1) / len(e), where="post", color=colour, ls=ls, label=name)
        ax.set_xscale("log")
        plain_log_ticks(ax.xaxis)
        ax.set_title(f"tilt {r.tilt_deg:.0f} deg")
        ax.set_xlabel("positioning error [cm]")
        ax.grid(True, which="both", color="0.85", lw=0.5)
    axes[0][0].set_ylabel("cumulative fraction of trials")
    axes[0][0].legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    save_png(fig, path, fmt)


ERROR_MAX_POSES = 1000
"""Most poses an error map simulates (about 6 s, pixel noise only; the budget's runs on
:data:`BUDGET_MAX_POSES` come on top); larger sites get a sparser sample and larger squares."""

ERROR_CELL_M = 1.0
"""Smallest side of the squares over which the error map takes its median and 90th percentile [m];
squares grow (in steps of 0.5 m) so that they hold :data:`ERROR_CELL_POSES` sampled poses each."""

ERROR_CELL_POSES = 20
"""Sampled poses an error-map square holds on average: a 90th percentile of fewer is one or two poses' error
(squares of eight poses each, about six located, drew noise as if it were measured)."""


BUDGET_MAX_POSES = 250
"""Most poses each term of a site's budget is run alone on (the first of the map's)."""


@dataclass(frozen=True)
class SiteAccuracy:
    """Simulated errors over a site: sampled camera centres (P x 3) [m] and errors (P,) [m] with ``terms`` at
    work, NaN where the pose gave no position (fewer than three whole LEDs, or all on one line); ``budget``
    holds each run of :func:`budget_runs` on the first poses: (poses located, median, 90th percentile [m])."""

    method: str
    terms: ErrorTerms
    position: np.ndarray
    error_m: np.ndarray
    cell_m: float = ERROR_CELL_M
    budget: dict[str, tuple[int, float | None, float | None]] = field(default_factory=dict)

    @property
    def dominant(self) -> str | None:
        """The largest contributor to the error (:func:`~planner.positioning.error_terms.dominant`, on medians)."""
        return dominant({k: v[1] for k, v in self.budget.items() if v[1] is not None})

    def summary(self) -> dict:
        e = self.error_m[np.isfinite(self.error_m)]
        q = (lambda p: round(float(np.percentile(e, p)), 6)) if len(e) else (lambda p: None)
        return {"method": self.method, "noise_px": self.terms.edge_px, "poses": int(len(self.error_m)),
                "located": int(len(e)), "median_m": q(50), "p90_m": q(90), "max_m": q(100),
                "cell_m": self.cell_m, "terms": self.terms.to_dict(), "includes": self.terms.active,
                "budget": {k: {"located": n, "median_m": m, "p90_m": p} for k, (n, m, p) in self.budget.items()},
                "dominant": self.dominant}
    def cells(self, cell_m: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Cell edges in x and y [m], the median and 90th-percentile error per cell [m] (NaN: no fix) and the
        poses located in each cell."""
        cell_m = cell_m or self.cell_m
        ok = np.isfinite(self.error_m)
        xy, err = self.position[ok, :2], self.error_m[ok]
        lo = np.floor(self.position[:, :2].min(axis=0) / cell_m) * cell_m
        hi = np.ceil(self.position[:, :2].max(axis=0) / cell_m + 1e-9) * cell_m
        edges = [np.arange(lo[k], hi[k] + cell_m / 2, cell_m) for k in (0, 1)]
        shape = (len(edges[0]) - 1, len(edges[1]) - 1)
        ix = [np.clip(np.searchsorted(edges[k], xy[:, k], side="right") - 1, 0, shape[k] - 1) for k in (0, 1)]
        med, p90, count = np.full(shape, np.nan), np.full(shape, np.nan), np.zeros(shape, int)
        flat = ix[0] * shape[1] + ix[1]
        for cell in np.unique(flat):
            vals = err[flat == cell]
            med.flat[cell], p90.flat[cell], count.flat[cell] = np.median(vals), np.percentile(vals, 90), len(vals)
        return edges[0], edges[1], med, p90, count


METHOD_TEXT = {"gravity": "gravity method (two whole LEDs plus gravity from the accelerometer)"}
"""Methods whose name alone does not say what they use."""


def method_text(method: str) -> str:
    """A method's name for summaries and figures; the gravity method says what it uses."""
    return METHOD_TEXT.get(method, f"{method} method")


def error_per_m2(area: np.ndarray, per_m2: float = ERROR_POSES_PER_M2) -> float:
    """Pose density of the error map over ``area`` [m]: ``per_m2``, but at most :data:`ERROR_MAX_POSES` in all."""
    from planner.layout.model import area_m2

    return min(per_m2, ERROR_MAX_POSES / max(area_m2(area), 1e-6))


def site_accuracy(xyz: np.ndarray, radii: np.ndarray, outline, camera: Camera, method: str = "perspective",
                  per_m2: float = ERROR_POSES_PER_M2, seed: int = 0, terms: ErrorTerms = DEFAULT_TERMS,
                  sample: PoseSample | None = None,
                  accelerometer_sigma_rad: float = math.radians(ACCELEROMETER_SIGMA_DEG)) -> SiteAccuracy:
    """Error map of ``method`` with ``terms`` over a site: poses sampled as the verification samples them,
    ``per_m2`` of floor but at most :data:`ERROR_MAX_POSES` (the first of ``sample``, a plan's one
    draw with seed ``seed``, if given); with two or more terms, the other runs of :func:`budget_runs`
    (exact images, each term alone) on the first :data:`BUDGET_MAX_POSES` poses too. The ``gravity``
    method weighs its vertical by ``accelerometer_sigma_rad``; ``terms.gravity_rad`` is its actual error."""
    from planner.verify.windows import sample_poses, working_area

    area = working_area(xyz[:, :2], outline) if sample is None else sample.area
    per_m2 = error_per_m2(area, per_m2)
    cell = max(ERROR_CELL_M, math.ceil(2 * math.sqrt(ERROR_CELL_POSES / per_m2)) / 2)
    poses = sample_poses(area, camera, per_m2=per_m2, seed=seed) if sample is None else sample.first(per_m2)[0]
    errors = site_errors(xyz, radii, poses, camera, method, terms, seed, accelerometer_sigma_rad)
    budget = {}
    if len(terms.active) > 1:
        first = poses.subset(slice(0, BUDGET_MAX_POSES))
        for name, run in budget_runs(terms).items():
            budget[name] = _quantiles(errors[:len(first)] if name == "all" else
                                      site_errors(xyz, radii, first, camera, method, run, seed,
                                                  accelerometer_sigma_rad, terms))
    return SiteAccuracy(method, terms, poses.position, errors, cell, budget)


def _quantiles(errors: np.ndarray) -> tuple[int, float | None, float | None]:
    e = errors[np.isfinite(errors)]
    if not len(e):
        return 0, None, None
    return len(e), round(float(np.median(e)), 6), round(float(np.percentile(e, 90)), 6)


def site_errors(xyz: np.ndarray, radii: np.ndarray, poses: Poses, camera: Camera, method: str = "perspective",
                terms: ErrorTerms = PIXEL_ONLY, seed: int = 0,
                accelerometer_sigma_rad: float = math.radians(ACCELEROMETER_SIGMA_DEG),
                model: ErrorTerms | None = None) -> np.ndarray:
    """Error [m] of ``method`` at every pose with ``terms`` at work (NaN where the pose gives no position),
    identities known; the site is installed once (``terms.install_m``). The fits weigh their residuals by
    ``model`` (default ``terms``: the budget's model, never its draws).

    ``gravity`` is the two-LED receiver: every pose draws the accelerometer's vertical (error
    ``terms.gravity_rad``, the twin's model), two whole LEDs suffice, the two whose rays are nearest
    the optical axis start the fix (its window) and every LED seen refines it."""
    rngs = streams(seed)
    leds = installed(xyz, terms.install_m, rngs["install"])
    believed = camera.ideal()
    out = np.full(len(poses), np.nan)
    rotations = poses.rotation
    error = _PER_POSE.get(method, _window_error)(method, xyz, radii, believed, terms, model or terms, rngs,
                                                 accelerometer_sigma_rad)
    for k in range(len(poses)):
        seen = observe_with(poses.position[k], rotations[k], leds, radii, camera, terms, rngs)
        out[k] = error(seen, rotations[k], poses.position[k])
    return out


def _window_error(method: str, xyz: np.ndarray, radii: np.ndarray, believed: Camera, terms: ErrorTerms,
                  model: ErrorTerms, rngs: dict, accelerometer_sigma_rad: float):
    """Per-pose error [m] of ``method`` on three or more whole LEDs (NaN with fewer)."""
    fix = solver(method, model)

    def error(seen: Sighting, rotation: np.ndarray, position: np.ndarray) -> float:
        return _error(fix, seen, xyz, radii, believed, position) if len(seen.index) >= 3 else np.nan

    return error


def _gravity_error(method: str, xyz: np.ndarray, radii: np.ndarray, believed: Camera, terms: ErrorTerms,
                   model: ErrorTerms, rngs: dict, accelerometer_sigma_rad: float):
    """Per-pose error [m] of the gravity method: every pose draws the accelerometer's vertical; two whole LEDs, the
    two whose rays are nearest the optical axis first (its window), suffice (NaN with fewer)."""

    def error(seen: Sighting, rotation: np.ndarray, position: np.ndarray) -> float:
        g = accelerometer(rotation, terms.gravity_rad, rngs["accelerometer"])
        if len(seen.index) < 2:
            return np.nan
        order = window_order(np.array([e.centre for e in seen.ellipses]), believed)
        seen = Sighting(seen.index[order], [seen.ellipses[i] for i in order])
        return _error(lambda x, r, e, c: locate_gravity(x, r, e, c, g, accelerometer_sigma_rad, model),
                      seen, xyz, radii, believed, position)

    return error


_PER_POSE = {"gravity": _gravity_error}
"""Per-pose error models that are not a three-LED method of :data:`planner.positioning.locate.METHODS`."""
