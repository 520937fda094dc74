"""Coordination number (the paper's eq. 10): C_n = sum(n_c) / N_p over the grains of a region.

n_c is the number of touching contacts of a grain: those carrying a force (F_n or F_s not 0; a
contact still overlapping whose damped normal force is clipped to 0 while it opens, and so
carries no shear force either, does not count).  Grain-grain contacts count once for each of
their two grains; grain-wall contacts count for their grain (``wall_grain``), as in PFC2D,
whose measurement logic counts every contact of a ball.  Grains without contacts (rattlers)
count in N_p.  Reference values for infinite packings of equal disks (the paper's Table 3):
square lattice 4, triangular (hexagonal) lattice 6.
"""

from __future__ import annotations

import numpy as np


def contacts_per_grain(n: int, i: np.ndarray, j: np.ndarray,
                       wall_grain: np.ndarray | None = None) -> np.ndarray:
    """Number of touching contacts of each of ``n`` grains [-].

    ``i, j``: grain indices of the grain-grain contacts; ``wall_grain``: grain index of each
    grain-wall contact (None: walls not counted)."""
    counts = np.bincount(np.asarray(i, dtype=np.int64), minlength=n)[:n]
    counts = counts + np.bincount(np.asarray(j, dtype=np.int64), minlength=n)[:n]
    if wall_grain is not None:
        counts = counts + np.bincount(np.asarray(wall_grain, dtype=np.int64), minlength=n)[:n]
    return counts


def coordination_number(counts: np.ndarray, mask: np.ndarray | None = None) -> float:
    """C_n = sum(n_c) / N_p over the grains where ``mask`` is True [-] (NaN if none)."""
    c = counts if mask is None else counts[mask]
    return float(c.sum() / c.size) if c.size else float("nan")
