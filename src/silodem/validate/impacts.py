"""Binary impacts of disks: the set-ups, the measurement of one contact, and the linear normal
impact checked against the analytic spring-dashpot solution (Chung & Ooi 2011 tests 1-3).

The analytic solution.  A linear spring-dashpot contact between bodies of reduced mass m_eff
obeys  m_eff delta'' + c delta' + k delta = 0  with delta(0) = 0, delta'(0) = v (the approach
speed); with w0 = sqrt(k/m_eff), zeta = c / (2 sqrt(k m_eff)), beta = zeta w0 and
w = w0 sqrt(1 - zeta^2),  delta(t) = (v/w) exp(-beta t) sin(w t).

* Tension allowed (the force k delta + c delta' may pull): the contact lasts until the overlap
  vanishes, t_c = pi / w, and the normal restitution is e = exp(-zeta pi / sqrt(1 - zeta^2)).
* No tension (the force is cut at zero): the contact ends when k delta + c delta' = 0, at
  w t* = pi - atan2(2 beta w, w0^2 - 2 beta^2), with
  e* = exp(-beta t*) (beta/w sin(w t*) - cos(w t*))  (Schwager & Poeschel 2007): a shorter
  contact and a larger restitution than with tension.

Measuring a simulated contact.  Every step reads the overlap before the step (the positions the
forces are computed from) and the normal force the step used.  The contact starts where the
overlap crosses zero (interpolated linearly between the two steps: the grains move on straight
lines between steps) and ends where the overlap crosses zero again (tension allowed), or where
the normal force reaches zero (no tension; extrapolated linearly from the last two non-zero
forces, within the step where it was cut).  Restitution = - (relative normal velocity after) /
(relative normal velocity before), read once the contact is over (no gravity).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from silodem.engine.contact import GrainLaw, damping_ratio_from_restitution
from silodem.engine.particles import Particles
from silodem.engine.simulation import Simulation
from silodem.engine.walls import Walls
from silodem.silo import sizes
from silodem.validate.records import Record, absolute, info, rel

CASE = "normal impact"
# Tolerances in units of the scheme's error (docs/validation.md, section 1).  A damped impact
# is first order in dt/t_c: the dashpot's velocity is half a step behind, and a contact with
# tension ends within a step on a force c v; each shifts e and the duration by about
# |ln e| dt/t_c (measured up to 1.09 |ln e| dt/t_c for e with the linear law, 0.96 with the
# Hertz-Mindlin law, and
# 0.63 |ln e| dt/t_c for the duration).  An undamped impact returns its speed to round-off
# (the leap-frog is time-reversible) and its duration to second order (0.41 (dt/t_c)^2
# measured, 0.5 for the Hertz-Mindlin law).
RESTITUTION_PER_STEP = 1.5  # relative error of e, per |ln e| dt/t_c
DURATION_PER_STEP = 1.0  # relative error of the duration, per |ln e| dt/t_c
DURATION_PER_STEP_SQUARED = 1.0  # relative error of the duration, per (dt/t_c)^2
ROUND_OFF = 1e-9  # relative


def restitution_tol(e: float, steps_per_contact: float) -> float:
    """Relative tolerance on the restitution of an impact of nominal ``e`` at dt = t_c /
    ``steps_per_contact`` (the constants above)."""
    return RESTITUTION_PER_STEP * abs(math.log(e)) / steps_per_contact + ROUND_OFF


def duration_tol(e: float, steps_per_contact: float) -> float:
    """Relative tolerance on the duration of that impact."""
    return (DURATION_PER_STEP * abs(math.log(e)) / steps_per_contact
            + DURATION_PER_STEP_SQUARED / steps_per_contact**2)


# the disks of the impact set-ups
RHO = 2500.0  # [kg/m^3]
R1 = 0.01  # [m]
R2 = 0.007  # [m] the second disk of a pair (unequal on purpose)
THICKNESS = 1.0  # [m]
K_N = 1.0e7  # contact normal stiffness [N/m]


def disk_mass(r: float) -> float:
    return RHO * math.pi * r * r * THICKNESS


@dataclass(frozen=True)
class SpringDashpot:
    """Analytic linear spring-dashpot impact (see module docstring)."""

    w0: float  # [rad/s]
    zeta: float  # [-]
    t_c: float  # contact duration with tension [s]
    e: float  # restitution with tension [-]
    t_star: float  # contact duration without tension [s]
    e_star: float  # restitution without tension [-]

    def duration(self, tension: bool) -> float:
        return self.t_c if tension else self.t_star

    def restitution(self, tension: bool) -> float:
        return self.e if tension else self.e_star


def spring_dashpot(k: float, m_eff: float, zeta: float) -> SpringDashpot:
    """The analytic impact of a linear spring (k [N/m]) and dashpot (critical-damping ratio
    zeta < 1) on a reduced mass m_eff [kg] (Schwager & Poeschel, Granular Matter 9 (2007) 465)."""
    if not 0.0 <= zeta < 1.0:
        raise ValueError(f"zeta must be in [0, 1), got {zeta}")
    w0 = math.sqrt(k / m_eff)
    w = w0 * math.sqrt(1.0 - zeta**2)
    beta = zeta * w0
    t_c = math.pi / w
    e = math.exp(-zeta * math.pi / math.sqrt(1.0 - zeta**2))
    t_star = (math.pi - math.atan2(2.0 * beta * w, w0**2 - 2.0 * beta**2)) / w
    e_star = math.exp(-beta * t_star) * (beta / w * math.sin(w * t_star) - math.cos(w * t_star))
    return SpringDashpot(w0, zeta, t_c, e, t_star, e_star)


# --- set-ups -----------------------------------------------------------------------------------


def law(kn: float = K_N, ks: float | None = None, mu: float = 0.0, zeta: float = 0.0,
        tension: bool = False) -> GrainLaw:
    return GrainLaw(kn=kn, ks=kn if ks is None else ks, mu=mu, zeta=zeta,
                    allow_tension=tension)


def pair_sim(grain_law: GrainLaw, dt: float, r1: float = R1, r2: float = R2,
             v1: tuple[float, float] = (1.0, 0.0), v2: tuple[float, float] = (-1.0, 0.0),
             w1: float = 0.0, w2: float = 0.0, gap_steps: float = 2.5) -> Simulation:
    """Two disks on the x axis, disk 1 (radius r1) left of disk 2 (radius r2), with velocities
    v1, v2 [m/s] and spins w1, w2 [rad/s]; they touch after about ``gap_steps`` steps."""
    closing = v1[0] - v2[0]
    if closing <= 0:
        raise ValueError("the disks must approach")
    gap = gap_steps * dt * closing
    p = Particles()
    p.add(np.array([0.0, r1 + r2 + gap]), np.zeros(2), np.array([r1, r2]), RHO, THICKNESS,
          vx=np.array([v1[0], v2[0]]), vy=np.array([v1[1], v2[1]]), omega=np.array([w1, w2]))
    return Simulation(p, Walls(), grain_law, dt=dt, gravity=0.0, skin=0.5 * min(r1, r2))


def wall_sim(grain_law: GrainLaw, dt: float, vn: float, vt: float = 0.0, w: float = 0.0,
             r: float = R1, wall_kn: float | None = None, wall_ks: float | None = None,
             wall_mu: float | None = None, gap_steps: float = 2.5) -> Simulation:
    """A disk of radius r above the floor y = 0 (a long, rigid wall), falling onto it with normal
    speed vn > 0, tangential velocity vt (along +x) and spin w [rad/s]."""
    walls = Walls()
    walls.add("floor", (-1.0e3 * r, 0.0), (1.0e3 * r, 0.0),
              grain_law.kn if wall_kn is None else wall_kn,
              grain_law.ks if wall_ks is None else wall_ks,
              grain_law.mu if wall_mu is None else wall_mu)
    p = Particles()
    p.add(np.array([0.0]), np.array([r + gap_steps * dt * vn]), r, RHO, THICKNESS,
          vx=vt, vy=-vn, omega=w)
    return Simulation(p, walls, grain_law, dt=dt, gravity=0.0, skin=0.5 * r)


def pair_overlap(sim: Simulation) -> float:
    p = sim.particles
    return float(p.radius[0] + p.radius[1] - math.hypot(p.x[1] - p.x[0], p.y[1] - p.y[0]))


def wall_overlap(sim: Simulation) -> float:
    p = sim.particles
    return float(p.radius[0] - p.y[0])


def _pair_force(sim: Simulation) -> tuple[float, float]:
    nb = sim.neighbors
    return float(nb.pair_fn[0]), float(nb.pair_fs[0])


def _wall_force(sim: Simulation) -> tuple[float, float]:
    nb = sim.neighbors
    return float(nb.wc_fn[0]), float(nb.wc_fs[0])


# --- one contact ---------------------------------------------------------------------------------


@dataclass
class ContactTrace:
    """Overlap [m] before each step and the normal/shear force [N] each step used, at times t
    [s] (the time of the positions), until the contact ended; duration by interpolation."""

    t: np.ndarray
    overlap: np.ndarray
    fn: np.ndarray
    fs: np.ndarray
    start: float
    end: float

    @property
    def duration(self) -> float:
        return self.end - self.start


def follow_contact(sim: Simulation, overlap: Callable[[Simulation], float],
                   force: Callable[[Simulation], tuple[float, float]],
                   max_steps: int = 1_000_000) -> ContactTrace:
    """Step ``sim`` until its single contact has started and ended (reads only)."""
    ts, ds, fns, fss = [], [], [], []
    started = False
    for _ in range(max_steps):
        t, d = sim.time, overlap(sim)
        sim.step()
        fn, fs = force(sim)
        ts.append(t)
        ds.append(d)
        fns.append(fn)
        fss.append(fs)
        if fn != 0.0 or fs != 0.0:
            started = True
        elif started:
            break
    else:
        raise RuntimeError("the contact did not end")
    t, dl, fn, fs = (np.array(a) for a in (ts, ds, fns, fss))
    dt = sim.dt
    first = int(np.argmax((fn != 0.0) | (fs != 0.0)))
    last = t.size - 2  # the last step with a force
    if first == 0 or dl[first - 1] > 0:
        raise RuntimeError("the contact started before the trace")
    start = t[first - 1] + dt * (-dl[first - 1]) / (dl[first] - dl[first - 1])
    if dl[last + 1] <= 0.0:  # the overlap closed: interpolate its zero
        end = t[last] + dt * dl[last] / (dl[last] - dl[last + 1])
    else:  # the force was cut at zero while the disks still overlap: extrapolate its zero
        f1, f0 = fn[last], fn[last - 1]
        frac = f1 / (f0 - f1) if f0 > f1 else 1.0
        end = t[last] + dt * min(max(frac, 0.0), 1.0)
    return ContactTrace(t, dl, fn, fs, float(start), float(end))


@dataclass(frozen=True)
class NormalImpact:
    geometry: str  # "disk-disk" or "disk-wall"
    e_nominal: float
    tension: bool
    steps_per_contact: int  # dt = t_c / steps_per_contact (t_c with tension)
    expected_e: float
    expected_t: float
    e: float
    t: float
    w0: float  # undamped angular frequency sqrt(k/m_eff) [rad/s]


def normal_impact(geometry: str, e: float, tension: bool, steps_per_contact: int,
                  v: float = 1.0) -> NormalImpact:
    """One head-on impact; returns the measured and the analytic restitution and duration."""
    zeta = damping_ratio_from_restitution(e)
    m1 = disk_mass(R1)
    if geometry == "disk-disk":
        m2 = disk_mass(R2)
        m_eff = m1 * m2 / (m1 + m2)
    else:
        m_eff = m1
    ref = spring_dashpot(K_N, m_eff, zeta)
    dt = ref.t_c / steps_per_contact
    g = law(zeta=zeta, tension=tension)
    if geometry == "disk-disk":
        sim = pair_sim(g, dt, v1=(v, 0.0), v2=(-v, 0.0))
        trace = follow_contact(sim, pair_overlap, _pair_force)
        p = sim.particles
        e_sim = -(p.vx[1] - p.vx[0]) / (-2.0 * v)
    else:
        sim = wall_sim(g, dt, vn=v)
        trace = follow_contact(sim, wall_overlap, _wall_force)
        e_sim = sim.particles.vy[0] / v
    # with tension the restitution expected is the nominal e itself, not exp(-zeta pi /
    # sqrt(1 - zeta^2)) of the engine's zeta: the check then also covers the engine's map
    # e -> zeta (``damping_ratio_from_restitution``), which every expected value here uses
    expected_e = e if tension else ref.e_star
    return NormalImpact(geometry, e, tension, steps_per_contact, expected_e,
                        ref.duration(tension), float(e_sim), trace.duration, ref.w0)


E_VALUES = (0.1, 0.3, 0.5, 0.7, 0.9, 1.0)
STEPS_CHECKED = (500, 1000, 2000)  # steps per contact of the checked impacts
STEPS_CONVERGENCE = (50, 100, 200, 500, 1000)  # the convergence study (tension allowed)
ORDER_TOL = 0.15  # absolute, on a convergence order


def convergence_order(steps: npt.ArrayLike, errors: npt.ArrayLike) -> float:
    """Least-squares slope of log|error| against log(dt), dt ~ 1/steps."""
    x = -np.log(np.asarray(steps, dtype=float))
    y = np.log(np.abs(np.asarray(errors, dtype=float)))
    return float(np.polyfit(x, y, 1)[0])


def default_steps_per_contact() -> float:
    """Steps per grain-grain contact (mean grains, t_c with tension) at the time step silodem
    chooses for the paper's case 2 (dt = safety * dt_crit)."""
    from silodem.scenario_files import load_config
    from silodem.silo.checks import choose_time_step, grain_law
    from silodem.silo.geometry import build_walls

    cfg = load_config("paper-case2", [])
    g = grain_law(cfg)
    walls = build_walls(cfg)
    dt, _ = choose_time_step(cfg, g, walls.kn, walls.ks)
    m = cfg.material
    r = sizes.mean_radius(m)
    mass = m.density * math.pi * r * r * m.thickness
    return spring_dashpot(g.kn, 0.5 * mass, g.zeta).t_c / dt


SERIES_STEPS = 1000  # steps per contact of the series-stiffness impacts (undamped)
SERIES_SPEED = 0.1  # [m/s], a small overlap at the silo's soft stiffness
WALL_KN = 2e7  # [N/m] walls of the series impacts, 4 x paper-case2's grains (5e6 N/m)


def silo_contact_durations() -> list[tuple[str, float, float]]:
    """Undamped head-on impacts with the contact constants a silo run builds from its
    configuration (paper-case2 with walls of ``WALL_KN``: ``silo.checks.grain_law``,
    ``silo.geometry.build_walls``),
    as (label, expected, measured) contact durations [s].  Expected: pi sqrt(m_eff / k) with
    k the series stiffness of the two bodies, k_a k_b / (k_a + k_b), worked out here from
    the configuration's body stiffnesses (PFC2D's convention, ``config``), not by the
    engine's ``contact.series``: the impacts above set the contact stiffness directly and
    would not see a wrong combination."""
    from silodem.scenario_files import load_config
    from silodem.silo.checks import grain_law
    from silodem.silo.geometry import build_walls

    # walls four times as stiff as the grains: with paper-case2's equal stiffnesses a wall
    # contact of walls.kn / 2, the grain's left out, passed with the same digits
    cfg = load_config("paper-case2", [f"walls.kn={WALL_KN:g}", f"walls.ks={WALL_KN:g}"])
    kg, kw = float(cfg.material.kn), float(cfg.walls.kn)
    g = GrainLaw(kn=grain_law(cfg).kn, ks=grain_law(cfg).ks, mu=0.0, zeta=0.0,
                 allow_tension=True)
    walls = build_walls(cfg)
    out = []
    m1, m2 = disk_mass(R1), disk_mass(R2)
    m_eff = m1 * m2 / (m1 + m2)
    t_pair = math.pi * math.sqrt(m_eff / (kg * kg / (kg + kg)))
    sim = pair_sim(g, t_pair / SERIES_STEPS, v1=(SERIES_SPEED, 0.0), v2=(-SERIES_SPEED, 0.0))
    out.append(("grain-grain", t_pair, follow_contact(sim, pair_overlap, _pair_force).duration))
    t_wall = math.pi * math.sqrt(m1 / (kg * kw / (kg + kw)))
    sim = wall_sim(g, t_wall / SERIES_STEPS, vn=SERIES_SPEED, wall_kn=float(walls.kn[0]),
                   wall_ks=float(walls.ks[0]), wall_mu=0.0)
    out.append(("grain-wall", t_wall, follow_contact(sim, wall_overlap, _wall_force).duration))
    return out


def run(quick: bool = False) -> tuple[list[Record], dict]:
    """Normal impacts, disk-disk and disk-wall, e in [0.1, 1], with and without tension, at
    three time steps; the order of convergence in dt; the error at a silo's time step."""
    records: list[Record] = []
    checked: list[NormalImpact] = []
    for geometry in ("disk-disk", "disk-wall"):
        for tension in (True, False):
            for e in E_VALUES:
                for n in STEPS_CHECKED:
                    r = normal_impact(geometry, e, tension, n)
                    checked.append(r)
                    label = (f"{CASE}, {geometry}, e={e:g}, "
                             f"{'tension' if tension else 'no tension'}, dt=t_c/{n}")
                    src = "nominal e" if tension else "Schwager & Poeschel 2007 e*"
                    records.append(rel(label, "restitution", r.expected_e, r.e,
                                       restitution_tol(e, n), note=src))
                    records.append(rel(label, "contact duration", r.expected_t, r.t,
                                       duration_tol(e, n), "s",
                                       "pi/w_d" if tension else "Schwager & Poeschel 2007 t*"))
    convergence: dict[tuple[str, float], list[tuple[int, float, float]]] = {}
    for geometry in ("disk-disk", "disk-wall"):
        for e in (0.1, 0.5, 0.9, 1.0):
            pts = []
            for n in STEPS_CONVERGENCE:
                r = normal_impact(geometry, e, True, n)
                pts.append((n, r.e / r.expected_e - 1.0, r.t / r.expected_t - 1.0))
            convergence[(geometry, e)] = pts
            label = f"{CASE}, {geometry}, e={e:g}, tension, dt=t_c/{STEPS_CONVERGENCE[0]}" \
                f"..t_c/{STEPS_CONVERGENCE[-1]}"
            steps = [p[0] for p in pts]
            if e < 1.0:
                records.append(absolute(
                    label, "convergence order of the restitution error", 1.0,
                    convergence_order(steps, [p[1] for p in pts]), ORDER_TOL,
                    note="first order: the dashpot uses the velocity half a step behind"))
            else:
                records.append(absolute(
                    label, "convergence order of the contact-duration error", 2.0,
                    convergence_order(steps, [p[2] for p in pts]), ORDER_TOL,
                    note="undamped: leap-frog is second order"))
    n_silo = default_steps_per_contact()
    silo_points = []
    for tension in (True, False):
        r = normal_impact("disk-disk", 0.5, tension, max(1, round(n_silo)))
        silo_points.append(r)
        records.append(info(f"{CASE}, disk-disk, e=0.5, {'tension' if tension else 'no tension'}"
                            f", dt=t_c/{round(n_silo)} (paper-case2's time step)",
                            "restitution", r.e, expected=r.expected_e,
                            note="reported: the dashpot's first-order error at a silo's dt"))
    for kind, expected, got in silo_contact_durations():
        records.append(rel(f"{CASE}, {kind}, paper-case2's contact constants (walls "
                           f"{WALL_KN:g} N/m), undamped, "
                           f"dt=t_c/{SERIES_STEPS}", "contact duration", expected, got,
                           duration_tol(1.0, SERIES_STEPS), "s",
                           "pi sqrt(m_eff/k), k = k_a k_b/(k_a + k_b) of the configuration's "
                           "body stiffnesses (series)"))
    return records, {"checked": checked, "convergence": convergence, "silo": silo_points,
                     "silo_steps": n_silo}
