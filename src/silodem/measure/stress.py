"""Average stress of a granular assembly from its contact forces (Love-Weber formula).

Sign convention: COMPRESSION POSITIVE (soil mechanics).  In 2D with grains of out-of-plane
thickness t [m], the mean stress [Pa] of a region of area A [m^2] is

    sigma_ab = -1/(A t) sum_p sum_(c in p) f_a^c l_b^(c,p)

with f^c the force ON grain p at contact c [N] and l^(c,p) = x_c - x_p the vector from the
grain's centre to the contact point [m] (Love 1927; Weber 1966; Christoffersen, Mehrabadi &
Nemat-Nasser 1981).  For a contact between two grains of the region the two terms add up to
f (x) l with l the branch vector between the centres (the contact-sum form sigma_ab = 1/A
sum_c f_a l_b, up to the sign convention); a wall contact contributes with the branch from the
grain's centre to the contact point on the wall.  Statics without body forces is assumed (the
weight and the inertia of the grains are left out, as in PFC); the tensor is symmetrised.

Grain moments M_p = sum_c f^c (x) l^(c,p) are computed once per reading (:func:`grain_moments`)
and summed over any region (:func:`region_stress`, :func:`circle_measure`).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt


def contact_points_pairs(x: np.ndarray, y: np.ndarray, r: np.ndarray, i: np.ndarray,
                         j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Contact points of grain-grain contacts [m]: x_i + (r_i - overlap/2) n, n from i to j."""
    dx, dy = x[j] - x[i], y[j] - y[i]
    d = np.hypot(dx, dy)
    d = np.where(d > 0, d, 1.0)
    reach = r[i] - 0.5 * (r[i] + r[j] - d)
    return x[i] + reach * dx / d, y[i] + reach * dy / d


def contact_points_walls(x: np.ndarray, y: np.ndarray, grain: np.ndarray, wall: np.ndarray,
                         ax: np.ndarray, ay: np.ndarray, bx: np.ndarray,
                         by: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Contact points of grain-wall contacts: the point of the wall segment closest to the
    grain's centre [m]."""
    px, py = x[grain], y[grain]
    ux, uy = bx[wall] - ax[wall], by[wall] - ay[wall]
    s = ((px - ax[wall]) * ux + (py - ay[wall]) * uy) / (ux * ux + uy * uy)
    s = np.clip(s, 0.0, 1.0)
    return ax[wall] + s * ux, ay[wall] + s * uy


def grain_moments(n: int, x: np.ndarray, y: np.ndarray, r: np.ndarray, i: np.ndarray,
                  j: np.ndarray, fx: np.ndarray, fy: np.ndarray, w_grain: np.ndarray,
                  w_cx: np.ndarray, w_cy: np.ndarray, w_fx: np.ndarray,
                  w_fy: np.ndarray) -> np.ndarray:
    """M[p] = sum over the contacts of grain p of f (x) (x_c - x_p), shape (n, 2, 2) [N m].

    Grain-grain contacts (i, j) with ``fx, fy`` the force on j [N]; grain-wall contacts with
    ``w_fx, w_fy`` the force on the grain [N] at the contact point (``w_cx, w_cy``) [m]."""
    out = np.zeros((n, 2, 2))
    if n == 0:
        return out
    cx, cy = contact_points_pairs(x, y, r, i, j)
    parts = [
        (j, fx, fy, cx - x[j], cy - y[j]),
        (i, -fx, -fy, cx - x[i], cy - y[i]),
        (w_grain, w_fx, w_fy, w_cx - x[w_grain], w_cy - y[w_grain]),
    ]
    for idx, gx, gy, lx, ly in parts:
        if len(idx) == 0:
            continue
        for a, fa in ((0, gx), (1, gy)):
            for b, lb in ((0, lx), (1, ly)):
                out[:, a, b] += np.bincount(idx, weights=fa * lb, minlength=n)[:n]
    return out


def _symmetric(total: np.ndarray, scale: float) -> np.ndarray:
    """(sigma_xx, sigma_zz, sigma_xz) = -scale * sym(total); a region without contacts gives
    0.0, not the -0.0 of the sign change (+ 0.0: IEEE 754 rounds -0.0 + 0.0 to +0.0)."""
    return -scale * np.array([total[0, 0], total[1, 1], 0.5 * (total[0, 1] + total[1, 0])]) + 0.0


def region_stress(moments: np.ndarray, mask: np.ndarray, area: float,
                  thickness: float) -> np.ndarray:
    """(sigma_xx, sigma_zz, sigma_xz) [Pa] of the grains whose centres are in a region of area
    ``area`` [m^2] (``mask`` over the grains), compression positive."""
    if area <= 0:
        return np.full(3, np.nan)
    return _symmetric(moments[mask].sum(axis=0), 1.0 / (area * thickness))


def lens_area(d: npt.ArrayLike, r: npt.ArrayLike, R: float) -> np.ndarray:
    """Area [m^2] of the intersection of a disk of radius r whose centre is at distance d from
    the centre of a circle of radius R (vectorised over d, r)."""
    d = np.asarray(d, dtype=float)
    r = np.broadcast_to(np.asarray(r, dtype=float), d.shape)
    out = np.zeros(d.shape)
    inside = d <= np.abs(R - r)
    out[inside] = np.pi * np.minimum(r[inside], R) ** 2
    part = (d < r + R) & ~inside
    dd, rr = d[part], r[part]
    a1 = rr**2 * np.arccos(np.clip((dd**2 + rr**2 - R**2) / (2 * dd * rr), -1, 1))
    a2 = R**2 * np.arccos(np.clip((dd**2 + R**2 - rr**2) / (2 * dd * R), -1, 1))
    k = (-dd + rr + R) * (dd + rr - R) * (dd - rr + R) * (dd + rr + R)
    out[part] = a1 + a2 - 0.5 * np.sqrt(np.clip(k, 0, None))
    return out


def circle_measure(x: np.ndarray, y: np.ndarray, r: np.ndarray, moments: np.ndarray,
                   counts: np.ndarray, cx: float, cz: float, R: float,
                   area_inside: float | None = None, thickness: float = 1.0) -> dict:
    """PFC2D-style measurement circle at (cx, cz) of radius R [m].

    porosity n = 1 - (area of the grains inside the circle) / (area of the circle inside the
    silo, ``area_inside``; default pi R^2) [-];
    stress [Pa] = -(1 - n) / (sum of the areas of the grains whose centres are inside) * sum of
    their moments / t   (PFC2D measurement logic: the grains with centres inside stand for the
    solid part of the circle); compression positive, returned as (xx, zz, xz);
    coordination = sum(n_c)/N_p over the grains whose centres are inside [-].
    """
    A = math.pi * R * R if area_inside is None else float(area_inside)
    dist = np.hypot(x - cx, y - cz)
    solid = float(lens_area(dist, r, R).sum())
    porosity = 1.0 - solid / A if A > 0 else float("nan")
    inside = dist < R
    n_in = int(inside.sum())
    if n_in == 0:
        return {"stress": np.full(3, np.nan), "porosity": porosity,
                "coordination": float("nan"), "count": 0}
    grain_area = float(np.sum(np.pi * r[inside] ** 2))
    stress = _symmetric(moments[inside].sum(axis=0), (1.0 - porosity) / (grain_area * thickness))
    return {"stress": stress, "porosity": porosity,
            "coordination": float(counts[inside].mean()), "count": n_in}
