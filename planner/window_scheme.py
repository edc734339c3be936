"""Schemes beyond the paper's: ``window`` (shortest IDs with every window unique) and ``unique``.

Every fix needs three LEDs, so it is enough that every *window* the camera can
produce on this layout is unique, not every neighbouring pair. Windows are
collected from a dense pose sample (:func:`planner.verify.design_windows`), IDs
are found by :mod:`planner.window_code`, and the result is verified on an
independent pose sample; windows that only the verification sample found are
added and the IDs repaired, up to ``REPAIR_ROUNDS`` times.
"""

from __future__ import annotations

import numpy as np

from . import window_code
from .assignment import Assignment, bits_for, tile_regions
from .camera import Camera
from .graph import NeighbourGraph
from .verify import Verification, design_windows, verify_plan
from .windows import CONGRUENCE_TOLERANCE_M, POSES_PER_M2, canonical_windows

REPAIR_ROUNDS = 3


def assign_unique(xy: np.ndarray, graph: NeighbourGraph) -> Assignment:
    """One ID per luminaire, 1..N in layout order: the naive scheme."""
    n = len(xy)
    ids = np.arange(1, n + 1, dtype=np.int64)
    bits = bits_for(n)
    return Assignment("unique", ids, tile_regions(xy, graph, n), bits, bits, bits, "one ID per luminaire", {})


def assign_window(xyz: np.ndarray, radii: np.ndarray, outline, graph: NeighbourGraph, camera: Camera, *,
                  seed: int = 0, time_budget: float = 10.0, per_m2: float = POSES_PER_M2,
                  tolerance_m: float = CONGRUENCE_TOLERANCE_M) -> tuple[Assignment, Verification]:
    """The window scheme, verified: IDs under which no two sampled windows share a key.

    Returns the assignment and its final verification (on poses of seed ``seed``).
    """
    n = len(xyz)
    design = design_windows(xyz, radii, outline, camera, per_m2=2 * per_m2, seed=seed + 1, tolerance_m=tolerance_m)
    code = window_code.assign_window_code(n, design.windows, design.shape, design.symmetric,
                                          seed=seed, time_budget=time_budget)
    labels, k = code.labels, code.K
    triples = design.windows
    ws = design
    method = code.method
    for _ in range(REPAIR_ROUNDS):
        check = verify_plan(xyz, radii, labels + 1, outline, camera, per_m2=per_m2, seed=seed, tolerance_m=tolerance_m)
        if not check.conflicts:
            break
        triples = np.vstack([triples, check.windows.windows])
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
        check = verify_plan(xyz, radii, labels + 1, outline, camera, per_m2=per_m2, seed=seed, tolerance_m=tolerance_m)
    ids = labels.astype(np.int64) + 1
    bits = bits_for(max(k, 2))
    detail = {"windows": len(ws), "labels": int(k), "optimal": bool(code.optimal and bits == code.bits),
              "lower_bound_labels": int(code.lower_bound_labels)}
    assignment = Assignment("window", ids, tile_regions(xyz[:, :2], graph, k), bits, bits_for(n),
                            int(code.lower_bound_bits), method, detail)
    return assignment, check
