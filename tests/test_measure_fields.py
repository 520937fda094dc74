"""Coarse-grained fields (``silodem.measure.fields``): the cells' areas inside the silo, bulk
density and Love-Weber stress per cell, against closed forms, exact sums and the recorder's
own run."""

from __future__ import annotations

import math

import numpy as np
import pytest
from measure_helpers import tiny_hopper_config

from silodem.measure.fields import (
    QUADRATURE,
    cell_area_inside,
    cell_sums,
    disk_rectangle_area,
    fields_of,
    solid_area_shares,
)
from silodem.measure.recorders import MeasureRecorder, recorders_for
from silodem.silo.geometry import silo_shape
from silodem.silo.procedure import SiloRun


def test_cell_areas_inside_a_flat_silo_and_a_hopper():
    """Flat silo: every cell wholly inside, its area exactly. Hopper: the cells' areas add up
    to the silo's area (trapezoid (b + B)/2 z_j + rectangle B (H - z_j), by hand) within the
    midpoint rule's error, at most one row of QUADRATURE^2 sub-cells per cell the walls cut."""
    flat = silo_shape(tiny_hopper_config().model_copy(update={
        "silo": tiny_hopper_config().silo.model_copy(update={"kind": "flat"})}))
    xe, ze = np.linspace(0, flat.width, 4), np.linspace(0, flat.wall_top, 7)
    np.testing.assert_allclose(cell_area_inside(flat, xe, ze),
                               np.outer(np.diff(xe), np.diff(ze)), rtol=1e-12)
    cfg = tiny_hopper_config()
    s = cfg.silo
    shape = silo_shape(cfg)
    zj = 0.5 * (s.cell_width - s.outlet_width) * math.tan(
        math.radians(s.hopper_angle_from_horizontal_deg))
    exact = 0.5 * (s.outlet_width + s.cell_width) * zj + s.cell_width * (s.wall_height - zj)
    xe, ze = np.linspace(0, s.cell_width, 7), np.linspace(0, s.wall_height, 13)
    area = cell_area_inside(shape, xe, ze)
    cell = np.outer(np.diff(xe), np.diff(ze))
    cut = (area > 0) & (area < cell * (1 - 1e-12))
    assert cut.sum() >= 4
    bound = (cell[cut] / QUADRATURE).sum()  # one row of sub-cells per cut cell
    assert abs(area.sum() - exact) < bound
    assert np.all((area[~cut] == 0) | (area[~cut] == cell[~cut]))  # wholly out or in


def test_density_of_a_triangular_lattice_is_its_packing_fraction():
    """Equal disks of radius r on a triangular lattice (rows 2r apart along x, sqrt(3) r apart
    in z) fill pi / (2 sqrt 3) of the plane; a cell of 2 x 2 periods (4r x 4 sqrt(3) r), the
    disks shared among the cells by area, holds exactly that share of solid, wherever the cell
    lies.  The cells at the grid's edge hold more or less (grains centred outside the grid
    are left out, the outer parts of those inside are kept), the grid as a whole exactly the
    mass of the grains centred in it."""
    r, rho, t = 0.05, 2500.0, 1.0
    rows, cols = 24, 24
    x = np.array([2 * r * c + (r if k % 2 else 0.0) for k in range(rows) for c in range(cols)])
    z = np.array([math.sqrt(3) * r * k for k in range(rows) for c in range(cols)])
    mass = np.full(x.size, rho * math.pi * r * r * t)
    xe = np.arange(0, 2 * r * cols, 4 * r) - 0.5 * r
    ze = np.arange(0, math.sqrt(3) * r * rows, 4 * math.sqrt(3) * r) - 0.5 * r
    msum, mom = cell_sums(x, z, np.full(x.size, r), mass, np.zeros((x.size, 2, 2)), xe, ze)
    area = np.outer(np.diff(xe), np.diff(ze))
    density, stress = fields_of(msum, mom, area, t, 1)
    inner = density[1:-1, 1:-1]
    assert inner.size >= 9
    np.testing.assert_allclose(inner, math.pi / (2 * math.sqrt(3)) * rho, rtol=1e-12)
    assert np.all(stress == 0)
    centred = (x >= xe[0]) & (x < xe[-1]) & (z >= ze[0]) & (z < ze[-1])
    assert (density * area * t).sum() == pytest.approx(mass[centred].sum(), rel=1e-12)
    # two samples of the same state: the same mean
    density2, _ = fields_of(2 * msum, 2 * mom, area, t, 2)
    np.testing.assert_allclose(density2, density, rtol=1e-15)


def test_disk_in_a_rectangle_has_its_exact_area():
    """Worked by hand: a disk of radius r wholly inside a rectangle covers pi r^2 of it;
    centred on an edge, half; on a corner, a quarter; one corner of the rectangle at the
    centre and the opposite corner at (a, b) inside the disk: the quarter-disk part
    a b (for a, b small against r, a^2 + b^2 <= r^2: the rectangle is wholly inside);
    the band |x - x_c| <= h: the disk less two circular segments,
    2 (h sqrt(r^2 - h^2) + r^2 asin(h / r))."""
    r = 0.3
    assert disk_rectangle_area(1.0, 2.0, r, 0.0, 5.0, 0.0, 5.0) == pytest.approx(
        math.pi * r * r, rel=1e-14)
    for x0, x1, z0, z1 in ((1.0, 5.0, 0.0, 5.0), (-5.0, 1.0, 0.0, 5.0),
                           (0.0, 5.0, 2.0, 5.0), (0.0, 5.0, 0.0, 2.0)):  # the four edges
        assert disk_rectangle_area(1.0, 2.0, r, x0, x1, z0, z1) == pytest.approx(
            0.5 * math.pi * r * r, rel=1e-14)
    for x0, x1, z0, z1 in ((1.0, 5.0, 2.0, 5.0), (-5.0, 1.0, 2.0, 5.0),
                           (1.0, 5.0, -5.0, 2.0), (-5.0, 1.0, -5.0, 2.0)):  # the four corners
        assert disk_rectangle_area(1.0, 2.0, r, x0, x1, z0, z1) == pytest.approx(
            0.25 * math.pi * r * r, rel=1e-14)
    assert disk_rectangle_area(1.0, 2.0, r, 1.0, 1.1, 2.0, 2.2) == pytest.approx(
        0.1 * 0.2, rel=1e-12)
    h = 0.1
    band = 2 * (h * math.sqrt(r * r - h * h) + r * r * math.asin(h / r))
    assert disk_rectangle_area(1.0, 2.0, r, 1.0 - h, 1.0 + h, -np.inf, np.inf) == \
        pytest.approx(band, rel=1e-14)
    assert disk_rectangle_area(1.0, 2.0, r, 1.4, 2.0, 0.0, 5.0) == 0.0  # apart


def test_disk_rectangle_area_against_a_fine_quadrature():
    """Random disks and rectangles cutting them anyhow: the area equals the midpoint rule on a
    2000 x 2000 grid over the disk's bounding square (error under ~ 4 r^2 / 2000 of the
    boundary's cells, well within 1e-3 pi r^2)."""
    rng = np.random.default_rng(3)
    n = 2000
    for _ in range(20):
        x, z, r = rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(0.05, 0.5)
        x0, z0 = x + rng.uniform(-1.2, 0.8) * r, z + rng.uniform(-1.2, 0.8) * r
        x1, z1 = x0 + rng.uniform(0.1, 2.0) * r, z0 + rng.uniform(0.1, 2.0) * r
        u = -r + 2 * r * (np.arange(n) + 0.5) / n
        gx, gz = np.meshgrid(x + u, z + u, indexing="ij")
        inside = ((gx - x) ** 2 + (gz - z) ** 2 <= r * r) & (gx >= x0) & (gx <= x1) \
            & (gz >= z0) & (gz <= z1)
        quad = inside.sum() * (2 * r / n) ** 2
        assert disk_rectangle_area(x, z, r, x0, x1, z0, z1) == pytest.approx(
            quad, abs=1e-3 * math.pi * r * r)


def test_solid_area_shares_add_up_to_each_grain():
    """Conservation: over an uneven grid, each grain centred in it has shares adding up to
    pi r^2 (the outer edges unbounded: a grain hanging over them counts there whole), so
    the cells' solid areas add up to the grains' total area; grains centred outside are left
    out.  Cells smaller than a grain: a grain reaches up to ceil(2r / cell) + 1 of them in
    each direction."""
    rng = np.random.default_rng(5)
    xe = np.array([0.0, 0.3, 0.35, 0.9, 1.0, 1.6])
    ze = np.array([0.0, 0.05, 0.5, 0.55, 1.2])
    x, z = rng.uniform(-0.1, 1.7, 400), rng.uniform(-0.1, 1.3, 400)
    r = rng.uniform(0.02, 0.2, 400)
    grain, cell, area = solid_area_shares(x, z, r, xe, ze)
    centred = (x >= 0) & (x < 1.6) & (z >= 0) & (z < 1.2)
    assert set(grain) == set(np.flatnonzero(centred))
    per_grain = np.bincount(grain, weights=area, minlength=x.size)
    np.testing.assert_allclose(per_grain[centred], np.pi * r[centred] ** 2, rtol=1e-12)
    assert np.all(area >= 0) and cell.max() < (xe.size - 1) * (ze.size - 1)
    # a disk centred on an inner corner (x = 0.9, z = 0.5) puts a quarter in each of 4 cells
    g, c, a = solid_area_shares([0.9], [0.5], [0.04], xe, ze)
    assert np.all(g == 0)
    nz = ze.size - 1
    assert sorted(c) == sorted([2 * nz + 1, 2 * nz + 2, 3 * nz + 1, 3 * nz + 2])
    np.testing.assert_allclose(a, 0.25 * math.pi * 0.04**2, rtol=1e-12)


def test_no_cell_holds_more_solid_than_the_disks_cover():
    """Equal disks touching on a triangular lattice, cells of one diameter: counted by their
    centres a cell held up to two grains, 2 pi r^2 / (2r)^2 = 1.57 of its area; shared by
    area, no cell holds more than its area (the disks do not overlap)."""
    r = 0.1
    rows, cols = 40, 20
    x = np.array([2 * r * c + (r if k % 2 else 0.0) for k in range(rows) for c in range(cols)])
    z = np.array([math.sqrt(3) * r * k for k in range(rows) for c in range(cols)])
    rho, t = 835.0, 1.0
    mass = np.full(x.size, rho * math.pi * r * r * t)
    xe, ze = np.arange(0.0, 2 * r * cols, 2 * r), np.arange(0.0, math.sqrt(3) * r * rows, 2 * r)
    msum, mom = cell_sums(x, z, np.full(x.size, r), mass, np.zeros((x.size, 2, 2)), xe, ze)
    density, _ = fields_of(msum, mom, np.outer(np.diff(xe), np.diff(ze)), t, 1)
    solid = density[1:-1, 1:-1] / rho
    assert solid.max() <= 1.0 + 1e-12
    assert solid.max() > math.pi / (2 * math.sqrt(3))  # (cells this small do vary)
    counted = np.histogram2d(x, z, bins=(xe, ze))[0][1:-1, 1:-1] * math.pi * r * r / (2 * r) ** 2
    assert counted.max() > 1.5  # what counting by centres made of the same cells


def test_cells_outside_the_silo_or_without_samples_are_nan():
    msum, mom = np.ones((2, 2)), np.ones((2, 2, 3))
    area = np.array([[1.0, 0.0], [1.0, 1.0]])
    density, stress = fields_of(msum, mom, area, 1.0, 1)
    assert np.isnan(density[0, 1]) and np.all(np.isnan(stress[0, 1]))
    assert density[0, 0] == 1.0 and np.all(stress[0, 0] == -1.0)  # compression positive
    assert np.all(np.isnan(fields_of(msum, mom, area, 1.0, 0)[0]))
    # a cell inside with no contact: 0 Pa, printed as 0, not -0 (the sign change's -0.0)
    stress = fields_of(msum, np.zeros((2, 2, 3)), area, 1.0, 1)[1]
    assert np.array_equal(stress[1], np.zeros((2, 3))) and not np.signbit(stress[1]).any()


@pytest.fixture(scope="module")
def recorded():
    cfg = tiny_hopper_config()
    run = SiloRun(cfg, recorders=recorders_for(cfg))
    run.run()
    return cfg, run, next(r for r in run.recorders if isinstance(r, MeasureRecorder))


def test_settled_field_holds_every_grain_of_the_settled_packing(recorded):
    """Mass conservation: the settled field's density times each cell's volume adds up to the
    mass of the grains in the silo when the gate opened (the flow record's radii, rho pi r^2 t
    each)."""
    cfg, _, rec = recorded
    f = rec.fields
    density, _ = fields_of(f.mass["settled"], f.moments["settled"], f.area_inside,
                           f.thickness, f.samples["settled"])
    t = cfg.material.thickness
    held = np.nansum(density * f.area_inside * t)
    grains = np.sum(cfg.material.density * np.pi * rec.flow.r0**2 * t)
    assert f.samples["settled"] == 1 and rec.flow.r0.size > 100
    assert held == pytest.approx(grains, rel=1e-12)


def test_discharge_field_averages_the_samples_of_the_discharge_window(recorded):
    """The discharge field has one sample per recorder row of the discharge window, counted
    here from the rows: delay <= t - t_open <= delay + window."""
    cfg, _, rec = recorded
    rows = np.array(rec.rows)
    t = rows[:, 0] - rec.flow.t_open
    m = cfg.measure
    in_window = (rows[:, 2] == 2) & (t >= m.discharge_delay) & (
        t <= m.discharge_delay + m.window)
    assert rec.fields.samples["discharge"] == in_window.sum() > 5


def test_fields_are_written_for_paraview_and_read_back(tmp_path):
    """With VTK output on, a run writes vtk/fields_settled.vtu and fields_discharge.vtu; read
    back with meshio, each quad spans its cell of results.h5's grid and carries that cell's
    density and stress (the same numbers, cell (i, k) at i * nz + k); 'silodem plot' writes
    the same files again."""
    import h5py
    import meshio

    from silodem.cli import main
    from silodem.config import Output
    from silodem.run import run_simulation

    cfg = tiny_hopper_config(report=False)
    cfg = cfg.model_copy(update={"output": Output(png=False, vtk_interval=1.0)})
    out = tmp_path / "run"
    run_simulation(cfg, out, progress=False)
    with h5py.File(out / "results.h5") as h5:
        f = h5["measure/fields"]
        xe, ze = f["x_edges"][()], f["z_edges"][()]
        nx, nz = xe.size - 1, ze.size - 1
        for window in ("settled", "discharge"):
            mesh = meshio.read(out / "vtk" / f"fields_{window}.vtu")
            quads = mesh.cells_dict["quad"]
            assert quads.shape == (nx * nz, 4)
            corners = mesh.points[quads]  # (cells, 4, 3)
            i, k = np.divmod(np.arange(nx * nz), nz)
            np.testing.assert_array_equal(corners[:, :, 0].min(axis=1), xe[i])
            np.testing.assert_array_equal(corners[:, :, 0].max(axis=1), xe[i + 1])
            np.testing.assert_array_equal(corners[:, :, 1].min(axis=1), ze[k])
            np.testing.assert_array_equal(corners[:, :, 1].max(axis=1), ze[k + 1])
            g = f[window]
            np.testing.assert_array_equal(mesh.cell_data["density"][0], g["density"][()].ravel())
            for c, name in enumerate(("stress_xx", "stress_zz", "stress_xz")):
                np.testing.assert_array_equal(mesh.cell_data[name][0],
                                              g["stress"][()][..., c].ravel())
    # 'silodem plot' writes them again, the same bytes
    written = {p.name: p.read_bytes() for p in (out / "vtk").glob("fields_*.vtu")}
    for name in written:
        (out / "vtk" / name).unlink()
    with pytest.raises(SystemExit) as exc:
        main(["plot", str(out)])
    assert exc.value.code == 0
    assert {p.name: p.read_bytes() for p in (out / "vtk").glob("fields_*.vtu")} == written


def test_band_solid_area_counts_each_disk_by_its_part_in_the_band():
    """Unit disks against the band 0.5 <= z < 10: one centred at z = 0 has in it the circular
    segment beyond a line 0.5 from its centre, acos(0.5) - 0.5 sqrt(0.75) = pi/3 - sqrt(3)/4;
    one at z = 5 is whole (pi); one at z = 9.5 is cut by the line z = 10, 0.5 above its
    centre: pi less the same segment; one at z = -2 has nothing in it."""
    from silodem.measure.fields import band_solid_area

    seg = math.pi / 3 - math.sqrt(3) / 4
    got = band_solid_area([0.0, 5.0, 9.5, -2.0], [1.0, 1.0, 1.0, 1.0], 0.5, 10.0)
    assert got == pytest.approx(seg + math.pi + (math.pi - seg), rel=1e-12)
    # a grain of radius 0.1 centred on the band's foot: half of it
    assert band_solid_area([0.5], [0.1], 0.5, 10.0) == pytest.approx(0.005 * math.pi, rel=1e-12)
