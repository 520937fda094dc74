"""Frames on disk: the segment files behind results.h5 ``/frames`` (docs/output.md).

A run does not hold all its frames in memory.  ``FramesRecorder`` hands them over in batches
(at every save of results.h5, and whenever the frames it holds pass ``PENDING_BYTES``), and
each batch becomes one segment file ``DIR/frames/frames-FIRST-LAST.h5`` (the numbers of its
first and last frame, from 0): a ``/frames`` group of its own frames in the layout of
docs/output.md, written whole or not at all (``atomic_hdf5``).

results.h5 ``/frames`` holds the frames' index itself (time, step, phase, walls in place,
offsets) and each table column (``particles/x`` ...) as an HDF5 *virtual dataset* that joins
the segments' columns end to end, so that h5py reads it as one array.  The segments' names
are relative: HDF5 looks for them beside results.h5, so the results folder may be moved or
copied whole; results.h5 alone, without ``frames/``, has the index but not the tables
(:func:`missing_segments` says which file is missing).

Segments are only ever added.  A checkpoint lists the segments written before it.  A run
resumed from it writes its next batch under the name the batch's frames give; a file of that
name left by the killed process holds the same frames (the run is deterministic) and is
replaced.  Files the killed process wrote after its last checkpoint that no save lists any
more are removed after the next save (``remove_unlisted``).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from silodem.atomic import atomic_hdf5

if TYPE_CHECKING:
    import h5py

FOLDER = "frames"  # beside results.h5
PENDING_BYTES = 64e6  # a recorder holding frames of more than this writes them out [B]
_NAME = re.compile(r"frames-\d{6,}-\d{6,}\.h5")


def segment_name(first: int, last: int) -> str:
    """The file name of the segment holding frames ``first`` to ``last`` (inclusive)."""
    return f"frames-{first:06d}-{last:06d}.h5"


class FrameStore:
    """The segment files of one run, in ``folder`` (``DIR/frames``).

    ``names[k]`` is segment k's file, ``rows[k]`` its row counts (grains, contacts, wall
    contacts); together they give the place of its rows in the joined columns."""

    def __init__(self, folder: Path | str) -> None:
        self.folder = Path(folder)
        self.names: list[str] = []
        self.rows = np.zeros((0, 3), dtype=np.int64)
        self.frames = 0  # frames in the segments

    def append(self, write: Any, count: int, rows: tuple[int, int, int]) -> None:
        """Write the next segment, ``count`` frames with ``rows`` table rows: ``write(group)``
        fills its ``/frames`` group (``frames.write_frames``)."""
        name = segment_name(self.frames, self.frames + count - 1)
        self.folder.mkdir(parents=True, exist_ok=True)
        with atomic_hdf5(self.folder / name) as h5:
            write(h5.create_group("frames"))
        self.names.append(name)
        self.rows = np.vstack([self.rows, np.asarray(rows, dtype=np.int64)[None, :]])
        self.frames += count

    def link(self, group: h5py.Group, tables: dict[str, dict[str, tuple[type, str]]]) -> None:
        """Into ``group`` (results.h5 ``/frames``): every column of ``tables`` (name: dtype,
        unit) as a virtual dataset joining the segments' columns, with its ``unit``; and the
        attribute ``segments`` (the files, relative to results.h5's folder)."""
        import h5py

        group.attrs["segments"] = [f"{FOLDER}/{name}" for name in self.names]
        for t, (table, fields) in enumerate(tables.items()):
            total = int(self.rows[:, t].sum())
            for key, (dtype, unit) in fields.items():
                layout = h5py.VirtualLayout(shape=(total,), dtype=dtype)
                at = 0
                for name, n in zip(self.names, self.rows[:, t].tolist(), strict=True):
                    if n:
                        layout[at:at + n] = h5py.VirtualSource(
                            f"{FOLDER}/{name}", f"frames/{table}/{key}", shape=(n,))
                    at += n
                group.create_virtual_dataset(f"{table}/{key}", layout).attrs["unit"] = unit

    def remove_unlisted(self) -> None:
        """Remove segment files in the folder that this store does not list (written by a
        process killed after its last checkpoint); other files are left alone."""
        if not self.folder.is_dir():
            return
        keep = set(self.names)
        for path in self.folder.iterdir():
            if _NAME.fullmatch(path.name) and path.name not in keep:
                path.unlink(missing_ok=True)

    def state(self) -> dict[str, Any]:
        return {"names": np.array(self.names, dtype=str), "rows": self.rows.copy(),
                "frames": self.frames}

    def restore(self, state: dict[str, Any]) -> None:
        """Inverse of ``state``; a listed segment file that is not there is a ValueError."""
        self.names = [str(n) for n in np.asarray(state["names"]).tolist()]
        self.rows = np.asarray(state["rows"], dtype=np.int64).reshape(-1, 3)
        self.frames = int(state["frames"])
        gone = [n for n in self.names if not (self.folder / n).is_file()]
        if gone:
            raise ValueError(f"the saved frames' file {self.folder / gone[0]} is missing "
                             f"({len(gone)} of {len(self.names)} missing)")


def clear(folder: Path) -> None:
    """Remove every segment file from ``folder`` (a new run in a used results folder)."""
    if folder.is_dir():
        for path in folder.iterdir():
            if _NAME.fullmatch(path.name):
                path.unlink(missing_ok=True)


def missing_segments(results: Path | str, group: h5py.Group) -> list[str]:
    """The segment files that results.h5 ``/frames`` (``group``) joins and that are not
    beside ``results``."""
    folder = Path(results).parent
    return [str(s) for s in group.attrs.get("segments", [])
            if not (folder / str(s)).is_file()]
