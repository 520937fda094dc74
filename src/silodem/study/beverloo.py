"""Beverloo's law fitted to a study's discharge rates (DESIGN: fitting C, k from simulations).

A study whose grid varies the outlet width ``silo.outlet_width`` over three values or more gets,
for each combination of its other grid values, the constants of the 2D law (docs/theory.md)

    W = C rho_b sqrt(g) (D - k d)^b t

with b held at 3/2 (``theory.fit_beverloo_three_halves``) and, from four widths on, b free
too (``theory.fit_beverloo_free``).  Per width: W is the mean of the seeds' steady rates
(results.csv ``discharge_rate``) and its error the larger of their combined standard errors
and the seeds' standard error of the mean (as ``validate.beverloo``); rho_b is the mean bulk
density of the group's settled packings (``bulk_density``), d the config's mean grain diameter
2<r> by number (``regions.mean_diameter``: r_min + r_max for the default uniform radii), t
its thickness and g its gravity.  Runs without a rate (a clog,
a discharge too short to measure) are left out of W, and so is a width left with no run; the
notes say which, and why a case has no fit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from silodem import theory as th
from silodem.measure.discharge import mean_of_runs
from silodem.measure.regions import mean_diameter
from silodem.report.draw import tight_layout
from silodem.study.plan import (
    PlannedRun,
    StudyPlan,
    format_value,
    key_unit,
    nicknames,
    value_label,
)
from silodem.study.table import as_float

OUTLET = "silo.outlet_width"
MIN_WIDTHS = 3  # for C and k with b = 3/2 and their errors
MIN_WIDTHS_FREE = 4  # for C, k and b


@dataclass
class OutletFit:
    """The fit of one combination of the other grid values (``label``; "all" if none)."""

    label: str
    D: np.ndarray  # outlet widths with a rate [m]
    W: np.ndarray  # mean steady rate at each [kg/s]
    W_err: np.ndarray  # its standard error [kg/s]
    n_runs: int  # runs behind the means
    left_out: list[float]  # outlet widths of the grid without a rate [m]
    rho_b: float  # [kg/m^3]
    d: float  # mean grain diameter [m]
    t: float  # thickness [m]
    g: float  # [m/s^2]
    fixed: th.BeverlooFit  # b = 3/2
    free: th.BeverlooFit | None  # b fitted too (None under MIN_WIDTHS_FREE widths)


def _fit_group(label: str, runs: list[PlannedRun],
               rows_by_id: dict[str, dict[str, Any]]) -> tuple[OutletFit | None, str]:
    """The fit of one case, or None; and a note on what was left out or why there is no fit."""
    by_width: dict[float, list[tuple[float, float]]] = {}
    rhos = []  # every settled packing counts, whatever happened at the outlet
    widths = sorted({float(run.cfg.silo.outlet_width) for run in runs})
    for run in runs:
        row = rows_by_id.get(run.id)
        if row is None:
            continue
        W, err, rho = (as_float(row.get(k)) for k in ("discharge_rate", "discharge_rate_err",
                                                     "bulk_density"))
        if math.isfinite(rho):
            rhos.append(rho)
        if math.isfinite(W) and W > 0:
            by_width.setdefault(float(run.cfg.silo.outlet_width), []).append((W, err))
    left_out = [x for x in widths if x not in by_width]
    note = (f"{label}: no steady rate at D = {', '.join(f'{x:g}' for x in left_out)} m "
            "(clogged, too short, or not finished)" if left_out else "")
    if len(by_width) < MIN_WIDTHS or not rhos:
        return None, (f"{label}: no fit, {len(by_width)} outlet width(s) with a steady rate, "
                      f"{MIN_WIDTHS} needed" + (f"; {note.split(': ', 1)[1]}" if note else ""))
    D = np.array(sorted(by_width))
    means = [mean_of_runs(np.array([w for w, _ in by_width[x]]),
                        np.array([e for _, e in by_width[x]])) for x in D]
    W = np.array([m for m, _ in means])
    W_err = np.array([e for _, e in means])
    rho_b = float(np.mean(rhos))
    cfg = runs[0].cfg
    d = mean_diameter(cfg)
    t, g = cfg.material.thickness, cfg.gravity
    errors = W_err if np.all(W_err > 0) else None
    try:
        fixed = th.fit_beverloo_three_halves(D, W, d, rho_b, g, t, W_err=errors)
    except ValueError as exc:  # rates that do not grow with D
        return None, f"{label}: no fit, {exc}" + (f"; {note.split(': ', 1)[1]}" if note else "")
    free = None
    if D.size >= MIN_WIDTHS_FREE and errors is not None:
        try:
            free = th.fit_beverloo_free(D, W, W_err, d, rho_b, g, t)
        except (RuntimeError, ValueError):  # no convergence, or widths under k d
            free = None
    n = sum(len(v) for v in by_width.values())
    return OutletFit(label, D, W, W_err, n, left_out, rho_b, d, t, g, fixed, free), note


def outlet_fits(plan: StudyPlan, rows_by_id: dict[str, dict[str, Any]]
                ) -> tuple[list[OutletFit], list[str]]:
    """One fit per combination of the grid values other than the outlet width (runs grouped by
    them), and notes: widths left out, cases without a fit.  No fit and no note when the grid
    does not vary ``silo.outlet_width``; a note when it does over fewer than MIN_WIDTHS."""
    grid = plan.study.spec.grid
    if OUTLET not in grid:
        return [], []
    if len(set(grid[OUTLET])) < MIN_WIDTHS:
        count = len(set(grid[OUTLET]))
        return [], [f"no Beverloo fit: the grid has {count} outlet width(s), {MIN_WIDTHS} needed"]
    others = [k for k in grid if k != OUTLET]
    names = nicknames(list(grid))
    groups: dict[tuple, list[PlannedRun]] = {}
    for run in plan.runs:
        groups.setdefault(tuple(format_value(run.point[k]) for k in others), []).append(run)
    fits, notes = [], []
    for runs in groups.values():
        label = ", ".join(value_label(names[k], key_unit(k), runs[0].point[k])
                          for k in others) or "all"
        fit, note = _fit_group(label, runs, rows_by_id)
        if fit is not None:
            fits.append(fit)
        if note:
            notes.append(note)
    return fits, notes


FIT_COLUMNS: list[tuple[str, str, str]] = [
    ("group", "", "the other grid values"),
    ("widths", "-", "outlet widths with a rate"),
    ("runs", "-", "runs behind the rates"),
    ("D_min", "m", "smallest outlet width"),
    ("D_max", "m", "largest outlet width"),
    ("bulk_density", "kg/m^3", "mean bulk density rho_b of the case's settled packings"),
    ("grain_diameter", "m", "mean grain diameter d = 2<r> by number"),
    ("C", "-", "Beverloo constant C with b = 3/2"),
    ("C_err", "-", "its standard error"),
    ("k", "-", "k with b = 3/2 (D - k d is the open width)"),
    ("k_err", "-", "its standard error"),
    ("C_free", "-", "C with b free (from four widths on)"),
    ("k_free", "-", "k with b free"),
    ("b_free", "-", "the exponent b fitted (2D Beverloo: 3/2)"),
    ("b_free_err", "-", "its standard error"),
]


def fit_rows(fits: list[OutletFit]) -> list[dict[str, Any]]:
    """The values of :data:`FIT_COLUMNS` per fit."""
    rows = []
    for f in fits:
        free = f.free
        rows.append({
            "group": f.label, "widths": int(f.D.size), "runs": f.n_runs,
            "D_min": float(f.D.min()), "D_max": float(f.D.max()), "bulk_density": f.rho_b,
            "grain_diameter": f.d, "C": f.fixed.C, "C_err": f.fixed.C_err, "k": f.fixed.k,
            "k_err": f.fixed.k_err,
            "C_free": free.C if free else math.nan, "k_free": free.k if free else math.nan,
            "b_free": free.b if free else math.nan, "b_free_err": free.b_err if free else math.nan,
        })
    return rows


def fig_beverloo(fits: list[OutletFit]) -> Figure | None:
    """W^(2/3) against D for every group: the measured means (error bars) and the fitted
    straight line of the 3/2 law, whose intercept with the axis is k d."""
    if not fits:
        return None
    fig = Figure(figsize=(8, 5.2), dpi=100)
    ax = fig.subplots()
    for f in fits:
        y = f.W ** (2.0 / 3.0)
        y_err = (2.0 / 3.0) * y / f.W * f.W_err
        line = ax.errorbar(f.D, y, yerr=y_err, fmt="o", ms=4, capsize=2,
                           label=f"{f.label}: C = {f.fixed.C:.3g}, k = {f.fixed.k:.3g}")
        # the fitted line itself, (C rho_b sqrt(g) t)^(2/3) (D - k d), from D = max(k d, 0):
        # a fit may give k <= 0 (rates ~ D^(3/2) give k ~ 0 in round-off), where the law's
        # own beverloo_2d refuses D = 0
        x = np.linspace(max(f.fixed.k * f.d, 0.0), f.D.max() * 1.05, 50)
        slope = (f.fixed.C * f.rho_b * math.sqrt(f.g) * f.t) ** (2.0 / 3.0)
        ax.plot(x, slope * (x - f.fixed.k * f.d), color=line[0].get_color(), lw=1.0)
    ax.set_xlim(left=0.0)
    ax.set_ylim(bottom=0.0)
    ax.set_xlabel("outlet width D [m]")
    ax.set_ylabel("W^(2/3) [(kg/s)^(2/3)]")
    ax.set_title("Beverloo: W = C rho_b sqrt(g) (D - k d)^(3/2) t is a straight line here",
                 fontsize=10)
    ax.legend(fontsize=8)
    tight_layout(fig)
    return fig
