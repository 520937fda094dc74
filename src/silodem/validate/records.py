"""One line of the validation table: a quantity, what theory or a publication expects, what the
simulation gave, and the tolerance that decides whether it passes.

Tolerance kinds:

* ``"rel"``  passes when |got - expected| <= tolerance * |expected|;
* ``"abs"``  passes when |got - expected| <= tolerance (in the record's unit);
* ``"info"`` a number reported, not judged (fitted constants, diagnostics): never fails the
  run (``passed`` is True), and its JSON ``pass`` is null, since nothing was checked.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Record:
    case: str
    quantity: str
    expected: float | None
    got: float | None
    tolerance: float | None
    kind: str = "rel"
    unit: str = "-"
    note: str = ""

    def __post_init__(self) -> None:
        if self.kind not in ("rel", "abs", "info"):
            raise ValueError(f"unknown tolerance kind {self.kind!r}")

    @property
    def passed(self) -> bool:
        if self.kind == "info":
            return True
        if self.got is None or self.expected is None or self.tolerance is None:
            return False
        got, exp = float(self.got), float(self.expected)
        if not (math.isfinite(got) and math.isfinite(exp)):
            return False
        err = abs(got - exp)
        if self.kind == "rel":
            return err <= self.tolerance * abs(exp)
        return err <= self.tolerance

    def to_dict(self) -> dict:
        """JSON-ready: NaN and inf become None; ``pass`` is None for an info record (not
        judged), so that a reader counting passes counts only the checks."""
        def clean(v):
            if v is None:
                return None
            v = float(v)
            return v if math.isfinite(v) else None

        return {"case": self.case, "quantity": self.quantity, "expected": clean(self.expected),
                "got": clean(self.got), "tolerance": clean(self.tolerance),
                "tolerance_kind": self.kind, "unit": self.unit,
                "pass": None if self.kind == "info" else self.passed,
                "note": self.note}


def rel(case: str, quantity: str, expected: float, got: float, tol: float, unit: str = "-",
        note: str = "") -> Record:
    return Record(case, quantity, float(expected), float(got), tol, "rel", unit, note)


def absolute(case: str, quantity: str, expected: float, got: float, tol: float,
             unit: str = "-", note: str = "") -> Record:
    return Record(case, quantity, float(expected), float(got), tol, "abs", unit, note)


def info(case: str, quantity: str, got: float, unit: str = "-", note: str = "",
         expected: float | None = None) -> Record:
    return Record(case, quantity, expected, float(got), None, "info", unit, note)
