"""Physical sanity of a configuration, checked before a run starts.

* Time step: dt_crit from the stiffest contact, the lightest grain and the normal dashpot
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
* Tangential stiffness (linear law): a contact carrying F slides once its tangential spring
  holds mu F, after an elastic tangential displacement mu F / k_s,contact.  A k_s far below
  k_n (Table 1's 1e3 N/m beside a k_n raised to 2e7 N/m: about 20 m) leaves the friction
  unmobilised, and the grains behave as frictionless in shear: warned, like the overlap, above
  5 % of the mean radius, with the k_s that keeps it under 1 %.
* A hopper lower than the largest grain's diameter (``shallow_hopper_warning``): the grains
  see a flat floor, and the hopper theory of the report does not apply; warned.
* PFC local damping in a run with a discharge (``local_damping_warning``): it slows the flow,
  and the discharge's measurements are those of a damped flow; warned.
* Values that are each valid but give no usable run together (``check_numbers``, before
  anything is written): stiffnesses out of range, a time step that is zero or not finite,
  or in which a grain that fell from the top of the walls crosses more than its radius,
  more than ``MAX_STEPS`` steps, a loose fill that does not fit; and lengths so small
  against the silo that the arrays they size would not fit in memory (``check_sizes``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from silodem.config import Config
from silodem.engine import hertz
from silodem.engine.contact import GrainLaw, critical_time_step
from silodem.errors import InputError
from silodem.silo import sizes
from silodem.silo.geometry import silo_shape
from silodem.silo.materials import contact_constants, impact_speed, linearised
from silodem.theory import janssen_sigma_v

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
        stiffest = "Hertz stiffness at the largest design overlap: static, impact or 1 % of r_max"
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
    # the keys of the grains' and the walls' stiffness (modulus) below ``recommended``
    soft_keys: tuple[str, ...] = ()
    # linear law: the elastic tangential displacement at the Coulomb limit, mu F / k_s,contact,
    # the larger of grain-grain and grain-wall [m], over the mean radius [-]; and each
    # tangential stiffness below the one that keeps it under 1 % (key, that value [N/m])
    slip: float = 0.0
    slip_fraction: float = 0.0
    shear_keys: tuple[tuple[str, float], ...] = ()

    @property
    def too_soft(self) -> bool:
        return self.overlap_fraction > WARN_OVERLAP

    @property
    def soft_shear(self) -> bool:
        return self.slip_fraction > WARN_OVERLAP

    def shear_advice(self) -> str:
        keys = " and ".join(f"{key} >= {value:.2g}" for key, value in self.shear_keys)
        f = self.slip_fraction
        size = f"{f:.3g} x" if f >= 1.0 else f"{100 * f:.2g}% of"
        return (f"a contact reaches its friction limit only after ~{self.slip:.3g} m of elastic "
                f"sliding, mu F_n / k_s ({size} the mean radius): before that the grains shear as "
                f"if frictionless; {keys} N/m keeps that under {100 * TARGET_OVERLAP:.0f}%")

    def warning(self) -> str:
        what, unit = ("Young's modulus", "Pa") if self.hertz else ("stiffness", "N/m")
        keys = self.soft_keys or (("material.young_modulus", "walls.young_modulus") if self.hertz
                                  else ("material.kn", "walls.kn"))
        named = [f"a {'grain' if key.startswith('material.') else 'wall'} {what} {key}"
                 for key in keys]  # the soft ones: raising a stiff one does nothing
        advice = f"{' and '.join(named)} >= {self.recommended:.2g} {unit}"
        return (
            f"soft contacts: under the expected {self.fill_height:.2f} m of grains the vertical "
            f"stress reaches ~{self.sigma_v:.3g} Pa, "
            f"contact forces ~{self.contact_force:.3g} N and overlaps ~{self.overlap:.3g} m = "
            f"{100 * self.overlap_fraction:.3g}% of the mean radius; "
            f"{advice} keeps them under {100 * TARGET_OVERLAP:.0f}%"
            + (f"; and {self.shear_advice()}" if self.soft_shear else "")
        )

    def shear_warning(self) -> str:
        """The warning of a linear law whose overlaps are fine but whose tangential springs
        are so soft that friction is hardly mobilised."""
        return (f"soft tangential contacts: with contact forces ~{self.contact_force:.3g} N at "
                f"the bottom of the expected {self.fill_height:.2f} m of grains, "
                f"{self.shear_advice()}")


def estimate_overlap(cfg: Config) -> OverlapEstimate:
    """The overlap to expect at the bottom of ``cfg``'s settled fill, before running it: the
    fill height from the grains' area at the packing fraction PACKING_FRACTION, Janssen's
    vertical stress (``theory.janssen_sigma_v``, K = JANSSEN_K, bulk density = the packing
    fraction x the grain density) at the junction, the force on one grain's diameter, and the
    overlap that force makes on the softer of the grain-grain and grain-wall contacts."""
    m, s = cfg.material, cfg.silo
    shape = silo_shape(cfg)
    r_mean = sizes.mean_radius(m)
    mean_r2 = sizes.mean_square_radius(m)
    area = cfg.fill.n_particles * math.pi * mean_r2 / PACKING_FRACTION
    fill_height = shape.height_of_area(area)
    depth = max(fill_height - shape.junction, 0.0)
    rho_b = PACKING_FRACTION * m.density
    mu_w = math.tan(math.radians(cfg.walls.friction_deg))
    sigma_v = float(janssen_sigma_v(depth, rho_b, cfg.gravity, s.cell_width, JANSSEN_K, mu_w))
    force = sigma_v * 2.0 * r_mean * m.thickness
    c = contact_constants(cfg)
    w = cfg.walls
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
    given = ((("material.young_modulus", m.young_modulus), ("walls.young_modulus",
                                                            w.young_modulus)) if c.hertz
             else (("material.kn", m.kn), ("walls.kn", w.kn)))
    soft = tuple(key for key, value in given if value < recommended)
    slip, shear = 0.0, ()
    if not c.hertz:  # (Mindlin's tangential stiffness follows the modulus and the overlap)
        mu_g = math.tan(math.radians(m.friction_deg))
        mu_w = max(mu_w, w.hopper_mu()) if s.kind == "hopper" else mu_w  # (the cell's above)
        slip = max(mu_g * force / c.grain_ks, mu_w * force / c.wall_ks)
        # each side's k_s at mu times the k_n recommended: contacts of k_s/2 at least hold
        # mu F within 1 % of the radius, as the k_n's hold F
        need = max(mu_g, mu_w) * recommended
        shear = tuple((f"{side}.ks", need) for side, ks in (("material", m.ks), ("walls", w.ks))
                      if ks < need)
    return OverlapEstimate(fill_height, sigma_v, force, overlap, overlap / r_mean, recommended,
                           c.hertz, soft, slip, slip / r_mean, shear)


# --- values that give no usable run together, and arrays too large -------------------------------


def law_key_names(cfg: Config) -> str:
    """The keys of ``cfg``'s contact law, for messages: "material.kn, material.ks, ..." """
    from silodem.config import LAW_KEYS

    names = LAW_KEYS[cfg.material.contact_model]
    return ", ".join(f"{section}.{key}" for section in ("material", "walls") for key in names)


def check_numbers(cfg: Config) -> tuple[float, float]:
    """(dt, dt_crit) [s] of ``cfg``; InputError when the values, each valid, give no usable
    run together: contact stiffnesses (moduli) outside ``STIFFNESS_RANGE``; a zero,
    infinite or NaN time step, or more than ``MAX_STEPS`` steps; lengths that size arrays
    beyond memory or bands larger than the silo (:func:`check_sizes`); a pouring speed, or
    the speed of a fall from the top of the walls, that carries a grain more than its radius
    in one step; grains poured at rest without gravity; a clog time shorter than the first
    grain needs to leave (:func:`shortest_clog_time`); a sliding gate that cannot open
    (:func:`check_gate`); time limits that leave a pour, the measurements or the discharge
    window undone (:func:`check_schedule`); a loose fill with more grains than fit in the
    silo."""
    from silodem.silo.geometry import build_walls

    law_keys = law_key_names(cfg)
    keys = f"{law_keys}, material.density, material.radius_min, material.thickness and time.dt"
    hertz = cfg.material.contact_model == "hertz_mindlin"
    what, unit = (("contact moduli 2 E*, 8 G*", "Pa") if hertz
                  else ("contact stiffnesses", "N/m"))
    try:
        with np.errstate(all="ignore"):
            law = grain_law(cfg)
            walls = build_walls(cfg)
            stiffness = [law.kn, law.ks, *walls.kn.tolist(), *walls.ks.tolist()]
            if not all(STIFFNESS_RANGE[0] <= k <= STIFFNESS_RANGE[1] for k in stiffness):
                raise InputError(
                    f"the {what} ({law_keys} combined) come out as {min(stiffness):.3g} to "
                    f"{max(stiffness):.3g} {unit}; they must lie in {STIFFNESS_RANGE[0]:.0e} to "
                    f"{STIFFNESS_RANGE[1]:.0e} {unit}")
            dt, dt_crit = choose_time_step(cfg, law, walls.kn, walls.ks)
            estimate_overlap(cfg)
    except InputError:
        raise
    except (ArithmeticError, ValueError) as exc:
        raise InputError(f"the grain and wall values give no usable time step ({exc}); "
                         f"check {keys}") from None
    if not (math.isfinite(dt) and math.isfinite(dt_crit) and dt > 0):
        raise InputError(f"the grain and wall values give a time step of {dt:.3g} s (stability "
                         f"limit {dt_crit:.3g} s), which cannot be used; check {keys}")
    check_sizes(cfg)
    step = cfg.fill.initial_speed * dt  # a poured grain's travel in one step [m]
    if cfg.fill.method == "pour" and not step <= cfg.material.radius_min:
        raise InputError(
            f"fill.initial_speed = {cfg.fill.initial_speed:.3g} m/s carries a poured grain "
            f"{step:.3g} m in one time step of {dt:.3g} s, more than its radius "
            f"(material.radius_min = {cfg.material.radius_min:.3g} m): contacts would be "
            f"missed; give at most {floor_3(cfg.material.radius_min / dt):.3g} m/s")
    fall = impact_speed(cfg) * dt  # a grain's travel in one step after a fall from the top
    if not fall <= cfg.material.radius_min:
        raise InputError(
            f"a time step of {dt:.3g} s carries a grain that fell from the top of the walls "
            f"({impact_speed(cfg):.3g} m/s) {fall:.3g} m in one step, more than its radius "
            f"(material.radius_min = {cfg.material.radius_min:.3g} m): contacts would be "
            f"missed and the run would end as unstable; check {keys}, silo.wall_height, "
            "gravity and fill.initial_speed")
    if cfg.fill.method == "pour" and cfg.gravity == 0.0 and cfg.fill.initial_speed == 0.0:
        raise InputError("gravity = 0 with fill.method = 'pour' and fill.initial_speed = 0: "
                         "the poured grains would hang where they are put and never fill the "
                         "silo; give gravity > 0 or fill.initial_speed > 0")
    shortest = shortest_clog_time(cfg)
    if cfg.discharge.enabled and not math.isfinite(shortest):
        raise InputError(f"gravity = {cfg.gravity:g} m/s^2 is too weak for a grain to fall out "
                         "of the outlet within any discharge.clog_time; give a larger gravity")
    if cfg.discharge.enabled and not shortest < cfg.discharge.max_time:  # (1e-300 m/s^2: the
        # clog_time's message blamed clog_time, asking for 9.4e149 s)
        raise InputError(f"gravity = {cfg.gravity:.3g} m/s^2 lets a grain at rest in the outlet "
                         f"fall out only after {shortest:.3g} s, not within discharge.max_time ="
                         f" {cfg.discharge.max_time:g} s: no grain could leave; give a larger "
                         "gravity or a longer discharge.max_time")
    if cfg.discharge.enabled and cfg.discharge.clog_time < shortest:
        raise InputError(
            f"discharge.clog_time = {cfg.discharge.clog_time:g} s is shorter than the first "
            f"grain needs to leave ({shortest:.3g} s: its fall from the outlet to the removal "
            "level 4 material.radius_max below it, plus the 0.05 s between the checks): the "
            f"discharge would be called a clog before any grain left; give at least "
            f"{math.ceil(shortest * 1000.0) / 1000.0:g} s")
    check_gate(cfg, dt)
    check_schedule(cfg)
    if cfg.fill.method == "loose":  # a fill that cannot fit, refused before anything is written
        from silodem.silo.procedure import loose_sites

        loose_sites(silo_shape(cfg), cfg.material.radius_max, cfg.fill.n_particles)
    total, words = phase_time_limits(cfg)
    if total / dt > MAX_STEPS:
        raise InputError(
            f"a time step of {dt:.3g} s would allow {total / dt:.2g} steps in the phase time "
            f"limits ({total:g} s = {words}), more than {MAX_STEPS:.0e}; check {keys}")
    return dt, dt_crit


def check_gate(cfg: Config, dt: float) -> None:
    """InputError when a sliding gate (``discharge.gate_speed``) cannot work: it would cross
    more than a smallest radius in one step of ``dt`` [s], the discharge would end before it
    had slid open, or, under a flat floor, the fill's expected overlaps are so large that the
    gate would have to run more than ``GATE_DEEPEST`` smallest radii under it to stay clear
    of the grains resting there (``geometry.gate_depth``)."""
    from silodem.silo.geometry import (
        GATE_CLEARANCE,
        GATE_DEEPEST,
        gate_depth,
        gate_opening_time,
        gate_overlap,
    )

    d, r_min = cfg.discharge, cfg.material.radius_min
    opening = gate_opening_time(cfg)
    if opening is None:
        return
    if not d.gate_speed * dt <= r_min:
        raise InputError(
            f"discharge.gate_speed = {d.gate_speed:.3g} m/s moves the gate "
            f"{d.gate_speed * dt:.3g} m in one time step of {dt:.3g} s, more than "
            f"material.radius_min = {r_min:.3g} m: give at most {floor_3(r_min / dt):.3g} m/s")
    if d.max_time <= opening:
        raise InputError(
            f"discharge.max_time = {d.max_time:g} s ends the discharge before the gate has slid "
            f"open (outlet width / discharge.gate_speed = {opening:.3g} s): give a longer "
            "max_time or a faster gate")
    overlap = gate_overlap(cfg)
    depth = gate_depth(cfg, overlap)
    if not depth <= GATE_DEEPEST * r_min:
        raise InputError(
            f"discharge.gate_speed: under the flat floor the sliding gate must run "
            f"{GATE_CLEARANCE:g} expected overlaps ({overlap:.3g} m) deep, {depth:.3g} m, to "
            "stay clear of the grains resting there, more than "
            f"{GATE_DEEPEST:g} material.radius_min; stiffen the contacts (the overlap "
            "warning's advice) or leave discharge.gate_speed unset")


def check_schedule(cfg: Config) -> None:
    """InputError when the time limits leave a phase's work undone whatever happens: a pour
    whose fill.rate cannot place fill.n_particles before fill.max_time (a batch every
    ``BATCH_INTERVAL``), a measurement interval longer than the whole run (no sample at all),
    a discharge measurement window that begins after discharge.max_time.  Each ran to the end
    and left a warning, an empty table or a report without the discharge."""
    from silodem.silo.procedure import BATCH_INTERVAL

    f, m, d = cfg.fill, cfg.measure, cfg.discharge
    allowed = f.rate * (f.max_time + 2.0 * BATCH_INTERVAL)  # what the batches let in at most
    placed = math.ceil(allowed) if math.isfinite(allowed) else allowed
    if f.method == "pour" and not placed >= f.n_particles:
        raise InputError(
            f"fill.rate = {f.rate:.3g} grains/s pours at most about {placed:.3g} of the "
            f"{f.n_particles} grains (fill.n_particles) in fill.max_time = {f.max_time:.3g} s; "
            f"give a fill.rate of at least {f.n_particles / f.max_time:.3g} grains/s, a longer "
            "fill.max_time or fewer grains")
    total, words = phase_time_limits(cfg)
    if not m.interval < total:
        raise InputError(f"measure.interval = {m.interval:.3g} s is longer than the whole run "
                         f"({total:.3g} s = {words}): not one measurement would be taken; "
                         f"give a shorter measure.interval")
    if d.enabled and not m.discharge_delay < d.max_time:
        raise InputError(f"measure.discharge_delay = {m.discharge_delay:.3g} s is not shorter "
                         f"than discharge.max_time = {d.max_time:.3g} s: the discharge would "
                         "end before its measurement window begins; give a shorter "
                         "measure.discharge_delay or a longer discharge.max_time")


def shortest_clog_time(cfg: Config) -> float:
    """The least ``discharge.clog_time`` [s] that can tell a clog from a start: the time a
    grain at rest in the outlet takes to fall to the removal level 4 r_max below it,
    sqrt(8 r_max / g), plus one check interval, since the clog clock starts when the gate
    opens and exits are counted at the checks (0.05 s apart).  Without gravity, the interval
    alone."""
    from silodem.silo.procedure import CHECK_INTERVAL

    g = cfg.gravity
    fall = math.sqrt(8.0 * cfg.material.radius_max / g) if g > 0 else 0.0
    return fall + CHECK_INTERVAL


def phase_time_limits(cfg: Config) -> tuple[float, str]:
    """The longest simulated time ``cfg`` may run [s], the sum of its phases' time limits,
    and that sum in words: fill.max_time + settle.max_time (+ discharge.max_time when the
    discharge is on)."""
    total, words = cfg.fill.max_time + cfg.settle.max_time, "fill.max_time + settle.max_time"
    if cfg.discharge.enabled:
        total += cfg.discharge.max_time
        words += " + discharge.max_time"
    return total, words


MAX_STEPS = 1e12  # a run allowed more steps than this is refused
STIFFNESS_RANGE = (1e-100, 1e100)  # contact stiffnesses [N/m] (or moduli [Pa]) outside: refused
MAX_GRID_CELLS = 1e7  # velocity-field cells (3 sums each) [-]
MAX_FIELD_CELLS = 1e6  # density and stress field cells (2 x 4 sums, 256 quadrature points) [-]
MAX_WALL_BINS = 1e6  # wall-stress bins [-]
MAX_KERNEL_CELLS = 1e4  # field cells a grain's or contact's Gaussian is summed over [-]
MAX_SEARCH_CELLS = 1e8  # cells of the neighbour search over the silo [-]


def _check_circles(cfg: Config, shape, size: str) -> None:
    """InputError for a configured measurement circle larger than the silo's diagonal (its
    area quadrature would overflow) or with no part inside the silo (it would measure
    nothing); the circles placed as the recorder places them (``regions.circles_for``)."""
    from silodem.measure.regions import circles_for

    if cfg.measure.circle_names is None:
        return
    reach = math.hypot(shape.width, shape.wall_top)
    for name, r in zip(cfg.measure.circle_names, cfg.measure.circle_radius):
        if r > reach:
            raise InputError(f"measure.circle_radius of circle '{name}' = {r:.3g} m is larger "
                             f"than {size} (diagonal {reach:.3g} m)")
    m = cfg.measure
    for c, z in zip(circles_for(cfg, shape), m.circle_z):
        if c.area_inside == 0.0:
            raise InputError(f"measurement circle '{c.name}' (x = {c.x:.3g} m, z = {z:.3g} m "
                             f"from the {m.circle_z_from}, radius {c.radius:.3g} m) has no "
                             f"part inside {size}")


def floor_3(x: float) -> float:
    """``x`` rounded down to 3 significant digits: a limit quoted with ``:.3g`` that the value
    quoted then meets (378.6 -> 378, not 379)."""
    if not (math.isfinite(x) and x > 0):
        return x
    unit = 10.0 ** (math.floor(math.log10(x)) - 2)
    return math.floor(x / unit * (1 + 1e-12)) * unit  # 3.6 / 0.01 is 359.99...


def check_sizes(cfg: Config) -> None:
    """InputError when a length, valid by itself, is so small against the silo that the
    arrays it sizes would not fit in memory: the velocity grid (``measure.grid_cell``), the
    density and stress fields (``measure.field_cell``), the wall bins (``measure.wall_bin``),
    the neighbour search's cells (2 r_max + skin); and when a band or strip of the
    measurements is larger than the silo (a near-wall strip wider than half the cell, a
    junction band or switch zone taller than the walls: their stresses would be divided by
    areas the silo does not have, and a zone of 1e20 m made the figures fail)."""
    from silodem.measure.gaussian import CUTOFF
    from silodem.measure.regions import (
        bin_length,
        field_cell,
        field_spacing,
        field_width,
        grid_cell,
    )
    from silodem.silo.procedure import neighbour_skin

    shape = silo_shape(cfg)
    width, height = shape.width, shape.wall_top
    size = f"the silo ({width:.3g} m x {height:.3g} m)"
    grids = [("grid_cell", grid_cell(cfg), "one mean grain diameter", "velocity",
              MAX_GRID_CELLS),
             ("field_cell", field_cell(cfg), "four mean grain diameters", "field",
              MAX_FIELD_CELLS)]
    bands = (("strip_width", 0.5 * width, "half the cell's width"),
             ("coordination_band", height, "the walls' height"),
             ("switch_zone_half_height", height, "the walls' height"))
    for name, limit, what in bands:
        value = getattr(cfg.measure, name)
        if value is not None and not value <= limit:
            raise InputError(f"measure.{name} = {value:.3g} m is more than {what} in {size}; "
                             f"give at most {floor_3(limit):.3g} m")
    for name, cell, default, what, limit in grids:
        # in floats: a silo of 1e300 m gives inf cells, refused, not an overflow
        cells = max(1.0, width / cell) * max(1.0, height / cell)
        if not cells <= limit:
            key = f"measure.{name}" if getattr(cfg.measure, name) else \
                f"measure.{name} (unset: {default})"
            raise InputError(f"{key} = {cell:.3g} m cuts {size} into {cells:.3g} {what} "
                             f"cells, more than {limit:.0e}; give a larger measure.{name}")
    bins = 2.0 * (width + height) / bin_length(cfg)
    if not bins <= MAX_WALL_BINS:
        key = "measure.wall_bin" if cfg.measure.wall_bin else \
            "measure.wall_bin (unset: two mean grain diameters)"
        raise InputError(f"{key} = {bin_length(cfg):.3g} m cuts the walls of {size} into "
                         f"{bins:.3g} bins, more than {MAX_WALL_BINS:.0e}; give a larger "
                         "measure.wall_bin")
    if cfg.measure.field_kernel == "gaussian":
        kernel, spacing = field_width(cfg, shape), field_spacing(cfg, shape)
        if not kernel >= 0.5 * spacing:
            raise InputError(
                f"measure.field_width = {kernel:.3g} m is less than half the field grid's "
                f"largest cell side ({spacing:.3g} m, measure.field_cell rounded to a whole "
                "number of cells across the silo): the grid's samples of the Gaussian no "
                "longer add up to a grain's mass (within 3 % at half a cell, 18 % at 0.4 of "
                f"one; all zero far below); give at least {0.5 * spacing:.3g} m or a smaller "
                "measure.field_cell")
        reach = 2.0 * CUTOFF * kernel / field_cell(cfg)  # cells across one kernel
        kernel_cells = reach * reach  # a float product: inf, not an OverflowError, for 1e300
        if not kernel_cells <= MAX_KERNEL_CELLS:
            raise InputError(
                f"measure.field_width = {kernel:.3g} m spreads each grain and contact "
                f"over {kernel_cells:.3g} field cells of {field_cell(cfg):.3g} m, more than "
                f"{MAX_KERNEL_CELLS:.0e} (a slow measurement); give a smaller "
                "measure.field_width or a larger measure.field_cell")
    _check_circles(cfg, shape, size)
    search = 2.0 * cfg.material.radius_max + neighbour_skin(cfg)  # as NeighborList.rebuild
    cells = (width / search + 1) * (height / search + 1)
    if not cells <= MAX_SEARCH_CELLS:
        raise InputError(f"material.radius_max = {cfg.material.radius_max:.3g} m is so small "
                         f"against {size} that its neighbour search needs {cells:.3g} cells, "
                         f"more than {MAX_SEARCH_CELLS:.0e}; give larger grains or a smaller "
                         "silo")


def shallow_hopper_warning(cfg: Config) -> str | None:
    """A warning for a hopper lower than the largest grain's diameter: the grains cannot tell
    it from a flat floor, and the hopper's measurements (the junction's stress peak, the
    hopper theory's predictions) then describe a hopper the run did not have."""
    s = cfg.silo
    diameter = 2.0 * cfg.material.radius_max
    if s.kind != "hopper" or s.hopper_height >= diameter:
        return None
    return (f"silo.hopper_angle_from_horizontal_deg = {s.hopper_angle_from_horizontal_deg:.3g} "
            f"deg makes a hopper {s.hopper_height:.3g} m high, lower than one grain "
            f"({diameter:.3g} m, 2 material.radius_max): the grains sit on it as on a flat "
            f"floor, and the hopper theory's predictions do not apply; give silo.kind = "
            f"'flat', or a steeper hopper")


def local_damping_warning(cfg: Config) -> str | None:
    """A warning for PFC local damping (``material.local_damping`` alpha > 0) in a run with a
    discharge: it takes alpha |F| off every moving grain's unbalanced force, so a grain in free
    fall accelerates at (1 - alpha) g (docs/physics.md), and the discharge's rate, Beverloo C
    and flow pattern are those of a damped flow (alpha = 0.7 took paper-case2 --quick's
    discharge from 3.1 s to 9.8 s, without a word: an audit)."""
    alpha = cfg.material.local_damping
    if alpha <= 0.0 or not cfg.discharge.enabled:
        return None
    return (f"material.local_damping = {alpha:g} slows the discharge (a falling grain "
            f"accelerates at {1.0 - alpha:.3g} g): its rate, Beverloo C and flow pattern are "
            "those of a damped flow; local damping is a settling aid, leave it at 0 to measure "
            "the discharge")
