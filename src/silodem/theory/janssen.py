"""Janssen (1895) for a 2D slot silo: the mean vertical stress under the free surface, the wall
stresses, and the fit of K (and mu_w) to a measured wall profile (docs/theory.md)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from silodem.theory import _checks as ck
from silodem.theory._fit import curve_fit_quiet


def _check(func: str, rho_b, g, B, K, mu_w) -> None:
    """The material and geometry parameters of Janssen's solution: zero weight (rho_b or g
    0) gives zero stress; mu_w = 0 (smooth walls) is the hydrostatic limit."""
    ck.non_negative(func, "rho_b", rho_b)
    ck.non_negative(func, "g", g)
    ck.positive(func, "B", B)
    ck.positive(func, "K", K)
    ck.non_negative(func, "mu_w", mu_w)


def _loaded_depth(depth, c: float):
    """(1 - exp(-c z)) / c [m] at depth z [m] (z < 0 as 0): the depth of grains whose weight a
    Janssen column bears at z, its walls carrying the rest, for c = K U mu / A [1/m] (the
    inverse of EN 1991-4's z_o); z for c = 0.  Never larger than z: the form rho g / c x
    (1 - exp(-c z)) overflowed for c < ~1e-304."""
    depth = np.maximum(np.asarray(depth, dtype=float), 0.0)
    return depth if c == 0.0 else -np.expm1(-c * depth) / c


def _sigma_v(depth, rho_b, g, B, K, mu_w):
    """:func:`janssen_sigma_v` unchecked (the fits evaluate it within their bounds)."""
    return rho_b * g * _loaded_depth(depth, 2.0 * K * mu_w / B)


def _sigma_h(depth, rho_b, g, B, K, mu_w):
    return K * _sigma_v(depth, rho_b, g, B, K, mu_w)


def janssen_sigma_v(depth: npt.ArrayLike, rho_b: float, g: float, B: float, K: float,
                    mu_w: float) -> np.ndarray | float:
    """Mean vertical stress [Pa] at ``depth`` [m] under the free surface of a 2D slot silo.

    sigma_v = rho_b g B / (2 K mu_w) * (1 - exp(-2 K mu_w depth / B))

    Janssen's slice balance for a slot of width B between two walls (plane strain: hydraulic
    radius A/U = B/2 per unit thickness): d(sigma_v)/dz = rho_b g - 2 K mu_w sigma_v / B.
    rho_b bulk density [kg/m^3], K = sigma_h/sigma_v [-], mu_w wall friction [-].
    Source: Janssen (1895), Z. Ver. Dtsch. Ing. 39; Nedderman (1992) ch. 3 (there in 3D form).
    Depths above the surface (< 0) have no stress; mu_w = 0 gives the hydrostatic
    rho_b g depth.  ValueError unless rho_b, g, mu_w >= 0 and B, K > 0 (finite scalars).
    """
    _check("janssen_sigma_v", rho_b, g, B, K, mu_w)
    return _sigma_v(ck.array("janssen_sigma_v", "depth", depth), rho_b, g, B, K, mu_w)


def janssen_sigma_h(depth: npt.ArrayLike, rho_b: float, g: float, B: float, K: float,
                    mu_w: float) -> np.ndarray | float:
    """Horizontal (wall normal) stress [Pa] of Janssen's solution: sigma_h = K sigma_v."""
    _check("janssen_sigma_h", rho_b, g, B, K, mu_w)
    return _sigma_h(ck.array("janssen_sigma_h", "depth", depth), rho_b, g, B, K, mu_w)


def janssen_wall_shear(depth: npt.ArrayLike, rho_b: float, g: float, B: float, K: float,
                       mu_w: float) -> np.ndarray | float:
    """Wall shear stress [Pa] of Janssen's solution (friction fully mobilised): mu_w K sigma_v."""
    _check("janssen_wall_shear", rho_b, g, B, K, mu_w)
    return mu_w * _sigma_h(ck.array("janssen_wall_shear", "depth", depth), rho_b, g, B, K, mu_w)


@dataclass(frozen=True)
class JanssenFit:
    """Result of :func:`fit_janssen`: K [-], mu_w [-], their standard errors (``mu_w_err`` is 0
    when mu_w was given, not fitted), rms residual [Pa], the number of points fitted and the
    shallowest and deepest of their depths [m] (NaN where not known)."""

    K: float
    mu_w: float
    K_err: float
    mu_w_err: float
    rms: float
    n_points: int
    mu_w_fitted: bool
    depth_min: float = float("nan")
    depth_max: float = float("nan")

    def shallow_to_deep(self, B: float) -> float:
        """sigma_h of the fitted curve at the shallowest fitted depth over that at the deepest
        [-]: (1 - exp(-a z_min)) / (1 - exp(-a z_max)), a = 2 K mu_w / B, B the silo's width
        [m]; z_min / z_max, its limit, where a = 0 (hydrostatic). Near 1: the curve is flat
        over the fitted depths. NaN where the depths are not known."""
        a = 2.0 * self.K * self.mu_w / B
        if a == 0.0:
            return float(self.depth_min / self.depth_max)
        return float(np.expm1(-a * self.depth_min) / np.expm1(-a * self.depth_max))

    @property
    def mu_w_at_bound(self) -> bool:
        """mu_w fitted onto its lower bound (``FIT_LOWER``): the profile is hydrostatic or
        steeper, it shows no wall support; K is then sigma_h / (rho_b g depth)."""
        return self.mu_w_fitted and self.mu_w <= 10 * FIT_LOWER


FIT_LOWER = 1e-6  # lower bound of K and mu_w in fit_janssen [-]


def fit_janssen(depth: npt.ArrayLike, sigma_h: npt.ArrayLike, rho_b: float, g: float, B: float,
                mu_w: float | None = None) -> JanssenFit:
    """Least-squares fit of Janssen's sigma_h(depth) to a measured wall normal stress profile.

    sigma_h = rho_b g B / (2 mu_w) (1 - exp(-2 K mu_w depth / B)): the asymptote gives mu_w, the
    curvature K mu_w.  With ``mu_w`` given (e.g. the mobilised wall friction measured as
    sum(tau)/sum(sigma_n)) only K is fitted.  NaN points and points at depth <= 0 (above the
    free surface) are left out.  Units as in
    :func:`janssen_sigma_v`.  Uses scipy.optimize.curve_fit (trust-region reflective, bounds
    K, mu_w > 0).  ValueError for depth and sigma_h of different shapes, or unless rho_b, g,
    B > 0 and mu_w (when given) >= 0 (finite scalars).
    """
    func = "fit_janssen"
    z, s = ck.array(func, "depth", depth), ck.array(func, "sigma_h", sigma_h)
    ck.same_length(func, ("depth", "sigma_h"), z, s)
    for name, value in (("rho_b", rho_b), ("g", g), ("B", B)):
        ck.positive(func, name, value)
    if mu_w is not None:
        ck.non_negative(func, "mu_w", mu_w)
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
            return _sigma_h(zz, rho_b, g, B, K, mu_w)

        popt, pcov = curve_fit_quiet(model_k, z, s, p0=[k0], bounds=([FIT_LOWER], [50.0]))
        K, mu = float(popt[0]), float(mu_w)
        errs = np.sqrt(np.clip(np.diag(pcov), 0.0, np.inf)) if np.all(np.isfinite(pcov)) else [
            np.nan]
        K_err, mu_err = float(errs[0]), 0.0
    else:
        mu0 = float(np.clip(rho_b * g * B / (2.0 * max(s.max(), 1e-12)), 0.05, 2.0))

        def model(zz, K, mu):
            return _sigma_h(zz, rho_b, g, B, K, mu)

        popt, pcov = curve_fit_quiet(model, z, s, p0=[k0, mu0],
                               bounds=([FIT_LOWER, FIT_LOWER], [50.0, 50.0]), maxfev=20000)
        K, mu = float(popt[0]), float(popt[1])
        if np.all(np.isfinite(pcov)):
            K_err, mu_err = (float(v) for v in np.sqrt(np.clip(np.diag(pcov), 0.0, np.inf)))
        else:
            K_err = mu_err = float("nan")
    resid = s - _sigma_h(z, rho_b, g, B, K, mu)
    return JanssenFit(K, mu, K_err, mu_err, float(np.sqrt(np.mean(resid**2))), int(z.size),
                      mu_w is None, float(z.min()), float(z.max()))
