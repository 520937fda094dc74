"""Gaussian coarse-graining (``silodem.measure.gaussian``): the closed-form line integral
against scipy's quadrature, conservation of mass and of the Love-Weber total over the plane,
a lattice's density, and a run's fields recounted from its settled packing."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from measure_helpers import tiny_hopper_config
from scipy.integrate import quad

from silodem.measure.fields import fields_of
from silodem.measure.gaussian import gaussian_sums, segment_weight
from silodem.measure.reading import read_simulation
from silodem.measure.recorders import MeasureRecorder, recorders_for
from silodem.silo.procedure import SiloRun
from silodem.silo.recorders import Recorder


def phi(dx, dz, w):
    return math.exp(-0.5 * (dx * dx + dz * dz) / (w * w)) / (2 * math.pi * w * w)


def test_line_integral_equals_quadrature():
    """int_0^1 phi(g - a - s l) ds by scipy's adaptive quadrature, for random segments and
    points: short and long against w, near and far, on the line and beside it."""
    rng = np.random.default_rng(3)
    for _ in range(200):
        w = rng.uniform(0.05, 0.3)
        ax, az, gx, gz = rng.uniform(-0.5, 0.5, 4)
        lx, lz = rng.uniform(-1, 1, 2) * rng.choice([1e-3, 0.1, 1.0])
        def along(s, ax=ax, az=az, lx=lx, lz=lz, gx=gx, gz=gz, w=w):
            return phi(gx - ax - s * lx, gz - az - s * lz, w)

        expected = quad(along, 0, 1, epsabs=0, epsrel=1e-12, limit=200)[0]
        assert segment_weight(ax, az, lx, lz, gx, gz, w) == pytest.approx(
            expected, rel=1e-9, abs=1e-14 / w**2)


def _frame(rng, n=60, contacts=120, walls=20):
    """Random grains, grain-grain and wall contacts (the fields of ``measure.reading.Reading``
    that ``gaussian_sums`` reads)."""
    x, z = rng.uniform(0.4, 0.6, n), rng.uniform(0.4, 0.6, n)
    i = rng.integers(0, n, contacts)
    j = (i + rng.integers(1, n, contacts)) % n
    g = rng.integers(0, n, walls)
    return SimpleNamespace(
        x=x, z=z, mass=rng.uniform(1, 2, n), i=i, j=j, fx=rng.normal(0, 5, contacts),
        fz=rng.normal(0, 5, contacts), w_grain=g, w_cx=x[g] + rng.uniform(-0.05, 0.05, walls),
        w_cz=z[g] + rng.uniform(-0.05, 0.05, walls), w_fx=rng.normal(0, 5, walls),
        w_fz=rng.normal(0, 5, walls))


def test_fields_integrate_to_the_mass_and_the_love_weber_total():
    """Over a grid that holds every kernel (5 w beyond every grain) and samples it finely
    (h = w/3, where the midpoint sum of a Gaussian is exact to exp(-2 pi^2 w^2/h^2)), the sum of
    h^2 rho t is the total mass and that of h^2 sigma t is sum f (x) l over the contacts
    (grain-grain: f on j, l = r_j - r_i; wall: minus the force on the grain, l = contact point
    - centre), to the cut at 5 w (4e-6)."""
    rd = _frame(np.random.default_rng(11))
    w = 0.04
    h = w / 3
    edges = np.arange(0.4 - 6 * w - 0.2, 0.6 + 6 * w + 0.2 + h, h)
    mass, stress = gaussian_sums(rd, edges, edges, w)
    assert mass.sum() * h * h == pytest.approx(rd.mass.sum(), rel=1e-5)
    lx, lz = rd.x[rd.j] - rd.x[rd.i], rd.z[rd.j] - rd.z[rd.i]
    wx, wz = rd.w_cx - rd.x[rd.w_grain], rd.w_cz - rd.z[rd.w_grain]
    total = np.array([
        np.sum(rd.fx * lx) - np.sum(rd.w_fx * wx),
        np.sum(rd.fz * lz) - np.sum(rd.w_fz * wz),
        0.5 * (np.sum(rd.fx * lz + rd.fz * lx) - np.sum(rd.w_fx * wz + rd.w_fz * wx))])
    scale = np.abs(total).max()
    np.testing.assert_allclose(stress.sum(axis=(0, 1)) * h * h, total, rtol=0,
                               atol=1e-5 * scale)


def test_density_of_a_triangular_lattice_is_its_packing_fraction():
    """Equal disks on a triangular lattice (spacing 2r) fill pi / (2 sqrt 3) of the plane; a
    Gaussian of width w = 2r averages the lattice to that density within exp(-16 pi^2 / 3)
    (the first term of its Fourier series) at points 5 w inside its edge, less what the cut
    of the kernel at 5 w drops (measured 2e-6; bound exp(-25/2) = 4e-6 of each term)."""
    r, rho, t = 0.05, 2500.0, 1.0
    rows, cols = 40, 40
    x = np.array([2 * r * c + (r if k % 2 else 0.0) for k in range(rows) for c in range(cols)])
    z = np.array([math.sqrt(3) * r * k for k in range(rows) for c in range(cols)])
    rd = SimpleNamespace(x=x, z=z, mass=np.full(x.size, rho * math.pi * r * r * t),
                         i=np.zeros(0, int), w_grain=np.zeros(0, int))
    w = 2 * r
    xe, ze = np.linspace(0, x.max(), 31), np.linspace(0, z.max(), 31)
    mass, stress = gaussian_sums(rd, xe, ze, w)
    density, _ = fields_of(mass, -stress, np.ones(mass.shape), t, 1)
    xc, zc = 0.5 * (xe[1:] + xe[:-1]), 0.5 * (ze[1:] + ze[:-1])
    inner = np.ix_((xc > 5 * w) & (xc < x.max() - 5 * w), (zc > 5 * w) & (zc < z.max() - 5 * w))
    assert density[inner].size > 50
    np.testing.assert_allclose(density[inner], math.pi / (2 * math.sqrt(3)) * rho, rtol=4e-6)


class _SettledFrame(Recorder):
    """Keeps a frame of the packing when settling ends, as the fields recorder takes it."""

    name = "settled frame"

    def __init__(self) -> None:
        super().__init__(1e9)
        self.frame = None

    def record(self, run) -> None:
        pass

    def phase_ended(self, run, phase: str) -> None:
        if phase == "settle":
            self.frame = read_simulation(run.sim)


def test_a_gaussian_run_records_the_fields_of_its_settled_packing():
    """With measure.field_kernel = 'gaussian' the recorder's settled field is the Gaussian
    coarse-graining of the packing at the end of settling: the same ``gaussian_sums`` called
    here on a frame of that state gives the same bits (this checks the recorder's wiring: the
    frame, the moment, the width; the sums themselves are checked against analytic fields in
    the tests above); centres outside the silo are NaN, those inside finite."""
    cfg = tiny_hopper_config()
    cfg = cfg.model_copy(update={"measure": cfg.measure.model_copy(
        update={"field_kernel": "gaussian", "field_width": 0.15})})
    grab = _SettledFrame()
    run = SiloRun(cfg, recorders=[*recorders_for(cfg), grab])
    run.run()
    f = next(r for r in run.recorders if isinstance(r, MeasureRecorder)).fields
    assert f.kernel == "gaussian" and f.width == 0.15 and f.samples["settled"] == 1
    mass, stress = gaussian_sums(grab.frame, f.x_edges, f.z_edges, 0.15)
    np.testing.assert_array_equal(f.mass["settled"], mass)
    np.testing.assert_array_equal(f.moments["settled"], -stress)
    density, sigma = fields_of(f.mass["settled"], f.moments["settled"], f.normaliser,
                               f.thickness, 1)
    inside = f.normaliser > 0
    assert np.all(np.isnan(density[~inside])) and np.all(np.isfinite(density[inside]))
    assert np.nanmax(sigma[..., 1]) > 0 and f.samples["discharge"] > 5


def test_a_gaussian_width_without_the_gaussian_kernel_is_refused(capsys):
    from silodem.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["show", "paper-case2", "--set", "measure.field_width=0.3"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.count("\n") == 1
    assert "measure.field_width" in err and "gaussian" in err
