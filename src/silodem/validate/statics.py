"""A settled column: the floor and the walls together carry exactly the weight of the grains.

A narrow box (five grains wide, with wall friction, so that the side walls carry part of the
weight, as in a silo) is filled with about a hundred polydisperse disks on a jittered lattice,
which fall and settle under gravity.  Once the mean unbalanced force is small, the forces of
the grains on the walls are averaged over a window of steps.  Static equilibrium of the whole
column (Newton's second law with no net acceleration) requires

    sum over walls of F_y = - m_total g,     sum over walls of F_x = 0,

whatever the distribution of the load between floor and walls.  The column is at rest only
on average; what it still moves is exact in the momentum balance of the whole column: the
grain-grain forces cancel in pairs, and the leap-frog adds each step's forces times dt to
m v, so over a window of T the mean force of the grains on the walls is

    sum over walls of F = - (m_total g + Delta P / T),   g = (0, -g),

to round-off, P = sum m v the grains' momentum (no local damping here).  Checked: that
balance within 1e-9 of the weight, and the column at rest, |Delta P_y / T| within 1e-3 of it.
"""

from __future__ import annotations

import numpy as np

from silodem.engine import quantities as q
from silodem.engine.contact import GrainLaw, damping_ratio_from_restitution
from silodem.engine.particles import Particles
from silodem.engine.simulation import Simulation
from silodem.engine.walls import Walls
from silodem.validate.records import Record, absolute, info, rel

CASE = "settled column"
TOL = 1e-3  # at rest: |Delta P_y / T| / weight
TOL_BALANCE = 1e-9  # momentum balance, round-off over the window's sums (measured ~1e-15)


def run(quick: bool = False) -> tuple[list[Record], dict]:
    rng = np.random.default_rng(11)
    width, height, k, g, rho = 1.0, 4.0, 1e6, 9.81, 1500.0
    walls = Walls()
    corners = [(0.0, 0.0), (width, 0.0), (width, height), (0.0, height)]
    for a, b, name in zip(corners, corners[1:] + corners[:1], ["floor", "right", "top", "left"]):
        walls.add(name, a, b, k, k, 0.5)
    xs, ys = np.meshgrid(np.linspace(0.11, width - 0.11, 5), np.linspace(0.12, 3.6, 20))
    p = Particles(8)
    p.add(xs.ravel() + rng.uniform(-0.01, 0.01, xs.size), ys.ravel(),
          rng.uniform(0.07, 0.1, xs.size), rho)
    law = GrainLaw(kn=k / 2, ks=k / 2, mu=0.5, zeta=damping_ratio_from_restitution(0.3))
    sim = Simulation(p, walls, law, dt=2e-4, gravity=g, skin=0.02)
    ratio = np.inf
    for _ in range(60):  # settle: at least 2 s, at most 12 s
        sim.run(1000)
        ratio = q.unbalanced_force_ratio(sim)
        if sim.time >= 2.0 and ratio < 1e-3:
            break
    window = 2500
    m = p.view("mass")

    def momentum() -> np.ndarray:
        return np.array([np.sum(m * p.view("vx")), np.sum(m * p.view("vy"))])

    before = momentum()
    total = np.zeros((len(walls), 2))
    for _ in range(window):
        sim.step()
        total += q.force_on_walls(sim)
    mean = total / window
    change = (momentum() - before) / (window * sim.dt)  # Delta P / T [N]
    weight = p.total_mass() * g
    fy = float(mean[:, 1].sum())
    label = f"{CASE}, {p.n} disks in a {width:g} m wide box, wall friction 0.5"
    side = float(-(mean[walls.index("left"), 1] + mean[walls.index("right"), 1]))
    records = [
        rel(label, "vertical force of the grains on floor + walls", -(weight + change[1]), fy,
            TOL_BALANCE, "N", "= -(weight + Delta P_y / T) (momentum balance)"),
        absolute(label, "horizontal force on floor + walls / weight", -change[0] / weight,
                 float(mean[:, 0].sum()) / weight, TOL_BALANCE, note="= -Delta P_x / T / weight"),
        absolute(label, "Delta P_y / T / weight over the window (the column at rest)", 0.0,
                 change[1] / weight, TOL),
        info(label, "share of the weight carried by the side walls (friction; < 0: they "
             "hold the column down)", side / weight, note="the column sprang back up after "
             "its fall (mean v_y > 0 near t = 0.7 s) and the wall friction, reversed, locked "
             "in: docs/validation.md section 3"),
        info(label, "unbalanced force ratio when averaging began", ratio),
    ]
    data = {"walls": walls.names, "mean_force": mean, "weight": weight,
            "x": p.view("x").copy(), "y": p.view("y").copy(), "r": p.view("radius").copy(),
            "width": width, "height": height}
    return records, data
