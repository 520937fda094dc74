"""A least-squares helper shared by the fits of ``janssen`` and ``beverloo``."""

from __future__ import annotations

import numpy as np


def curve_fit_quiet(f, xdata, ydata, **kwargs):
    """scipy.optimize.curve_fit without its OptimizeWarning: when the covariance cannot be
    estimated it comes back infinite and the fits (fit_janssen, fit_beverloo_*) report NaN
    errors, which say so in the result instead of on the user's terminal (a sweep printed the
    warning per run).

    A parameter the data do not determine (the model does not change with it: the Jacobian's
    column is zero, to round-off) gets a variance of 0 from curve_fit's pseudo-inverse, which
    drops that direction; with residuals left over, it is given an infinite variance instead.
    A Janssen K with mu_w = tan 89 deg, whose curve is flat at its asymptote from the first
    bin on, was reported as 1 +- 0 (an audit)."""
    import warnings

    from scipy.optimize import OptimizeWarning, curve_fit

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OptimizeWarning)
        popt, pcov = curve_fit(f, xdata, ydata, **kwargs)
    resid = np.asarray(ydata, dtype=float) - f(xdata, *popt)
    undetermined = np.diag(pcov) == 0.0
    if undetermined.any() and np.any(resid != 0.0):
        pcov = np.array(pcov, dtype=float)
        pcov[undetermined, :] = np.inf
        pcov[:, undetermined] = np.inf
    return popt, pcov
