"""Continuum silo theory to compare the simulations with (docs/theory.md).

Units are SI throughout: lengths [m], densities [kg/m^3], g [m/s^2], stresses [Pa], angles in
degrees where the argument name ends in ``_deg``.  Stresses are compressive positive (soil
mechanics).  The depth and height arguments (and the data of the fits) may be NumPy arrays;
the material and geometry parameters are scalars.

Angles: the config gives the hopper wall slope theta FROM THE HORIZONTAL
(``silo.hopper_angle_from_horizontal_deg``); hopper theory (Walker, Jenike, Nedderman) uses the
half-angle alpha FROM THE VERTICAL, alpha = 90 deg - theta (:func:`alpha_from_theta`).

Planar (2D, wedge) versus conical hoppers: the differential slice balance of a hopper reads, with
h the height above the (virtual) apex and m = 0 for a wedge, m = 1 for a cone,

    h d(sigma_v)/dh = n sigma_v - gamma h,   n = (m + 1) [D (1 + mu_w / tan(alpha)) - 1]

whose solution with sigma_v(H) = q at the transition h = H is

    sigma_v(h) = gamma h / (n - 1) [1 - (h/H)^(n-1)] + q (h/H)^n.

A 2D DEM hopper is a wedge (plane strain): m = 0.  The paper's eq. (12) is the conical form
(m = 1, D = 1, its n_i = n - 1); it overstates the wall support of a 2D slice by a factor of two
(perimeter/area of a cone 2/x, of a wedge 1/x) and so underpredicts the hopper stresses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

# --- helpers ---------------------------------------------------------------------------------


def alpha_from_theta(theta_from_horizontal_deg: float) -> float:
    """Hopper half-angle from the vertical alpha [deg] = 90 - theta (theta from the horizontal)."""
    return 90.0 - float(theta_from_horizontal_deg)


def apex_below_outlet(outlet_width: float, alpha_deg: float) -> float:
    """Depth of the virtual apex of a hopper under its outlet [m]: (D/2) / tan(alpha).

    Slice theory measures heights h from the apex, where the hopper walls would meet."""
    return 0.5 * outlet_width / math.tan(math.radians(alpha_deg))


# --- Janssen (1895), 2D slot -----------------------------------------------------------------


def janssen_sigma_v(depth: npt.ArrayLike, rho_b: float, g: float, B: float, K: float,
                    mu_w: float) -> np.ndarray | float:
    """Mean vertical stress [Pa] at ``depth`` [m] under the free surface of a 2D slot silo.

    sigma_v = rho_b g B / (2 K mu_w) * (1 - exp(-2 K mu_w depth / B))

    Janssen's slice balance for a slot of width B between two walls (plane strain: hydraulic
    radius A/U = B/2 per unit thickness): d(sigma_v)/dz = rho_b g - 2 K mu_w sigma_v / B.
    rho_b bulk density [kg/m^3], K = sigma_h/sigma_v [-], mu_w wall friction [-].
    Source: Janssen (1895), Z. Ver. Dtsch. Ing. 39; Nedderman (1992) ch. 3 (there in 3D form).
    """
    depth = np.maximum(np.asarray(depth, dtype=float), 0.0)
    c = 2.0 * K * mu_w / B
    if c == 0.0:
        return rho_b * g * depth
    return rho_b * g / c * -np.expm1(-c * depth)


def janssen_sigma_h(depth: npt.ArrayLike, rho_b: float, g: float, B: float, K: float,
                    mu_w: float) -> np.ndarray | float:
    """Horizontal (wall normal) stress [Pa] of Janssen's solution: sigma_h = K sigma_v."""
    return K * janssen_sigma_v(depth, rho_b, g, B, K, mu_w)


def janssen_wall_shear(depth: npt.ArrayLike, rho_b: float, g: float, B: float, K: float,
                       mu_w: float) -> np.ndarray | float:
    """Wall shear stress [Pa] of Janssen's solution (friction fully mobilised): mu_w K sigma_v."""
    return mu_w * janssen_sigma_h(depth, rho_b, g, B, K, mu_w)


@dataclass(frozen=True)
class JanssenFit:
    """Result of :func:`fit_janssen`: K [-], mu_w [-], their standard errors (``mu_w_err`` is 0
    when mu_w was given, not fitted), rms residual [Pa]."""

    K: float
    mu_w: float
    K_err: float
    mu_w_err: float
    rms: float
    n_points: int
    mu_w_fitted: bool

    @property
    def mu_w_at_bound(self) -> bool:
        """mu_w fitted onto its lower bound (``FIT_LOWER``): the profile is hydrostatic or
        steeper, it shows no wall support; K is then sigma_h / (rho_b g depth)."""
        return self.mu_w_fitted and self.mu_w <= 10 * FIT_LOWER


FIT_LOWER = 1e-6  # lower bound of K and mu_w in fit_janssen [-]


def _curve_fit(*args, **kwargs):
    """scipy.optimize.curve_fit without its OptimizeWarning: when the covariance cannot be
    estimated it comes back infinite and the fits below report NaN errors, which say so in
    the result instead of on the user's terminal (a sweep printed the warning per run)."""
    import warnings

    from scipy.optimize import OptimizeWarning, curve_fit

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OptimizeWarning)
        return curve_fit(*args, **kwargs)


def fit_janssen(depth: npt.ArrayLike, sigma_h: npt.ArrayLike, rho_b: float, g: float, B: float,
                mu_w: float | None = None) -> JanssenFit:
    """Least-squares fit of Janssen's sigma_h(depth) to a measured wall normal stress profile.

    sigma_h = rho_b g B / (2 mu_w) (1 - exp(-2 K mu_w depth / B)): the asymptote gives mu_w, the
    curvature K mu_w.  With ``mu_w`` given (e.g. the mobilised wall friction measured as
    sum(tau)/sum(sigma_n)) only K is fitted.  NaN points and points at depth <= 0 (above the
    free surface) are left out.  Units as in
    :func:`janssen_sigma_v`.  Uses scipy.optimize.curve_fit (trust-region reflective, bounds
    K, mu_w > 0).
    """

    z = np.asarray(depth, dtype=float)
    s = np.asarray(sigma_h, dtype=float)
    ok = np.isfinite(z) & np.isfinite(s) & (z > 0)
    z, s = z[ok], s[ok]
    if z.size < (1 if mu_w is not None else 2):
        raise ValueError("fit_janssen: not enough finite points with depth > 0")
    # start: K from the slope at small depth (sigma_h ~ K rho_b g depth), mu_w from the asymptote
    shallow = z <= np.quantile(z, 0.5)
    k0 = float(np.clip(np.sum(s[shallow] * z[shallow]) / np.sum(z[shallow] ** 2) / (rho_b * g),
                       0.05, 5.0))
    if mu_w is not None:
        def model_k(zz, K):
            return janssen_sigma_h(zz, rho_b, g, B, K, mu_w)

        popt, pcov = _curve_fit(model_k, z, s, p0=[k0], bounds=([FIT_LOWER], [50.0]))
        K, mu = float(popt[0]), float(mu_w)
        errs = np.sqrt(np.clip(np.diag(pcov), 0.0, np.inf)) if np.all(np.isfinite(pcov)) else [
            np.nan]
        K_err, mu_err = float(errs[0]), 0.0
    else:
        mu0 = float(np.clip(rho_b * g * B / (2.0 * max(s.max(), 1e-12)), 0.05, 2.0))

        def model(zz, K, mu):
            return janssen_sigma_h(zz, rho_b, g, B, K, mu)

        popt, pcov = _curve_fit(model, z, s, p0=[k0, mu0],
                               bounds=([FIT_LOWER, FIT_LOWER], [50.0, 50.0]), maxfev=20000)
        K, mu = float(popt[0]), float(popt[1])
        if np.all(np.isfinite(pcov)):
            K_err, mu_err = (float(v) for v in np.sqrt(np.clip(np.diag(pcov), 0.0, np.inf)))
        else:
            K_err = mu_err = float("nan")
    resid = s - janssen_sigma_h(z, rho_b, g, B, K, mu)
    return JanssenFit(K, mu, K_err, mu_err, float(np.sqrt(np.mean(resid**2))), int(z.size),
                      mu_w is None)


# --- Walker (1966): slice method in hoppers ----------------------------------------------------


def walker_exponent(alpha_deg: float, mu_w: float, D: float = 1.0, planar: bool = True) -> float:
    """Exponent n of the hopper slice solution [-].

    n = (m + 1) [D (1 + mu_w / tan(alpha)) - 1],  m = 0 planar wedge (2D), m = 1 cone.

    alpha: half-angle from the vertical [deg]; mu_w = tan(phi_w) wall friction [-]; D = sigma_n /
    sigma_v, Walker's distribution factor (wall normal stress over mean vertical stress) [-].
    With D = 1 and m = 1, n = 2 (1 + mu_w/tan(alpha)) - 2 = n_i + 1 with the paper's
    n_i = 2 (1 + tan(phi_P)/tan(alpha)) - 3.  Source: Walker (1966), Chem. Eng. Sci. 21, 975;
    Nedderman (1992), the method of differential slices.
    """
    m = 0 if planar else 1
    return (m + 1) * (D * (1.0 + mu_w / math.tan(math.radians(alpha_deg))) - 1.0)


def hopper_sigma_v(h: npt.ArrayLike, H: float, q: float, gamma: float, alpha_deg: float,
                   mu_w: float, D: float = 1.0, planar: bool = True) -> np.ndarray | float:
    """Mean vertical stress [Pa] at height ``h`` [m] above the apex of a hopper (slice method).

    sigma_v(h) = gamma h / (n - 1) [1 - (h/H)^(n-1)] + q (h/H)^n      (n from walker_exponent)

    solves h d(sigma_v)/dh = n sigma_v - gamma h with sigma_v(H) = q, the slice balance
    d(A sigma_v)/dh = -gamma A + P sigma_n (tan(alpha) + mu_w), sigma_n = D sigma_v, with A = 2 h
    tan(alpha), P = 2 (wedge, per unit thickness) or A = pi (h tan(alpha))^2, P = 2 pi h
    tan(alpha) (cone).  H: height of the transition above the apex [m]; q: mean vertical stress
    on the transition from the cell above [Pa]; gamma = rho_b g [N/m^3]; n = 1 is the limit
    gamma h ln(H/h) + q h/H.  Source: Walker (1966); Nedderman (1992), the method of
    differential slices.
    """
    h = np.asarray(h, dtype=float)
    n = walker_exponent(alpha_deg, mu_w, D, planar)
    x = np.clip(h / H, 1e-300, None)
    a = n - 1.0
    log_x = np.log(x)
    # (1 - x^a)/a, continuous through a = 0, where it is -ln x
    if abs(a) < 1e-12:
        growth = -log_x
    else:
        growth = -np.expm1(a * log_x) / a
    return gamma * h * growth + q * np.exp(n * log_x)


def hopper_wall_normal(h: npt.ArrayLike, H: float, q: float, gamma: float, alpha_deg: float,
                       mu_w: float, D: float = 1.0, planar: bool = True) -> np.ndarray | float:
    """Hopper wall normal stress [Pa]: sigma_n = D sigma_v (:func:`hopper_sigma_v`)."""
    return D * hopper_sigma_v(h, H, q, gamma, alpha_deg, mu_w, D, planar)


def paper_eq12(z_below_transition: npt.ArrayLike, h_prime: float, q: float, gamma: float,
               alpha_deg: float, mu_w: float) -> np.ndarray | float:
    """The paper's eq. (12) as printed [Pa], with its hopper angle read as alpha, the half-angle
    from the vertical (DESIGN.md section 4; the paper writes one theta for this angle and for
    the hopper slopes of its cases, which the config reads from the horizontal):

    sigma = gamma [(h' - z)/n_i + (q/gamma - h'/n_i) (1 - z/h')^(n_i + 1)],
    n_i = 2 (1 + tan(phi_P)/tan(alpha)) - 3,

    z measured down from the transition, h' the distance from the transition to the apex [m].
    It equals :func:`hopper_sigma_v` with planar=False, D = 1, h = h' - z, H = h'.
    """
    z = np.asarray(z_below_transition, dtype=float)
    n_i = 2.0 * (1.0 + mu_w / math.tan(math.radians(alpha_deg))) - 3.0
    return gamma * ((h_prime - z) / n_i + (q / gamma - h_prime / n_i)
                    * (1.0 - z / h_prime) ** (n_i + 1.0))


def walker_distribution_factor(delta_deg: float, phi_w_deg: float, alpha_deg: float) -> float:
    """Walker's distribution factor D = sigma_n / sigma_v at a hopper wall [-].

    D = (1 + sin(delta) cos(2 omega)) / (1 - sin(delta) cos(2 (alpha + omega))),
    2 omega = phi_w + arcsin(sin(phi_w) / sin(delta)),

    from the Mohr circle of a material at yield (effective angle of internal friction delta) in
    the passive (flowing) state at a wall of friction angle phi_w, with the vertical stress at
    the wall taken as the mean vertical stress (Walker's assumption).  alpha: half-angle from
    the vertical [deg].  For alpha = 0 it is the vertical-wall K of Walker/Nedderman; for a
    vertical smooth wall (alpha = 0 and phi_w = 0) Rankine's passive K =
    (1 + sin delta)/(1 - sin delta).  The passive state only: it is the stress distribution
    of a flowing hopper, not of one being filled.
    Source: Walker (1966); Nedderman (1992), the method of differential slices.
    """
    s = math.sin(math.radians(delta_deg))
    pw = math.radians(phi_w_deg)
    if math.sin(pw) > s:
        raise ValueError("walker_distribution_factor: phi_w must not exceed delta")
    two_omega = pw + math.asin(math.sin(pw) / s)
    a2 = 2.0 * math.radians(alpha_deg)
    return (1.0 + s * math.cos(two_omega)) / (1.0 - s * math.cos(a2 + two_omega))


# --- Beverloo (1961), 2D -------------------------------------------------------------------------


def beverloo_2d(D: float, d: float, rho_b: float, g: float, C: float, k: float,
                thickness: float = 1.0) -> float:
    """Discharge mass flow rate [kg/s] through a slot of width D [m] (2D Beverloo law):

    W = C rho_b sqrt(g) (D - k d)^(3/2) * thickness

    d: grain diameter [m]; C, k: empirical constants [-]; rho_b [kg/m^3]; thickness t [m] of the
    slot (W per unit thickness times t).  Zero when D <= k d.  Source: Beverloo, Leniger & van de
    Velde (1961), Chem. Eng. Sci. 15, 260 (3D form W ~ (D - k d)^(5/2)); Nedderman (1992) ch. 10;
    the 3/2 power of a 2D silo: Janda, Zuriguel & Maza (2012), Phys. Rev. Lett. 108, 248001.
    """
    open_width = max(D - k * d, 0.0)
    return C * rho_b * math.sqrt(g) * open_width**1.5 * thickness


def beverloo_2d_C(rate: float, D: float, d: float, rho_b: float, g: float, k: float,
                  thickness: float = 1.0) -> float:
    """The Beverloo constant C [-] that a measured rate [kg/s] implies for a given k."""
    base = beverloo_2d(D, d, rho_b, g, 1.0, k, thickness)
    return rate / base if base > 0 else float("nan")


@dataclass(frozen=True)
class BeverlooFit:
    """Constants of W = C rho_b sqrt(g) (D - k d)^b t fitted to measured rates, with their
    standard errors (NaN where the fit gives none; 0 for an exponent held at 3/2)."""

    C: float
    k: float
    b: float
    b_err: float
    C_err: float = float("nan")
    k_err: float = float("nan")


def fit_beverloo_free(D: npt.ArrayLike, W: npt.ArrayLike, W_err: npt.ArrayLike, d: float,
                      rho_b: float, g: float, t: float) -> BeverlooFit:
    """C, k and the exponent b free: weighted least squares on ln W (scipy ``curve_fit``,
    sigma = W_err / W, absolute); k is bounded above by 0.95 min(D)/d (so that D - k d > 0 at
    every width).  Needs four outlet widths or
    more (three parameters).  D, W, W_err: arrays [m, kg/s, kg/s]; d [m], rho_b [kg/m^3],
    g [m/s^2], t [m] as in :func:`beverloo_2d`."""

    D, W, W_err = (np.asarray(a, dtype=float) for a in (D, W, W_err))
    scale = rho_b * math.sqrt(g) * t

    def model(x, lnC, k, b):
        return lnC + b * np.log(np.maximum(x - k * d, 1e-12)) + math.log(scale)

    k_max = 0.95 * D.min() / d
    p0 = [math.log(0.6), min(1.0, 0.5 * k_max), 1.5]  # the start inside the bounds
    bounds = ([-10.0, -5.0, 0.5], [10.0, k_max, 3.0])
    popt, pcov = _curve_fit(model, D, np.log(W), p0=p0, sigma=W_err / W, absolute_sigma=True,
                           bounds=bounds, maxfev=20000)
    errs = np.sqrt(np.diag(pcov)) if np.all(np.isfinite(pcov)) else np.full(3, np.nan)
    C = float(math.exp(popt[0]))
    return BeverlooFit(C, float(popt[1]), float(popt[2]), float(errs[2]),
                       C_err=float(C * errs[0]), k_err=float(errs[1]))


def fit_beverloo_three_halves(D: npt.ArrayLike, W: npt.ArrayLike, d: float, rho_b: float,
                              g: float, t: float,
                              W_err: npt.ArrayLike | None = None) -> BeverlooFit:
    """C and k with the exponent held at 3/2: W^(2/3) = (C rho_b sqrt(g) t)^(2/3) (D - k d) is a
    straight line in D (least squares, weighted by the errors of W^(2/3) when ``W_err`` is
    given).  Two outlet widths determine it; the errors of C and k need three or more.
    ValueError when the line does not rise with D: rates that do not grow with the outlet
    follow no Beverloo law."""
    D, W = np.asarray(D, dtype=float), np.asarray(W, dtype=float)
    y = W ** (2.0 / 3.0)
    w = None
    if W_err is not None:
        y_err = (2.0 / 3.0) * y / W * np.asarray(W_err, dtype=float)
        if np.all(y_err > 0):
            w = 1.0 / y_err
    cov = np.full((2, 2), np.nan)
    if w is not None and D.size >= 3:  # the given errors: absolute
        (slope, intercept), cov = np.polyfit(D, y, 1, w=w, cov="unscaled")
    else:
        slope, intercept = np.polyfit(D, y, 1)
        if D.size >= 3:  # errors from the scatter about the line, N - 2 degrees of freedom
            # (written out: numpy's cov=True scaled by N - 4 before numpy 2)
            A = np.column_stack([D, np.ones_like(D)])
            resid = y - (slope * D + intercept)
            cov = np.linalg.inv(A.T @ A) * float(resid @ resid) / (D.size - 2)
    if not slope > 0.0:
        raise ValueError(f"the rates do not grow with the outlet width (W^(2/3) against D has "
                         f"slope {slope:.3g}): no Beverloo law to fit")
    scale = rho_b * math.sqrt(g) * t
    C = slope**1.5 / scale
    k = -intercept / slope / d
    # first-order propagation: C ~ slope^(3/2); k d = -intercept / slope
    C_err = 1.5 * C / abs(slope) * math.sqrt(cov[0, 0])
    dk = np.array([intercept / slope**2, -1.0 / slope]) / d  # d k / d(slope, intercept)
    k_err = math.sqrt(max(float(dk @ cov @ dk), 0.0))
    return BeverlooFit(float(C), float(k), 1.5, 0.0, C_err=float(C_err), k_err=float(k_err))


# --- EN 1991-4:2006 ------------------------------------------------------------------------------


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
