"""Parametric studies: a grid of runs over a base scenario, on Dask (docs/sweeps.md).

    spec.py     the study file (pydantic model) and the embedded studies
    plan.py     grid expansion, resolved configs, run ids
    execute.py  the Dask task of a run, atomic run folders, resumption
    cluster.py  the local cluster or a scheduler's client, its workers, its shutdown
    table.py    per-run summaries and the results table (CSV)
    report.py   the study report (report.html, figures/)
    beverloo.py the fit of Beverloo's C and k to a grid over the outlet width
    api.py      run_study and finish_study
    worker_setup.py  what each Dask worker does first

``run_study`` does it all: plan, run what is missing, write results.csv and report.html.
"""

from __future__ import annotations

from silodem.study.plan import StudyPlan, expand
from silodem.study.spec import LoadedStudy, list_studies, load_study, study_names, study_text

__all__ = ["LoadedStudy", "StudyPlan", "expand", "finish_study", "list_studies", "load_study",
           "run_study", "study_names", "study_text"]


def __getattr__(name: str):
    """``run_study`` and ``finish_study`` on first use: ``study.api`` imports the run (numba,
    matplotlib), which ``silodem show`` and ``silodem run``'s study check need not load."""
    if name in ("finish_study", "run_study"):
        from silodem.study import api

        return getattr(api, name)
    raise AttributeError(f"module 'silodem.study' has no attribute {name!r}")
