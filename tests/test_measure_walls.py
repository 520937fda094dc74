"""Wall stress profiles: a settled column in a flat-bottomed silo.  Statics says the floor and
the friction on the side walls carry the whole weight, and the horizontal wall forces cancel."""

from __future__ import annotations

import numpy as np
import pytest

from silodem.config import Config, Discharge, Fill, Material, Settle, Silo, WallMaterial
from silodem.measure.reading import read_simulation
from silodem.measure.wall_profiles import (
    bottom_load,
    peak_in_zone,
    rises_past,
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
    """Over 2500 steps (T = 0.5 s) the binned tractions times their areas give the grains'
    force on the walls, which the momentum balance fixes exactly (no local damping: the
    grain-grain forces cancel in pairs): the floor's normal stress and the downward shear on
    the side walls carry the weight W plus the rate of change of the grains' momentum,
    W + Delta P_z / T, and the horizontal forces sum to -Delta P_x / T, to round-off.  The
    column at rest makes Delta P / T a small part of W."""
    cfg, run = settled
    sim, w = run.sim, run.walls
    assert cfg.material.local_damping == 0.0
    p = sim.particles
    m = p.mass[:p.n]

    def momentum():
        return np.array([np.sum(m * p.vx[:p.n]), np.sum(m * p.vy[:p.n])])

    before = momentum()
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
    change = (momentum() - before) / (steps * sim.dt)  # Delta P / T [N]
    assert abs((shear_sum + floor_sum) / steps - (weight + change[1])) < 1e-12 * weight
    assert side.min() > 0  # both side walls are pushed outwards
    assert abs(np.sum(total[:, 0]) / steps + change[0]) < 1e-12 * weight
    assert abs(np.sum(total[:, 1]) / steps + weight + change[1]) < 1e-12 * weight
    assert np.all(np.abs(change) < 1e-3 * weight)  # at rest: 1.9e-4 and 4e-5 of W


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


def test_a_zones_largest_value_is_named_a_peak_only_where_it_is_one():
    """A profile rising down a hopper to a closed gate (36 kPa at the bottom; the audit's
    case 2) has its zone maximum at the zone's lower edge: the profile goes on rising below
    it.  A bump inside the zone is a peak; an unordered or NaN-holed profile is read in z."""
    z = [0.25, 0.65, 1.05, 1.45, 1.85]
    rising = [36e3, 27e3, 18.4e3, 2.5e3, 16e3]
    v, at = peak_in_zone(z, rising, 1.0, 1.9)
    assert (v, at) == (18.4e3, 1.05) and rises_past(z, rising, at) == "below"
    assert rises_past(z, [1, 2, 9, 4, 3], 1.05) is None
    assert rises_past(z, [1, 2, 4, 9, 30], 1.45) == "above"
    assert rises_past(z[::-1], [3, 4, 9, 2, 1], 1.05) is None
    assert rises_past(z, [1, np.nan, 9, np.nan, 3], 1.05) is None
    assert rises_past(z, [10, np.nan, 9, np.nan, 3], 1.05) == "below"
    assert rises_past(z, rising, 7.0) is None


def test_the_bottom_load_sums_the_floor_and_gate_bins_over_their_spans():
    """Bins of a wall, the left floor (0.2 m and 0.3 m spans), the gate (0.4 m) and the right
    floor (0.3 m), at 1000, 2000, 3000 and 4000 Pa on a slab 0.5 m thick: F = 0.5 (200 + 600
    + 1200 + 1200) = 1600 N over 1.2 m of bottom, p = 1600 / (0.5 x 1.2) = 2666.7 Pa; the
    wall's bin and a NaN bin are not counted; without a bottom bin, NaN."""
    names = ["left_wall", "left_floor", "gate", "right_floor"]
    s0 = np.array([0.0, 0.0, 0.2, 0.0, 0.0, 0.5])
    s1 = np.array([1.0, 0.2, 0.5, 0.4, 0.3, 0.9])
    wall = np.array([0, 1, 1, 2, 3, 3])
    normal = np.array([9e9, 1000.0, 2000.0, 3000.0, 4000.0, np.nan])
    force, pressure = bottom_load(normal, s0, s1, wall, names, 0.5)
    assert force == pytest.approx(1600.0, rel=1e-12)
    assert pressure == pytest.approx(1600.0 / 0.6, rel=1e-12)
    assert all(np.isnan(bottom_load(normal[:1], s0[:1], s1[:1], wall[:1], names, 0.5)))


def test_a_sliding_gates_stress_is_binned_along_the_gate_where_it_is_now():
    """A sliding gate moves from where the walls were built: its contacts were binned by their
    distance from the built gate's end A, so a grain a quarter along a gate slid by half its
    length was put three quarters along (in the other of its two 0.2 m bins). They are binned
    along the gate as it is now: the bin whose span holds a quarter of its length."""
    import types

    from silodem.measure.reading import make_reading
    from silodem.measure.recorders import _ProfilesPart
    from silodem.silo.geometry import build_walls, silo_shape

    cfg = _column_config()
    built = build_walls(cfg)
    profiles = _ProfilesPart(cfg, silo_shape(cfg), built)
    g = built.index("gate")
    length = float(np.hypot(built.bx[g] - built.ax[g], built.by[g] - built.ay[g]))
    tangent = np.array([built.bx[g] - built.ax[g], built.by[g] - built.ay[g]]) / length
    shift = 0.5 * length * tangent  # slid along itself by half its length
    now = types.SimpleNamespace(ax=built.ax.copy(), ay=built.ay.copy(), bx=built.bx.copy(),
                                by=built.by.copy())
    now.ax[g] += shift[0]
    now.bx[g] += shift[0]
    r, force = 0.05, 30.0  # a grain resting on the gate a quarter along, pushed up [m, N]
    x, z = now.ax[g] + 0.25 * length * tangent[0], built.ay[g] + r
    one, none = np.ones(1), np.zeros(0)
    rd = make_reading(0.0, 0, np.array([x]), np.array([z]), np.array([r]), np.zeros(1),
                      np.zeros(1), one, np.zeros(1, np.int64), none.astype(np.int64),
                      none.astype(np.int64), none, none, np.zeros(1, np.int64),
                      np.array([g]), np.zeros(1), np.array([force]), now)
    profiles.record(rd)
    bins = profiles.bins
    on_gate = bins.wall == g
    quarter = np.flatnonzero(on_gate & (bins.s0 <= 0.25 * length) & (0.25 * length < bins.s1))
    three_quarters = np.flatnonzero(on_gate & (bins.s0 <= 0.75 * length)
                                    & (0.75 * length < bins.s1))
    assert quarter.size == 1 and three_quarters.size == 1 and quarter[0] != three_quarters[0]
    pressure = profiles.normal[-1]
    area = bins.length[quarter[0]] * cfg.material.thickness
    assert pressure[quarter[0]] == pytest.approx(force / area, rel=1e-12)
    assert np.count_nonzero(pressure) == 1
