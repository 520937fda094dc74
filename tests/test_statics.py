"""Static equilibrium: the walls of a closed box carry exactly the weight of the settled pile."""

from __future__ import annotations

import numpy as np
import pytest

from silodem.engine import quantities as q
from silodem.engine.contact import GrainLaw, damping_ratio_from_restitution
from silodem.engine.particles import Particles
from silodem.engine.simulation import Simulation
from silodem.engine.walls import Walls


@pytest.mark.parametrize("local_damping", [0.0, 0.7])
def test_settled_pile_weight_equals_summed_wall_forces(local_damping):
    """108 grains settled in a closed box for 6 s, then 2500 steps (T = 0.5 s) averaged.

    Without local damping the grains' momentum P obeys dP/dt = -(force on the walls) + weight
    exactly (the grain-grain forces cancel in pairs; the leap-frog adds each step's forces
    times dt to m v), so the mean force on the walls is -(W + Delta P / T) to round-off, and
    the pile being at rest makes Delta P / T a small part of W.  PFC's local damping
    (alpha = 0.7) adds forces that do not cancel, and takes the pile to rest
    geometrically: after 6 s the walls carry its weight to within 1e-8 (measured 1e-10)."""
    rng = np.random.default_rng(11)
    size, k, g = 2.0, 1e6, 9.81
    walls = Walls()
    corners = [(0, 0), (size, 0), (size, 2 * size), (0, 2 * size)]
    for a, b, name in zip(corners, corners[1:] + corners[:1], ["floor", "right", "top", "left"]):
        walls.add(name, a, b, k, k, 0.4)
    xs, ys = np.meshgrid(np.linspace(0.12, 1.88, 9), np.linspace(0.15, 2.6, 12))
    p = Particles(8)
    p.add(xs.ravel() + rng.uniform(-0.02, 0.02, xs.size), ys.ravel(),
          rng.uniform(0.07, 0.1, xs.size), 1500.0)
    law = GrainLaw(kn=k / 2, ks=k / 2, mu=0.5, zeta=damping_ratio_from_restitution(0.3),
                   local_damping=local_damping)
    sim = Simulation(p, walls, law, dt=2e-4, gravity=g, skin=0.02)
    sim.run(int(6.0 / sim.dt))
    window = 2500
    m = p.mass[:p.n]

    def momentum():
        return np.array([np.sum(m * p.vx[:p.n]), np.sum(m * p.vy[:p.n])])

    before = momentum()
    total = np.zeros(2)
    for _ in range(window):
        sim.step()
        total += q.force_on_walls(sim).sum(axis=0)
    weight = p.total_mass() * g
    mean = total / window
    change = (momentum() - before) / (window * sim.dt)  # Delta P / T [N]
    if local_damping == 0.0:
        # grains push the walls down with their weight, less what speeds them up
        assert abs(mean[1] + weight + change[1]) < 1e-12 * weight  # measured 7e-16
        assert abs(mean[0] + change[0]) < 1e-12 * weight  # the side walls balance
        assert abs(change[1]) < 1e-3 * weight  # at rest: 1.4e-4 (settling on)
    else:
        assert abs(mean[1] + weight) < 1e-8 * weight and abs(mean[0]) < 1e-8 * weight
        assert q.unbalanced_force_ratio(sim) < 1e-8


@pytest.mark.parametrize("alpha", [0.3, 0.7])
def test_local_damping_scales_gravity_by_one_minus_alpha_falling_one_plus_alpha_rising(alpha):
    """PFC local damping, F_d = -alpha |F| sign(v) per degree of freedom (Itasca PFC2D manual;
    docs/physics.md): a free grain's only force is its weight, so while it falls it
    accelerates at g (1 - alpha) and while it rises it slows at g (1 + alpha). The leap-frog
    integrates a constant acceleration exactly; the horizontal velocity and the spin, with no
    force or moment on them, keep their values."""
    g, dt, steps = 9.81, 1e-3, 1000
    p = Particles(8)
    p.add([0.0, 5.0], [0.0, 0.0], [0.1, 0.1], 1000.0, vx=[0.7, -0.4], vy=[-1.0, 20.0],
          omega=[3.0, -2.0])
    law = GrainLaw(kn=1e6, ks=1e6, mu=0.5, zeta=0.0, local_damping=alpha)
    sim = Simulation(p, Walls(), law, dt=dt, gravity=g, skin=0.02)
    sim.run(steps)
    t = steps * dt
    by_uid = np.argsort(p.view("uid"))
    vx, vy, omega = (p.view(name)[by_uid] for name in ("vx", "vy", "omega"))
    assert vy[0] == pytest.approx(-1.0 - g * (1 - alpha) * t, rel=1e-12)
    assert vy[1] == pytest.approx(20.0 - g * (1 + alpha) * t, rel=1e-12)
    assert vy[1] > 0  # still rising: the sign of v did not change
    np.testing.assert_array_equal(vx, [0.7, -0.4])
    np.testing.assert_array_equal(omega, [3.0, -2.0])


def test_config_stiffnesses_combine_in_series_for_grain_and_wall_contacts():
    """PFC2D's convention (DESIGN section 1): the stiffness of a contact is the two bodies'
    springs in series, k = k_a k_b / (k_a + k_b). Two grains stacked at rest on the floor of a
    silo built from a config with grain k_n = 1e6 N/m and wall k_n = 3e6 N/m: the floor
    contact carries both weights on 7.5e5 N/m, the grain-grain contact the upper weight on
    5e5 N/m, so the overlaps are those weights over these stiffnesses (statics)."""
    from silodem.scenario_files import load_config
    from silodem.silo.checks import grain_law
    from silodem.silo.geometry import build_walls

    cfg = load_config("paper-case1", ["material.kn=1e6", "material.ks=1e6", "walls.kn=3e6",
                                      "walls.ks=3e6", "material.restitution=0.1"])
    m, g = cfg.material, cfg.gravity
    r1, r2 = m.radius_min, m.radius_max
    p = Particles(8)
    p.add([1.0, 1.0], [r1, 2 * r1 + r2], [r1, r2], m.density, thickness=m.thickness)
    sim = Simulation(p, build_walls(cfg), grain_law(cfg), dt=1e-4, gravity=g, skin=0.02)
    sim.run(40_000)
    assert q.unbalanced_force_ratio(sim) < 1e-9
    by_uid = np.argsort(p.view("uid"))  # the list build may have reordered the grains
    y, mass = p.view("y")[by_uid], p.view("mass")[by_uid]
    floor_overlap = r1 - y[0]
    pair_overlap = r1 + r2 - (y[1] - y[0])
    assert floor_overlap == pytest.approx(mass.sum() * g / 7.5e5, rel=1e-6)
    assert pair_overlap == pytest.approx(mass[1] * g / 5e5, rel=1e-6)


def test_the_top_of_the_grains_is_the_mean_of_the_five_highest_tops():
    """The fill level (procedure and the mass-flow index's rows): by hand, tops 1.1, 2.2,
    3.3, 4.4, 5.5, 6.6 and 0.5 -> (2.2 + 3.3 + 4.4 + 5.5 + 6.6) / 5 = 4.4; fewer than five
    grains: all of them; none: 0."""
    from silodem.engine.quantities import top_of_grains

    y = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 0.4])
    r = np.array([0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.1])
    assert top_of_grains(y, r) == pytest.approx(4.4, rel=1e-15)
    assert top_of_grains(y[:2], r[:2]) == pytest.approx(1.65, rel=1e-15)
    assert top_of_grains(np.zeros(0), np.zeros(0)) == 0.0
