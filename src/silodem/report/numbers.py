"""How the reports write a number: significant digits without an exponent where a reader
expects none (a wall stress of 2053 Pa, not 2.05e+03)."""

from __future__ import annotations

import math

import numpy as np


def significant(value: float | None, digits: int = 3) -> str:
    """``value`` to ``digits`` significant digits, but every integer digit of a value under 1e9
    that would otherwise take an exponent (2053.4 -> '2053', 999.6 -> '1000'); 'n/a' for None,
    NaN or infinity."""
    if value is None:
        return "n/a"
    v = float(value)
    if not math.isfinite(v):
        return "n/a"
    text = f"{v:.{digits}g}"
    if "e" in text and 1.0 <= abs(v) < 1e9:  # 2053.4 -> 2.05e+03, 999.6 -> 1e+03
        return f"{v:.0f}"
    return text


def poorly_determined(value: float, error: float) -> bool:
    """A fitted value whose standard error is over half of it, or not finite: a fit to few or
    noisy points (a Janssen K of 1.29 +- 0.69 from six wall bins) that measures nothing."""
    return not abs(error) <= 0.5 * abs(value)


def pascals(value: float | None) -> str:
    """A stress in whole pascals with thousands separators (20,929), 'n/a' for None or NaN."""
    return f"{value:,.0f}" if value is not None and math.isfinite(value) else "n/a"


def percent_change(before: float, after: float) -> float:
    """100 (after - before) / before [%]; NaN from a zero or non-finite ``before``."""
    return 100.0 * (after - before) / before if before and math.isfinite(before) \
        else float("nan")


def percent_change_error(before: float, before_err: float, after: float,
                         after_err: float) -> float:
    """Standard error [%] of :func:`percent_change` p = 100 (after - before) / before from the
    standard errors of the two values (independent: windows apart in time), by first-order
    propagation: dp = 100 sqrt((after_err / before)^2 + (after before_err / before^2)^2).
    NaN where p is NaN or an error is not finite."""
    if not (before and math.isfinite(before) and math.isfinite(after)):
        return float("nan")
    return 100.0 * math.hypot(after_err / before, after * before_err / before**2)


def resolved(change: float, error: float) -> bool:
    """A change [%] larger than its standard error [%]: one within its error (or without a
    finite error) is not resolved by the run, whichever its sign."""
    return math.isfinite(change) and math.isfinite(error) and abs(change) > error


UNLOADED = 0.1  # samples with sigma_v under this fraction of its median are left out


def loaded(sv: np.ndarray, usable: np.ndarray) -> np.ndarray:
    """The ``usable`` samples whose sigma_v is at least ``UNLOADED`` times the median of the
    usable ones: a ratio sigma_h / sigma_v of two near-zero numbers is noise, not anisotropy
    (a study's CV of the ratio, its Fig. 7 and the run report's Fig. 7 leave the others out,
    ``report.draw.loaded_ratio``)."""
    return usable & (sv >= UNLOADED * float(np.median(sv[usable]))) if usable.any() else usable
