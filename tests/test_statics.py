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
    total = np.zeros(2)
    for _ in range(window):
        sim.step()
        total += q.force_on_walls(sim).sum(axis=0)
    weight = p.total_mass() * g
    mean = total / window
    assert mean[1] == pytest.approx(-weight, rel=1e-3)  # grains push the walls down
    assert abs(mean[0]) < 1e-3 * weight  # side walls balance each other
    assert q.unbalanced_force_ratio(sim) < 1e-2
