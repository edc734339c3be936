"""The fits weigh each measured ellipse number by its standard deviation under the error budget (issue 37,
Build 4): the default (perspective) method is no worse than the paper's under the full budget, keeps its
sub-millimetre advantage with pixel noise alone, and an unreliable ellipse pulls it less."""

import dataclasses
import math

import numpy as np
import pytest

from planner.camera.model import Camera
from planner.positioning.accuracy import (
    PAPER_LEDS_M,
    _trial_pose,
    paper_experiment,
    paper_test_points,
    site_errors,
    stats_cm,
)
from planner.positioning.error_terms import DEFAULT_TERMS, PIXEL_ONLY, installed, observe_with, streams
from planner.positioning.fix import Fix, anchor_triple, ellipse_residuals, observed, rms
from planner.positioning.perspective import initial_poses, refine
from planner.positioning.uncertainty import residual_sigmas
from planner.verify.windows import sample_poses, working_area

CAM = Camera()
RADII = np.full(len(PAPER_LEDS_M), 0.1)


@pytest.fixture(scope="module")
def full_budget():
    """The paper's rig, every term at its default, 16 points x 3 trials at 0, 20 and 40 deg (seed 0)."""
    return {r.tilt_deg: r for r in paper_experiment((0, 20, 40), 3, DEFAULT_TERMS)}


def test_the_default_method_is_no_worse_than_the_papers_under_the_full_budget(full_budget):
    # measured 2026-12-04, mean / 90 % [cm]: level paper 3.25 / 5.13, perspective 1.43 / 2.38; 20 deg 14.68 / 22.33
    # against 2.57 / 3.85; 40 deg 14.03 / 24.34 against 3.52 / 5.48 (every residual weighed alike, as before this
    # fit: perspective 23.4 / 40.8 level, 11.1 / 16.7 at 40 deg)
    for tilt, r in full_budget.items():
        paper, persp = stats_cm(r.errors["paper"])[0], stats_cm(r.errors["perspective"])[0]
        assert np.isfinite(r.errors["perspective"]).sum() == np.isfinite(r.errors["paper"]).sum() >= 40
        assert persp <= 0.7 * paper, (tilt, persp, paper)
        assert stats_cm(r.errors["perspective"])[1] <= stats_cm(r.errors["paper"])[1], tilt  # the 90 % too


def test_with_pixel_noise_alone_the_default_method_stays_sub_millimetre():
    """The receiver weighs for the full budget (as vlp-accuracy's ``pixel only`` column), the world has pixel noise
    only: measured 2026-12-04, perspective 0.04 / 0.05 cm mean at 0 / 40 deg, the paper's 0.74 / 13.1 cm."""
    for r in paper_experiment((0, 40), 2, PIXEL_ONLY, model=DEFAULT_TERMS):
        persp, paper = stats_cm(r.errors["perspective"])[0], stats_cm(r.errors["paper"])[0]
        assert persp < 0.1 and persp < 0.1 * paper, (r.tilt_deg, persp, paper)


@pytest.mark.parametrize("tilt", [0, 40])
def test_each_residuals_modelled_sigma_matches_its_spread_at_the_true_pose(tilt):
    """The model (planner/positioning/uncertainty.py) against the residuals the budget's images leave at the true
    pose, RMS per residual kind over 32 trials. Measured 2026-12-04, level: centre 26.7 / 25.9 px (model 28.1), shape
    entries 1.18 / 2.15 / 4.05 px (model 1.21 / 2.65 / 5.40); 40 deg: 18.2 / 18.0 (20.5), 1.25 / 1.06 / 2.19
    (0.96 / 1.75 / 3.47)."""
    rngs = streams(0)
    seen_res, model = [], []
    for aim, az in zip(*paper_test_points()):
        for _ in range(2):
            position, rotation = _trial_pose(aim, az, tilt, rngs["pose"])
            leds = installed(PAPER_LEDS_M, DEFAULT_TERMS.install_m, rngs["install"])
            seen = observe_with(position, rotation, leds, RADII, CAM, DEFAULT_TERMS, rngs)
            centres, shapes = observed(seen.ellipses)
            seen_res.append(ellipse_residuals(position, rotation, PAPER_LEDS_M[seen.index], RADII[seen.index],
                                              centres, shapes, CAM).reshape(-1, 5))
            model.append(residual_sigmas(centres, shapes, RADII[seen.index], CAM, DEFAULT_TERMS).reshape(-1, 5))
    ratio = np.sqrt((np.vstack(model) ** 2).mean(axis=0) / (np.vstack(seen_res) ** 2).mean(axis=0))
    assert np.all((ratio > 0.5) & (ratio < 2.0)), ratio
    assert ratio[:2].min() > 0.9  # centres: not under-stated (install and skew), so they cannot outvote the shapes


def _weighted(xyz, radii, ellipses, camera, robust):
    centres, shapes = observed(ellipses)
    starts = initial_poses(xyz, radii, ellipses, anchor_triple(centres), camera)
    position, rotation = min(starts, key=lambda s: rms(ellipse_residuals(*s, xyz, radii, centres, shapes, camera)))
    position, rotation, _ = refine(position, rotation, xyz, radii, centres, shapes, camera)
    sigmas = residual_sigmas(centres, shapes, radii, camera, DEFAULT_TERMS)
    return Fix(*refine(position, rotation, xyz, radii, centres, shapes, camera, sigmas, robust=robust), "test")


def test_an_ellipse_read_too_long_pulls_the_robust_fit_less():
    """The LED nearest the image centre read 20 % too long (a small blob cut short by its stripes), every term on,
    40 deg: measured 2026-12-04 (3 trials) mean 6.0 cm robust, 16.9 cm on squares, 229 cm for the paper's method."""
    errors = {True: [], False: []}
    rngs = streams(0)
    for aim, az in zip(*paper_test_points()):
        for _ in range(2):
            position, rotation = _trial_pose(aim, az, 40, rngs["pose"])
            leds = installed(PAPER_LEDS_M, DEFAULT_TERMS.install_m, rngs["install"])
            seen = observe_with(position, rotation, leds, RADII, CAM, DEFAULT_TERMS, rngs)
            ellipses = [dataclasses.replace(seen.ellipses[0], major=1.2 * seen.ellipses[0].major), *seen.ellipses[1:]]
            for robust in errors:
                fix = _weighted(PAPER_LEDS_M[seen.index], RADII[seen.index], ellipses, CAM, robust)
                errors[robust].append(np.linalg.norm(fix.position - position))
    assert np.mean(errors[True]) < 0.6 * np.mean(errors[False])


def test_the_gravity_fit_weighs_its_ellipses_too():
    """4 x 3 luminaires 1.2 m apart, 80 deg lens, every term on and a 1 deg accelerometer: measured 2026-12-04,
    gravity method median 1.6 cm, 90 % 2.9 cm over 66 located poses (every ellipse residual weighed alike: 4.9 /
    9.2 cm)."""
    xyz = np.array([[x, y, 2.8] for x in (0.0, 1.2, 2.4, 3.6) for y in (0.0, 1.2, 2.4)])
    cam = Camera.from_fov(math.radians(80))
    poses = sample_poses(working_area(xyz[:, :2], None), cam, per_m2=8.0, seed=0)
    terms = dataclasses.replace(DEFAULT_TERMS, gravity_rad=math.radians(1.0))
    e = site_errors(xyz, np.full(len(xyz), 0.1), poses, cam, "gravity", terms)
    assert np.isfinite(e).sum() > 60 and np.nanmedian(e) < 0.03
