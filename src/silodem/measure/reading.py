"""One read of a simulation's arrays between two steps, with what every measurement needs:
grain arrays, touching contacts with their contact points, grain moments and contact counts.
Copies only; the simulation is never changed."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from silodem.measure.coordination import contacts_per_grain
from silodem.measure.stress import contact_points_walls, grain_moments

if TYPE_CHECKING:
    from silodem.engine.simulation import Simulation
    from silodem.engine.walls import Walls


@dataclass
class Reading:
    """Grains (x, z = y, r [m], vx, vz [m/s], mass [kg], uid), grain-grain contacts (i, j,
    force on j fx, fz [N]), grain-wall contacts (grain, wall, force on the grain [N], contact
    point [m]), moments (n, 2, 2) [N m], contacts per grain, and each wall's end A as it is
    now (wall_ax, wall_az [m]: a sliding gate's has moved from where it was built)."""

    time: float
    step: int
    x: np.ndarray
    z: np.ndarray
    r: np.ndarray
    vx: np.ndarray
    vz: np.ndarray
    mass: np.ndarray
    uid: np.ndarray
    i: np.ndarray
    j: np.ndarray
    fx: np.ndarray
    fz: np.ndarray
    w_grain: np.ndarray
    w_wall: np.ndarray
    w_fx: np.ndarray
    w_fz: np.ndarray
    w_cx: np.ndarray
    w_cz: np.ndarray
    moments: np.ndarray
    counts: np.ndarray
    wall_ax: np.ndarray
    wall_az: np.ndarray

    @property
    def n(self) -> int:
        return int(self.x.size)


def make_reading(time: float, step: int, x: np.ndarray, z: np.ndarray, r: np.ndarray,
                 vx: np.ndarray, vz: np.ndarray, mass: np.ndarray, uid: np.ndarray,
                 i: np.ndarray, j: np.ndarray, fx: np.ndarray, fz: np.ndarray,
                 w_grain: np.ndarray, w_wall: np.ndarray, w_fx: np.ndarray, w_fz: np.ndarray,
                 walls: Walls) -> Reading:
    """Build a reading from plain arrays; ``walls`` has segment arrays ax, ay, bx, by."""
    n = int(np.asarray(x).size)
    w_cx, w_cz = contact_points_walls(x, z, w_grain, w_wall, walls.ax, walls.ay, walls.bx,
                                      walls.by)
    moments = grain_moments(n, x, z, r, i, j, fx, fz, w_grain, w_cx, w_cz, w_fx, w_fz)
    counts = contacts_per_grain(n, i, j, w_grain)
    return Reading(float(time), int(step), x, z, r, vx, vz, mass, uid, i, j, fx, fz, w_grain,
                   w_wall, w_fx, w_fz, w_cx, w_cz, moments, counts,
                   np.array(walls.ax, dtype=float), np.array(walls.ay, dtype=float))


def read_simulation(sim: Simulation) -> Reading:
    """A reading of an engine ``Simulation`` (its contact lists must be current: read it after a
    step, as recorders do)."""
    from silodem.engine import quantities as q

    p = sim.particles
    gc = q.grain_contacts(sim)
    wc = q.wall_contacts(sim)
    return make_reading(sim.time, sim.steps, p.view("x").copy(), p.view("y").copy(),
                        p.view("radius").copy(), p.view("vx").copy(), p.view("vy").copy(),
                        p.view("mass").copy(), p.view("uid").copy(), gc.i, gc.j, gc.fx, gc.fy,
                        wc.grain, wc.wall, wc.fx, wc.fy, sim.walls)
