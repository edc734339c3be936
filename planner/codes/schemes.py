"""Schemes beyond the paper's: ``window`` (shortest IDs with every window unique) and ``unique``.

Every fix needs three LEDs, so it is enough that every *window* the camera can
produce on this layout is unique, not every neighbouring pair. Where the window set is
proved (:mod:`planner.verify.proof`), the labels are designed against it
(:mod:`planner.codes.proved`). Elsewhere windows are
collected from a dense pose sample (:func:`planner.verify.verify.design_windows`, at
least ``DESIGN_PER_M2``) and joined by every triangle of the window set
(:mod:`planner.verify.window_set`); IDs are found by :mod:`planner.codes.window`, with every
other triple of the site that could read like a window (:mod:`planner.verify.rivals`) as a
passive triple, which no window may read like. The result
is checked on ``CHECK_SEEDS`` independent pose samples at the verification
density; windows that only those samples found are added and the IDs repaired,
up to ``WIDEN_AFTER`` passes per width, then one bit more, width after width, before one
ID per luminaire. The last check sample (seed ``seed``) is the verification reported in the plan.
"""

from __future__ import annotations

import numpy as np

from planner.camera.model import Camera
from planner.codes import proved
from planner.codes import window as window_code
from planner.codes.alike import rows_in
from planner.codes.assignment import Assignment, bits_for, tile_regions
from planner.defaults import INSTALL_TOLERANCE_M
from planner.graph import NeighbourGraph
from planner.layout.model import area_m2
from planner.verify.proof import Proof
from planner.verify.rivals import counter_clockwise, find_rivals, longest_side, sides, site_triples
from planner.verify.tiles import tiled_shape_matches
from planner.verify.verify import Verification, classify, design_windows, observe_site
from planner.verify.window_set import window_superset
from planner.verify.windows import CONGRUENCE_TOLERANCE_M, POSES_PER_M2, working_area

CHECK_SEEDS = 2
"""Independent pose samples the IDs are checked and repaired against (the last is the one reported)."""

DESIGN_PER_M2 = 2000.0
"""Least density of the design sample [1/m^2]: rare windows must be in it to be made unique."""

WIDEN_AFTER = 3
"""Repair passes at one width after which the labels get one bit more, if rivals remain (up to one ID per luminaire)."""

MAX_READINGS = 200_000
"""Above this many keyed readings of the site's short triples, rivals join the ID search as they are found."""

DESIGN_MAX_POSES = 2_000_000
"""Cap on the design sample, for very large sites."""

def _keyed(windows: np.ndarray, xyz: np.ndarray, tolerance_m: float,
           others: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The windows (active) and every triple of the site that could read like one (passive).

    A triple's shape is its cell: each side, counter-clockwise from the canonical vertex,
    in steps of ``tolerance_m``. A window is keyed in its own cell; every triple short
    enough (windows included) also sits, passively, in each window-holding cell within one
    step per side, in each rotation, so that a window and anything whose sides are within
    the tolerance of its own share a cell. ``others`` limits the passive triples to those
    (and the windows). Returns (triples, shape, symmetric, active).
    """
    windows = np.unique(np.sort(np.asarray(windows, dtype=np.int64).reshape(-1, 3), axis=1), axis=0)
    if len(windows) == 0:
        return windows, np.zeros(0, np.int64), np.zeros(0, bool), np.zeros(0, bool)
    longest = longest_side(windows, xyz)
    if others is None:
        others = site_triples(xyz[:, :2], longest + tolerance_m + 1e-9)
    site = counter_clockwise(np.unique(np.sort(np.vstack([windows, others]), axis=1), axis=0), xyz[:, :2])
    win = counter_clockwise(windows, xyz[:, :2])
    base = int(np.ceil((longest + 2 * tolerance_m) / tolerance_m)) + 2

    def code(c):
        return (c[..., 0] * base + c[..., 1]) * base + c[..., 2]

    def canonical(c):
        return code(c) <= np.minimum(code(np.roll(c, -1, axis=-1)), code(np.roll(c, -2, axis=-1)))

    # windows: their own cell, in the rotation that makes it canonical
    cells = np.floor(sides(win, xyz) / tolerance_m).astype(np.int64)
    rot = np.argmin(np.stack([code(np.roll(cells, -r, axis=1)) for r in range(3)], axis=1), axis=1)
    idx = (np.arange(3)[None, :] + rot[:, None]) % 3
    act_t = np.take_along_axis(win, idx, axis=1)
    act_c = code(np.take_along_axis(cells, idx, axis=1))
    held = np.unique(act_c)
    # every short triple, every rotation, every neighbouring cell that holds a window
    s_cells = np.floor(sides(site, xyz) / tolerance_m).astype(np.int64)
    offsets = np.array(np.meshgrid([-1, 0, 1], [-1, 0, 1], [-1, 0, 1], indexing="ij")).reshape(3, -1).T
    pas_t_parts: list[np.ndarray] = []
    pas_c_parts: list[np.ndarray] = []
    for r in range(3):
        t_r, c_r = np.roll(site, -r, axis=1), np.roll(s_cells, -r, axis=1)
        for o in offsets:
            c = c_r + o
            ok = canonical(c) & np.isin(code(c), held) & (c >= 0).all(axis=1)
            pas_t_parts.append(t_r[ok])
            pas_c_parts.append(code(c[ok]))
    pas_t, pas_c = np.concatenate(pas_t_parts), np.concatenate(pas_c_parts)
    def sym_cell(c):
        return (c // (base * base) == (c // base) % base) & ((c // base) % base == c % base)
    # one copy per cell and reading (any rotation reads alike in a 3-fold symmetric cell);
    # never a window's own triple in its own cell
    reading = np.where(sym_cell(pas_c)[:, None], np.sort(pas_t, axis=1), pas_t)
    _, first = np.unique(np.column_stack([pas_c, reading]), axis=0, return_index=True)
    pas_t, pas_c = pas_t[first], pas_c[first]
    own = {(int(c), *sorted(t)) for c, t in zip(act_c.tolist(), act_t.tolist())}
    keep = np.array([(int(c), *sorted(t)) not in own for c, t in zip(pas_c.tolist(), pas_t.tolist())], dtype=bool)
    pas_t, pas_c = pas_t[keep], pas_c[keep]
    shape = np.searchsorted(held, np.concatenate([act_c, pas_c]))
    active = np.r_[np.ones(len(act_c), bool), np.zeros(len(pas_c), bool)]
    return np.vstack([act_t, pas_t]), shape.astype(np.int64), sym_cell(held), active


def _protected(sampled: np.ndarray, xyz: np.ndarray, radii: np.ndarray, tolerance_m: float,
               install_tolerance_m: float) -> tuple[np.ndarray, float]:
    """The windows to protect first: the sampled ones and every triangle the empty-triangle rule
    allows up to the longest sampled side plus the tolerance; returns them and that bound [m]."""
    if len(sampled) == 0:
        return sampled, 0.0
    bound = longest_side(sampled, xyz) + tolerance_m
    extra = window_superset(xyz, radii, bound, install_tolerance_m)
    return np.unique(np.sort(np.vstack([sampled, extra]), axis=1), axis=0), bound


def design_per_m2(per_m2: float, floor_m2: float) -> float:
    """Density of the sampled design (no complete proof) [1/m^2]: five times the verification's, at least
    :data:`DESIGN_PER_M2`, at most :data:`DESIGN_MAX_POSES` in all but never under twice the verification's."""
    return min(max(5 * per_m2, DESIGN_PER_M2), max(DESIGN_MAX_POSES / max(floor_m2, 1e-6), 2 * per_m2))


def assign_unique(xy: np.ndarray, graph: NeighbourGraph) -> Assignment:
    """One ID per luminaire, 1..N in layout order: the naive scheme."""
    n = len(xy)
    ids = np.arange(1, n + 1, dtype=np.int64)
    bits = bits_for(n)
    return Assignment("unique", ids, tile_regions(xy, graph, n), bits, bits, bits, "one ID per luminaire", {})


def assign_window(xyz: np.ndarray, radii: np.ndarray, outline, graph: NeighbourGraph, camera: Camera, *,
                  seed: int = 0, time_budget: float = 10.0, per_m2: float = POSES_PER_M2,
                  tolerance_m: float = CONGRUENCE_TOLERANCE_M, install_tolerance_m: float = INSTALL_TOLERANCE_M,
                  observations: dict | None = None, proof: Proof | None = None) -> tuple[Assignment, Verification]:
    """The window scheme, verified: IDs under which no protected window reads like another triple.

    Returns the assignment and its final verification (on poses of seed ``seed``).
    With a complete ``proof`` the labels are designed against it; otherwise against samples and the empty-triangle set. ``observations``
    (seed -> :class:`Observation` at ``per_m2``) is filled and reused, so a caller
    verifying other schemes on the same samples observes each once.
    """
    seen = {} if observations is None else observations
    if proof is not None and proof.complete:
        made = proved.assign_proved(xyz, radii, outline, graph, camera, proof, seed=seed,
                              per_m2=per_m2, tolerance_m=tolerance_m, observations=seen)
        if made is not None:
            return made  # else designed as below, and judged on the proved set by the caller

    def checked(s: int, labels: np.ndarray) -> Verification:
        if s not in seen:
            seen[s] = observe_site(xyz, radii, outline, camera, per_m2=per_m2, seed=s, tolerance_m=tolerance_m)
        return classify(seen[s], labels + 1)

    n = len(xyz)
    area = working_area(xyz[:, :2], outline)
    floor_m2 = max(area_m2(area), 1e-6)
    design = design_windows(xyz, radii, outline, camera, per_m2=design_per_m2(per_m2, floor_m2), seed=seed + 1,
                            tolerance_m=tolerance_m)
    rival_site: np.ndarray | None = None  # where rivals are searched: every short triple, or a proof's matches
    if proof is not None and proof.triangles is not None:  # proved, but too large to design against directly:
        # the proved set holds every window (the sampled ones too), so no superset of it is needed
        windows = np.unique(np.sort(np.vstack([design.windows.reshape(-1, 3), proof.triangles]), axis=1), axis=0)
        bound = longest_side(windows, xyz)
        rival_site = proof.shape_matches(tolerance_m)
        extra = windows[~rows_in(windows, np.sort(proof.triangles, axis=1))]  # both sorted within rows
        if len(extra):  # none while the proof is sound: matched all the same
            rival_site = np.vstack([rival_site, tiled_shape_matches(extra, xyz, tolerance_m, proof.runner)])
    else:
        windows, bound = _protected(design.windows, xyz, radii, tolerance_m, install_tolerance_m)
    others, first = None, windows
    # too many short triples to key them all (the windows alone are readings): rivals join as they are found
    full = None if len(windows) > MAX_READINGS else _keyed(windows, xyz, tolerance_m)
    lazy = full is None or len(full[0]) > MAX_READINGS
    if lazy:
        others = windows

    def solve(repair_from=None, min_bits=1):
        fresh = others is None and repair_from is None and len(windows) == len(first)
        problem = full if fresh and full is not None else _keyed(windows, xyz, tolerance_m, others)
        if repair_from is not None:
            got = window_code.repair_labels(repair_from[0], n, *problem[:3], repair_from[1], seed=seed,
                                            max_steps=200_000, active=problem[3])
            if got is not None:
                return None, got, repair_from[1], problem
        c = window_code.assign_window_code(n, *problem[:3], seed=seed, time_budget=time_budget,
                                           active=problem[3], min_bits=min_bits)
        return c, c.labels, c.K, problem

    code, labels, k, problem = solve()
    method = code.method
    check_seeds = [seed + 1000 * (r + 1) for r in range(CHECK_SEEDS - 1)] + [seed]
    widths, passes = [bits_for(max(k, 2))], 0  # passes: repairs at the present width
    while True:
        found = [t for _, t in find_rivals(windows, xyz, labels + 1, tolerance_m, site=rival_site)]
        missed: list[tuple[int, ...]] = []
        check: Verification | None = None
        for s in check_seeds:
            check = checked(s, labels)
            missed.extend(g[0] for g in check.conflicts)  # a sampled window outside the set; rivals follow
        if (not found and not missed) or len(np.unique(labels)) == n:
            break
        windows = np.vstack([windows, np.array(missed, dtype=np.int64).reshape(-1, 3)])
        if rival_site is not None and missed:  # a proved set is sound, so never; but if it were not
            rival_site = np.vstack([rival_site, tiled_shape_matches(np.array(missed, dtype=np.int64), xyz, tolerance_m)])
        if lazy:
            assert others is not None  # lazy keying starts from the windows and only grows
            others = np.vstack([others, np.array(found, dtype=np.int64).reshape(-1, 3)])
        passes += 1
        if passes <= WIDEN_AFTER:
            new_code, labels, k, problem = solve((labels, k))
        elif bits_for(max(k, 2)) + 1 < bits_for(n):  # repairs at this width keep making new rivals: one bit
            # more, afresh (measured on the hexagonal site, rivals lazy: labels carried up from the width
            # below crowd into half the labels, and rivals the search does not know yet follow them)
            new_code, labels, k, problem = solve(min_bits=bits_for(max(k, 2)) + 1)
            widths.append(bits_for(max(k, 2)))
            passes = 0
        else:  # no reuse left to try
            new_code, labels, k = None, np.arange(n, dtype=np.int64), n
        code = new_code or code
        method = f"{code.method}, repaired against rivals and verification"
        if k == n:
            method = "distinct labels (every shorter width left rivals)"
    ids = labels.astype(np.int64) + 1
    bits = bits_for(max(k, 2))
    detail = {"windows": int(problem[3].sum()), "sampled_windows": len(design.windows),
              "max_side_m": round(bound, 4), "rivals": "lazy" if lazy else "all",
              "widths_tried": widths, "labels": int(k), "optimal": bool(code.optimal and bits == code.bits),
              "lower_bound_labels": int(code.lower_bound_labels)}
    assignment = Assignment("window", ids, tile_regions(xyz[:, :2], graph, k), bits, bits_for(n),
                            int(code.lower_bound_bits), method, detail)
    assert check is not None  # check_seeds is never empty
    return assignment, check
