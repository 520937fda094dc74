"""Files written whole or not at all (docs/reliability.md: an interrupted run loses nothing it
had written).

Every file of a results folder is written to a temporary name beside it, flushed to the disk
and renamed over the old one (``os.replace``, atomic on POSIX), so a reader, or a run
interrupted at any moment, finds either the old file or the new one.  If writing fails or is
interrupted, the temporary file is removed.
"""

from __future__ import annotations

import errno
import io
import os
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Any


def fsync_path(path: Path) -> None:
    """Flush a written file (or a folder's entries) to the disk."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


@contextmanager
def atomic_file(path: Path | str, temporary: Path | None = None) -> Iterator[Path]:
    """Yield a temporary name in the folder of ``path`` (``temporary``, where a writer needs
    another: ffmpeg picks a video's container by its suffix); on success, fsync it and rename
    it onto ``path`` (``os.replace``), so ``path`` is always either the old or the new file.
    On any exception (KeyboardInterrupt included) the temporary file is removed."""
    path = Path(path)
    if path.is_dir():  # say so before the work, naming the file asked for, not the temporary
        raise IsADirectoryError(errno.EISDIR, "a folder is in the way of the file", str(path))
    tmp = temporary if temporary is not None else path.with_name(f".{path.name}.tmp")
    try:
        yield tmp
        fsync_path(tmp)
        os.replace(tmp, path)
    except BaseException as exc:
        with suppress(OSError):
            tmp.unlink()
        if isinstance(exc, OSError) and not exc.filename:  # (a full disk's write names no
            exc.filename = str(path)                        # file: the one asked for)
        raise
    with suppress(OSError):  # make the rename itself durable (not possible everywhere)
        fsync_path(path.parent)


def write_atomic(path: Path | str, data: bytes | str) -> None:
    """Write ``data`` (text as UTF-8) to ``path`` through ``atomic_file``."""
    raw = data.encode("utf-8") if isinstance(data, str) else data
    with atomic_file(path) as tmp:
        tmp.write_bytes(raw)


@contextmanager
def atomic_hdf5(path: Path | str, **options: Any) -> Iterator[Any]:
    """Yield a new ``h5py.File`` (``options``: h5py.File's keywords) built in memory; on
    success write its bytes to ``path`` through ``atomic_file``.

    The HDF5 library never writes to the disk itself: a write that fails (a full disk, a file
    size limit) is an OSError from Python's own write, which a run can survive.  Written by
    HDF5 into the temporary file, such a failure left the library's state broken and crashed
    the process (a segmentation fault) in the middle of a save."""
    import h5py

    with atomic_file(path) as tmp:
        image = io.BytesIO()
        with h5py.File(image, "w", **options) as h5:
            yield h5
        tmp.write_bytes(image.getbuffer())
