"""Shared test helpers: synthetic layouts."""

import numpy as np


def grid_xy(rows: int, cols: int, sx: float = 1.0, sy: float = 1.0, angle_rad: float = 0.0,
            jitter_m: float = 0.0, seed: int = 0) -> np.ndarray:
    """Plan positions of a rows x cols lattice, optionally rotated and jittered [m]."""
    pts = np.array([(c * sx, r * sy) for r in range(rows) for c in range(cols)], dtype=float)
    pts += np.random.default_rng(seed).normal(0.0, jitter_m, pts.shape)
    cos, sin = np.cos(angle_rad), np.sin(angle_rad)
    return pts @ np.array([[cos, sin], [-sin, cos]])


def hex_xy(rows: int, cols: int, pitch: float = 1.0) -> np.ndarray:
    """Staggered rows (every other row shifted half a pitch): a triangular lattice."""
    return np.array([(c * pitch + 0.5 * pitch * (r % 2), r * pitch * 0.866) for r in range(rows) for c in range(cols)])
