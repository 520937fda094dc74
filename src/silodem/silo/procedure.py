"""The silo procedure of the paper's Fig. 1: fill, settle to equilibrium, discharge.

``SiloRun`` builds the simulation from a validated ``Config`` and drives it through the phases.
The phases only add grains (filling), remove grains (discharge) and toggle the gate; the physics
is the engine's.  A time series is sampled every ``output.sample_interval`` seconds, and the
state at the end of settling and at the end of the run is kept as snapshots.
"""

from __future__ import annotations

import math
import time as wallclock
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from silodem.config import Config
from silodem.engine import quantities as q
from silodem.engine.particles import Particles
from silodem.engine.simulation import Simulation
from silodem.silo.checks import choose_time_step, estimate_overlap, grain_law
from silodem.silo.geometry import GATE, build_walls, silo_shape

PHASES = ("fill", "settle", "discharge")
_BATCH_INTERVAL = 0.05  # pouring: grains are placed in batches this often [s]
_CHECK_INTERVAL = 0.05  # equilibrium / discharge checks this often [s]
_PLACEMENT_TRIES = 40  # random positions tried per grain before waiting for room


@dataclass
class Progress:
    """What a progress display shows."""

    phase: str
    time: float  # simulated time [s]
    particles: int
    steps: int
    steps_per_s: float
    detail: str = ""


@dataclass
class Snapshot:
    """A copy of the grains and contacts at one moment (arrays over the live grains)."""

    time: float
    particles: dict[str, np.ndarray]
    contacts: dict[str, np.ndarray]
    wall_contacts: dict[str, np.ndarray]
    walls_active: np.ndarray  # which walls were in place [bool per wall]


@dataclass
class TimeSeries:
    columns: tuple[str, ...] = (
        "time", "phase", "kinetic_energy", "n_particles", "discharged_mass", "n_contacts",
        "n_wall_contacts", "force_ratio",
    )
    rows: list[tuple[float, ...]] = field(default_factory=list)

    def append(self, row: tuple[float, ...]) -> None:
        self.rows.append(row)

    def as_arrays(self) -> dict[str, np.ndarray]:
        data = np.array(self.rows, dtype=float).reshape(-1, len(self.columns))
        return {name: data[:, k] for k, name in enumerate(self.columns)}


class SiloRun:
    """One fill -> settle -> discharge run of a configured silo."""

    def __init__(self, cfg: Config, on_progress: Callable[[Progress], None] | None = None) -> None:
        self.cfg = cfg
        self.on_progress = on_progress
        self.rng = np.random.default_rng(cfg.seed)
        self.shape = silo_shape(cfg)
        self.walls = build_walls(cfg)
        self.law = grain_law(cfg)
        self.dt, self.dt_crit = choose_time_step(cfg, self.law, self.walls.kn, self.walls.ks)
        m = cfg.material
        self.radii = self.rng.uniform(m.radius_min, m.radius_max, cfg.fill.n_particles)
        self.sim = Simulation(Particles(cfg.fill.n_particles), self.walls, self.law, self.dt,
                              gravity=cfg.gravity, skin=0.4 * 0.5 * (m.radius_min + m.radius_max))
        self.phase = "fill"
        self.series = TimeSeries()
        self.warnings: list[str] = []
        self.events: dict[str, float | str | int] = {}
        self.snapshots: dict[str, Snapshot] = {}
        self.discharged_mass = 0.0
        self.discharged_count = 0
        self.lost_count = 0
        self.lost_mass = 0.0
        self.z_remove = -4.0 * m.radius_max
        self._sample_every = max(1, round(cfg.output.sample_interval / self.dt))
        self._wall_t0 = wallclock.perf_counter()
        self._last_report = 0.0
        overlap = estimate_overlap(cfg)
        self.overlap_estimate = overlap
        if overlap.too_soft:
            self.warnings.append(overlap.warning())

    # --- driving the clock --------------------------------------------------------------------
    def _advance(self, n_steps: int) -> None:
        """Remove the grains that left the silo since the last call, then step.  Removing first
        keeps the contact lists current whenever control returns to the procedure."""
        sim = self.sim
        if self.phase == "discharge":
            self._remove_discharged(self.cfg.discharge.reinsert)
        self._remove_escaped()
        for _ in range(n_steps):
            sim.step()
            if sim.steps % self._sample_every == 0:
                self._sample()
        self._report()

    def _remove_escaped(self) -> None:
        """Remove grains that left the silo other than through the open outlet (pushed through
        a wall by too soft contacts, or thrown out) and say so once."""
        p, shape = self.sim.particles, self.shape
        x, y = p.view("x"), p.view("y")
        margin = 1.0 + 4.0 * self.cfg.material.radius_max
        out = (x < -margin) | (x > shape.width + margin) | (y > shape.wall_top + 20.0)
        if self.phase != "discharge":
            out |= y < self.z_remove
        if not np.any(out):
            return
        count = int(np.count_nonzero(out))
        if self.lost_count == 0:
            self.warnings.append(
                f"grains lost: {count} grain(s) left the silo through a wall during {self.phase} "
                f"at t = {self.sim.time:.2f} s (contacts too soft or time step too large); they "
                "are removed and counted in events/lost_count"
            )
        self.lost_count += count
        self.lost_mass += float(np.sum(p.view("mass")[out]))
        self.events["lost_count"] = self.lost_count
        self.sim.remove(out)

    def _sample(self) -> None:
        sim = self.sim
        ngg, ngw = q.contact_count(sim)
        ratio = q.unbalanced_force_ratio(sim) if sim.particles.n else 0.0
        self.series.append((sim.time, PHASES.index(self.phase), sim.particles.kinetic_energy(),
                            sim.particles.n, self.discharged_mass, ngg, ngw,
                            ratio if math.isfinite(ratio) else np.nan))

    def _report(self, detail: str = "", force: bool = False) -> None:
        if self.on_progress is None:
            return
        now = wallclock.perf_counter()
        if not force and now - self._last_report < 0.2:
            return
        self._last_report = now
        elapsed = max(now - self._wall_t0, 1e-9)
        self.on_progress(Progress(self.phase, self.sim.time, self.sim.particles.n,
                                  self.sim.steps, self.sim.steps / elapsed, detail))

    def _steps(self, seconds: float) -> int:
        return max(1, round(seconds / self.dt))

    # --- the procedure ------------------------------------------------------------------------
    def run(self) -> None:
        self.fill()
        self.settle()
        self.snapshots["settled"] = self.snapshot()
        if self.cfg.discharge.enabled:
            self.discharge()
        self.snapshots["final"] = self.snapshot()
        self._report(force=True)

    def fill(self) -> None:
        """Place all grains: poured at a controlled rate, or generated loose at once."""
        self.phase = "fill"
        t0 = self.sim.time
        if self.cfg.fill.method == "loose":
            self._place_loose()
        else:
            self._pour()
        self.events["fill_time"] = self.sim.time - t0

    def _pour(self) -> None:
        f = self.cfg.fill
        n_total = f.n_particles
        placed = 0
        t0 = self.sim.time
        while placed < n_total:
            elapsed = self.sim.time - t0
            if elapsed > f.max_time:
                self.warnings.append(
                    f"pouring stopped after fill.max_time = {f.max_time} s with {placed} of "
                    f"{n_total} grains placed: no room in the pouring band"
                )
                break
            target = min(n_total, math.ceil(f.rate * (elapsed + _BATCH_INTERVAL)))
            if target > placed:
                placed += self._insert(self.radii[placed:target], -f.initial_speed)
            self._advance(self._steps(_BATCH_INTERVAL))
        self.events["n_poured"] = placed

    def _insert(self, radii: np.ndarray, vy: float) -> int:
        """Place grains at random free spots of the pouring band; return how many fit."""
        f, shape, p = self.cfg.fill, self.shape, self.sim.particles
        top = shape.wall_top
        bottom = top - f.band_height
        rmax = self.cfg.material.radius_max
        near = p.view("y") > bottom - 2.0 * rmax
        ox, oy, orad = p.view("x")[near], p.view("y")[near], p.view("radius")[near]
        new_x: list[float] = []
        new_y: list[float] = []
        new_r: list[float] = []
        for r in radii:
            for _ in range(_PLACEMENT_TRIES):
                z = self.rng.uniform(bottom + r, top - r)
                lo, hi = shape.inner_x_range(z)
                if hi - lo <= 2 * r:
                    continue
                x = self.rng.uniform(lo + r, hi - r)
                ax = np.concatenate([ox, new_x])
                ay = np.concatenate([oy, new_y])
                ar = np.concatenate([orad, new_r])
                if ax.size and np.any((ax - x) ** 2 + (ay - z) ** 2 < (ar + r) ** 2):
                    continue
                new_x.append(x)
                new_y.append(z)
                new_r.append(r)
                break
            else:
                break  # the band is full: the rest waits for the next batch
        if new_x:
            p.add(np.array(new_x), np.array(new_y), np.array(new_r), self.cfg.material.density,
                  self.cfg.material.thickness, vy=vy)
            self.sim.invalidate()
        return len(new_x)

    def _place_loose(self) -> None:
        """All grains at once on a jittered square lattice filling the silo from the bottom."""
        m, shape = self.cfg.material, self.shape
        spacing = 2.0 * m.radius_max * 1.05
        xs: list[float] = []
        ys: list[float] = []
        z = spacing / 2
        while len(xs) < self.radii.size:
            if z > shape.wall_top - m.radius_max:
                from silodem.errors import InputError

                raise InputError(
                    f"fill.n_particles = {self.radii.size} grains do not fit loose in the silo "
                    f"(room for {len(xs)}); raise silo.wall_height or use fill.method = 'pour'"
                )
            lo, hi = shape.inner_x_range(z - spacing / 2)
            lo2, hi2 = shape.inner_x_range(z + spacing / 2)
            lo, hi = max(lo, lo2), min(hi, hi2)
            count = int((hi - lo) / spacing)
            for k in range(count):
                xs.append(lo + spacing * (k + 0.5))
                ys.append(z)
            z += spacing
        n = self.radii.size
        jitter = 0.5 * (spacing - 2.0 * self.radii)
        x = np.array(xs[:n]) + self.rng.uniform(-1, 1, n) * jitter
        self.sim.particles.add(x, np.array(ys[:n]), self.radii, m.density, m.thickness)
        self.sim.invalidate()
        self.events["n_poured"] = n

    def settle(self) -> None:
        """Run until the equilibrium criterion is met (or settle.max_time passes)."""
        self.phase = "settle"
        s = self.cfg.settle
        t0 = self.sim.time
        value = float("inf")
        while True:
            self._advance(self._steps(_CHECK_INTERVAL))
            elapsed = self.sim.time - t0
            if s.criterion == "force_ratio":
                value = q.unbalanced_force_ratio(self.sim)
            else:
                value = q.mean_kinetic_energy(self.sim)
            self._report(f"{s.criterion} {value:.2e}")
            if elapsed >= s.min_time and value < s.threshold:
                break
            if elapsed >= s.max_time:
                self.warnings.append(
                    f"not settled: {s.criterion} = {value:.3g} is still above settle.threshold = "
                    f"{s.threshold:g} after settle.max_time = {s.max_time} s; discharging anyway"
                )
                break
        self.events["settle_time"] = self.sim.time - t0
        self.events["settle_criterion_value"] = value
        self.events["fill_level"] = self.fill_level()

    def fill_level(self) -> float:
        """Height of the top of the grains in the silo [m] (mean of the 5 highest tops)."""
        p = self.sim.particles
        if p.n == 0:
            return 0.0
        tops = p.view("y") + p.view("radius")
        return float(np.mean(np.sort(tops)[-min(5, p.n):]))

    def discharge(self) -> None:
        """Withdraw the gate; stop on the discharged fraction, the time limit or a clog."""
        self.phase = "discharge"
        d = self.cfg.discharge
        self.sim.set_wall_active(GATE, False)
        t0 = self.sim.time
        mass0 = self.sim.particles.total_mass()
        self.events["discharge_start_time"] = t0
        self.events["initial_mass"] = mass0
        self._last_exit = t0
        reason = "time"
        while True:
            self._advance(self._steps(_CHECK_INTERVAL))
            fraction = self.discharged_mass / mass0 if mass0 > 0 else 1.0
            self._report(f"discharged {100 * fraction:.0f}%")
            if fraction >= d.stop_fraction or (self.sim.particles.n == 0 and not d.reinsert):
                reason = "fraction"
                break
            if self.sim.time - t0 >= d.max_time:
                reason = "time"
                break
            if self.sim.time - self._last_exit >= d.clog_time:
                reason = "clog"
                self.warnings.append(
                    f"clogged: no grain left the silo for {d.clog_time} s "
                    f"(discharge.clog_time) at t = {self.sim.time:.2f} s; an arch blocks the "
                    f"outlet after {100 * fraction:.0f}% of the mass left"
                )
                break
        self.events["discharge_end_reason"] = reason
        self.events["discharge_time"] = self.sim.time - t0
        self.events["discharged_fraction"] = self.discharged_mass / mass0 if mass0 > 0 else 0.0

    def _remove_discharged(self, reinsert: bool) -> None:
        p = self.sim.particles
        gone = p.view("y") < self.z_remove
        if not np.any(gone):
            return
        self._last_exit = self.sim.time
        self.discharged_mass += float(np.sum(p.view("mass")[gone]))
        self.discharged_count += int(np.count_nonzero(gone))
        radii = p.view("radius")[gone].copy()
        self.sim.remove(gone)
        if reinsert:
            self._insert(radii, 0.0)

    # --- read-outs ----------------------------------------------------------------------------
    def snapshot(self) -> Snapshot:
        sim, p = self.sim, self.sim.particles
        parts = {k: p.view(k).copy() for k in ("x", "y", "vx", "vy", "omega", "radius", "uid")}
        parts["fx"] = p.view("fx").copy()
        parts["fy"] = p.view("fy").copy()
        gc = q.grain_contacts(sim)
        wc = q.wall_contacts(sim)
        contacts = {"i": gc.i, "j": gc.j, "fn": gc.fn, "fs": gc.fs, "fx": gc.fx, "fy": gc.fy}
        wall_contacts = {"grain": wc.grain, "wall": wc.wall, "fn": wc.fn, "fs": wc.fs,
                         "fx": wc.fx, "fy": wc.fy}
        return Snapshot(sim.time, parts, contacts, wall_contacts, self.walls.active.copy())
