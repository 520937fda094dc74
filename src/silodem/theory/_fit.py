"""A least-squares helper shared by the fits of ``janssen`` and ``beverloo``."""

from __future__ import annotations


def curve_fit_quiet(*args, **kwargs):
    """scipy.optimize.curve_fit without its OptimizeWarning: when the covariance cannot be
    estimated it comes back infinite and the fits (fit_janssen, fit_beverloo_*) report NaN
    errors, which say so in the result instead of on the user's terminal (a sweep printed the
    warning per run)."""
    import warnings

    from scipy.optimize import OptimizeWarning, curve_fit

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OptimizeWarning)
        return curve_fit(*args, **kwargs)
