"""The validation suite (``silodem validate``): the physics checked against analytic solutions
and published results.  See docs/validation.md and :mod:`silodem.validate.runner`."""

from silodem.validate.records import Record
from silodem.validate.runner import Validation, run_validation

__all__ = ["Record", "Validation", "run_validation"]
