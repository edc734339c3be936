"""Labels designed against a complete (proved) window set: the fewest bits whose labels keep every proved
window apart from every triple of the site that could read like it.

The pairs that must differ are found by :mod:`planner.codes.readings` (or grouped by shape,
:mod:`planner.codes.classes`) and searched by min-conflicts (:mod:`planner.codes.pairwise`), width by
width from the counting bound. :mod:`planner.codes.schemes` uses this where the proof reaches and keeps
the sampled design for the rest.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from planner.camera.model import Camera
from planner.codes import classes, pairwise
from planner.codes.assignment import Assignment, bits_for, tile_regions
from planner.codes.readings import ReadingIndex
from planner.graph import NeighbourGraph
from planner.verify.proof import Proof
from planner.verify.rivals import shape_matches
from planner.verify.verify import Verification, classify, observe_site
from planner.verify.windows import CONGRUENCE_TOLERANCE_M

PROVED_STEPS_PER_LUMINAIRE = 20
"""Against a proved set: moves a width's min-conflicts search may make, per luminaire (it also stops when it stalls)."""

HOPELESS_PER_LUMINAIRE = 2
"""Against a proved set: widths whose random labels leave more conflicting pairs than this per luminaire are not tried."""

HOPELESS_IN_GROUPS_PER_LUMINAIRE = 4
"""The same for shape groups (lattices): measured on ``grid-256``, random 5-bit labels leave 8.4 per
luminaire and a search stalls; 6-bit labels leave 2.1 and are found in 45 moves (2026-12-03)."""


def counting_bound(triangles: np.ndarray, xyz: np.ndarray, tolerance_m: float) -> int:
    """Fewest labels that can keep a complete window set apart: the larger of
    :func:`planner.codes.classes.clique_lower_bound` and :func:`~planner.codes.classes.near_lower_bound`."""
    return int(max(classes.clique_lower_bound(triangles, xyz), classes.near_lower_bound(triangles, xyz, tolerance_m)))


@dataclass(frozen=True)
class ProvedLabels:
    """Labels designed against a complete window set (:func:`proved_labels`).

    ``labels`` (N,) 0..``k``-1, or None when no width below one ID per luminaire was met;
    ``bound`` the counting lower bound on the labels of this set (:func:`counting_bound`);
    ``detail`` what ``plan.yaml`` records.
    """

    labels: np.ndarray | None
    k: int
    bound: int
    detail: dict

    @property
    def bits(self) -> int:
        return bits_for(max(self.k, 2))

    @property
    def bound_bits(self) -> int:
        return bits_for(max(self.bound, 2))


def proved_labels(triangles: np.ndarray, xyz: np.ndarray, tolerance_m: float, *, seed: int = 0,
                  matches: Callable[[], np.ndarray] | None = None,
                  hopeless_per_luminaire: float | None = None) -> ProvedLabels | None:
    """The fewest bits whose labels keep every window of a complete set apart from every triple of the site.

    The pairs that must differ are those of a window and a triple of the site within the tolerance of
    it (``matches`` gives :meth:`Proof.shape_matches`, found once): the pairs of triples sharing a
    luminaire are listed and the others found by their labels (:mod:`planner.codes.readings`); where
    those are over :data:`planner.codes.alike.PAIR_BUDGET`, every group of triples of one shape
    (:mod:`planner.codes.classes`).
    Widths are tried from the counting bound up, each by min-conflicts for at most
    :data:`PROVED_STEPS_PER_LUMINAIRE` moves per luminaire; a width that falls short seeds the next
    with its best labels (valid labels there too, with the conflicts it left to resolve), so a
    width's conflicts lead to one bit more, not to one ID per luminaire. Widths whose random labels
    leave more conflicts than ``hopeless_per_luminaire`` per luminaire (default
    :data:`HOPELESS_PER_LUMINAIRE`, :data:`HOPELESS_IN_GROUPS_PER_LUMINAIRE` for groups) are skipped
    at first; if no other width is met they are climbed too, from the first skipped. None when
    neither the pairs nor the groups are within their budgets (:data:`planner.codes.classes.LINK_BUDGET`).
    """
    n = len(xyz)
    index: pairwise.ConflictIndex | None = None
    groups: classes.Groups | None = None
    found = matches() if matches else shape_matches(triangles, xyz, tolerance_m)
    keyed = ReadingIndex.build(triangles, found, xyz, tolerance_m)
    if keyed is not None:
        index, per, size = keyed, HOPELESS_PER_LUMINAIRE, {"listed_pairs": keyed.local.pairs, "triples": len(keyed.T)}
    else:  # congruent cliques (a lattice), else cells of the tolerance's width
        groups = (classes.shape_groups(triangles, xyz, tolerance_m, found)
                  or classes.shape_groups(triangles, xyz, tolerance_m, found, resolution_m=tolerance_m))
        if groups is None:  # neither the pairs nor the groups fit
            return None
        per, size = HOPELESS_IN_GROUPS_PER_LUMINAIRE, {"shape_groups": groups.count,
                                                        "grouped_triples": len(groups.triples)}

    def index_for(K: int) -> pairwise.ConflictIndex | None:
        if index is not None:
            return index
        assert groups is not None
        return classes.ClassIndex(n, groups, K) if classes.ClassIndex.fits(groups, K) else None
    hopeless = (per if hopeless_per_luminaire is None else hopeless_per_luminaire) * n
    unique_bits = bits_for(n)
    bound = counting_bound(triangles, xyz, tolerance_m)  # no fewer labels can work: not tried
    max_steps = max(1000, PROVED_STEPS_PER_LUMINAIRE * n)
    tried: list[int] = []
    left: list[int] = []
    skipped: list[int] = []
    steps_of = 0

    split: dict = {}

    def climb(widths: list[int], skip: bool) -> tuple[np.ndarray | None, int]:
        """Labels of the first width of ``widths`` met (and its K), each width seeded by the one below."""
        nonlocal steps_of
        below: np.ndarray | None = None  # the best labels of the last width tried, if it fell short
        below_at: tuple[pairwise.ConflictIndex, int] | None = None  # its index and K
        for b in widths:
            K = 2 ** b
            width = index_for(K)
            if width is None:  # over the tables' budget: the width below's labels, with digits that part its conflicts
                if below is not None and below_at is not None and isinstance(below_at[0], classes.ClassIndex):
                    alike = below_at[0].alike_rows(below)
                    lab, conflicts = split_labels(alike, below, below_at[1], K, n, rng=np.random.default_rng([seed, K]),
                                                  max_steps=max_steps)
                    tried.append(b)
                    left.append(conflicts)
                    if conflicts == 0:
                        split.update(split_from_bits=bits_for(below_at[1]), split_pairs=len(alike))
                        return lab, K
                continue
            rng = np.random.default_rng([seed, K])
            if below is None:
                if skip and width.begin(np.random.default_rng([seed, b]).integers(0, K, n))[0] > hopeless:
                    skipped.append(b)  # measured: such widths stall (4 bits on the jittered sites of
                    continue  # tests/verify/test_window_set.py); tried last, if no other is met
                lab = rng.integers(0, K, n).astype(np.int64)
            else:  # the width below, short of a few conflicts: its labels are labels of this width too
                lab = below
            conflicts, steps_of = pairwise.search_from(width, K, lab, rng=rng, max_steps=max_steps)
            tried.append(b)
            left.append(int(conflicts))
            if conflicts == 0:
                return lab, K
            below, below_at = lab, (width, K)
        return None, n

    widths = list(range(max(1, bits_for(bound)), unique_bits))
    labels, k = climb(widths, skip=True)
    if labels is None and skipped:  # every width left conflicts: the skipped ones too, each seeding the next
        labels, k = climb(widths[widths.index(skipped[0]):], skip=False)
    detail = {"windows": len(triangles), **size, "widths_tried": tried, "conflicts_left": left, "steps": int(steps_of),
              "max_steps": max_steps, "labels": int(k), **split}
    return ProvedLabels(labels, k, int(bound), detail)


def split_labels(alike: np.ndarray, below: np.ndarray, k_below: int, K: int, n: int, *, rng: np.random.Generator,
                 max_steps: int) -> tuple[np.ndarray, int]:
    """Labels 0..K-1 made of the labels ``below`` (0..k_below-1) and one more digit base ``K / k_below`` per luminaire,
    the digits chosen by min-conflicts so that every pair ``alike`` under ``below`` ((P, 6) rows, as
    :class:`planner.codes.pairwise.Index` takes them) differs in some place; and the pairs left alike.

    Two triples alike under the combined labels are alike under ``below`` too, so ``alike`` holds every
    pair that can conflict: parting them all leaves none. Used where the width's own tables are over
    their budget (:data:`planner.codes.classes.TABLE_BUDGET`): the pairs left by the width below are few.
    """
    digits = K // k_below
    extra = rng.integers(0, digits, n).astype(np.int64)
    conflicts, _ = pairwise.search_from(pairwise.Index(n, alike), digits, extra, rng=rng, max_steps=max_steps)
    return below * digits + extra, int(conflicts)


def assign_proved(xyz: np.ndarray, radii: np.ndarray, outline, graph: NeighbourGraph, camera: Camera,
                   proof: Proof, *, seed: int, per_m2: float, tolerance_m: float,
                   observations: dict) -> tuple[Assignment, Verification] | None:
    """The window scheme against a complete window set (:func:`proved_labels`): no sample, key
    cells or repair rounds are needed. None when the set is too large to design against."""
    assert proof.triangles is not None
    n = len(xyz)
    got = proved_labels(proof.triangles, xyz, tolerance_m, seed=seed, matches=lambda: proof.shape_matches(tolerance_m))
    if got is None or got.labels is None:  # no width short of one ID each: the sampled design may still reuse
        return None
    labels, method = got.labels, f"min-conflicts against the {len(proof.triangles):,} proved windows"
    if "split_from_bits" in got.detail:
        method += (f" (the {got.detail['split_from_bits']}-bit labels' {got.detail['split_pairs']:,} alike pairs "
                   "parted by the last bits)")
    ids = labels.astype(np.int64) + 1
    if seed not in observations:
        observations[seed] = observe_site(xyz, radii, outline, camera, per_m2=per_m2, seed=seed, tolerance_m=tolerance_m)
    check = classify(observations[seed], ids)
    detail = {**got.detail, "optimal": got.bits == got.bound_bits, "lower_bound_labels": got.bound}  # in this order
    return Assignment("window", ids, tile_regions(xyz[:, :2], graph, got.k), got.bits, bits_for(n), got.bound_bits,
                      method, detail), check


def window_set_bound(proof: Proof, xyz: np.ndarray, window: Assignment | None,
                     tolerance_m: float = CONGRUENCE_TOLERANCE_M) -> dict | None:
    """What ``plan.yaml`` says beside the width (``code.window_set``): whether the window set the IDs
    answer to is proved or sampled, its size and its counting lower bound (labels and bits).

    Proved: :func:`counting_bound` of the proved set, whatever the scheme. Otherwise the window scheme's
    own bound over the windows it protected (``window``), or None when it was not made."""
    if proof.triangles is not None:
        labels = counting_bound(proof.triangles, xyz, tolerance_m)
        return {"set": "proved", "windows": len(proof.triangles), "lower_bound_labels": int(labels),
                "lower_bound_bits": bits_for(max(labels, 2))}
    if window is None or "lower_bound_labels" not in window.detail:
        return None
    return {"set": "sampled", "windows": int(window.detail["windows"]),
            "lower_bound_labels": int(window.detail["lower_bound_labels"]), "lower_bound_bits": window.lower_bound_bits}
