"""Neighbour search: a cell list builds a Verlet list of candidate contacts with a skin.

At each rebuild the grains are sorted by cell (spatial sorting: neighbours sit close in memory),
then every pair closer than r_i + r_j + skin is listed once (i < j), and every grain closer than
r + skin to an active wall gets a grain-wall candidate.  The list stays valid while no grain has
moved more than skin/2 since the rebuild (two grains then close by at most ``skin``); the
integrator reports the largest displacement and the simulation rebuilds when it passes skin/2.

Contact history (the shear force) is keyed by the permanent grain ``uid`` (and wall index), so
it survives the rebuild, the reordering and the compaction of the arrays: the old keys are sorted
once and each new candidate finds its history by binary search, O(P log P).
"""

from __future__ import annotations

import numpy as np

from silodem.engine.contact import closest_point
from silodem.errors import UnstableRunError
from silodem.jit import kernel, njit, prange

UID_SPAN = np.int64(1) << np.int64(31)  # pair key = min_uid * UID_SPAN + max_uid
WALL_SPAN = np.int64(1024)  # wall contact key = uid * WALL_SPAN + wall index
_MAX_CELLS_PER_GRAIN = 64


@njit
def cell_sort(n, x, y, xmin, ymin, cell_size, ncx, ncy):
    """Counting sort of the grains by cell (row-major).  Returns ``order`` (new index k holds
    old index order[k]) and ``cell_start`` (grains of cell c are order[cell_start[c]:...])."""
    ncell = ncx * ncy
    cell = np.empty(n, dtype=np.int64)
    count = np.zeros(ncell + 1, dtype=np.int64)
    for p in range(n):
        cx = min(max(int((x[p] - xmin) / cell_size), 0), ncx - 1)
        cy = min(max(int((y[p] - ymin) / cell_size), 0), ncy - 1)
        c = cy * ncx + cx
        cell[p] = c
        count[c + 1] += 1
    for c in range(ncell):
        count[c + 1] += count[c]
    cell_start = count.copy()
    fill = count[:-1].copy()
    order = np.empty(n, dtype=np.int64)
    for p in range(n):
        c = cell[p]
        order[fill[c]] = p
        fill[c] += 1
    return order, cell_start


@kernel
def _pairs_of(n, x, y, radius, uid, xmin, ymin, cell_size, ncx, ncy, cell_start, skin,
              counts, pair_j, pair_key, offsets, fill):
    """Count (fill=False) or write (fill=True) the candidates j > i of every grain i; the grains
    must already be in cell order so that cell c holds indices cell_start[c]:cell_start[c+1]."""
    for i in prange(n):
        cx = min(max(int((x[i] - xmin) / cell_size), 0), ncx - 1)
        cy = min(max(int((y[i] - ymin) / cell_size), 0), ncy - 1)
        k = offsets[i] if fill else 0
        for ny in range(max(cy - 1, 0), min(cy + 2, ncy)):
            for nx in range(max(cx - 1, 0), min(cx + 2, ncx)):
                c = ny * ncx + nx
                for j in range(max(cell_start[c], i + 1), cell_start[c + 1]):
                    dx = x[j] - x[i]
                    dy = y[j] - y[i]
                    cut = radius[i] + radius[j] + skin
                    if dx * dx + dy * dy < cut * cut:
                        if fill:
                            pair_j[k] = j
                            a = min(uid[i], uid[j])
                            b = max(uid[i], uid[j])
                            pair_key[k] = a * UID_SPAN + b
                        k += 1
        if not fill:
            counts[i] = k


@njit
def _csr_by(index, n):
    """For each value v in 0..n-1 the positions where ``index`` equals v (counting sort)."""
    start = np.zeros(n + 1, dtype=np.int64)
    for k in range(index.shape[0]):
        start[index[k] + 1] += 1
    for v in range(n):
        start[v + 1] += start[v]
    fill = start[:-1].copy()
    out = np.empty(index.shape[0], dtype=np.int64)
    for k in range(index.shape[0]):
        v = index[k]
        out[fill[v]] = k
        fill[v] += 1
    return start, out


@njit
def _wall_candidates(n, x, y, radius, uid, w_ax, w_ay, w_bx, w_by, w_active, w_one_sided, skin):
    """Grain-wall pairs closer than r + skin (3r + skin for one-sided walls, whose contacts may
    persist with the centre pressed behind the line)."""
    count = 0
    for p in range(n):
        for w in range(w_ax.shape[0]):
            if w_active[w]:
                cx, cy, _ = closest_point(x[p], y[p], w_ax[w], w_ay[w], w_bx[w], w_by[w])
                cut = radius[p] * (3.0 if w_one_sided[w] else 1.0) + skin
                if (x[p] - cx) ** 2 + (y[p] - cy) ** 2 < cut * cut:
                    count += 1
    wc_i = np.empty(count, dtype=np.int64)
    wc_w = np.empty(count, dtype=np.int64)
    wc_key = np.empty(count, dtype=np.int64)
    k = 0
    for p in range(n):
        for w in range(w_ax.shape[0]):
            if w_active[w]:
                cx, cy, _ = closest_point(x[p], y[p], w_ax[w], w_ay[w], w_bx[w], w_by[w])
                cut = radius[p] * (3.0 if w_one_sided[w] else 1.0) + skin
                if (x[p] - cx) ** 2 + (y[p] - cy) ** 2 < cut * cut:
                    wc_i[k] = p
                    wc_w[k] = w
                    wc_key[k] = uid[p] * WALL_SPAN + w
                    k += 1
    return wc_i, wc_w, wc_key


@kernel
def transfer_history(old_key, old_val, new_key, new_val):
    """new_val[k] = old_val of the old candidate with the same key, else 0."""
    order = np.argsort(old_key)
    sorted_key = old_key[order]
    m = sorted_key.shape[0]
    for k in prange(new_key.shape[0]):
        pos = np.searchsorted(sorted_key, new_key[k])
        if pos < m and sorted_key[pos] == new_key[k]:
            new_val[k] = old_val[order[pos]]
        else:
            new_val[k] = 0.0


class NeighborList:
    """Verlet list of grain-grain and grain-wall candidates, with their contact state.

    Per grain pair k: ``pair_i[k] < pair_j[k]``, shear force ``pair_fs`` [N] (history), normal
    force ``pair_fn`` [N] and force on j ``pair_fx, pair_fy`` [N] of the last step.
    Per grain-wall candidate k: ``wc_i, wc_w``, and ``wc_fs, wc_fn, wc_fx, wc_fy`` likewise
    (force on the grain).
    """

    def __init__(self, skin: float) -> None:
        if skin <= 0:
            raise ValueError("neighbour skin must be positive")
        self.skin = float(skin)
        self.rebuilds = 0
        empty_i = np.zeros(0, dtype=np.int64)
        self.pair_i = self.pair_j = self.pair_key = empty_i
        self.pair_fs = self.pair_fn = self.pair_fx = self.pair_fy = np.zeros(0)
        self.i_start = self.j_start = np.zeros(1, dtype=np.int64)
        self.j_pairs = empty_i
        self.wc_i = self.wc_w = self.wc_key = empty_i
        self.wc_fs = self.wc_fn = self.wc_fx = self.wc_fy = np.zeros(0)
        self.w_start = np.zeros(1, dtype=np.int64)

    def rebuild(self, particles, walls) -> None:
        """Sort the grains by cell, list the candidates, carry the contact history over."""
        p = particles
        n = p.n
        x, y, radius = p.view("x"), p.view("y"), p.view("radius")
        cell_size = 2.0 * (float(radius.max()) if n else 1.0) + self.skin
        if n:
            xmin, xmax = float(x.min()), float(x.max())
            ymin, ymax = float(y.min()), float(y.max())
        else:
            xmin = xmax = ymin = ymax = 0.0
        ncx = int((xmax - xmin) / cell_size) + 1
        ncy = int((ymax - ymin) / cell_size) + 1
        if ncx * ncy > _MAX_CELLS_PER_GRAIN * max(n, 1) + 4096:
            raise UnstableRunError(
                f"grains spread over {xmax - xmin:.3g} m x {ymax - ymin:.3g} m: a grain has "
                "escaped the domain (unstable run?)"
            )
        order, cell_start = cell_sort(n, x, y, xmin, ymin, cell_size, ncx, ncy)
        p.permute(order)
        x, y, radius, uid = p.view("x"), p.view("y"), p.view("radius"), p.view("uid")

        counts = np.zeros(n, dtype=np.int64)
        dummy = np.zeros(0, dtype=np.int64)
        pairs_of = _pairs_of.pick(n)
        pairs_of(n, x, y, radius, uid, xmin, ymin, cell_size, ncx, ncy, cell_start, self.skin,
                 counts, dummy, dummy, dummy, False)
        i_start = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(counts, out=i_start[1:])
        npairs = int(i_start[-1])
        pair_j = np.empty(npairs, dtype=np.int64)
        pair_key = np.empty(npairs, dtype=np.int64)
        pairs_of(n, x, y, radius, uid, xmin, ymin, cell_size, ncx, ncy, cell_start, self.skin,
                 counts, pair_j, pair_key, i_start, True)
        pair_i = np.repeat(np.arange(n, dtype=np.int64), counts)
        pair_fs = np.empty(npairs)
        transfer_history.pick(n)(self.pair_key, self.pair_fs, pair_key, pair_fs)
        self.pair_i, self.pair_j, self.pair_key, self.pair_fs = pair_i, pair_j, pair_key, pair_fs
        self.pair_fn = np.zeros(npairs)
        self.pair_fx = np.zeros(npairs)
        self.pair_fy = np.zeros(npairs)
        self.i_start = i_start
        self.j_start, self.j_pairs = _csr_by(pair_j, n)

        wc_i, wc_w, wc_key = _wall_candidates(n, x, y, radius, uid, walls.ax, walls.ay,
                                              walls.bx, walls.by, walls.active, walls.one_sided,
                                              self.skin)
        wc_fs = np.empty(wc_i.shape[0])
        wc_fn = np.empty(wc_i.shape[0])
        transfer_history.pick(n)(self.wc_key, self.wc_fs, wc_key, wc_fs)
        transfer_history.pick(n)(self.wc_key, self.wc_fn, wc_key, wc_fn)  # "contact exists"
        self.wc_i, self.wc_w, self.wc_key, self.wc_fs = wc_i, wc_w, wc_key, wc_fs
        self.wc_fn = wc_fn
        self.wc_fx = np.zeros(wc_i.shape[0])
        self.wc_fy = np.zeros(wc_i.shape[0])
        self.w_start = np.searchsorted(wc_i, np.arange(n + 1)).astype(np.int64)

        p.x_ref[:n] = x
        p.y_ref[:n] = y
        self.rebuilds += 1
