"""Love-Weber stress: a packing compressed between walls carries the applied wall stress.

The reference is the wall stress applied by a servo (force on a wall / its loaded length), not
the code under test: in static equilibrium the mean stress of the whole assembly equals the
boundary traction (Christoffersen et al. 1981)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from silodem.engine import quantities as q
from silodem.engine.contact import GrainLaw, damping_ratio_from_restitution
from silodem.engine.particles import Particles
from silodem.engine.simulation import Simulation
from silodem.engine.walls import Walls
from silodem.measure.reading import read_simulation
from silodem.measure.stress import circle_measure, grain_moments, lens_area, region_stress

P_X, P_Z = 3000.0, 1500.0  # applied stresses [Pa]


@pytest.fixture(scope="module")
def compressed_box():
    """16 x 16 grains in a box of frictionless walls; the right and top walls are servo-driven
    to the stresses P_X and P_Z, then stopped and the packing relaxed to rest (no gravity)."""
    N, k, ext = 16, 1e6, 0.6
    L0 = 0.1 * N
    w = Walls()
    w.add("floor", (-ext, 0), (L0 + ext, 0), k, k, 0.0)
    w.add("right", (L0, -ext), (L0, L0 + ext), k, k, 0.0)
    w.add("top", (L0 + ext, L0), (-ext, L0), k, k, 0.0)
    w.add("left", (0, L0 + ext), (0, -ext), k, k, 0.0)
    rng = np.random.default_rng(5)
    xs, ys = np.meshgrid(np.arange(N) * 0.1 + 0.05, np.arange(N) * 0.1 + 0.05)
    p = Particles(512)
    p.add(xs.ravel(), ys.ravel(), rng.uniform(0.045, 0.05, N * N), 1000.0)
    law = GrainLaw(kn=k / 2, ks=k / 2, mu=0.3, zeta=damping_ratio_from_restitution(0.3),
                   local_damping=0.7)
    sim = Simulation(p, w, law, dt=4e-4, gravity=0.0, skin=0.02)
    vmax = 0.05
    for _ in range(450):
        f = q.force_on_walls(sim)
        px, pz = f[1, 0] / w.ay[2], f[2, 1] / w.ax[1]
        w.vx[1] = -vmax * np.clip((P_X - px) / P_X, -1, 1)
        w.vy[2] = -vmax * np.clip((P_Z - pz) / P_Z, -1, 1)
        sim.run(25)
    w.vx[1] = w.vy[2] = 0.0
    sim.run(3000)
    return sim


def boundary_stress(sim):
    """The mean stress of the box from its boundary alone, and how far equilibrium lets the
    Love-Weber stress differ from it.

    Summing f (x) (x_c - X) over every grain, the two forces of a grain-grain contact act at
    one point and cancel in sum f (x) x_c, leaving the wall contacts: sum_walls f (x) x_c minus
    sum_grains F_p (x) X_p, where F_p is grain p's resultant (zero at rest, no gravity). So
    sigma = -(1/A) sym(sum_walls f (x) x_c) (compression positive) to within
    (1/A) sum_p |F_p| |X_p| (Christoffersen et al. 1981). The walls are the box's four sides,
    so each contact point is the grain's centre moved onto its wall's line: computed here
    without the code under test. Returns (sigma_xx, sigma_zz, sigma_xz) [Pa] and the bound."""
    w, p = sim.walls, sim.particles
    width, height = w.ax[1], w.ay[2]
    wc = q.wall_contacts(sim)
    x, z = p.view("x")[wc.grain], p.view("y")[wc.grain]
    cx = np.select([wc.wall == 1, wc.wall == 3], [width, 0.0], x)  # right, left: x fixed
    cz = np.select([wc.wall == 0, wc.wall == 2], [0.0, height], z)  # floor, top: z fixed
    t = np.array([[np.sum(wc.fx * cx), np.sum(wc.fx * cz)],
                  [np.sum(wc.fy * cx), np.sum(wc.fy * cz)]])
    area = width * height
    sigma = -np.array([t[0, 0], t[1, 1], 0.5 * (t[0, 1] + t[1, 0])]) / area
    resultant = np.hypot(p.view("fx"), p.view("fy"))
    bound = np.sum(resultant * np.hypot(p.view("x"), p.view("y"))) / area
    return sigma, bound


def test_stress_of_a_packing_compressed_between_walls_equals_the_wall_stress(compressed_box):
    """Love-Weber over the whole box equals the boundary traction (normal and shear: the side
    walls' loads act at different heights, so the box carries a shear stress) to within what
    the grains' leftover resultants allow; so do the wall forces over the walls' lengths."""
    sim = compressed_box
    w = sim.walls
    width, height = w.ax[1], w.ay[2]  # right wall x, top wall z: the box [0, W] x [0, H]
    f = q.force_on_walls(sim)
    applied_x, applied_z = f[1, 0] / height, f[2, 1] / width  # [Pa], thickness 1 m
    assert applied_x > 1.3 * applied_z > 0  # an anisotropic load (it relaxes a little)
    rd = read_simulation(sim)
    whole = region_stress(rd.moments, np.ones(rd.n, bool), width * height, 1.0)
    reference, bound = boundary_stress(sim)
    assert bound < 1e-5 * applied_z  # at rest: the comparison below is sharp
    assert abs(reference[2]) > 100 * bound  # a shear stress, not zero, is what is checked
    np.testing.assert_allclose(whole, reference, rtol=0, atol=bound)
    # frictionless walls: the side walls carry the x stress, floor and top the z stress
    assert whole[0] == pytest.approx(applied_x, abs=bound)
    assert whole[1] == pytest.approx(applied_z, abs=bound)
    # a PFC measurement circle enclosing the box, porosity taken over the box area
    m = circle_measure(rd.x, rd.z, rd.r, rd.moments, rd.counts, width / 2, height / 2,
                       0.75 * max(width, height), area_inside=width * height)
    np.testing.assert_allclose(m["stress"], reference, rtol=0, atol=bound)
    solid = np.sum(np.pi * rd.r**2)
    assert m["porosity"] == pytest.approx(1.0 - solid / (width * height), abs=1e-9)
    # circles inside the packing (about 70 grains each): the same stress on average. Each
    # circle's value scatters with the grains it holds; the mean of the five is within one
    # circle's scatter s of the applied stress (for independent circles its standard error is
    # s / sqrt 5, for these overlapping ones between that and s): |mean - applied| < s
    xs = []
    for cx, cz in [(0.35, 0.35), (0.35, 0.65), (0.65, 0.35), (0.65, 0.65), (0.5, 0.5)]:
        xs.append(circle_measure(rd.x, rd.z, rd.r, rd.moments, rd.counts, cx * width,
                                 cz * height, 0.3 * width)["stress"])
    mean, scatter = np.mean(xs, axis=0), np.std(xs, axis=0, ddof=1)
    assert abs(mean[0] - applied_x) < scatter[0]
    assert abs(mean[1] - applied_z) < scatter[1]
    assert mean[0] > mean[1]  # the anisotropy of the load is seen


def test_stress_field_of_the_compressed_box_adds_up_to_the_wall_stress(compressed_box):
    """The coarse-grained field on a 4 x 4 grid over the box: each grain is in one cell, so the
    cells' stresses weighted by their areas add up to the whole box's Love-Weber stress
    (exactly) and so to the boundary traction (to the equilibrium bound above)."""
    from silodem.measure.fields import cell_sums, fields_of

    sim = compressed_box
    w = sim.walls
    width, height = w.ax[1], w.ay[2]
    rd = read_simulation(sim)
    xe, ze = np.linspace(0, width, 5), np.linspace(0, height, 5)
    mass, moments = cell_sums(rd.x, rd.z, rd.r, rd.mass, rd.moments, xe, ze)
    area = np.outer(np.diff(xe), np.diff(ze))
    density, stress = fields_of(mass, moments, area, 1.0, 1)
    whole = region_stress(rd.moments, np.ones(rd.n, bool), width * height, 1.0)
    np.testing.assert_allclose((stress * area[..., None]).sum(axis=(0, 1)) / (width * height),
                               whole, rtol=1e-12, atol=1e-12 * abs(whole).max())
    reference, bound = boundary_stress(sim)
    np.testing.assert_allclose(whole, reference, rtol=0, atol=bound)
    assert (density * area).sum() == pytest.approx(rd.mass.sum(), rel=1e-12)


def test_two_disks_pressed_together_carry_f_times_2r_over_the_area():
    # two disks of radius r touching along x with force F: sigma_xx = F * 2r / A, compression
    r, F = 0.5, 10.0
    x, z, rr = np.array([0.0, 2 * r]), np.zeros(2), np.full(2, r)
    m = grain_moments(2, x, z, rr, np.array([0]), np.array([1]), np.array([F]), np.array([0.0]),
                      np.zeros(0, int), np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0))
    s = region_stress(m, np.ones(2, bool), 4.0, 2.0)
    np.testing.assert_allclose(s, [F * 2 * r / (4.0 * 2.0), 0.0, 0.0], atol=1e-12)


def test_grains_without_contacts_carry_plus_zero_stress():
    """No contact, no moment: the stress is exactly 0, and prints as 0, not -0 (the sign
    change of compression-positive turned the zero sum into -0.0 in the tables)."""
    x, z, rr = np.array([0.0, 3.0]), np.zeros(2), np.full(2, 0.5)
    none, no_f = np.zeros(0, int), np.zeros(0)
    m = grain_moments(2, x, z, rr, none, none, no_f, no_f, none, no_f, no_f, no_f, no_f)
    region = region_stress(m, np.ones(2, bool), 4.0, 1.0)
    circle = circle_measure(x, z, rr, m, np.zeros(2), 0.0, 0.0, 1.0)["stress"]
    from silodem.measure.wall_profiles import binned_stress  # the strips' and slices'

    binned = binned_stress(m, z, np.ones(2, bool), np.array([-1.0, 0.0, 1.0]), np.ones(2), 1.0)
    for s in (region, circle, binned):
        assert np.array_equal(s, np.zeros_like(s)) and not np.signbit(s).any(), s


def _lens_closed_form(d: float, r: float, R: float) -> float:
    """Area common to circles of radii r and R whose centres are d apart (the two circular
    segments either side of the common chord; Weisstein, "Circle-Circle Intersection")."""
    if d >= r + R:
        return 0.0
    if d <= abs(R - r):
        return math.pi * min(r, R) ** 2
    a = r * r * math.acos((d * d + r * r - R * R) / (2 * d * r))
    b = R * R * math.acos((d * d + R * R - r * r) / (2 * d * R))
    c = 0.5 * math.sqrt((-d + r + R) * (d + r - R) * (d - r + R) * (d + r + R))
    return a + b - c


def test_lens_area_against_quadrature():
    """Against the closed form (to round-off) and, independently of any formula, against a
    count of the pixels of a 1500 x 1500 grid inside both circles (to the grid's error)."""
    R = 1.0
    cases = [(0.0, 0.3), (2.5, 0.3), (0.9, 0.3), (0.5, 0.8), (1.2, 1.5)]
    n = 1500
    h = 6.0 / n
    g = -3.0 + h * (np.arange(n) + 0.5)
    gx, gz = np.meshgrid(g, g)
    in_c = gx**2 + gz**2 <= R * R
    for d, r in cases:
        brute = np.sum(in_c & ((gx - d) ** 2 + gz**2 <= r * r)) * h * h
        area = lens_area(np.array([d]), np.array([r]), R)[0]
        assert area == pytest.approx(_lens_closed_form(d, r, R), rel=1e-12, abs=1e-15)
        assert area == pytest.approx(brute, abs=5e-3)
    assert lens_area(np.array([0.0]), np.array([0.3]), R)[0] == pytest.approx(math.pi * 0.09)


def test_gaussian_stress_of_the_compressed_box_integrates_to_the_wall_stress(compressed_box):
    """The Gaussian coarse-grained stress (width w = 2 grain diameters) summed over a fine grid
    (h = w/3) that holds every kernel, divided by the box's area, is the box's Love-Weber
    stress (to the kernel's cut, 4e-6) and so the boundary traction."""
    from silodem.measure.gaussian import gaussian_sums

    sim = compressed_box
    w = sim.walls
    width, height = w.ax[1], w.ay[2]
    rd = read_simulation(sim)
    kernel = 0.2
    h = kernel / 3
    edges = np.arange(-6 * kernel, max(width, height) + 6 * kernel, h)
    _, stress = gaussian_sums(rd, edges, edges, kernel)  # thickness 1 m: sigma = the sums
    mean = stress.sum(axis=(0, 1)) * h * h / (width * height)
    whole = region_stress(rd.moments, np.ones(rd.n, bool), width * height, 1.0)
    np.testing.assert_allclose(mean, whole, rtol=0, atol=1e-5 * abs(whole).max())
    reference, bound = boundary_stress(sim)
    np.testing.assert_allclose(mean, reference, rtol=0, atol=bound + 1e-5 * abs(whole).max())
