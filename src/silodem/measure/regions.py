"""Where the measurements are made: circles, the junction band, the switch zone, edge strips.

Coordinates as in ``silodem.silo.geometry``: x across the silo from the left wall, z up from the
outlet.  Defaults follow the silo's size, so that ``--quick`` variants keep them in place.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from silodem.config import Config
from silodem.silo import sizes
from silodem.silo.geometry import SiloShape


@dataclass(frozen=True)
class CircleRegion:
    """A measurement circle: centre (x, z) [m], radius [m], area inside the silo [m^2]."""

    name: str
    x: float
    z: float
    radius: float
    area_inside: float


def mean_diameter(cfg: Config) -> float:
    """Mean grain diameter by number [m] (``silo.sizes.mean_radius``)."""
    return 2.0 * sizes.mean_radius(cfg.material)


def inside_silo(shape: SiloShape, x: npt.ArrayLike, z: npt.ArrayLike) -> np.ndarray:
    """True where the points (x, z) lie inside the silo (0 <= z <= wall top) [bool]."""
    x = np.asarray(x, dtype=float)
    z = np.asarray(z, dtype=float)
    lo, hi = shape.inner_x_bounds(z)
    return (z >= 0.0) & (z <= shape.wall_top) & (x >= lo) & (x <= hi)


def edge_distance(shape: SiloShape, x: npt.ArrayLike,
                  z: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal distance [m] of points from the left and from the right edge of the silo at
    their height (vertical wall above the junction, hopper wall below)."""
    x = np.asarray(x, dtype=float)
    lo, hi = shape.inner_x_bounds(z)
    return x - lo, hi - x


def area_inside_circle(shape: SiloShape, cx: float, cz: float, R: float, n: int = 401) -> float:
    """Area of the circle's part inside the silo [m^2] (midpoint quadrature on an n x n grid;
    relative error ~ 1e-4 for n = 401)."""
    h = 2.0 * R / n
    c = -R + h * (np.arange(n) + 0.5)
    gx, gz = np.meshgrid(cx + c, cz + c)
    in_circle = (gx - cx) ** 2 + (gz - cz) ** 2 <= R * R
    inside = in_circle & inside_silo(shape, gx, gz)
    frac = inside.sum() / max(in_circle.sum(), 1)
    return float(frac * math.pi * R * R)


def reference_height(shape: SiloShape, reach: float) -> float:
    """The height the switch-zone measurements centre on [m]: the junction of a hopper silo;
    ``reach`` above the floor of a flat one (where its dead zones meet the flowing core)."""
    return shape.junction if shape.kind == "hopper" else reach


def circles_for(cfg: Config, shape: SiloShape) -> list[CircleRegion]:
    """The configured measurement circles, or the default three at the switch zone: radius two
    mean diameters, centred at the junction height, touching the left wall, on the axis, and
    touching the right wall (a flat silo: resting on the floor)."""
    m = cfg.measure
    if m.circle_names is not None:
        z0 = shape.junction if m.circle_z_from == "junction" else 0.0
        specs = list(zip(m.circle_names, m.circle_x, [z0 + z for z in m.circle_z],
                         m.circle_radius))
    else:
        R = 2.0 * mean_diameter(cfg)
        z = reference_height(shape, R)
        B = shape.width
        specs = [("switch_left", R, z, R), ("switch_centre", 0.5 * B, z, R),
                 ("switch_right", B - R, z, R)]
    return [CircleRegion(name, float(x), float(z), float(r),
                         area_inside_circle(shape, float(x), float(z), float(r)))
            for name, x, z, r in specs]


def switch_zone(cfg: Config, shape: SiloShape) -> tuple[float, float]:
    """(z_lo, z_hi) of the switch zone [m]: the junction height +- measure.switch_zone_half_height
    (default two mean diameters, but at most half the hopper's height: in a short hopper the
    zone would otherwise reach the outlet, whose own stress concentration it would then report
    as the switch's peak); for a flat silo from the floor up to 2 x that."""
    half = cfg.measure.switch_zone_half_height
    if half is None:
        half = 2.0 * mean_diameter(cfg)
        if shape.kind == "hopper":
            half = min(half, 0.5 * shape.junction)
    zc = reference_height(shape, half)
    return max(zc - half, 0.0), zc + half


def junction_band(cfg: Config, shape: SiloShape) -> tuple[float, float]:
    """(z_lo, z_hi) of the band across the silo where Fig. 2's coordination number is counted."""
    h = cfg.measure.coordination_band or 4.0 * mean_diameter(cfg)
    zc = max(reference_height(shape, 0.5 * h), 0.5 * h)
    return zc - 0.5 * h, zc + 0.5 * h


def strip_width(cfg: Config) -> float:
    """Width of the near-wall strips [m] (default two mean diameters)."""
    return cfg.measure.strip_width or 2.0 * mean_diameter(cfg)


def grid_cell(cfg: Config) -> float:
    """Cell size of the velocity-field grid [m] (default one mean diameter)."""
    return cfg.measure.grid_cell or mean_diameter(cfg)


def field_cell(cfg: Config) -> float:
    """Cell size of the density and stress fields [m] (default four mean diameters)."""
    return cfg.measure.field_cell or 4.0 * mean_diameter(cfg)


def field_width(cfg: Config, shape: SiloShape) -> float:
    """Width w of the Gaussian coarse-graining of the fields [m]; default half the grid's
    largest cell side (:func:`field_spacing`), the least width whose samples at the cell
    centres add up to a grain's mass within 3 % (docs/measurements.md)."""
    return cfg.measure.field_width or 0.5 * field_spacing(cfg, shape)


def field_spacing(cfg: Config, shape: SiloShape) -> float:
    """The largest side of the field grid's cells [m]: ``field_cell`` rounded to a whole
    number of cells across the silo's width and height (:func:`grid_edges`), up to about 1.5
    times it in a small silo."""
    x_edges, z_edges = grid_edges(shape, field_cell(cfg))
    return float(max(np.max(np.diff(x_edges)), np.max(np.diff(z_edges))))


def bin_length(cfg: Config) -> float:
    """Bin length along the walls and bin height of the profiles [m] (default two mean
    diameters)."""
    return cfg.measure.wall_bin or 2.0 * mean_diameter(cfg)


def even_edges(lo: float, hi: float, step: float) -> np.ndarray:
    """Edges of round((hi - lo) / step) (at least 1) equal bins from lo to hi [m]."""
    return np.linspace(lo, hi, max(1, round((hi - lo) / step)) + 1)


def grid_edges(shape: SiloShape, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """(x_edges, z_edges) [m] of a grid of cells about ``cell`` wide over the silo, from the
    left wall to the right and from the outlet to the wall top."""
    return even_edges(0.0, shape.width, cell), even_edges(0.0, shape.wall_top, cell)


def grid_cell_index(x: np.ndarray, z: np.ndarray, x_edges: np.ndarray,
                    z_edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(flat cell index ix * nz + iz of the points inside the grid, mask of those points)."""
    nx, nz = x_edges.size - 1, z_edges.size - 1
    ix = np.searchsorted(x_edges, x, side="right") - 1
    iz = np.searchsorted(z_edges, z, side="right") - 1
    ok = (ix >= 0) & (ix < nx) & (iz >= 0) & (iz < nz)
    return ix[ok] * nz + iz[ok], ok


def profile_edges(cfg: Config, shape: SiloShape) -> np.ndarray:
    """Bin edges in z for the profiles through the grains [m]: from the outlet to the wall top
    in steps of about the bin length, with an edge at the junction."""
    dz = bin_length(cfg)
    if shape.kind == "hopper" and shape.junction > 0:
        lower = even_edges(0.0, shape.junction, dz)
        upper = even_edges(shape.junction, shape.wall_top, dz)
        return np.concatenate([lower, upper[1:]])
    return even_edges(0.0, shape.wall_top, dz)
