"""Gaussian coarse-graining of mass and contact stress at the points of a grid.

The fields of a set of grains with masses m_p at r_p and contacts c carrying the force f_c
along the branch from a_c to a_c + l_c are (Goldhirsch, Granular Matter 12 (2010) 239;
Weinhart, Thornton, Luding & Bokhove, Granular Matter 14 (2012) 289, for disks
of thickness t):

    rho(r)      = 1/t sum_p m_p phi(r - r_p)
    sigma_ab(r) = 1/t sum_c f_c,a l_c,b int_0^1 phi(r - a_c - s l_c) ds   (compression > 0)

with the normalised Gaussian phi(r) = exp(-|r|^2 / (2 w^2)) / (2 pi w^2) of width w.  A
grain-grain contact's branch runs from grain i's centre to grain j's and f is the force on j;
a wall contact's runs from the grain's centre to the contact point and f is minus the force on
the grain (the wall's side of the contact).  The line integral has a closed form: with s0 the
parameter of the point of the line a + s l nearest to r and h its distance from r,

    int_0^1 phi ds = exp(-h^2 / (2 w^2)) / (2 pi w^2) * w sqrt(pi/2) / |l|
                     * (erf((1 - s0) |l| / (sqrt(2) w)) + erf(s0 |l| / (sqrt(2) w)))

Integrated over the plane, rho t gives the total mass and sigma t the sum of f (x) l, the
Love-Weber total of the box average, exactly; the kernel is cut at CUTOFF widths, which drops
a share exp(-CUTOFF^2 / 2) = 4e-6 of each term.  Unlike the box average, the Gaussian fields
are smooth, and do not depend on where the cell edges fall; near a wall they fall off over
about 2 w, since the wall has no grains behind it (Weinhart et al. 2012, section 5).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from silodem.jit import njit

if TYPE_CHECKING:
    from silodem.measure.reading import Reading

CUTOFF = 5.0  # terms are summed where the kernel is within this many widths [-]


@njit
def segment_weight(ax, az, lx, lz, gx, gz, w):
    """int_0^1 phi((gx, gz) - (ax, az) - s (lx, lz)) ds [1/m^2] (module docstring); the point
    value phi when the segment is much shorter than w."""
    dx = gx - ax
    dz = gz - az
    l2 = lx * lx + lz * lz
    norm = 1.0 / (2.0 * math.pi * w * w)
    if l2 < 1e-12 * w * w:
        return norm * math.exp(-0.5 * (dx * dx + dz * dz) / (w * w))
    s0 = (dx * lx + dz * lz) / l2
    h2 = max(dx * dx + dz * dz - s0 * s0 * l2, 0.0)
    length = math.sqrt(l2)
    c = length / (math.sqrt(2.0) * w)
    return (norm * math.exp(-0.5 * h2 / (w * w)) * w * math.sqrt(0.5 * math.pi) / length
            * (math.erf((1.0 - s0) * c) + math.erf(s0 * c)))


@njit
def _span(lo, hi, origin, step, n):
    """Indices k0:k1 of the grid points origin + (k + 1/2) step within [lo, hi]."""
    k0 = max(0, math.ceil((lo - origin) / step - 0.5))
    k1 = min(n, math.floor((hi - origin) / step - 0.5) + 1)
    return k0, k1


@njit
def add_points(x, z, weight, x0, hx, nx, z0, hz, nz, w, out):
    """out[kx, kz] += sum_p weight_p phi(centre - r_p) at the centres of the grid of nx x nz
    cells of size hx x hz from (x0, z0)."""
    cut = CUTOFF * w
    for p in range(x.size):
        kx0, kx1 = _span(x[p] - cut, x[p] + cut, x0, hx, nx)
        kz0, kz1 = _span(z[p] - cut, z[p] + cut, z0, hz, nz)
        for kx in range(kx0, kx1):
            gx = x0 + (kx + 0.5) * hx
            for kz in range(kz0, kz1):
                gz = z0 + (kz + 0.5) * hz
                out[kx, kz] += weight[p] * segment_weight(x[p], z[p], 0.0, 0.0, gx, gz, w)


@njit
def add_segments(ax, az, lx, lz, fx, fz, x0, hx, nx, z0, hz, nz, w, out):
    """out[kx, kz, :] += (f_x l_x, f_z l_z, (f_x l_z + f_z l_x)/2) int_0^1 phi ds over the
    segments from (ax, az) along (lx, lz) carrying (fx, fz), at the grid's centres."""
    cut = CUTOFF * w
    for c in range(ax.size):
        bx = ax[c] + lx[c]
        bz = az[c] + lz[c]
        kx0, kx1 = _span(min(ax[c], bx) - cut, max(ax[c], bx) + cut, x0, hx, nx)
        kz0, kz1 = _span(min(az[c], bz) - cut, max(az[c], bz) + cut, z0, hz, nz)
        txx = fx[c] * lx[c]
        tzz = fz[c] * lz[c]
        txz = 0.5 * (fx[c] * lz[c] + fz[c] * lx[c])
        for kx in range(kx0, kx1):
            gx = x0 + (kx + 0.5) * hx
            for kz in range(kz0, kz1):
                gz = z0 + (kz + 0.5) * hz
                s = segment_weight(ax[c], az[c], lx[c], lz[c], gx, gz, w)
                out[kx, kz, 0] += txx * s
                out[kx, kz, 1] += tzz * s
                out[kx, kz, 2] += txz * s


def gaussian_sums(rd: Reading, x_edges: np.ndarray, z_edges: np.ndarray,
                  width: float) -> tuple[np.ndarray, np.ndarray]:
    """sum_p m_p phi [kg/m^2], shape (nx, nz), and sum_c f (x) l int phi [N/m], shape
    (nx, nz, 3) (xx, zz, xz), at the cell centres of the (uniform) grid, for one reading
    ``rd`` (``measure.reading.Reading``): divided by t they are rho and sigma."""
    nx, nz = x_edges.size - 1, z_edges.size - 1
    grid = (float(x_edges[0]), float(x_edges[1] - x_edges[0]), nx,
            float(z_edges[0]), float(z_edges[1] - z_edges[0]), nz, float(width))
    mass = np.zeros((nx, nz))
    add_points(rd.x, rd.z, rd.mass, *grid, mass)
    stress = np.zeros((nx, nz, 3))
    if rd.i.size:
        add_segments(rd.x[rd.i], rd.z[rd.i], rd.x[rd.j] - rd.x[rd.i], rd.z[rd.j] - rd.z[rd.i],
                     rd.fx, rd.fz, *grid, stress)
    if rd.w_grain.size:
        g = rd.w_grain
        add_segments(rd.x[g], rd.z[g], rd.w_cx - rd.x[g], rd.w_cz - rd.z[g], -rd.w_fx,
                     -rd.w_fz, *grid, stress)
    return mass, stress
