"""EN 1991-4:2006 (Eurocode 1, silos): the wall loads of §5.2 and §5.3 and the hopper loads of
§6, for the planar (2D) silo (docs/theory.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from silodem.theory.hopper import hopper_sigma_v, walker_distribution_factor, walker_exponent


def en1991_4_slenderness(h_c: float, d_c: float, flat_bottom: bool) -> str:
    """EN 1991-4:2006 §1.5 / §5.1 slenderness class of a silo whose vertical walls stand
    h_c [m] from the transition (or the flat bottom) to the equivalent surface, of inside
    dimension d_c [m] (the width B of a planar silo): "slender" for h_c/d_c >= 2,
    "intermediate" for 1 < h_c/d_c < 2, "squat" for 0.4 < h_c/d_c <= 1 and, with a hopper,
    below; "retaining" for a flat bottom and h_c/d_c <= 0.4.  The Janssen-form loads below
    (§5.2) are the standard's rules for slender silos only."""
    if not (h_c > 0.0 and d_c > 0.0):
        raise ValueError(f"h_c and d_c must be positive, got {h_c} and {d_c}")
    ratio = h_c / d_c
    if ratio >= 2.0:
        return "slender"
    if ratio > 1.0:
        return "intermediate"
    return "retaining" if ratio <= 0.4 and flat_bottom else "squat"


def en1991_4_filling(depth: npt.ArrayLike, gamma: float, K: float, mu: float,
                     A_over_U: float) -> tuple[np.ndarray | float, np.ndarray | float,
                                               np.ndarray | float]:
    """EN 1991-4:2006 §5.2.1.1 symmetrical filling loads on vertical walls of slender silos.

    p_hf = p_ho Y_J(z), p_wf = mu p_hf, p_vf = p_ho / K Y_J(z), with
    p_ho = gamma K z_o, z_o = A/(K mu U), Y_J = 1 - exp(-z/z_o)   (Janssen form).

    depth z [m] below the equivalent surface; gamma [N/m^3]; K, mu [-]; A/U hydraulic radius [m]
    (B/2 for a 2D slot of width B).  Returns (p_h, p_w, p_v) [Pa].  The characteristic values
    of the standard use K and mu at their extremes (K = 1.1 (1 - sin phi_i) as a mean value);
    give the values to compare.
    """
    z = np.maximum(np.asarray(depth, dtype=float), 0.0)
    z_o = A_over_U / (K * mu)
    p_ho = gamma * K * z_o
    yj = -np.expm1(-z / z_o)
    p_h = p_ho * yj
    return p_h, mu * p_h, p_ho / K * yj


def en1991_4_discharge(depth: npt.ArrayLike, gamma: float, K: float, mu: float,
                       A_over_U: float, C_h: float = 1.15,
                       C_w: float = 1.10) -> tuple[np.ndarray | float, np.ndarray | float]:
    """EN 1991-4:2006 §5.2.2.2 fixed discharge loads of slender silos: p_he = C_h p_hf,
    p_we = C_w p_wf [Pa] (C_h = 1.15, C_w = 1.10; 1.0 for a silo emptied from the top).
    The patch load is not included.  Returns (p_he, p_we)."""
    p_h, p_w, _ = en1991_4_filling(depth, gamma, K, mu, A_over_U)
    return C_h * p_h, C_w * p_w


def en1991_4_h_o(d_c: float, phi_r_deg: float, planar: bool = True) -> float:
    """Depth h_o [m] below the equivalent surface of the highest solid-wall contact, for a
    silo filled centrally to a heap at the angle of repose phi_r (EN 1991-4:2006 §1.6 and
    Fig. 1.1): d_c tan(phi_r) / 4 for a planar (or rectangular) silo of width d_c, and
    r tan(phi_r) / 3 for a circular one of radius r = d_c / 2.  Geometry: the heap is a
    triangle (a cone) of height (d_c/2) tan(phi_r) on the level of the wall contacts; the level
    surface of the same volume lies 1/2 (1/3) of that height above it."""
    rise = 0.5 * d_c * math.tan(math.radians(phi_r_deg))
    return rise / 2.0 if planar else rise / 3.0


def en1991_4_filling_squat(depth: npt.ArrayLike, gamma: float, K: float, mu: float,
                           A_over_U: float, phi_r_deg: float,
                           h_o: float) -> tuple[np.ndarray | float, np.ndarray | float,
                                                np.ndarray | float]:
    """EN 1991-4:2006 §5.3.1.1 symmetrical filling loads on the vertical walls of squat and
    intermediate-slenderness silos (h_c/d_c < 2):

        p_hf = p_ho Y_R(z),  p_wf = mu p_hf,  p_vf = gamma z_V,
        p_ho = gamma K z_o,  z_o = A / (K mu U),
        Y_R(z) = 1 - ((z - h_o) / (z_o - h_o) + 1)^n,  n = -(1 + tan phi_r) (1 - h_o / z_o),
        z_V = h_o - (z_o - h_o - (z + z_o - 2 h_o)^(n+1) / (z_o - h_o)^n) / (n + 1).

    z_V is the slice balance d(p_vf)/dz = gamma - mu p_hf U / A integrated from p_vf = gamma
    h_o at z = h_o (with n = -1 it is a logarithm).  Above h_o (the highest wall contact) no
    wall is loaded: p_hf = p_wf = 0 and p_vf = gamma z.  Deep down p_hf tends to p_ho, as in
    the Janssen form of slender silos (:func:`en1991_4_filling`).

    depth z [m] below the equivalent surface; gamma [N/m^3]; K, mu [-]; A/U [m] (B/2 for a
    2D slot); phi_r the angle of repose [deg]; h_o [m] (:func:`en1991_4_h_o` for a heap, 0 for
    a levelled top).  Returns (p_h, p_w, p_v) [Pa]."""
    z_o = A_over_U / (K * mu)
    if not 0.0 <= h_o < z_o:
        raise ValueError(f"h_o must lie in [0, z_o = {z_o:.4g} m), got {h_o}")
    z = np.maximum(np.asarray(depth, dtype=float), 0.0)
    below = np.maximum(z, h_o)  # the wall-loaded part starts at the highest wall contact
    n = -(1.0 + math.tan(math.radians(phi_r_deg))) * (1.0 - h_o / z_o)
    ratio = 1.0 + (below - h_o) / (z_o - h_o)  # = (z + z_o - 2 h_o) / (z_o - h_o) >= 1
    p_h = gamma * K * z_o * (1.0 - ratio**n)
    # z_V = h_o + (z_o - h_o) (ratio^(n+1) - 1) / (n + 1), written with expm1 so that it stays
    # exact as n + 1 -> 0 (where it becomes h_o + (z_o - h_o) ln(ratio))
    m, log_r = n + 1.0, np.log(ratio)
    z_v = h_o + (z_o - h_o) * (np.expm1(m * log_r) / m if m != 0.0 else log_r)
    p_v = gamma * np.where(z < h_o, z, z_v)
    return p_h, mu * p_h, p_v


def en1991_4_discharge_factors(h_c: float, d_c: float, flat_bottom: bool) -> tuple[float, float]:
    """EN 1991-4:2006 discharge load magnifiers (C_h, C_w) on the symmetrical filling loads of
    the vertical walls, by slenderness class (:func:`en1991_4_slenderness`): slender
    (§5.2.2.2) 1.15 and 1.10; intermediate (§5.3.2.2) 1 + 0.15 C_S and 1 + 0.1 C_S with
    C_S = h_c/d_c - 1 (so the two rules meet at h_c/d_c = 2); squat (§5.3.2.2) 1 and 1 (the
    discharge loads equal the filling loads).  Retaining silos (§5.4) are not covered: a
    ValueError.  For a silo emptied from the top both are 1 whatever the class."""
    kind = en1991_4_slenderness(h_c, d_c, flat_bottom)
    if kind == "slender":
        return 1.15, 1.10
    if kind == "intermediate":
        c_s = h_c / d_c - 1.0
        return 1.0 + 0.15 * c_s, 1.0 + 0.10 * c_s
    if kind == "squat":
        return 1.0, 1.0
    raise ValueError("EN 1991-4 loads of retaining silos (§5.4, h_c/d_c <= 0.4 on a flat "
                     "bottom) are not built")


@dataclass(frozen=True)
class HopperLoad:
    """EN 1991-4:2006 §6 loads on the walls of a hopper (:func:`en1991_4_hopper_filling`,
    :func:`en1991_4_hopper_discharge`).  kind: "steep" or "shallow" (§6.1); mu_eff: the wall
    friction used, mu_h (steep) or the mobilised mu_heff (shallow) [-]; F: the hopper pressure
    ratio p_n / p_v [-]; n: the exponent of p_v [-]; p_n, p_t, p_v: normal pressure, frictional
    traction (mu_eff p_n) and mean vertical stress at the heights asked [Pa]."""

    kind: str
    mu_eff: float
    F: float
    n: float
    p_n: np.ndarray | float
    p_t: np.ndarray | float
    p_v: np.ndarray | float


def en1991_4_hopper_kind(beta_deg: float, K: float, mu_h: float) -> str:
    """EN 1991-4:2006 §6.1 class of a hopper of apex half-angle beta [deg] (from the vertical,
    alpha of this module): "flat" when its walls lie within 5 deg of the horizontal (beta > 85),
    "steep" when tan(beta) < (1 - K) / (2 mu_h) (the wall friction is then fully mobilised),
    "shallow" otherwise.  K: lateral pressure ratio [-]; mu_h: hopper wall friction [-]."""
    if not 0.0 < beta_deg < 90.0:
        raise ValueError(f"beta must lie in (0, 90) deg, got {beta_deg}")
    if beta_deg > 85.0:
        return "flat"
    # tan(beta) < (1 - K) / (2 mu_h), multiplied out so that mu_h = 0 needs no division
    return "steep" if 2.0 * mu_h * math.tan(math.radians(beta_deg)) < 1.0 - K else "shallow"


def _hopper_load(x, h_h, p_vft, gamma, beta_deg, kind, mu, F, planar) -> HopperLoad:
    """p_v of the slice balance with p_n = F p_v (:func:`hopper_sigma_v` with D = F): EN's p_v
    expression, with the slice balance's exponent n = S (F mu cot(beta) + F) - S (S = 1 for a
    wedge, 2 for a cone; for a cone it is the standard's n for a pressure ratio F)."""
    p_v = hopper_sigma_v(x, h_h, p_vft, gamma, beta_deg, mu, F, planar)
    n = walker_exponent(beta_deg, mu, F, planar)
    return HopperLoad(kind, mu, F, n, F * p_v, mu * F * p_v, p_v)


def en1991_4_hopper_filling(x: npt.ArrayLike, h_h: float, p_vft: float, gamma: float,
                            beta_deg: float, K: float, mu_h: float, planar: bool = True,
                            b: float = 0.2) -> HopperLoad:
    """EN 1991-4:2006 §6.3.2 (steep) and §6.4.2 (shallow) filling loads on a hopper's walls:

        p_nf = F_f p_v,  p_tf = mu_eff F_f p_v,  F_f = 1 - b / (1 + tan(beta) / mu_eff),
        p_v = gamma h_h / (n - 1) [x/h_h - (x/h_h)^n] + p_vft (x/h_h)^n,
        n = S (1 - b) mu_eff cot(beta),  S = 1 (wedge, planar) or 2 (cone),

    with mu_eff = mu_h in a steep hopper and the mobilised mu_heff = (1 - K) / (2 tan(beta)) in
    a shallow one (:func:`en1991_4_hopper_kind`; the two meet at the class limit).  n is the
    slice balance's exponent with F = F_f, S [F_f (1 + mu_eff cot(beta)) - 1], simplified.

    x: height above the hopper's (virtual) apex [m]; h_h: the transition's height above the
    apex [m]; p_vft: mean vertical stress on the transition [Pa] (EN: C_b p_vf of the vertical
    walls; C_b = 1.0, more for some silo classes and solids); gamma [N/m^3];
    beta: apex half-angle from the vertical [deg]; K, mu_h [-]; b = 0.2, EN's empirical
    coefficient.  A shallow hopper needs K < 1 (mu_heff > 0); a flat bottom (beta > 85 deg)
    has no hopper rule: ValueError for both."""
    kind = en1991_4_hopper_kind(beta_deg, K, mu_h)
    tan_b = math.tan(math.radians(beta_deg))
    if kind == "flat":
        raise ValueError(f"beta = {beta_deg} deg is a flat bottom (walls within 5 deg of the "
                         "horizontal): EN 1991-4's hopper rules do not apply")
    if kind == "shallow" and K >= 1.0:
        raise ValueError(f"a shallow hopper's mobilised friction (1 - K)/(2 tan beta) needs "
                         f"K < 1, got K = {K:.3g}")
    mu = mu_h if kind == "steep" else (1.0 - K) / (2.0 * tan_b)
    F_f = 1.0 - b * mu / (mu + tan_b)  # = 1 - b / (1 + tan(beta) / mu), also at mu = 0
    return _hopper_load(x, h_h, p_vft, gamma, beta_deg, kind, mu, F_f, planar)


def en1991_4_hopper_discharge(x: npt.ArrayLike, h_h: float, p_vft: float, gamma: float,
                              beta_deg: float, K: float, mu_h: float, phi_i_deg: float,
                              planar: bool = True, b: float = 0.2) -> HopperLoad:
    """EN 1991-4:2006 §6.3.3 discharge loads on a steep hopper's walls (§6.4.3: a shallow
    hopper's discharge loads are its filling loads, :func:`en1991_4_hopper_filling`):

        p_ne = F_e p_v,  p_te = mu_h F_e p_v,
        F_e = (1 + sin(phi_i) cos(eps)) / (1 - sin(phi_i) cos(2 beta + eps)),
        eps = phi_wh + arcsin(sin(phi_wh) / sin(phi_i)),  phi_wh = arctan(mu_h),

    F_e being Walker's passive distribution factor (:func:`walker_distribution_factor` with
    delta = phi_i, eps = 2 omega), and p_v the slice balance's (EN's p_v expression) with
    F = F_e in n = S (F mu_h cot(beta) + F) - S.  phi_i: angle of internal friction [deg],
    at least phi_wh; the other arguments as for the filling loads."""
    if en1991_4_hopper_kind(beta_deg, K, mu_h) != "steep":
        return en1991_4_hopper_filling(x, h_h, p_vft, gamma, beta_deg, K, mu_h, planar, b)
    F_e = walker_distribution_factor(phi_i_deg, math.degrees(math.atan(mu_h)), beta_deg)
    return _hopper_load(x, h_h, p_vft, gamma, beta_deg, "steep", mu_h, F_e, planar)


def en1991_4_phi_i_from_K(K: float) -> float:
    """Angle of internal friction [deg] that EN 1991-4:2006's estimate of the lateral pressure
    ratio from it, K = 1.1 (1 - sin(phi_i)) (its section 4, on the properties of particulate
    solids), gives for a measured K; NaN where none does (K <= 0 or K >= 1.1)."""
    s = 1.0 - K / 1.1
    return math.degrees(math.asin(s)) if 0.0 < s < 1.0 else float("nan")
