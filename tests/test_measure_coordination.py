"""Coordination number of regular packings of equal disks: 4 (square) and 6 (triangular),
the paper's Table 3."""

from __future__ import annotations

import numpy as np
import pytest

from silodem.engine.contact import GrainLaw
from silodem.engine.particles import Particles
from silodem.engine.simulation import Simulation
from silodem.engine.walls import Walls
from silodem.measure.coordination import contacts_per_grain, coordination_number
from silodem.measure.reading import read_simulation
from silodem.measure.stress import circle_measure

R = 0.05


def _packing(kind: str, n: int = 14):
    """Equal disks on a square or triangular lattice, touching with a tiny overlap."""
    s = 2 * R * (1 - 1e-4)
    pts = []
    for row in range(n):
        for col in range(n):
            if kind == "square":
                pts.append((col * s, row * s))
            else:
                pts.append((col * s + (row % 2) * s / 2, row * s * np.sqrt(3) / 2))
    x, z = np.array(pts).T
    p = Particles(n * n)
    p.add(x, z, R, 1000.0)
    sim = Simulation(p, Walls(), GrainLaw(kn=1e5, ks=1e5, mu=0.5, zeta=0.0), dt=1e-5,
                     gravity=0.0, skin=0.01)
    sim.step()  # one step computes the contact forces
    return sim, x.mean(), z.mean()


@pytest.mark.parametrize("kind,expected", [("square", 4), ("triangular", 6)])
def test_coordination_number_of_regular_packings(kind, expected):
    sim, cx, cz = _packing(kind)
    rd = read_simulation(sim)
    m = circle_measure(rd.x, rd.z, rd.r, rd.moments, rd.counts, cx, cz, 0.3)
    assert m["count"] > 20
    assert m["coordination"] == expected
    inner = np.hypot(rd.x - cx, rd.z - cz) < 0.3
    assert coordination_number(rd.counts, inner) == expected


def test_contacts_per_grain_counts_pairs_twice_and_walls_once():
    counts = contacts_per_grain(4, np.array([0, 0, 1]), np.array([1, 2, 2]), np.array([3, 3]))
    assert counts.tolist() == [2, 2, 2, 2]
    assert coordination_number(counts) == 2.0
    assert np.isnan(coordination_number(counts, np.zeros(4, bool)))
