"""Recorders: what a run samples while it goes, without ever changing its state (HOOMD's writers).

A recorder is called every ``every_steps(dt)`` steps with the run (``record``), is told when a
phase ends (``phase_ended``), and writes what it gathered into its own group of results.h5
(``write``).  ``state``/``restore`` let a checkpoint carry a recorder's data.  The built-in
``TimeSeries`` is one; measurements (stress circles, wall profiles...) add more.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from silodem.engine import quantities as q

if TYPE_CHECKING:
    import h5py

    from silodem.silo.procedure import SiloRun


class Recorder:
    """Base class: sample every ``interval`` seconds of simulated time."""

    name = "recorder"
    key = ""  # the config key of ``interval`` (named by the base ``volume_warning``)

    def __init__(self, interval: float) -> None:
        if interval <= 0:
            raise ValueError(f"{self.name}: interval must be positive")
        self.interval = float(interval)

    def every_steps(self, dt: float) -> int:
        return max(1, round(self.interval / dt))

    def record(self, run: SiloRun) -> None:  # pragma: no cover - interface
        raise NotImplementedError

    def phase_ended(self, run: SiloRun, phase: str) -> None:
        """Called when ``phase`` ends (before the next one begins)."""

    def grains_lost(self, run: SiloRun, uids: np.ndarray) -> None:
        """Called with the ids of grains that left the silo other than through the outlet
        (pushed through a wall), just before they are removed."""

    def volume_warning(self, run: SiloRun) -> str | None:
        """A warning when what this recorder would gather is out of proportion (None: fine);
        asked once, before the run starts.  Here: an interval shorter than the time step,
        which samples at every step (measure.interval = 1e-300 s ran a quick case 25 times
        slower, without a word)."""
        from silodem.silo.checks import phase_time_limits

        if not self.key or self.interval >= run.dt:
            return None
        duration, words = phase_time_limits(run.cfg)
        return (f"{self.key} = {self.interval:.3g} s is shorter than the time step "
                f"{run.dt:.3g} s: sampled at every step, up to {duration / run.dt:.3g} "
                f"samples in {duration:.3g} s of simulated time ({words}), which slows the "
                "run; an interval of many steps samples less")

    def write(self, group: h5py.Group) -> None:  # pragma: no cover - interface
        raise NotImplementedError

    def saved_everywhere(self) -> None:
        """Called once results.h5, and checkpoint.h5 when enabled, are written with what
        ``write`` and ``state`` gave (files the recorder keeps beside them may be tidied)."""

    def state(self) -> dict[str, Any]:
        """Everything needed to continue recording after a checkpoint (arrays or scalars)."""
        return {}

    def restore(self, state: dict[str, Any]) -> None:
        """Inverse of ``state``."""


PHASE_CODES = {"fill": 0, "settle": 1, "discharge": 2}
"""The code of each phase in the ``phase`` columns of results.h5 (/timeseries, /measure,
/frames).  Recorders sample only while a phase runs: the procedure's last state, "done", is
never sampled (its frame is the end of the discharge), so it has no code."""

PHASE_CODES_TEXT = ",".join(f"{name}={code}" for name, code in PHASE_CODES.items())
"""``fill=0,settle=1,discharge=2``: the ``phase_codes`` attributes of results.h5."""


class TimeSeries(Recorder):
    """Time, phase, kinetic energy, grains in the silo, discharged mass, contacts, force ratio.

    The rows are kept (and checkpointed) as floats; the phase code (``PHASE_CODES``) and the
    counts are integers in ``as_arrays`` and results.h5, as in its other groups."""

    name = "timeseries"
    key = "output.sample_interval"
    columns = ("time", "phase", "kinetic_energy", "n_particles", "discharged_mass", "n_contacts",
               "n_wall_contacts", "force_ratio")
    units = ("s", "-", "J", "-", "kg", "-", "-", "-")
    dtypes = (np.float64, np.int8, np.float64, np.int64, np.float64, np.int64, np.int64,
              np.float64)

    def __init__(self, interval: float) -> None:
        super().__init__(interval)
        self.rows: list[tuple[float, ...]] = []

    def record(self, run: SiloRun) -> None:
        sim = run.sim
        ngg, ngw = q.contact_count(sim)
        ratio = q.unbalanced_force_ratio(sim) if sim.particles.n else 0.0
        self.rows.append((sim.time, PHASE_CODES[run.phase], sim.particles.kinetic_energy(),
                          sim.particles.n, run.state.discharged_mass, ngg, ngw,
                          ratio if math.isfinite(ratio) else np.nan))

    def as_arrays(self) -> dict[str, np.ndarray]:
        """One array per column, of the column's dtype (the float rows hold whole numbers
        exactly: counts far below 2^53)."""
        data = np.array(self.rows, dtype=float).reshape(-1, len(self.columns))
        return {name: data[:, k].astype(dtype)
                for k, (name, dtype) in enumerate(zip(self.columns, self.dtypes, strict=True))}

    def write(self, group: h5py.Group) -> None:
        for (key, arr), unit in zip(self.as_arrays().items(), self.units, strict=True):
            ds = group.create_dataset(key, data=arr)
            ds.attrs["unit"] = unit
        group.attrs["phase_codes"] = PHASE_CODES_TEXT
        group.attrs["interval"] = self.interval  # the configured one [s] (docs/output.md)

    def state(self) -> dict[str, Any]:
        return {"rows": np.array(self.rows, dtype=float).reshape(-1, len(self.columns))}

    def restore(self, state: dict[str, Any]) -> None:
        self.rows = [tuple(row) for row in np.asarray(state["rows"]).tolist()]


@dataclass
class Snapshot:
    """A copy of the grains and contacts at one moment (arrays over the live grains)."""

    time: float
    particles: dict[str, np.ndarray]
    contacts: dict[str, np.ndarray]
    wall_contacts: dict[str, np.ndarray]
    walls_active: np.ndarray  # which walls were in place [bool per wall]


SNAPSHOT_UNITS = {"x": "m", "y": "m", "vx": "m/s", "vy": "m/s", "omega": "rad/s", "radius": "m",
                  "uid": "-", "i": "-", "j": "-", "grain": "-", "wall": "-", "fn": "N",
                  "fs": "N", "fx": "N", "fy": "N"}  # the columns of a snapshot's tables


def write_snapshot(group: h5py.Group, snap: Snapshot) -> None:
    """``snap`` into ``group``: attr ``time`` [s], ``walls_active`` and the groups particles,
    contacts, wall_contacts, each column with its ``unit`` (docs/output.md, /settled)."""
    group.attrs["time"] = snap.time
    group.create_dataset("walls_active", data=snap.walls_active).attrs["unit"] = "-"
    for sub in ("particles", "contacts", "wall_contacts"):
        g = group.create_group(sub)
        for key, arr in getattr(snap, sub).items():
            g.create_dataset(key, data=arr).attrs["unit"] = SNAPSHOT_UNITS[key]


def take_snapshot(run: SiloRun) -> Snapshot:
    """Grains (position, velocity, spin, radius, uid, contact force), touching contacts with
    their forces (indices into the snapshot's grain arrays) and the walls in place."""
    sim, p = run.sim, run.sim.particles
    parts = {k: p.view(k).copy() for k in ("x", "y", "vx", "vy", "omega", "radius", "uid",
                                            "fx", "fy")}
    gc = q.grain_contacts(sim)
    wc = q.wall_contacts(sim)
    contacts = {"i": gc.i, "j": gc.j, "fn": gc.fn, "fs": gc.fs, "fx": gc.fx, "fy": gc.fy}
    wall_contacts = {"grain": wc.grain, "wall": wc.wall, "fn": wc.fn, "fs": wc.fs,
                     "fx": wc.fx, "fy": wc.fy}
    return Snapshot(sim.time, parts, contacts, wall_contacts, run.walls.active.copy())
