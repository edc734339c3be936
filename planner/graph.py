"""The graph stage: which luminaires are neighbours, and the odd/even checkerboard.

Neighbours come from the geometry, not from an assumed grid: the Delaunay
triangulation of the luminaires' plan positions, keeping an edge only when
every angle facing it in its triangles is below ``MAX_FACING_ANGLE_RAD`` (a
relaxed Gabriel graph). This drops the diagonals of square and rectangular
cells (facing angle 90 deg) and edges across gaps, and keeps all edges of
triangular (hexagonal, staggered) layouts. See ``docs/graph.md``.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial import Delaunay, QhullError

if TYPE_CHECKING:  # NetworkX loads when a graph is built, not with every module that reads one
    import networkx as nx

MAX_FACING_ANGLE_RAD = math.radians(80.0)
"""A Delaunay edge faced by an angle at least this large is not a neighbour edge [rad]."""

LATTICE_TOLERANCE = 0.15
"""Largest offset from a lattice line, as a share of the spacing, for a lattice layout."""


@dataclass(frozen=True)
class NeighbourGraph:
    """Neighbour relation and checkerboard classes of a layout.

    Attributes
    ----------
    graph : networkx.Graph
        Nodes ``0..N-1`` (indices into the layout's luminaires); edges carry ``length`` [m].
    odd : numpy.ndarray of bool, shape (N,)
        True for the odd class (odd IDs), False for the even class.
    bipartite : bool
        Whether the graph is two-colourable.
    odd_cycle : list of int or None
        A witness when it is not: node indices of an odd cycle.
    lattice : numpy.ndarray of int, shape (N, 2), or None
        Column and row index of each luminaire when the layout is a (subset of a)
        rectangular lattice, rows and columns counted in order along the layout's
        principal axes.
    angle_rad : float
        Direction of the layout's principal axis [rad].
    """

    graph: nx.Graph
    odd: np.ndarray
    bipartite: bool
    odd_cycle: list[int] | None
    lattice: np.ndarray | None
    angle_rad: float

    @property
    def cross_edges(self) -> np.ndarray:
        """Edges joining an odd and an even luminaire, shape (E, 2), odd end first."""
        e = self.edges
        if len(e) == 0:
            return e
        e = e[self.odd[e[:, 0]] != self.odd[e[:, 1]]]
        swap = ~self.odd[e[:, 0]]
        e[swap] = e[swap][:, ::-1]
        return e

    @property
    def same_class_edges(self) -> np.ndarray:
        """Edges inside one class (only when the graph is not bipartite), shape (E, 2)."""
        e = self.edges
        return e[self.odd[e[:, 0]] == self.odd[e[:, 1]]] if len(e) else e

    @property
    def edges(self) -> np.ndarray:
        """All edges, shape (E, 2), each as (low index, high index), sorted."""
        e = np.array(sorted((min(u, v), max(u, v)) for u, v in self.graph.edges()), dtype=np.int64)
        return e.reshape(-1, 2)


def neighbour_edges(xy: np.ndarray) -> np.ndarray:
    """Relaxed Gabriel edges of plan points ``xy`` [m], shape (E, 2), sorted."""
    n = len(xy)
    if n < 2:
        return np.empty((0, 2), dtype=np.int64)
    try:
        tri = Delaunay(xy)
    except QhullError:
        # All on one line (or too few): neighbours are consecutive along it.
        centred = xy - xy.mean(axis=0)
        direction = np.linalg.svd(centred, full_matrices=False)[2][0]
        order = np.argsort(centred @ direction, kind="stable")
        pairs = np.stack([order[:-1], order[1:]], axis=1)
        return np.unique(np.sort(pairs, axis=1), axis=0)
    simplices = tri.simplices
    pts = xy[simplices]  # (T, 3, 2)
    keep: dict[tuple[int, int], bool] = {}
    for k in range(3):
        b, c = simplices[:, (k + 1) % 3], simplices[:, (k + 2) % 3]
        u = pts[:, (k + 1) % 3] - pts[:, k]
        v = pts[:, (k + 2) % 3] - pts[:, k]
        cos = np.einsum("ij,ij->i", u, v) / (np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1))
        facing = np.arccos(np.clip(cos, -1.0, 1.0))  # angle at vertex a faces edge (b, c)
        for p, q, ang in zip(b.tolist(), c.tolist(), facing.tolist()):
            key = (p, q) if p < q else (q, p)
            keep[key] = keep.get(key, True) and ang < MAX_FACING_ANGLE_RAD
    edges = np.array(sorted(k for k, ok in keep.items() if ok), dtype=np.int64)
    return edges.reshape(-1, 2)


def principal_angle_of_edges(xy: np.ndarray, edges: np.ndarray) -> float:
    """Dominant edge direction folded into (-pi/4, pi/4] [rad] (mean of 4 theta on the circle).

    Rounded to 1e-9 rad so that float noise on an axis-aligned grid gives exactly 0.
    """
    if len(edges) == 0:
        return 0.0
    d = xy[edges[:, 1]] - xy[edges[:, 0]]
    theta = np.arctan2(d[:, 1], d[:, 0])
    return round(float(np.angle(np.exp(4j * theta).sum()) / 4.0), 9)


def _axis_ranks(values: np.ndarray, spacing: float) -> np.ndarray | None:
    """Rank of each value's cluster along one axis, or None if not on lines."""
    order = np.argsort(values, kind="stable")
    sorted_v = values[order]
    new_line = np.diff(sorted_v) > 0.5 * spacing
    rank_sorted = np.concatenate([[0], np.cumsum(new_line)])
    ranks = np.empty(len(values), dtype=np.int64)
    ranks[order] = rank_sorted
    line_pos = np.array([sorted_v[rank_sorted == r].mean() for r in range(rank_sorted[-1] + 1)])
    if np.max(np.abs(values - line_pos[ranks])) > LATTICE_TOLERANCE * spacing:
        return None
    return ranks


def detect_lattice(xy: np.ndarray, edges: np.ndarray, angle_rad: float) -> np.ndarray | None:
    """Column and row of each point if the layout is a subset of a rectangular lattice.

    Rows and columns may be unevenly spaced (a missing row is closed up), but every
    luminaire must sit on one row line and one column line, one luminaire per cell.
    """
    if len(edges) == 0:
        return None
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    local = xy @ np.array([[c, -s], [s, c]])
    d = np.abs(local[edges[:, 1]] - local[edges[:, 0]])
    horizontal, vertical = d[:, 1] < 0.2 * d[:, 0], d[:, 0] < 0.2 * d[:, 1]
    if np.count_nonzero(horizontal | vertical) < 0.8 * len(d):  # mostly diagonal: not rectangular
        return None
    sx = float(np.median(d[horizontal, 0])) if horizontal.any() else float(np.median(d[vertical, 1]))
    sy = float(np.median(d[vertical, 1])) if vertical.any() else sx
    cols, rows = _axis_ranks(local[:, 0], sx), _axis_ranks(local[:, 1], sy)
    if cols is None or rows is None:
        return None
    cells = np.stack([cols, rows], axis=1)
    if len(np.unique(cells, axis=0)) != len(cells):
        return None
    return cells


def _bfs_colouring(graph: nx.Graph, n: int) -> tuple[np.ndarray, list[int] | None]:
    """Two-colour by breadth-first search from the lowest index of each component.

    Returns (odd, odd_cycle): the colouring (roots are odd) and, if some edge joins
    two nodes of one colour, an odd cycle through it built from the BFS tree.
    """
    colour = np.full(n, -1, dtype=np.int8)
    parent = np.full(n, -1, dtype=np.int64)
    witness = None
    for root in range(n):
        if colour[root] >= 0:
            continue
        colour[root] = 0
        queue = deque([root])
        while queue:
            u = queue.popleft()
            for w in sorted(graph.adj[u]):
                if colour[w] < 0:
                    colour[w] = 1 - colour[u]
                    parent[w] = u
                    queue.append(w)
                elif colour[w] == colour[u] and witness is None:
                    witness = (u, w)
    cycle = None
    if witness is not None:
        u, w = witness
        path_u, path_w = [u], [w]
        while path_u[-1] != -1:
            path_u.append(int(parent[path_u[-1]]))
        while path_w[-1] != -1:
            path_w.append(int(parent[path_w[-1]]))
        ancestors_w = set(path_w)
        lca = next(x for x in path_u if x in ancestors_w)
        cycle = path_u[: path_u.index(lca) + 1] + path_w[: path_w.index(lca)][::-1]
        cycle = [int(x) for x in cycle]
    return colour == 0, cycle


def _improve_cut(graph: nx.Graph, odd: np.ndarray, max_passes: int = 50) -> np.ndarray:
    """Flip nodes with more same-class than cross-class neighbours (a local max cut)."""
    odd = odd.copy()
    for _ in range(max_passes):
        changed = False
        for u in range(len(odd)):
            same = sum(1 for w in graph.adj[u] if odd[w] == odd[u])
            if 2 * same > len(graph.adj[u]):
                odd[u] = not odd[u]
                changed = True
        if not changed:
            break
    return odd


def build_graph(xy: np.ndarray) -> NeighbourGraph:
    """Neighbour graph and checkerboard classes of plan positions ``xy`` [m], shape (N, 2).

    Bipartite layouts are two-coloured exactly. A layout that is not bipartite is
    coloured by breadth-first search, locally improved so that every luminaire has
    at least as many neighbours in the other class as in its own; the first odd
    cycle found is kept as a witness. A lattice layout is instead coloured by the
    parity of row + column (the paper's checkerboard; the luminaire in the first
    row and column is odd) unless that leaves more same-class neighbours.
    """
    xy = np.asarray(xy, dtype=float)
    n = len(xy)
    edges = neighbour_edges(xy)
    import networkx as nx

    graph: nx.Graph[int] = nx.Graph()
    graph.add_nodes_from(range(n))
    lengths = np.linalg.norm(xy[edges[:, 1]] - xy[edges[:, 0]], axis=1) if len(edges) else []
    graph.add_edges_from((int(u), int(v), {"length": float(d)}) for (u, v), d in zip(edges, lengths))
    angle = principal_angle_of_edges(xy, edges)
    lattice = detect_lattice(xy, edges, angle)
    bfs_odd, cycle = _bfs_colouring(graph, n)
    if cycle is not None:
        bfs_odd = _improve_cut(graph, bfs_odd)
    if lattice is not None:
        lattice_odd = (lattice.sum(axis=1) % 2) == 0
        # The lattice's own checkerboard unless it puts more neighbours in one class
        # (e.g. rows closed up around an odd row) than the graph's own colouring.
        if _same_class_count(edges, lattice_odd) <= _same_class_count(edges, bfs_odd):
            return NeighbourGraph(graph, lattice_odd, cycle is None, cycle, lattice, angle)
    return NeighbourGraph(graph, bfs_odd, cycle is None, cycle, None, angle)


def _same_class_count(edges: np.ndarray, odd: np.ndarray) -> int:
    return int(np.count_nonzero(odd[edges[:, 0]] == odd[edges[:, 1]])) if len(edges) else 0
