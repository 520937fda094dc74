"""Frames: compact snapshots saved while a run goes, for animations, pictures and ParaView.

``FramesRecorder`` takes a frame (grains, touching contacts with their forces, walls in place,
time, phase) every ``output.frame_interval`` seconds of simulated time and at the end of each
phase, and writes them to results.h5 ``/frames``.  With a results folder it keeps only the
frames not yet written out: they go to segment files in ``DIR/frames/`` that results.h5 joins
(:mod:`silodem.silo.frame_store`).  When ``output.vtk_interval`` is set it also writes
ParaView files into ``DIR/vtk/`` (:mod:`silodem.viz.vtk`) as the run goes.

Layout of ``/frames`` (docs/output.md): the frames are *concatenated*.  Frame ``k`` owns rows
``particle_offset[k]:particle_offset[k+1]`` of every ``particles/*`` array, rows
``contact_offset[k]:contact_offset[k+1]`` of ``contacts/*`` and rows
``wall_contact_offset[k]:wall_contact_offset[k+1]`` of ``wall_contacts/*``.  Contact indices
``i``, ``j`` and ``grain`` count from the first grain *of the frame*; ``wall`` indexes
``/walls``.  Floats are float32 (frames are for looking at; the exact states are the
``/settled`` and ``/final`` snapshots and the checkpoints).

:func:`read_frames` reads them back (NumPy arrays) for notebooks and for ``silodem animate``.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import suppress
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from silodem.measure.stress import contact_points_walls
from silodem.silo import frame_store
from silodem.silo.checks import phase_time_limits
from silodem.silo.frame_store import FrameStore
from silodem.silo.recorders import PHASE_CODES, Recorder, take_snapshot

if TYPE_CHECKING:
    import h5py

    from silodem.config import Config
    from silodem.silo.procedure import SiloRun

PHASE_NAMES = {code: name for name, code in PHASE_CODES.items()}

# What a frame costs (paper-case2 --quick: 755 frames held 75,315 grain rows and 74,771 contact
# rows; its VTK files held 72 B per grain in particles_*.vtu and 28 B per contact in
# contacts_*.vtu; a settled packing has up to about 2 contacts per grain):
FRAME_BYTES_PER_GRAIN = 72  # 40 B of grain fields + 2 contacts of 16 B [B]
VTK_BYTES_PER_GRAIN = 130  # a grain and 2 contacts in VTK XML [B]
VTK_FILES_PER_OUTPUT = 3  # particles, contacts, walls
WARN_BYTES = 1e9  # frames or VTK files past this draw a warning [B]
WARN_VTK_FILES = 10_000  # VTK files past this draw a warning

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
_OFFSETS = {"particles": "particle_offset", "contacts": "contact_offset",
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

    def closest_points(self, wall: np.ndarray, x: np.ndarray, y: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
        """The point of segment ``wall[k]`` closest to ``(x[k], y[k])`` (a grain's contact)."""
        return contact_points_walls(x, y, np.arange(len(wall)), wall, self.ax, self.ay,
                                    self.bx, self.by)


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
    every save of results.h5 and whenever those held pass ``frame_store.PENDING_BYTES``;
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

    @property
    def count(self) -> int:
        """Frames taken so far (written out or held)."""
        return self.saved["time"].size + len(self.frames)

    @classmethod
    def from_config(cls, cfg: Config, out_dir: Path | str | None) -> FramesRecorder:
        """The recorder of ``cfg.output`` for the results folder ``out_dir``."""
        o = cfg.output
        vtk_dir = Path(out_dir) / "vtk" if out_dir is not None and o.vtk_interval else None
        store = Path(out_dir) / frame_store.FOLDER if out_dir is not None else None
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
            said.append(f"output.frame_interval = {self.interval:.3g} s may save about "
                        f"{frames:.3g} frames, {_bytes(size)} on disk")
        vs = self._vtk_steps(dt)
        if vs is not None:
            outputs = duration / (vs * dt)
            size = outputs * n * VTK_BYTES_PER_GRAIN
            files = outputs * VTK_FILES_PER_OUTPUT
            if size > WARN_BYTES or files > WARN_VTK_FILES:
                said.append(f"output.vtk_interval = {self.vtk_interval:.3g} s may write about "
                            f"{files:.3g} VTK files, {_bytes(size)}")
        if not said:
            return None
        return (f"{'; '.join(said)} ({n} grains, time step {dt:.3g} s, up to {duration:.3g} s "
                f"of simulated time: {words}); a larger interval saves less")

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
        """A frame at the end of each phase (the settled state, the final state)."""
        last = (self.frames[-1].step if self.frames else
                int(self.saved["step"][-1]) if self.saved["step"].size else None)
        if last == run.sim.steps:
            return
        self._keep(frame_of(run))

    def _keep(self, frame: Frame) -> None:
        self.frames.append(frame)
        self.held_bytes += frame.nbytes
        if self.store is not None and self.held_bytes > frame_store.PENDING_BYTES:
            with suppress(OSError):  # a full disk: they stay held; the next save tries again
                self.write_out()  # (and a failed save warns)

    def write_out(self) -> None:
        """Write the frames held to the next segment file of the store (none: nothing)."""
        if self.store is None or not self.frames:
            return
        held = frames_to_arrays(self.frames)
        rows = tuple(int(held[_OFFSETS[t]][-1]) for t in FIELDS)
        self.store.append(lambda g: write_frames(g, self.frames, self.interval,
                                                 self.vtk_interval), len(self.frames), rows)
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

        if self._vtk is None:
            self._vtk = VtkSeries(self.vtk_dir, WallGeometry.of(run.walls),
                                  fresh=not self.vtk_times)
        self._vtk.write(len(self.vtk_times), frame)
        self.vtk_times.append(frame.time)
        self._vtk.write_collections(self.vtk_times)

    # --- results.h5 -----------------------------------------------------------------------
    def arrays(self) -> dict[str, np.ndarray]:
        """The frames held (not yet written out) as flat arrays (the ``/frames`` layout)."""
        return frames_to_arrays(self.frames)

    def write(self, group: h5py.Group) -> None:
        """results.h5 ``/frames``: with a store, the frames held are written out first and
        the tables are joined from the segments; without, every frame is written here."""
        if self.store is None:
            write_frames(group, self.frames, self.interval, self.vtk_interval)
            return
        self.write_out()
        _write_index(group, self.saved, self.interval, self.vtk_interval)
        self.store.link(group, FIELDS)

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
            self.saved = {k: np.asarray(state["saved"][k]) for k in _INDEX}


def _bytes(size: float) -> str:
    """``size`` [B] as GB or MB."""
    return f"{size / 1e9:.3g} GB" if size >= 1e9 else f"{size / 1e6:.3g} MB"


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
        out[_OFFSETS[table]] = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        for key, (dt, _) in fields.items():
            parts = [getattr(f, table)[key] for f in frames]
            out[f"{table}/{key}"] = (np.concatenate(parts).astype(dt, copy=False) if parts
                                     else np.zeros(0, dtype=dt))
    return out


def frames_from_arrays(a: dict[str, np.ndarray]) -> list[Frame]:
    frames = []
    for k in range(a["time"].shape[0]):
        tables = {}
        for table, fields in FIELDS.items():
            off = a[_OFFSETS[table]]
            s = slice(int(off[k]), int(off[k + 1]))
            tables[table] = {key: np.asarray(a[f"{table}/{key}"][s]) for key in fields}
        frames.append(Frame(float(a["time"][k]), int(a["step"][k]),
                            PHASE_NAMES[int(a["phase"][k])], tables["particles"],
                            tables["contacts"], tables["wall_contacts"],
                            np.asarray(a["walls_active"][k], dtype=bool)))
    return frames


_INDEX = ("time", "step", "phase", "walls_active", "particle_offset", "contact_offset",
          "wall_contact_offset")  # the per-frame part of the layout (the rest: the tables)


def _empty_index() -> dict[str, np.ndarray]:
    return {k: v for k, v in frames_to_arrays([]).items() if k in _INDEX}


def _join_index(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The index of frames ``a`` then ``b`` (each a ``frames_to_arrays`` result)."""
    out = {}
    for key in _INDEX:
        x, y = a[key], b[key]
        if key.endswith("offset"):
            out[key] = np.concatenate([x, y[1:] + x[-1]])
        elif key == "walls_active" and x.shape[0] == 0:
            out[key] = y.copy()
        else:
            out[key] = np.concatenate([x, y])
    return out


def _write_index(group: h5py.Group, index: dict[str, np.ndarray], interval: float,
                 vtk_interval: float | None) -> None:
    """The attributes of ``/frames`` and its per-frame datasets (``_INDEX``)."""
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
    group.attrs["phase_codes"] = "fill=0,settle=1,discharge=2"
    _write_arrays(group, {k: index[k] for k in _INDEX})


def _write_arrays(group: h5py.Group, arrays: dict[str, np.ndarray]) -> None:
    units = {"time": "s"}
    for table, fields in FIELDS.items():
        units.update({f"{table}/{k}": u for k, (_, u) in fields.items()})
    for key, arr in arrays.items():
        big = arr.size > 1024
        ds = group.create_dataset(key, data=arr, compression="gzip" if big else None,
                                  shuffle=big)
        if key in units:
            ds.attrs["unit"] = units[key]


def write_frames(group: h5py.Group, frames: list[Frame], interval: float,
                 vtk_interval: float | None = None) -> None:
    """``frames`` into ``group`` (results.h5 ``/frames``, or a segment's), gzip-compressed."""
    arrays = frames_to_arrays(frames)
    _write_index(group, arrays, interval, vtk_interval)
    _write_arrays(group, {k: v for k, v in arrays.items() if k not in _INDEX})


class Frames:
    """The frames of a results.h5 (:func:`read_frames`), with the wall geometry and events."""

    def __init__(self, frames: list[Frame], walls: WallGeometry, events: dict[str, Any],
                 attrs: dict[str, Any], scenario: str = "") -> None:
        self.frames = frames
        self.scenario = scenario
        self.walls = walls
        self.events = events
        self.attrs = attrs

    def __len__(self) -> int:
        return len(self.frames)

    def __getitem__(self, k: int) -> Frame:
        return self.frames[k]

    def __iter__(self) -> Iterator[Frame]:
        return iter(self.frames)

    @property
    def times(self) -> np.ndarray:
        return np.array([f.time for f in self.frames], dtype=float)

    def end_of_filling(self) -> Frame:
        """The last frame before the gate opened (the settled packing), else the last one."""
        before = [f for f in self.frames if f.phase in ("fill", "settle")]
        return before[-1] if before else self.frames[-1]

    def nearest(self, time: float) -> Frame:
        """The frame closest in time to ``time`` [s]."""
        return self.frames[int(np.argmin(np.abs(self.times - time)))]


class NoFramesError(ValueError):
    """A results.h5 without ``/frames`` (written by an older silodem or another program), or
    whose segment files (``DIR/frames/``) are not beside it; ``str()`` is one line naming the
    file."""


def read_frames(path: Path | str) -> Frames:
    """The ``/frames`` of a results.h5 (``NoFramesError``, a ValueError, when it has none or
    its segment files are missing)."""
    import h5py

    with h5py.File(path, "r") as h5:
        if "frames" not in h5:
            raise NoFramesError(f"'{path}' has no /frames (saved frames); run it again "
                                "with this version of silodem")
        g = h5["frames"]
        missing = frame_store.missing_segments(path, g)
        if missing:
            raise NoFramesError(f"'{path}' keeps its frames in "
                                f"'{Path(path).parent / frame_store.FOLDER}/', and "
                                f"{Path(missing[0]).name} is not there ({len(missing)} of "
                                f"{len(g.attrs['segments'])} files missing): copy or move a "
                                "results folder whole, frames/ with results.h5")
        arrays = {}
        g.visititems(lambda name, obj: arrays.__setitem__(name, obj[()])
                     if isinstance(obj, h5py.Dataset) else None)
        walls = WallGeometry.of(h5["walls"])
        events = dict(h5["events"].attrs) if "events" in h5 else {}
        attrs = dict(g.attrs)
        scenario = str(h5.attrs.get("scenario", ""))
    return Frames(frames_from_arrays(arrays), walls, events, attrs, scenario)
