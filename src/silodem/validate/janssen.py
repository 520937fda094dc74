"""Janssen (1895) in a 2D slot silo: wall pressures of a tall column against the 2D solution.

Set-up (a narrow, tall flat-bottomed silo run by ``SiloRun`` with discharge disabled):
slot width B = 12 d (d = 1 cm mean diameter, radii uniform in [0.4 d, 0.6 d], thickness d),
1700 grains filled loose and settled, a column about 11 B deep, grain friction 35 deg, wall
friction phi_w = 15 deg (mu_w = tan phi_w = 0.268).

Mobilising the wall friction.  Janssen assumes that the wall friction is fully mobilised,
tau = mu_w sigma_h, i.e. that the grains are about to slide down the walls.  A column that was
poured or dropped and came to rest has no reason to be in that state: the friction the walls
carry depends on its history and is usually far below mu_w sigma_h (docs/theory.md).  Here,
once the column has settled, the floor (both floor pieces and the gate) is lowered slowly,
0.3 d/s over 3 d, so that the whole column slides down along the walls, then held still and
the column settled again; this is the active state Janssen describes.  The side walls reach
10 d below the floor so that no gap opens at the corners.  The mobilised friction
sum(tau)/sum(sigma_n) is checked against tan(phi_w) within 15 % (``MOBILISED_TOL``): in a
packing of disks it stays a little below it (0.91-0.96), as wall grains can roll instead of
slide; Coulomb's law bounds it from above.

Measured (averaged over 20 frames and five fills with different seeds):

* the wall normal stress sigma_h(depth) in bins of 4 d on both vertical walls, and the
  mobilised wall friction, with ``measure.wall_profiles``;
* the Love-Weber stress of the grains within 2 d of each wall, in 4 d high bins: K_tensor =
  sum(sigma_xx)/sum(sigma_zz) over the column (``measure.stress``, ``binned_stress``);
* the bulk density rho_b of the column (each disk by its area in the band,
  ``measure.fields.band_solid_area``).

Checks: the mobilised friction, above, the one reference from outside the run (the two
below take mu_mob from the same bins, so they follow any wall friction the engine applies);
K fitted to the wall profile with ``theory.fit_janssen`` (mu_w = the mobilised
friction) agrees with K_tensor within 10 % (traction continuity: the wall's normal stress is
the grains' sigma_xx at the wall, so two independent measurements of one ratio); the
saturation wall stress (mean of sigma_h deeper than three Janssen lengths B/(2 K mu_mob))
matches 2D Janssen with the mobilised friction at the same depths within 5 %: deep down the
walls carry the weight, 2 mu_mob sigma_h = rho_b g B (vertical force balance; the saturation
level does not depend on K, which only sets how close to it the bins are: the depth factor
1 - exp(-depth / L) is 0.95-1 over these bins, so K's share of the expected value is under
5 %).  The 5 % tolerance: the saturation moved by about +-3 % between sets of fills in the
runs of docs/validation.md, section 4 (+4 % to +10.6 % against tan(phi_w)).  Reported, not
checked: the textbook level rho_b g B/(2 tan(phi_w)), which assumes full mobilisation and so
lies below the measured one by the mobilised share (about 1/0.91 = 1.10, the size of a 10 %
tolerance: a check against it passed or failed by the scatter between fills).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from silodem import theory as th
from silodem.config import Config
from silodem.measure import regions
from silodem.measure.fields import band_solid_area
from silodem.measure.reading import read_simulation
from silodem.measure.wall_profiles import binned_stress, wall_bins, wall_stress
from silodem.silo.procedure import SiloRun
from silodem.validate.records import Record, info, rel

CASE = "Janssen slot silo"
K_TOL = 0.10
SATURATION_TOL = 0.05
# Janssen's assumption, a column sliding down its walls mobilising their friction fully, and
# Coulomb's law, which bounds it by tan(phi_w): measured 0.91-0.96 of it (wall disks partly
# roll); a law applying 0.7 of the configured friction falls 30 % short
MOBILISED_TOL = 0.15
D = 0.01  # mean grain diameter [m]
WIDTH = 12  # slot width / d
N_GRAINS = 1700
SEEDS = (1, 2, 3, 4, 5)
GRAIN_FRICTION_DEG = 35.0
WALL_FRICTION_DEG = 15.0
LOWER_SPEED = 0.3 * D  # [m/s]
LOWER_BY = 3.0 * D  # [m]
BIN = 4.0 * D  # wall bins and stress bins [m]
STRIP = 2.0 * D  # near-wall strips [m]
SAMPLES, SAMPLE_STEPS = 20, 100
FLOORS = ("left_floor", "right_floor", "gate")


def config(seed: int) -> Config:
    grain = {"density": 2500.0, "radius_min": 0.4 * D, "radius_max": 0.6 * D, "thickness": D,
             "kn": 2e4, "ks": 2e4, "friction_deg": GRAIN_FRICTION_DEG, "restitution": 0.5}
    return Config.model_validate({
        "name": "validate-janssen", "seed": seed,
        "description": "validation: Janssen slot silo (silodem validate)",
        "material": grain,
        "walls": {"kn": 2e4, "ks": 2e4, "friction_deg": WALL_FRICTION_DEG},
        "silo": {"kind": "flat", "cell_width": WIDTH * D, "wall_height": 2.5,
                 "outlet_width": 4 * D},
        "fill": {"method": "loose", "n_particles": N_GRAINS},
        "settle": {"criterion": "force_ratio", "threshold": 1e-3, "max_time": 5.0,
                   "min_time": 0.3},
        "discharge": {"enabled": False},
        "output": {"png": False},
        "checkpoint": {"enabled": False},
    })


@dataclass
class Column:
    """One filled, lowered and settled column: profiles in the lab frame, time-averaged."""

    level: float  # free surface [m]
    floor: float  # z of the floor [m]
    rho_b: float  # bulk density [kg/m^3]
    z_wall: np.ndarray  # wall bin centres [m], both walls
    sigma_n: np.ndarray  # wall normal stress [Pa]
    tau_down: np.ndarray  # downward shear traction on the wall [Pa]
    z_strip: np.ndarray  # stress bin centres [m]
    near: np.ndarray  # near-wall Love-Weber stress (xx, zz, xz) [Pa], both walls averaged
    slices: np.ndarray  # full-width Love-Weber stress [Pa]


def fill_column(seed: int) -> Column:
    cfg = config(seed)
    run = SiloRun(cfg)
    walls = run.walls
    # the side walls reach below the floor, so that lowering the floor opens no gap
    walls.by[walls.index("left_wall")] = -10.0 * D
    walls.ay[walls.index("right_wall")] = -10.0 * D
    walls.update_caps()
    run.run()
    sim = run.sim
    floors = [walls.index(name) for name in FLOORS]
    walls.vy[floors] = -LOWER_SPEED
    sim.run(round(LOWER_BY / LOWER_SPEED / sim.dt))
    walls.vy[floors] = 0.0
    sim.run(round(0.2 / sim.dt))
    bins = wall_bins(walls.ax, walls.ay, walls.bx, walls.by, BIN)
    z_edges = np.arange(-10.0 * D, cfg.silo.wall_height + BIN, BIN)
    dz = np.diff(z_edges)
    sn_sum = np.zeros(bins.wall.size)
    tau_sum = np.zeros(bins.wall.size)
    near_sum = np.zeros((dz.size, 3))
    slice_sum = np.zeros((dz.size, 3))
    t = cfg.material.thickness
    for _ in range(SAMPLES):
        sim.run(SAMPLE_STEPS)
        rd = read_simulation(sim)
        sn, tau = wall_stress(bins, walls.ax, walls.ay, rd.w_wall, rd.w_cx, rd.w_cz, rd.w_fx,
                              rd.w_fz, t)
        sn_sum += sn
        tau_sum += tau
        dl, dr = regions.edge_distance(run.shape, rd.x, rd.z)
        for mask in (dl < STRIP, dr < STRIP):
            near_sum += 0.5 * binned_stress(rd.moments, rd.z, mask, z_edges, STRIP * dz, t)
        slice_sum += binned_stress(rd.moments, rd.z, np.ones(rd.n, bool), z_edges,
                                   cfg.silo.cell_width * dz, t)
    sn, tau = sn_sum / SAMPLES, tau_sum / SAMPLES
    side = np.isin(bins.wall, [walls.index("left_wall"), walls.index("right_wall")])
    down = -tau * np.sign(bins.tangent[bins.wall, 1])  # traction pointing down the wall
    level = run.fill_level()
    floor = float(walls.ay[floors[0]])
    p = sim.particles
    lo, hi = floor + 2.0 * D, level - 2.0 * D
    solid = band_solid_area(p.view("y"), p.view("radius"), lo, hi)
    rho_b = cfg.material.density * solid / ((hi - lo) * cfg.silo.cell_width)
    return Column(level, floor, rho_b, bins.z[side], sn[side], down[side],
                  0.5 * (z_edges[:-1] + z_edges[1:]), near_sum / SAMPLES, slice_sum / SAMPLES)


def _cell(depth, height) -> np.ndarray:
    """Bins of the column proper: below the surface layer, above the floor's corner zone."""
    return (depth > 2.0 * D) & (height > 4.0 * D)


def run(quick: bool = False) -> tuple[list[Record], dict]:
    cols = [fill_column(s) for s in SEEDS]
    B, g = WIDTH * D, 9.81
    mu_w = math.tan(math.radians(WALL_FRICTION_DEG))
    rho_b = float(np.mean([c.rho_b for c in cols]))
    depth = np.concatenate([c.level - c.z_wall for c in cols])
    height = np.concatenate([c.z_wall - c.floor for c in cols])
    sn = np.concatenate([c.sigma_n for c in cols])
    down = np.concatenate([c.tau_down for c in cols])
    cell = _cell(depth, height)
    mu_mob = float(down[cell].sum() / sn[cell].sum())
    fit = th.fit_janssen(depth[cell], sn[cell], rho_b, g, B, mu_w=mu_mob)
    free = th.fit_janssen(depth[cell], sn[cell], rho_b, g, B)
    s_depth = np.concatenate([c.level - c.z_strip for c in cols])
    s_height = np.concatenate([c.z_strip - c.floor for c in cols])
    near = np.concatenate([c.near for c in cols])
    slices = np.concatenate([c.slices for c in cols])
    s_cell = _cell(s_depth, s_height) & np.isfinite(near[:, 0]) & np.isfinite(near[:, 1])
    k_tensor = float(near[s_cell, 0].sum() / near[s_cell, 1].sum())
    length = B / (2.0 * fit.K * mu_mob)  # Janssen length [m]
    deep = cell & (depth > 3.0 * length)
    s_deep = s_cell & (s_depth > 3.0 * length)
    sat_h = float(sn[deep].mean()) if deep.any() else float("nan")
    sat_v = float(slices[s_deep, 1].mean()) if s_deep.any() else float("nan")
    expected_h = (float(np.mean(th.janssen_sigma_h(depth[deep], rho_b, g, B, fit.K, mu_mob)))
                  if deep.any() else float("nan"))
    label = (f"{CASE}, B = {WIDTH} d, {len(SEEDS)} fills of {N_GRAINS} grains, "
             f"phi_w = {WALL_FRICTION_DEG:g} deg")
    records = [
        rel(label, "mobilised wall friction sum(tau)/sum(sigma_n)", mu_w, mu_mob, MOBILISED_TOL,
            note="expected: tan(phi_w), fully mobilised as the column slid down its walls "
            "(the floor lowered); Coulomb's law bounds it"),
        info(label, "bulk density rho_b", rho_b, "kg/m^3"),
        info(label, "column depth / Janssen length B/(2 K mu)",
             float(np.mean([c.level - c.floor for c in cols])) / length),
        rel(label, "K fitted to the wall profile (mu_w = mobilised)", k_tensor, fit.K, K_TOL,
            note=f"expected: K = sigma_xx/sigma_zz within {STRIP / D:g} d of the walls "
            f"(Love-Weber); fit +- {fit.K_err:.2g}"),
        rel(label, "saturation wall stress sigma_h (depth > 3 Janssen lengths)", expected_h,
            sat_h, SATURATION_TOL, "Pa",
            note="2D Janssen with mu_mob at those depths, -> rho_b g B / (2 mu_mob): the walls "
            "carry the weight"),
        info(label, "the same against full mobilisation, rho_b g B / (2 tan(phi_w))", sat_h,
             "Pa", expected=rho_b * g * B / (2.0 * mu_w),
             note="lower by the mobilised share mu_mob / tan(phi_w)"),
        info(label, "free Janssen fit (K and mu_w): K", free.K),
        info(label, "free Janssen fit (K and mu_w): mu_w", free.mu_w),
        info(label, "saturation mean vertical stress (slices)", sat_v, "Pa",
             expected=rho_b * g * B / (2.0 * fit.K * mu_mob),
             note="expected: rho_b g B / (2 K mu_mob)"),
    ]
    data = {"depth": depth, "height": height, "sigma_n": sn, "tau_down": down, "cell": cell,
            "s_depth": s_depth, "near": near, "slices": slices, "s_cell": s_cell,
            "rho_b": rho_b, "B": B, "g": g, "mu_w": mu_w, "mu_mob": mu_mob, "K_fit": fit.K,
            "K_tensor": k_tensor, "length": length, "sat_h": sat_h}
    return records, data
