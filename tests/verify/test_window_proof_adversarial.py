"""The proved window set against adversarial installations and poses (issue 34), and a window the install
tolerance really adds under the paper's rule, which the receiver's crossing rule refuses: the reason the set at
3 cm can be the set proved on the exact drawing.

Soundness here means: every window found by projecting *every* LED of the installed site (conftest's
``exact_nearest``) at a pose of the envelope is in the set proved on the drawing. The installations push
luminaires by the full tolerance perpendicular to lattice lines (alternating, in both directions); the
poses sit on the envelope's boundary (largest tilt, nearest and farthest ceiling) and at near ties (the
axis point on lattice-symmetric points, where two LEDs' angles from the axis are nearly equal).
"""
import math

import numpy as np
import pytest

from conftest import accepted, exact_nearest, grid_xy, hex_xy, jittered_xy
from planner.camera.model import Camera, Poses, project_discs
from planner.verify import proof as wp
from planner.verify.envelope import envelope
from planner.verify.windows import MIN_FLATNESS, crossed, flatness

D = 0.03
"""The default install tolerance [m]: every push below is by the full tolerance."""


def _proved(xy: np.ndarray, install_m: float) -> set:
    drawn = np.column_stack([xy, np.full(len(xy), 2.5)])
    radii = np.full(len(xy), 0.1)
    tri = wp.possible_windows(drawn, radii, envelope(Camera(), drawn, radii, install_m), budget=10**7, pair_budget=10**7)
    return {tuple(t) for t in tri.tolist()}


def _perpendicular_pushes(xy: np.ndarray) -> dict[str, np.ndarray]:
    """Displacements of exactly ``D``, perpendicular to a lattice line through each luminaire (the line to its
    nearest neighbour, or the rows and columns of a lattice), the sign alternating along the line."""
    step = np.sort(np.linalg.norm(xy[:, None] - xy[None], axis=2), axis=1)[:, 1].min()
    col, row = np.round((xy - xy.min(axis=0)) / step).astype(int).T
    nearest = np.argsort(np.linalg.norm(xy[:, None] - xy[None], axis=2), axis=1)[:, 1]
    along = xy[nearest] - xy
    normal = np.column_stack([-along[:, 1], along[:, 0]]) / np.linalg.norm(along, axis=1, keepdims=True)
    ones = np.ones(len(xy))
    return {"across rows, alternating by column": D * np.column_stack([0 * ones, (-1.0) ** col]),
            "across rows, opposite sign": -D * np.column_stack([0 * ones, (-1.0) ** col]),
            "across columns, alternating by row": D * np.column_stack([(-1.0) ** row, 0 * ones]),
            "across the nearest-neighbour line": D * normal * ((-1.0) ** (col + row))[:, None],
            "every other row pushed up": D * np.column_stack([0 * ones, row % 2])}


def _boundary_poses(xy: np.ndarray, count: int, seed: int) -> Poses:
    """Poses at the envelope's boundary: half at the largest tilt, heights at the limits for a third each,
    a quarter with the axis point (of a vertical camera) on a lattice-symmetric point: near ties."""
    cam, rng = Camera(), np.random.default_rng(seed)
    lo, hi = xy.min(axis=0) - 0.5, xy.max(axis=0) + 0.5
    pos = lo + rng.random((count, 2)) * (hi - lo)
    step = np.sort(np.linalg.norm(xy[:, None] - xy[None], axis=2), axis=1)[:, 1].min()
    ties = rng.random(count) < 0.25  # half-step points (lattice points, edge midpoints, cell centres), 1 mm off
    snapped = xy.min(axis=0) + np.round((pos - xy.min(axis=0)) / (0.5 * step)) * 0.5 * step
    pos = np.where(ties[:, None], snapped + rng.normal(0, 1e-3, pos.shape), pos)
    u = rng.random((count, 3))
    height = np.select([u[:, 0] < 1 / 3, u[:, 0] < 2 / 3], [cam.min_height_m, cam.max_height_m],
                       cam.min_height_m + rng.random(count) * (cam.max_height_m - cam.min_height_m))
    tilt = np.where(u[:, 1] < 0.5, cam.max_tilt_rad, np.sqrt(rng.random(count)) * cam.max_tilt_rad)
    tilt = np.where(ties & (u[:, 1] < 0.75), 0.0, tilt)
    return Poses(np.column_stack([pos, height]), tilt, u[:, 2] * 2 * math.pi, rng.random(count) * 2 * math.pi)


def _exact_windows(drawn_xy: np.ndarray, installed_xy: np.ndarray, poses: Poses) -> tuple[set, set]:
    """The windows the receiver takes at ``poses`` on the installed site, and those the paper's rule alone takes
    (three whole LEDs nearest the centre, not collinear)."""
    drawn = np.column_stack([drawn_xy, np.full(len(drawn_xy), 2.5)])
    xyz = np.column_stack([installed_xy, np.full(len(installed_xy), 2.5)])
    radii, found, paper = np.full(len(xyz), 0.1), set(), set()
    for part in range(0, len(poses), 5000):
        w = exact_nearest(xyz, radii, Camera(), poses.subset(slice(part, part + 5000)), 3)
        found |= {tuple(t) for t in accepted(w, drawn, xyz, radii).tolist()}
        paper |= {tuple(t) for t in w[flatness(drawn[w]) >= MIN_FLATNESS].tolist()}
    return found, paper


def _check(xy: np.ndarray, poses_per_push: int, seed: int) -> tuple[int, int]:
    """Windows found over every push, and the windows of the paper's rule outside the set proved for the exact
    drawing (the adversarial installations do find such windows: without the crossing rule a set that shrank to
    it would fail here; every one of them has an LED over a side, so the receiver refuses it)."""
    proved, exact, total, beyond_exact = _proved(xy, D), _proved(xy, 0.0), 0, 0
    for k, (name, push) in enumerate(_perpendicular_pushes(xy).items()):
        assert np.allclose(np.linalg.norm(push, axis=1)[np.linalg.norm(push, axis=1) > 0], D)
        windows, paper = _exact_windows(xy, xy + push, _boundary_poses(xy, poses_per_push, seed + k))
        assert not windows - proved, (name, sorted(windows - proved)[:3])
        total, beyond_exact = total + len(windows), beyond_exact + len(paper - exact)
    return total, beyond_exact


def test_a_window_the_install_tolerance_adds_has_an_led_over_a_side_and_is_refused():
    """On a 6 x 8 lattice at 0.5 m, luminaires 12, 19, 21 (drawn at (2, 0.5), (1.5, 1), (2.5, 1)) hold
    luminaire 20 on an edge, so the set proved for the exact drawing excludes them. Moved by 3 cm (the
    three pulled towards their centroid, the rest pushed away), the pose below takes them as the paper's window:
    luminaire 20 is nearer the image centre than the farthest of them but its disc is cut by the image's
    border. Its disc still overlaps the side from 19 to 21, so the receiver refuses that window (the crossing
    rule), and the set proved at 3 cm is the set proved for the exact drawing."""
    xy, cam = grid_xy(6, 8, 0.5, 0.5), Camera()
    tri, edge = np.array([12, 19, 21]), 20
    away = xy - xy[tri].mean(axis=0)
    away /= np.maximum(np.linalg.norm(away, axis=1, keepdims=True), 1e-12)
    push = D * away
    push[tri] *= -1
    installed = np.column_stack([xy + push, np.full(len(xy), 2.5)])
    radii = np.full(len(xy), 0.1)
    pose = Poses(np.array([[2.0996426678117257, 0.2082670416362642, 1.2513442615452681]]), np.array([0.2971029319005593]),
                 np.array([1.7819938645520905]), np.array([3.207904603330115]))
    assert exact_nearest(installed, radii, cam, pose, 3).tolist() == [tri.tolist()]
    img = project_discs(pose, installed[None], radii[None], cam)
    off = np.hypot(img["u"][0] - cam.cx_px, img["v"][0] - cam.cy_px)
    assert off[edge] < off[tri].max() and not img["inside"][0][edge]  # nearer, but not wholly seen
    assert flatness(installed[tri][None])[0] >= MIN_FLATNESS
    assert crossed(tri[None], installed, radii)[0]  # luminaire 20's disc over the side 19-21: refused
    assert crossed(tri[None], np.column_stack([xy, np.full(len(xy), 2.5)]), radii)[0]
    assert tuple(tri) not in _proved(xy, 0.0) and tuple(tri) not in _proved(xy, D)
    assert _proved(xy, D) == _proved(xy, 0.0)


def test_lattice_pushed_across_its_lines_and_posed_at_the_envelope_boundary():
    total, beyond_exact = _check(grid_xy(6, 8, 0.5, 0.5), 12_000, 1)
    assert total > 300 and beyond_exact >= 1


def test_hexagonal_site_pushed_across_its_lines_and_posed_at_the_envelope_boundary():
    total, beyond_exact = _check(hex_xy(6, 7, 0.6), 12_000, 1)
    assert total > 300 and beyond_exact >= 1


@pytest.mark.slow
@pytest.mark.parametrize("poses_per_push", [16_000, pytest.param(80_000, marks=pytest.mark.acceptance)])
@pytest.mark.parametrize("name,xy", [("lattice 10 x 12, 0.5 m", grid_xy(10, 12, 0.5, 0.5)),
                                     ("hexagonal 9 x 9, 0.7 m", hex_xy(9, 9, 0.7)),
                                     ("jittered 0.6 m, 12 cm", jittered_xy(3)[:160])])
def test_dense_adversarial_sample_finds_no_window_outside_the_proved_set(name, xy, poses_per_push):
    """Five pushes of 16,000 poses each in the suite (2,053, 2,141 and 3,219 windows, measured 2026-12-05), of
    80,000 under ``--acceptance``."""
    assert _check(xy, poses_per_push, 7)[0] > 1000, name
