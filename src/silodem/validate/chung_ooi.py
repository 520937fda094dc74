"""Chung & Ooi (2011) benchmark tests 4-8, adapted to disks, against rigid-body impact theory.

Chung, Y.C., Ooi, J.Y. (2011) Benchmark tests for verifying discrete element modelling codes
at particle impact level.  Granular Matter 13, 643-656, doi:10.1007/s10035-011-0277-0.
Their tests are for spheres; here the bodies are disks with I = kappa m R^2, kappa = 1/2.

Rigid-body impact of a disk on a wall (normal approach speed v_n, tangential velocity v_t of
the centre, spin w; contact-point slip velocity u = v_t + w R).  The normal impulse is
P_n = m (1 + e) v_n.  A tangential impulse P_t opposing the slip changes v_t by -P_t/m and
w R by -P_t R^2/I = -P_t/(kappa m), so it changes u by -(1 + 1/kappa) P_t/m (3 P_t/m for a
disk).  Coulomb friction allows |P_t| <= mu P_n:

* gross sliding, when |u| >= (1 + 1/kappa) mu (1 + e) v_n (the disk slips throughout):
  P_t = mu P_n sign(u), v_t' = v_t - mu (1+e) v_n, w' R = w R - (1/kappa) mu (1+e) v_n;
* sticking otherwise: the slip stops (u' = 0), P_t = m u / (1 + 1/kappa).

With the normalised incident and recoil slips Psi_1 = u / (mu (1+e) v_n) and
Psi_2 = u' / (mu (1+e) v_n), gross sliding is Psi_1 >= 1 + 1/kappa = 3 for a disk (7/2 for a
sphere), and there Psi_2 = Psi_1 - 3, while the normalised spin change is -1/kappa = -2.

The sticking limit.  A disk that starts without spin (w = 0, u = v_t) and leaves rolling
(u' = 0) keeps v_t'/v_t = 1 - 1/(1 + 1/kappa) = 1/(1 + kappa): 2/3 for a disk (5/7 for a
sphere).  Gross sliding gives v_t'/v_t = 1 - mu (1+e) v_n / v_t, which reaches 2/3 exactly at
the limit tan(theta) = v_t/v_n = 3 mu (1 + e).

The DEM contact has a tangential spring: below the limit it does not stick like a rigid body
(the tangential force oscillates; Maw, Barber & Fawcett 1976), so only the gross-sliding side is
checked against the rigid-body solution; the sticking side is drawn.  A damped contact starts
with a jump of its normal force (the dashpot), which the tangential spring needs a moment to
follow, so the tangential impulse falls short of mu P_n by about 2 zeta^2 (k_n/k_s) /
(Psi_1 (1+e)^2): nearly elastic contacts (e = 0.9, 0.98) keep that about 2e-4 here.

Two disks (tests 7, 8): the same with the reduced mass m* = m1 m2/(m1 + m2) and the relative
slip of the contact points; momentum is conserved exactly (equal and opposite forces); angular
momentum about a fixed point changes by -integral(overlap * F_s dt), since the torques use the
radii, not the distances to the contact point: |dL| <= max overlap * |P_t|.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from silodem.engine.contact import damping_ratio_from_restitution
from silodem.validate import impacts as im
from silodem.validate.records import Record, absolute, info, rel

KAPPA_DISK = 0.5  # I / (m R^2) of a disk
TOL = 5e-3  # relative agreement with the rigid-body solution around the stick-slip change
PSI_TOL = 0.015  # absolute, on Psi_2 (0.5 % of the jump of 3 of a gross-sliding impact)
STEPS = 500  # time steps per contact duration
OVERLAP = 1e-3  # largest overlap / radius of the impacts (sets k_n)
# elastic, frictionless impact: off by O((w dt)^2) = (pi/STEPS)^2 = 4e-5 during the contact,
# the time-reversible leap-frog returns the energy to round-off after it (1.7e-11 measured)
ENERGY_TOL = 1e-9
# test 4 (e = 0.98): e's own first-order error at STEPS (impacts.restitution_tol), 6e-5
GROSS_SLIDING_TOL = im.restitution_tol(0.98, STEPS)


def sticking_tangential_restitution(kappa: float = KAPPA_DISK) -> float:
    """v_t'/v_t of a body without initial spin that leaves a rigid wall rolling: 1/(1 + kappa)
    (2/3 for a disk, kappa = 1/2; 5/7 for a sphere, kappa = 2/5)."""
    return 1.0 / (1.0 + kappa)


def sliding_limit(kappa: float = KAPPA_DISK) -> float:
    """The normalised incident slip Psi_1 above which an impact slides throughout: 1 + 1/kappa."""
    return 1.0 + 1.0 / kappa


@dataclass(frozen=True)
class RigidWall:
    vn: float  # rebound normal speed [m/s]
    vt: float  # tangential velocity of the centre [m/s]
    omega: float  # spin [rad/s]
    sliding: bool


def rigid_wall_impact(vn: float, vt: float, omega: float, r: float, e: float, mu: float,
                      kappa: float = KAPPA_DISK) -> RigidWall:
    """Rigid-body impact of a round body (I = kappa m r^2) on a wall (see module docstring).
    vn > 0 is the approach speed; vt and omega r are positive in the same sense."""
    u = vt + omega * r
    pn = (1.0 + e) * vn  # normal impulse / m
    k = 1.0 + 1.0 / kappa
    sliding = abs(u) >= k * mu * pn
    pt = math.copysign(mu * pn, u) if sliding else u / k
    return RigidWall(e * vn, vt - pt, omega - pt / (kappa * r), sliding)


@dataclass(frozen=True)
class RigidPair:
    vt1: float
    vt2: float
    omega1: float
    omega2: float
    impulse_t: float  # tangential impulse on disk 2 [N s]
    sliding: bool


def rigid_pair_impact(m1: float, m2: float, r1: float, r2: float, gn: float, vt1: float,
                      vt2: float, w1: float, w2: float, e: float, mu: float,
                      kappa: float = KAPPA_DISK) -> RigidPair:
    """Rigid-body impact of disk 1 (left) and disk 2 (right) on the x axis: gn > 0 closing
    speed, vt tangential (y) velocities, w spins (counter-clockwise).  The slip of 2's contact
    point relative to 1's is u = vt2 - w2 r2 - vt1 - w1 r1; a tangential impulse J on 2 (-J on
    1) changes it by J (1 + 1/kappa) / m*."""
    m_star = m1 * m2 / (m1 + m2)
    u = vt2 - w2 * r2 - vt1 - w1 * r1
    pn = m_star * (1.0 + e) * gn
    k = 1.0 + 1.0 / kappa
    sliding = abs(u) * m_star / k >= mu * pn
    j = -math.copysign(mu * pn, u) if sliding else -u * m_star / k
    return RigidPair(vt1 - j / m1, vt2 + j / m2, w1 - j / (kappa * m1 * r1),
                     w2 - j / (kappa * m2 * r2), j, sliding)


def e_star(e: float) -> float:
    """Normal restitution of the no-tension contact with nominal e (silodem's default law)."""
    return im.spring_dashpot(1.0, 1.0, damping_ratio_from_restitution(e)).e_star


# --- DEM impacts -----------------------------------------------------------------------------


@dataclass(frozen=True)
class WallImpact:
    vn: float
    vt: float
    omega0: float
    e: float  # restitution the rigid-body solution uses (e* of the contact)
    mu: float
    vn_after: float
    vt_after: float
    omega_after: float

    @property
    def scale(self) -> float:
        return self.mu * (1.0 + self.e) * self.vn


def dem_wall_impact(vn: float, vt: float, omega: float, e: float, mu: float, r: float = im.R1,
                    steps: int = STEPS) -> WallImpact:
    """A disk hits the floor; k_n such that the largest overlap is OVERLAP * r; k_s = k_n."""
    m = im.disk_mass(r)
    kn = m * (vn / (OVERLAP * r)) ** 2
    zeta = damping_ratio_from_restitution(e)
    ref = im.spring_dashpot(kn, m, zeta)
    sim = im.wall_sim(im.law(kn=kn, mu=mu, zeta=zeta), ref.t_c / steps, vn, vt, omega, r=r)
    im.follow_contact(sim, im.wall_overlap, im._wall_force)
    p = sim.particles
    return WallImpact(vn, vt, omega, ref.e_star, mu, float(p.vy[0]), float(p.vx[0]),
                      float(p.omega[0]))


@dataclass(frozen=True)
class PairImpact:
    r1: float
    r2: float
    v: float  # each disk approaches with v: closing speed 2v
    w1: float
    w2: float
    e: float
    mu: float
    vt1: float
    vt2: float
    omega1: float
    omega2: float
    d_momentum: float  # largest |change of a momentum component| / sum(m |v|)
    d_angular: float  # |change of angular momentum about the origin| / (max overlap |P_t|)
    d_energy: float  # relative change of the kinetic energy
    impulse_t: float  # tangential impulse on disk 2 [N s]


def _angular_momentum(p) -> float:
    n = p.n
    return float(np.sum(p.mass[:n] * (p.x[:n] * p.vy[:n] - p.y[:n] * p.vx[:n])
                        + p.inertia() * p.omega[:n]))


def dem_pair_impact(r1: float, r2: float, v: float, w1: float, w2: float, e: float, mu: float,
                    steps: int = STEPS) -> PairImpact:
    m1, m2 = im.disk_mass(r1), im.disk_mass(r2)
    m_star = m1 * m2 / (m1 + m2)
    kn = m_star * (2.0 * v / (OVERLAP * min(r1, r2))) ** 2
    zeta = damping_ratio_from_restitution(e)
    ref = im.spring_dashpot(kn, m_star, zeta)
    sim = im.pair_sim(im.law(kn=kn, mu=mu, zeta=zeta), ref.t_c / steps, r1, r2, (v, 0.0),
                      (-v, 0.0), w1, w2)
    p = sim.particles
    mom0 = np.array([np.dot(p.mass[:2], p.vx[:2]), np.dot(p.mass[:2], p.vy[:2])])
    ang0, ke0 = _angular_momentum(p), p.kinetic_energy()
    vy2_0 = float(p.vy[1])
    tr = im.follow_contact(sim, im.pair_overlap, im._pair_force)
    mom1 = np.array([np.dot(p.mass[:2], p.vx[:2]), np.dot(p.mass[:2], p.vy[:2])])
    impulse = m2 * (float(p.vy[1]) - vy2_0)
    lever = float(tr.overlap.max()) * abs(impulse)
    d_ang = abs(_angular_momentum(p) - ang0) / lever if lever > 0 else 0.0
    return PairImpact(r1, r2, v, w1, w2, ref.e_star, mu, float(p.vy[0]), float(p.vy[1]),
                      float(p.omega[0]), float(p.omega[1]),
                      float(np.max(np.abs(mom1 - mom0)) / ((m1 + m2) * abs(v))), d_ang,
                      p.kinetic_energy() / ke0 - 1.0, impulse)


# --- the tests ---------------------------------------------------------------------------------

PSI_VALUES = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 5.0, 6.0, 8.0, 10.0)


def test4(records: list[Record]) -> dict:
    """Constant impact speed 3.9 m/s at incident angles 5-85 deg from the normal, no spin
    (mu = 0.092, e = 0.98, as for Kharaz et al.'s alumina spheres in Chung & Ooi's test 4)."""
    case = "Chung-Ooi 4, disk-wall oblique"
    v, mu, e_nom = 3.9, 0.092, 0.98
    e = e_star(e_nom)
    angles = np.arange(5.0, 86.0, 5.0)
    out = {"angle": angles, "et": [], "omega": [], "rebound": [], "mu": mu, "e": e, "v": v,
           "r": im.R1}
    for a in angles:
        vn, vt = v * math.cos(math.radians(a)), v * math.sin(math.radians(a))
        d = dem_wall_impact(vn, vt, 0.0, e_nom, mu)
        rb = rigid_wall_impact(vn, vt, 0.0, im.R1, e, mu)
        et, reb = d.vt_after / vt, math.degrees(math.atan2(d.vt_after, d.vn_after))
        out["et"].append(et)
        out["omega"].append(d.omega_after)
        out["rebound"].append(reb)
        if rb.sliding:
            # in gross sliding the friction impulse is mu (1 + e) m v_n: its error is e's,
            # first order in dt (impacts.restitution_tol), and so is the spin's it sets; the
            # rebound angle carries the errors of v_t' and v_n' = e v_n both.  Checked as the
            # friction's share 1 - v_t'/v_t, not v_t'/v_t, which near grazing is 1 - 1.6 %
            # (85 deg) whatever mu.
            label = f"{case}, angle {a:g} deg (gross sliding)"
            records.append(rel(label, "friction's share 1 - v_t'/v_t", 1.0 - rb.vt / vt,
                               1.0 - et, GROSS_SLIDING_TOL))
            records.append(rel(label, "spin after", rb.omega, d.omega_after, GROSS_SLIDING_TOL,
                               "rad/s"))
            records.append(rel(label, "rebound angle", math.degrees(math.atan2(rb.vt, rb.vn)),
                               reb, 2 * GROSS_SLIDING_TOL, "deg"))
    # the sticking limit: tan(theta) = 3 mu (1 + e)
    a_c = math.atan(sliding_limit() * mu * (1.0 + e))
    d = dem_wall_impact(v * math.cos(a_c), v * math.sin(a_c), 0.0, e_nom, mu)
    records.append(rel(f"{case}, sticking limit tan(theta) = 3 mu (1+e), "
                       f"theta = {math.degrees(a_c):.2f} deg",
                       "tangential restitution v_t'/v_t", sticking_tangential_restitution(),
                       d.vt_after / (v * math.sin(a_c)), GROSS_SLIDING_TOL,
                       note="1/(1 + kappa) = 2/3 for a disk"))
    out["limit"] = (math.degrees(a_c), d.vt_after / (v * math.sin(a_c)))
    return out


def test5(records: list[Record]) -> dict:
    """Constant normal speed, tangential speeds giving Psi_1 = 0.5-10, no spin."""
    case = "Chung-Ooi 5, disk-wall, varying v_t"
    vn, mu, e_nom = 1.0, 0.3, 0.9
    e = e_star(e_nom)
    s = mu * (1.0 + e) * vn
    out = {"psi1": np.array(PSI_VALUES), "psi2": [], "spin": []}
    for psi in PSI_VALUES:
        d = dem_wall_impact(vn, psi * s, 0.0, e_nom, mu)
        psi2 = (d.vt_after + d.omega_after * im.R1) / s
        spin = d.omega_after * im.R1 / s
        out["psi2"].append(psi2)
        out["spin"].append(spin)
        if psi >= sliding_limit():
            label = f"{case}, Psi_1 = {psi:g}"
            records.append(absolute(label, "normalised recoil slip Psi_2", psi - sliding_limit(),
                                    psi2, PSI_TOL, note="rigid body: Psi_1 - 3"))
            records.append(rel(label, "normalised spin w'R/(mu(1+e)v_n)", -1.0 / KAPPA_DISK,
                               spin, TOL, note="rigid body: -1/kappa = -2"))
    return out


def test6(records: list[Record]) -> dict:
    """Normal speed 0.2 m/s, no tangential speed, spins giving Psi_1 = 0.5-10."""
    case = "Chung-Ooi 6, disk-wall, varying spin"
    vn, mu, e_nom = 0.2, 0.3, 0.9
    e = e_star(e_nom)
    s = mu * (1.0 + e) * vn
    out = {"psi1": np.array(PSI_VALUES), "psi2": [], "vt": []}
    for psi in PSI_VALUES:
        w0 = psi * s / im.R1
        d = dem_wall_impact(vn, 0.0, w0, e_nom, mu)
        psi2 = (d.vt_after + d.omega_after * im.R1) / s
        out["psi2"].append(psi2)
        out["vt"].append(d.vt_after / s)
        if psi >= sliding_limit():
            label = f"{case}, Psi_1 = {psi:g} (w0 = {w0:.3g} rad/s)"
            records.append(rel(label, "normalised rebound velocity v_t'/(mu(1+e)v_n)", -1.0,
                               d.vt_after / s, TOL, note="rigid body: -1"))
            records.append(absolute(label, "normalised recoil slip Psi_2",
                                    psi - sliding_limit(), psi2, PSI_TOL,
                                    note="rigid body: Psi_1 - 3"))
    return out


def _pair_test(records: list[Record], number: int, r1: float, r2: float) -> dict:
    kind = "identical disks" if r1 == r2 else f"disks r2/r1 = {r2 / r1:g}"
    case = f"Chung-Ooi {number}, {kind}"
    v, mu, e_nom = 0.2, 0.3, 0.9
    e = e_star(e_nom)
    m1, m2 = im.disk_mass(r1), im.disk_mass(r2)
    s = mu * (1.0 + e) * 2.0 * v
    out = {"psi1": np.array(PSI_VALUES), "spin1": [], "spin2": [], "r1": r1, "r2": r2}
    for psi in PSI_VALUES:
        w = psi * s / (r1 + r2)  # both spin w (counter-clockwise): slip u = -w (r1 + r2)
        d = dem_pair_impact(r1, r2, v, w, w, e_nom, mu)
        rb = rigid_pair_impact(m1, m2, r1, r2, 2.0 * v, 0.0, 0.0, w, w, e, mu)
        m_star = m1 * m2 / (m1 + m2)  # normalised: rigid body gives -1/kappa in sliding
        out["spin1"].append((d.omega1 - w) * r1 * m1 / (m_star * s))
        out["spin2"].append((d.omega2 - w) * r2 * m2 / (m_star * s))
        label = f"{case}, Psi_1 = {psi:g}"
        if psi >= sliding_limit():
            for q, exp_, got, unit in (("v_t' of disk 1", rb.vt1, d.vt1, "m/s"),
                                       ("v_t' of disk 2", rb.vt2, d.vt2, "m/s"),
                                       ("spin change, disk 1", rb.omega1 - w, d.omega1 - w,
                                        "rad/s"),
                                       ("spin change, disk 2", rb.omega2 - w, d.omega2 - w,
                                        "rad/s")):
                records.append(rel(label, q, exp_, got, TOL, unit))
        if psi in (1.0, 4.0, 10.0):
            records.append(absolute(label, "momentum change / sum(m|v|)", 0.0, d.d_momentum,
                                    1e-12, note="exact: equal and opposite forces"))
            records.append(absolute(label, "|dL| / (max overlap * |P_t|)", 0.0, d.d_angular,
                                    1.0, note="bound: torques use the radii"))
    d = dem_pair_impact(r1, r2, v, 30.0, -10.0, 1.0, 0.0)
    records.append(absolute(f"{case}, e = 1, frictionless, spinning", "kinetic energy change "
                            "(relative)", 0.0, d.d_energy, ENERGY_TOL,
                            note="elastic: conserved up to O((w dt)^2)"))
    records.append(absolute(f"{case}, e = 1, frictionless, spinning",
                            "momentum change / sum(m|v|)", 0.0, d.d_momentum, 1e-12))
    return out


def damped_shortfall(records: list[Record]) -> None:
    """Reported, not checked: how far a strongly damped contact (e = 0.5) falls short of the
    rigid-body tangential impulse mu P_n in gross sliding (Psi_1 = 3), against the estimate
    2 zeta^2 (k_n/k_s) / (Psi_1 (1+e)^2) of the module docstring; tests 5-8 use e = 0.9,
    where it is about 2e-4 (2.1e-4 at Psi_1 = 3)."""
    vn, mu, e_nom, psi = 1.0, 0.3, 0.5, 3.0
    e = e_star(e_nom)
    vt = psi * mu * (1.0 + e) * vn
    d = dem_wall_impact(vn, vt, 0.0, e_nom, mu)
    shortfall = 1.0 - (vt - d.vt_after) / (mu * (vn + d.vn_after))
    # k_n / k_s = 1: dem_wall_impact's law has k_s = k_n
    estimate = 2.0 * damping_ratio_from_restitution(e_nom) ** 2 / (psi * (1.0 + e) ** 2)
    records.append(info("Chung-Ooi 5, disk-wall, e = 0.5, Psi_1 = 3",
                        "tangential impulse shortfall 1 - P_t/(mu P_n)", shortfall,
                        expected=estimate, note="the dashpot's jump of F_n at first contact "
                        "(docs/validation.md, section 2); expected: the estimate"))


def run(quick: bool = False) -> tuple[list[Record], dict]:
    records: list[Record] = []
    data = {"test4": test4(records), "test5": test5(records), "test6": test6(records),
            "test7": _pair_test(records, 7, im.R1, im.R1),
            "test8": _pair_test(records, 8, im.R1, 2.0 * im.R1)}
    damped_shortfall(records)
    return records, data
