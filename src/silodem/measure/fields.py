"""Coarse-grained continuum fields on a grid: bulk density and Love-Weber stress per cell.

Box coarse-graining with the grains counted by their centres (the Love-Weber average of
``stress`` applied to each cell; Christoffersen, Mehrabadi & Nemat-Nasser 1981; for the method
and its resolution, Weinhart, Thornton, Luding & Bokhove, Granular Matter 14 (2012) 289): for a
cell c of the grid, with A_c its area inside the silo [m^2] and t the thickness [m],

    rho_c      = sum over grains p centred in c of m_p / (A_c t)                [kg/m^3]
    sigma_c,ab = -1/(A_c t) sum over those grains of M_p,ab (symmetrised)       [Pa]

with M_p the grain moment of ``stress.grain_moments`` (compression positive).  Summed over
the cells, area-weighted, they give the region averages of the whole silo exactly (each grain
is in one cell).  A cell a few grains wide resolves the field with an error of the order of a
grain diameter over the cell size at its edges (grains straddling them); the default cell is
four mean diameters (``regions.field_cell``).

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


def cell_sums(x: np.ndarray, z: np.ndarray, mass: np.ndarray, moments: np.ndarray,
              x_edges: np.ndarray, z_edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sums over the grains centred in each cell: mass [kg], shape (nx, nz), and the moments'
    (xx, zz, xz) components [N m], shape (nx, nz, 3), xz symmetrised.  Grains outside the grid
    are left out."""
    nx, nz = x_edges.size - 1, z_edges.size - 1
    flat, ok = regions.grid_cell_index(x, z, x_edges, z_edges)
    m = moments[ok]
    parts = (m[:, 0, 0], m[:, 1, 1], 0.5 * (m[:, 0, 1] + m[:, 1, 0]))
    mass_sum = np.bincount(flat, weights=mass[ok], minlength=nx * nz).reshape(nx, nz)
    moment_sum = np.stack([np.bincount(flat, weights=w, minlength=nx * nz) for w in parts],
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
        stress = np.where(ok[..., None], -moment_sum / np.where(ok, volume, 1.0)[..., None],
                          np.nan)
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
        self.width = regions.field_width(cfg)
        if self.kernel == "gaussian":  # point values: 1 where the centre is inside, else 0
            xc, zc = np.meshgrid(0.5 * (self.x_edges[1:] + self.x_edges[:-1]),
                                 0.5 * (self.z_edges[1:] + self.z_edges[:-1]), indexing="ij")
            self.volume_of = regions.inside_silo(shape, xc, zc).astype(float)
        else:  # sums over each cell, divided by its area inside the silo
            self.volume_of = self.area_inside
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
            mass, moments = cell_sums(rd.x, rd.z, rd.mass, rd.moments, self.x_edges,
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
        meaning = ("at the cell centre, Gaussian coarse-graining of width attrs['width']"
                   if self.kernel == "gaussian" else "grains centred in the cell / its volume")
        for w in self.WINDOWS:
            h = f.create_group(w)
            h.attrs["samples"] = self.samples[w]
            density, stress = fields_of(self.mass[w], self.moments[w], self.volume_of,
                                        self.thickness, self.samples[w])
            dataset(h, "density", density, "kg/m^3", meaning=f"bulk density: {meaning}")
            dataset(h, "stress", stress, "Pa",
                    components=f"xx,zz,xz; compression positive (Love-Weber, {meaning})")
