"""Frames: compact snapshots saved while a run goes, for animations, pictures and ParaView.

A frame holds the grains, the touching contacts with their forces, the walls in place, the
time and the phase.  The frames recorder (:mod:`silodem.silo.frame_store`) takes them as a
run goes and writes them to results.h5 ``/frames``, joined from segment files in
``DIR/frames/``.

Layout of ``/frames`` (docs/output.md): the frames are *concatenated*.  Frame ``k`` owns rows
``particle_offset[k]:particle_offset[k+1]`` of every ``particles/*`` array, rows
``contact_offset[k]:contact_offset[k+1]`` of ``contacts/*`` and rows
``wall_contact_offset[k]:wall_contact_offset[k+1]`` of ``wall_contacts/*``.  Contact indices
``i``, ``j`` and ``grain`` count from the first grain *of the frame*; ``wall`` indexes
``/walls``.  Floats are float32 (frames are for looking at; the exact states are the
``/settled`` and ``/final`` snapshots and the checkpoints).

:func:`read_frames` reads them back (NumPy arrays, a frame at a time) for notebooks and for
``silodem animate``.
"""

from __future__ import annotations

import math
import numbers
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from silodem.errors import one_line
from silodem.measure.stress import contact_points_walls
from silodem.silo.geometry import gate_shift
from silodem.silo.recorders import PHASE_CODES, PHASE_CODES_TEXT

if TYPE_CHECKING:
    import h5py

PHASE_NAMES = {code: name for name, code in PHASE_CODES.items()}
FOLDER = "frames"  # the segment files of results.h5 /frames, beside it (silo/frame_store.py)
BLOCK_BYTES = 64e6  # read_frames reads consecutive frames of up to this much at a time [B]

#: The arrays of a frame, their dtypes and units, by table.
FIELDS: dict[str, dict[str, tuple[type, str]]] = {
    "particles": {
        "x": (np.float32, "m"), "y": (np.float32, "m"),
        "vx": (np.float32, "m/s"), "vy": (np.float32, "m/s"),
        "omega": (np.float32, "rad/s"), "radius": (np.float32, "m"),
        "fx": (np.float32, "N"), "fy": (np.float32, "N"),  # resultant contact force (no gravity)
        "uid": (np.int64, "-"),
    },
    "contacts": {
        "i": (np.int32, "-"), "j": (np.int32, "-"),
        "fn": (np.float32, "N"), "fs": (np.float32, "N"),
    },
    "wall_contacts": {
        "grain": (np.int32, "-"), "wall": (np.int32, "-"),
        "fn": (np.float32, "N"), "fs": (np.float32, "N"),
    },
}
OFFSETS = {"particles": "particle_offset", "contacts": "contact_offset",
           "wall_contacts": "wall_contact_offset"}


@dataclass
class WallGeometry:
    """The wall segments of a silo: from (ax, ay) to (bx, by) [m]."""

    names: list[str]
    ax: np.ndarray
    ay: np.ndarray
    bx: np.ndarray
    by: np.ndarray

    def __len__(self) -> int:
        return len(self.names)

    @classmethod
    def of(cls, walls: Any) -> WallGeometry:
        """From an engine ``Walls`` object or results.h5's ``/walls`` group."""
        keys = ("ax", "ay", "bx", "by")
        if hasattr(walls, "names"):
            names = [str(n) for n in walls.names]
            coords = [np.asarray(getattr(walls, k), dtype=float).copy() for k in keys]
        else:
            names = [n.decode() if isinstance(n, bytes) else str(n) for n in walls["name"][()]]
            coords = [np.asarray(walls[k][()], dtype=float) for k in keys]
        return cls(names, *coords)

    def closest_points(self, wall: np.ndarray, x: np.ndarray, y: np.ndarray,
                       shift: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The point of segment ``wall[k]`` closest to ``(x[k], y[k])`` (a grain's contact),
        each wall moved by ``shift`` [m] in x (``Frames.wall_shift``) if given."""
        dx = np.zeros(len(self)) if shift is None else shift
        return contact_points_walls(x, y, np.arange(len(wall)), wall, self.ax + dx, self.ay,
                                    self.bx + dx, self.by)


@dataclass
class Frame:
    """One saved moment: arrays over the grains in the silo then (see ``FIELDS``)."""

    time: float  # [s]
    step: int
    phase: str  # "fill", "settle" or "discharge"
    particles: dict[str, np.ndarray]
    contacts: dict[str, np.ndarray]
    wall_contacts: dict[str, np.ndarray]
    walls_active: np.ndarray  # bool per wall

    @property
    def n(self) -> int:
        return int(self.particles["x"].shape[0])

    @property
    def nbytes(self) -> int:
        """Bytes of the frame's tables."""
        return sum(a.nbytes for table in (self.particles, self.contacts, self.wall_contacts)
                   for a in table.values())

    def coordination(self) -> np.ndarray:
        """Number of touching contacts of each grain, with grains and with walls [-]."""
        n = self.n
        c, w = self.contacts, self.wall_contacts
        return (np.bincount(c["i"], minlength=n) + np.bincount(c["j"], minlength=n)
                + np.bincount(w["grain"], minlength=n)).astype(np.int32)

    def force(self) -> np.ndarray:
        """Magnitude of the resultant contact force on each grain (gravity excluded) [N]."""
        return np.hypot(self.particles["fx"], self.particles["fy"])

    def normal_force_sum(self) -> np.ndarray:
        """Sum of the normal forces of each grain's contacts [N]: large along force chains."""
        n = self.n
        c, w = self.contacts, self.wall_contacts
        return (np.bincount(c["i"], weights=c["fn"], minlength=n)
                + np.bincount(c["j"], weights=c["fn"], minlength=n)
                + np.bincount(w["grain"], weights=w["fn"], minlength=n)).astype(np.float32)

    def speed(self) -> np.ndarray:
        """|v| of each grain [m/s]."""
        return np.hypot(self.particles["vx"], self.particles["vy"])


# --- the flat layout ----------------------------------------------------------------------
def frames_to_arrays(frames: list[Frame]) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {
        "time": np.array([f.time for f in frames], dtype=float),
        "step": np.array([f.step for f in frames], dtype=np.int64),
        "phase": np.array([PHASE_CODES[f.phase] for f in frames], dtype=np.int8),
    }
    n_walls = frames[0].walls_active.size if frames else 0
    out["walls_active"] = (np.stack([f.walls_active for f in frames]) if frames
                           else np.zeros((0, n_walls), dtype=bool))
    for table, fields in FIELDS.items():
        counts = [getattr(f, table)["fn" if table != "particles" else "x"].size for f in frames]
        out[OFFSETS[table]] = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        for key, (dt, _) in fields.items():
            parts = [getattr(f, table)[key] for f in frames]
            out[f"{table}/{key}"] = (np.concatenate(parts).astype(dt, copy=False) if parts
                                     else np.zeros(0, dtype=dt))
    return out


def frames_from_arrays(a: dict[str, np.ndarray]) -> list[Frame]:
    return [frame_at(a, k, a) for k in range(a["time"].shape[0])]


def frame_at(index: dict[str, np.ndarray], k: int, columns: dict[str, np.ndarray],
             first: int = 0, copy: bool = False) -> Frame:
    """Frame ``k`` of the layout: ``index`` holds the per-frame datasets (``INDEX_KEYS``),
    ``columns`` the table columns (``"particles/x"``...) from frame ``first``'s rows on;
    ``copy``: the frame's arrays are copies, not views of ``columns``."""
    tables = {}
    for table, fields in FIELDS.items():
        off = index[OFFSETS[table]]
        rows = slice(int(off[k] - off[first]), int(off[k + 1] - off[first]))
        tables[table] = {key: _array(columns[f"{table}/{key}"][rows], copy)
                         for key in fields}
    return Frame(float(index["time"][k]), int(index["step"][k]),
                 PHASE_NAMES[int(index["phase"][k])], tables["particles"], tables["contacts"],
                 tables["wall_contacts"], np.asarray(index["walls_active"][k], dtype=bool))


def _array(a: np.ndarray, copy: bool) -> np.ndarray:
    return np.array(a) if copy else np.asarray(a)


INDEX_KEYS = ("time", "step", "phase", "walls_active", "particle_offset", "contact_offset",
          "wall_contact_offset")  # the per-frame part of the layout (the rest: the tables)


def write_index(group: h5py.Group, index: dict[str, np.ndarray], interval: float,
                 vtk_interval: float | None) -> None:
    """The attributes of ``/frames`` and its per-frame datasets (``INDEX_KEYS``)."""
    group.attrs["interval"] = interval
    group.attrs["unit_interval"] = "s"
    if vtk_interval is not None:
        group.attrs["vtk_interval"] = vtk_interval
    group.attrs["count"] = int(index["time"].size)
    group.attrs["layout"] = (
        "concatenated: frame k owns rows particle_offset[k]:particle_offset[k+1] of "
        "particles/*, contact_offset[k]:contact_offset[k+1] of contacts/*, "
        "wall_contact_offset[k]:wall_contact_offset[k+1] of wall_contacts/*; contact i, j and "
        "wall_contacts grain index the frame's own grains; wall indexes /walls"
    )
    group.attrs["phase_codes"] = PHASE_CODES_TEXT
    _write_arrays(group, {k: index[k] for k in INDEX_KEYS})


def _write_arrays(group: h5py.Group, arrays: dict[str, np.ndarray]) -> None:
    units = {"time": "s"} | {k: "-" for k in INDEX_KEYS if k != "time"}  # counts, codes
    for table, fields in FIELDS.items():
        units.update({f"{table}/{k}": u for k, (_, u) in fields.items()})
    for key, arr in arrays.items():  # each with a Fletcher-32 checksum: a changed byte of an
        big = arr.size > 1024            # uncompressed column read back as another number
        ds = group.create_dataset(key, data=arr, compression="gzip" if big else None,
                                  shuffle=big, fletcher32=arr.size > 0)
        if key in units:
            ds.attrs["unit"] = units[key]


def write_frames(group: h5py.Group, frames: list[Frame], interval: float,
                 vtk_interval: float | None = None) -> None:
    """``frames`` into ``group`` (results.h5 ``/frames``, or a segment's), gzip-compressed."""
    write_layout(group, frames_to_arrays(frames), interval, vtk_interval)


def write_layout(group: h5py.Group, arrays: dict[str, np.ndarray], interval: float,
                 vtk_interval: float | None = None) -> None:
    """Frames already laid out (``frames_to_arrays``) into ``group``, as ``write_frames``."""
    write_index(group, arrays, interval, vtk_interval)
    _write_arrays(group, {k: v for k, v in arrays.items() if k not in INDEX_KEYS})


class FramesFile:
    """The frames of a results.h5, read from the file a block at a time when asked for
    (``[k]``), so that a run's frames need not fit in memory together: the per-frame index
    (``index``: time, step, phase, walls in place, offsets) is held, and the last block read:
    consecutive frames of at most ``BLOCK_BYTES`` together (or one larger frame), read with
    one slice per column (a read per frame cost 10 ms, mostly HDF5's: 100 s for 10,000 frames)."""

    def __init__(self, path: Path | str, index: dict[str, np.ndarray]) -> None:
        self.path = Path(path)
        self.index = index
        self.blocks = _blocks(index)  # the first frame of each block, then the count
        self._block: tuple[int, dict[str, np.ndarray]] | None = None  # (block, columns)

    def __len__(self) -> int:
        return int(self.index["time"].size)

    def __getitem__(self, k: int | slice) -> Frame | list[Frame]:
        n = len(self)
        if isinstance(k, slice):  # as a list's slice
            return [self[i] for i in range(*k.indices(n))]
        if not -n <= k < n:
            raise IndexError(f"frame {k} of {n}")
        k %= n
        b = int(np.searchsorted(self.blocks, k, side="right")) - 1
        if self._block is None or self._block[0] != b:
            self._block = None  # (not two blocks in memory at once)
            self._block = (b, self._read(int(self.blocks[b]), int(self.blocks[b + 1])))
        # copies: a frame the caller keeps keeps no block alive
        return frame_at(self.index, k, self._block[1], int(self.blocks[b]), copy=True)

    def column_max(self, name: str) -> float:
        """The largest value of column ``name`` (``"particles/radius"``...) over every frame,
        read in slices of ``BLOCK_BYTES`` (0 when the column has no rows)."""
        import h5py

        top = 0.0
        try:
            with h5py.File(self.path, "r") as h5:
                column = h5["frames"][name]
                rows, step = column.shape[0], max(1, int(BLOCK_BYTES // column.dtype.itemsize))
                for a in range(0, rows, step):
                    top = max(top, float(column[a:min(a + step, rows)].max()))
        except (OSError, RuntimeError) as exc:  # h5py's errors: a segment file damaged
            raise damaged(self.path, 0, len(self), exc) from None
        return top

    def _read(self, first: int, end: int) -> dict[str, np.ndarray]:
        """Every column's rows of frames ``first`` to ``end - 1``."""
        import h5py

        out = {}
        try:
            with h5py.File(self.path, "r") as h5:
                g = h5["frames"]
                for table, fields in FIELDS.items():
                    off = self.index[OFFSETS[table]]
                    a, b = int(off[first]), int(off[end])
                    # (HDF5 reads no 0 rows of a virtual dataset)
                    for key, (dt, _) in fields.items():
                        out[f"{table}/{key}"] = (g[f"{table}/{key}"][a:b] if b > a
                                                 else np.zeros(0, dtype=dt))
        except (OSError, RuntimeError) as exc:  # h5py's errors: a segment file damaged
            raise damaged(self.path, first, end, exc) from None
        return out


def _blocks(index: dict[str, np.ndarray]) -> np.ndarray:
    """Cut the frames into runs of at most ``BLOCK_BYTES`` of rows (a larger frame alone):
    the first frame of each run, then the number of frames."""
    size = np.zeros(index["time"].size)
    for table, fields in FIELDS.items():
        row = sum(np.dtype(dt).itemsize for dt, _ in fields.values())
        size += row * np.diff(index[OFFSETS[table]])
    starts, total = [0], 0.0
    for k, s in enumerate(size.tolist()):
        if total + s > BLOCK_BYTES and k > starts[-1]:
            starts.append(k)
            total = 0.0
        total += s
    return np.array([*starts, size.size] if size.size else [0, 0], dtype=np.int64)


class Frames:
    """The frames of a results.h5 (:func:`read_frames`: a ``FramesFile``, read one frame at a
    time) or a list of frames, with the wall geometry and events."""

    def __init__(self, frames: list[Frame] | FramesFile, walls: WallGeometry,
                 events: dict[str, Any], attrs: dict[str, Any], scenario: str = "",
                 status: str = "") -> None:
        self.frames = frames
        self.scenario = scenario
        self.status = status  # results.h5's: "complete", "running"...; "" when not known
        self.walls = walls
        self.events = events
        self.attrs = attrs

    def __len__(self) -> int:
        return len(self.frames)

    def __getitem__(self, k: int) -> Frame:
        if isinstance(k, bool) or not isinstance(k, numbers.Integral | slice):
            raise TypeError(f"frames are indexed by an integer (or a slice); got {k!r} (a time: "
                            "Frames.nearest)")
        return self.frames[k]

    def __iter__(self) -> Iterator[Frame]:
        return (self.frames[k] for k in range(len(self.frames)))

    def wall_shift(self, time: float) -> np.ndarray:
        """Each wall's x displacement [m] at ``time`` [s] from where ``walls`` (results.h5
        /walls, the silo as built) has it: a sliding gate's (``geometry.gate_shift``)."""
        return gate_shift(self.events, self.walls.names, self.walls.ax, self.walls.bx, time)

    @property
    def times(self) -> np.ndarray:
        """The time of each frame [s]."""
        if isinstance(self.frames, FramesFile):
            return self.frames.index["time"].astype(float)
        return np.array([f.time for f in self.frames], dtype=float)

    @property
    def phases(self) -> list[str]:
        """The phase of each frame ("fill", "settle" or "discharge")."""
        if isinstance(self.frames, FramesFile):
            return [PHASE_NAMES[int(c)] for c in self.frames.index["phase"]]
        return [f.phase for f in self.frames]

    def largest_radius(self) -> float:
        """The largest grain radius in any frame [m] (0 without grains)."""
        if isinstance(self.frames, FramesFile):
            return self.frames.column_max("particles/radius")
        return max((float(f.particles["radius"].max()) for f in self.frames if f.n),
                   default=0.0)

    @property
    def settled(self) -> bool:
        """Whether :meth:`end_of_filling` is a settled packing: false only for the frames of
        a run whose results.h5 was written before the run ended (``status``) and before its
        settling ended (no event ``settle_time``)."""
        return self.status in ("", "complete") or "settle_time" in self.events

    def end_of_filling(self) -> Frame:
        """The last frame before the gate opened (the settled packing), else the last one."""
        before = [k for k, phase in enumerate(self.phases) if phase in ("fill", "settle")]
        return self.frames[before[-1] if before else -1]

    def nearest(self, time: float) -> Frame:
        """The frame closest in time to ``time`` [s] (a finite number; ValueError else)."""
        if isinstance(time, bool) or not isinstance(time, numbers.Real) \
                or not math.isfinite(time):
            raise ValueError(f"time must be a finite number of seconds; got {time!r}")
        return self.frames[int(np.argmin(np.abs(self.times - time)))]


class NoFramesError(ValueError):
    """A results.h5 without ``/frames`` (written by an older silodem or another program), or
    whose segment files (``DIR/frames/``) are not beside it or cannot be read
    (``DamagedFramesError``); ``str()`` is one line naming the file."""


class DamagedFramesError(NoFramesError):
    """A segment file of ``/frames`` (or results.h5 itself, for frames kept in it) that h5py
    cannot read: cut short (a disk filled up, a copy broken off), overwritten.  Raised by
    :func:`read_frames` when the file cannot be opened, and when a frame is read (``[k]``)
    whose rows it cannot give."""


_SEGMENT = re.compile(r"frames-(\d+)-(\d+)\.h5$")  # frame_store.segment_name(first, last)


def _one_line(exc: BaseException) -> str:
    return one_line(exc) or type(exc).__name__


def damaged(results: Path | str, first: int, end: int, exc: BaseException) -> NoFramesError:
    """The error for ``exc``, raised by h5py reading frames ``first`` to ``end - 1`` of the
    results file ``results``: a ``DamagedFramesError`` naming the first segment file of those
    frames that h5py cannot read whole (each is opened and read again on its own), else
    naming ``results``."""
    import h5py

    results = Path(results)
    segments: list[str] = []
    try:
        with h5py.File(results, "r") as h5:
            segments = [str(s) for s in h5["frames"].attrs.get("segments", [])]
    except (OSError, RuntimeError, KeyError) as err:
        return DamagedFramesError(f"'{results}' is damaged ({type(err).__name__}: "
                                  f"{_one_line(err)}); its frames cannot be read")
    for name in segments:
        found = _SEGMENT.search(name)
        if found and (int(found[2]) < first or int(found[1]) >= end):
            continue  # (not one of the frames read)
        why = segment_damage(results.parent / name)
        if why:
            return damaged_segment(results, name, why)
    return DamagedFramesError(f"the frames of '{results}' cannot be read "
                              f"({type(exc).__name__}: {_one_line(exc)}); damaged?")


def damaged_segment(results: Path | str, name: str, why: str) -> DamagedFramesError:
    """The error for the segment file ``name`` (as results.h5 lists it) of the results file
    ``results``, which h5py cannot read (``why``)."""
    found = _SEGMENT.search(name)
    which = f"frames {int(found[1])} to {int(found[2])}" if found else "the frames"
    return DamagedFramesError(f"'{Path(results).parent / name}' is damaged ({why}): {which} "
                              f"of the run cannot be read (the rest of its results.h5 can)")


def segment_damage(path: Path, whole: bool = True) -> str:
    """Why h5py cannot read the segment file ``path`` (``whole``: every column of its frames;
    else only open it): "OSError: ..." in one line; "" when it can."""
    import h5py

    try:
        with h5py.File(path, "r") as h5:
            g = h5["frames"]
            if whole:
                for table, fields in FIELDS.items():
                    for key in fields:
                        g[f"{table}/{key}"][()]
    except (OSError, RuntimeError, KeyError) as exc:
        return f"{type(exc).__name__}: {_one_line(exc)}"
    return ""


def read_frames(path: Path | str) -> Frames:
    """The ``/frames`` of a results.h5 (``NoFramesError``, a ValueError, when it has none or
    its segment files are missing).  Only the index is read here; each frame is read when
    asked for (``FramesFile``)."""
    import h5py

    with h5py.File(path, "r") as h5:
        if "frames" not in h5:
            raise NoFramesError(f"'{path}' has no /frames (saved frames); run it again "
                                "with this version of silodem")
        g = h5["frames"]
        missing = missing_segments(path, g)
        if missing:
            raise NoFramesError(f"'{path}' keeps its frames in "
                                f"'{Path(path).parent / FOLDER}/', and "
                                f"{Path(missing[0]).name} is not there ({len(missing)} of "
                                f"{len(g.attrs['segments'])} files missing): copy or move a "
                                "results folder whole, frames/ with results.h5")
        for name in g.attrs.get("segments", []):  # each opens (a file cut short does not)
            why = segment_damage(Path(path).parent / str(name), whole=False)
            if why:
                raise damaged_segment(path, str(name), why)
        index = {key: g[key][()] for key in INDEX_KEYS}
        for table, fields in FIELDS.items():  # every column there, as long as the index says
            rows = int(index[OFFSETS[table]][-1])
            for key in fields:
                if g[f"{table}/{key}"].shape != (rows,):
                    raise ValueError(f"/frames/{table}/{key} has shape "
                                     f"{g[f'{table}/{key}'].shape}, not ({rows},)")
        walls = WallGeometry.of(h5["walls"])
        events = dict(h5["events"].attrs) if "events" in h5 else {}
        attrs = dict(g.attrs)
        scenario = str(h5.attrs.get("scenario", ""))
        status = h5.attrs.get("status", "")
    status = status.decode() if isinstance(status, bytes) else str(status)
    return Frames(FramesFile(path, index), walls, events, attrs, scenario, status)


def missing_segments(results: Path | str, group: h5py.Group) -> list[str]:
    """The segment files that results.h5 ``/frames`` (``group``) joins and that are not
    beside ``results``."""
    folder = Path(results).parent
    return [str(s) for s in group.attrs.get("segments", [])
            if not (folder / str(s)).is_file()]
