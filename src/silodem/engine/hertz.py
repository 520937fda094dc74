"""The Hertz-Mindlin contact law: its constants, its damping, and the stiffness that sets the
time step.  The force kernels are those of the linear law (``contact.hertz_mindlin``).

For two bodies of Young's moduli E_a, E_b, Poisson's ratios nu_a, nu_b and radii R_a, R_b
(R = inf for a wall) touching with overlap delta [m] (Johnson, *Contact Mechanics*, 1985,
ch. 4 and 7; Mindlin, J. Appl. Mech. 16 (1949) 259; the forms used by Di Renzo & Di Maio,
Chem. Eng. Sci. 59 (2004) 525):

    1/E* = (1 - nu_a^2)/E_a + (1 - nu_b^2)/E_b            effective modulus [Pa]
    1/G* = 2 (2 - nu_a)(1 + nu_a)/E_a + 2 (2 - nu_b)(1 + nu_b)/E_b
    1/R* = 1/R_a + 1/R_b                                    effective radius [m]
    a    = sqrt(R* delta)                                   half-width of the contact [m]
    F_n  = 4/3 E* sqrt(R*) delta^(3/2) - c_n v_n            (Hertz)
    S_n  = dF_n/d delta = 2 E* a,   S_s = 8 G* a            tangent stiffnesses [N/m] (Mindlin)
    dF_s = -S_s v_t dt,  |F_s| <= mu F_n                    (no slip until Coulomb's limit)
    c_n  = 2 zeta_H sqrt(S_n m_eff)

The kernels take 2 E* and 8 G* in place of the linear law's k_n and k_s, multiply them by a,
and apply the linear law to 2/3 delta: S_n * 2/3 delta = 4/3 E* sqrt(R*) delta^(3/2).

This is the contact law of spheres, applied to disks with a cylinder's mass and inertia (rho pi
r^2 t, m r^2 / 2), as a 2D LAMMPS run of ``gran/hertz/history`` with ``set density/disc`` (the
mass) and ``fix nve/sphere disc`` (the inertia): the thickness t does not enter the force, and E
is a parameter that sets the contact stiffness, not the material's modulus. (Two parallel
cylinders pressed together along their length follow another, nearly linear law with a
logarithm, Johnson ch. 4.3, and are much stiffer; it is not built.)

The dashpot above, whose coefficient grows as delta^(1/4) (Tsuji, Tanaka & Ishida, Powder
Technol. 71 (1992) 239), gives the same restitution at every impact speed: in the units
delta_0 = v_0 T, T = sqrt(m_eff / (K delta_0^(1/2))), K = 4/3 E* sqrt(R*), the impact reads
xi'' = -xi^(3/2) - 2 sqrt(3/2) zeta_H xi^(1/4) xi', xi(0) = 0, xi'(0) = 1, whatever v_0.
``damping_ratio_from_restitution`` gives the zeta_H of a restitution e.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np


def effective_modulus(e_a: float, nu_a: float, e_b: float, nu_b: float) -> float:
    """E* [Pa] of two bodies (a wall of infinite modulus: pass ``math.inf``)."""
    return 1.0 / ((1.0 - nu_a**2) / e_a + (1.0 - nu_b**2) / e_b)


def effective_shear_modulus(e_a: float, nu_a: float, e_b: float, nu_b: float) -> float:
    """G* [Pa] of two bodies: 1/G* = 2 (2 - nu)(1 + nu)/E summed over both."""
    return 1.0 / (2.0 * (2.0 - nu_a) * (1.0 + nu_a) / e_a
                  + 2.0 * (2.0 - nu_b) * (1.0 + nu_b) / e_b)


def kernel_constants(e_a: float, nu_a: float, e_b: float, nu_b: float) -> tuple[float, float]:
    """(2 E*, 8 G*) [Pa]: what the force kernels take as k_n and k_s under this law."""
    return (2.0 * effective_modulus(e_a, nu_a, e_b, nu_b),
            8.0 * effective_shear_modulus(e_a, nu_a, e_b, nu_b))


def overlap_under_force(force: float, kn: float, r_eff: float) -> float:
    """The overlap delta [m] at which the elastic force 2/3 kn sqrt(R*) delta^(3/2) equals
    ``force`` [N] (``kn`` = 2 E*)."""
    return (1.5 * force / (kn * math.sqrt(r_eff))) ** (2.0 / 3.0)


def impact_overlap(speed: float, m_eff: float, kn: float, r_eff: float) -> float:
    """The largest overlap delta [m] of an undamped impact at normal speed ``speed`` [m/s]:
    1/2 m_eff v^2 = 2/5 K delta^(5/2), K = 2/3 kn sqrt(R*) (Johnson 1985, ch. 11)."""
    k_hertz = 2.0 / 3.0 * kn * math.sqrt(r_eff)
    return (1.25 * m_eff * speed**2 / k_hertz) ** 0.4


def tangent_stiffness(k: float | np.ndarray, r_eff: float,
                      overlap: float) -> float | np.ndarray:
    """S = k sqrt(R* delta) [N/m]: S_n for k = 2 E*, S_s for k = 8 G* (a number or an array
    of them, one per wall)."""
    return k * math.sqrt(r_eff * overlap)


def damping_ratio_from_restitution(e: float) -> float:
    """zeta_H = sqrt(5/6) (-ln e) / sqrt(pi^2 + ln^2 e) [-]: the damping ratio whose isolated
    Hertz contact, tension allowed, rebounds with normal restitution e at any impact speed
    (module docstring).  The form of LIGGGHTS's and EDEM's Hertz-Mindlin model (LIGGGHTS
    documentation, "gran model hertz"; after Tsuji et al. 1992): sqrt(5/6) times the linear
    law's ratio (``contact.damping_ratio_from_restitution``).  An integration of the
    dimensionless impact agrees with it within 1e-10 for e from 0.001 to 0.99
    (``validate.hertz_mindlin.dimensionless_rebound``, tests/test_hertz_mindlin.py)."""
    if not 0.0 < e <= 1.0:
        raise ValueError(f"restitution must be in (0, 1], got {e}")
    if e == 1.0:
        return 0.0
    le = math.log(e)
    return math.sqrt(5.0 / 6.0) * -le / math.sqrt(math.pi**2 + le**2)
