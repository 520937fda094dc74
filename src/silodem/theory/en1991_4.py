"""EN 1991-4:2006 (Eurocode 1, silos): the wall loads of §5.2 and §5.3 and the hopper loads of
§6, for the planar (2D) silo (docs/theory.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from silodem.theory import _checks as ck
from silodem.theory.hopper import _exponent, _sigma_v, walker_distribution_factor
from silodem.theory.janssen import _loaded_depth


def en1991_4_slenderness(h_c: float, d_c: float, flat_bottom: bool) -> str:
    """EN 1991-4:2006 §1.5 / §5.1 slenderness class of a silo whose vertical walls stand
    h_c [m] from the transition (or the flat bottom) to the equivalent surface, of inside
    dimension d_c [m] (the width B of a planar silo): "slender" for h_c/d_c >= 2,
    "intermediate" for 1 < h_c/d_c < 2, "squat" for 0.4 < h_c/d_c <= 1 and, with a hopper,
    below; "retaining" for a flat bottom and h_c/d_c <= 0.4.  The Janssen-form loads below
    (§5.2) are the standard's rules for slender silos only.  ValueError unless h_c, d_c > 0
    and flat_bottom is a bool."""
    _check_silo("en1991_4_slenderness", h_c, d_c, flat_bottom)
    return _slenderness(h_c, d_c, flat_bottom)


def _check_silo(func: str, h_c, d_c, flat_bottom) -> None:
    ck.positive(func, "h_c", h_c)
    ck.positive(func, "d_c", d_c)
    ck.flag(func, "flat_bottom", flat_bottom)


def _slenderness(h_c, d_c, flat_bottom) -> str:
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
    give the values to compare.  ValueError unless gamma >= 0 and K, mu, A_over_U > 0 (mu = 0
    makes z_o infinite).
    """
    return _filling("en1991_4_filling", depth, gamma, K, mu, A_over_U)


def _check_wall(func: str, gamma, K, mu, A_over_U) -> None:
    """The material and section of the vertical walls' loads (z_o = A / (K mu U) finite)."""
    ck.non_negative(func, "gamma", gamma)
    ck.positive(func, "K", K)
    ck.positive(func, "mu", mu)
    ck.positive(func, "A_over_U", A_over_U)


def _filling(func: str, depth, gamma, K, mu, A_over_U):
    _check_wall(func, gamma, K, mu, A_over_U)
    # z_o Y_J(z), Janssen's loaded depth with 1 / z_o: p_ho = gamma K z_o overflowed for
    # K mu / (A/U) < ~1e-308, and p_ho Y_J was inf x 0
    z_yj = _loaded_depth(ck.array(func, "depth", depth), K * mu / A_over_U)
    p_h = gamma * K * z_yj
    return p_h, mu * p_h, gamma * z_yj


def en1991_4_discharge(depth: npt.ArrayLike, gamma: float, K: float, mu: float,
                       A_over_U: float, C_h: float = 1.15,
                       C_w: float = 1.10) -> tuple[np.ndarray | float, np.ndarray | float]:
    """EN 1991-4:2006 §5.2.2.2 fixed discharge loads of slender silos: p_he = C_h p_hf,
    p_we = C_w p_wf [Pa] (C_h = 1.15, C_w = 1.10; 1.0 for a silo emptied from the top).
    The patch load is not included.  Returns (p_he, p_we).  ValueError unless C_h, C_w >= 1
    (magnifiers) and the conditions of :func:`en1991_4_filling`."""
    ck.between("en1991_4_discharge", "C_h", C_h, 1.0, math.inf, lo_in=True)
    ck.between("en1991_4_discharge", "C_w", C_w, 1.0, math.inf, lo_in=True)
    p_h, p_w, _ = _filling("en1991_4_discharge", depth, gamma, K, mu, A_over_U)
    return C_h * p_h, C_w * p_w


def en1991_4_h_o(d_c: float, phi_r_deg: float, planar: bool = True) -> float:
    """Depth h_o [m] below the equivalent surface of the highest solid-wall contact, for a
    silo filled centrally to a heap at the angle of repose phi_r (EN 1991-4:2006: h_o as its
    symbol list, §1.6, and Fig. 1.1 define it; its formulas are with the squat silos' filling
    loads, §5.3.1.1): d_c tan(phi_r) / 4 for a planar (or rectangular) silo of width d_c, and
    r tan(phi_r) / 3 for a circular one of radius r = d_c / 2.  Geometry: the heap is a
    triangle (a cone) of height (d_c/2) tan(phi_r) on the level of the wall contacts; the level
    surface of the same volume lies 1/2 (1/3) of that height above it.  ValueError unless
    d_c > 0, 0 <= phi_r < 90 deg (0: a level top, h_o = 0) and planar is a bool."""
    ck.positive("en1991_4_h_o", "d_c", d_c)
    ck.between("en1991_4_h_o", "phi_r_deg", phi_r_deg, 0.0, 90.0, lo_in=True)
    ck.flag("en1991_4_h_o", "planar", planar)
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
    a levelled top).  Returns (p_h, p_w, p_v) [Pa].  ValueError unless 0 <= phi_r < 90 deg,
    0 <= h_o < z_o and the conditions of :func:`en1991_4_filling`."""
    func = "en1991_4_filling_squat"
    _check_wall(func, gamma, K, mu, A_over_U)
    ck.between(func, "phi_r_deg", phi_r_deg, 0.0, 90.0, lo_in=True)
    ck.number(func, "h_o", h_o)
    z_o = A_over_U / (K * mu)
    if not 0.0 <= h_o < z_o:
        raise ValueError(f"{func}: h_o must lie in [0, z_o = A_over_U / (K mu) = {z_o:.4g} m); "
                         f"got {ck.show(h_o)}")
    z = np.maximum(ck.array(func, "depth", depth), 0.0)
    below = np.maximum(z, h_o)  # the wall-loaded part starts at the highest wall contact
    n = -(1.0 + math.tan(math.radians(phi_r_deg))) * (1.0 - h_o / z_o)
    # ratio = 1 + x = (z + z_o - 2 h_o) / (z_o - h_o) >= 1, taken as log1p(x): 1 - ratio^n
    # formed from ratio itself cancelled where x is small (a smooth wall, z_o huge: 3.5e-4
    # of p_h lost at mu = 1e-12, all of it at 1e-15)
    log_r = np.log1p((below - h_o) / (z_o - h_o))
    p_h = gamma * K * z_o * -np.expm1(n * log_r)
    # z_V = h_o + (z_o - h_o) (ratio^(n+1) - 1) / (n + 1), written with expm1 so that it stays
    # exact as n + 1 -> 0 (where it becomes h_o + (z_o - h_o) ln(ratio))
    m = n + 1.0
    z_v = h_o + (z_o - h_o) * (np.expm1(m * log_r) / m if m != 0.0 else log_r)
    p_v = gamma * np.where(z < h_o, z, z_v)
    return p_h, mu * p_h, p_v


def en1991_4_discharge_factors(h_c: float, d_c: float, flat_bottom: bool) -> tuple[float, float]:
    """EN 1991-4:2006 discharge load magnifiers (C_h, C_w) on the symmetrical filling loads of
    the vertical walls, by slenderness class (:func:`en1991_4_slenderness`): slender
    (§5.2.2.2) 1.15 and 1.10; intermediate (§5.3.2.2) 1 + 0.15 C_S and 1 + 0.1 C_S with
    C_S = h_c/d_c - 1 (so the two rules meet at h_c/d_c = 2); squat (§5.3.2.2) 1 and 1 (the
    discharge loads equal the filling loads).  Retaining silos (§5.4) are not covered: a
    ValueError (and for the arguments :func:`en1991_4_slenderness` refuses).  For a silo
    emptied from the top both are 1 whatever the class."""
    _check_silo("en1991_4_discharge_factors", h_c, d_c, flat_bottom)
    kind = _slenderness(h_c, d_c, flat_bottom)
    if kind == "slender":
        return 1.15, 1.10
    if kind == "intermediate":
        c_s = h_c / d_c - 1.0
        return 1.0 + 0.15 * c_s, 1.0 + 0.10 * c_s
    if kind == "squat":
        return 1.0, 1.0
    raise ValueError("en1991_4_discharge_factors: EN 1991-4 loads of retaining silos (§5.4, "
                     "h_c/d_c <= 0.4 on a flat bottom) are not built")


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
    "shallow" otherwise.  K: lateral pressure ratio [-]; mu_h: hopper wall friction [-].
    ValueError unless 0 < beta < 90 deg, K > 0 and mu_h >= 0."""
    _check_hopper("en1991_4_hopper_kind", beta_deg, K, mu_h)
    return _hopper_kind(beta_deg, K, mu_h)


def _check_hopper(func: str, beta_deg, K, mu_h) -> None:
    ck.between(func, "beta_deg", beta_deg, 0.0, 90.0)
    ck.positive(func, "K", K)
    ck.non_negative(func, "mu_h", mu_h)


def _hopper_kind(beta_deg, K, mu_h) -> str:
    if beta_deg > 85.0:
        return "flat"
    # tan(beta) < (1 - K) / (2 mu_h), multiplied out so that mu_h = 0 needs no division
    return "steep" if 2.0 * mu_h * math.tan(math.radians(beta_deg)) < 1.0 - K else "shallow"


def _hopper_load(x, h_h, p_vft, gamma, beta_deg, kind, mu, F, planar) -> HopperLoad:
    """p_v of the slice balance with p_n = F p_v (:func:`hopper_sigma_v` with D = F): EN's p_v
    expression, with the slice balance's exponent n = S (F mu cot(beta) + F) - S (S = 1 for a
    wedge, 2 for a cone; for a cone it is the standard's n for a pressure ratio F)."""
    p_v = _sigma_v(x, h_h, p_vft, gamma, beta_deg, mu, F, planar)
    n = _exponent(beta_deg, mu, F, planar)
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
    has no hopper rule: ValueError for both, and unless 0 <= x <= h_h (the hopper, apex to
    transition), h_h > 0, p_vft >= 0, gamma >= 0, 0 <= b < 1, planar a bool and the conditions
    of :func:`en1991_4_hopper_kind`."""
    x = _check_hopper_loads("en1991_4_hopper_filling", x, h_h, p_vft, gamma, beta_deg, K,
                            mu_h, planar, b)
    return _hopper_filling("en1991_4_hopper_filling", x, h_h, p_vft, gamma, beta_deg, K, mu_h,
                           planar, b)


def _check_hopper_loads(func: str, x, h_h, p_vft, gamma, beta_deg, K, mu_h, planar,
                        b) -> np.ndarray:
    """The arguments of the hopper loads, ``x`` as an array in [0, h_h]."""
    ck.positive(func, "h_h", h_h)
    ck.non_negative(func, "p_vft", p_vft)
    ck.non_negative(func, "gamma", gamma)
    _check_hopper(func, beta_deg, K, mu_h)
    ck.flag(func, "planar", planar)
    ck.between(func, "b", b, 0.0, 1.0, lo_in=True)  # F_f = 1 - b mu / (mu + tan beta) > 0
    x = ck.array(func, "x", x)
    ck.within(func, "x", x, 0.0, h_h, "h_h")
    return x


def _hopper_filling(func: str, x, h_h, p_vft, gamma, beta_deg, K, mu_h, planar,
                    b) -> HopperLoad:
    kind = _hopper_kind(beta_deg, K, mu_h)
    tan_b = math.tan(math.radians(beta_deg))
    if kind == "flat":
        raise ValueError(f"{func}: beta_deg = {ck.show(beta_deg)} is a flat bottom (walls "
                         "within 5 deg of the horizontal): EN 1991-4's hopper rules do not apply")
    if kind == "shallow" and K >= 1.0:
        raise ValueError(f"{func}: a shallow hopper's mobilised friction (1 - K)/(2 tan beta) "
                         f"needs K < 1; got K = {K:.3g}")
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
    F = F_e in n = S (F mu_h cot(beta) + F) - S.  For a wedge (S = 1) this departs from the
    standard as printed (§6.3.1: n = S (F mu cot(beta) + F) - 2, the cone's slice balance),
    whose n is lower by 1 and whose discharge pressures are higher (docs/theory.md; the
    printed one is :func:`en1991_4_printed_exponent`).  phi_i: angle of internal friction [deg],
    at least phi_wh; the other arguments as for the filling loads.  ValueError unless
    0 < phi_i < 90 deg, in a steep hopper phi_i >= phi_wh, and as for the filling loads."""
    func = "en1991_4_hopper_discharge"
    x = _check_hopper_loads(func, x, h_h, p_vft, gamma, beta_deg, K, mu_h, planar, b)
    ck.between(func, "phi_i_deg", phi_i_deg, 0.0, 90.0)
    if _hopper_kind(beta_deg, K, mu_h) != "steep":
        return _hopper_filling(func, x, h_h, p_vft, gamma, beta_deg, K, mu_h, planar, b)
    phi_wh = math.degrees(math.atan(mu_h))
    if phi_i_deg < phi_wh:  # no passive stress state at a wall rougher than the solid
        raise ValueError(f"{func}: phi_i_deg must be >= arctan(mu_h) = {phi_wh:.3g} deg in a "
                         f"steep hopper; got {ck.show(phi_i_deg)}")
    F_e = walker_distribution_factor(phi_i_deg, phi_wh, beta_deg)
    return _hopper_load(x, h_h, p_vft, gamma, beta_deg, "steep", mu_h, F_e, planar)


def en1991_4_printed_exponent(F: float, mu: float, beta_deg: float, planar: bool = True) -> float:
    """The hopper exponent as EN 1991-4:2006 §6.3.1 prints it, n = S (F mu cot(beta) + F) - 2
    (S = 1 wedge, 2 cone) [-].  For a cone it is the slice balance's S [F (1 + mu cot(beta))
    - 1], which the hopper loads above use; for a wedge it is 1 lower (docs/theory.md).
    ValueError unless F > 0, mu >= 0, 0 < beta < 90 deg and planar is a bool."""
    func = "en1991_4_printed_exponent"
    ck.positive(func, "F", F)
    ck.non_negative(func, "mu", mu)
    ck.between(func, "beta_deg", beta_deg, 0.0, 90.0)
    ck.flag(func, "planar", planar)
    S = 1.0 if planar else 2.0
    return S * (F * mu / math.tan(math.radians(beta_deg)) + F) - 2.0


def en1991_4_phi_i_from_K(K: float) -> float:
    """Angle of internal friction [deg] that EN 1991-4:2006's estimate of the lateral pressure
    ratio from it, K = 1.1 (1 - sin(phi_i)) (its section 4, on the properties of particulate
    solids), gives for a measured K; NaN where none does (K <= 0 or K >= 1.1).  ValueError
    for a K that is not a finite number."""
    ck.number("en1991_4_phi_i_from_K", "K", K)
    s = 1.0 - K / 1.1
    return math.degrees(math.asin(s)) if 0.0 < s < 1.0 else float("nan")
