"""A DEM simulation: the state, the walls, the contact law and the one ordered timestep.

One step, in the order the code runs it (``Simulation.run``; ``step`` is ``run(1)``):

1. rebuild the neighbour list if two grains may have closed in by ``skin`` or a grain may have
   reached a wall since the last build (``list_validity``: the global test, then the test by
   cells), or grains/walls changed;
2. grain-grain contact forces (contact law on every candidate pair), summed per grain as they
   are computed (even strips of cell rows, then odd ones: race-free with threads);
3. per grain: its grain-wall contact forces, added to its sums, then integrate (leap-frog,
   gravity, optional local damping); note the displacements;
4. advance the clock (in the compiled loop); then move the walls that have a velocity (in
   Python, one step per call while any wall moves).

Nothing else changes the state inside a step: measurements read the arrays between steps.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from silodem.engine.contact import GrainLaw, pair_forces, pair_forces_hertz
from silodem.engine.integrate import walls_and_leapfrog, walls_and_leapfrog_hertz
from silodem.engine.list_validity import global_bound, list_expired, must_rebuild
from silodem.engine.neighbors import NeighborList
from silodem.engine.particles import Particles
from silodem.engine.walls import Walls
from silodem.errors import UnstableRunError
from silodem.jit import specialised


class Simulation:
    """Owns the particles, walls, neighbour list and clock.

    Parameters: ``law`` grain-grain contact parameters (series stiffnesses [N/m], or the
    moduli 2 E*, 8 G* [Pa] of the Hertz-Mindlin law), ``dt`` time step [s], ``gravity`` g
    [m/s^2] acting along -y, ``skin`` Verlet skin [m], ``cell_test`` whether the list is kept
    past the global test while the test by cells holds (``list_validity``; off: rebuilt as
    soon as the global test fails: ``list_validity.list_expired``, the displacements' bound
    against the skin).
    """

    def __init__(self, particles: Particles, walls: Walls, law: GrainLaw, dt: float,
                 gravity: float = 9.81, skin: float | None = None,
                 cell_test: bool = True) -> None:
        if dt <= 0:
            raise ValueError("time step must be positive")
        self.particles = particles
        self.walls = walls
        self.law = law
        self.dt = float(dt)
        self.gravity = float(gravity)
        if skin is None:
            r = particles.view("radius")
            skin = 0.4 * float(r.mean()) if r.size else 0.01
        self.neighbors = NeighborList(skin)
        self.cell_test = bool(cell_test)
        self.time = 0.0
        self.steps = 0
        self._stale = True  # the neighbour list must be rebuilt before the next force pass
        # called with the simulation right before each neighbour-list build: the place to move
        # grains across a periodic boundary, as LAMMPS remaps atoms only when it re-neighbours
        self.before_rebuild: list = []
        self._drift = 0.0  # largest grain displacement since the last rebuild [m]
        self._wall_drift = 0.0
        self._spread = (0.0, 0.0, 0.0, 0.0)  # bounding box of the displacements [m]

    # --- changes of the system between steps -------------------------------------------------
    def invalidate(self) -> None:
        """Grains were added, removed or moved, or walls changed: rebuild before the next step."""
        self._stale = True

    def set_wall_active(self, name: str, active: bool) -> None:
        self.walls.set_active(name, active)
        self.invalidate()

    def set_wall_velocity(self, name: str, vx: float, vy: float) -> None:
        """Give wall ``name`` the velocity (vx, vy) [m/s] from the next step on (step 4)."""
        w = self.walls.index(name)
        self.walls.vx[w], self.walls.vy[w] = vx, vy

    def remove(self, mask: np.ndarray) -> None:
        """Remove the grains where ``mask`` (over the live grains) is True."""
        self.particles.keep(~mask)
        self.invalidate()

    # --- the timestep ------------------------------------------------------------------------
    def step(self) -> None:
        self.run(1)

    def run(self, n_steps: int) -> None:
        """Advance ``n_steps`` timesteps (the order is in the module docstring).

        Steps 1 (the list) and 4 (walls) run here; steps 2-3 run in a compiled loop
        (``serial_steps`` or ``threaded_steps``) for as many steps as the list stays valid (it
        saves Python's dispatch of each step, a tenth of a step below about 1e4 grains, and
        more with threads), or one step per call while a wall moves.  The threaded kernels
        are used from ``jit.PARALLEL_MIN_GRAINS`` grains on; they give the same bits as the
        serial ones."""
        p, nb, w, law, dt = self.particles, self.neighbors, self.walls, self.law, self.dt
        left = int(n_steps)
        walls_move = w.moving()
        while left > 0:
            if self._stale or self._list_expired():
                self._rebuild_list()
            threads = numba.get_num_threads()  # asked once: it takes a lock
            threaded = pair_forces.pick(p.n, threads) is pair_forces.parallel
            done, time, max_d2, *self._spread = STEPS[threaded, law.hertz](
                1 if walls_move else left, nb.strip_start, nb.blocks(threads if threaded else 1),
                nb.i_start, nb.i_apart, nb.pair_j, nb.pair_fs, nb.pair_fn,
                nb.w_start, nb.wc_w, nb.wc_fs, nb.wc_fn, nb.wc_fx, nb.wc_fy,
                w.arrays(), p.x, p.y, p.vx, p.vy, p.omega, p.radius, p.mass, p.inv_mass,
                p.fx, p.fy, p.torque, p.x_ref, p.y_ref, law.kn, law.ks, law.mu, law.zeta,
                law.allow_tension, law.local_damping, self.gravity, dt, nb.skin,
                self._wall_drift, self.time, nb.step_report(threads if threaded else 1),
                # not while walls move: their drift grows after the leap-frog's report
                self.cell_test and not walls_move, nb.wall_gap, nb.fast, nb.cell_grid,
                nb.cell_start, self._drift, *self._spread)
            self.steps += done
            self.time = time
            left -= done
            if not np.isfinite(max_d2):
                raise UnstableRunError(
                    f"non-finite grain displacement at t = {self.time:.6g} s (step {self.steps}): "
                    "the run is unstable (a time step too large for its contacts, or extreme "
                    "values of density, gravity or speed)"
                )
            self._drift = float(np.sqrt(max_d2))
            if walls_move:  # step 4, one step at a time
                self._wall_drift += w.advance(dt)

    def _rebuild_list(self) -> None:
        """Step 1's build: the hooks (``before_rebuild``), then the neighbour list, which
        becomes the reference of the displacements (drifts and their box back to 0)."""
        for hook in self.before_rebuild:
            hook(self)
        self.neighbors.rebuild(self.particles, self.walls)
        self._stale = False
        self._wall_drift = 0.0
        self._drift, self._spread = 0.0, (0.0, 0.0, 0.0, 0.0)

    def _past_global_test(self) -> bool:
        """Whether the global test alone would rebuild the list (``list_validity``)."""
        bound = global_bound(self._drift, *self._spread)
        return list_expired(bound, self._drift, self._wall_drift, self.neighbors.skin)

    def _list_expired(self) -> bool:
        """Whether the Verlet list may miss a contact (``list_validity``: the global test,
        and if that fails and ``cell_test`` is on, the test by cells on the last step's
        report)."""
        nb, p = self.neighbors, self.particles
        return must_rebuild(global_bound(self._drift, *self._spread), self._drift,
                            self._wall_drift, nb.skin, self.cell_test, p.n, nb.report, nb.fast,
                            p.x, p.y, p.x_ref, p.y_ref, p.radius, nb.i_start, nb.pair_j,
                            nb.cell_grid, nb.cell_start)


# the kernels ``_steps`` calls; each compiled copy below binds them to one variant
_pair_forces = pair_forces.serial
_walls_and_leapfrog = walls_and_leapfrog.serial


def _steps(max_steps, strip_start, blocks, i_start, i_apart, pair_j, pair_fs, pair_fn,
           w_start, wc_w, wc_fs, wc_fn, wc_fx, wc_fy, walls,
           x, y, vx, vy, omega, radius, mass, inv_mass, fx, fy, torque, x_ref, y_ref,
           kn, ks, mu, zeta, allow_tension, local_damping, gravity, dt, skin,
           wall_drift, time, runs, cell_test, wall_gap, fast, cell_grid, cell_start,
           drift, lox, hix, loy, hiy):
    """Steps 2 and 3, repeated up to ``max_steps`` times and until the neighbour list expires
    (``list_validity``: the global test, then if ``cell_test`` the test by cells on the
    leap-frog's report in ``runs``) or a position is not finite.  The leap-frog lists
    the fast grains for the test by cells only on steps that follow one whose global bound
    (from ``drift`` and the box ``lox, hix, loy, hiy`` of the displacements [m], those of the
    step before this call at first) reached half the skin: before, the global test cannot
    fail unless a grain jumps by that much in one step, and then the list is rebuilt.
    Compiled four times (``jit.specialised``, ``STEPS``): ``serial_steps`` calls the serial
    kernels, ``threaded_steps`` the parallel ones (one thread per run of strips in
    ``blocks``), and ``*_hertz`` their Hertz-Mindlin copies.
    Returns the steps done, the clock [s] after them, the largest squared displacement since
    the build [m^2] (not finite: the last step attempted was unstable and is not counted) and
    the bounding box of the displacements [m]."""
    done = 0
    max_d2 = drift * drift
    bound = global_bound(drift, lox, hix, loy, hiy)
    fast_d2 = 0.25 * skin * skin  # moved skin/2 or more: compared by the test by cells
    while done < max_steps:
        _pair_forces(strip_start, blocks, i_start, i_apart, pair_j, pair_fs, pair_fn,
                     x, y, vx, vy, omega, radius, inv_mass, fx, fy, torque,
                     kn, ks, mu, zeta, allow_tension, dt)
        collect = cell_test and bound >= 0.5 * skin
        max_d2, lox, hix, loy, hiy = _walls_and_leapfrog(
            strip_start, blocks, w_start, wc_w, wc_fs, wc_fn, wc_fx, wc_fy, walls,
            x, y, vx, vy, omega, fx, fy, torque, radius, mass, x_ref, y_ref, gravity,
            zeta, allow_tension, local_damping, dt, runs, collect, wall_gap, wall_drift, fast_d2,
            fast)
        if not np.isfinite(max_d2):
            break
        done += 1
        time += dt
        drift = math.sqrt(max_d2)
        bound = global_bound(drift, lox, hix, loy, hiy)
        if must_rebuild(bound, drift, wall_drift, skin, cell_test, strip_start[-1], runs, fast,
                        x, y, x_ref, y_ref, radius, i_start, pair_j, cell_grid, cell_start):
            break
    return done, time, max_d2, lox, hix, loy, hiy


serial_steps = specialised(_steps, "_serial", _pair_forces=pair_forces.serial,
                           _walls_and_leapfrog=walls_and_leapfrog.serial)
threaded_steps = specialised(_steps, "_threaded", _pair_forces=pair_forces.parallel,
                             _walls_and_leapfrog=walls_and_leapfrog.parallel)
serial_steps_hertz = specialised(_steps, "_serial_hertz", _pair_forces=pair_forces_hertz.serial,
                                 _walls_and_leapfrog=walls_and_leapfrog_hertz.serial)
threaded_steps_hertz = specialised(_steps, "_threaded_hertz",
                                   _pair_forces=pair_forces_hertz.parallel,
                                   _walls_and_leapfrog=walls_and_leapfrog_hertz.parallel)
# the loop for (threaded, Hertz-Mindlin law); each is compiled on its first call only
STEPS = {(False, False): serial_steps, (True, False): threaded_steps,
         (False, True): serial_steps_hertz, (True, True): threaded_steps_hertz}
