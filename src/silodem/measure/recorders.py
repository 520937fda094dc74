"""The measurement recorder of a run (docs/measurements.md, layout in docs/output.md).

``recorders_for(cfg)`` gives the recorders ``SiloRun`` samples; here one ``MeasureRecorder``
(group ``/measure`` of results.h5) every ``measure.interval`` seconds of simulated time.  Each
sample reads the run once (:mod:`silodem.measure.reading`) and feeds four parts:

* circles:  Love-Weber stress, porosity, coordination number in each measurement circle, and
            the coordination number of the band across the junction (Fig. 2);
* profiles: normal and shear stress in bins along every wall; Love-Weber stress in near-wall
            strips along both edges of the silo and in full-width slices, binned in z;
* fields:   bulk density and Love-Weber stress on a grid, of the settled packing and over
            the discharge window (:mod:`silodem.measure.fields`);
* flow:     from the gate opening on: when each grain leaves, how far it moved (dead zones;
            grains already outside the silo at the opening marked lost, not followed),
            the mean velocity field on a grid over the discharge window, the velocities near the
            walls and on the axis above the junction (mass flow index), and a snapshot of the
            grains and contacts in the middle of the discharge window (force network, Fig. 5).

Nothing here changes the run.  ``state``/``restore`` carry all gathered data through a
checkpoint (a flat dict of NumPy arrays and scalars).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from silodem.config import Config
from silodem.engine.quantities import top_of_grains
from silodem.measure import regions
from silodem.measure.fields import FieldsPart
from silodem.measure.reading import Reading, read_simulation
from silodem.measure.stress import circle_measure, region_stress
from silodem.measure.wall_profiles import binned_stress, wall_bins, wall_stress
from silodem.silo.geometry import build_walls, outlet_room, silo_shape
from silodem.silo.recorders import (
    PHASE_CODES,
    PHASE_CODES_TEXT,
    Recorder,
    Snapshot,
    take_snapshot,
    write_snapshot,
)

if TYPE_CHECKING:
    import h5py

    from silodem.silo.procedure import SiloRun

DISCHARGE = PHASE_CODES["discharge"]


def _stack(rows: list, shape: tuple[int, ...]) -> np.ndarray:
    return np.array(rows, dtype=float).reshape((len(rows), *shape))


def _dataset(group, name: str, data, unit: str | None = None, **attrs) -> None:
    arr = np.asarray(data)
    kw = {"compression": "gzip", "compression_opts": 4} if arr.size > 4096 else {}
    ds = group.create_dataset(name, data=arr, **kw)
    if unit is not None:
        ds.attrs["unit"] = unit
    for k, v in attrs.items():
        ds.attrs[k] = v


class _CirclesPart:
    def __init__(self, cfg: Config, shape) -> None:
        self.circles = regions.circles_for(cfg, shape)
        self.band = regions.junction_band(cfg, shape)
        self.band_area = shape.area_below(self.band[1]) - shape.area_below(self.band[0])
        self.thickness = cfg.material.thickness
        self.rows: dict[str, list] = {k: [] for k in ("stress", "porosity", "coordination",
                                                      "count", "band")}

    def record(self, rd: Reading) -> None:
        nc = len(self.circles)
        stress, por, coord, cnt = np.full((nc, 3), np.nan), np.full(nc, np.nan), \
            np.full(nc, np.nan), np.zeros(nc)
        for k, c in enumerate(self.circles):
            m = circle_measure(rd.x, rd.z, rd.r, rd.moments, rd.counts, c.x, c.z, c.radius,
                               c.area_inside, self.thickness)
            stress[k], por[k], coord[k], cnt[k] = m["stress"], m["porosity"], \
                m["coordination"], m["count"]
        inb = (rd.z >= self.band[0]) & (rd.z < self.band[1])
        nb = int(inb.sum())
        band_stress = region_stress(rd.moments, inb, self.band_area, self.thickness)
        band = [rd.counts[inb].mean() if nb else np.nan, nb, *band_stress]
        for key, val in zip(self.rows, (stress, por, coord, cnt, band)):
            self.rows[key].append(val)

    def arrays(self) -> dict[str, np.ndarray]:
        nc = len(self.circles)
        shapes = {"stress": (nc, 3), "porosity": (nc,), "coordination": (nc,), "count": (nc,),
                  "band": (5,)}
        return {k: _stack(v, shapes[k]) for k, v in self.rows.items()}

    def restore(self, state: dict[str, Any]) -> None:
        for k in self.rows:
            self.rows[k] = list(np.asarray(state[f"circles.{k}"]))

    def write(self, g: h5py.Group) -> None:
        import h5py

        a = self.arrays()
        c = g.create_group("circles")
        c.create_dataset("name", data=np.array([x.name for x in self.circles],
                                               dtype=h5py.string_dtype()))
        for key in ("x", "z", "radius", "area_inside"):
            _dataset(c, key, [getattr(x, key) for x in self.circles],
                     "m^2" if key == "area_inside" else "m")
        _dataset(c, "stress", a["stress"], "Pa",
                 components="xx,zz,xz; compression positive (Love-Weber, PFC normalisation)")
        _dataset(c, "porosity", a["porosity"], "-")
        _dataset(c, "coordination", a["coordination"], "-")
        _dataset(c, "count", a["count"], "-")
        b = g.create_group("band")
        b.attrs["z_lo"], b.attrs["z_hi"] = self.band
        _dataset(b, "coordination", a["band"][:, 0], "-")
        _dataset(b, "count", a["band"][:, 1], "-")
        _dataset(b, "stress", a["band"][:, 2:], "Pa", components="xx,zz,xz")


class _ProfilesPart:
    def __init__(self, cfg: Config, shape, walls) -> None:
        self.shape = shape
        self.bins = wall_bins(walls.ax, walls.ay, walls.bx, walls.by, regions.bin_length(cfg))
        self.z_edges = regions.profile_edges(cfg, shape)
        self.width = regions.strip_width(cfg)
        dz = np.diff(self.z_edges)
        self.strip_area = self.width * dz
        self.slice_area = np.array([shape.area_below(b) - shape.area_below(a)
                                    for a, b in zip(self.z_edges[:-1], self.z_edges[1:])])
        self.thickness = cfg.material.thickness
        self.normal: list = []
        self.shear: list = []
        self.left: list = []
        self.right: list = []
        self.slices: list = []

    def record(self, rd: Reading) -> None:
        # along each wall from its end A where it is now: a sliding gate's bins move with it
        sn, tau = wall_stress(self.bins, rd.wall_ax, rd.wall_az, rd.w_wall, rd.w_cx, rd.w_cz,
                              rd.w_fx, rd.w_fz, self.thickness)
        self.normal.append(sn)
        self.shear.append(tau)
        dl, dr = regions.edge_distance(self.shape, rd.x, rd.z)
        args = (rd.moments, rd.z)
        self.left.append(binned_stress(*args, dl < self.width, self.z_edges, self.strip_area,
                                       self.thickness))
        self.right.append(binned_stress(*args, dr < self.width, self.z_edges, self.strip_area,
                                        self.thickness))
        self.slices.append(binned_stress(*args, np.ones(rd.n, bool), self.z_edges,
                                         self.slice_area, self.thickness))

    def arrays(self) -> dict[str, np.ndarray]:
        nb, nz = self.bins.wall.size, self.z_edges.size - 1
        return {"normal": _stack(self.normal, (nb,)), "shear": _stack(self.shear, (nb,)),
                "left": _stack(self.left, (nz, 3)), "right": _stack(self.right, (nz, 3)),
                "slices": _stack(self.slices, (nz, 3))}

    def restore(self, state: dict[str, Any]) -> None:
        for k in ("normal", "shear", "left", "right", "slices"):
            setattr(self, k, list(np.asarray(state[f"profiles.{k}"])))

    def write(self, g: h5py.Group) -> None:
        a = self.arrays()
        b = self.bins
        wg = g.create_group("wall_bins")
        _dataset(wg, "wall", b.wall, "-")
        for key in ("s0", "s1", "x", "z"):
            _dataset(wg, key, getattr(b, key), "m")
        _dataset(wg, "tangent", b.tangent, "-")
        _dataset(wg, "normal_vector", b.normal, "-")
        _dataset(wg, "normal", a["normal"], "Pa",
                 meaning="pressure of the grains on the wall, per bin")
        _dataset(wg, "shear", a["shear"], "Pa",
                 meaning="shear traction on the wall along its tangent A->B, per bin")
        pg = g.create_group("profiles")
        _dataset(pg, "z_edges", self.z_edges, "m")
        pg.attrs["strip_width"] = self.width
        for key in ("left", "right", "slices"):
            _dataset(pg, key, a[key], "Pa", components="xx,zz,xz; compression positive")


class _FlowPart:
    def __init__(self, cfg: Config, shape) -> None:
        m = cfg.measure
        self.shape = shape
        self.delay, self.window = m.discharge_delay, m.window
        self.d = regions.mean_diameter(cfg)
        self.room = outlet_room(cfg)  # beside the outlet's span [m]
        self.g = cfg.gravity  # [m/s^2]
        cell = regions.grid_cell(cfg)
        self.x_edges, self.z_edges = regions.grid_edges(shape, cell)
        self.mfi_band = (np.nan, np.nan)  # set when the gate opens, from the fill level
        self.t_open = np.nan
        self.uid0 = np.zeros(0, dtype=np.int64)
        self.x0 = self.z0 = self.r0 = self.exit_time = self.max_disp = np.zeros(0)
        self.window_disp = np.zeros(0)  # max_disp as it stood at the discharge window's end
        self.lost = np.zeros(0, dtype=bool)  # lost before the discharge (``begin``)
        self.lost_later = np.zeros(0, dtype=bool)  # lost through a wall after (``lose``)
        shape2 = (self.x_edges.size - 1, self.z_edges.size - 1)
        self.grid = np.zeros((3, *shape2))  # sum vx, sum vz, count
        self.grid_samples = 0
        self.mfi_rows: list = []
        self.snapshot: Snapshot | None = None

    def start(self, run: SiloRun) -> None:
        """The gate opens: note every grain's place (``begin``)."""
        p = run.sim.particles
        self.begin(run.sim.time, p.view("uid").copy(), p.view("x").copy(),
                   p.view("y").copy(), p.view("radius").copy(), run.fill_level())

    def begin(self, t_open: float, uid: np.ndarray, x: np.ndarray, z: np.ndarray,
              r: np.ndarray, fill_level: float) -> None:
        """The gate opens at ``t_open`` [s] on the grains ``uid`` at (x, z) [m] of radii r [m]:
        note their places; mark the grains lost before the discharge (centre outside the
        silo, ``SiloShape.pushed_out``: through a wall, pushed by too soft contacts while
        filling; they did not discharge, so they get no exit time and no displacement, NaN,
        and the procedure counts them as lost wherever they fall); fit the
        mass-flow-index band (one diameter above the junction, a third of the remaining fill
        up to ``fill_level`` [m], between one diameter and B/2 high) under the free surface."""
        self.t_open = float(t_open)
        lo = regions.reference_height(self.shape, 0.0) + self.d
        height = float(np.clip((fill_level - lo) / 3.0, self.d, 0.5 * self.shape.width))
        self.mfi_band = (lo, lo + height)
        self.uid0 = np.asarray(uid, dtype=np.int64).copy()
        self.x0, self.z0, self.r0 = (np.asarray(v, dtype=float).copy() for v in (x, z, r))
        self.lost = self.shape.pushed_out(self.x0, self.z0, self.room)
        self.lost_later = np.zeros(self.uid0.size, dtype=bool)
        self.exit_time = np.full(self.uid0.size, np.nan)
        self.max_disp = np.where(self.lost, np.nan, 0.0)
        self.window_disp = self.max_disp.copy()

    def lose(self, uids: np.ndarray) -> None:
        """The grains ``uids`` left through a wall after the gate opened (the procedure's
        ``grains_lost``): they did not discharge, so what was recorded of them is undone (an
        exit time given while their centre was under the floor, their displacement: NaN),
        and they are followed no more."""
        if not np.isfinite(self.t_open):
            return
        hit = np.isin(self.uid0, uids) & ~self.lost  # (one lost before is not lost twice)
        self.lost_later |= hit
        self.exit_time[hit] = np.nan
        self.max_disp[hit] = np.nan
        self.window_disp[hit] = np.nan

    def record(self, run: SiloRun | None, rd: Reading) -> None:
        """One sample ``rd`` after the gate opened: the tracked grains absent from it or with
        their centre below the outlet (z < 0, ``SiloShape.came_through_outlet``) have left, at
        this sample's time after the opening unless they had left before; the others' largest
        displacement grows.  The grains lost (before the discharge, or through a wall since)
        are not followed.  (``run`` is read only for the snapshot in the middle of the
        discharge window.)"""
        if not np.isfinite(self.t_open):
            return
        t = rd.time - self.t_open
        order = np.argsort(rd.uid)
        pos = np.searchsorted(rd.uid[order], self.uid0)
        pos = np.clip(pos, 0, max(rd.n - 1, 0))
        idx = order[pos] if rd.n else pos
        present = (rd.uid[idx] == self.uid0) if rd.n else np.zeros(self.uid0.size, bool)
        if rd.n:  # under the silo: left through the outlet, or pushed through a wall (``lose``)
            present &= (rd.z[idx] >= 0.0) | ~self.shape.came_through_outlet(
                rd.x[idx], rd.z[idx], rd.vx[idx], rd.vz[idx], self.g, self.room)
        followed = ~(self.lost | self.lost_later)
        gone = ~present & np.isnan(self.exit_time) & followed
        self.exit_time[gone] = t
        present &= followed
        if rd.n:
            k = idx[present]
            disp = np.hypot(rd.x[k] - self.x0[present], rd.z[k] - self.z0[present])
            self.max_disp[present] = np.maximum(self.max_disp[present], disp)
            if t <= self.delay + self.window:  # the dead zone's horizon (``dead_zone``)
                self.window_disp[present] = self.max_disp[present]
        if rd.n == 0:
            return
        if self.in_window(rd):
            self._grid(rd)
            if self.snapshot is None and t >= self.delay + 0.5 * self.window:
                self.snapshot = take_snapshot(run)
        self._mfi(rd, t)

    def in_window(self, rd: Reading) -> bool:
        """Whether the sample ``rd`` is in the discharge window (and holds grains)."""
        t = rd.time - self.t_open
        return rd.n > 0 and bool(self.delay <= t <= self.delay + self.window)

    def _grid(self, rd: Reading) -> None:
        flat, ok = regions.grid_cell_index(rd.x, rd.z, self.x_edges, self.z_edges)
        size = self.grid.shape[1] * self.grid.shape[2]
        for c, w in enumerate((rd.vx[ok], rd.vz[ok], np.ones(int(ok.sum())))):
            self.grid[c] += np.bincount(flat, weights=w, minlength=size).reshape(
                self.grid.shape[1:])
        self.grid_samples += 1

    def _mfi(self, rd: Reading, t: float) -> None:
        lo, hi = self.mfi_band
        band = (rd.z >= lo) & (rd.z < hi)
        dl, dr = regions.edge_distance(self.shape, rd.x, rd.z)
        near = band & ((dl < self.d) | (dr < self.d))
        axis = band & (np.abs(rd.x - 0.5 * self.shape.width) < self.d)
        self.mfi_rows.append((t, rd.vz[near].mean() if near.any() else np.nan,
                              rd.vz[axis].mean() if axis.any() else np.nan, near.sum(),
                              axis.sum(), top_of_grains(rd.z, rd.r)))

    def state(self) -> dict[str, Any]:
        out: dict[str, Any] = {"flow.t_open": self.t_open, "flow.uid0": self.uid0,
                               "flow.x0": self.x0, "flow.z0": self.z0, "flow.r0": self.r0,
                               "flow.exit_time": self.exit_time, "flow.max_disp": self.max_disp,
                               "flow.window_disp": self.window_disp,
                               "flow.lost": self.lost, "flow.lost_later": self.lost_later,
                               "flow.grid": self.grid, "flow.grid_samples": self.grid_samples,
                               "flow.mfi": _stack(self.mfi_rows, (6,)),
                               "flow.mfi_band": np.array(self.mfi_band)}
        if self.snapshot is not None:
            s = self.snapshot
            out["flow.snap.time"] = s.time
            out["flow.snap.walls_active"] = s.walls_active
            for sub in ("particles", "contacts", "wall_contacts"):
                for key, arr in getattr(s, sub).items():
                    out[f"flow.snap.{sub}.{key}"] = arr
        return out

    def restore(self, state: dict[str, Any]) -> None:
        self.t_open = float(state["flow.t_open"])
        for key in ("uid0", "x0", "z0", "r0", "exit_time", "max_disp", "grid"):
            setattr(self, key, np.array(state[f"flow.{key}"]))
        if "flow.lost" in state:
            self.lost = np.array(state["flow.lost"], dtype=bool)
        else:  # a checkpoint written before the flag: from the grains' places at the opening,
            # and what was recorded of those grains undone (they had the first exit time)
            self.lost = self.shape.pushed_out(self.x0, self.z0, self.room)
            self.exit_time[self.lost] = np.nan
            self.max_disp = np.where(self.lost, np.nan, self.max_disp)
        # a checkpoint written before the window's own record: the largest displacement so
        # far, which bounds it from above (a grain called dead is dead; a few may be missed)
        self.window_disp = np.array(state.get("flow.window_disp", self.max_disp), dtype=float)
        self.lost_later = (np.array(state["flow.lost_later"], dtype=bool)
                           if "flow.lost_later" in state else np.zeros(self.uid0.size, bool))
        self.grid_samples = int(state["flow.grid_samples"])
        self.mfi_band = tuple(float(v) for v in state["flow.mfi_band"])
        self.mfi_rows = [tuple(r) for r in np.asarray(state["flow.mfi"]).tolist()]
        if "flow.snap.time" in state:
            parts: dict[str, dict[str, np.ndarray]] = {"particles": {}, "contacts": {},
                                                        "wall_contacts": {}}
            for key, val in state.items():
                if key.startswith("flow.snap.") and key.count(".") == 3:
                    _, _, sub, name = key.split(".")
                    parts[sub][name] = np.array(val)
            self.snapshot = Snapshot(float(state["flow.snap.time"]), parts["particles"],
                                     parts["contacts"], parts["wall_contacts"],
                                     np.array(state["flow.snap.walls_active"]))

    def write(self, g: h5py.Group) -> None:
        f = g.create_group("flow")
        f.attrs["t_open"] = self.t_open
        f.attrs["window_start"] = self.delay
        f.attrs["window"] = self.window
        f.attrs["mfi_band_lo"], f.attrs["mfi_band_hi"] = self.mfi_band
        _dataset(f, "uid", self.uid0, "-")
        _dataset(f, "x0", self.x0, "m")
        _dataset(f, "z0", self.z0, "m")
        _dataset(f, "r0", self.r0, "m")
        _dataset(f, "exit_time", self.exit_time, "s", meaning="time after the gate opened at "
                 "which the grain left (NaN: still inside, or lost through a wall)")
        _dataset(f, "max_displacement", self.max_disp, "m", meaning="largest distance from "
                 "its place at the gate opening (NaN: lost through a wall)")
        _dataset(f, "max_displacement_window", self.window_disp, "m", meaning="largest "
                 "distance from its place at the gate opening up to the end of the discharge "
                 "window (window_start + window after the opening), the dead zone's horizon "
                 "(NaN: lost through a wall)")
        _dataset(f, "lost_before_discharge", self.lost, "-", meaning="the grain's centre was under "
                 "the floor (z < 0 away from the outlet) or beyond a wall when the gate "
                 "opened: lost through a wall while filling, not discharged")
        _dataset(f, "lost_during_discharge", self.lost_later, "-", meaning="the grain left through "
                 "a wall after the gate opened (pushed through it), not through the outlet")
        grid = f.create_group("grid")
        _dataset(grid, "x_edges", self.x_edges, "m")
        _dataset(grid, "z_edges", self.z_edges, "m")
        count = self.grid[2]
        with np.errstate(invalid="ignore", divide="ignore"):
            _dataset(grid, "vx", np.where(count > 0, self.grid[0] / count, np.nan), "m/s")
            _dataset(grid, "vz", np.where(count > 0, self.grid[1] / count, np.nan), "m/s")
            _dataset(grid, "occupancy", count / max(self.grid_samples, 1), "-",
                     meaning="mean number of grain centres in the cell per sample")
        grid.attrs["samples"] = self.grid_samples
        mfi = _stack(self.mfi_rows, (6,))
        m = f.create_group("mass_flow_index")
        for k, (key, unit) in enumerate((("time", "s"), ("v_wall", "m/s"), ("v_axis", "m/s"),
                                         ("n_wall", "-"), ("n_axis", "-"), ("level", "m"))):
            _dataset(m, key, mfi[:, k], unit)
        if self.snapshot is not None:
            write_snapshot(g.create_group("discharge_snapshot"), self.snapshot)


class MeasureRecorder(Recorder):
    """Circles, wall and edge profiles, and discharge flow, sampled every ``measure.interval``."""

    name = "measure"
    key = "measure.interval"

    def __init__(self, cfg: Config) -> None:
        super().__init__(cfg.measure.interval)
        shape = silo_shape(cfg)
        walls = build_walls(cfg)
        self.circles = _CirclesPart(cfg, shape)
        self.profiles = _ProfilesPart(cfg, shape, walls)
        self.flow = _FlowPart(cfg, shape)
        self.fields = FieldsPart(cfg, shape)
        self.rows: list[tuple[float, float, float]] = []  # time, step, phase

    def record(self, run: SiloRun) -> None:
        rd = read_simulation(run.sim)
        phase = PHASE_CODES[run.phase]
        self.rows.append((rd.time, rd.step, phase))
        self.circles.record(rd)
        self.profiles.record(rd)
        if phase == DISCHARGE:
            self.flow.record(run, rd)
            if self.flow.in_window(rd):
                self.fields.add("discharge", rd)

    def grains_lost(self, run: SiloRun, uids: np.ndarray) -> None:
        self.flow.lose(uids)

    def phase_ended(self, run: SiloRun, phase: str) -> None:
        if phase == "settle":
            self.fields.add("settled", read_simulation(run.sim))
            if run.cfg.discharge.enabled:
                self.flow.start(run)

    def state(self) -> dict[str, Any]:
        out: dict[str, Any] = {"rows": _stack(self.rows, (3,))}
        out.update({f"circles.{k}": v for k, v in self.circles.arrays().items()})
        out.update({f"profiles.{k}": v for k, v in self.profiles.arrays().items()})
        out.update(self.flow.state())
        out.update(self.fields.state())
        return out

    def restore(self, state: dict[str, Any]) -> None:
        self.rows = [tuple(r) for r in np.asarray(state["rows"]).tolist()]
        self.circles.restore(state)
        self.profiles.restore(state)
        self.flow.restore(state)
        self.fields.restore(state)

    def write(self, group: h5py.Group) -> None:
        rows = _stack(self.rows, (3,))
        _dataset(group, "time", rows[:, 0], "s")
        _dataset(group, "step", rows[:, 1].astype(np.int64), "-")
        _dataset(group, "phase", rows[:, 2].astype(np.int8), "-",
                 codes=PHASE_CODES_TEXT)
        group.attrs["interval"] = self.interval
        self.circles.write(group)
        self.profiles.write(group)
        self.flow.write(group)
        self.fields.write(group, _dataset)


def recorders_for(cfg: Config) -> list[Recorder]:
    """The measurement recorders a run of ``cfg`` needs (pass to ``SiloRun(recorders=...)``)."""
    return [MeasureRecorder(cfg)]
