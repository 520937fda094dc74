"""Beverloo (1961) in 2D: the discharge rate of a slot outlet, and its fits to simulated rates
(docs/theory.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from silodem.theory import _checks as ck
from silodem.theory._fit import curve_fit_quiet


def beverloo_2d(D: float, d: float, rho_b: float, g: float, C: float, k: float,
                thickness: float = 1.0) -> float:
    """Discharge mass flow rate [kg/s] through a slot of width D [m] (2D Beverloo law):

    W = C rho_b sqrt(g) (D - k d)^(3/2) * thickness

    d: grain diameter [m]; C, k: empirical constants [-]; rho_b [kg/m^3]; thickness t [m] of the
    slot (W per unit thickness times t).  Zero when D <= k d.  Source: Beverloo, Leniger & van de
    Velde (1961), Chem. Eng. Sci. 15, 260 (3D form W ~ (D - k d)^(5/2)); Nedderman (1992) ch. 10;
    the 3/2 power of a 2D silo: Janda, Zuriguel & Maza (2012), Phys. Rev. Lett. 108, 248001.
    ValueError unless D, d, C, thickness > 0, rho_b, g >= 0 and k finite (scalars all; a fit
    may give k < 0).
    """
    _check_law("beverloo_2d", D, d, rho_b, g, k, thickness)
    ck.positive("beverloo_2d", "C", C)
    return _rate(D, d, rho_b, g, C, k, thickness)


def _check_law(func: str, D, d, rho_b, g, k, thickness) -> None:
    ck.positive(func, "D", D)
    ck.positive(func, "d", d)
    ck.non_negative(func, "rho_b", rho_b)
    ck.non_negative(func, "g", g)
    ck.number(func, "k", k)
    ck.positive(func, "thickness", thickness)


def _rate(D, d, rho_b, g, C, k, thickness) -> float:
    open_width = max(D - k * d, 0.0)
    return C * rho_b * math.sqrt(g) * open_width**1.5 * thickness


def beverloo_2d_C(rate: float, D: float, d: float, rho_b: float, g: float, k: float,
                  thickness: float = 1.0) -> float:
    """The Beverloo constant C [-] that a measured rate [kg/s] implies for a given k; NaN where
    the law gives no flow (D <= k d, or rho_b or g 0).  ValueError unless the rate is finite
    (of either sign: a measured rate may be) and the conditions of :func:`beverloo_2d`."""
    ck.number("beverloo_2d_C", "rate", rate)
    _check_law("beverloo_2d_C", D, d, rho_b, g, k, thickness)
    base = _rate(D, d, rho_b, g, 1.0, k, thickness)
    return rate / base if base > 0 else float("nan")


def beverloo_narrow_widths(B: float, D: float, d: float) -> list[tuple[str, float]]:
    """The widths [m] that a silo of width B [m] is narrower than, of the two from which the
    rate through its outlet D [m] of grains of diameter d [m] no longer depends on the width:
    ("2.5 D", 2.5 D) and ("D + 30 d", D + 30 d), each listed when B is under it, so that [] is
    a silo wide enough for Beverloo's law.  Source: Nedderman (1992), as Mankoc et al. (2007),
    Granular Matter 9, 407, quote it.  ValueError unless B, D, d > 0."""
    for name, value in (("B", B), ("D", D), ("d", d)):
        ck.positive("beverloo_narrow_widths", name, value)
    return [(what, need) for what, need in (("2.5 D", 2.5 * D), ("D + 30 d", D + 30.0 * d))
            if B < need]


def _check_data(func: str, min_widths: int, fitted: str, D, W, W_err, d, rho_b, g,
                t) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The data of a fit as float arrays of one length, every value finite and > 0 (W_err may
    be None), at least ``min_widths`` distinct widths; the constants finite and > 0."""
    arrays = {"D": D, "W": W} | ({} if W_err is None else {"W_err": W_err})
    arrays = {name: ck.array(func, name, v, vector=True) for name, v in arrays.items()}
    ck.same_length(func, tuple(arrays), *arrays.values())
    for name, a in arrays.items():
        ck.positive_values(func, name, a)
    widths = np.unique(arrays["D"]).size
    if widths < min_widths:
        raise ValueError(f"{func}: D must hold at least {min_widths} distinct outlet widths to "
                         f"fit {fitted}; got {widths}")
    for name, value in (("d", d), ("rho_b", rho_b), ("g", g), ("t", t)):
        ck.positive(func, name, value)
    return arrays["D"], arrays["W"], arrays.get("W_err")


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
    every width).  Needs four distinct outlet widths or
    more (three parameters).  D, W, W_err: arrays [m, kg/s, kg/s]; d [m], rho_b [kg/m^3],
    g [m/s^2], t [m] as in :func:`beverloo_2d`.  ValueError for fewer widths, arrays of
    different lengths, values of D, W or W_err that are not finite and > 0, or d, rho_b, g,
    t not > 0."""
    if W_err is None:
        ck.fail("fit_beverloo_free", "W_err", "an array of the rates' errors", W_err)
    D, W, W_err = _check_data("fit_beverloo_free", 4, "C, k and b", D, W, W_err, d, rho_b, g, t)
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
    Without ``W_err`` they come from the scatter about the line, which assumes the same noise
    in every W^(2/3): for rates whose relative errors are alike (2 % at each of six widths, a
    Monte Carlo of 2000 fits) the error of C comes out a third too small, so give ``W_err``
    where the rates have errors (``study.beverloo`` does; ``silodem validate`` reports C and
    k without errors).
    ValueError when the line does not rise with D: rates that do not grow with the outlet
    follow no Beverloo law; and for fewer than two distinct widths, arrays of different
    lengths, values of D, W or W_err that are not finite and > 0, or d, rho_b, g, t not > 0."""
    D, W, W_err = _check_data("fit_beverloo_three_halves", 2, "C and k", D, W, W_err, d, rho_b,
                              g, t)
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
