"""The frames recorder, and the segment files behind results.h5 ``/frames`` (docs/output.md).

``FramesRecorder`` takes a frame (:mod:`silodem.silo.frames`) every
``output.frame_interval`` seconds of simulated time and at the end of each phase; when
``output.vtk_interval`` is set it also writes ParaView files into ``DIR/vtk/``
(:mod:`silodem.viz.vtk`) as the run goes.

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
(``frames.missing_segments`` says which file is missing).

Segments are only ever added.  A checkpoint lists the segments written before it.  A run
resumed from it writes its next batch under the name the batch's frames give; a file of that
name left by the killed process holds the same frames (the run is deterministic) and is
replaced.  Files the killed process wrote after its last checkpoint that no save lists any
more are removed after the next save (``remove_unlisted``).
"""

from __future__ import annotations

import math
import re
import time
from contextlib import suppress
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from silodem.atomic import atomic_hdf5
from silodem.silo.checks import phase_time_limits
from silodem.silo.frames import (
    FIELDS,
    FOLDER,
    INDEX_KEYS,
    OFFSETS,
    Frame,
    WallGeometry,
    frames_from_arrays,
    frames_to_arrays,
    write_frames,
    write_index,
    write_layout,
)
from silodem.silo.recorders import Recorder, take_snapshot

if TYPE_CHECKING:
    import h5py

    from silodem.config import Config
    from silodem.silo.procedure import SiloRun

PENDING_BYTES = 64e6  # a recorder holding frames of more than this writes them out [B]
PVD_EVERY_S = 2.0  # the VTK .pvd collections are rewritten at most this often [s of wall time]

# What a frame costs (paper-case2 --quick: 755 frames held 75,315 grain rows and 74,771 contact
# rows; its VTK files held 72 B per grain in particles_*.vtu and 28 B per contact in
# contacts_*.vtu; a settled packing has up to about 2 contacts per grain):
FRAME_BYTES_PER_GRAIN = 72  # 40 B of grain fields + 2 contacts of 16 B [B]
VTK_BYTES_PER_GRAIN = 130  # a grain and 2 contacts in VTK XML [B]
VTK_FILES_PER_OUTPUT = 3  # particles, contacts, walls
WARN_BYTES = 1e9  # frames or VTK files past this draw a warning [B]
WARN_VTK_FILES = 10_000  # VTK files past this draw a warning
_NAME = re.compile(r"frames-\d{6,}-\d{6,}\.h5")
_PARTIAL = re.compile(r"\.frames-\d{6,}-\d{6,}\.h5\.tmp")  # atomic_file's, left by a SIGKILL


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

    def append(self, first: int, arrays: dict[str, np.ndarray], interval: float,
               vtk_interval: float | None) -> None:
        """Write the next segment: the frames laid out in ``arrays`` (``frames_to_arrays``),
        numbered from ``first``, with the ``/frames`` attributes of the run's intervals."""
        count = arrays["time"].size
        name = segment_name(first, first + count - 1)
        self.folder.mkdir(parents=True, exist_ok=True)
        with atomic_hdf5(self.folder / name) as h5:
            write_layout(h5.create_group("frames"), arrays, interval, vtk_interval)
        rows = [int(arrays[OFFSETS[t]][-1]) for t in FIELDS]
        self.names.append(name)
        self.rows = np.vstack([self.rows, np.asarray(rows, dtype=np.int64)[None, :]])

    def link(self, group: h5py.Group) -> None:
        """Into ``group`` (results.h5 ``/frames``): every table column of ``frames.FIELDS``
        as a virtual dataset joining the segments' columns, with its ``unit``; and the
        attribute ``segments`` (the files, relative to results.h5's folder)."""
        import h5py

        group.attrs["segments"] = [f"{FOLDER}/{name}" for name in self.names]
        for t, (table, fields) in enumerate(FIELDS.items()):
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
        process killed after its last checkpoint), and the temporary files of segments whose
        writing a SIGKILL cut short; other files are left alone."""
        if not self.folder.is_dir():
            return
        keep = set(self.names)
        for path in self.folder.iterdir():
            if (_NAME.fullmatch(path.name) and path.name not in keep
                    or _PARTIAL.fullmatch(path.name)):
                path.unlink(missing_ok=True)

    def state(self) -> dict[str, Any]:
        return {"names": np.array(self.names, dtype=str), "rows": self.rows.copy()}

    def restore(self, state: dict[str, Any]) -> None:
        """Inverse of ``state``; a listed segment file that is not there, or whose tables'
        row counts are not the ones saved (another run's file of the same name: a checkpoint
        copied into another run's folder), is a ValueError."""
        import h5py

        self.names = [str(n) for n in np.asarray(state["names"]).tolist()]
        self.rows = np.asarray(state["rows"], dtype=np.int64).reshape(-1, 3)
        if len(self.names) != len(self.rows):
            raise ValueError(f"{len(self.names)} frame segments listed with "
                             f"{len(self.rows)} row counts")
        gone = [n for n in self.names if not (self.folder / n).is_file()]
        if gone:
            raise ValueError(f"the saved frames' file {self.folder / gone[0]} is missing "
                             f"({len(gone)} of {len(self.names)} missing; the run can be "
                             "resumed once they are back)")
        for name, rows in zip(self.names, self.rows.tolist(), strict=True):
            path = self.folder / name
            try:
                with h5py.File(path, "r") as h5:
                    held = [h5[f"frames/{table}/{next(iter(fields))}"].shape[0]
                            for table, fields in FIELDS.items()]
            except (OSError, KeyError) as exc:
                raise ValueError(f"the saved frames' file {path} cannot be read "
                                 f"({exc})") from None
            if held != rows:
                raise ValueError(f"the saved frames' file {path} is not the one this "
                                 f"checkpoint wrote: it holds {held} grain, contact and wall "
                                 f"contact rows, not {rows} (another run's?)")


def clear(folder: Path) -> None:
    """Remove every segment file (and partial one) from ``folder`` (a new run in a used
    results folder)."""
    FrameStore(folder).remove_unlisted()  # (it lists none)


def frame_of(run: SiloRun) -> Frame:
    """The current state of ``run`` as a (float32) frame."""
    snap = take_snapshot(run)
    tables = {}
    for table, source in (("particles", snap.particles), ("contacts", snap.contacts),
                          ("wall_contacts", snap.wall_contacts)):
        tables[table] = {k: np.ascontiguousarray(source[k], dtype=dt)
                         for k, (dt, _) in FIELDS[table].items()}
    return Frame(float(snap.time), int(run.sim.steps), run.phase, tables["particles"],
                 tables["contacts"], tables["wall_contacts"],
                 np.asarray(snap.walls_active, dtype=bool).copy())


class FramesRecorder(Recorder):
    """Saves a frame every ``frame_interval`` [s] and at each phase end; with ``vtk_dir`` and
    ``vtk_interval`` set, also writes ParaView files every ``vtk_interval`` [s].

    With ``store_dir`` (``DIR/frames``) the frames are written out to segment files there at
    every save of results.h5 and whenever those held pass ``PENDING_BYTES``;
    ``frames`` holds only the ones not yet written, ``saved`` the index of the others.
    Without it every frame stays in ``frames`` and results.h5 holds them itself."""

    name = "frames"

    def __init__(self, frame_interval: float, vtk_interval: float | None = None,
                 vtk_dir: Path | str | None = None,
                 store_dir: Path | str | None = None) -> None:
        super().__init__(frame_interval)
        if vtk_interval is not None and vtk_interval <= 0:
            raise ValueError("frames: vtk_interval must be positive")
        self.vtk_interval = vtk_interval if vtk_dir is not None else None
        self.vtk_dir = Path(vtk_dir) if vtk_dir is not None else None
        self.store = FrameStore(store_dir) if store_dir is not None else None
        self.frames: list[Frame] = []  # not yet written out
        self.held_bytes = 0  # of the frames kept by ``_keep`` since the last write-out [B]
        self.saved = _empty_index()  # the index of the frames in the store
        self.vtk_times: list[float] = []  # time of VTK file k [s]
        self._vtk = None
        self._listed = 0  # VTK output times the .pvd collections list
        self._listed_at = -math.inf  # when they were last written (time.monotonic) [s]

    @property
    def count(self) -> int:
        """Frames taken so far (written out or held)."""
        return self.saved["time"].size + len(self.frames)

    @classmethod
    def from_config(cls, cfg: Config, out_dir: Path | str | None) -> FramesRecorder:
        """The recorder of ``cfg.output`` for the results folder ``out_dir``."""
        o = cfg.output
        vtk_dir = Path(out_dir) / "vtk" if out_dir is not None and o.vtk_interval else None
        store = Path(out_dir) / FOLDER if out_dir is not None else None
        return cls(o.frame_interval, o.vtk_interval, vtk_dir, store)

    # --- when -----------------------------------------------------------------------------
    def _frame_steps(self, dt: float) -> int:
        return max(1, round(self.interval / dt))

    def _vtk_steps(self, dt: float) -> int | None:
        """Steps between VTK outputs.  A VTK interval that is a whole multiple of the frame
        interval is made a whole multiple of the frame steps, so each VTK file is a frame.
        (The multiple is taken of the steps: a frame interval below dt is one step, and
        frame_interval 1e-9 s with vtk_interval 1e-3 s is a VTK file every 1e-3 s, not every
        1e6 steps.)"""
        if self.vtk_interval is None:
            return None
        steps = max(1, round(self.vtk_interval / dt))
        ratio = self.vtk_interval / self.interval
        if ratio >= 1.0 and abs(ratio - round(ratio)) < 1e-6:
            frame_steps = self._frame_steps(dt)
            return frame_steps * max(1, round(steps / frame_steps))
        return steps

    def every_steps(self, dt: float) -> int:
        vs = self._vtk_steps(dt)
        fs = self._frame_steps(dt)
        return fs if vs is None else math.gcd(fs, vs)

    def volume_warning(self, run: SiloRun) -> str | None:
        """A warning when the frames the run may save, up to its phase time limits, pass
        ``WARN_BYTES``, or the VTK files pass ``WARN_BYTES`` or ``WARN_VTK_FILES``; None
        otherwise."""
        dt, n = run.dt, run.cfg.fill.n_particles
        duration, words = phase_time_limits(run.cfg)
        said = []
        frames = duration / (self._frame_steps(dt) * dt)
        size = frames * n * FRAME_BYTES_PER_GRAIN
        if size > WARN_BYTES:
            said.append(f"output.frame_interval = {self.interval:.3g} s may save up to about "
                        f"{frames:.3g} frames, {_bytes(size)} before compression")
        vs = self._vtk_steps(dt)
        if vs is not None:
            outputs = duration / (vs * dt)
            size = outputs * n * VTK_BYTES_PER_GRAIN
            files = outputs * VTK_FILES_PER_OUTPUT
            if size > WARN_BYTES or files > WARN_VTK_FILES:
                said.append(f"output.vtk_interval = {self.vtk_interval:.3g} s may write up to "
                            f"about {files:.3g} VTK files, {_bytes(size)}")
        if not said:
            return None
        return (f"{'; '.join(said)} ({n} grains, time step {dt:.3g} s, up to {duration:.3g} s "
                f"of simulated time: {words}, a bound that a run which settles and empties "
                "sooner stays under); a larger interval saves less")

    # --- recording ------------------------------------------------------------------------
    def record(self, run: SiloRun) -> None:
        steps = run.sim.steps
        vs = self._vtk_steps(run.dt)
        want_frame = steps % self._frame_steps(run.dt) == 0
        want_vtk = vs is not None and steps % vs == 0
        if not (want_frame or want_vtk):
            return
        frame = frame_of(run)
        if want_frame:
            self._keep(frame)
        if want_vtk:
            self._write_vtk(run, frame)

    def phase_ended(self, run: SiloRun, phase: str) -> None:
        """A frame at the end of each phase (the settled state, the final state); the VTK
        collections listed up to it."""
        self.list_vtk()
        last = (self.frames[-1].step if self.frames else
                int(self.saved["step"][-1]) if self.saved["step"].size else None)
        if last == run.sim.steps:
            return
        self._keep(frame_of(run))

    def _keep(self, frame: Frame) -> None:
        self.frames.append(frame)
        self.held_bytes += frame.nbytes
        if self.store is not None and self.held_bytes > PENDING_BYTES:
            with suppress(OSError):  # a full disk: they stay held; the next save tries again
                self.write_out()  # (and a failed save warns)

    def write_out(self) -> None:
        """Write the frames held to the next segment file of the store (none: nothing)."""
        if self.store is None or not self.frames:
            return
        held = frames_to_arrays(self.frames)
        self.store.append(self.saved["time"].size, held, self.interval, self.vtk_interval)
        self.saved = _join_index(self.saved, held)
        self.frames = []
        self.held_bytes = 0

    def saved_everywhere(self) -> None:
        """results.h5 and checkpoint.h5 are written: remove the segment files neither
        lists (left by a process killed after its last checkpoint)."""
        if self.store is not None:
            self.store.remove_unlisted()

    def _write_vtk(self, run: SiloRun, frame: Frame) -> None:
        from silodem.viz.vtk import VtkSeries

        walls = WallGeometry.of(run.walls)  # where they are now (a sliding gate moves)
        if self._vtk is None:
            self._vtk = VtkSeries(self.vtk_dir, walls, fresh=not self.vtk_times)
        self._vtk.walls = walls
        self._vtk.write(len(self.vtk_times), frame)
        self.vtk_times.append(frame.time)
        if time.monotonic() - self._listed_at >= PVD_EVERY_S:
            self.list_vtk()

    def list_vtk(self) -> None:
        """Write the .pvd collections of the VTK files written so far, if they lack some.
        Each rewrite lists every file, so rewriting them after each output made a run with
        a short ``vtk_interval`` quadratic in its output count (an audit: 50,000 steps/s fell
        to 85 at 6,000 outputs); they are rewritten at most every ``PVD_EVERY_S`` of wall
        time, at each phase's end and at every save of results.h5."""
        if self._vtk is not None and self._listed < len(self.vtk_times):
            self._vtk.write_collections(self.vtk_times)
            self._listed, self._listed_at = len(self.vtk_times), time.monotonic()

    # --- results.h5 -----------------------------------------------------------------------
    def arrays(self) -> dict[str, np.ndarray]:
        """The frames held (not yet written out) as flat arrays (the ``/frames`` layout)."""
        return frames_to_arrays(self.frames)

    def write(self, group: h5py.Group) -> None:
        """results.h5 ``/frames``: with a store, the frames held are written out first and
        the tables are joined from the segments; without, every frame is written here.  The
        VTK collections are brought up to date with it."""
        self.list_vtk()
        if self.store is None:
            write_frames(group, self.frames, self.interval, self.vtk_interval)
            return
        self.write_out()
        write_index(group, self.saved, self.interval, self.vtk_interval)
        self.store.link(group)

    def state(self) -> dict[str, Any]:
        out = {key.replace("/", "__"): arr for key, arr in self.arrays().items()}
        out["vtk_times"] = np.asarray(self.vtk_times, dtype=float)
        if self.store is not None:
            out["saved"] = dict(self.saved)
            out["store"] = self.store.state()
        return out

    def restore(self, state: dict[str, Any]) -> None:
        arrays = {key.replace("__", "/"): np.asarray(val) for key, val in state.items()
                  if key not in ("vtk_times", "saved", "store")}
        self.frames = frames_from_arrays(arrays)
        self.held_bytes = sum(f.nbytes for f in self.frames)
        self.vtk_times = [float(t) for t in np.asarray(state.get("vtk_times", []))]
        self._vtk = None
        if "store" in state:
            if self.store is None:
                raise ValueError("frames: the checkpoint's frames are in segment files, and "
                                 "this recorder has no results folder to read them from")
            self.store.restore(state["store"])
            self.saved = {k: np.asarray(state["saved"][k]) for k in INDEX_KEYS}


def _bytes(size: float) -> str:
    """``size`` [B] as GB or MB."""
    return f"{size / 1e9:.3g} GB" if size >= 1e9 else f"{size / 1e6:.3g} MB"


def _empty_index() -> dict[str, np.ndarray]:
    return {k: v for k, v in frames_to_arrays([]).items() if k in INDEX_KEYS}


def _join_index(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The index of frames ``a`` then ``b`` (each a ``frames_to_arrays`` result)."""
    out = {}
    for key in INDEX_KEYS:
        x, y = a[key], b[key]
        if key.endswith("offset"):
            out[key] = np.concatenate([x, y[1:] + x[-1]])
        elif key == "walls_active" and x.shape[0] == 0:
            out[key] = y.copy()
        else:
            out[key] = np.concatenate([x, y])
    return out
