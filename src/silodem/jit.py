"""The one place that holds the numba flags every kernel uses (PySDM's habit).

* ``cache=True``: compiled kernels are stored next to the sources, so only the first run of a
  fresh install pays for compilation.
* ``fastmath=False`` and ``error_model="numpy"``: IEEE arithmetic, so that a run is
  bit-reproducible from its seed.
* Kernels whose outer loop is a ``prange`` are compiled twice, serial and parallel
  (``@kernel``); ``pick`` takes the parallel one only for systems large enough to pay for the
  threads.  Both give the same bits: every parallel loop writes disjoint entries, and sums run
  in a fixed order.
"""

from __future__ import annotations

import hashlib
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numba

from silodem.atomic import write_atomic

FLAGS = {"cache": True, "fastmath": False, "error_model": "numpy"}
KERNEL_SOURCES = ("engine/*.py", "jit.py", "measure/gaussian.py")  # every file with kernels
STAMP_NAME = "kernel-sources.sha256"
CACHE_STAMP = "engine/__pycache__/" + STAMP_NAME  # where it is in the usual in-tree cache


def _cache_dir(source: Path) -> Path:
    """The folder where numba caches the kernels of ``source``: the first of numba's own
    cache locators that accepts it, as numba picks one (``NUMBA_CACHE_DIR`` if set, else
    ``__pycache__`` beside the file, else a user-wide folder where that is read-only)."""
    try:
        from numba.core import caching
        impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl
        locators = list(impl._locator_classes)
    except (ImportError, AttributeError):
        return source.parent / "__pycache__"
    for locator in locators:
        try:  # a locator reads only the file's path; any function stands in for the kernel
            found = locator.from_function(_cache_dir, str(source))
        except Exception:  # noqa: BLE001, S112 - a locator that does not apply
            continue
        if found is not None:
            return Path(found.get_cache_path())
    return source.parent / "__pycache__"


def clear_stale_caches(root: Path = Path(__file__).parent) -> bool:
    """Remove the package's cached kernels when any kernel source changed since they were
    stored; True if it removed them.

    numba checks a cached kernel only against the stamp of the file that defines it (numba's
    docs, "Cache invalidation"), but a kernel inlines what it calls from other files: the
    compiled step loop of simulation.py kept the old contact law of an edited contact.py.
    So the hash of all kernel sources is kept beside the caches, and a different hash clears
    them all.  The caches are looked for where numba keeps them (``NUMBA_CACHE_DIR``, the
    user-wide folder of a read-only install), and the hash is kept with the engine's; where
    none is writable nothing is done."""
    files = sorted(f for pattern in KERNEL_SOURCES for f in root.glob(pattern))
    if not files:
        return False
    digest = hashlib.sha256(b"".join(f.read_bytes() for f in files)).hexdigest()
    caches = {f.parent: _cache_dir(f) for f in files}  # numba's folder depends on the folder
    stamp = caches.get(root / "engine", next(iter(caches.values()))) / STAMP_NAME
    try:
        if stamp.read_text(encoding="ascii") == digest:
            return False
    except (OSError, UnicodeDecodeError):
        pass
    try:
        for cache in set(caches.values()):
            for stale in cache.glob("*.nb[ic]"):
                stale.unlink(missing_ok=True)
        stamp.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(stamp, digest)
    except OSError:
        return False
    return True


clear_stale_caches()
PARALLEL_MIN_GRAINS = 800  # below this, thread start-up costs more than it saves

njit = numba.njit(**FLAGS)
"""Decorator for serial helpers."""

prange = numba.prange


def _renamed(fn: types.FunctionType, suffix: str, names=None) -> types.FunctionType:
    """A copy of ``fn`` under another qualified name (so the compiled caches differ), with
    the global ``names`` bound to other objects if given."""
    scope = fn.__globals__ if names is None else {**fn.__globals__, **names}
    copy = types.FunctionType(fn.__code__, scope, fn.__name__ + suffix,
                              fn.__defaults__, fn.__closure__)
    copy.__qualname__ = fn.__qualname__ + suffix
    copy.__module__ = fn.__module__
    copy.__doc__ = fn.__doc__
    return copy


class Kernel:
    """A kernel compiled serial (``.serial``) and parallel (``.parallel``), on first use."""

    def __init__(self, fn: types.FunctionType, suffix: str = "", **names: Any) -> None:
        self.__doc__ = fn.__doc__
        self.__name__ = fn.__name__ + suffix
        self._fn = fn
        self.serial = numba.njit(**FLAGS)(_renamed(fn, suffix + "_serial", names or None))
        self.parallel = numba.njit(parallel=True, **FLAGS)(
            _renamed(fn, suffix + "_parallel", names or None))

    def variant(self, suffix: str, **names: Any) -> Kernel:
        """The same kernel compiled with the globals ``names`` bound to other values, which
        numba takes as compile-time constants (a switch such as ``HERTZ = True`` costs nothing
        in the loop, where a run-time flag let LLVM compute both sides of each branch)."""
        return Kernel(self._fn, suffix, **names)

    def pick(self, n: int, threads: int | None = None) -> Callable[..., Any]:
        """The variant for ``n`` grains with ``threads`` threads (default: numba's current
        count; asking numba costs ~2 us, so a caller that picks many kernels at once, like
        the list build, asks once and passes it)."""
        if n >= PARALLEL_MIN_GRAINS and (numba.get_num_threads() if threads is None
                                         else threads) > 1:
            return self.parallel
        return self.serial

    def __call__(self, *args: Any) -> Any:
        return self.serial(*args)


def kernel(fn: types.FunctionType) -> Kernel:
    """Decorator for kernels with a race-free ``prange`` outer loop."""
    return Kernel(fn)


def specialised(fn: types.FunctionType, suffix: str, **names: Any) -> Callable[..., Any]:
    """``fn`` compiled (``njit``) with the globals ``names`` bound to other objects, under the
    name ``fn.__name__ + suffix``: one loop written once, compiled over the serial kernels
    and once over the parallel ones, so that a serial run neither compiles nor loads the
    parallel ones (on a fresh install that was 7 s more for the first `silodem run`)."""
    return numba.njit(**FLAGS)(_renamed(fn, suffix, names))
