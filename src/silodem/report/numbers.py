"""How the reports write a number: significant digits without an exponent where a reader
expects none (a wall stress of 2053 Pa, not 2.05e+03)."""

from __future__ import annotations

import math


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
