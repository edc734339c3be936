"""Two-LED windows: the gravity-aided receiver's window, sampled over poses, and its verdicts.

With the vertical known from the accelerometer, two luminaires fix the position and the yaw
(:mod:`planner.positioning.gravity`). The receiver's window is then the two LEDs wholly inside
the image whose centres lie at the smallest angle from the optical axis (by ray angle, so a
distorting lens changes nothing). It reads their IDs and their distance (from the pair's
bearings, levelled by gravity, and the discs' sizes, as the three-LED receiver measures a
triangle's sides); it does not know the yaw, so the pair is read **unordered**: the key is
``(distance, {L[a], L[b]})``. A window is decodable when no other pair of the site whose
length is within the congruence tolerance carries the same two labels, and its own two labels
differ (equal labels leave the 180 deg turn about the pair's middle: two places).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from planner.camera.model import Camera, Poses
from planner.verify.verify import AMBIGUOUS, DECODABLE, TOO_FEW, Verification, WindowSetCheck
from planner.verify.windows import nearest_seen


@dataclass(frozen=True)
class PosePairs:
    """The two-LED window of every pose: ``pairs`` (P, 2) luminaire indices, ascending, -1 where
    fewer than two LEDs are wholly seen; ``seen`` (P,) LEDs wholly seen (among those examined)."""

    pairs: np.ndarray
    seen: np.ndarray

    @property
    def covered(self) -> np.ndarray:
        return self.pairs[:, 0] >= 0

    def first(self, n: int) -> PosePairs:
        return PosePairs(self.pairs[:n], self.seen[:n])


def find_pairs(poses: Poses, xyz: np.ndarray, radii: np.ndarray, camera: Camera) -> PosePairs:
    """Every pose's two-LED window: the two wholly seen LEDs at the smallest angle from the axis."""
    pairs, seen = nearest_seen(poses, xyz, radii, camera, 2)
    return PosePairs(pairs, seen)


def pair_lengths(pairs: np.ndarray, xyz: np.ndarray) -> np.ndarray:
    """Length (M,) [m] of each pair (M, 2) of luminaire indices."""
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    return np.linalg.norm(xyz[pairs[:, 0]] - xyz[pairs[:, 1]], axis=1)


def site_pairs(xyz: np.ndarray, max_length_m: float) -> np.ndarray:
    """Every pair ``i < j`` of the site (M, 2) no longer than ``max_length_m``."""
    return cKDTree(xyz).query_pairs(max_length_m, output_type="ndarray").astype(np.int64).reshape(-1, 2)


def pair_rivals(windows: np.ndarray, xyz: np.ndarray, ids: np.ndarray, tolerance_m: float) -> list[list[tuple]]:
    """Windows (M, 2) that read like another pair of the site under ``ids``, each group the window
    and its rivals (a window with two equal labels is its own rival, reversed), largest first."""
    windows = np.unique(np.sort(np.asarray(windows, dtype=np.int64).reshape(-1, 2), axis=1), axis=0)
    if len(windows) == 0:
        return []
    ids = np.asarray(ids)
    length = pair_lengths(windows, xyz)
    site = site_pairs(xyz, float(length.max()) + tolerance_m + 1e-9)
    site_len = pair_lengths(site, xyz)
    lo, hi = np.sort(ids[site], axis=1).T
    base = int(ids.max()) + 1
    code = lo * base + hi
    order = np.argsort(code, kind="stable")
    code, site, site_len = code[order], site[order], site_len[order]
    wl, wh = np.sort(ids[windows], axis=1).T
    first = np.searchsorted(code, wl * base + wh, side="left")
    last = np.searchsorted(code, wl * base + wh, side="right")
    count = last - first
    owner = np.repeat(np.arange(len(windows)), count)
    rows = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count) + np.repeat(first, count)
    alike = (np.abs(site_len[rows] - length[owner]) <= tolerance_m + 1e-12) & (site[rows] != windows[owner]).any(axis=1)
    found: dict[int, list[tuple]] = {int(w): [(int(windows[w, 1]), int(windows[w, 0]))] for w in np.flatnonzero(wl == wh)}
    for w, r in zip(owner[alike].tolist(), rows[alike].tolist()):
        found.setdefault(w, []).append((int(site[r, 0]), int(site[r, 1])))
    groups = [[(int(windows[w, 0]), int(windows[w, 1]))] + rivals for w, rivals in found.items()]
    return sorted(groups, key=lambda g: (-len(g), g))


@dataclass(frozen=True)
class PairSet:
    """Distinct two-LED windows (M, 2), as :class:`planner.verify.windows.WindowSet` holds triples."""

    windows: np.ndarray

    def __len__(self) -> int:
        return len(self.windows)


def classify_pairs(position: np.ndarray, pp: PosePairs, xyz: np.ndarray, ids: np.ndarray, *, per_m2: float,
                   seed: int, tolerance_m: float) -> Verification:
    """Each sampled pose as decodable, ambiguous or too few LEDs seen (under two), under ``ids``."""
    status = np.full(len(pp.pairs), TOO_FEW, dtype=np.int64)
    covered = pp.covered
    status[covered] = DECODABLE
    windows = np.unique(pp.pairs[covered], axis=0).reshape(-1, 2)
    groups = pair_rivals(windows, xyz, ids, tolerance_m)
    if groups:
        bad = {g[0] for g in groups}
        idx = np.flatnonzero(covered)
        hit = np.array([tuple(p) in bad for p in pp.pairs[idx].tolist()], dtype=bool)
        status[idx[hit]] = AMBIGUOUS
    return Verification(position, status, PairSet(windows), groups, per_m2, seed, tolerance_m)


@dataclass(frozen=True)
class PairSetCheck(WindowSetCheck):
    """Every pair that may be a two-LED window up to ``length_cap_m`` long (the proved pairs,
    :mod:`planner.verify.pair_proof`, or every site pair), checked against every pair of the site.

    ``length_cap_m`` is the receiver's window rule's cap (:func:`length_cap_m`): a window longer than
    it is no window, the receiver does not read its pair alone. So with a complete proof, ``proved``
    holds for every pose of the envelope whose two nearest whole LEDs are at most the cap apart.
    """

    length_cap_m: float = math.inf
    capped: int = 0  # proved pairs longer than the cap, left out of the check

    def summary(self, names: list[str], limit: int = 5) -> dict:
        out = super().summary(names, limit)
        out["rule"] = "pair spindle and axis disc" if self.complete else "pairs up to the sampled length"
        out["max_length_m"] = out.pop("max_side_m")
        out["max_length_from"] = out.pop("max_side_from")
        out["pairs"] = out.pop("triangles")
        if self.complete and math.isfinite(self.length_cap_m):
            out["window_length_cap_m"] = round(self.length_cap_m, 4)
            out["proved_pairs_beyond_cap"] = self.capped
        return out


def length_cap_m(sampled: np.ndarray, xyz: np.ndarray, tolerance_m: float) -> float:
    """The window rule's cap on a pair's length [m]: the longest sampled window plus the congruence
    tolerance (the receiver reads lengths to that). The proof keeps pairs far longer that no pose of the
    sample takes (docs/verification.md): beyond the cap the pair alone is not read."""
    return float(pair_lengths(sampled, xyz).max()) + tolerance_m if len(sampled) else 0.0


def window_pairs(xyz: np.ndarray, proved: np.ndarray | None, sampled: np.ndarray, tolerance_m: float
                 ) -> tuple[np.ndarray, float, int]:
    """The pairs that may be windows under the rule's length cap (:func:`length_cap_m` of the ``sampled``
    windows): the ``proved`` ones within it, or with no proof every site pair within it; with the cap [m]
    and how many proved pairs lie beyond it. The IDs are designed against these and checked on them."""
    cap = length_cap_m(sampled, xyz, tolerance_m)
    if proved is None:
        return (site_pairs(xyz, cap) if len(sampled) else np.empty((0, 2), np.int64)), cap, 0
    within = pair_lengths(proved, xyz) <= cap + 1e-9
    return proved[within], cap, int((~within).sum())


def check_pair_set(xyz: np.ndarray, ids: np.ndarray, pairs: np.ndarray | None, sampled: np.ndarray, *,
                   tolerance_m: float, install_tolerance_m: float, reason: str,
                   envelope: dict | None) -> PairSetCheck:
    """Check ``pairs`` (the proved set) or, with none, every site pair, up to the window rule's length cap
    (:func:`window_pairs`)."""
    complete = pairs is not None
    pairs, cap, capped = window_pairs(xyz, pairs, sampled, tolerance_m)
    longest = float(pair_lengths(pairs, xyz).max()) if len(pairs) else 0.0
    groups = pair_rivals(pairs, xyz, ids, tolerance_m)
    return PairSetCheck(len(pairs), groups, longest, install_tolerance_m, tolerance_m, complete,
                        "" if complete else reason, envelope, cap, capped)
