"""The Hertz-Mindlin law (docs/physics.md) against Hertz's and Mindlin's solutions.

* Hertz's force: during an undamped impact every step's normal force equals
  4/3 E* sqrt(R*) delta^(3/2) at that step's overlap (to rounding).
* Hertz's impact (Johnson, *Contact Mechanics*, 1985, section 11.4): the largest overlap
  delta_max = (15 m_eff v^2 / (16 E* sqrt(R*)))^(2/5) and the duration
  t_c = 2 delta_max / v * 2/5 B(2/5, 1/2) of an undamped impact at relative speed v, for two
  unequal disks and a disk on a wall.
* Restitution: Tsuji's dashpot gives one restitution at every speed; with tension allowed it
  is the e asked for (``engine.hertz.damping_ratio_from_restitution``), without tension the e*
  of the dimensionless impact integrated here by scipy (``dimensionless_rebound``), checked at
  0.1, 1 and 10 m/s.
* A disk at rest on a floor sinks by Hertz's static overlap (3 m g / (4 E* sqrt(r)))^(2/3);
  nudged sideways it rocks on its contact at omega = sqrt(3 S_s / m), S_s = 8 G* sqrt(r delta)
  (Mindlin): the shear modulus G* checked through a frequency.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp
from scipy.special import beta

from silodem.engine import hertz
from silodem.engine.contact import GrainLaw
from silodem.engine.particles import Particles
from silodem.engine.simulation import Simulation
from silodem.engine.walls import Walls
from silodem.validate.impacts import (
    R1,
    R2,
    RHO,
    THICKNESS,
    ContactTrace,
    _pair_force,
    _wall_force,
    disk_mass,
    duration_tol,
    follow_contact,
    pair_overlap,
    pair_sim,
    restitution_tol,
    wall_overlap,
    wall_sim,
)
from silodem.validate.records import Record, absolute, rel

CASE = "Hertz-Mindlin"
E_GRAIN, NU_GRAIN = 7.0e10, 0.25  # glass [Pa], [-]
E_WALL, NU_WALL = 2.1e11, 0.3  # steel
STEPS = 1000  # steps per undamped contact
# relative, largest overlap of an impact: sampled at the steps, within (pi dt/t_c)^2 / 8 of
# the peak, doubled for the integration's own second-order error
OVERLAP_TOL = (math.pi / STEPS) ** 2 / 4
LAW_TOL = 1e-9  # F_n against Hertz's force at the same overlap, over the largest F_n
STATIC_TOL = 1e-6  # relative, overlap of a disk at rest
FREQUENCY_TOL = 1e-6  # relative, rocking period against the leap-frog's own (measured 6e-8)
SPEEDS = (0.1, 1.0, 10.0)  # impact speeds of the restitution checks [m/s]


def dimensionless_rebound(zeta: float, tension: bool) -> float:
    """Restitution of xi'' = -xi^(3/2) - 2 sqrt(3/2) zeta xi^(1/4) xi', xi(0) = 0, xi'(0) = 1
    (a Hertz impact in units of its own size and time, docs/physics.md), integrated by scipy
    (DOP853, rtol 1e-11): the contact ends when xi returns to 0, or without tension when the
    force first vanishes."""
    c = 2.0 * math.sqrt(1.5) * zeta

    def force(s):
        xi = max(s[0], 0.0)
        return xi**1.5 + c * xi**0.25 * s[1]

    def rhs(_t, s):
        return [s[1], -force(s)]

    def ended(_t, s):
        return s[0] if tension else force(s)

    ended.terminal, ended.direction = True, -1
    sol = solve_ivp(rhs, (0.0, 50.0), [1e-12, 1.0], events=ended, rtol=1e-11, atol=1e-14,
                    method="DOP853", first_step=1e-7)
    return float(-sol.y_events[0][0][1])


def textbook_moduli(e_a: float, nu_a: float, e_b: float, nu_b: float) -> tuple[float, float]:
    """(E*, G*) [Pa] of two bodies, written here apart from the engine's ``engine.hertz``
    (which builds the law under test): 1/E* = (1 - nu_a^2)/E_a + (1 - nu_b^2)/E_b (Johnson
    1985, eq. 4.22), and with G = E / (2 (1 + nu)), 1/G* = (2 - nu_a)/G_a + (2 - nu_b)/G_b
    (Mindlin 1949; Di Renzo & Di Maio 2004).  The expected values below use these, so that a
    wrong modulus in the engine is seen."""
    e_star = 1.0 / ((1.0 - nu_a**2) / e_a + (1.0 - nu_b**2) / e_b)
    g_a, g_b = e_a / (2.0 * (1.0 + nu_a)), e_b / (2.0 * (1.0 + nu_b))
    return e_star, 1.0 / ((2.0 - nu_a) / g_a + (2.0 - nu_b) / g_b)


def hertz_impact(v_rel: float, m_eff: float, e_star: float, r_eff: float) -> tuple[float, float]:
    """(largest overlap [m], duration [s]) of Hertz's undamped impact (module docstring)."""
    d_max = (15.0 * m_eff * v_rel**2 / (16.0 * e_star * math.sqrt(r_eff))) ** 0.4
    return d_max, 2.0 * d_max / v_rel * 0.4 * float(beta(0.4, 0.5))


def _law(zeta: float = 0.0, tension: bool = False, mu: float = 0.5) -> GrainLaw:
    kn, ks = hertz.kernel_constants(E_GRAIN, NU_GRAIN, E_GRAIN, NU_GRAIN)
    return GrainLaw(kn=kn, ks=ks, mu=mu, zeta=zeta, allow_tension=tension, hertz=True)


def _wall_constants() -> tuple[float, float]:
    return hertz.kernel_constants(E_GRAIN, NU_GRAIN, E_WALL, NU_WALL)


def impact(geometry: str, v: float, e: float = 1.0,
           tension: bool = False) -> tuple[ContactTrace, float, float, float, float]:
    """One head-on impact at closing speed ``v`` [m/s] (disk-disk: v/2 each): the trace of
    ``impacts.follow_contact``, the measured restitution, and Hertz's (d_max, t_c)."""
    zeta = hertz.damping_ratio_from_restitution(e)
    g = _law(zeta, tension)
    if geometry == "disk-disk":
        m1, m2 = disk_mass(R1), disk_mass(R2)
        m_eff, r_eff = m1 * m2 / (m1 + m2), R1 * R2 / (R1 + R2)
        e_star, _ = textbook_moduli(E_GRAIN, NU_GRAIN, E_GRAIN, NU_GRAIN)
        d_max, t_c = hertz_impact(v, m_eff, e_star, r_eff)
        sim = pair_sim(g, t_c / STEPS, v1=(v / 2, 0.0), v2=(-v / 2, 0.0))
        trace = follow_contact(sim, pair_overlap, _pair_force)
        p = sim.particles
        e_sim = (p.vx[1] - p.vx[0]) / v
    else:
        m_eff, r_eff = disk_mass(R1), R1
        e_star, _ = textbook_moduli(E_GRAIN, NU_GRAIN, E_WALL, NU_WALL)
        d_max, t_c = hertz_impact(v, m_eff, e_star, r_eff)
        kn, ks = _wall_constants()
        sim = wall_sim(g, t_c / STEPS, vn=v, wall_kn=kn, wall_ks=ks)
        trace = follow_contact(sim, wall_overlap, _wall_force)
        e_sim = sim.particles.vy[0] / v
    k_hertz = 4.0 / 3.0 * e_star * math.sqrt(r_eff)
    return trace, float(e_sim), d_max, t_c, k_hertz


def resting_disk(mu: float = 0.9) -> Simulation:
    """A disk (radius R1) settled on a floor under gravity (1 s of damped motion)."""
    kn, ks = _wall_constants()
    walls = Walls()
    walls.add("floor", (-1.0, 0.0), (1.0, 0.0), kn, ks, mu, one_sided=True)
    p = Particles()
    p.add(np.array([0.0]), np.array([R1]), R1, RHO, THICKNESS)
    law = _law(hertz.damping_ratio_from_restitution(0.3), mu=mu)
    e_star, _ = textbook_moduli(E_GRAIN, NU_GRAIN, E_WALL, NU_WALL)
    static = (3 * disk_mass(R1) * 9.81 / (4 * e_star * math.sqrt(R1))) ** (2 / 3)
    # the normal period at the static overlap, 200 steps to it
    period = 2 * math.pi * math.sqrt(disk_mass(R1) / (2 * e_star * math.sqrt(R1 * static)))
    sim = Simulation(p, walls, law, dt=period / 200, gravity=9.81, skin=0.5 * R1)
    sim.run(round(1.0 / sim.dt))
    return sim


def rocking_period(sim: Simulation, omega: float, cycles: int = 10) -> tuple[float, float]:
    """Nudge the resting disk sideways (1e-3 of the speed that moves its contact by its own
    overlap in 1/omega) and read the period of its shear force from the zero crossings over
    ``cycles`` cycles [s]; also the largest |F_s| over mu F_n (no slip: well below 1)."""
    p = sim.particles
    p.vx[0] = 1e-3 * (p.radius[0] - p.y[0]) * omega
    t, f = [], []
    for _ in range(int(cycles * 2 * math.pi / omega / sim.dt) + 10):
        sim.step()
        t.append(sim.time)
        f.append(sim.neighbors.wc_fs[0])
    t, f = np.array(t), np.array(f)
    k = np.flatnonzero(np.sign(f[:-1]) != np.sign(f[1:]))
    crossings = t[k] + (t[k + 1] - t[k]) * f[k] / (f[k] - f[k + 1])
    mobilised = np.abs(f).max() / (sim.law.mu * sim.neighbors.wc_fn[0])
    return float(2.0 * np.mean(np.diff(crossings))), float(mobilised)


def run(quick: bool = False) -> tuple[list[Record], dict]:
    """Every check of the module docstring; the data of the figure."""
    records: list[Record] = []
    data: dict = {"law": {}, "restitution": []}
    for geometry in ("disk-disk", "disk-wall"):
        trace, e_sim, d_max, t_c, k_hertz = impact(geometry, 1.0)
        label = f"{CASE}, {geometry}, elastic, 1 m/s, dt=t_c/{STEPS}"
        on = trace.fn != 0.0
        miss = np.abs(trace.fn[on] - k_hertz * trace.overlap[on] ** 1.5).max()
        records.append(absolute(label, "largest |F_n - 4/3 E* sqrt(R*) delta^(3/2)| / F_n,max",
                                0.0, float(miss / trace.fn.max()), LAW_TOL,
                                note="Hertz 1882; overlaps from the positions each step used"))
        records.append(rel(label, "largest overlap", d_max, float(trace.overlap.max()),
                           OVERLAP_TOL, "m", "Johnson 1985, ch. 11"))
        records.append(rel(label, "contact duration", t_c, trace.duration,
                           duration_tol(1.0, STEPS), "s", "2 delta_max/v 2/5 B(2/5, 1/2)"))
        records.append(rel(label, "restitution", 1.0, e_sim, restitution_tol(1.0, STEPS),
                           note="undamped: energy conserved"))
        data["law"][geometry] = (trace.overlap[on], trace.fn[on], k_hertz)
    for tension in (True, False):
        for e in (0.1, 0.5, 0.9):
            zeta = hertz.damping_ratio_from_restitution(e)
            expected = e if tension else dimensionless_rebound(zeta, False)
            for v in SPEEDS:
                _, e_sim, *_ = impact("disk-disk", v, e, tension)
                label = (f"{CASE}, disk-disk, e={e:g}, {'tension' if tension else 'no tension'}"
                         f", {v:g} m/s")
                note = ("zeta_H = sqrt(5/6) (-ln e)/sqrt(pi^2 + ln^2 e)" if tension
                        else "e* of the dimensionless impact (scipy)")
                records.append(rel(label, "restitution", expected, e_sim,
                                   restitution_tol(e, STEPS), note=note))
                data["restitution"].append((e, tension, v, e_sim, expected))
    sim = resting_disk()
    m = disk_mass(R1)
    e_star, g_star = textbook_moduli(E_GRAIN, NU_GRAIN, E_WALL, NU_WALL)
    static = (3 * m * 9.81 / (4 * e_star * math.sqrt(R1))) ** (2 / 3)
    delta = float(R1 - sim.particles.y[0])
    records.append(rel(f"{CASE}, disk at rest on a floor", "static overlap", static, delta,
                       STATIC_TOL, "m", "m g = 4/3 E* sqrt(r) delta^(3/2)"))
    omega = math.sqrt(3 * 8 * g_star * math.sqrt(R1 * delta) / m)
    period, mobilised = rocking_period(sim, omega)
    label = f"{CASE}, disk at rest on a floor, nudged"
    leap_frog = math.pi * sim.dt / math.asin(omega * sim.dt / 2)  # 2 pi / omega, less
    records.append(rel(label, "rocking period", leap_frog, period, FREQUENCY_TOL, "s",
                       "u'' = -3 S_s u / m, S_s = 8 G* sqrt(r delta) (Mindlin 1949), as the "
                       "leap-frog steps it: sin(omega_h dt/2) = omega dt/2"))
    records.append(absolute(label, "largest |F_s| / (mu F_n)", 0.0, mobilised, 0.01,
                            note="no slip: Mindlin's stiffness alone"))
    return records, data
