"""Large test sites for the label search (issue 34), built in code: used by tests/codes and by
``benchmarks/label_bench.py``.

- :func:`hexagonal_site`: a triangular lattice 0.7 m apart on a 3 m ceiling, every luminaire moved
  up to 3 cm (uniformly in a disc, seeded), 1,088 luminaires by default (32 rows of 34);
  ``layouts/hex-1088.yaml`` holds the same site.
- :func:`jittered_site`: a 51 x 40 lattice 0.6 m apart, each luminaire moved up to 12 cm along each
  axis (as issue 13's site, without the holes): 2,040 luminaires, 2.5 m ceiling.
- :func:`square_lattice`: ``planner.studies.efficiency.lattice_layout`` (the benchmarks' lattices),
  32 x 32 = 1,024 luminaires 0.5 m apart by default.
"""

from __future__ import annotations

import numpy as np

from planner.layout.model import Layout, Luminaire

HEX_PITCH_M = 0.7
HEX_HEIGHT_M = 3.0
HEX_JITTER_M = 0.03


def _layout(xy: np.ndarray, height_m: float, name: str, radius_m: float = 0.1) -> Layout:
    xy = xy - xy.min(axis=0) + 0.5  # half a metre to the walls
    lums = tuple(Luminaire(f"L{k:05d}", round(float(x), 4), round(float(y), 4), height_m, radius_m)
                 for k, (x, y) in enumerate(xy))
    w, h = (round(v, 4) for v in (xy.max(axis=0) + 0.5).tolist())
    return Layout(lums, ((0.0, 0.0), (w, 0.0), (w, h), (0.0, h)), name)


def hexagonal_xy(rows: int = 32, cols: int = 34, pitch_m: float = HEX_PITCH_M, jitter_m: float = HEX_JITTER_M,
                 seed: int = 34) -> np.ndarray:
    """Plan positions [m] of a triangular lattice (rows ``pitch_m * sqrt(3) / 2`` apart, every other row
    shifted half a pitch), each moved by up to ``jitter_m`` in a uniformly drawn direction."""
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    xy = np.column_stack([(c + 0.5 * (r % 2)).ravel() * pitch_m, r.ravel() * pitch_m * np.sqrt(3) / 2])
    rng = np.random.default_rng(seed)
    angle = rng.uniform(0, 2 * np.pi, len(xy))
    reach = jitter_m * np.sqrt(rng.uniform(0, 1, len(xy)))  # uniform in the disc
    return xy + reach[:, None] * np.column_stack([np.cos(angle), np.sin(angle)])


def hexagonal_site(rows: int = 32, cols: int = 34, seed: int = 34) -> Layout:
    """The hexagonal site of issue 34: 0.7 m triangular lattice, 3 m ceiling, moved up to 3 cm."""
    return _layout(hexagonal_xy(rows, cols, seed=seed), HEX_HEIGHT_M, f"hex-{rows * cols}.yaml")


def jittered_xy(rows: int = 40, cols: int = 51, pitch_m: float = 0.6, jitter_m: float = 0.12,
                seed: int = 7) -> np.ndarray:
    """Plan positions [m] of a rows x cols lattice, each moved up to ``jitter_m`` along each axis."""
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    xy = pitch_m * np.column_stack([c.ravel(), r.ravel()]).astype(float)
    return xy + np.random.default_rng(seed).uniform(-jitter_m, jitter_m, xy.shape)


def jittered_site(rows: int = 40, cols: int = 51, seed: int = 7) -> Layout:
    """The jittered site of issue 34: 2,040 luminaires by default, 2.5 m ceiling."""
    return _layout(jittered_xy(rows, cols, seed=seed), 2.5, f"jittered-{rows * cols}.yaml")


def square_lattice(n: int = 1024) -> Layout:
    """The benchmarks' square lattice of ``n`` luminaires (0.5 m apart, 2.5 m ceiling)."""
    from planner.studies.efficiency import lattice_layout

    return lattice_layout(n)


def check_default_plan(layout: Layout, seed: int, samples: int = 5) -> None:
    """Issue 34's Done-when on one large site: the default plan (without its error map) is proved complete,
    reuses IDs within 2 bits of its proved window set's counting bound, and ``samples`` fresh pose samples (the
    Done-when's five) at ten times the default density (seeds the planner never uses), each window against every
    physical triple, find no ambiguous pose."""
    from planner.codes.assignment import bits_for
    from planner.plan.pipeline import PlanOptions, make_plan
    from planner.verify.verify import AMBIGUOUS, classify, observe_site
    from planner.verify.windows import POSES_PER_M2

    plan = make_plan(layout, PlanOptions(error_poses_per_m2=0))
    proved = plan.verification.window_set
    assert proved is not None and proved.proved and proved.complete, proved
    a = plan.assignment
    counted = a.detail["window_set"]
    assert counted["set"] == "proved" and counted["windows"] == proved.triangles
    assert a.bits < bits_for(len(layout.luminaires)) and a.bits <= counted["lower_bound_bits"] + 2, (a.bits, counted)
    xyz, radii = layout.xyz, np.array([lum.radius for lum in layout.luminaires])
    poses = 0
    for fresh in range(samples):
        obs = observe_site(xyz, radii, layout.outline, plan.camera, per_m2=10 * POSES_PER_M2, seed=seed + fresh)
        verdict = classify(obs, a.ids)
        assert verdict.count(AMBIGUOUS) == 0, (a.scheme, verdict.conflicts[:2])
        assert verdict.poses > 100_000
        poses += verdict.poses
    print(f"{layout.source_path}: {a.bits} bits (bound {counted['lower_bound_bits']}) over {proved.triangles:,} proved"
          f" windows; 0 of {poses:,} fresh poses ambiguous")
