"""Arrays placed so that the step's parallel streams do not share an L1 cache set.

The step reads and writes many arrays at the same index: the leap-frog about a dozen
per-grain arrays at grain i, the pair loop seven at grain i and seven at its candidates.
An L1 data cache of 32 KB with 8 ways and 64-byte lines (the AMD EPYC cores this project
is measured on, and most x86 cores) has 32768 / (8 x 64) = 64 sets, chosen by address bits
6-11, so two arrays whose starts are equal modulo 4 KB put element i in the same set. glibc
serves every allocation above its mmap threshold (128 KB to start with: numpy arrays of
16,384 or more float64) with fresh pages, and numpy's data then starts 16 bytes into a page:
every large array starts at the same offset modulo 4 KB. Ten or more streams then compete
for the 8 ways of one set, and a line is evicted before its 8 grains are used.

Measured (commit 033e476, ``docs/performance.md``, 1 thread): in the packed scaling silo
the step at 1e5-1e6 grains cost 72-83 core-ns per particle-step with the arrays in one set
and 54-61 in lanes, against 50-52 at 1e4 grains (arrays below 128 KB, which lay at
scattered offsets on the heap before the lanes too).  This is the cache-set conflict that
processor optimization manuals warn of for arrays a multiple of 4 KB apart (Intel 64 and
IA-32 Architectures Optimization Reference Manual, on 4K aliasing and cache associativity).

``empty(n, lane)`` starts an array ``lane x LANE_BYTES`` past a 4 KB boundary (modulo 4 KB).
``LANE_BYTES`` is 5 lines, odd in lines, so lanes 0-63 fall in 64 different sets.  Each
array holds 4 KB more than it needs (the room to move its start); the values and the
arithmetic are untouched, so a run gives the same bits whatever the lanes.
"""

from __future__ import annotations

import numpy as np

PAGE_BYTES = 4096  # the span of addresses over which the L1 sets repeat (64 sets x 64 B)
LINE_BYTES = 64
LANE_BYTES = 5 * LINE_BYTES  # odd in lines: lanes 0 ... 63 start in 64 different sets

# lanes of the neighbour list's arrays (the grains' fields take lanes 0 ... 13, in the order
# of ``particles.FIELDS``)
WALL_GAP_LANE = 20
PAIR_FS_LANE = 24
PAIR_FN_LANE = 28


def empty(n: int, lane: int, dtype=np.float64) -> np.ndarray:
    """An uninitialised array of ``n`` values whose start lies ``lane x LANE_BYTES`` past a
    4 KB boundary (modulo 4 KB): C-contiguous, writeable, aligned to a cache line."""
    dtype = np.dtype(dtype)
    nbytes = int(n) * dtype.itemsize
    raw = np.empty(nbytes + PAGE_BYTES, dtype=np.uint8)
    start = (lane * LANE_BYTES - raw.ctypes.data) % PAGE_BYTES
    return raw[start:start + nbytes].view(dtype)


def zeros(n: int, lane: int, dtype=np.float64) -> np.ndarray:
    """``empty`` filled with zeros."""
    out = empty(n, lane, dtype)
    out[:] = 0
    return out


def copy(values: np.ndarray, lane: int) -> np.ndarray:
    """A copy of the 1-D array ``values`` in ``lane``."""
    out = empty(values.shape[0], lane, values.dtype)
    out[:] = values
    return out
