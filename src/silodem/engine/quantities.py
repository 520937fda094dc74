"""Quantities read from a simulation between steps.  Nothing here changes the state."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from silodem.engine.simulation import Simulation


@dataclass(frozen=True)
class ContactTable:
    """Touching grain-grain contacts: indices into the live grain arrays, forces [N].

    ``fx, fy`` is the force on grain j; ``fn`` the normal and ``fs`` the shear force."""

    i: np.ndarray
    j: np.ndarray
    fn: np.ndarray
    fs: np.ndarray
    fx: np.ndarray
    fy: np.ndarray


@dataclass(frozen=True)
class WallContactTable:
    """Touching grain-wall contacts: grain index, wall index, forces on the grain [N]."""

    grain: np.ndarray
    wall: np.ndarray
    fn: np.ndarray
    fs: np.ndarray
    fx: np.ndarray
    fy: np.ndarray


def _touching(fn: np.ndarray, fs: np.ndarray) -> np.ndarray:
    return (fn != 0.0) | (fs != 0.0)


def grain_contacts(sim: Simulation) -> ContactTable:
    """The force on j is F_n n + F_s t with n the unit vector from i to j and t = (-n_y, n_x)
    (``contact`` module), n taken from the current positions: the step computed the forces at
    the positions it started from, so the direction differs by one step's motion, a relative
    |v_rel dt / d|: 1e-6 to 1e-4 in a settled packing, about 1e-2 near the outlet of a fast
    discharge, up to 0.15 at fast impacts of soft grains with a long step (paper-case1
    --quick); a grain's resultant rebuilt from its contacts misses its fx, fy by as much of a
    contact force.  The vector stays parallel to the branch vector that stress measurements
    pair it with."""
    nb, p = sim.neighbors, sim.particles
    m = _touching(nb.pair_fn, nb.pair_fs)
    i, j, fn, fs = nb.pair_i[m], nb.pair_j[m], nb.pair_fn[m], nb.pair_fs[m]
    dx, dy = p.x[j] - p.x[i], p.y[j] - p.y[i]
    dist = np.hypot(dx, dy)
    nx, ny = dx / dist, dy / dist
    return ContactTable(i, j, fn, fs, fn * nx - fs * ny, fn * ny + fs * nx)


def wall_contacts(sim: Simulation) -> WallContactTable:
    nb = sim.neighbors
    m = _touching(nb.wc_fn, nb.wc_fs)
    return WallContactTable(nb.wc_i[m], nb.wc_w[m], nb.wc_fn[m], nb.wc_fs[m],
                            nb.wc_fx[m], nb.wc_fy[m])


def force_on_walls(sim: Simulation) -> np.ndarray:
    """Total force exerted BY the grains ON each wall, shape (n_walls, 2) [N]."""
    wc = wall_contacts(sim)
    out = np.zeros((len(sim.walls), 2))
    np.add.at(out[:, 0], wc.wall, -wc.fx)
    np.add.at(out[:, 1], wc.wall, -wc.fy)
    return out


def contact_count(sim: Simulation) -> tuple[int, int]:
    """Numbers of touching grain-grain and grain-wall contacts."""
    nb = sim.neighbors
    return (int(np.count_nonzero(_touching(nb.pair_fn, nb.pair_fs))),
            int(np.count_nonzero(_touching(nb.wc_fn, nb.wc_fs))))


def unbalanced_force_ratio(sim: Simulation) -> float:
    """Mean unbalanced force on the grains / mean contact force (PFC2D's equilibrium ratio).

    The unbalanced force of a grain is |F_contacts + m g| [N]; the mean contact force is over the
    touching contacts, grain-grain and grain-wall.  ``inf`` when nothing touches; 0 without
    grains."""
    p, nb = sim.particles, sim.neighbors
    n = p.n
    if n == 0:
        return 0.0
    fy = p.fy[:n] - p.mass[:n] * sim.gravity
    unbalanced = np.mean(np.hypot(p.fx[:n], fy))
    pm = _touching(nb.pair_fn, nb.pair_fs)
    wm = _touching(nb.wc_fn, nb.wc_fs)
    mags = np.concatenate([np.hypot(nb.pair_fn[pm], nb.pair_fs[pm]),
                           np.hypot(nb.wc_fx[wm], nb.wc_fy[wm])])
    if mags.size == 0 or mags.mean() == 0.0:
        return float("inf")
    return float(unbalanced / mags.mean())


def mean_kinetic_energy(sim: Simulation) -> float:
    """Mean kinetic energy per grain [J] (0 with no grains)."""
    n = sim.particles.n
    return sim.particles.kinetic_energy() / n if n else 0.0


def top_of_grains(y: np.ndarray, radius: np.ndarray, count: int = 5) -> float:
    """Height of the top of a heap of grains centred at heights ``y`` [m], radii ``radius``
    [m]: the mean of the ``count`` highest tops y + r [m] (a level that one grain bouncing
    above the rest barely moves); 0 for no grains."""
    if len(y) == 0:
        return 0.0
    tops = np.asarray(y, dtype=float) + np.asarray(radius, dtype=float)
    return float(np.mean(np.sort(tops)[-min(count, tops.size):]))
