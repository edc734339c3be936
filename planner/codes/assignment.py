"""The assignment stage: an ID for every luminaire.

Scheme ``paper`` is the region code of the paper's section 2.2: odd IDs on the
odd class, even IDs on the even class, and every adjacent (odd ID, even ID)
pair used once on the whole site, so that a pair seen together names the
region. Lattice layouts get it by construction (:mod:`planner.codes.region_lattice`),
other layouts by search (:mod:`planner.codes.region_search`). Every result is
checked by :func:`pair_conflicts` before it is returned.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.codes import region_lattice, region_search
from planner.errors import PlanningError
from planner.graph import NeighbourGraph


@dataclass(frozen=True)
class Assignment:
    """IDs of a site.

    Attributes
    ----------
    scheme : str
        ``"paper"``.
    ids : numpy.ndarray of int, shape (N,)
        The ID each luminaire broadcasts, 1..``max_id`` (sent as ``id - 1`` in ``bits`` bits).
    regions : numpy.ndarray of int, shape (N,)
        Region (the paper's group) of each luminaire, 0-based.
    bits, naive_bits, lower_bound_bits : int
        Bits of this code, of one unique ID per luminaire (``ceil(log2 N)``), and the
        fewest any code under the pair rule could use on this graph.
    method : str
        How the IDs were found.
    detail : dict
        Method specifics (block lattice, time budget, ...), written into the plan.
    """

    scheme: str
    ids: np.ndarray
    regions: np.ndarray
    bits: int
    naive_bits: int
    lower_bound_bits: int
    method: str
    detail: dict

    @property
    def max_id(self) -> int:
        return int(self.ids.max())

    @property
    def alphabet(self) -> int:
        """Number of distinct IDs in use."""
        return len(np.unique(self.ids))

    @property
    def efficiency(self) -> float:
        """The paper's coding efficiency, ``1 - bits / naive_bits``."""
        return 1.0 - self.bits / self.naive_bits if self.naive_bits else 0.0


def bits_for(max_id: int) -> int:
    """Bits to send IDs 1..max_id as ``id - 1``: ``ceil(log2 max_id)``, at least 1."""
    return max(1, math.ceil(math.log2(max_id))) if max_id > 1 else 1


def pair_lower_bound(graph: NeighbourGraph) -> tuple[int, int]:
    """Smallest largest-ID and bits of any code under the pair rule (counting bound).

    With ``A`` odd and ``B`` even IDs the distinct pairs number ``A * B``, which must
    cover the ``E`` cross edges (READING.md section 2); an even luminaire's odd
    neighbours need distinct IDs (``A >= `` its degree), and likewise for ``B``.
    The largest ID is ``max(2A - 1, 2B)``.
    """
    cross = graph.cross_edges
    if len(cross) == 0:
        return 2, 1
    n_edges = len(cross)
    deg_odd = int(np.bincount(cross[:, 0]).max())  # even neighbours of an odd luminaire -> B
    deg_even = int(np.bincount(cross[:, 1]).max())
    best = None
    for a in range(max(1, deg_even), n_edges + 1):
        b = max(deg_odd, math.ceil(n_edges / a))
        top = max(2 * a - 1, 2 * b)
        best = top if best is None else min(best, top)
        if 2 * a - 1 > best:
            break
    assert best is not None  # a cross edge exists, so n_edges >= deg_even >= 1 and the loop ran
    return best, bits_for(best)


def pair_conflicts(graph: NeighbourGraph, ids: np.ndarray, limit: int = 10) -> list[str]:
    """Violations of the pair rule, as sentences naming luminaire indices (at most ``limit``).

    Checks over the whole graph, group borders included: odd luminaires carry odd
    IDs and even ones even IDs; no (odd ID, even ID) pair occurs on two cross
    edges; luminaires joined by a same-class edge have different IDs.
    """
    problems = []
    wrong = np.flatnonzero((ids % 2 == 1) != graph.odd)
    problems += [f"luminaire {int(v)} has ID {int(ids[v])} of the wrong parity" for v in wrong[:limit]]
    seen: dict[tuple[int, int], tuple[int, int]] = {}
    for u, w in graph.cross_edges.tolist():
        key = (int(ids[u]), int(ids[w]))
        if key in seen:
            problems.append(f"pair {key} occurs at luminaires {seen[key]} and {(u, w)}")
        else:
            seen[key] = (u, w)
    for u, w in graph.same_class_edges.tolist():
        if ids[u] == ids[w]:
            problems.append(f"neighbours {u} and {w} of one class share ID {int(ids[u])}")
    return problems[:limit]


def tile_regions(xy: np.ndarray, graph: NeighbourGraph, alphabet: int) -> np.ndarray:
    """Regions for layouts without groups: square tiles holding about one alphabet.

    The tile side is ``sqrt(alphabet)`` typical neighbour spacings, aligned to the
    layout's principal axis; tiles are numbered row by row.
    """
    lengths = [d["length"] for _, _, d in graph.graph.edges(data=True)]
    spacing = float(np.median(lengths)) if lengths else 1.0
    side = max(spacing, spacing * math.sqrt(alphabet))
    c, s = math.cos(graph.angle_rad), math.sin(graph.angle_rad)
    local = xy @ np.array([[c, -s], [s, c]])
    tiles = np.floor((local - local.min(axis=0)) / side).astype(np.int64)
    _, regions = np.unique(tiles[:, ::-1], axis=0, return_inverse=True)
    return regions.astype(np.int64)


def _one_per_luminaire(odd: np.ndarray) -> np.ndarray:
    """IDs 1, 3, 5... on the odd class and 2, 4, 6... on the even class: trivially pair-unique."""
    ids = np.empty(len(odd), dtype=np.int64)
    ids[odd] = 2 * np.arange(int(odd.sum())) + 1
    ids[~odd] = 2 * np.arange(int((~odd).sum())) + 2
    return ids


def assign_paper(xy: np.ndarray, graph: NeighbourGraph, *, time_budget: float = 10.0, seed: int = 0) -> Assignment:
    """The paper's region code for a site with plan positions ``xy`` [m], shape (N, 2).

    Lattice layouts use the construction; others the search (greedy, then CP-SAT
    for ``time_budget`` deterministic seconds). Raises :class:`PlanningError` if
    the result breaks the pair rule (it never should: the check is independent).
    """
    n = len(xy)
    naive = bits_for(n)
    bound_id, bound_bits = pair_lower_bound(graph)
    code = None
    if graph.lattice is not None:
        code = region_lattice.construct(graph.lattice, graph.odd, bound_bits, max(naive, bound_bits) + 2)
        if code is not None and pair_conflicts(graph, code.ids, limit=1):
            code = None  # cross edges beyond the lattice's (across gaps): search instead
    if code is not None:
        a, b, d, transposed = code.block
        ids, regions = code.ids, code.regions
        method = "lattice construction"
        detail: dict[str, object] = {"group_columns": a, "group_rows": d, "group_shift": b, "transposed": transposed,
                  "group_size": code.alphabet}
    else:
        ids, method = region_search.search(graph, bound_bits, time_budget, seed)
        regions = tile_regions(xy, graph, int(ids.max()))
        detail = {"time_budget": time_budget, "seed": seed}
    trivial = _one_per_luminaire(graph.odd)
    if bits_for(int(trivial.max())) < bits_for(int(ids.max())):  # small sites: odd/even numbering is shorter
        ids, method, regions, detail = trivial, "one ID per luminaire (odd/even)", np.zeros(n, dtype=np.int64), {}
    problems = pair_conflicts(graph, ids)
    if problems:
        raise PlanningError(f"internal error: the {method} broke the pair rule: {problems[0]}")
    return Assignment("paper", ids, regions, bits_for(int(ids.max())), naive, bound_bits, method, detail)
