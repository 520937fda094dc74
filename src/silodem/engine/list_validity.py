"""Whether the Verlet list still holds every contact: the global test, then one by cells.

At a build every pair closer than r_i + r_j + skin is listed, and every grain closer than
r + skin to a wall (``neighbors``).  A pair left out can only touch once the two grains have
closed in by more than the skin, |D_i - D_j| > skin, where D is a grain's displacement since
the build.

``list_expired`` (the global test) bounds |D_i - D_j| by the largest displacement of all
(``global_bound``): min(2 max|D|, diagonal of the box of all D).  In a large system some
grain somewhere is always fast (in the benchmark silo, grains falling freely for tens of
metres), so the list is rebuilt at the pace of the fastest grain, and more often the larger
the system: 59 builds per 500 steps in one silo, 111 in 100 side by side
(docs/performance-history.md, fourteenth session).

``cells_keep_list`` (the test by cells) asks only the grains that could meet.  On the
build's cell grid (cells of size c = 2 r_max + skin, each grain in the cell of its build
position) two grains in cells k apart (Chebyshev distance, k >= 2) were more than (k - 1) c
apart, and touch only within r_i + r_j <= c - skin, so they cannot meet while
|D_i - D_j| <= (k - 2) c + skin.  Hence the list holds every contact while

* for every two grains in cells at most 2 apart (the same cell included): |D_i - D_j| < skin,
  or else they do not touch now, or they are a candidate pair (``apart_or_listed``: the list
  need only hold the contacts of the next force evaluation, and the test runs after every
  step);
* for cells 3 or more apart: min(2 max|D|, diagonal of the box of all D) < c + skin;
* for every grain: |D| + wall drift < its gap to the walls it is not a candidate of
  (``NeighborList.wall_gap``).

A falling grain then costs a rebuild only when it comes within reach of a grain that moves
differently, not at every skin's worth of fall.  Two grains that both moved less than skin/2
cannot have closed in by the skin, so the leap-frog, which has each grain's displacement at
hand, lists the grains that moved skin/2 or more ("fast") and flags a grain too near a wall
(``integrate.walls_and_leapfrog``); the test compares only the fast grains with the grains
of the cells up to 2 from theirs, and gives up (rebuild) when more than one grain in
``FAST_SHARE_MAX`` is fast, where that would cost more than a build.  The step loop asks it
only after the global test has failed, and not while walls move (their drift grows after
the leap-frog's report).  Where a fast grain has closed in on a neighbour by the skin, the
exact look (touching? listed?) keeps the list through shear in a flowing packing, where
neighbours part and pass by the skin without touching anew: in the packed benchmark silo
33 of 88 builds per 1000 steps were for that before, and 72 of 101 with ten silos side by
side (docs/performance-history.md, fifteenth session).
``must_rebuild`` puts the two together: the one rule that the step loop and ``Simulation``
both ask.  The same rebuilds, hence the same bits, for any number of threads.
Proof checked in tests/test_neighbors.py: no contact missed after any step, by brute force,
for a grain shot into a resting block and in the benchmark silo.
"""

from __future__ import annotations

import math

from silodem.engine.cells import cell_of
from silodem.engine.contact import pair_offset
from silodem.jit import njit


@njit
def global_bound(drift, lox, hix, loy, hiy):
    """The global bound [m] on how far two grains have closed in since the build, from the
    largest displacement ``drift`` [m] and the bounding box of the displacement vectors:
    min(2 max|D|, diagonal of the box) (0 for an empty box).

    A pair (i, j) has closed in by at most |D_i - D_j| (D = displacement since the build),
    which is at most min(2 max|D|, diagonal of the bounding box of all D).  The second bound is
    the sharper one when the grains move together (a falling column, a discharging bulk), and
    keeps the list twice as long as the usual max|D| < skin/2 when part of the grains is at
    rest."""
    diagonal = math.hypot(hix - lox, hiy - loy) if hix >= lox else 0.0
    return min(2.0 * drift, diagonal)


@njit
def list_expired(bound, drift, wall_drift, skin):
    """Whether the Verlet list may miss a contact by the global test, from ``global_bound``,
    the largest grain displacement since the build ``drift`` and how far the walls moved
    [m]: a pair left out at the build was at least r_i + r_j + skin apart, and a grain-wall
    candidate is kept within r + skin, so a wall is safe while max|D| + wall drift < skin."""
    return bound >= skin or drift + wall_drift >= skin


# past one fast grain in this many the test gives up (a rebuild): each fast grain is compared
# with about 50 grains (25 cells), so at 1e4 grains the test then costs about a step
FAST_SHARE_MAX = 16


@njit
def apart_or_listed(f, g, x, y, radius, i_start, pair_j):
    """Whether grains ``f`` and ``g`` do not touch (by the pair loop's own test, on the same
    positions) or are a candidate pair of the list: either way the next forces miss nothing
    between them."""
    i = min(f, g)
    j = max(f, g)
    _, _, d2, rsum = pair_offset(i, j, x, y, radius)
    if d2 >= rsum * rsum:
        return True
    if not d2 < rsum * rsum:  # NaN: a rebuild, which reports the unstable run
        return False
    for k in range(i_start[i], i_start[i + 1]):
        if pair_j[k] == j:
            return True
    return False


@njit
def cells_keep_list(n, runs, fast, x, y, x_ref, y_ref, radius, i_start, pair_j, skin,
                    cell_grid, cell_start, bound):
    """True if the list still holds every contact of the ``n`` grains by the test by cells
    (module docstring), given ``global_bound`` [m] and what the leap-frog reported for the step
    just done (``integrate.walls_and_leapfrog``): per run of strips a row of ``runs`` with, in
    column 5, how many of its grains moved skin/2 or more since the build (listed in ``fast``
    from the run's first grain on, column 7), and in column 6 a 1 if a grain came within
    reach of a wall it is not a candidate of, or if the leap-frog listed nothing.
    ``cell_grid`` (xmin, ymin, cell size, ncx, ncy) and ``cell_start`` (each cell's first
    grain) are the build's; False (rebuild) when the build left none.

    Two grains that both moved less than skin/2 cannot have closed in by the skin, so only
    the fast grains are compared, each with the grains of the cells up to 2 from its own; a
    pair that closed in by the skin is looked at exactly (``apart_or_listed``).  ``radius``,
    ``i_start``, ``pair_j``: the grains' radii [m] and the candidate list."""
    xmin, ymin, cell = cell_grid[0], cell_grid[1], cell_grid[2]
    ncx, ncy = int(cell_grid[3]), int(cell_grid[4])
    if cell_start.shape[0] != ncx * ncy + 1:
        return False
    if not bound < cell + skin:  # cells 3 or more apart
        return False
    n_fast = 0
    for b in range(runs.shape[0]):
        if runs[b, 6] != 0.0:
            return False
        n_fast += int(runs[b, 5])
    if n_fast * FAST_SHARE_MAX > n:  # comparing them would cost more than a build
        return False
    skin2 = skin * skin
    for b in range(runs.shape[0]):
        first = int(runs[b, 7])
        for q in range(int(runs[b, 5])):
            f = fast[first + q]
            dfx = x[f] - x_ref[f]
            dfy = y[f] - y_ref[f]
            c = cell_of(x_ref[f], y_ref[f], xmin, ymin, cell, ncx, ncy)
            cx = c % ncx
            cy = c // ncx
            for ey in range(max(cy - 2, 0), min(cy + 3, ncy)):
                for ex in range(max(cx - 2, 0), min(cx + 3, ncx)):
                    e = ey * ncx + ex
                    for g in range(cell_start[e], cell_start[e + 1]):
                        ddx = dfx - (x[g] - x_ref[g])
                        ddy = dfy - (y[g] - y_ref[g])
                        # closed in by the skin or more (or NaN): then they must not
                        # touch, or touch as candidates
                        if not ddx * ddx + ddy * ddy < skin2 and not apart_or_listed(
                                f, g, x, y, radius, i_start, pair_j):
                            return False
    return True


@njit
def must_rebuild(bound, drift, wall_drift, skin, cell_test, n, runs, fast, x, y, x_ref, y_ref,
                 radius, i_start, pair_j, cell_grid, cell_start):
    """The one rule of when the list goes, for the step loop and for ``Simulation`` alike:
    when the global test fails (``list_expired`` on ``global_bound``, ``drift`` and the
    walls' drift [m]) and, if ``cell_test``, the test by cells on the leap-frog's last
    report ``runs`` (``cells_keep_list``; no report: rebuild) does not keep it."""
    if not list_expired(bound, drift, wall_drift, skin):
        return False
    if not cell_test or runs.shape[0] == 0:
        return True
    return not cells_keep_list(n, runs, fast, x, y, x_ref, y_ref, radius, i_start, pair_j,
                               skin, cell_grid, cell_start, bound)
