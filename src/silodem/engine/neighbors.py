"""Neighbour search: a cell list builds a Verlet list of candidate contacts with a skin.

At each rebuild every pair closer than r_i + r_j + skin is listed once (i < j), grouped by i
(CSR: the candidates of grain i are ``pair_j[i_start[i]:i_start[i+1]]``, those that touch at
the build first, up to ``i_apart[i]``: the pair loop's branch predictor then rarely misses,
``contact.strip_pairs``), and every grain closer than r + skin to an active wall (3r + skin
for one-sided walls; only the walls binned to its cell are tested) gets a grain-wall
candidate, grouped by grain the same way (``w_start``).
The list stays valid while no two grains can have closed in by the skin since the build
(``list_validity``: a global test on the largest displacement, then a test by cells on the
grains that moved skin/2 or more); the build leaves what the test by cells needs: each
grain's gap to the walls it is not a candidate of, the cell grid and each cell's grains.

At each rebuild the grains are first reordered by cell (spatial sorting: neighbours sit close
in memory, and each cell is a contiguous index range, which the half-stencil search needs;
the cell grid and the strips are ``engine/cells.py``).

Contact history (shear force) survives the rebuild, the reordering and the removal of grains
without any search over all contacts: the last rebuild remembered, for each permanent grain
``uid``, the grain's index then (``slot_of_uid``); a new candidate (a, b) finds its old entry
by looking through the few old candidates of grain min(old a, old b), O(P) in all.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numba
import numpy as np

from silodem.engine import lanes
from silodem.engine.cells import (
    INDEX,
    cell_list,
    cell_of,
    first_grains,
    strip_rows,
    thread_blocks,
    walls_by_cell,
)
from silodem.engine.contact import closest_point
from silodem.errors import UnstableRunError
from silodem.jit import kernel, prange

if TYPE_CHECKING:
    from silodem.engine.particles import Particles
    from silodem.engine.walls import Walls

_MAX_CELLS_PER_GRAIN = 64
# the test by cells keeps each cell's first grain from the build; with more cells than this
# per grain (a few grains spread over a large domain) the list falls back to the global test
CELL_TEST_MAX_CELLS_PER_GRAIN = 4
@kernel
def _pairs_of(n, x, y, radius, xmin, ymin, cell_size, ncx, ncy, cell_start, rows, skin,
              counts, buf, stride):
    """The candidates j > i of every grain i, written to ``buf[i*stride : i*stride+stride]``
    as 2 j + 1 if they touch now, 2 j if not (only the first ``stride`` of them; ``counts[i]``
    is the true number; ``_compact_touching_first`` reads them).  The touch test is the pair
    loop's (``contact.pair_offset``).

    The grains must be sorted by cell (row-major), so that cell c holds the index range
    cell_start[c]:cell_start[c+1]; then a half stencil (the grain's own cell after i, and the
    cells east, north-west, north and north-east, all of higher index) finds each pair once.
    In row-major order that stencil is two contiguous index ranges: own cell + east, and
    north-west..north-east; the loop runs over cells so each cell works them out once.  The
    threads share out the strips of cell rows (``rows``, from ``strip_rows``), which hold equal
    numbers of grains: in cell order one thread got the packed lower half, the other the empty
    upper half."""
    for s in prange(rows.shape[0] - 1):
        for c in range(rows[s] * ncx, rows[s + 1] * ncx):
            _search_cell(c, x, y, radius, ncx, ncy, cell_start, skin, counts, buf, stride)


@numba.njit(inline="always", cache=True)
def _offer(j, xi, yi, rad_i, reach_i, x, y, radius, buf, base, k, last):
    """Grain ``j`` as a candidate of grain i (at ``xi, yi`` with radius ``rad_i`` [m], and
    ``reach_i`` = rad_i + skin): writes 2 j + touch to ``buf[base + min(k, last)]`` and
    returns k + 1 if j is within r_i + r_j + skin, else k.  Branch-free: always write, advance
    only for a candidate.  The touch test is the pair loop's arithmetic
    (``contact.pair_offset``, with grain i's values held in registers)."""
    u = numba.uint64(j)  # unsigned: no negative-index test on each access
    dx = x[u] - xi
    dy = y[u] - yi
    d2 = dx * dx + dy * dy
    rsum = rad_i + radius[u]
    cut = reach_i + radius[u]
    buf[base + min(k, last)] = 2 * j + (d2 < rsum * rsum)
    return k + (d2 < cut * cut)


@numba.njit(inline="always", cache=True)
def _search_cell(c, x, y, radius, ncx, ncy, cell_start, skin, counts, buf, stride):
    """The candidates of the grains of cell ``c`` (see ``_pairs_of``): the grain's own cell
    after it and the cell east (one index range), then the three cells north (another)."""
    cx = c % ncx
    cy = c // ncx
    end_a = cell_start[c + 2] if cx + 1 < ncx else cell_start[c + 1]
    lo_b = hi_b = 0
    if cy + 1 < ncy:
        row = (cy + 1) * ncx
        lo_b = cell_start[row + max(cx - 1, 0)]
        hi_b = cell_start[row + min(cx + 1, ncx - 1) + 1]
    for i in range(cell_start[c], cell_start[c + 1]):
        k = 0
        base = i * stride
        last = stride - 1
        xi = x[i]
        yi = y[i]
        rad_i = radius[i]
        reach_i = rad_i + skin
        for j in range(i + 1, end_a):
            k = _offer(j, xi, yi, rad_i, reach_i, x, y, radius, buf, base, k, last)
        for j in range(lo_b, hi_b):
            k = _offer(j, xi, yi, rad_i, reach_i, x, y, radius, buf, base, k, last)
        counts[i] = k


@kernel
def _compact(n, buf, stride, start, out):
    """Copy each grain's candidates from the strided buffer to the CSR array."""
    for i in prange(n):
        base = i * stride
        o = start[i]
        for k in range(start[i + 1] - o):
            out[o + k] = buf[base + k]


@kernel
def _compact_touching_first(n, buf, stride, start, out, apart):
    """``_compact`` for the grain-grain candidates of ``_pairs_of`` (entries 2 j + touch):
    each grain's candidates that touch now come first, then the others, each group in index
    order; ``apart[i]`` is the first of the others (the pair loop evaluates the first group
    without a branch: ``contact.strip_pairs``).  Branch-free too: whether a candidate
    touches is a coin toss."""
    for i in prange(n):
        base = i * stride
        m = start[i + 1] - start[i]
        touching = 0
        for k in range(m):
            touching += buf[base + k] & 1
        t = start[i]  # where the next touching candidate goes
        a = t + touching  # where the next one apart goes
        apart[i] = a
        for k in range(m):
            e = buf[base + k]
            touch = e & 1
            out[t if touch else a] = e >> 1
            t += touch
            a += 1 - touch


@kernel
def _wall_candidates_of(n, x, y, radius, w_lox, w_hix, w_loy, w_hiy, w_ax, w_ay, w_bx, w_by,
                        w_one_sided, skin, xmin, ymin, cell_size, ncx, ncy,
                        cell_wstart, cell_walls, bin_reach, gap, counts, buf, stride):
    """The walls near each grain (r + skin; 3r + skin for one-sided walls) among the active
    walls of its cell (``walls_by_cell``, which binned them with ``bin_reach``), written to
    ``buf[p*stride : p*stride+stride]`` like ``_pairs_of``; ``w_lo*, w_hi*`` are each wall's
    bounding box (a quick first test).

    ``gap[p]`` [m]: a lower bound on how far grain p is from touching any active wall that is
    not its candidate (at least ``skin``): the exact gap to the walls of its cell that are not
    candidates, 2r + skin for those the quick test rejects, and bin_reach - r for the walls
    not binned to its cell (their bounding box is farther than bin_reach)."""
    for p in prange(n):
        k = 0
        base = p * stride
        last = stride - 1
        reach = 3.0 * radius[p] + skin
        g = bin_reach - radius[p]
        c = cell_of(x[p], y[p], xmin, ymin, cell_size, ncx, ncy)
        for q in range(cell_wstart[c], cell_wstart[c + 1]):
            w = cell_walls[q]
            if (x[p] > w_lox[w] - reach and x[p] < w_hix[w] + reach
                    and y[p] > w_loy[w] - reach and y[p] < w_hiy[w] + reach):
                cx, cy, _ = closest_point(x[p], y[p], w_ax[w], w_ay[w], w_bx[w], w_by[w])
                cut = radius[p] * (3.0 if w_one_sided[w] else 1.0) + skin
                d2 = (x[p] - cx) ** 2 + (y[p] - cy) ** 2
                if d2 < cut * cut:
                    buf[base + min(k, last)] = w
                    k += 1
                else:
                    g = min(g, math.sqrt(d2) - radius[p])
            else:
                g = min(g, reach - radius[p])
        counts[p] = k
        gap[p] = g


@kernel
def _old_index(n, uid, slot_of_uid, old_of):
    """Each grain's index at the last build (-1 for a grain added since): one lookup per
    grain, so that the carry-over below does one per candidate, not two."""
    nslot = slot_of_uid.shape[0]
    for a in prange(n):
        old_of[a] = slot_of_uid[uid[a]] if uid[a] < nslot else -1


@kernel
def _carry_pairs(n, old_of, i_start, i_apart, pair_j, pair_fs, old_i_start, old_pair_j,
                 old_pair_fs):
    """Shear force of each new candidate that touches at the build (up to ``i_apart``) from
    the old list (0 for a new pair).  The others get 0 without a look: the step's next force
    evaluation, on these same positions, finds them apart and writes F_s = 0 without reading
    it (``contact.add_pair``), so their history is never used (in the bench silo's packed
    flow that is about 28 % of the candidates, in its loose state 92 %)."""
    for a in prange(n):
        oa = old_of[a]
        for k in range(i_apart[a], i_start[a + 1]):
            pair_fs[k] = 0.0
        for k in range(i_start[a], i_apart[a]):
            fs = 0.0
            if oa >= 0:
                ob = old_of[pair_j[k]]
                if ob >= 0:
                    lo = min(oa, ob)
                    hi = max(oa, ob)
                    for q in range(old_i_start[lo], old_i_start[lo + 1]):
                        if old_pair_j[q] == hi:
                            fs = old_pair_fs[q]
                            break
            pair_fs[k] = fs


@kernel
def _carry_walls(n, old_of, w_start, wc_w, wc_fs, wc_fn,
                 old_w_start, old_wc_w, old_wc_fs, old_wc_fn):
    """Shear and normal force ("the contact exists") of each new grain-wall candidate."""
    for a in prange(n):
        oa = old_of[a]
        for k in range(w_start[a], w_start[a + 1]):
            fs = 0.0
            fn = 0.0
            if oa >= 0:
                for q in range(old_w_start[oa], old_w_start[oa + 1]):
                    if old_wc_w[q] == wc_w[k]:
                        fs = old_wc_fs[q]
                        fn = old_wc_fn[q]
                        break
            wc_fs[k] = fs
            wc_fn[k] = fn


def _owners(start: np.ndarray) -> np.ndarray:
    """The grain of each entry of a CSR list grouped by grain (``start``: first entries)."""
    return np.repeat(np.arange(start.size - 1, dtype=INDEX), np.diff(start))


class NeighborList:
    """Verlet list of grain-grain and grain-wall candidates, with their contact state.

    Per grain pair k (grouped by i; grain i's candidates that touched at the build first, up
    to ``i_apart[i]``): ``pair_i[k] < pair_j[k]``, shear force ``pair_fs`` [N] (history) and
    normal force ``pair_fn`` [N] of the last step; ``strip_start`` cuts the
    grains into strips of whole cell rows (``strip_rows``, ``first_grains``), shared out
    among the threads by ``blocks``.  Per grain-wall candidate k (grouped by grain):
    ``wc_i, wc_w``, and ``wc_fs, wc_fn, wc_fx, wc_fy`` likewise (force on the grain).
    """

    def __init__(self, skin: float) -> None:
        if skin <= 0:
            raise ValueError("neighbour skin must be positive")
        self.skin = float(skin)
        self.rebuilds = 0
        empty_i = np.zeros(0, dtype=INDEX)
        self.pair_j = empty_i
        self.pair_fs = self.pair_fn = np.zeros(0)
        self.i_start = np.zeros(1, dtype=INDEX)
        self.i_apart = np.zeros(0, dtype=INDEX)
        self.strip_start = np.zeros(2, dtype=INDEX)
        self._blocks = np.zeros(2, dtype=INDEX)  # what ``blocks`` returns, cut for
        self._blocks_threads = 0  # this many threads (0: not cut since the last build)
        self.wc_w = empty_i
        self.wc_fs = self.wc_fn = self.wc_fx = self.wc_fy = np.zeros(0)
        self.w_start = np.zeros(1, dtype=INDEX)
        # for the test by cells (``list_validity``): each grain's gap to the walls it is not a
        # candidate of [m], the build's cell grid (xmin, ymin, cell size, ncx, ncy) and the
        # first grain of each cell (the grains are sorted by cell), scratch
        self.wall_gap = np.zeros(0)
        self.cell_grid = np.zeros(5)
        self.cell_start = np.zeros(0, dtype=INDEX)
        self.fast = np.zeros(0, dtype=INDEX)  # grains that moved skin/2 or more, per run
        self.report = np.zeros((0, 8))  # the leap-frog's report of the last step, per run
        self.slot_of_uid = np.zeros(0, dtype=np.int64)
        self._pair_i: np.ndarray | None = empty_i
        self._wc_i: np.ndarray | None = empty_i
        # room per grain in the search buffers (grows when a grain needs more)
        self._pair_stride = 12
        self._wall_stride = 2
        self._buf = np.zeros(0, dtype=INDEX)

    def to_lanes(self) -> None:
        """Copy the arrays the step streams beside the grains' into their lanes
        (``engine/lanes.py``), after they were replaced wholesale (a checkpoint's restore)."""
        self.pair_fs = lanes.copy(self.pair_fs, lanes.PAIR_FS_LANE)
        self.pair_fn = lanes.copy(self.pair_fn, lanes.PAIR_FN_LANE)
        self.wall_gap = lanes.copy(self.wall_gap, lanes.WALL_GAP_LANE)

    # first grain of each candidate, expanded from the CSR starts on demand (measurements only;
    # the step works from the CSR starts)
    @property
    def pair_i(self) -> np.ndarray:
        if self._pair_i is None:
            self._pair_i = _owners(self.i_start)
        return self._pair_i

    @property
    def wc_i(self) -> np.ndarray:
        if self._wc_i is None:
            self._wc_i = _owners(self.w_start)
        return self._wc_i

    # what a checkpoint leaves out: the expansions above (remade from the CSR starts) and the
    # search's scratch buffer (overwritten at every build)
    NOT_STATE = ("_pair_i", "_wc_i", "_buf")

    def forget_derived(self) -> None:
        """Drop the expansions of ``pair_i`` and ``wc_i`` (after a build or a restore)."""
        self._pair_i = self._wc_i = None

    def step_report(self, threads: int) -> np.ndarray:
        """Rows for the leap-frog's report of each step, one per run of strips of
        ``blocks(threads)`` (``integrate.walls_and_leapfrog``); the last step's report stays
        here (and in checkpoints) for the list test that follows it."""
        rows = self.blocks(threads).shape[0] - 1
        if self.report.shape[0] != rows:
            self.report = np.zeros((rows, 8))
        return self.report

    def blocks(self, threads: int) -> np.ndarray:
        """The strips cut into one run per thread (``thread_blocks``), worked out once per
        list build (and again if the thread count changes)."""
        if threads != self._blocks_threads:
            self._blocks = thread_blocks(self.strip_start, self.i_start, threads)
            self._blocks_threads = threads
        return self._blocks

    def _strided(self, search, n, args, name, threads, compact=None):
        """Run a search kernel that writes up to ``stride`` entries per grain into a strided
        buffer (widening it and searching again if a grain had more), then compact the entries
        to CSR form (``compact(n, buf, stride, start, out)``, ``_compact`` by default):
        returns (start, entries)."""
        while True:
            stride = getattr(self, name)
            if self._buf.size < n * stride:
                self._buf = np.empty(n * stride, dtype=INDEX)
            counts = np.empty(n, dtype=np.int64)
            search.pick(n, threads)(*args, counts, self._buf, stride)
            most = int(counts.max()) if n else 0
            if most <= stride:
                break
            setattr(self, name, most + 4)  # a crowded grain: widen the buffer and search again
        total = np.cumsum(counts)
        if n and total[-1] > np.iinfo(INDEX).max:
            raise UnstableRunError(f"{int(total[-1])} contact candidates: more than 32-bit "
                                   "indices hold (grains crowded together: unstable run?)")
        start = np.zeros(n + 1, dtype=INDEX)
        start[1:] = total
        out = np.empty(int(start[-1]), dtype=INDEX)
        (compact or _compact.pick(n, threads))(n, self._buf, stride, start, out)
        return start, out

    def rebuild(self, particles: Particles, walls: Walls) -> None:
        """Sort the grains by cell, list the candidates, carry the contact history over."""
        p = particles
        n = p.n
        threads = numba.get_num_threads()  # once: each kernel below picks its variant by it
        x, y, radius = p.view("x"), p.view("y"), p.view("radius")
        r_max = float(radius.max()) if n else 0.0
        cell_size = 2.0 * (r_max if n else 1.0) + self.skin
        if n:
            xmin, xmax = float(x.min()), float(x.max())
            ymin, ymax = float(y.min()), float(y.max())
        else:
            xmin = xmax = ymin = ymax = 0.0
        if not np.isfinite(xmax - xmin + ymax - ymin):
            raise UnstableRunError("non-finite extent of the grain positions: the run is "
                                   "unstable")
        ncx = int((xmax - xmin) / cell_size) + 1
        ncy = int((ymax - ymin) / cell_size) + 1
        if ncx * ncy > _MAX_CELLS_PER_GRAIN * max(n, 1) + 4096:
            raise UnstableRunError(
                f"grains spread over {xmax - xmin:.3g} m x {ymax - ymin:.3g} m: a grain has "
                "escaped the domain (unstable run?)"
            )
        cell_start, members = cell_list(n, x, y, xmin, ymin, cell_size, ncx, ncy)
        # sort the grains by cell; forces are recomputed by the step and the references reset
        p.permute(members, skip=("fx", "fy", "torque", "x_ref", "y_ref"), threads=threads)
        x, y, radius, uid = p.view("x"), p.view("y"), p.view("radius"), p.view("uid")

        rows = strip_rows(cell_start, ncx, ncy)
        if 2 * n > np.iinfo(INDEX).max:  # the search writes 2 j + touch (``_pairs_of``)
            raise ValueError(f"{n} grains: more than the 32-bit candidate lists hold")
        i_apart = np.empty(n, dtype=INDEX)
        i_start, pair_j = self._strided(
            _pairs_of, n,
            (n, x, y, radius, xmin, ymin, cell_size, ncx, ncy, cell_start, rows, self.skin),
            "_pair_stride", threads,
            lambda *csr: _compact_touching_first.pick(n, threads)(*csr, i_apart))
        old_of = np.empty(n, dtype=INDEX)
        _old_index.pick(n, threads)(n, uid, self.slot_of_uid, old_of)
        pair_fs = lanes.empty(pair_j.size, lanes.PAIR_FS_LANE)
        _carry_pairs.pick(n, threads)(n, old_of, i_start, i_apart, pair_j, pair_fs,
                                      self.i_start, self.pair_j, self.pair_fs)

        wb = walls
        w_box = (np.minimum(wb.ax, wb.bx), np.maximum(wb.ax, wb.bx),
                 np.minimum(wb.ay, wb.by), np.maximum(wb.ay, wb.by))
        bin_reach = 3.0 * r_max + self.skin
        cell_wstart, cell_walls = walls_by_cell(*w_box, wb.active, bin_reach,
                                                xmin, ymin, cell_size, ncx, ncy)
        wall_gap = lanes.empty(n, lanes.WALL_GAP_LANE)
        w_start, wc_w = self._strided(
            _wall_candidates_of, n,
            (n, x, y, radius, *w_box, wb.ax, wb.ay, wb.bx, wb.by, wb.one_sided,
             self.skin, xmin, ymin, cell_size, ncx, ncy, cell_wstart, cell_walls, bin_reach,
             wall_gap),
            "_wall_stride", threads)
        wc_fs = np.empty(wc_w.size)
        wc_fn = np.empty(wc_w.size)
        _carry_walls.pick(n, threads)(n, old_of, w_start, wc_w, wc_fs, wc_fn,
                             self.w_start, self.wc_w, self.wc_fs, self.wc_fn)

        self.i_start, self.i_apart, self.pair_j, self.pair_fs = i_start, i_apart, pair_j, pair_fs
        self.pair_fn = lanes.zeros(pair_j.size, lanes.PAIR_FN_LANE)
        self.strip_start = first_grains(cell_start, ncx, rows)
        self._blocks_threads = 0  # to be cut again
        self.w_start, self.wc_w, self.wc_fs, self.wc_fn = w_start, wc_w, wc_fs, wc_fn
        self.wc_fx = np.zeros(wc_w.size)
        self.wc_fy = np.zeros(wc_w.size)
        self.wall_gap = wall_gap
        self.cell_grid = np.array([xmin, ymin, cell_size, ncx, ncy], dtype=float)
        # the test by cells needs each cell's grains (off until the next build if there are
        # many more cells than grains)
        many = ncx * ncy > CELL_TEST_MAX_CELLS_PER_GRAIN * max(n, 1)
        self.cell_start = np.zeros(0, dtype=INDEX) if many else cell_start.astype(INDEX)
        if self.fast.shape[0] < p.capacity:
            self.fast = np.zeros(p.capacity, dtype=INDEX)  # (saved: no stray bytes in a file)
        self.forget_derived()  # expanded on demand (measurements only)

        slot = np.full(p.next_uid, -1, dtype=np.int64)
        slot[uid] = np.arange(n, dtype=np.int64)
        self.slot_of_uid = slot
        p.x_ref[:n] = x
        p.y_ref[:n] = y
        self.rebuilds += 1
