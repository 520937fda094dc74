"""Physical sanity of a configuration, checked before a run starts.

* Time step: dt_crit from the stiffest contact and the lightest grain
  (``silodem.engine.contact.critical_time_step``); a user dt above it is refused.
* Overlap under the silo's own weight.  The vertical stress at the bottom of the cell is
  estimated with the 2D Janssen solution for a slot of width B with two walls,
      sigma_v = rho_b g B / (2 K mu_w) * (1 - exp(-2 K mu_w h / B)),
  with K = 0.4 (the paper's value during filling) and rho_b = 0.82 rho (a random packing of
  disks covers about 82 % of the plane).  A grain of diameter 2r and thickness t carries about
  F = sigma_v 2r t, and its contacts overlap about F / k_n,contact (linear law), or
  (3 F / (4 E* sqrt(R*)))^(2/3) (Hertz-Mindlin law).
* Hertz-Mindlin time step: dt_crit of the tangent stiffnesses at the largest of that overlap,
  the overlap of an impact after a fall from the top of the walls, and 1 % of r_max
  (``materials.design_overlaps``, ``materials.linearised``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from silodem.config import Config
from silodem.engine import hertz
from silodem.engine.contact import GrainLaw, critical_time_step
from silodem.errors import InputError
from silodem.silo.geometry import silo_shape
from silodem.silo.materials import contact_constants, linearised
from silodem.theory import janssen_sigma_v

if TYPE_CHECKING:
    import numpy as np

PACKING_FRACTION = 0.82  # area fraction of a random packing of disks [-]
JANSSEN_K = 0.4  # lateral pressure ratio during filling (the paper, section 4.2) [-]
WARN_OVERLAP = 0.05  # warn when the expected overlap exceeds this fraction of the mean radius
TARGET_OVERLAP = 0.01  # the stiffness recommended keeps the overlap under 1 % of the radius


def grain_law(cfg: Config) -> GrainLaw:
    """The grain-grain contact law of ``cfg``: series stiffnesses (``contact_constants``),
    mu = tan(phi_G), the damping ratio from the restitution, the tension and local-damping
    options and the law (linear or Hertz-Mindlin)."""
    m = cfg.material
    c = contact_constants(cfg)
    return GrainLaw(
        kn=c.grain_kn,
        ks=c.grain_ks,
        mu=math.tan(math.radians(m.friction_deg)),
        zeta=m.normal_damping_ratio,
        allow_tension=m.allow_tension,
        local_damping=m.local_damping,
        hertz=c.hertz,
    )


def choose_time_step(cfg: Config, law: GrainLaw, wall_kn: np.ndarray,
                     wall_ks: np.ndarray) -> tuple[float, float]:
    """(dt, dt_crit) [s]; raises InputError if the user's dt exceeds dt_crit.  A Hertz-Mindlin
    law is judged by its stiffest expected contacts (``materials.linearised``)."""
    m = cfg.material
    m_min = m.density * math.pi * m.radius_min**2 * m.thickness
    stiffest = "stiffest contact"
    if law.hertz:
        force = estimate_overlap(cfg).contact_force
        law, wall_kn, wall_ks = linearised(cfg, law, wall_kn, wall_ks, force)
        stiffest = "Hertz stiffness at the overlap of a fall from the wall top"
    dt_crit = critical_time_step(m_min, law, wall_kn, wall_ks)
    if cfg.time.dt is None:
        return cfg.time.safety * dt_crit, dt_crit
    if cfg.time.dt > dt_crit:
        raise InputError(
            f"time.dt = {cfg.time.dt:.4g} s exceeds the stability limit dt_crit = {dt_crit:.4g} s "
            f"(lightest grain, {stiffest}); use time.dt <= {dt_crit:.4g} or leave it unset"
        )
    return cfg.time.dt, dt_crit


@dataclass(frozen=True)
class OverlapEstimate:
    fill_height: float  # expected height of the settled fill [m]
    sigma_v: float  # vertical stress at the bottom of the cell [Pa]
    contact_force: float  # typical contact force there [N]
    overlap: float  # expected overlap [m]
    overlap_fraction: float  # overlap / mean radius [-]
    # for an overlap of 1 % of the radius: grain stiffness [N/m] (linear law) or Young's
    # modulus [Pa] (Hertz-Mindlin law)
    recommended: float
    hertz: bool = False

    @property
    def too_soft(self) -> bool:
        return self.overlap_fraction > WARN_OVERLAP

    def warning(self) -> str:
        advice = (f"a grain Young's modulus material.young_modulus >= "
                  f"{self.recommended:.2g} Pa (and a wall modulus as large)" if self.hertz
                  else f"a grain stiffness material.kn >= {self.recommended:.2g} N/m (and a "
                  "wall stiffness as large)")
        return (
            f"soft contacts: under the expected {self.fill_height:.2f} m of grains the vertical "
            f"stress reaches ~{self.sigma_v:.3g} Pa, "
            f"contact forces ~{self.contact_force:.3g} N and overlaps ~{self.overlap:.3g} m = "
            f"{100 * self.overlap_fraction:.3g}% of the mean radius; "
            f"{advice} keeps them under {100 * TARGET_OVERLAP:.0f}%"
        )


def estimate_overlap(cfg: Config) -> OverlapEstimate:
    """The overlap to expect at the bottom of ``cfg``'s settled fill, before running it: the
    fill height from the grains' area at the packing fraction PACKING_FRACTION, Janssen's
    vertical stress (``theory.janssen_sigma_v``, K = JANSSEN_K, bulk density = the packing
    fraction x the grain density) at the junction, the force on one grain's diameter, and the
    overlap that force makes on the softer of the grain-grain and grain-wall contacts."""
    m, s = cfg.material, cfg.silo
    shape = silo_shape(cfg)
    r_mean = 0.5 * (m.radius_min + m.radius_max)
    mean_r2 = (m.radius_max**3 - m.radius_min**3) / (3 * (m.radius_max - m.radius_min)) \
        if m.radius_max > m.radius_min else m.radius_min**2
    area = cfg.fill.n_particles * math.pi * mean_r2 / PACKING_FRACTION
    fill_height = shape.height_of_area(area)
    depth = max(fill_height - shape.junction, 0.0)
    rho_b = PACKING_FRACTION * m.density
    mu_w = math.tan(math.radians(cfg.walls.friction_deg))
    sigma_v = float(janssen_sigma_v(depth, rho_b, cfg.gravity, s.cell_width, JANSSEN_K, mu_w))
    force = sigma_v * 2.0 * r_mean * m.thickness
    c = contact_constants(cfg)
    if c.hertz:
        overlap = max(hertz.overlap_under_force(force, c.grain_kn, 0.5 * r_mean),
                      hertz.overlap_under_force(force, c.wall_kn, r_mean))
        # E* = E / (2 (1 - nu^2)) between equal grains, 2 E* = kn: F = 2/3 kn sqrt(r/2)
        # (0.01 r)^(3/2)
        kn = 1.5 * force / (math.sqrt(0.5 * r_mean) * (TARGET_OVERLAP * r_mean) ** 1.5)
        recommended = kn * (1.0 - m.poisson_ratio**2)
    else:
        overlap = force / min(c.grain_kn, c.wall_kn)
        # grain stiffness k with contact stiffness k/2 >= F / (0.01 r)
        recommended = 2.0 * force / (TARGET_OVERLAP * r_mean)
    return OverlapEstimate(fill_height, sigma_v, force, overlap, overlap / r_mean, recommended,
                           c.hertz)
