"""The study report: DIR/report.html (self-contained, figures as base64 PNG) and DIR/figures/.

Layout of the figures: the first grid key gives the rows of the panel grids and heat maps and
the groups of the bar charts; the combinations of the other keys give the columns / bars.  For
the paper's study: rows = hopper slope theta, columns = (phi_G, phi_P).  Values are means over
the seeds (bars carry the standard deviation over the seeds when there are several); the time
series are those of the first seed.
"""

from __future__ import annotations

import html
import itertools
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import matplotlib

matplotlib.use("Agg")
import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from silodem import __version__
from silodem.atomic import write_atomic
from silodem.report.draw import (
    loaded_ratio,
    png_bytes,
    ratio_axis,
    rolling_mean,
    shade_phases,
    tight_layout,
)
from silodem.report.html import PAGE_CSS, figure_html, html_table, page_head, quick_caveat
from silodem.report.numbers import UNLOADED, poorly_determined, significant
from silodem.study.beverloo import FIT_COLUMNS, fig_beverloo, fit_rows, outlet_fits
from silodem.study.plan import (
    PlannedRun,
    StudyPlan,
    format_value,
    key_unit,
    nicknames,
    value_label,
)
from silodem.study.table import (
    CIRCLE_QUANTITIES,
    COLUMNS,
    SwitchSeries,
    as_float,
    switch_series,
    table_csv,
)

# the Runs table: one line per run (its name wrapped over five lines in the column the ten
# numbers left it), a smaller font, and a scroll bar when it is wider than the page; in print
# (paper does not scroll: its right-hand columns were cut off) its cells wrap
STUDY_CSS = """
.wide{overflow-x:auto;margin:.5em 0}table.runs{margin:0}table.runs td,table.runs th{
font-size:.8em;padding:3px 5px}table.runs td{white-space:nowrap}table.runs td.warn{
white-space:normal}
@media print{.wide{overflow:visible}table.runs{width:100%;table-layout:fixed}table.runs td,
table.runs th{white-space:normal;overflow-wrap:anywhere;font-size:.7em}}
"""
BEVERLOO_CSV = "beverloo.csv"  # the Beverloo fits, when the grid varies the outlet width
CV_ANISOTROPIC = 0.5  # ratio CV during discharge above this: 'anisotropic' (our judgement)


def regime(cv: float) -> str:
    """The paper's reading of the ratio sigma_h / sigma_v at the switch zone (section 6): a
    steady ratio means continuum-like behaviour, large fluctuations an anisotropic stress field."""
    if cv is None or not math.isfinite(cv):
        return "n/a"
    return "anisotropic" if cv > CV_ANISOTROPIC else "continuum-like"


@dataclass
class Layout:
    row_key: str
    rows: list[Any]  # values of the first grid key
    cols: list[dict[str, Any]]  # combinations of the other keys
    names: dict[str, str]  # key -> short name
    units: dict[str, str] = field(default_factory=dict)  # key -> its unit ("": none)

    def value_label(self, key: str, value: Any) -> str:
        """'theta=35 deg': the key's short name, the value and its unit (a number's only)."""
        return value_label(self.names[key], self.units.get(key, ""), value)

    def col_label(self, col: dict[str, Any]) -> str:
        return ", ".join(self.value_label(k, v) for k, v in col.items()) or "all"

    def row_label(self, value: Any) -> str:
        return self.value_label(self.row_key, value)


def layout_of(plan: StudyPlan) -> Layout:
    grid = plan.study.spec.grid
    keys = list(grid)
    rest = keys[1:]
    cols = [dict(zip(rest, vals)) for vals in itertools.product(*(grid[k] for k in rest))]
    return Layout(keys[0], list(grid[keys[0]]), cols, nicknames(keys),
                  {k: key_unit(k) for k in keys})


def _runs_at(plan: StudyPlan, lay: Layout, row: Any, col: dict[str, Any]) -> list[PlannedRun]:
    point = {lay.row_key: row, **col}
    return [r for r in plan.runs if all(r.point[k] == v for k, v in point.items())]


def _values(rows_by_id: dict[str, dict], runs: list[PlannedRun], column: str) -> np.ndarray:
    rows = (rows_by_id.get(r.id) for r in runs)
    return np.array([as_float(row.get(column)) for row in rows if row is not None], dtype=float)


def _mean_std(v: np.ndarray) -> tuple[float, float]:
    v = v[np.isfinite(v)]
    if v.size == 0:
        return math.nan, math.nan
    return float(v.mean()), float(v.std(ddof=1)) if v.size > 1 else 0.0


# --- figures ---------------------------------------------------------------------------------


def _quick_silo(plan: StudyPlan) -> str:
    """What --quick ran: the shrunk cell width, wall height and grain count (each value the
    runs have), which the set and grid values above do not show."""
    def values(get) -> str:
        return " or ".join(format_value(v) for v in sorted({get(r.cfg) for r in plan.runs}))

    return (f"yes: cell width B = {values(lambda c: c.silo.cell_width)} m, wall height "
            f"{values(lambda c: c.silo.wall_height)} m, outlet D = "
            f"{values(lambda c: c.silo.outlet_width)} m, "
            f"{values(lambda c: c.fill.n_particles)} grains (the set and grid values above "
            "are those before --quick shrinks them)")


def _switch_series(folder: Path | None) -> SwitchSeries | None:
    """The run's switch-zone series, None without a run or a readable results.h5 (a damaged
    one is named in the run's summary_error; the other panels are still drawn)."""
    if folder is None or not (folder / "results.h5").is_file():
        return None
    try:
        return switch_series(folder)
    except (OSError, KeyError, ValueError):  # h5py: not an HDF5 file, a dataset missing
        return None


def fig_evolution(plan: StudyPlan, out_dir: Path, lay: Layout, ratio: bool) -> Figure | None:
    """Fig. 7 for every case: switch-zone sigma_h and sigma_v (or their ratio) against time."""
    nr, nc = len(lay.rows), len(lay.cols)
    # wide enough for the title and the one-line legend above the panels, even for one column
    fig = Figure(figsize=(max(2.9 * nc + 1.0, 7.5), 2.3 * nr + 1.2), dpi=90)
    # the stresses on one scale across the cases, so that a taller trace is a larger stress
    axes = np.atleast_2d(fig.subplots(nr, nc, squeeze=False, sharex=True, sharey=not ratio))
    drawn, top = 0, 0.0
    for i, row in enumerate(lay.rows):
        for j, col in enumerate(lay.cols):
            ax = axes[i, j]
            runs = _runs_at(plan, lay, row, col)
            folder = out_dir / "runs" / runs[0].id if runs else None
            s = _switch_series(folder)
            if i == 0:
                ax.set_title(lay.col_label(col), fontsize=8)
            if j == 0:
                ax.set_ylabel(lay.row_label(row) + ("\nsigma_h/sigma_v [-]" if ratio
                                                    else "\nstress [kPa]"), fontsize=8)
            ax.tick_params(labelsize=7)
            if s is None or s.time.size == 0:
                ax.text(0.5, 0.5, "no result", ha="center", va="center", transform=ax.transAxes,
                        fontsize=8, color="0.5")
                continue
            shade_phases(ax, s.time, s.phase)
            n = max(1, round(0.2 / max(float(np.median(np.diff(s.time))), 1e-9))) \
                if s.time.size > 1 else 1
            if ratio:
                r = loaded_ratio(s.sigma_h, s.sigma_v)
                ax.plot(s.time, r, color="#7f7f7f", lw=0.5)
                ax.plot(s.time, rolling_mean(r, n), color="k", lw=1.2)
                ratio_axis(ax, r)
            else:
                for values, color, ls, label in ((s.sigma_h, "#1f77b4", "-", "sigma_h"),
                                                 (s.sigma_v, "#ff7f0e", "--", "sigma_v")):
                    kpa = rolling_mean(values, n) / 1e3
                    ax.plot(s.time, kpa, color=color, lw=1.2, ls=ls, label=label)
                    top = np.nanmax(kpa, initial=top)
            drawn += 1
    if not drawn:
        return None
    if not ratio and top > 0:  # the shared scale, from 0 to the largest trace of all
        axes[0, 0].set_ylim(0.0, 1.05 * top)
    for ax in axes[-1, :]:
        ax.set_xlabel("time [s]", fontsize=8)
    handles, labels = [], []
    for ax in axes.ravel():  # one legend for the figure: phases (and the two stresses)
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    what = (f"ratio sigma_h / sigma_v (grey: samples, black: 0.2 s running mean;\nsamples "
            f"with sigma_v under {UNLOADED:g} x its median left out, as in the CV)" if ratio
            else "horizontal and vertical stress, 0.2 s running mean")
    fig.suptitle(f"Switch zone: {what}", fontsize=9, x=0.02, y=0.995, ha="left", va="top")
    extra = 0.15 * what.count("\n")  # a second title line [in] (the whole caption showed
    # in no figure width: it ran past the right edge)
    top = 1.0 - (0.55 + extra) / fig.get_figheight()  # room for the title and the legend
    tight_layout(fig, rect=(0, 0, 1, top))
    if handles:
        fig.legend(handles, labels, loc="upper left", bbox_to_anchor=(0.02, 1.0 - (0.25 + extra)
                   / fig.get_figheight()), ncol=len(labels), fontsize=7, frameon=False)
    return fig


def fig_change(plan: StudyPlan, rows_by_id: dict, lay: Layout) -> Figure | None:
    """Fig. 8a/8b: percentage change of sigma_h and sigma_v at the switch zone from filling to
    discharge, bars grouped by the first grid key (hopper slope), one bar per friction pair."""
    fig = Figure(figsize=(max(7.0, 1.6 * len(lay.rows) * max(1, len(lay.cols)) / 3 + 4), 7.5),
                 dpi=90)
    axes = fig.subplots(2, 1, sharex=True)
    x = np.arange(len(lay.rows))
    width = 0.8 / max(1, len(lay.cols))
    colors = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
              "#7f7f7f", "#bcbd22", "#17becf"]
    any_value = False
    for ax, comp, title in ((axes[0], "switch_sigma_h_change_pct", "(a) horizontal stress"),
                            (axes[1], "switch_sigma_v_change_pct", "(b) vertical stress")):
        for j, col in enumerate(lay.cols):
            means, errs = [], []
            for row in lay.rows:
                m, s = _mean_std(_values(rows_by_id, _runs_at(plan, lay, row, col), comp))
                means.append(m)
                errs.append(s)
            any_value |= bool(np.isfinite(means).any())
            ax.bar(x - 0.4 + width * (j + 0.5), means, width, yerr=errs if len(
                plan.study.spec.seeds) > 1 else None, color=colors[j % len(colors)],
                label=lay.col_label(col), capsize=2)
        ax.axhline(0, color="k", lw=0.8)
        ax.set_ylabel("change, discharge vs filling [%]", fontsize=9)
        ax.set_title(f"{title} at the switch zone", fontsize=10)
    if not any_value:
        return None
    axes[1].set_xticks(x, [lay.row_label(r) for r in lay.rows])
    axes[0].legend(fontsize=8, ncol=2)
    tight_layout(fig)
    return fig


class HeatMap(NamedTuple):
    """One heat map of the study report: a column of results.csv over the grid."""

    column: str  # results.csv's column (its unit in COLUMNS)
    title: str  # what it is, with its unit
    signed: bool  # below 0 by its definition: a two-sided map centred on 0 (SIGNED_CMAP)
    cmap: str = "viridis"  # the one-way map of a quantity that is not signed
    shares: str = ""  # maps with the same (non-empty) key, side by side, share one colour range


SIGNED_CMAP = "RdBu_r"  # white at 0, red above, blue below
HEATMAPS = [
    HeatMap("switch_sigma_h_change_pct", "change of sigma_h [%]", True, shares="change"),
    HeatMap("switch_sigma_v_change_pct", "change of sigma_v [%]", True, shares="change"),
    # one-sided: compressive (positive) stresses and their ratio, a CV, a fitted K (bounded
    # above 0), a mass rate, a contact count
    HeatMap("switch_ratio_discharge", "sigma_h / sigma_v, discharge [-]", False),
    HeatMap("switch_ratio_cv_discharge", "CV of sigma_h / sigma_v, discharge [-]", False,
            "magma_r"),
    HeatMap("wall_peak_fill", "wall peak in the switch zone, after filling [Pa]", False,
            shares="peak"),
    HeatMap("wall_peak_discharge", "wall peak in the switch zone, discharge [Pa]", False,
            shares="peak"),
    HeatMap("janssen_K_fill", "Janssen K after filling (mu_w = tan phi_P) [-]", False),
    # signed: sum(tau) / sum(sigma_n) on the walls, below 0 where they push the grains up
    HeatMap("wall_friction_mobilised_fill", "mobilised wall friction after filling [-]", True),
    HeatMap("discharge_rate", "discharge rate [kg/s]", False),
    # one-sided: a ratio of two downward speeds, from 0 (the wall grains stand still: funnel
    # flow) up to about 1 (mass flow); the threshold between them, 0.3, is not its middle
    HeatMap("mass_flow_index", "mass flow index v_wall / v_axis [-]", False),
    HeatMap("coordination_discharge", "coordination number at the junction, discharge [-]",
            False),
]
# heat maps whose cells are starred where a run's fit is poorly determined: value -> its error
FIT_ERRORS = {"janssen_K_fill": "janssen_K_fill_err"}
# heat maps whose cells are hatched where a run's value is flagged as the run report flags it
# (silodem.report.flags): value -> (its flag column of results.csv, the caption line)
FLAGS = {
    "janssen_K_fill": ("janssen_K_fill_above_1", (
        "hatched: a run's K is above 1 by more than its error (no fill at rest)")),
    "wall_friction_mobilised_fill": ("wall_friction_negative_fill", (
        "hatched: a run's friction is below 0: the walls carry none of the weight")),
}
FLAG_HATCHES = (("//", "k"), ("\\\\", "w"))  # crossed black and white: seen on any colour


def flag_set(value: Any) -> bool:
    """A flag cell of a summary or of results.csv as a bool: True for true (a summary's) or
    "true" (results.csv's text); False for anything else (false, empty, a row written before
    the column existed)."""
    return value is True or (isinstance(value, str) and value.strip().lower() == "true")


def _flagged(rows_by_id: dict, runs: list[PlannedRun], column: str) -> bool:
    """Whether any run of ``runs`` has ``column``'s flag (``FLAGS[column]``) set."""
    flag = FLAGS[column][0]
    return any(flag_set(rows_by_id.get(run.id, {}).get(flag)) for run in runs)


def _poorly_fitted(rows_by_id: dict, runs: list[PlannedRun], column: str) -> bool:
    """Whether any run of ``runs`` has a finite ``column`` whose standard error (the column
    ``FIT_ERRORS[column]``) is over half of it or not finite, as the run report says of K.
    A row written before the error column existed is not starred."""
    for run in runs:
        row = rows_by_id.get(run.id)
        if row is None or FIT_ERRORS[column] not in row:
            continue
        value = as_float(row.get(column))
        if math.isfinite(value) and poorly_determined(value, as_float(row[FIT_ERRORS[column]])):
            return True
    return False


def colour_range(grid: np.ndarray, signed: bool,
                 starred: np.ndarray) -> tuple[float, float, str] | None:
    """(vmin, vmax, extend) of a heat map of the values ``grid`` (in the map's unit); None
    without a finite value.

    The range is that of the finite values not ``starred`` (poorly determined, see
    ``FIT_ERRORS``; all of them when every value is starred): a K of 3 +- 2 among
    well-determined 0.7-1.4 would set the range and leave those alike.  A starred value
    outside it is drawn in the colour of the range's end and ``extend`` ("max", "min",
    "both", "neither": matplotlib's colorbar argument) says so.  ``signed``: centred on 0,
    +- the largest magnitude, so that the sign is the colour's side."""
    finite = np.isfinite(grid)
    if not finite.any():
        return None
    ranged = grid[finite & ~starred] if (finite & ~starred).any() else grid[finite]
    if signed:
        lim = float(np.max(np.abs(ranged))) or 1.0
        vmin, vmax = -lim, lim
    else:
        vmin, vmax = float(ranged.min()), float(ranged.max())
    return vmin, vmax, _extend(grid, vmin, vmax)


def _extend(grid: np.ndarray, vmin: float, vmax: float) -> str:
    """matplotlib's colorbar ``extend`` for the finite values of ``grid`` beyond vmin, vmax."""
    finite = grid[np.isfinite(grid)]
    over, under = bool((finite > vmax).any()), bool((finite < vmin).any())
    return {(True, True): "both", (True, False): "max", (False, True): "min",
            (False, False): "neither"}[over, under]


def shared_colour_range(maps: list[tuple[np.ndarray, np.ndarray]], signed: bool,
                        own: np.ndarray) -> tuple[float, float, str] | None:
    """``colour_range`` over the values of several maps, ``maps`` ((grid, starred) each), for
    the map ``own`` among them (its colour bar's ``extend``): the same quantity after filling
    and in discharge side by side, each on its own range, drew 22,735 Pa teal on the left
    and 23,774 Pa yellow on the right.  None when ``own`` has no finite value."""
    if not np.isfinite(own).any():
        return None
    limits = colour_range(np.concatenate([g.ravel() for g, _ in maps]), signed,
                          np.concatenate([st.ravel() for _, st in maps]))
    if limits is None:
        return None
    vmin, vmax, _ = limits
    return vmin, vmax, _extend(own, vmin, vmax)


CELL_FONT = 9  # [pt] of the cells' values: 11 px at the figure's 90 dpi (7 pt was 9 px)


def _map_values(rows_by_id: dict, cells: list[list[list[PlannedRun]]],
                column: str) -> tuple[np.ndarray, np.ndarray]:
    """(grid, starred) of a heat map of ``column``: the seed mean per cell (of ``cells``, the
    runs at each), and where a run's fit there is poorly determined (``FIT_ERRORS``)."""
    grid = np.array([[_mean_std(_values(rows_by_id, runs, column))[0] for runs in line]
                     for line in cells], dtype=float)
    starred = np.zeros(grid.shape, dtype=bool)
    if column in FIT_ERRORS:
        for (i, j), v in np.ndenumerate(grid):
            starred[i, j] = math.isfinite(v) and _poorly_fitted(rows_by_id, cells[i][j], column)
    return grid, starred


def fig_heatmaps(plan: StudyPlan, rows_by_id: dict, lay: Layout) -> Figure | None:
    """One heat map per quantity over the grid (seed means, the value written in each cell;
    a star where a run's fitted value there is poorly determined, see ``FIT_ERRORS``, its
    colour left out of the map's range, see ``colour_range``; the cell hatched where a run's
    value there is flagged, see ``FLAGS``; each map's title says what its marks mean).  A
    quantity that can be below 0 (``HeatMap.signed``) on a two-sided map centred on 0."""
    n = len(HEATMAPS)
    ncols = 2
    nrows = math.ceil(n / ncols)
    fig = Figure(figsize=(6.2 * ncols, (0.6 * len(lay.rows) + 2.6) * nrows), dpi=90)
    axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
    any_value = False
    cells = [[_runs_at(plan, lay, row, col) for col in lay.cols] for row in lay.rows]
    maps = {hm.column: _map_values(rows_by_id, cells, hm.column) for hm in HEATMAPS}
    for ax, hm in zip(axes, HEATMAPS):
        column, title = hm.column, hm.title
        grid, starred = maps[column]
        if hm.shares:
            limits = shared_colour_range([maps[m.column] for m in HEATMAPS
                                          if m.shares == hm.shares], hm.signed, grid)
            title += "\n(one colour scale with the map beside it)"
        else:
            limits = colour_range(grid, hm.signed, starred)
        any_value |= limits is not None
        vmin, vmax, extend = limits or (None, None, "neither")
        im = ax.imshow(np.ma.masked_invalid(grid), cmap=SIGNED_CMAP if hm.signed else hm.cmap,
                       aspect="auto", vmin=vmin, vmax=vmax)
        hatched = False
        for (i, j), v in np.ndenumerate(grid):
            if column in FLAGS and _flagged(rows_by_id, cells[i][j], column):
                hatched = True
                for hatch, color in FLAG_HATCHES:
                    ax.add_patch(Rectangle((j - 0.5, i - 0.5), 1.0, 1.0, fill=False, lw=0.0,
                                           hatch=hatch, edgecolor=color))
            ax.text(j, i, significant(v) + ("*" if starred[i, j] else ""), ha="center",
                    va="center", fontsize=CELL_FONT, color="k",
                    bbox={"facecolor": "white", "alpha": 0.7, "lw": 0, "pad": 1.5})
        if starred.any():
            title += ("\n*: a run's fit there is poorly determined (error over half the value);"
                      "\nits colour is left out of the range")
        if hatched:
            title += "\n" + FLAGS[column][1]
        ax.set_xticks(range(len(lay.cols)), [lay.col_label(c) for c in lay.cols], fontsize=8,
                      rotation=20, ha="right")
        ax.set_yticks(range(len(lay.rows)), [lay.row_label(r) for r in lay.rows], fontsize=8)
        ax.set_title(title, fontsize=9.5)
        fig.colorbar(im, ax=ax, shrink=0.85, extend=extend).ax.tick_params(labelsize=8)
    for ax in axes[n:]:
        ax.set_visible(False)
    if not any_value:
        return None
    tight_layout(fig)
    return fig


# --- the page --------------------------------------------------------------------------------


def _fmt(value: Any, digits: int = 3) -> str:
    try:
        v = float(value)
    except (TypeError, ValueError):
        return str(value) if value not in (None, "") else "n/a"
    return significant(v, digits)


def _run_table(plan: StudyPlan, rows_by_id: dict, out_dir: Path, failed: dict[str, str]) -> str:
    head = ("run", "change sigma_h [%]", "change sigma_v [%]", "sigma_h/sigma_v discharge [-]",
            "CV of the ratio [-]", "regime", "wall peak change, peak to peak [%]",
            "wall change at the filling peak's height [%]", "emptied at the window's end [%]",
            "discharge rate [kg/s]", "flow pattern")
    cells = "".join(f"<th scope='col'>{html.escape(h)}</th>" for h in head)
    body = []
    for run in plan.runs:
        row = rows_by_id.get(run.id)
        report = out_dir / "runs" / run.id / "report.html"
        name = html.escape(run.label)
        if report.is_file():
            name = f"<a href='runs/{html.escape(run.id)}/report.html'>{name}</a>"
        if row is None or row.get("summary_error"):  # (all n/a, without the reason)
            why = (failed.get(run.id, "not run yet") if row is None else
                   f"finished, but its results.h5 could not be read: {row['summary_error']}")
            body.append(f"<tr><td>{name}</td><td colspan='{len(head) - 1}' class='warn'>"
                        f"{html.escape(why)}</td></tr>")
            continue
        vals = [_fmt(row.get("switch_sigma_h_change_pct")),
                _fmt(row.get("switch_sigma_v_change_pct")),
                _fmt(row.get("switch_ratio_discharge")),
                _fmt(row.get("switch_ratio_cv_discharge")),
                regime(as_float(row.get("switch_ratio_cv_discharge"))),
                _fmt(row.get("wall_peak_change_pct")),
                _fmt(row.get("wall_at_fill_peak_change_pct")),
                _fmt(row.get("window_emptied_end_pct")), _fmt(row.get("discharge_rate"), 4),
                str(row.get("flow_pattern") or "n/a")]
        body.append(f"<tr><td>{name}</td>" + "".join(f"<td>{html.escape(v)}</td>" for v in vals)
                    + "</tr>")
    return (f"<div class='wide'><table class='runs'><tr>{cells}</tr>{''.join(body)}</table>"
            "</div>")


FIGURES = [
    ("fig7_switch_stresses", "Fig. 7", ("Evolution of the horizontal and vertical stress at "
     "the switch zone (mean Love-Weber stress of the two measurement circles against the walls "
     "at the cell-hopper junction) through filling, settling and discharge, for every case.")),
    ("fig7_switch_ratio", "Fig. 7", ("Ratio sigma_h / sigma_v at the switch zone for every "
     "case: a steady ratio is the paper's continuum-like behaviour, strong fluctuations an "
     "anisotropic stress field.")),
    ("fig8_change", "Figs. 8a, 8b", ("Percentage change of the horizontal (a) and vertical (b) "
     "stress at the switch zone from the end of filling (settling window) to the discharge "
     "window, grouped by the first grid key, one bar per combination of the others.")),
    ("heatmaps", "", "The main quantities over the grid (seed means)."),
    ("beverloo", "", ("Discharge rate against outlet width, as W^(2/3) against D, where the 2D "
     "Beverloo law W = C rho_b sqrt(g) (D - k d)^(3/2) t is a straight line crossing the axis "
     "at k d: seed means with their standard errors, and the fitted line of each case.")),
]


def _beverloo_section(fits: list, notes: list[str], out_dir: Path) -> list[str]:
    """The Beverloo fits' table for the report with its notes (what was left out, why a case
    has no fit), and beverloo.csv (removed when there is no fit)."""
    path = out_dir / BEVERLOO_CSV
    listed = ("<ul>" + "".join(f"<li>{html.escape(n)}</li>" for n in notes) + "</ul>"
              if notes else "")
    if not fits:
        path.unlink(missing_ok=True)
        return ["<h2>Beverloo fit</h2>", listed] if notes else []
    rows = fit_rows(fits)
    columns = [c for c, _, _ in FIT_COLUMNS]
    write_atomic(path, table_csv(columns, rows).encode("utf-8"))

    def pm(r: dict[str, Any], key: str) -> str:
        if not math.isfinite(r[key]):
            return "n/a"
        return f"{_fmt(r[key])} +- {_fmt(r[key + '_err'], 2)}"

    shown = [(r["group"], r["widths"], r["runs"], _fmt(r["bulk_density"]), pm(r, "C"),
              pm(r, "k"), pm(r, "b_free")) for r in rows]
    return ["<h2>Beverloo fit</h2>",
            ("<p>The grid varies the outlet width D: per case, W = C rho_b sqrt(g) (D - k d)^b "
             "t fitted to the seed means of the steady discharge rate, with b = 3/2 (C, k) and, "
             "from four widths on, b free; d is the mean grain diameter, rho_b the settled "
             f"bulk density (docs/theory.md, docs/sweeps.md). Every value: {BEVERLOO_CSV}.</p>"),
            html_table(shown, ("case", "widths", "runs", "rho_b [kg/m^3]", "C (b = 3/2)",
                           "k (b = 3/2)", "b free")), listed]


def write_study_report(plan: StudyPlan, out_dir: Path, rows: list[dict[str, Any]],
                       failed: dict[str, str] | None = None, where: str = "",
                       undrawn: dict[str, str] | None = None) -> Path:
    """Render the figures into ``out_dir/figures`` and write ``out_dir/report.html``.

    A figure whose drawing fails is left out, and the page says which and why: the report
    stands on the whole study's runs, and one figure's error lost all of it.  ``undrawn``,
    when given, receives those figures' names and errors (the sweep warns with them)."""
    out_dir = Path(out_dir)
    failed = failed or {}
    undrawn = {} if undrawn is None else undrawn
    rows_by_id = {r["id"]: r for r in rows}
    lay = layout_of(plan)
    fits, fit_notes = outlet_fits(plan, rows_by_id)
    makers = {
        "fig7_switch_stresses": lambda: fig_evolution(plan, out_dir, lay, ratio=False),
        "fig7_switch_ratio": lambda: fig_evolution(plan, out_dir, lay, ratio=True),
        "fig8_change": lambda: fig_change(plan, rows_by_id, lay),
        "heatmaps": lambda: fig_heatmaps(plan, rows_by_id, lay),
        "beverloo": lambda: fig_beverloo(fits),
    }
    fig_dir = out_dir / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)
    pngs = []
    for name, paper, caption in FIGURES:
        try:
            fig = makers[name]()
            png = png_bytes(fig) if fig is not None else None  # (drawing happens here)
        except Exception as exc:  # noqa: BLE001 - the other figures and the tables stand
            undrawn[name] = f"{type(exc).__name__}: {exc}"
            png = None
        if png is None:
            (fig_dir / f"{name}.png").unlink(missing_ok=True)
            continue
        write_atomic(fig_dir / f"{name}.png", png)
        pngs.append((name, paper, caption, png))
    spec = plan.study.spec
    title = f"silodem study: {plan.name}" + (" (--quick)" if plan.quick else "")
    parts = [page_head(title, PAGE_CSS + STUDY_CSS), f"<h1>{html.escape(title)}</h1>"]
    if spec.description:  # (no empty paragraph without one)
        parts.append(f"<p>{html.escape(spec.description)}</p>")
    n_done = len(rows)
    meta = [("base", spec.base or "the grid's", ""), ("seeds", ", ".join(map(str, spec.seeds)), ""),
            *((f"set {k}", format_value(v), "") for k, v in spec.set.items()),
            *((f"grid {k} ({nicknames(list(spec.grid))[k]})",
               ", ".join(format_value(v) for v in vals), "") for k, vals in spec.grid.items()),
            ("--quick (small silo of each case)", _quick_silo(plan) if plan.quick else "no",
             ""),
            ("runs finished / planned", f"{n_done} / {len(plan.runs)}", ""),
            ("failed", str(len(failed)), ""),
            ("computed on", where or "n/a", ""),
            ("silodem", __version__, ""),
            ("written", time.strftime("%Y-%m-%d %H:%M:%S"), "")]
    parts += ["<h2>Study</h2>", html_table([(a, b) for a, b, _ in meta], ("item", "value"))]
    if plan.quick:
        hopper = any(run.cfg.silo.kind == "hopper" for run in plan.runs)
        parts.append(f"<p class='warn'>{html.escape(quick_caveat(hopper))}</p>")
    parts.append(
        "<p>Stresses are compressive positive [Pa]: 2D forces per unit length divided by the "
        "grains' out-of-plane thickness (material.thickness). The switch "
        "zone is the cell-hopper junction; its stresses are the mean Love-Weber stress of the "
        "two measurement circles against the walls at the junction (docs/measurements.md). "
        "'After filling' is the last measure.window of settling, 'discharge' the window that "
        "starts measure.discharge_delay after the gate opens. The regime reads the coefficient "
        f"of variation of the sampled ratio sigma_h / sigma_v in the discharge window: above "
        f"{CV_ANISOTROPIC:g} 'anisotropic', else 'continuum-like' (the paper's section 6; the "
        "threshold is ours). Hopper slope theta from the horizontal; phi_G grain-grain, phi_P "
        "grain-wall friction angle.</p>")
    if failed:
        parts.append("<h2>Failed runs</h2><ul>" + "".join(
            f"<li class='warn'>{html.escape(k)}: {html.escape(v)}</li>"
            for k, v in failed.items()) + "</ul>")
    parts += ["<h2>Runs</h2>", _run_table(plan, rows_by_id, out_dir, failed),
              ("<p>Every value per run, with units: results.csv (columns in docs/sweeps.md). "
              "A run's name links to its own report when it wrote one.</p>")]
    parts += _beverloo_section(fits, fit_notes, out_dir)
    parts.append("<h2>Figures</h2>")
    parts += [f"<p class='warn'>{html.escape(name)} could not be drawn ({html.escape(why)})."
              "</p>" for name, why in undrawn.items()]
    parts += [figure_html(name, png, caption, f"{paper} equivalent." if paper else "")
              for name, paper, caption, png in pngs]
    parts.append("<h2>Columns of results.csv</h2>" + html_table(
        [(c, u or "-", d) for c, u, d in COLUMNS]
        + [(f"circle_<name>_{c}", u or "-", d) for c, u, d in CIRCLE_QUANTITIES],
        ("column", "unit", "meaning"), cls="long-first"))
    parts.append("<h2>Study file</h2><pre>" + html.escape(plan.study.text) + "</pre>")
    parts.append("</body></html>")
    path = out_dir / "report.html"
    write_atomic(path, "\n".join(parts).encode("utf-8"))
    return path
