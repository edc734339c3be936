"""Schemes beyond the paper's: ``window`` (shortest IDs with every window unique) and ``unique``.

Every fix needs three LEDs, so it is enough that every *window* the camera can
produce on this layout is unique, not every neighbouring pair. Windows are
collected from a dense pose sample (:func:`planner.verify.design_windows`, at
least ``DESIGN_PER_M2``), IDs are found by :mod:`planner.window_code`, and the
result is checked on ``CHECK_SEEDS`` independent pose samples at the
verification density; windows that only those samples found are added and the
IDs repaired, up to ``REPAIR_ROUNDS`` passes. The last check sample (seed
``seed``) is the verification reported in the plan.
"""

from __future__ import annotations

import numpy as np

from . import window_code
from .assignment import Assignment, bits_for, tile_regions
from .camera import Camera
from .graph import NeighbourGraph
from .verify import Verification, classify, design_windows, observe
from .windows import CONGRUENCE_TOLERANCE_M, POSES_PER_M2, canonical_windows, working_area


def _polygon_area(p: np.ndarray) -> float:
    x, y = p[:, 0], p[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1))))

REPAIR_ROUNDS = 3
"""Passes over the check samples; each pass adds the windows they found and repairs the IDs."""

CHECK_SEEDS = 2
"""Independent pose samples the IDs are checked and repaired against (the last is the one reported)."""

DESIGN_PER_M2 = 2000.0
"""Least density of the design sample [1/m^2]: rare windows must be in it to be made unique."""

DESIGN_MAX_POSES = 2_000_000
"""Cap on the design sample, for very large sites."""


def assign_unique(xy: np.ndarray, graph: NeighbourGraph) -> Assignment:
    """One ID per luminaire, 1..N in layout order: the naive scheme."""
    n = len(xy)
    ids = np.arange(1, n + 1, dtype=np.int64)
    bits = bits_for(n)
    return Assignment("unique", ids, tile_regions(xy, graph, n), bits, bits, bits, "one ID per luminaire", {})


def assign_window(xyz: np.ndarray, radii: np.ndarray, outline, graph: NeighbourGraph, camera: Camera, *,
                  seed: int = 0, time_budget: float = 10.0, per_m2: float = POSES_PER_M2,
                  tolerance_m: float = CONGRUENCE_TOLERANCE_M,
                  observations: dict | None = None) -> tuple[Assignment, Verification]:
    """The window scheme, verified: IDs under which no two sampled windows share a key.

    Returns the assignment and its final verification (on poses of seed ``seed``).
    ``observations`` (seed -> :class:`Observation` at ``per_m2``) is filled and reused,
    so a caller verifying other schemes on the same samples observes each once.
    """
    seen = {} if observations is None else observations

    def checked(s: int, labels: np.ndarray) -> Verification:
        if s not in seen:
            seen[s] = observe(xyz, radii, outline, camera, per_m2=per_m2, seed=s, tolerance_m=tolerance_m)
        return classify(seen[s], labels + 1)

    n = len(xyz)
    area = working_area(xyz[:, :2], outline)
    area_m2 = max(_polygon_area(area), 1e-6)
    design_density = min(max(5 * per_m2, DESIGN_PER_M2), max(DESIGN_MAX_POSES / area_m2, 2 * per_m2))
    design = design_windows(xyz, radii, outline, camera, per_m2=design_density, seed=seed + 1,
                            tolerance_m=tolerance_m)
    code = window_code.assign_window_code(n, design.windows, design.shape, design.symmetric,
                                          seed=seed, time_budget=time_budget)
    labels, k = code.labels, code.K
    triples, ws = design.windows, design
    method = code.method
    check_seeds = [seed + 1000 * (r + 1) for r in range(CHECK_SEEDS - 1)] + [seed]
    check = None
    for _ in range(REPAIR_ROUNDS):
        found = []
        for s in check_seeds:
            check = checked(s, labels)
            if check.conflicts:
                found.append(check.windows.windows)
        if not found:
            break
        triples = np.vstack([triples, *found])
        ws = canonical_windows(triples, xyz, tolerance_m)
        repaired = window_code.repair_labels(labels, n, ws.windows, ws.shape, ws.symmetric, k, seed=seed,
                                             max_steps=200_000)
        if repaired is None:
            code = window_code.assign_window_code(n, ws.windows, ws.shape, ws.symmetric, seed=seed,
                                                  time_budget=time_budget)
            repaired, k = code.labels, code.K
        labels = repaired
        method = f"{code.method}, repaired after verification"
    else:
        check = checked(seed, labels)
    ids = labels.astype(np.int64) + 1
    bits = bits_for(max(k, 2))
    detail = {"windows": len(ws), "labels": int(k), "optimal": bool(code.optimal and bits == code.bits),
              "lower_bound_labels": int(code.lower_bound_labels)}
    assignment = Assignment("window", ids, tile_regions(xyz[:, :2], graph, k), bits, bits_for(n),
                            int(code.lower_bound_bits), method, detail)
    return assignment, check
