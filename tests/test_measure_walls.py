"""Wall stress profiles: a settled column in a flat-bottomed silo.  Statics says the floor and
the friction on the side walls carry the whole weight, and the horizontal wall forces cancel."""

from __future__ import annotations

import numpy as np
import pytest

from silodem.config import Config, Discharge, Fill, Material, Settle, Silo, WallMaterial
from silodem.measure.reading import read_simulation
from silodem.measure.wall_profiles import (
    peak_in_zone,
    wall_bins,
    wall_force_from_profile,
    wall_stress,
)
from silodem.silo.procedure import SiloRun


def _column_config() -> Config:
    return Config(
        name="column", seed=4,
        material=Material(density=1000.0, radius_min=0.045, radius_max=0.055, kn=1e6, ks=1e6,
                          friction_deg=25.0, restitution=0.3),
        walls=WallMaterial(kn=1e6, ks=1e6, friction_deg=20.0),
        silo=Silo(kind="flat", cell_width=1.2, wall_height=3.0, outlet_width=0.4),
        fill=Fill(method="loose", n_particles=160),
        settle=Settle(threshold=2e-4, max_time=6.0, min_time=1.0),
        discharge=Discharge(enabled=False),
    )


@pytest.fixture(scope="module")
def settled():
    cfg = _column_config()
    run = SiloRun(cfg)
    run.run()
    return cfg, run


def test_wall_shear_and_floor_carry_the_weight(settled):
    cfg, run = settled
    sim, w = run.sim, run.walls
    bins = wall_bins(w.ax, w.ay, w.bx, w.by, 0.2)
    vertical = [w.index("left_wall"), w.index("right_wall")]
    floor = [w.index("left_floor"), w.index("right_floor"), w.index("gate")]
    steps = 2500
    shear_sum = floor_sum = 0.0
    side = np.zeros(2)
    total = np.zeros((len(w), 2))
    t = cfg.material.thickness
    for _ in range(steps):
        sim.step()
        rd = read_simulation(sim)
        sn, tau = wall_stress(bins, w.ax, w.ay, rd.w_wall, rd.w_cx, rd.w_cz, rd.w_fx, rd.w_fz, t)
        area = bins.length * t
        for k in vertical:  # vertical walls: the downward part of the shear traction
            b = bins.wall == k
            shear_sum += np.sum(-tau[b] * bins.tangent[k, 1] * area[b])
        for k in floor:  # horizontal walls: the normal stress
            b = bins.wall == k
            floor_sum += np.sum(sn[b] * area[b])
        side += [np.sum((sn * area)[bins.wall == k]) for k in vertical]
        total += wall_force_from_profile(bins, sn, tau, t)
    weight = sim.particles.total_mass() * sim.gravity
    assert (shear_sum + floor_sum) / steps == pytest.approx(weight, rel=1e-3)
    assert side.min() > 0  # both side walls are pushed outwards
    assert abs(np.sum(total[:, 0])) / steps < 1e-3 * weight  # horizontal forces balance
    assert np.sum(total[:, 1]) / steps == pytest.approx(-weight, rel=1e-3)


def test_bins_cut_each_wall_into_equal_lengths_and_the_peak_is_found_in_its_zone():
    bins = wall_bins(np.array([0.0, 2.0]), np.array([3.0, 0.0]), np.array([0.0, 2.0]),
                     np.array([0.0, 1.0]), 0.4)
    for k, length in ((0, 3.0), (1, 1.0)):
        b = bins.wall == k
        assert bins.length[b].sum() == pytest.approx(length)
        assert np.allclose(bins.length[b], bins.length[b][0])
    assert bins.normal[0].tolist() == [1.0, 0.0]  # left wall drawn downwards: inside at +x
    assert peak_in_zone([0, 1, 2, 3], [5, 9, 7, 20], 0.5, 2.5) == (9.0, 1.0)
    assert np.isnan(peak_in_zone([0, 1], [1, 2], 5, 6)[0])
