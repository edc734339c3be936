"""The proved window set: every triple that a pose of the envelope could take as its window.

A window is the three wholly seen LEDs whose projected centres lie nearest the
image centre (the paper's rule). Take a pose, its window ``T``, the angle ``θ3``
between the optical axis and the farthest member, and the level set ``E(θ)``: the
ceiling points within angle ``θ`` of the axis, an ellipse (a plane section of the
cone of those rays). LEDs whose centres lie within ``α' = α_in - δ`` of the axis
are wholly seen (``α_in``: the cone inscribed in the image, ``δ``: the largest
angular radius of a disc, at the nearest ceiling distance). Two cases:

* **A** (``θ3 <= α'``): no other LED lies inside ``E(θ3)``, which holds ``T``.
  ``E(θ3)``'s radius of curvature is at most ``R`` (its ``a^2/b`` at the largest
  tilt, angle and distance), so it holds the ``R``-spindle (the lens cut by the two
  ``R``-circles through both points) of any two members (Blaschke: a convex body
  whose curvature is at least ``1/R`` is the intersection of the ``R``-discs that
  contain it). So no other LED lies in the spindle of any two members.
* **B** (``θ3 > α'``): ``E(α')``, which holds the disc ``D(q, ρ)`` of radius
  ``ρ = h_min sin α'`` about the axis point ``q``, holds no other LED; and every LED
  in ``conv(T ∪ D(q, ρ))`` with a disc no larger than the members' is wholly seen and
  nearer (the hull's image is the hull of in-view images; ``E(θ3)`` is convex), so
  that hull holds none. Every such hull holds a triangle on any side ``ab`` of ``T``
  with its apex ``ρ`` from the line ``ab`` on ``q``'s side (scale the disc's far
  point towards the side's middle); so an LED deep in such triangles, for every apex
  position, excludes ``q`` beyond that side. ``q`` inside ``T`` is searched in
  cells (branch and bound) down to :data:`MIN_CELL_M`.

A triple is excluded only when both cases are, so what is left is a superset of
every window. Installed luminaires lie up to ``d`` from the drawing: an LED counts
against a triple only when it is deeper than ``2 d`` inside the region, and the
spindles are taken over every centre within ``R + d`` of both (drawn) ends. The
``2 d`` margin is not slack for the paper's rule: an LED on an edge, moved outwards, can
be nearer yet cut by the image's border, and the hull is all this proof knows of the view
(docs/verification.md measures such a window). The receiver's crossing rule closes it: a
window with another LED's disc over one of its sides is refused, and an LED within its
radius less ``2 d`` of a drawn side overlaps the installed side, so such triples are dropped
before the two cases (:mod:`planner.verify.window_set`), as are triples drawn collinear
(:func:`planner.verify.window_set.may_be_decoded`).
Pairs are tested first (an LED may be the unknown third member, so two are needed).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from planner.camera.model import Camera
from planner.parallel import Runner
from planner.verify.envelope import Envelope, NotProvable, envelope
from planner.verify.exclusion import pair_reach_m, pairs_kept
from planner.verify.tiles import tiled_shape_matches, tiled_windows

PAIR_BUDGET = 120_000
"""Most pairs within reach that the proof examines; a larger site is not proved (it is sampled)."""

TRIANGLE_BUDGET = 400_000
"""Most candidate triangles (after the cheap tests) that the proof examines and the planner designs against."""



def possible_pairs(xy: np.ndarray, radii: np.ndarray, env: Envelope, budget: int = PAIR_BUDGET) -> np.ndarray:
    """Pairs ``i < j`` (M x 2) that can be two members of a window at some pose of the envelope;
    :class:`NotProvable` when more than ``budget`` pairs lie within reach. (One tile: the whole site;
    :func:`possible_windows` runs :func:`pairs_kept` per tile.)"""
    n = len(xy)
    tree = cKDTree(xy)
    pairs = tree.query_pairs(pair_reach_m(env), output_type="ndarray").astype(np.int64)
    if len(pairs) > budget:
        raise NotProvable(f"{len(pairs):,} pairs of luminaires within the camera's reach of "
                          f"{env.reach_m:.2f} m, over the proof's budget of {budget:,}")
    if len(pairs) == 0 or n < 4:
        return pairs.reshape(-1, 2)
    return pairs[pairs_kept(xy, radii, env, tree, pairs, float(radii.min()))]


def possible_windows(xyz: np.ndarray, radii: np.ndarray, env: Envelope, budget: int = TRIANGLE_BUDGET,
                     pair_budget: int = PAIR_BUDGET, runner: Runner | None = None) -> np.ndarray:
    """Every triple (T x 3, ``i < j < k``) that may be a window at some pose of the envelope, proved tile by
    tile (:mod:`planner.verify.tiles`) on ``runner`` (default: in process). ``budget`` and ``pair_budget``
    hold per tile: a tile over either keeps every candidate of its cheap tests, unexcluded
    (:attr:`TiledWindows.over_budget` names it; use :func:`planner.verify.tiles.tiled_windows` to see it)."""
    return tiled_windows(xyz, radii, env, runner, budget, pair_budget).triangles


@dataclass(frozen=True)
class Proof:
    """The outcome of :func:`prove_window_set` for the site ``xyz``: the proved window set, or why there is none;
    ``runner`` runs its rival search (:meth:`shape_matches`) too."""

    triangles: np.ndarray | None
    reason: str
    envelope: dict | None
    xyz: np.ndarray | None = None
    _matches: dict[float, np.ndarray] = field(default_factory=dict, compare=False, repr=False)
    runner: Runner | None = field(default=None, compare=False, repr=False)

    @property
    def complete(self) -> bool:
        return self.triangles is not None

    def shape_matches(self, tolerance_m: float) -> np.ndarray:
        """The site's triples that can read like a proved window (:func:`planner.verify.rivals.shape_matches`),
        found once per tolerance [m] however many schemes are judged against the proof."""
        assert self.triangles is not None and self.xyz is not None
        if tolerance_m not in self._matches:
            self._matches[tolerance_m] = tiled_shape_matches(self.triangles, self.xyz, tolerance_m, self.runner)
        return self._matches[tolerance_m]


def prove_window_set(xyz: np.ndarray, radii: np.ndarray, camera: Camera, install_tolerance_m: float,
                     runner: Runner | None = None) -> Proof:
    """Every triple that may be a window at some pose, or the reason this site and camera are not proved;
    the tiles run on ``runner`` (default: in process), the result is the same whatever runs them."""
    try:
        env = envelope(camera, xyz, radii, install_tolerance_m)
        tiled = tiled_windows(xyz, radii, env, runner, TRIANGLE_BUDGET, PAIR_BUDGET)
        return Proof(tiled.triangles, "", env.summary() | tiled.summary(), xyz, runner=runner)
    except NotProvable as exc:
        return Proof(None, str(exc), None)
