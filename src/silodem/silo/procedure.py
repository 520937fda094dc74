"""The silo procedure of the paper's Fig. 1: fill, settle to equilibrium, discharge.

``SiloRun`` builds the simulation from a validated ``Config`` and drives it through the phases
as a state machine: ``run()`` repeats ``advance_chunk()`` (one pouring batch or one check
interval of the current phase) until the phase is ``"done"``.  Everything the loop needs to go
on lives in ``self.state`` and in the simulation, so a run can be saved between two chunks and
continued (checkpoints).

The phases only add grains (filling), remove grains (discharge, escapes) and toggle the gate;
the physics is the engine's.  Recorders (``silodem.silo.recorders``) sample the state at their
own intervals and never change it.
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
from silodem.errors import InputError
from silodem.silo import sizes
from silodem.silo.checks import (
    PACKING_FRACTION,
    choose_time_step,
    estimate_overlap,
    grain_law,
    local_damping_warning,
    shallow_hopper_warning,
)
from silodem.silo.geometry import (
    GATE,
    SiloShape,
    build_walls,
    gate_opening_time,
    outlet_room,
    silo_shape,
)
from silodem.silo.recorders import Recorder, Snapshot, TimeSeries, take_snapshot

PHASES = ("fill", "settle", "discharge", "done")
LOST_TOTAL = "grains lost in all: "  # the warning that holds the running total
NOT_SETTLED = "not settled: "  # the warning of a settling that ended at settle.max_time
BATCH_INTERVAL = 0.05  # pouring: grains are placed in batches this often [s]
CHECK_INTERVAL = 0.05  # equilibrium / discharge checks this often [s]
_PLACEMENT_TRIES = 40  # random positions tried per grain before waiting for room


@dataclass
class Progress:
    """What a progress display shows."""

    phase: str
    time: float  # simulated time [s]
    particles: int
    steps: int
    steps_per_s: float  # mean since the first report; NaN at the first (whose wall time
    detail: str = ""    # holds the kernels' compilation: 600 steps/s for a run of 40,000)


@dataclass
class ProcedureState:
    """Where the procedure is: everything its loop needs to continue after a checkpoint."""

    phase: str = "fill"
    phase_start: float = 0.0  # simulated time at which the phase began [s]
    placed: int = 0  # grains placed in the silo so far
    criterion_value: float = math.inf  # last value of the settling criterion
    mass0: float = 0.0  # mass in the silo when the gate opened [kg]
    last_exit: float = 0.0  # time a grain last left through the outlet [s]
    discharged_mass: float = 0.0  # [kg]
    discharged_count: int = 0
    lost_mass: float = 0.0  # grains that left through a wall [kg]
    lost_count: int = 0
    lost_mass_discharge: float = 0.0  # of lost_mass, lost after the gate opened [kg]
    pending_radii: list[float] = field(default_factory=list)  # discharged, to re-insert [m]
    # uids of the grains outside the silo when the gate opened (SiloShape.pushed_out): lost,
    # wherever they fall (one under the floor may fall out under the outlet's span)
    pushed_out: list[int] = field(default_factory=list)


def neighbour_skin(cfg: Config) -> float:
    """Verlet-list skin of a silo run [m]: 0.4 mean grain radii."""
    return 0.4 * sizes.mean_radius(cfg.material)


def loose_spacing(radius_max: float) -> float:
    """Lattice spacing of the loose fill [m]: a largest grain's diameter plus 5 %."""
    return 2.0 * radius_max * 1.05


def loose_sites(shape: SiloShape, radius_max: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The first ``n`` sites (x, y) [m] of the loose fill's square lattice (``loose_spacing``),
    row by row from the bottom, each row across the silo's inside; InputError when fewer fit
    with the top row a largest grain's radius ``radius_max`` [m] under the top of the walls."""
    spacing = loose_spacing(radius_max)
    xs: list[float] = []
    ys: list[float] = []
    z = spacing / 2
    while len(xs) < n:
        if z > shape.wall_top - radius_max:
            raise InputError(
                f"fill.n_particles = {n} grains do not fit loose in the silo (room for "
                f"{len(xs)}); raise silo.wall_height or use fill.method = 'pour'"
            )
        lo, hi = shape.inner_x_range(z - spacing / 2)
        lo2, hi2 = shape.inner_x_range(z + spacing / 2)
        lo, hi = max(lo, lo2), min(hi, hi2)
        for k in range(int((hi - lo) / spacing)):
            xs.append(lo + spacing * (k + 0.5))
            ys.append(z)
        z += spacing
    return np.array(xs[:n]), np.array(ys[:n])


class SiloRun:
    """One fill -> settle -> discharge run of a configured silo."""

    def __init__(self, cfg: Config, on_progress: Callable[[Progress], None] | None = None,
                 recorders: list[Recorder] | None = None) -> None:
        self.cfg = cfg
        self.on_progress = on_progress
        self.rng = np.random.default_rng(cfg.seed)
        self.shape = silo_shape(cfg)
        self.walls = build_walls(cfg)
        # the segments as built, the gate closed: results.h5 /walls (a sliding gate moves)
        self.walls_built = {k: getattr(self.walls, k).copy() for k in ("ax", "ay", "bx", "by")}
        self.law = grain_law(cfg)
        self.dt, self.dt_crit = choose_time_step(cfg, self.law, self.walls.kn, self.walls.ks)
        m = cfg.material
        self.radii = sizes.draw_radii(m, cfg.fill.n_particles, self.rng)
        self.sim = Simulation(Particles(cfg.fill.n_particles), self.walls, self.law, self.dt,
                              gravity=cfg.gravity, skin=neighbour_skin(cfg))
        self.state = ProcedureState()
        self.series = TimeSeries(cfg.output.sample_interval)
        self.recorders: list[Recorder] = [self.series, *(recorders or [])]
        self.chunk_hooks: list[Callable[[SiloRun], None]] = []  # called between chunks
        self.warnings: list[str] = []
        # the source digest of the code that started the run (provenance.py), where a resume
        # goes on with other code; None: this code's own run
        self.started_by: str | None = None
        self.events: dict[str, float | str | int] = {}
        self.snapshots: dict[str, Snapshot] = {}
        self.z_remove = -4.0 * m.radius_max  # grains below this have left the silo [m]
        self._rate_from: tuple[float, int] | None = None  # (wall s, steps) at the 1st report
        self._last_report = 0.0
        self._reported_phase = ""
        self.overlap_estimate = estimate_overlap(cfg)
        if self.overlap_estimate.too_soft:
            self.warnings.append(self.overlap_estimate.warning())
        elif self.overlap_estimate.soft_shear:
            self.warnings.append(self.overlap_estimate.shear_warning())
        for warning in (shallow_hopper_warning(cfg), local_damping_warning(cfg)):
            if warning is not None:
                self.warnings.append(warning)
        self.warnings += [w for rec in self.recorders if (w := rec.volume_warning(self))]
        if (warning := self._early_window()) is not None:
            self.warnings.append(warning)

    @property
    def phase(self) -> str:
        return self.state.phase

    # --- the procedure ------------------------------------------------------------------------
    def run(self) -> None:
        """Run (or continue) to the end of the procedure."""
        self._rate_from = None
        while self.state.phase != "done":
            self.advance_chunk()
            for hook in self.chunk_hooks:
                hook(self)
        self._report(force=True)

    def advance_chunk(self) -> None:
        """One pouring batch or one check interval of the current phase, then its transition."""
        {"fill": self._fill_chunk, "settle": self._settle_chunk,
         "discharge": self._discharge_chunk}[self.state.phase]()

    def _begin(self, phase: str) -> None:
        ended = self.state.phase
        for rec in self.recorders:
            rec.phase_ended(self, ended)
        self.state.phase = phase
        self.state.phase_start = self.sim.time

    def _fill_chunk(self) -> None:
        """Place grains: poured at ``fill.rate`` in batches, or all at once ('loose')."""
        f, st = self.cfg.fill, self.state
        if f.method == "loose":
            self._place_loose()
        else:
            elapsed = self.sim.time - st.phase_start
            target = min(f.n_particles, math.ceil(f.rate * (elapsed + BATCH_INTERVAL)))
            if target > st.placed:
                st.placed += self._insert(self.radii[st.placed:target], -f.initial_speed)
        self._advance(self._steps(BATCH_INTERVAL))
        elapsed = self.sim.time - st.phase_start
        if st.placed < f.n_particles and elapsed > f.max_time:
            why = self._pour_stop_reason(elapsed)
            self.warnings.append(
                f"pouring stopped after fill.max_time = {f.max_time} s with {st.placed} of "
                f"{f.n_particles} grains placed: {why}"
            )
        if st.placed >= f.n_particles or elapsed > f.max_time:
            self.events["n_poured"] = st.placed
            self.events["fill_time"] = elapsed
            self._begin("settle")

    def _pour_stop_reason(self, elapsed: float) -> str:
        """Why pouring ended at fill.max_time short of fill.n_particles: the rate (it lets in
        fewer than asked, and at least half of those were placed), else no room in the
        pouring band, with the rate reached, and whether the grains placed would fill the
        silo up to the band at rest (their area at ``checks.PACKING_FRACTION``)."""
        f, st = self.cfg.fill, self.state
        allowed = f.rate * f.max_time  # what the rate lets in at most
        if allowed < f.n_particles and st.placed >= 0.5 * allowed:
            return f"fill.rate = {f.rate:g} grains/s pours only about {allowed:.3g} in that time"
        # the height the grains placed would fill at rest (the grains in the band are falling)
        area = float(np.sum(np.pi * self.radii[:st.placed] ** 2)) / PACKING_FRACTION
        band = self.shape.wall_top - f.band_height
        if self.shape.height_of_area(area) >= band - 2.0 * self.cfg.material.radius_max:
            return "no room in the pouring band: the silo is full up to it"
        return (f"no room in the pouring band for more: {st.placed / elapsed:.3g} grains/s "
                f"placed against fill.rate = {f.rate:g} (a batch places only the grains that "
                "find room); give a longer fill.max_time")

    def _settle_chunk(self) -> None:
        """Run until the equilibrium criterion is met (or settle.max_time passes)."""
        s, st = self.cfg.settle, self.state
        self._advance(self._steps(CHECK_INTERVAL))
        elapsed = self.sim.time - st.phase_start
        if s.criterion == "force_ratio":
            st.criterion_value = q.unbalanced_force_ratio(self.sim)
        else:
            st.criterion_value = q.mean_kinetic_energy(self.sim)
        self._report(f"{s.criterion} {st.criterion_value:.2e}")
        settled = elapsed >= s.min_time and st.criterion_value < s.threshold
        if not settled and elapsed < s.max_time:
            return
        if not settled:
            self.warnings.append(
                f"{NOT_SETTLED}{s.criterion} = {st.criterion_value:.3g} is still above "
                f"settle.threshold = {s.threshold:g} after settle.max_time = {s.max_time} s; "
                "going on anyway"
            )
        self.events["settle_time"] = elapsed
        self.events["settle_criterion_value"] = st.criterion_value
        self.events["fill_level"] = self.fill_level()
        self.snapshots["settled"] = take_snapshot(self)
        if self.cfg.discharge.enabled:
            self._begin("discharge")
            self._open_gate()
            p = self.sim.particles
            st.pushed_out = self.pushed_out_uids(p.view("x"), p.view("y"), p.view("uid"))
            st.mass0 = self.sim.particles.total_mass()
            st.last_exit = self.sim.time
            self.events["discharge_start_time"] = self.sim.time
            self.events["initial_mass"] = st.mass0
        else:
            self._finish()

    def _open_gate(self) -> None:
        """Start the discharge: the gate removed at once (the paper's), or set sliding
        sideways at ``discharge.gate_speed`` (towards +x, under the right-hand floor or hopper
        wall), to be removed once its trailing end has passed the outlet (``_gate_slid``)."""
        opening = gate_opening_time(self.cfg)
        if opening is None:
            self.sim.set_wall_active(GATE, False)
            return
        self.sim.set_wall_velocity(GATE, self.cfg.discharge.gate_speed, 0.0)
        self.events["gate_opening_time"] = opening

    def _early_window(self) -> str | None:
        """The warning of a discharge window that begins while a sliding gate still covers
        part of the outlet (its measurements are of a partly open outlet)."""
        opening, delay = gate_opening_time(self.cfg), self.cfg.measure.discharge_delay
        if opening is None or delay >= opening:
            return None
        return (f"the discharge window begins {delay:g} s after the gate begins to slide "
                f"(measure.discharge_delay), before the outlet is clear at {opening:.3g} s: "
                "its wall stresses, velocity field and flow pattern are of a partly open "
                f"outlet; give measure.discharge_delay >= {math.ceil(opening * 100) / 100:g} s "
                "to measure the open silo")

    def gate_sliding(self) -> bool:
        """Whether the gate is sliding open (``discharge.gate_speed``), not yet removed."""
        w = self.walls.index(GATE)
        return bool(self.walls.active[w] and self.walls.vx[w] != 0.0)

    def _gate_slid(self) -> None:
        """Remove a sliding gate once its trailing end has passed the outlet's right edge;
        the clog clock starts there (no grain may leave before the outlet is open)."""
        w = self.walls.index(GATE)
        if not (self.gate_sliding() and self.walls.ax[w] >= self.shape.outlet_right):
            return
        self.sim.set_wall_velocity(GATE, 0.0, 0.0)
        self.sim.set_wall_active(GATE, False)
        self.state.last_exit = max(self.state.last_exit, self.sim.time)

    def _discharge_chunk(self) -> None:
        """Gate withdrawn (or sliding open); stop on the discharged fraction (of the mass not
        lost through a wall: ``stop_fraction_of``), the time limit or a clog (not while the
        gate slides)."""
        d, st = self.cfg.discharge, self.state
        self._advance(self._steps(CHECK_INTERVAL))
        self._gate_slid()
        fraction = self.discharged_fraction()
        self._report(f"discharged {100 * fraction:.0f}%")
        elapsed = self.sim.time - st.phase_start
        if self.stop_fraction_of() >= d.stop_fraction or (self.sim.particles.n == 0
                                                          and not d.reinsert):
            reason = "fraction"
        elif elapsed >= d.max_time:
            reason = "time"
        elif self.sim.time - st.last_exit >= d.clog_time and not self.gate_sliding():
            reason = "clog"
            self.warnings.append(
                f"clogged: no grain left the silo for {d.clog_time} s (discharge.clog_time) at "
                f"t = {self.sim.time:.2f} s; an arch blocks the outlet after "
                f"{100 * fraction:.0f}% of the mass left"
            )
        else:
            return
        self.events["discharge_end_reason"] = reason
        self.events["discharge_time"] = elapsed
        self.events["discharged_fraction"] = fraction
        self._finish()

    def _finish(self) -> None:
        self.snapshots["final"] = take_snapshot(self)
        self._begin("done")

    # --- driving the clock --------------------------------------------------------------------
    def _advance(self, n_steps: int) -> None:
        """Remove the grains that left the silo since the last call, then step.  Removing first
        keeps the contact lists current whenever control returns to the procedure."""
        sim = self.sim
        self._remove_escaped()
        if self.state.phase == "discharge":
            self._remove_discharged()
        every = [rec.every_steps(self.dt) for rec in self.recorders]
        end = sim.steps + n_steps
        while sim.steps < end:
            # up to the next step at which a recorder samples (a multiple of its interval)
            due = min([end] + [(sim.steps // e + 1) * e for e in every])
            sim.run(due - sim.steps)
            for rec, e in zip(self.recorders, every):
                if sim.steps % e == 0:
                    rec.record(self)
        self._report()

    def _steps(self, seconds: float) -> int:
        return max(1, round(seconds / self.dt))

    def _report(self, detail: str = "", force: bool = False) -> None:
        if self.on_progress is None:
            return
        now = wallclock.perf_counter()
        new_phase = self.state.phase != self._reported_phase  # said at once: a log has a line
        if not force and not new_phase and now - self._last_report < 0.2:  # for every phase
            return
        self._last_report, self._reported_phase = now, self.state.phase
        if self._rate_from is None:
            self._rate_from = (now, self.sim.steps)
        wall_from, steps_from = self._rate_from
        rate = ((self.sim.steps - steps_from) / (now - wall_from) if now > wall_from
                else float("nan"))
        self.on_progress(Progress(self.state.phase, self.sim.time, self.sim.particles.n,
                                  self.sim.steps, rate, detail))

    # --- adding and removing grains -----------------------------------------------------------
    def _insert(self, radii: np.ndarray, vy: float) -> int:
        """Place grains at random free spots of the pouring band; return how many fit."""
        f, shape, p = self.cfg.fill, self.shape, self.sim.particles
        top = shape.wall_top
        bottom = top - f.band_height
        near = p.view("y") > bottom - 2.0 * self.cfg.material.radius_max
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
        m, st = self.cfg.material, self.state
        if st.placed:
            return
        spacing = loose_spacing(m.radius_max)
        xs, ys = loose_sites(self.shape, m.radius_max, self.radii.size)
        n = self.radii.size
        jitter = 0.5 * (spacing - 2.0 * self.radii)
        x = xs + self.rng.uniform(-1, 1, n) * jitter
        self.sim.particles.add(x, ys, self.radii, m.density, m.thickness)
        self.sim.invalidate()
        st.placed = n

    def _remove_discharged(self) -> None:
        p, st = self.sim.particles, self.state
        gone = p.view("y") < self.z_remove
        if np.any(gone):
            st.last_exit = self.sim.time
            st.discharged_mass += float(np.sum(p.view("mass")[gone]))
            st.discharged_count += int(np.count_nonzero(gone))
            if self.cfg.discharge.reinsert:
                st.pending_radii.extend(p.view("radius")[gone].tolist())
            self.sim.remove(gone)
        if st.pending_radii:
            placed = self._insert(np.array(st.pending_radii), 0.0)
            del st.pending_radii[:placed]

    def _remove_escaped(self) -> None:
        """Remove grains that left the silo other than through the open outlet (pushed through
        a wall by too soft contacts, or thrown out): far beside or above the silo, or under
        it while the gate is closed or not come through the open outlet
        (``SiloShape.came_through_outlet``; never one outside the silo when the gate opened,
        ``ProcedureState.pushed_out``); the recorders are told first
        (``Recorder.grains_lost``).  One warning names the first loss, and a second, rewritten
        at each later loss, holds the running total."""
        p, shape, st = self.sim.particles, self.shape, self.state
        x, y = p.view("x"), p.view("y")
        margin = 1.0 + 4.0 * self.cfg.material.radius_max
        out = (x < -margin) | (x > shape.width + margin) | (y > shape.wall_top + 20.0)
        under = y < self.z_remove
        if st.phase == "discharge":
            through = shape.came_through_outlet(x, y, p.view("vx"), p.view("vy"),
                                                self.cfg.gravity, outlet_room(self.cfg))
            if st.pushed_out:
                through &= ~np.isin(p.view("uid"), st.pushed_out)
            under &= ~through
        out |= under
        if not np.any(out):
            return
        for rec in self.recorders:
            rec.grains_lost(self, p.view("uid")[out])
        count = int(np.count_nonzero(out))
        if st.lost_count == 0:
            self.warnings.append(
                f"grains lost: {count} grain(s) left the silo through a wall during {st.phase} "
                f"at t = {self.sim.time:.2f} s (contacts too soft or time step too large); they "
                "are removed and counted in events/lost_count"
            )
        first = st.lost_count == 0
        st.lost_count += count
        st.lost_mass += float(np.sum(p.view("mass")[out]))
        if st.phase == "discharge":
            st.lost_mass_discharge += float(np.sum(p.view("mass")[out]))
        self.events["lost_count"] = st.lost_count
        self.sim.remove(out)
        if not first:
            self._note_lost_total()

    def _note_lost_total(self) -> None:
        """Put the running total of lost grains in the warnings (replacing the last total)."""
        st = self.state
        share = (f" ({100 * st.lost_count / st.placed:.0f}% of the {st.placed} poured)"
                 if st.placed else "")
        text = (f"{LOST_TOTAL}{st.lost_count} grain(s){share}, {st.lost_mass:.3g} kg, the last "
                f"during {st.phase} at t = {self.sim.time:.2f} s; the measurements describe the "
                "grains that stayed")
        old = [i for i, w in enumerate(self.warnings) if w.startswith(LOST_TOTAL)]
        if old:
            self.warnings[old[0]] = text
        else:
            self.warnings.append(text)

    # --- read-outs (never change the state) ---------------------------------------------------
    @property
    def discharged_mass(self) -> float:
        """Mass of the grains discharged so far [kg]."""
        return self.state.discharged_mass

    @property
    def discharged_count(self) -> int:
        return self.state.discharged_count

    def discharged_fraction(self) -> float:
        """Share of the mass in the silo at the gate's opening that has left through the
        outlet [-] (1 when there was none): ``/events`` ``discharged_fraction``."""
        st = self.state
        return st.discharged_mass / st.mass0 if st.mass0 > 0 else 1.0

    def stop_fraction_of(self) -> float:
        """The share ``discharge.stop_fraction`` is held against [-]: the discharged mass over
        the mass at the opening less the mass lost through a wall since (1 when none is left),
        so that grains that can never reach the outlet cannot keep the run from stopping."""
        st = self.state
        stayed = st.mass0 - st.lost_mass_discharge
        return st.discharged_mass / stayed if stayed > 0 else 1.0

    def pushed_out_uids(self, x: np.ndarray, y: np.ndarray, uid: np.ndarray) -> list[int]:
        """The uids of the grains at (x, y) [m] outside the silo (``SiloShape.pushed_out``):
        at the gate's opening, those lost wherever they fall (``ProcedureState.pushed_out``)."""
        out = self.shape.pushed_out(x, y, outlet_room(self.cfg))
        return [int(u) for u in np.asarray(uid)[out]]

    def fill_level(self) -> float:
        """Height of the top of the grains in the silo [m] (mean of the 5 highest tops)."""
        p = self.sim.particles
        return q.top_of_grains(p.view("y"), p.view("radius"))
