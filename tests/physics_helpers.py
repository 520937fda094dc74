"""Small set-ups shared by the physics tests, and the analytic solutions they are checked
against."""

from __future__ import annotations

import math

import numpy as np

from silodem.engine.contact import GrainLaw
from silodem.engine.particles import Particles
from silodem.engine.simulation import Simulation
from silodem.engine.walls import Walls

RHO = 1000.0  # [kg/m^3]
R = 0.1  # [m]
MASS = RHO * math.pi * R**2  # unit thickness [kg]


def spring_dashpot(k: float, m_eff: float, zeta: float) -> dict[str, float]:
    """Analytic linear spring-dashpot impact (delta'' + 2 zeta w0 delta' + w0^2 delta = 0).

    With tension allowed the contact lasts t_c = pi / w_d and e = exp(-zeta pi / sqrt(1-zeta^2)).
    Without tension it ends when the force k delta + c delta' vanishes, at
    w_d t* = pi - atan2(2 beta w_d, w0^2 - 2 beta^2), beta = zeta w0, with
    e* = exp(-beta t*) (beta/w_d sin w_d t* - cos w_d t*)   (Schwager & Poeschel, Granular
    Matter 9 (2007) 465).
    """
    w0 = math.sqrt(k / m_eff)
    wd = w0 * math.sqrt(1.0 - zeta**2)
    beta = zeta * w0
    t_c = math.pi / wd
    e = math.exp(-zeta * math.pi / math.sqrt(1.0 - zeta**2))
    t_star = (math.pi - math.atan2(2.0 * beta * wd, w0**2 - 2.0 * beta**2)) / wd
    e_star = math.exp(-beta * t_star) * (beta / wd * math.sin(wd * t_star) - math.cos(wd * t_star))
    return {"t_c": t_c, "e": e, "t_star": t_star, "e_star": e_star}


def law(k: float = 1e5, mu: float = 0.3, zeta: float = 0.0, tension: bool = False,
        ks: float | None = None) -> GrainLaw:
    return GrainLaw(kn=k, ks=k if ks is None else ks, mu=mu, zeta=zeta, allow_tension=tension)


def floor(k: float, mu: float, ks: float | None = None, length: float = 20.0) -> Walls:
    w = Walls()
    w.add("floor", (-length / 2, 0.0), (length / 2, 0.0), k, k if ks is None else ks, mu)
    return w


def run_until_separated(sim: Simulation, touching, max_steps: int = 10_000_000):
    """Step until a contact has started and ended; return (time of first and last force)."""
    started = ended = None
    for _ in range(max_steps):
        sim.step()
        if touching():
            if started is None:
                started = sim.time - sim.dt
            ended = sim.time
        elif started is not None:
            return started, ended
    raise AssertionError("contact never ended")


def pair_impact(e_law: GrainLaw, v: float, dt: float, vt: float = 0.0):
    """Two equal disks approaching head-on with speed v each (relative speed 2v)."""
    p = Particles()
    p.add(np.array([0.0, 2 * R + 1e-6 + v * dt]), np.array([0.0, 0.0]), R, RHO,
          vx=np.array([v, -v]), vy=np.array([vt, -vt]))
    sim = Simulation(p, Walls(), e_law, dt=dt, gravity=0.0, skin=0.05)
    return sim


def wall_impact(e_law: GrainLaw, walls: Walls, vn: float, vt: float, dt: float):
    """A disk falling onto the floor y = 0 with normal speed vn and tangential speed vt."""
    p = Particles()
    p.add(np.array([0.0]), np.array([R + 1e-6 + vn * dt]), R, RHO, vx=vt, vy=-vn)
    return Simulation(p, walls, e_law, dt=dt, gravity=0.0, skin=0.05)


def frictionless_pair_leapfrog(x, y, vx, vy, mass, radius, k, dt):
    """Brute-force reference: two disks with a linear spring (stiffness k [N/m], no damping,
    no friction, no tension) integrated by the leap-frog of docs/physics.md (forces from the
    positions at t, velocities at half steps), in plain Python, from the start until the
    contact has begun and ended.  ``x, y, vx, vy``: lists of the two disks' values [m, m/s],
    changed in place."""
    started = False
    while True:
        dx = x[1] - x[0]
        dy = y[1] - y[0]
        d = math.hypot(dx, dy)
        f = k * (2.0 * radius - d) if d < 2.0 * radius else 0.0
        if f > 0.0:
            started = True
        elif started:
            return
        fx = f * dx / d  # the force on disk 1; disk 0 gets its opposite
        fy = f * dy / d
        for a, sign in ((0, -1.0), (1, 1.0)):
            vx[a] += sign * fx / mass * dt
            vy[a] += sign * fy / mass * dt
            x[a] += vx[a] * dt
            y[a] += vy[a] * dt
