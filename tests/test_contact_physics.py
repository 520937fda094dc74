"""Binary impacts against the analytic linear spring-dashpot and rigid-body solutions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from physics_helpers import (
    MASS,
    RHO,
    R,
    floor,
    frictionless_pair_leapfrog,
    law,
    pair_impact,
    run_until_separated,
    spring_dashpot,
    wall_impact,
)

from silodem.engine.contact import damping_ratio_from_restitution
from silodem.engine.particles import Particles
from silodem.engine.simulation import Simulation
from silodem.engine.walls import Walls

K = 1e5  # contact stiffness [N/m]


@pytest.mark.parametrize("e", [0.2, 0.5, 0.9])
def test_disk_disk_normal_impact_matches_spring_dashpot_with_tension(e):
    zeta = damping_ratio_from_restitution(e)
    ref = spring_dashpot(K, MASS / 2, zeta)
    sim = pair_impact(law(K, zeta=zeta, tension=True), v=1.0, dt=ref["t_c"] / 1000)
    t0, t1 = run_until_separated(sim, lambda: sim.neighbors.pair_fn[0] != 0.0)
    p = sim.particles
    e_sim = (p.vx[1] - p.vx[0]) / 2.0
    # the central-difference scheme's error in e is of order dt / t_c (here 1e-3): within two
    assert e_sim == pytest.approx(e, rel=2e-3)
    # the contact is seen in whole steps: its start and its end each within one step
    assert t1 - t0 == pytest.approx(ref["t_c"], abs=2 * sim.dt)


@pytest.mark.parametrize("e", [0.2, 0.5, 0.9])
def test_disk_wall_normal_impact_matches_spring_dashpot_with_tension(e):
    zeta = damping_ratio_from_restitution(e)
    ref = spring_dashpot(K, MASS, zeta)
    sim = wall_impact(law(K, zeta=zeta, tension=True), floor(K, 0.3), vn=1.0, vt=0.0,
                      dt=ref["t_c"] / 1000)
    t0, t1 = run_until_separated(sim, lambda: sim.neighbors.wc_fn[0] != 0.0)
    assert sim.particles.vy[0] == pytest.approx(e, rel=2e-3)  # O(dt / t_c), as above
    assert t1 - t0 == pytest.approx(ref["t_c"], abs=2 * sim.dt)  # whole steps, as above


@pytest.mark.parametrize("e", [0.02, 0.2, 0.5, 0.9])
def test_no_tension_ends_contact_when_force_vanishes(e):
    """Without tension the contact ends early (Schwager & Poeschel 2007): a shorter contact and
    a larger restitution than the nominal e, both as the analytic solution says."""
    zeta = damping_ratio_from_restitution(e)
    ref = spring_dashpot(K, MASS, zeta)
    sim = wall_impact(law(K, zeta=zeta, tension=False), floor(K, 0.3), vn=1.0, vt=0.0,
                      dt=ref["t_c"] / 2000)
    t0, t1 = run_until_separated(sim, lambda: sim.neighbors.wc_fn[0] != 0.0)
    assert sim.particles.vy[0] == pytest.approx(ref["e_star"], rel=2e-3)  # O(dt / t_c)
    assert t1 - t0 == pytest.approx(ref["t_star"], abs=2 * sim.dt)  # whole steps, as above
    assert ref["e_star"] > e and ref["t_star"] < ref["t_c"]


@pytest.mark.parametrize("e, vt", [(0.5, 10.0), (0.9, 5.0), (0.9, 10.0)])
def test_oblique_wall_impact_gross_sliding_matches_rigid_body(e, vt):
    """v_t' = v_t - mu (1+e) v_n and omega' R = -2 mu (1+e) v_n for a disk (I = m R^2/2) sliding
    on a floor below it throughout the impact; e is the restitution of the no-tension contact."""
    mu, vn = 0.3, 1.0
    zeta = damping_ratio_from_restitution(e)
    ref = spring_dashpot(K, MASS, zeta)
    e_eff = ref["e_star"]
    sim = wall_impact(law(K, mu=mu, zeta=zeta), floor(K, mu), vn=vn, vt=vt, dt=ref["t_c"] / 2000)
    run_until_separated(sim, lambda: sim.neighbors.wc_fn[0] != 0.0)
    p = sim.particles
    assert p.vx[0] == pytest.approx(vt - mu * (1 + e_eff) * vn, rel=5e-3)
    assert p.omega[0] * R == pytest.approx(-2 * mu * (1 + e_eff) * vn, rel=5e-3)


@pytest.mark.parametrize("geometry", ["pair", "wall"])
@pytest.mark.parametrize("phase", [0.0, 0.25, 0.5, 0.75])
def test_undamped_impact_conserves_energy(geometry, phase):
    """zeta = 0, no friction: kinetic energy after the impact equals that before within 2e-5,
    and the pair's velocities after it are those of a brute-force leap-frog of the two disks.

    ``phase`` shifts where the contact starts between two steps.  At dt = t_c/100 the worst of
    20 phases loses 1.5e-5 of the energy in this oblique pair and 2.7e-6 at the wall; at
    t_c/50, 9e-4 and 2.2e-5 (docs/physics.md)."""
    m_eff = MASS / 2 if geometry == "pair" else MASS
    dt = spring_dashpot(K, m_eff, 0.0)["t_c"] / 100
    p = Particles()
    if geometry == "pair":
        p.add(np.array([0.0, 2 * R + 2 * phase * dt]), np.zeros(2), R, RHO,
              vx=np.array([1.0, -1.0]), vy=np.array([0.3, -0.3]))
        start = [p.x.tolist(), p.y.tolist(), p.vx.tolist(), p.vy.tolist()]
        sim = Simulation(p, Walls(), law(K, mu=0.0), dt=dt, gravity=0.0, skin=0.05)
        touching = lambda: sim.neighbors.pair_fn[0] != 0.0
    else:
        p.add(np.array([0.0]), np.array([R + phase * dt]), R, RHO, vx=0.7, vy=-1.0)
        sim = Simulation(p, floor(K, 0.0), law(K, mu=0.0), dt=dt, gravity=0.0, skin=0.05)
        touching = lambda: sim.neighbors.wc_fn[0] != 0.0
    before = p.kinetic_energy()
    run_until_separated(sim, touching)
    assert p.kinetic_energy() == pytest.approx(before, rel=2e-5)
    if geometry == "pair":
        x, y, vx, vy = start
        frictionless_pair_leapfrog(x, y, vx, vy, MASS, R, K, dt)
        # after the contact both fly free: their velocities no longer change
        assert p.vx.tolist() == pytest.approx(vx, rel=1e-12, abs=1e-12)
        assert p.vy.tolist() == pytest.approx(vy, rel=1e-12, abs=1e-12)


def test_damping_ratio_inverts_restitution():
    for e in (0.1, 0.3, 0.7, 0.99):
        zeta = damping_ratio_from_restitution(e)
        assert math.exp(-zeta * math.pi / math.sqrt(1 - zeta**2)) == pytest.approx(e, rel=1e-12)


def _block_walls(k: float, slot_first: bool, thickness: float = 0.2) -> Walls:
    """The left floor piece of the benchmark's outlet: a block x < 0, -thickness < y < 0 drawn
    as its top face and its outlet-side face, joined at the convex corner (0, 0), added in
    either order (the first one carries the corner)."""
    faces = [("floor", (-5.0, 0.0), (0.0, 0.0)), ("slot", (0.0, 0.0), (0.0, -thickness))]
    w = Walls()
    for name, a, b in faces[::-1] if slot_first else faces:
        w.add(name, a, b, k, k, 0.3, one_sided=True)
    return w


def _nearest_on_block(px: float, py: float, thickness: float = 0.2) -> tuple[float, float]:
    """Nearest point of the block's surface to an outside point (clamping to the box)."""
    return min(max(px, -5.0), 0.0), min(max(py, -thickness), 0.0)


@pytest.mark.parametrize("angle", np.linspace(-60.0, 150.0, 15))
@pytest.mark.parametrize("depth", [0.02, 0.3])
@pytest.mark.parametrize("slot_first", [False, True])
def test_convex_corner_pushes_as_the_nearest_point_of_the_block(angle, depth, slot_first):
    """A grain at rest around the edge of a thick floor (floor face, corner wedge, outlet
    face) feels one contact, k (r - dist) along the normal from the block's nearest point,
    whichever of the two segments carries it: no gap at the corner, no double count."""
    r, k = 0.1, 1e5
    dist = r * (1.0 - depth)
    a = math.radians(angle)
    # centre at distance ``dist`` from the block: around the corner for 0-90 degrees, over the
    # floor face beyond 90, beside the outlet face below 0
    cx, cy = _corner_offset(a, dist)
    qx, qy = _nearest_on_block(cx, cy)
    d = math.hypot(cx - qx, cy - qy)
    assert d == pytest.approx(dist, rel=1e-12)
    p = Particles(1)
    p.add(cx, cy, r, 1000.0)
    sim = Simulation(p, _block_walls(k, slot_first), law(k), dt=1e-6, gravity=0.0, skin=0.01)
    sim.step()
    f = k * (r - d)
    assert p.fx[0] == pytest.approx(f * (cx - qx) / d, abs=1e-9 * f)
    assert p.fy[0] == pytest.approx(f * (cy - qy) / d, abs=1e-9 * f)


@pytest.mark.parametrize("offset", [0.0, 1e-12, -1e-12])
def test_grain_over_the_joint_of_two_floor_pieces_rests_on_them(offset):
    """Floor, gate and floor end to end, as the silo builds them: a grain whose centre is
    exactly above a joint (it met neither face and fell through) rests like any other, at
    the static overlap m g / k, with one contact."""
    r, k, g = 0.01, 1e5, 9.81
    w = Walls()
    w.add("left_floor", (-1.0, 0.0), (-0.02, 0.0), k, k, 0.4, one_sided=True)
    w.add("gate", (-0.02, 0.0), (0.02, 0.0), k, k, 0.4, one_sided=True)
    w.add("right_floor", (0.02, 0.0), (1.0, 0.0), k, k, 0.4, one_sided=True)
    p = Particles(1)
    p.add(-0.02 + offset, r + 1e-3, r, 2500.0)
    sim = Simulation(p, w, law(k, zeta=0.3), dt=1e-5, gravity=g, skin=0.003)
    sim.run(20_000)
    assert r - p.y[0] == pytest.approx(p.mass[0] * g / k, rel=1e-9)
    assert np.count_nonzero(sim.neighbors.wc_fn) == 1


def test_a_floor_end_left_by_a_sliding_gate_is_a_contact_point_again():
    """A gate joined to the end of a floor slides away: the floor's end, a joint while they
    met (no cap), is a free end afterwards, and a grain over it is pushed by it as by any
    end point, k (r - d) along the line from it (d: the centre's distance to the end)."""
    r, k = 0.1, 1e6
    w = Walls()
    w.add("floor", (-1.0, 0.0), (0.0, 0.0), k, k, 0.3, one_sided=True)
    w.add("gate", (0.0, 0.0), (1.0, 0.0), k, k, 0.3, velocity=(1.0, 0.0), one_sided=True)
    p = Particles(1)
    p.add(5.0, 5.0, r, 1000.0)  # far from the walls while the gate moves
    sim = Simulation(p, w, law(k, zeta=0.3), dt=1e-4, gravity=0.0, skin=0.02)
    sim.run(5_000)  # the gate is 0.5 m away
    w.vx[1] = 0.0
    cx, cy = 0.05, 0.06  # over the floor's end, off the floor's face (x > 0)
    p.x[0], p.y[0] = cx, cy
    sim.invalidate()
    sim.run(1)
    d = math.hypot(cx, cy)
    assert np.count_nonzero(sim.neighbors.wc_fn) == 1
    assert np.hypot(sim.neighbors.wc_fx, sim.neighbors.wc_fy).sum() == pytest.approx(
        k * (r - d), rel=1e-9)


def _corner_offset(a: float, dist: float) -> tuple[float, float]:
    """A point at distance ``dist`` outside the block, parametrised by ``a``: the corner wedge
    for 0 <= a <= 90 deg, the floor face (x < 0) above 90, the outlet face (y < 0) below 0."""
    if a > math.pi / 2:
        return -dist * (a - math.pi / 2), dist
    if a < 0.0:
        return dist, dist * a
    return dist * math.cos(a), dist * math.sin(a)


def test_kinetic_energy_of_translating_and_spinning_disks():
    """E = m v^2 / 2 + I omega^2 / 2 with I = m r^2 / 2 for a disk, per grain and in total."""
    from silodem.engine.particles import Particles

    p = Particles(4)
    r = np.array([0.1, 0.2])
    p.add(np.zeros(2), np.zeros(2), r, 1000.0, vx=np.array([3.0, 0.0]),
          vy=np.array([4.0, 0.0]), omega=np.array([0.0, 10.0]))
    m = 1000.0 * np.pi * r**2  # disks of unit thickness
    expected = np.array([0.5 * m[0] * 25.0, 0.5 * (0.5 * m[1] * 0.04) * 100.0])
    assert p.kinetic_energies() == pytest.approx(expected, rel=1e-14)
    assert p.kinetic_energy() == pytest.approx(expected.sum(), rel=1e-14)


@pytest.mark.parametrize("tension", [False, True])
def test_branch_free_law_equals_the_reference_law_exactly(tension):
    """``linear_law`` (min/max, no data-dependent branch) gives the bits of the reference DEM's
    if/else form on contacts that stick, slide either way, pull apart or are pushed apart by
    their dashpot."""
    from reference_dem import _law

    from silodem.engine.contact import linear_law

    rng = np.random.default_rng(7)
    kn, ks, cn, mu, dt = 1e5, 8e4, 40.0, 0.4, 1e-4
    for _ in range(2000):
        overlap = rng.uniform(-1e-3, 2e-3)
        vn, vt = rng.normal(0.0, 2.0, 2)
        fs_old = rng.normal(0.0, 50.0)
        got = linear_law(overlap, vn, vt, fs_old, kn, ks, cn, mu, tension, dt)
        assert got == _law(kn * overlap, vn, vt, fs_old, ks, cn, mu, tension, dt)


@pytest.mark.parametrize("zeta", [0.0, 0.05, 0.2155, 0.5, 1.0, 3.0])
def test_damped_step_factor_is_the_leapfrog_stability_edge_of_a_4x_stiffer_mode(zeta):
    """Brute force: the leap-frog of one damped mode x'' = -w^2 x - 2 z w x', dashpot on the
    half-step velocity as in the engine, steps (x, v) by a 2x2 matrix built here from its two
    update lines; it is stable while the matrix's spectral radius is <= 1.  For the mode that
    dt_crit leaves room for, w = 2 sqrt(k/m) with the dashpot's c/k kept (z = 2 zeta),
    bisection on dt sqrt(k/m) finds the edge, which must be sqrt(1 + 4 zeta^2) - 2 zeta
    (undamped: 1, dt_crit itself)."""
    from silodem.engine.contact import damped_step_factor

    def radius(y_c: float) -> float:
        y, z = 2.0 * y_c, 2.0 * zeta  # the 4x stiffer mode: w dt and its damping ratio
        # v' = v - dt (w^2 x + 2 z w v);  x' = x + dt v'   (units: w dt = y, v in w x)
        step = np.array([[1.0, 0.0], [-y, 1.0 - 2.0 * z * y]])  # (x, v) -> (x, v')
        move = np.array([[1.0, y], [0.0, 1.0]])  # (x, v') -> (x + dt v', v')
        return float(np.max(np.abs(np.linalg.eigvals(move @ step))))

    lo, hi = 1e-6, 4.0
    assert radius(lo) <= 1.0 + 1e-12 < radius(hi)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if radius(mid) <= 1.0 + 1e-12 else (lo, mid)
    assert damped_step_factor(zeta) == pytest.approx(lo, rel=1e-6)


def test_a_damped_triangular_packing_is_stable_at_dt_crit_and_not_at_the_undamped_limit():
    """64 disks in a triangular packing, 0.2 % compressed in a box, shear springs at k_n / 5
    (the normal spring sets dt_crit) and e = 0.5, released with velocities of 1e-6 m/s:
    stepped at dt_crit, the dashpots take the kinetic energy of the release down by more than
    a thousand; at the undamped limit sqrt(m_eff / k) (the normal dashpot's factor left out,
    1 / 0.658 x longer) the packing's fastest modes grow instead, as the leap-frog's stability
    condition (docs/physics.md) says.  Growth is shown by energy: dashpots and friction only
    take energy away, so a stable integration keeps the mechanical energy at or below the
    energy at release, E0 (the normal springs' 1/2 k delta^2 over every overlap, the kinetic
    energy; no shear spring is loaded yet); at the undamped limit the kinetic energy plus the
    normal springs' energy alone (a lower bound: the shear springs' is left out) exceeds E0 at
    every sample.  Overlaps are recounted here from the positions, all pairs and the four
    walls."""
    from silodem.engine.contact import critical_time_step, damped_step_factor

    kn, eps, n = 1e6, 2e-3, 8
    zeta = damping_ratio_from_restitution(0.5)
    a = 2 * R * (1 - eps)
    xs = np.array([i * a + (j % 2) * a / 2 for j in range(n) for i in range(n)])
    ys = np.array([j * a * math.sqrt(3) / 2 for j in range(n) for i in range(n)])
    lo, top = -R * (1 - eps), R * (1 - eps)
    corners = [(lo, lo), (xs.max() + top, lo), (xs.max() + top, ys.max() + top),
               (lo, ys.max() + top)]

    def normal_spring_energy(p) -> float:
        x, y = p.x[:p.n], p.y[:p.n]
        upper = np.triu_indices(p.n, 1)
        d = np.hypot(x[:, None] - x[None, :], y[:, None] - y[None, :])[upper]
        gaps = (x - lo, corners[1][0] - x, y - lo, corners[2][1] - y)  # to the four walls
        return 0.5 * kn * (np.sum(np.maximum(2 * R - d, 0.0) ** 2)
                           + sum(np.sum(np.maximum(R - g, 0.0) ** 2) for g in gaps))

    def energies(dt_of) -> tuple[float, list[float], list[float]]:
        grain = law(kn, mu=0.5, zeta=zeta, ks=0.2 * kn)
        walls = Walls()
        for q in range(4):
            walls.add(f"w{q}", corners[q], corners[(q + 1) % 4], kn, 0.2 * kn, 0.5,
                      one_sided=True)
        dt_crit = critical_time_step(MASS, grain, walls.kn, walls.ks)
        rng = np.random.default_rng(0)
        p = Particles()
        p.add(xs, ys, R, RHO, vx=rng.normal(0, 1e-6, xs.size), vy=rng.normal(0, 1e-6, xs.size))
        sim = Simulation(p, walls, grain, dt=dt_of(dt_crit), gravity=0.0, skin=0.02)
        e0 = normal_spring_energy(p) + p.kinetic_energy()
        kinetic, mechanical = [], []
        for _ in range(12):
            sim.run(50)
            kinetic.append(p.kinetic_energy())
            mechanical.append(kinetic[-1] + normal_spring_energy(p))
        return e0, kinetic, mechanical

    e0, kinetic, mechanical = energies(lambda dt_crit: dt_crit)
    # 1/2 k (2 R eps)^2 = 0.08 J in each of the 161 grain-grain contacts, 0.02 J at a wall
    assert 161 * 0.08 < e0 < 161 * 0.08 + 32 * 0.02 + 1e-9
    assert kinetic[-1] < 1e-3 * kinetic[0]
    assert max(mechanical) <= e0
    e0_undamped, _, mechanical = energies(lambda dt_crit: dt_crit / damped_step_factor(zeta))
    assert e0_undamped == e0
    assert min(mechanical) > e0  # energy made by the integration: 1.5-2.4 E0 (six seeds)


def test_a_disk_on_a_moving_wall_slides_then_rolls_at_a_third_of_the_walls_speed():
    """A disk at rest on a floor that starts moving at v (the sliding gate's contact): kinetic
    friction mu m g drives it, a = mu g, and spins it, alpha = mu m g r / I = 2 mu g / r, so
    its bottom point gains 3 mu g per second until it moves with the floor, at t* = v/(3 mu g);
    then it rolls, with no force needed, at v/3 and omega = 2 v / (3 r) (rigid-body mechanics
    of a disk on a belt). The tangential spring rings about the rolling state once the slip
    stops; its mean over many periods is the rigid body's."""
    r, k, g, mu, v = 0.01, 1e5, 9.81, 0.4, 0.2
    w = Walls()
    w.add("floor", (-10.0, 0.0), (10.0, 0.0), k, k, mu, one_sided=True)
    p = Particles(1)
    p.add(0.0, r - 2500.0 * math.pi * r * r * g / k, r, 2500.0)  # at its static overlap
    dt = 1e-5
    sim = Simulation(p, w, law(k, zeta=0.3, mu=mu), dt=dt, gravity=g, skin=0.003)
    sim.run(5_000)  # at rest
    w.vx[0] = v
    t_stick = v / (3.0 * mu * g)
    half = round(0.5 * t_stick / dt)
    sim.run(half)
    t = half * dt
    assert p.vx[0] == pytest.approx(mu * g * t, rel=0.02)
    assert p.omega[0] == pytest.approx(2.0 * mu * g * t / r, rel=0.02)
    sim.run(round(t_stick / dt))  # past t*
    vx, omega = [], []
    for _ in range(2000):  # 0.2 s: many periods of the ringing
        sim.run(10)
        vx.append(p.vx[0])
        omega.append(p.omega[0])
    assert np.mean(vx) == pytest.approx(v / 3.0, rel=0.01)
    assert np.mean(omega) == pytest.approx(2.0 * v / (3.0 * r), rel=0.01)
