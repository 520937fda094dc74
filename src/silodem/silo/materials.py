"""The constants the force kernels take for a configuration's contacts, under either law.

* linear: the series stiffnesses of the two bodies (PFC2D's convention, ``config``):
  k = k_a k_b / (k_a + k_b), for grain-grain and grain-wall contacts;
* Hertz-Mindlin: 2 E* and 8 G* of the two bodies' moduli (``engine.hertz``), which the
  kernels turn into the stiffnesses S_n = 2 E* sqrt(R* delta), S_s = 8 G* sqrt(R* delta).

Also the largest tangent stiffness a Hertz-Mindlin run should meet, which sets its time step
(``linearised``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from silodem.config import Config
from silodem.engine import hertz
from silodem.engine.contact import GrainLaw, series


@dataclass(frozen=True)
class ContactConstants:
    """k_n, k_s of grain-grain and grain-wall contacts: [N/m] (linear) or [Pa] (Hertz)."""

    grain_kn: float
    grain_ks: float
    wall_kn: float
    wall_ks: float
    hertz: bool


def contact_constants(cfg: Config) -> ContactConstants:
    """The kernels' k_n and k_s of ``cfg``'s contacts (module docstring)."""
    m, w = cfg.material, cfg.walls
    if m.contact_model == "hertz_mindlin":
        gg = hertz.kernel_constants(m.young_modulus, m.poisson_ratio,
                                    m.young_modulus, m.poisson_ratio)
        gw = hertz.kernel_constants(m.young_modulus, m.poisson_ratio,
                                    w.young_modulus, w.poisson_ratio)
        return ContactConstants(*gg, *gw, hertz=True)
    return ContactConstants(series(m.kn, m.kn), series(m.ks, m.ks),
                            series(m.kn, w.kn), series(m.ks, w.ks), hertz=False)


def impact_speed(cfg: Config) -> float:
    """A bound on the speed [m/s] at which grains meet during filling: a fall from the top
    of the walls, plus the pouring speed."""
    return math.sqrt(2.0 * cfg.gravity * cfg.silo.wall_height) + cfg.fill.initial_speed


MIN_DESIGN_OVERLAP = 0.01  # the design overlap is at least this fraction of r_max [-]


def design_overlaps(cfg: Config, static_force: float) -> tuple[float, float]:
    """The largest overlap [m] of a grain-grain and of a grain-wall Hertz contact expected in
    ``cfg``'s run: the largest of the overlap under ``static_force`` [N] (the contact force
    under the silo's weight, ``checks.estimate_overlap``), that of an impact at
    ``impact_speed`` (the heaviest grains, ``hertz.impact_overlap``), and 1 % of r_max (the
    stiffness, and so the time step, depends on it only as delta^(1/2) and delta^(-1/4))."""
    m, c = cfg.material, contact_constants(cfg)
    r = m.radius_max
    m_max = m.density * math.pi * r**2 * m.thickness
    v = impact_speed(cfg)
    least = MIN_DESIGN_OVERLAP * r
    grain = max(hertz.overlap_under_force(static_force, c.grain_kn, 0.5 * r),
                hertz.impact_overlap(v, 0.5 * m_max, c.grain_kn, 0.5 * r), least)
    wall = max(hertz.overlap_under_force(static_force, c.wall_kn, r),
               hertz.impact_overlap(v, m_max, c.wall_kn, r), least)
    return grain, wall


def linearised(cfg: Config, law: GrainLaw, wall_kn: np.ndarray, wall_ks: np.ndarray,
               static_force: float) -> tuple[GrainLaw, np.ndarray, np.ndarray]:
    """A Hertz-Mindlin law, and its walls' constants, replaced by the tangent stiffnesses
    S = k sqrt(R* delta) [N/m] at the design overlaps (``design_overlaps``) and the largest
    radii (R* = r_max / 2 between grains, r_max against a wall): the stiffest contacts of the
    run, for ``contact.critical_time_step``.  A linear law is returned as it is."""
    if not law.hertz:
        return law, wall_kn, wall_ks
    r = cfg.material.radius_max
    d_grain, d_wall = design_overlaps(cfg, static_force)
    grain = [hertz.tangent_stiffness(k, 0.5 * r, d_grain) for k in (law.kn, law.ks)]
    wall = [hertz.tangent_stiffness(np.asarray(k), r, d_wall) for k in (wall_kn, wall_ks)]
    return replace(law, kn=grain[0], ks=grain[1], hertz=False), wall[0], wall[1]
