"""Site advice: which change would bring a site's sampled coverage up to a goal.

A plan's coverage is the share of sampled poses that decode (``planner.verify``).
Below :data:`COVERAGE_GOAL`, the planner tries changes an integrator can make
(another receiver mode of :data:`RECEIVERS`, a wider camera profile, luminaires mounted
higher, denser luminaires), each alone and then two at a time, and measures each with
the same sampled measure: the share of a coarse pose sample (:func:`advice_per_m2`)
whose camera sees a window of its receiver mode: three whole, non-collinear LEDs (the
paper's rule, section 3), or two whole LEDs with gravity. The IDs are designed afterwards
to make those windows unique, so this is the coverage a plan of the changed site
can reach. Given the plan's frame limits, a change whose coverage reaches the goal is
also checked to still fit its frames (:mod:`planner.advice.frames`): one that needs faster
drivers says so, one that fits at no driver rate is not recommended. Every figure is
sampled, never proved. ``docs/advice.md``.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from planner.advice.changes import KNOBS, WINDOW_WORDS, Change, Site
from planner.advice.changes import RECEIVERS as RECEIVERS  # the coverage measure per mode, re-exported
from planner.advice.frames import FrameFit, FrameLimits, frame_fit, frame_text
from planner.camera.model import Poses
from planner.defaults import COVERAGE_GOAL, USABLE_COVERAGE
from planner.layout.model import area_m2
from planner.modulation.timing import timing_per_m2
from planner.receivers.modes import PAPER
from planner.receivers.modes import RECEIVERS as MODES
from planner.verify.windows import pose_count, sample_poses, working_area

ADVICE_POSES_PER_M2 = 10.0
"""Pose density of the advice's coarse sample [1/m^2] (the plan verifies at 400)."""

ADVICE_MIN_POSES = 4000
"""The coarse sample holds at least this many poses on small sites (sampling error about 0.5 point)."""

ADVICE_MAX_POSES = 20000
"""... and at most this many on large ones, so that the advice stays cheap beside the plan."""

MARGIN = 0.01
"""A change counts as reaching the goal when its sampled coverage is at least goal + MARGIN (sampling error)."""


@dataclass(frozen=True)
class Row:
    """A tried change (one or two :class:`Change`), its sampled coverage, whether that is at least the goal
    (``covers``) and, when it is and the plan's limits are known, how its frames fit."""

    changes: tuple[Change, ...]
    coverage: float
    covers: bool
    frame: FrameFit | None = None

    @property
    def reaches(self) -> bool:
        """Covers the goal, and its frames fit the plan's drivers (or were not checked)."""
        return self.covers and (self.frame is None or self.frame.fits)

    @property
    def needs_driver(self) -> bool:
        """Covers the goal, but only with faster drivers."""
        return self.covers and self.frame is not None and self.frame.needs_driver_hz is not None

    def rank(self) -> int:
        """0 reaches the goal, 1 reaches it with faster drivers, 2 does not."""
        return 0 if self.reaches else 1 if self.needs_driver else 2

    def summary(self) -> dict:
        driver = self.frame.needs_driver_hz if self.needs_driver and self.frame else None
        return {"change": "; ".join(c.text for c in self.changes),
                "flags": [f for c in self.changes for f in c.flags] + (["--driver-max-hz", f"{driver:.0f}"]
                                                                       if driver else []),
                "applicable_by_flags": all(c.flags for c in self.changes),
                "camera": next((c.camera for c in self.changes if c.camera), None),
                "coverage": round(self.coverage, 4), "reaches_goal": self.reaches,
                "covers_goal": self.covers, **({"frame": self.frame.summary()} if self.frame else {})}


@dataclass(frozen=True)
class Advice:
    """The advice for one plan: its coverage, the goal, the changes tried and which reach the goal."""

    coverage: float  # the plan's verified (sampled) coverage
    too_few: float  # share of the plan's sampled poses that see too few whole LEDs for the plan's receiver
    ambiguous: float  # share of the plan's sampled poses whose window reads like another triple
    goal: float
    baseline: float  # the site as planned, under the advice's measure
    rows: tuple[Row, ...]
    poses: int
    per_m2: float
    receiver: str = "three"
    frames: FrameLimits | None = None  # the plan's frame limits the changes were checked against
    allow_unusable: bool = False  # the plan was made with --allow-unusable (vlp-verify exits 0 on it too)
    tone_site: bool = False  # an existing tone site (docs/tones.md): its IDs are kept, not chosen by a scheme

    @property
    def usable(self) -> bool:
        return self.coverage >= USABLE_COVERAGE

    @property
    def recommended(self) -> Row | None:
        """The first row that reaches the goal, else the first that reaches it with faster drivers (rows are in
        that order, then of least change)."""
        return next((r for r in self.rows if r.rank() < 2), None)

    def summary(self) -> dict:
        """The ``advice`` mapping of ``plan.yaml`` and of ``vlp-plan --json``."""
        rec = self.recommended
        return {"goal": self.goal, "usable_from": USABLE_COVERAGE, "usable": self.usable,
                "coverage": round(self.coverage, 6), "too_few_leds": round(self.too_few, 4),
                "ambiguous": round(self.ambiguous, 4), "meets_goal": self.coverage >= self.goal,
                "method": "sampled", "receiver": self.receiver,
                "measure": f"share of sampled poses whose camera sees {WINDOW_WORDS[self.receiver]}",
                "poses_per_candidate": self.poses, "poses_per_m2": round(self.per_m2, 4),
                "baseline": round(self.baseline, 4), "changes": [r.summary() for r in self.rows],
                "recommended": None if rec is None else self.rows.index(rec),
                "driver_max_hz": None if self.frames is None else self.frames.driver_max_hz,
                "allow_unusable": self.allow_unusable, **({"tone_site": True} if self.tone_site else {})}


def advice_per_m2(area: np.ndarray) -> float:
    """Pose density of the coarse sample over ``area``: :data:`ADVICE_POSES_PER_M2`, more on small sites and
    less on large ones (between :data:`ADVICE_MIN_POSES` and :data:`ADVICE_MAX_POSES` poses)."""
    m2 = max(area_m2(area), 1e-6)
    return float(np.clip(ADVICE_POSES_PER_M2 * m2, ADVICE_MIN_POSES, ADVICE_MAX_POSES)) / m2


class _SharedWindows:
    """The advice's pose samples, drawn once: every candidate site samples the same floor with the same seed and
    the same receiver heights and tilt, so they share one Sobol draw; the coverage sample (``per_m2``) and the
    timing sample of the frame check (:func:`planner.modulation.timing.timing_per_m2`) are prefixes of it, and a
    candidate's windows are found once, on the longer prefix it needs (windows are found pose by pose, so a
    prefix's windows are the windows of the prefix: the figures are those of separate draws)."""

    def __init__(self, area: np.ndarray, per_m2: float, seed: int):
        self.area, self.seed = area, seed
        self.n_coverage, self.n_timing = pose_count(area, per_m2), pose_count(area, timing_per_m2(area))
        self.per_m2 = max(per_m2, timing_per_m2(area))
        self.poses: dict[tuple[float, ...], Poses] = {}
        self.found: dict[tuple[str, ...], tuple[np.ndarray, np.ndarray]] = {}

    def _windows(self, s: Site, changes: tuple[Change, ...], n: int) -> tuple[Poses, np.ndarray, np.ndarray]:
        cam = s.camera
        held = (cam.min_height_m, cam.max_height_m, cam.max_tilt_rad)
        if held not in self.poses:
            self.poses[held] = sample_poses(self.area, cam, self.per_m2, self.seed)
        poses = self.poses[held]
        key = tuple(c.text for c in changes)
        leds, covered = self.found.get(key, (np.empty((0, MODES[s.receiver].leds), dtype=np.int64),
                                             np.zeros(0, dtype=bool)))
        if len(covered) < n:
            more = MODES[s.receiver].window_leds(poses.subset(slice(len(covered), n)), s.xyz, s.radii, cam)
            leds, covered = np.concatenate([leds, more[0]]), np.concatenate([covered, more[1]])
            self.found[key] = leds, covered
        return poses.subset(slice(0, n)), leds[:n], covered[:n]

    def coverage(self, s: Site, changes: tuple[Change, ...]) -> float:
        """Share of the coverage sample's poses that see a window of ``s``'s receiver."""
        return float(self._windows(s, changes, self.n_coverage)[2].mean())

    def timing(self, s: Site, changes: tuple[Change, ...]) -> tuple[Poses, np.ndarray, np.ndarray]:
        """The timing sample's poses, window LEDs and coverage (:func:`planner.advice.frames.smallest_image_rows`)."""
        return self._windows(s, changes, self.n_timing)


def advise(site: Site, coverage: float, too_few: float = 0.0, ambiguous: float = 0.0, *, goal: float = COVERAGE_GOAL,
           seed: int = 0, frames: FrameLimits | None = None, allow_unusable: bool = False) -> Advice:
    """Try the candidate changes on ``site`` (planned at ``coverage``, ``too_few`` of its poses
    seeing fewer than three LEDs and ``ambiguous`` of them reading alike) until some reach ``goal``.

    For each knob the least change that reaches the goal, else the least that reaches it with
    faster drivers, else its best; if no single change reaches it, the least pair of changes (two
    knobs) that does, else the least pair that does with faster drivers, else the best pair. With
    ``frames`` (the plan's limits) a change reaches the goal only if its frames fit them too.
    """
    area = working_area(site.xyz[:, :2], site.outline)
    per_m2 = advice_per_m2(area)
    windows = _SharedWindows(area, per_m2, seed)

    def applied(changes: tuple[Change, ...]) -> Site:
        s = site
        for c in changes:
            s = c.apply(s)
        return s

    def row(changes: tuple[Change, ...]) -> Row:
        s = applied(changes)
        cov = windows.coverage(s, changes)
        covers = cov >= goal + MARGIN
        return Row(changes, cov, covers, frame_fit(s, frames, seed, windows.timing(s, changes)) if covers and frames
                   else None)

    def kept(tried: list[Row]) -> Row:  # the one that reaches, else the least fixed by drivers, else the best
        return min(enumerate(tried), key=lambda kr: (kr[1].rank(), -kr[1].coverage if kr[1].rank() == 2
                                                     else kr[0]))[1]

    baseline = windows.coverage(site, ())
    knobs = [c for c in (knob(site) for knob in KNOBS) if c]
    rows: list[Row] = []
    if coverage < goal:
        for changes in knobs:
            tried = []
            for c in changes:
                tried.append(row((c,)))
                if tried[-1].reaches:
                    break
            rows.append(kept(tried))
        if not any(r.reaches for r in rows):
            tried = []
            for a, b in itertools.combinations(knobs, 2):
                pairs = sorted(itertools.product(range(len(a)), range(len(b))), key=lambda ij: (sum(ij), ij))
                here = []
                for i, j in pairs:
                    here.append(row((a[i], b[j])))
                    if here[-1].reaches:
                        break
                if kept(here).rank() < 2:  # reaches, or would with faster drivers
                    rows.append(kept(here))
                tried += here
            if tried and not any(r.rank() < 2 for r in rows):
                rows.append(kept(tried))
    rows.sort(key=lambda r: (r.rank(), len(r.changes), -r.coverage if r.rank() == 2 else 0))
    n_poses = max(1, int(round(per_m2 * area_m2(area))))
    return Advice(coverage, too_few, ambiguous, goal, baseline, tuple(rows), n_poses, per_m2, site.receiver, frames,
                  allow_unusable)


def standing(coverage: float, too_few: float, ambiguous: float, goal: float, receiver: str) -> dict:
    """The keys :func:`verdict` reads, for a coverage measured anew (``vlp-verify``): shares of sampled poses."""
    return {"goal": goal, "usable_from": USABLE_COVERAGE, "usable": coverage >= USABLE_COVERAGE, "coverage": coverage,
            "too_few_leds": too_few, "ambiguous": ambiguous, "meets_goal": coverage >= goal, "receiver": receiver}


def verdict(advice: dict) -> str:
    """One line on whether a plan is usable and meets the goal, from the ``advice`` mapping."""
    cov, goal = 100 * advice["coverage"], 100 * advice["goal"]
    if not advice["usable"]:
        few, alike = 100 * advice.get("too_few_leds", 0.0), 100 * advice.get("ambiguous", 0.0)
        seen = MODES.get(str(advice.get("receiver")), PAPER).leds_text
        why = (f"{few:.0f} % see fewer than {seen} whole LEDs: the luminaires are too sparse for this camera"
               if few >= 50 else f"{alike:.0f} % are ambiguous: " + ("repeated tones read alike, retune some (docs/tones.md)"
                                                                       if advice.get("tone_site") else
                                                                       "under this scheme (--scheme auto avoids that)")
               if alike >= few else "poses fail near the walls or see collinear LEDs")
        return (f"NOT USABLE: only {cov:.1f} % of sampled poses decode (a usable plan needs "
                f"{100 * advice['usable_from']:.0f} %); {why}; see the advice table")
    if not advice["meets_goal"]:
        return f"usable, below the goal: {cov:.1f} % of sampled poses decode, the goal is {goal:.0f} %"
    return f"meets the goal: {cov:.1f} % of sampled poses decode (goal {goal:.0f} %)"


def table(advice: dict) -> list[tuple[str, str, str]]:
    """The advice table as (change, sampled coverage, remark) rows, the site as planned first."""
    rows = [("as planned (this site, this camera)", f"{100 * advice['baseline']:.1f} %", "")]
    for k, c in enumerate(advice["changes"]):
        remark = ("recommended: " if k == advice["recommended"] else "") + (
            "reaches the goal" if c["reaches_goal"] else
            f"reaches the goal's coverage, but {frame_text(c['frame'], advice.get('driver_max_hz'))}"
            if c.get("covers_goal") and c.get("frame") else
            f"within {100 * MARGIN:g} point of the goal (sampling error)" if c["coverage"] >= advice["goal"] else
            "below the goal")
        frame = c.get("frame")
        if c["flags"] and not (frame and not frame["fits"] and frame["needs_driver_hz"] is None):  # no flags fix it
            remark += "; vlp-plan " + " ".join(c["flags"])
        if not c["applicable_by_flags"]:
            remark += "; change the layout"
        rows.append((c["change"], f"{100 * c['coverage']:.1f} %", remark))
    return rows
