"""The run report: every figure re-rendered from results.h5, and a self-contained report.html.

``write_report(folder)`` reads ``folder/results.h5`` (never re-runs anything), writes the PNG
figures into ``folder/figures/`` and ``folder/report.html`` (figures embedded as base64 PNG,
key numbers, warnings, the config).  ``silodem plot DIR`` calls it; ``silodem run`` too, at the
end of a run.
"""

from __future__ import annotations

from silodem.report.html import write_report

__all__ = ["write_report"]
