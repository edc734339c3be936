"""The paper's region code on lattice layouts, by construction.

The paper (section 2.2) keeps one class's IDs fixed in every group and permutes
the other class's IDs per group so that every adjacent (odd ID, even ID) pair
occurs once. Its figures are lost; this module builds such codes for any
subset of a rectangular lattice, with a proof instead of a search:

* Groups are the translates of a fundamental domain of a block lattice
  ``Lambda = <(a, 0), (b, d)>`` (columns, rows), which must lie inside
  ``Lc = {(i, j): j even, i = j mod 4}``: ``a`` a multiple of 4, ``d`` even
  and ``b = d mod 4``. The alphabet has ``K = a * d`` IDs, one group's worth.
* Fixed class (odd IDs): the ID is the cell's position in its group.
* Permuted class (even IDs): the cell's coset of ``Lc`` (4 cosets per class) and,
  inside it, ``(group number + index within the coset) mod K/8``, a cyclic
  Latin square, so each group holds each ID once.

Two permuted cells with one even ID lie in one coset of ``Lc`` at different
positions modulo ``Lambda``; the offsets between neighbours of two cells
(0, (+-2, 0), (0, +-2), (+-1, +-1)) are not in ``Lc`` except 0, so their
neighbourhoods share no fixed ID, across group borders included. A site fits
when it spans at most ``K / 8`` groups: up to ``K^2 / 8`` luminaires, i.e.
``2^(2 bits - 3)``. With 8 x 8 groups (K = 64) this is the paper's 512 case.
See ``docs/region-code.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.codes.pairwise import distinct


@dataclass(frozen=True)
class LatticeCode:
    """A region code on lattice cells.

    Attributes
    ----------
    ids : numpy.ndarray of int, shape (N,)
        IDs 1..K: odd on the fixed class, even on the permuted class.
    regions : numpy.ndarray of int, shape (N,)
        Group number of each cell, 0-based.
    block : tuple of int
        ``(a, b, d, transposed)``: the block lattice and whether rows and columns were swapped.
    alphabet : int
        ``K``, the number of IDs of a full group.
    """

    ids: np.ndarray
    regions: np.ndarray
    block: tuple[int, int, int, bool]
    alphabet: int


def block_lattices(alphabet: int) -> list[tuple[int, int, int]]:
    """Block lattices ``(a, b, d)`` of index ``alphabet`` inside Lc, squarest first."""
    found: list[tuple[int, int, int]] = []
    for a in range(4, alphabet + 1, 4):
        if alphabet % a:
            continue
        d = alphabet // a
        if d % 2:  # (b, d) in Lc needs d even and b = d mod 4
            continue
        found.extend((a, b, d) for b in range(0, a) if (b - d) % 4 == 0)
    return sorted(found, key=lambda abd: (abs(math.log(abd[0] / abd[2])), abd[1], abd[0]))


def _reduce(cells: np.ndarray, a: int, b: int, d: int):
    """Residue of each cell in the fundamental domain [0, a) x [0, d) and its group."""
    i, j = cells[:, 0], cells[:, 1]
    m = np.floor_divide(j, d)
    ii = i - m * b
    c = np.floor_divide(ii, a)
    return ii - c * a, j - m * d, m, c


def _domain_tables(a: int, d: int, fixed_parity: int):
    """Per-residue ID tables: fixed-class rank, permuted-class coset and index within it."""
    gi, gj = np.meshgrid(np.arange(a), np.arange(d), indexing="ij")
    ri, rj = gi.ravel(), gj.ravel()
    order = np.lexsort((ri, rj))  # row by row, as a person reads a group
    ri, rj = ri[order], rj[order]
    fixed = (ri + rj) % 2 == fixed_parity
    fixed_rank = np.full((a, d), -1, dtype=np.int64)
    fixed_rank[ri[fixed], rj[fixed]] = np.arange(int(fixed.sum()))
    coset_key = (rj % 2) * 4 + (ri - rj) % 4
    keys = sorted(set(coset_key[~fixed].tolist()))
    coset = np.full((a, d), -1, dtype=np.int64)
    within = np.full((a, d), -1, dtype=np.int64)
    for ci, key in enumerate(keys):
        sel = (~fixed) & (coset_key == key)
        coset[ri[sel], rj[sel]] = ci
        within[ri[sel], rj[sel]] = np.arange(int(sel.sum()))
    return fixed_rank, coset, within


def try_block(cells: np.ndarray, fixed: np.ndarray, a: int, b: int, d: int) -> tuple[np.ndarray, np.ndarray] | None:
    """IDs and groups for one block lattice, or None if the site spans too many groups."""
    alphabet = a * d
    per_coset = alphabet // 8
    ri, rj, m, c = _reduce(cells, a, b, d)
    key = (m - m.min()) * (int(c.max() - c.min()) + 1) + (c - c.min())  # (m, c) in lexicographic order
    groups = distinct(key)  # numpy's unique of rows is slow: a 100,000-luminaire lattice tries thousands of blocks
    if len(groups) > per_coset:
        return None
    regions = np.searchsorted(groups, key)
    fixed_parity = int((cells[fixed][0].sum()) % 2) if fixed.any() else 0
    fixed_rank, coset, within = _domain_tables(a, d, fixed_parity)
    ids = np.empty(len(cells), dtype=np.int64)
    ids[fixed] = 2 * fixed_rank[ri[fixed], rj[fixed]] + 1
    p = ~fixed
    t = (regions[p] + within[ri[p], rj[p]]) % per_coset
    ids[p] = 2 * (coset[ri[p], rj[p]] * per_coset + t) + 2
    return ids, regions.astype(np.int64)


def construct(cells: np.ndarray, fixed: np.ndarray, min_bits: int, max_bits: int) -> LatticeCode | None:
    """The shortest lattice region code with ``min_bits <= bits <= max_bits``.

    ``cells`` are integer (column, row) positions, shape (N, 2); ``fixed`` marks the
    class that keeps its IDs in every group (it gets the odd IDs) and must be one
    parity class of the lattice. Tries alphabets in multiples of 8 from the
    smallest the site could fit (``K^2 / 8 >= N``), both orientations.
    """
    cells = np.asarray(cells, dtype=np.int64)
    cells = cells - cells.min(axis=0)
    n = len(cells)
    smallest = max(8, math.ceil(math.sqrt(8 * n)))
    for bits in range(max(min_bits, 3), max_bits + 1):
        lo = max(smallest, 2 ** (bits - 1) + 1)
        for alphabet in range(8 * math.ceil(lo / 8), 2**bits + 1, 8):
            for a, b, d in block_lattices(alphabet):
                for transposed in (False, True):
                    use = cells[:, ::-1] if transposed else cells
                    found = try_block(use, fixed, a, b, d)
                    if found is not None:
                        return LatticeCode(found[0], found[1], (a, b, d, transposed), alphabet)
    return None
