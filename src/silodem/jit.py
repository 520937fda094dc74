"""The one place that holds the numba flags every kernel uses (PySDM's habit).

* ``cache=True``: compiled kernels are stored next to the sources, so only the first run of a
  fresh install pays for compilation.
* ``fastmath=False`` and ``error_model="numpy"``: IEEE arithmetic, so that a run is
  bit-reproducible from its seed for a given thread count.
"""

from __future__ import annotations

import numba

FLAGS = {"cache": True, "fastmath": False, "error_model": "numpy"}

njit = numba.njit(**FLAGS)
"""Decorator for serial kernels."""

njit_parallel = numba.njit(parallel=True, **FLAGS)
"""Decorator for kernels whose outer loop is a race-free ``numba.prange``."""

prange = numba.prange
