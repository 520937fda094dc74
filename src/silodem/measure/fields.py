"""Coarse-grained continuum fields on a grid: bulk density and Love-Weber stress per cell.

Box coarse-graining (for the method and its resolution, Weinhart, Thornton, Luding & Bokhove,
Granular Matter 14 (2012) 289).  For a cell c of the grid, with A_c its area inside the silo
[m^2], t the thickness [m] and a_pc the area [m^2] of grain p's disk inside the cell's
rectangle (``disk_rectangle_area``, exact):

    rho_c      = sum over grains p of m_p a_pc / (pi r_p^2) / (A_c t)            [kg/m^3]
    sigma_c,ab = -1/(A_c t) sum over the grains centred in c of M_p,ab (symm.)  [Pa]

The density shares each grain's mass among the cells in proportion to the part of its disk in
each, so a cell holds no more solid than the disks cover (its solid fraction rho_c / rho_grain
passes the 0.907 of disks in a triangular packing only where the grains overlap each other);
counted by centres, whole grains 0.2 m across made cells 0.8 m wide read 0.97.  The stress is
the Love-Weber average of ``stress`` applied to each cell, each grain's moment M_p (of
``stress.grain_moments``, negative under compression, hence the sign) in the cell of its
centre (Christoffersen,
Mehrabadi & Nemat-Nasser 1981).  Only the grains centred in the grid count, and the part of
such a grain beyond the grid's outer edges (pressed into a wall, or hanging through the outlet)
counts in the cell at that edge, as the part beyond a hopper wall counts in the cell the wall
cuts: summed over the cells, area-weighted, both fields give the region averages of the grains
centred in the silo exactly.  A cell a few grains wide resolves the stress with an error of the
order of a grain diameter over the cell size at its edges (grains straddling them); the default
cell is four mean diameters (``regions.field_cell``).

Two fields per run: the settled packing (one sample at the end of settling: it is at rest) and
the mean over the discharge window (every sample in it, as the velocity grid).

``measure.field_kernel = "gaussian"`` replaces the box by a Gaussian of width
``measure.field_width`` (``measure.gaussian``): smooth fields at the cell centres, NaN at
centres outside the silo.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from silodem.measure import regions
from silodem.measure.gaussian import gaussian_sums
from silodem.measure.reading import Reading

if TYPE_CHECKING:
    import h5py

    from silodem.config import Config
    from silodem.silo.geometry import SiloShape

QUADRATURE = 16  # midpoints per cell side for the cell's area inside the silo


def cell_area_inside(shape: SiloShape, x_edges: np.ndarray, z_edges: np.ndarray) -> np.ndarray:
    """Area of each cell inside the silo [m^2], shape (nx, nz): midpoint quadrature on
    QUADRATURE x QUADRATURE points per cell (exact for cells wholly inside or outside)."""
    u = (np.arange(QUADRATURE) + 0.5) / QUADRATURE
    zs = (z_edges[:-1, None] + np.diff(z_edges)[:, None] * u).ravel()
    nz = z_edges.size - 1
    frac = np.empty((x_edges.size - 1, nz))
    for k in range(x_edges.size - 1):  # one column of cells at a time: little memory
        gx, gz = np.meshgrid(x_edges[k] + (x_edges[k + 1] - x_edges[k]) * u, zs, indexing="ij")
        inside = regions.inside_silo(shape, gx, gz)
        frac[k] = inside.reshape(QUADRATURE, nz, QUADRATURE).mean(axis=(0, 2))
    return frac * np.outer(np.diff(x_edges), np.diff(z_edges))


def _below_left_area(a: np.ndarray, b: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Area [m^2] of the disk of radius ``r`` centred at the origin where x <= a and z <= b
    (a, b [m], any values; arrays broadcast): the integral over x in [-r, a] of the length of
    the vertical chord under z = b, with I(x) = int_0^x sqrt(r^2 - s^2) ds
    = (x sqrt(r^2 - x^2) + r^2 asin(x / r)) / 2 in closed form."""
    a = np.clip(a, -r, r)
    b = np.clip(b, -r, r)

    def integral(x):  # I(x) for |x| <= r
        return 0.5 * (x * np.sqrt(np.maximum(r * r - x * x, 0.0))
                      + r * r * np.arcsin(np.clip(x / r, -1.0, 1.0)))

    c = np.sqrt(np.maximum(r * r - b * b, 0.0))  # the line z = b cuts the circle at x = +-c
    hi = np.clip(a, -c, c)
    # |x| < c: the chord under z = b runs from -sqrt(r^2 - x^2) up to b
    inner = b * (hi + c) + integral(hi) - integral(-c)
    # |x| > c: the whole chord (b >= 0) or none of it (b < 0)
    outer = 2.0 * (integral(np.minimum(a, -c)) - integral(-r)
                   + integral(np.maximum(a, c)) - integral(c))
    return inner + np.where(b >= 0.0, outer, 0.0)


def disk_rectangle_area(x: npt.ArrayLike, z: npt.ArrayLike, r: npt.ArrayLike,
                        x0: npt.ArrayLike, x1: npt.ArrayLike, z0: npt.ArrayLike,
                        z1: npt.ArrayLike) -> np.ndarray:
    """Area [m^2] of the disk centred at (x, z) of radius r [m] inside the rectangle
    [x0, x1] x [z0, z1] [m] (edges may be +-inf), exact: a sum of the four corners'
    ``_below_left_area`` (inclusion-exclusion); arrays broadcast."""
    x, z, r = (np.asarray(v, dtype=float) for v in (x, z, r))
    x0, x1, z0, z1 = (np.asarray(v, dtype=float) - c for v, c in ((x0, x), (x1, x), (z0, z),
                                                                   (z1, z)))
    area = (_below_left_area(x1, z1, r) - _below_left_area(x0, z1, r)
            - _below_left_area(x1, z0, r) + _below_left_area(x0, z0, r))
    return np.maximum(area, 0.0)  # (rounding of a sliver)


def band_solid_area(z: npt.ArrayLike, r: npt.ArrayLike, lo: float, hi: float) -> float:
    """Solid area [m^2] of the disks centred at heights ``z`` with radii ``r`` [m] inside the
    horizontal band lo <= z < hi [m] (unbounded sideways), each by the exact area of its disk
    in the band (``disk_rectangle_area``), not whole by its centre.  A bulk density is the
    grain density times this over the band's area."""
    z = np.asarray(z, dtype=float)
    return float(disk_rectangle_area(0.0, z, r, -np.inf, np.inf, lo, hi).sum())


def solid_area_shares(x: npt.ArrayLike, z: npt.ArrayLike, r: npt.ArrayLike,
                      x_edges: np.ndarray,
                      z_edges: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The grains centred in the grid (x_edges, z_edges [m], increasing) shared among its
    cells: (grain index, flat cell index ix * nz + iz, area [m^2] of the grain's disk in that
    cell), one row per grain and cell it reaches.  The grid's outer edges are taken as
    unbounded (the part of a grain beyond them counts in the cell at that edge), so each
    grain's areas add up to pi r^2."""
    return _shares(x, z, r, x_edges, z_edges)[:3]


def _shares(x, z, r, x_edges, z_edges):
    """``solid_area_shares``, and the flat index of the cell of each grain's centre and the
    mask of the grains centred in the grid (``regions.grid_cell_index``)."""
    x, z, r = (np.asarray(v, dtype=float) for v in (x, z, r))
    nx, nz = x_edges.size - 1, z_edges.size - 1
    ixc = np.searchsorted(x_edges, x, side="right") - 1  # as regions.grid_cell_index
    izc = np.searchsorted(z_edges, z, side="right") - 1
    ok = (ixc >= 0) & (ixc < nx) & (izc >= 0) & (izc < nz)
    grain = np.flatnonzero(ok)
    x, z, r, ixc, izc = x[grain], z[grain], r[grain], ixc[grain], izc[grain]
    centre = ixc * nz + izc
    xe = np.concatenate([[-np.inf], x_edges[1:-1], [np.inf]])  # the outer edges unbounded
    ze = np.concatenate([[-np.inf], z_edges[1:-1], [np.inf]])
    # a disk within the cell of its centre (most, in cells several grains wide) is whole there
    whole = ((x - r >= xe[ixc]) & (x + r <= xe[ixc + 1]) & (z - r >= ze[izc])
             & (z + r <= ze[izc + 1]))
    rows = [(grain[whole], centre[whole], np.pi * r[whole] ** 2)]
    cut = np.flatnonzero(~whole)
    xc, zc, rc = x[cut], z[cut], r[cut]
    # the range of cells the others' bounding boxes reach (clipped to the grid)
    ix0 = np.clip(np.searchsorted(x_edges, xc - rc, side="right") - 1, 0, nx - 1)
    ix1 = np.clip(np.searchsorted(x_edges, xc + rc, side="left") - 1, 0, nx - 1)
    iz0 = np.clip(np.searchsorted(z_edges, zc - rc, side="right") - 1, 0, nz - 1)
    iz1 = np.clip(np.searchsorted(z_edges, zc + rc, side="left") - 1, 0, nz - 1)
    span_x = int((ix1 - ix0).max()) + 1 if cut.size else 0
    span_z = int((iz1 - iz0).max()) + 1 if cut.size else 0
    for dx in range(span_x):
        for dz in range(span_z):
            k = np.flatnonzero((ix0 + dx <= ix1) & (iz0 + dz <= iz1))
            ix, iz = ix0[k] + dx, iz0[k] + dz
            area = disk_rectangle_area(xc[k], zc[k], rc[k], xe[ix], xe[ix + 1], ze[iz],
                                       ze[iz + 1])
            rows.append((grain[cut[k]], ix * nz + iz, area))
    g, c, a = (np.concatenate(col) for col in zip(*rows))
    return g, c, a, centre, ok


def cell_sums(x: np.ndarray, z: np.ndarray, r: np.ndarray, mass: np.ndarray,
              moments: np.ndarray, x_edges: np.ndarray,
              z_edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sums over the grains of each cell: mass [kg], shape (nx, nz), each grain's mass shared
    among the cells by the area of its disk (radius ``r`` [m]) in each
    (``solid_area_shares``), and the moments' (xx, zz, xz) components [N m] of the grains
    centred in the cell, shape (nx, nz, 3), xz symmetrised.  Grains centred outside the grid
    are left out."""
    nx, nz = x_edges.size - 1, z_edges.size - 1
    grain, cell, area, centre, ok = _shares(x, z, r, x_edges, z_edges)
    r = np.asarray(r, dtype=float)
    share = area / (np.pi * r[grain] ** 2)
    mass_sum = np.bincount(cell, weights=np.asarray(mass, dtype=float)[grain] * share,
                           minlength=nx * nz).reshape(nx, nz)
    m = moments[ok]
    parts = (m[:, 0, 0], m[:, 1, 1], 0.5 * (m[:, 0, 1] + m[:, 1, 0]))
    moment_sum = np.stack([np.bincount(centre, weights=w, minlength=nx * nz) for w in parts],
                          axis=-1).reshape(nx, nz, 3)
    return mass_sum, moment_sum


def fields_of(mass_sum: np.ndarray, moment_sum: np.ndarray, area_inside: np.ndarray,
              thickness: float, samples: int) -> tuple[np.ndarray, np.ndarray]:
    """(bulk density [kg/m^3], stress (xx, zz, xz) [Pa], compression positive) per cell from
    sums over ``samples`` samples; NaN in cells without area inside the silo or samples.
    (Gaussian sums are already per unit area: ``area_inside`` is then 1 inside, 0 outside.)"""
    volume = area_inside * thickness * samples
    with np.errstate(invalid="ignore", divide="ignore"):
        ok = volume > 0
        density = np.where(ok, mass_sum / np.where(ok, volume, 1.0), np.nan)
        stress = np.where(ok[..., None],  # (0.0 - x: an empty cell's 0 is +0.0, not -0.0)
                          0.0 - moment_sum / np.where(ok, volume, 1.0)[..., None], np.nan)
    return density, stress


class FieldsPart:
    """The recorder part that gathers the settled and the discharge-window fields."""

    WINDOWS = ("settled", "discharge")

    def __init__(self, cfg: Config, shape: SiloShape) -> None:
        cell = regions.field_cell(cfg)
        self.x_edges, self.z_edges = regions.grid_edges(shape, cell)
        self.area_inside = cell_area_inside(shape, self.x_edges, self.z_edges)
        self.thickness = cfg.material.thickness
        self.kernel = cfg.measure.field_kernel
        self.width = regions.field_width(cfg, shape)
        # what each cell's sums are divided by: its area inside the silo [m^2] (box), or,
        # the Gaussian's being point values, 1 where the cell's centre is inside, else 0
        if self.kernel == "gaussian":
            xc, zc = np.meshgrid(0.5 * (self.x_edges[1:] + self.x_edges[:-1]),
                                 0.5 * (self.z_edges[1:] + self.z_edges[:-1]), indexing="ij")
            self.normaliser = regions.inside_silo(shape, xc, zc).astype(float)
        else:  # sums over each cell, divided by its area inside the silo
            self.normaliser = self.area_inside
        size = (self.x_edges.size - 1, self.z_edges.size - 1)
        self.mass = {w: np.zeros(size) for w in self.WINDOWS}
        self.moments = {w: np.zeros((*size, 3)) for w in self.WINDOWS}
        self.samples = dict.fromkeys(self.WINDOWS, 0)

    def add(self, window: str, rd: Reading) -> None:
        """Add one sample (a reading) to ``window``."""
        if self.kernel == "gaussian":
            mass, stress = gaussian_sums(rd, self.x_edges, self.z_edges, self.width)
            moments = -stress  # as the box's sums: stress = -moments / volume
        else:
            mass, moments = cell_sums(rd.x, rd.z, rd.r, rd.mass, rd.moments, self.x_edges,
                                      self.z_edges)
        self.mass[window] += mass
        self.moments[window] += moments
        self.samples[window] += 1

    def state(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for w in self.WINDOWS:
            out[f"fields.{w}.mass"] = self.mass[w]
            out[f"fields.{w}.moments"] = self.moments[w]
            out[f"fields.{w}.samples"] = self.samples[w]
        return out

    def restore(self, state: dict[str, Any]) -> None:
        for w in self.WINDOWS:
            if f"fields.{w}.mass" in state:  # checkpoints written before the fields existed
                self.mass[w] = np.array(state[f"fields.{w}.mass"])
                self.moments[w] = np.array(state[f"fields.{w}.moments"])
                self.samples[w] = int(state[f"fields.{w}.samples"])

    def write(self, g: h5py.Group, dataset: Callable[..., None]) -> None:
        """Group ``fields``: the grid, each cell's area inside the silo, and per window the
        bulk density and stress (``dataset`` writes one array with its unit)."""
        f = g.create_group("fields")
        dataset(f, "x_edges", self.x_edges, "m")
        dataset(f, "z_edges", self.z_edges, "m")
        dataset(f, "area_inside", self.area_inside, "m^2")
        f.attrs["kernel"] = self.kernel
        if self.kernel == "gaussian":
            f.attrs["width"] = self.width
            gauss = "at the cell centre, Gaussian coarse-graining of width attrs['width']"
            meaning = {"density": gauss, "stress": gauss}
        else:
            meaning = {"density": "the grains' mass in the cell (each grain's shared by the "
                                  "area of its disk in the cell) / the cell's volume",
                       "stress": "grains centred in the cell / its volume"}
        for w in self.WINDOWS:
            h = f.create_group(w)
            h.attrs["samples"] = self.samples[w]
            density, stress = fields_of(self.mass[w], self.moments[w], self.normaliser,
                                        self.thickness, self.samples[w])
            dataset(h, "density", density, "kg/m^3",
                    meaning=f"bulk density: {meaning['density']}")
            dataset(h, "stress", stress, "Pa", components="xx,zz,xz; compression positive "
                    f"(Love-Weber, {meaning['stress']})")
