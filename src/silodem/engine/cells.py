"""The cell grid of a neighbour-list build and the strips of cell rows the step's loops work
in (``neighbors.NeighborList.rebuild``).

* ``cell_list``: the grains sorted by cell (a counting sort, row-major cells of side
  2 r_max + skin), which ``Particles.permute`` applies (spatial sorting: neighbours sit close
  in memory, and each cell is a contiguous index range, which the half-stencil search needs);
* ``walls_by_cell``: the walls that can reach each cell, so that a grain's wall search looks
  at its own cell's walls only;
* ``strip_rows``, ``first_grains``: the cell rows cut into strips of about equal grain counts
  (the pair loop's unit of work: strips of one parity run in parallel, ``contact.pair_forces``),
  and ``thread_blocks``: the strips cut into one run of consecutive strips per thread, of
  about equal work.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from silodem.jit import njit

STRIPS = 64  # strips of cell rows for the pair loop (contact.pair_forces): 32 per parity
# candidate lists and their starts hold 32-bit indices: the pair loop streams them every step,
# and half the bytes make it 8 % faster at 3e5 grains (none at 3e4; docs/performance-history.md)
INDEX = np.int32


@numba.njit(inline="always", cache=True)
def cell_of(px, py, xmin, ymin, cell_size, ncx, ncy):
    """Row-major index of the cell holding the point (px, py), clamped to the grid."""
    cx = min(max(int((px - xmin) / cell_size), 0), ncx - 1)
    cy = min(max(int((py - ymin) / cell_size), 0), ncy - 1)
    return cy * ncx + cx


@njit
def cell_list(n, x, y, xmin, ymin, cell_size, ncx, ncy):
    """Counting sort of the grains by cell (row-major).  Returns ``cell_start`` and
    ``members``: the grains of cell c are members[cell_start[c]:cell_start[c+1]]."""
    ncell = ncx * ncy
    cell = np.empty(n, dtype=np.int64)
    start = np.zeros(ncell + 1, dtype=np.int64)
    for p in range(n):
        c = cell_of(x[p], y[p], xmin, ymin, cell_size, ncx, ncy)
        cell[p] = c
        start[c + 1] += 1
    for c in range(ncell):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    members = np.empty(n, dtype=np.int64)
    for p in range(n):
        c = cell[p]
        members[fill[c]] = p
        fill[c] += 1
    return start, members


@njit
def walls_by_cell(w_lox, w_hix, w_loy, w_hiy, w_active, reach, xmin, ymin, cell_size, ncx,
                  ncy):
    """The active walls whose bounding box, widened by ``reach`` [m], overlaps each cell (CSR:
    cell c's walls are ``walls[start[c]:start[c+1]]``, in ascending wall index).  The wall
    search then looks at a grain's own cell's walls only: O(N + cells covered), not O(N x
    walls)."""
    nw = w_lox.shape[0]
    lo_x = np.empty(nw, dtype=np.int64)
    hi_x = np.empty(nw, dtype=np.int64)
    lo_y = np.empty(nw, dtype=np.int64)
    hi_y = np.empty(nw, dtype=np.int64)
    start = np.zeros(ncx * ncy + 1, dtype=np.int64)
    for w in range(nw):
        a = math.floor((w_lox[w] - reach - xmin) / cell_size)
        b = math.floor((w_hix[w] + reach - xmin) / cell_size)
        c = math.floor((w_loy[w] - reach - ymin) / cell_size)
        d = math.floor((w_hiy[w] + reach - ymin) / cell_size)
        if not w_active[w] or b < 0 or a >= ncx or d < 0 or c >= ncy:
            lo_x[w] = 1  # an empty range: the wall is off or away from every grain
            hi_x[w] = 0
            lo_y[w] = hi_y[w] = 0
            continue
        lo_x[w] = max(a, 0)
        hi_x[w] = min(b, ncx - 1)
        lo_y[w] = max(c, 0)
        hi_y[w] = min(d, ncy - 1)
        for cy in range(lo_y[w], hi_y[w] + 1):
            for cx in range(lo_x[w], hi_x[w] + 1):
                start[cy * ncx + cx + 1] += 1
    for c in range(ncx * ncy):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    walls = np.empty(start[-1], dtype=np.int64)
    for w in range(nw):  # ascending w: each cell's list is sorted
        for cy in range(lo_y[w], hi_y[w] + 1):
            for cx in range(lo_x[w], hi_x[w] + 1):
                c = cy * ncx + cx
                walls[fill[c]] = w
                fill[c] += 1
    return start, walls


@njit
def strip_rows(cell_start, ncx, ncy, n_strips=STRIPS):
    """Cut the cell rows into at most ``n_strips`` runs of whole rows holding about equal
    numbers of grains (grains sorted by cell, row-major): returns the first cell row of each
    strip and ncy at the end.  Row k + 1 starts strip m when it is the first row whose first
    grain is at or past m n / n_strips (clamped to rows 1 .. ncy - 1; repeated cuts merged).
    Depends on the positions only, never on the thread count.  Compiled: in numpy it took
    ~30 us of Python per list build, a third of the build at 1e3 grains."""
    rows = np.empty(n_strips + 1, dtype=INDEX)
    rows[0] = 0
    count = 1
    n = cell_start[ncy * ncx]
    if ncy > 1:
        row = 0  # the first row whose first grain is at or past the target
        for m in range(1, n_strips):
            target = n * m / n_strips
            while row <= ncy and cell_start[row * ncx] < target:
                row += 1
            cut = min(max(row, 1), ncy - 1)
            if cut != rows[count - 1]:
                rows[count] = cut
                count += 1
    rows[count] = ncy
    return rows[: count + 1].copy()


def first_grains(cell_start: np.ndarray, ncx: int, rows: np.ndarray) -> np.ndarray:
    """Strips of cell rows (``strip_rows``) as grain ranges: the first grain of each strip,
    and n at the end."""
    return cell_start[rows.astype(np.int64) * ncx].astype(INDEX)


# cost of one candidate pair in the pair loop against one grain in the leap-frog (a touching
# pair ~20 ns, one that does not a few ns; ~6 ns per grain: docs/performance-history.md)
PAIR_WORK = 2.5


def thread_blocks(strip_start: np.ndarray, i_start: np.ndarray, n_blocks: int) -> np.ndarray:
    """Cut the strips into ``n_blocks`` runs of consecutive strips, one per thread, of about
    equal work (grains + ``PAIR_WORK`` x candidate pairs): returns the first strip of each run
    and the number of strips at the end.  Runs of consecutive strips keep each grain on one
    thread in the pair loop and the leap-frog alike, so its state stays in that core's cache
    (handing out single strips in turn, as before, moved most grains between the cores twice
    a step); the cut is by work because the contacts sit in the packed lower part of a silo.
    The cut decides only which thread computes what, never a result."""
    n_strips = strip_start.size - 1
    work = strip_start.astype(np.float64) + PAIR_WORK * i_start[strip_start]
    targets = work[-1] * np.arange(1, n_blocks) / n_blocks
    upper = np.clip(np.searchsorted(work, targets), 1, n_strips)
    nearer = work[upper] - targets > targets - work[upper - 1]
    cuts = np.where(nearer, upper - 1, upper)
    return np.concatenate(([0], cuts, [n_strips])).astype(INDEX)
