"""Argument checks of the theory functions: a one-line ValueError that names the function, the
argument as the caller wrote it, what it must be, and the value got, e.g.
``janssen_sigma_v: B must be a positive finite number; got 0.0``.

Numbers: Python ints and floats, NumPy integer and float scalars (and 0-d arrays of them);
never a bool, a string or an array where the docstring asks for a scalar.  Flags: True or
False only (a bool or a NumPy bool)."""

from __future__ import annotations

import math
import numbers
import reprlib

import numpy as np

_repr = reprlib.Repr()
_repr.maxstring = _repr.maxother = 40


def _is_real(value) -> bool:
    if isinstance(value, (bool, np.bool_)):
        return False
    if isinstance(value, np.ndarray):
        return value.ndim == 0 and value.dtype.kind in "iuf"
    return isinstance(value, numbers.Real)


def show(value) -> str:
    """The value got, short and on one line."""
    if isinstance(value, np.ndarray) and value.ndim > 0:
        return f"an array of shape {value.shape}"
    if isinstance(value, (list, tuple)):
        return f"a {type(value).__name__} of length {len(value)}"
    if _is_real(value):
        return str(int(value)) if isinstance(value, numbers.Integral) else repr(float(value))
    return _repr.repr(value)


def fail(func: str, name: str, must: str, value) -> None:
    """Raise the one-line ValueError: '<func>: <name> must be <must>; got <value>'."""
    raise ValueError(f"{func}: {name} must be {must}; got {show(value)}")


def number(func: str, name: str, value) -> None:
    """A finite real scalar (any sign)."""
    if not (_is_real(value) and math.isfinite(value)):
        fail(func, name, "a finite number", value)


def positive(func: str, name: str, value) -> None:
    """A finite real scalar > 0."""
    if not (_is_real(value) and math.isfinite(value) and value > 0):
        fail(func, name, "a positive finite number", value)


def non_negative(func: str, name: str, value) -> None:
    """A finite real scalar >= 0."""
    if not (_is_real(value) and math.isfinite(value) and value >= 0):
        fail(func, name, "a finite number >= 0", value)


def between(func: str, name: str, value, lo: float, hi: float, *, lo_in: bool = False,
            hi_in: bool = False) -> None:
    """A finite real scalar in the interval from lo to hi, each end open unless ``*_in``."""
    ok = _is_real(value) and math.isfinite(value) and (
        (value >= lo if lo_in else value > lo) and (value <= hi if hi_in else value < hi))
    if not ok:
        interval = f"{'[' if lo_in else '('}{lo:g}, {hi:g}{']' if hi_in else ')'}"
        fail(func, name, f"a finite number in {interval}", value)


def flag(func: str, name: str, value) -> None:
    """True or False (a bool or a NumPy bool), nothing else: 'no' or 0 are refused."""
    if not isinstance(value, (bool, np.bool_)):
        fail(func, name, "True or False", value)


def array(func: str, name: str, value, *, vector: bool = False) -> np.ndarray:
    """``value`` as a float array: numbers, or an array (list) of them; with ``vector`` a 1-D
    array.  NaN and inf pass (the callers decide what they mean)."""
    a = np.asarray(value)
    if a.dtype.kind not in "iuf":  # strings, None, bools, objects, complex numbers
        fail(func, name, "a number or an array of numbers", value)
    if vector and a.ndim != 1:
        fail(func, name, "a 1-D array of numbers", value)
    return np.asarray(a, dtype=float)


def within(func: str, name: str, values: np.ndarray, lo: float, hi: float,
           hi_name: str) -> None:
    """Every one of ``values`` finite and in [lo, hi], hi being the argument ``hi_name``."""
    bad = ~((values >= lo) & (values <= hi))
    if bad.any():
        fail(func, name, f"within [{lo:g}, {hi_name} = {show(hi)}] (every value)",
             values[bad].flat[0])


def positive_values(func: str, name: str, values: np.ndarray) -> None:
    """Every one of ``values`` finite and > 0."""
    bad = ~(np.isfinite(values) & (values > 0))
    if bad.any():
        fail(func, name, "finite and > 0 (every value)", values[bad].flat[0])


def same_length(func: str, names: tuple[str, ...], *arrays: np.ndarray) -> None:
    """Arrays of one shape: "<func>: D and W must have the same length; got 5 and 4"."""
    if len({a.shape for a in arrays}) > 1:
        got = [str(a.size) if a.ndim == 1 else f"shape {a.shape}" for a in arrays]
        raise ValueError(f"{func}: {_and(names)} must have the same length; got {_and(got)}")


def _and(words) -> str:
    return ", ".join(words[:-1]) + " and " + words[-1]
