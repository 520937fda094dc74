"""Beverloo (1961) in 2D: the discharge rate of a slot outlet, and its fits to simulated rates
(docs/theory.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from silodem.theory._fit import curve_fit_quiet


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
    popt, pcov = curve_fit_quiet(model, D, np.log(W), p0=p0, sigma=W_err / W, absolute_sigma=True,
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
