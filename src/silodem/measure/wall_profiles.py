"""Stress profiles along the walls and through the silo.

Wall stresses: each wall segment A->B is cut into bins of equal length (about ``bin_len``);
a grain-wall contact falls in the bin of its contact point.  With f the force of the wall ON
the grain [N], t the unit tangent A->B, n_in the wall's inner normal (the left of A->B) and the
bin length L_b [m] and grain thickness t_g [m]:

    normal stress  sigma_n = sum f . n_in / (L_b t_g)    [Pa]  (pressure on the wall, >= 0)
    shear stress   tau     = sum (-f) . t  / (L_b t_g)   [Pa]  (traction ON the wall along A->B)

so that sum over bins of (sigma_n (-n_in) + tau t) L_b t_g is the total force of the grains on
the wall.  On the silo's vertical walls sigma_n is the horizontal stress sigma_h.

Profiles through the grains use the Love-Weber stress (``stress``) of the grains whose centres
lie in horizontal bins: near-wall strips of width w along the left and right edges of the silo
(they follow the hopper walls below the junction), and full-width slices.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt


@dataclass(frozen=True)
class WallBins:
    """Bins along every wall: per bin its wall, start/end along the wall [m], length [m] and
    centre (x, z) [m]; per wall its unit tangent and inner normal."""

    wall: np.ndarray
    s0: np.ndarray
    s1: np.ndarray
    x: np.ndarray
    z: np.ndarray
    tangent: np.ndarray  # (n_walls, 2)
    normal: np.ndarray  # (n_walls, 2), inner normal

    @property
    def length(self) -> np.ndarray:
        return self.s1 - self.s0


def wall_bins(ax: npt.ArrayLike, ay: npt.ArrayLike, bx: npt.ArrayLike, by: npt.ArrayLike,
              bin_len: float) -> WallBins:
    """Cut each wall (ends A = (ax, ay), B = (bx, by) [m]) into round(L / bin_len) (at least
    1) equal bins, ``bin_len`` [m]."""
    ax, ay, bx, by = (np.asarray(v, dtype=float) for v in (ax, ay, bx, by))
    length = np.hypot(bx - ax, by - ay)
    tangent = np.column_stack([(bx - ax) / length, (by - ay) / length])
    normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])
    wall, s0, s1 = [], [], []
    for w, L in enumerate(length):
        k = max(1, round(L / bin_len))
        edges = np.linspace(0.0, L, k + 1)
        wall += [w] * k
        s0 += list(edges[:-1])
        s1 += list(edges[1:])
    wall_a, s0_a, s1_a = np.array(wall, dtype=np.int64), np.array(s0), np.array(s1)
    mid = 0.5 * (s0_a + s1_a)
    return WallBins(wall_a, s0_a, s1_a, ax[wall_a] + mid * tangent[wall_a, 0],
                    ay[wall_a] + mid * tangent[wall_a, 1], tangent, normal)


def contact_bins(bins: WallBins, ax: np.ndarray, ay: np.ndarray, w_wall: np.ndarray,
                 w_cx: np.ndarray, w_cy: np.ndarray) -> np.ndarray:
    """Bin index of each grain-wall contact (contact point (w_cx, w_cy) on wall w_wall)."""
    t = bins.tangent[w_wall]
    s = (w_cx - ax[w_wall]) * t[:, 0] + (w_cy - ay[w_wall]) * t[:, 1]
    first = np.searchsorted(bins.wall, np.arange(bins.tangent.shape[0]))
    count = np.bincount(bins.wall, minlength=bins.tangent.shape[0])
    L = bins.s1[first + count - 1]
    k = np.floor(s / L[w_wall] * count[w_wall]).astype(np.int64)
    return first[w_wall] + np.clip(k, 0, count[w_wall] - 1)


def wall_stress(bins: WallBins, ax: np.ndarray, ay: np.ndarray, w_wall: np.ndarray,
                w_cx: np.ndarray, w_cy: np.ndarray, w_fx: np.ndarray, w_fy: np.ndarray,
                thickness: float) -> tuple[np.ndarray, np.ndarray]:
    """(sigma_n, tau) per bin [Pa] from the grain-wall contacts (force ON the grain, [N])."""
    nb = bins.wall.size
    if len(w_wall) == 0:
        return np.zeros(nb), np.zeros(nb)
    b = contact_bins(bins, ax, ay, w_wall, w_cx, w_cy)
    nrm, tan = bins.normal[w_wall], bins.tangent[w_wall]
    fn = w_fx * nrm[:, 0] + w_fy * nrm[:, 1]
    ft = -(w_fx * tan[:, 0] + w_fy * tan[:, 1])
    area = bins.length * thickness
    return (np.bincount(b, weights=fn, minlength=nb) / area,
            np.bincount(b, weights=ft, minlength=nb) / area)


def wall_force_from_profile(bins: WallBins, sigma_n: np.ndarray, tau: np.ndarray,
                            thickness: float) -> np.ndarray:
    """Force of the grains on each wall (n_walls, 2) [N] rebuilt from binned stresses."""
    area = bins.length * thickness
    fx = (-sigma_n * bins.normal[bins.wall, 0] + tau * bins.tangent[bins.wall, 0]) * area
    fy = (-sigma_n * bins.normal[bins.wall, 1] + tau * bins.tangent[bins.wall, 1]) * area
    nw = bins.tangent.shape[0]
    return np.column_stack([np.bincount(bins.wall, weights=fx, minlength=nw),
                            np.bincount(bins.wall, weights=fy, minlength=nw)])


def binned_stress(moments: np.ndarray, z: np.ndarray, mask: np.ndarray, z_edges: np.ndarray,
                  areas: np.ndarray, thickness: float) -> np.ndarray:
    """Love-Weber stress (xx, zz, xz) [Pa] of the grains in ``mask`` binned by centre height
    ``z`` into ``z_edges``; ``areas`` [m^2] is the area of each bin's region.  Shape (nbins, 3);
    NaN where a bin has no area."""
    nb = len(z_edges) - 1
    k = np.searchsorted(z_edges, z, side="right") - 1
    ok = mask & (k >= 0) & (k < nb)
    out = np.empty((nb, 3))
    m = moments[ok]
    kk = k[ok]
    parts = [m[:, 0, 0], m[:, 1, 1], 0.5 * (m[:, 0, 1] + m[:, 1, 0])]
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(areas > 0, -1.0 / (np.asarray(areas) * thickness), np.nan)
    for c, vals in enumerate(parts):  # (+ 0.0: an empty bin's 0 * -scale is +0.0, not -0.0)
        out[:, c] = np.bincount(kk, weights=vals, minlength=nb)[:nb] * scale + 0.0
    return out


def peak_in_zone(z: npt.ArrayLike, values: npt.ArrayLike, z_lo: float,
                 z_hi: float) -> tuple[float, float]:
    """(largest value, its z [m]) among the points with z_lo <= z <= z_hi [m] (``values`` in
    their own unit); (nan, nan) if none."""
    z = np.asarray(z, dtype=float)
    v = np.asarray(values, dtype=float)
    sel = (z >= z_lo) & (z <= z_hi) & np.isfinite(v)
    if not np.any(sel):
        return float("nan"), float("nan")
    k = np.argmax(np.where(sel, v, -np.inf))
    return float(v[k]), float(z[k])


def rises_past(z: npt.ArrayLike, values: npt.ArrayLike, z_peak: float) -> str | None:
    """Whether the largest value of a zone at ``z_peak`` [m] is a local peak of the whole
    profile: None if it is (no neighbouring point, in or out of the zone, holds more), else
    "below" or "above", the side on which the profile goes on rising past it (a zone's edge
    on a stress that keeps growing, e.g. down a hopper wall over a closed gate).  NaN points
    are skipped; a ``z_peak`` not among ``z`` gives None."""
    z = np.asarray(z, dtype=float)
    v = np.asarray(values, dtype=float)
    ok = np.isfinite(v) & np.isfinite(z)
    z, v = z[ok], v[ok]
    order = np.argsort(z)
    z, v = z[order], v[order]
    at = np.flatnonzero(z == z_peak)
    if at.size == 0:
        return None
    k = int(at[0])
    if k > 0 and v[k - 1] > v[k]:
        return "below"
    if k + 1 < z.size and v[k + 1] > v[k]:
        return "above"
    return None


BOTTOM_WALLS = ("left_floor", "right_floor", "gate")  # what carries a silo from below


def bottom_load(normal: npt.ArrayLike, s0: npt.ArrayLike, s1: npt.ArrayLike,
                wall: npt.ArrayLike, names: list[str], thickness: float) -> tuple[float, float]:
    """(force [N], mean pressure [Pa]) of the grains on the silo's bottom: the floor pieces
    and the gate of a flat silo, the gate of a hopper silo (``BOTTOM_WALLS`` among ``names``),
    from the time-averaged normal pressure of each wall bin ``normal`` [Pa] over its span
    s1 - s0 [m] (bins of walls ``wall``, indices into ``names``) and the slab thickness t
    [m]: F = t sum p_i (s1_i - s0_i), p = F / (t sum (s1_i - s0_i)).  (nan, nan) without
    such a bin; a withdrawn gate's bins hold 0 Pa."""
    ids = [k for k, name in enumerate(names) if name in BOTTOM_WALLS]
    sel = np.isin(np.asarray(wall), ids)
    span = (np.asarray(s1, dtype=float) - np.asarray(s0, dtype=float))[sel]
    p = np.asarray(normal, dtype=float)[sel]
    ok = np.isfinite(p)
    if not ok.any() or span[ok].sum() <= 0:
        return float("nan"), float("nan")
    force = float(thickness * np.sum(p[ok] * span[ok]))
    return force, force / (thickness * float(span[ok].sum()))
