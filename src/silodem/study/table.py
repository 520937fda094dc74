"""Per-run results of a study: the summary of one results folder, and the tidy table.

``summarise_run(folder)`` reduces a run's results.h5 to the numbers the paper's section 5
compares (switch-zone stresses after filling and during discharge, their change, the ratio
sigma_h / sigma_v and its fluctuation, the wall peak, the discharge rate and flow pattern).  It
uses the colleague's analysis (``silodem.report.analysis``) for the time windows, the wall
profiles and the discharge rate, so a study and the run's own report.html agree.

The table has one row per finished run and one column per quantity (docs/sweeps.md lists them
with their units).  It holds only values that a run determines, so the same study gives the same
table whether run serially or on any cluster.
"""

from __future__ import annotations

import csv
import io
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from silodem.report.numbers import loaded

if TYPE_CHECKING:
    from silodem.study.plan import StudyPlan

SETTLE, DISCHARGE = 1, 2
WALL_CIRCLES = ("switch_left", "switch_right")

# (column, unit, meaning) of the per-run quantities, in table order
COLUMNS: list[tuple[str, str, str]] = [
    ("switch_sigma_h_fill", "Pa", "horizontal stress at the switch zone after filling"),
    ("switch_sigma_h_discharge", "Pa", "horizontal stress at the switch zone during discharge"),
    ("switch_sigma_h_change_pct", "%", "change of the horizontal stress, filling -> discharge"),
    ("switch_sigma_v_fill", "Pa", "vertical stress at the switch zone after filling"),
    ("switch_sigma_v_discharge", "Pa", "vertical stress at the switch zone during discharge"),
    ("switch_sigma_v_change_pct", "%", "change of the vertical stress, filling -> discharge"),
    ("switch_ratio_fill", "-", ("sigma_h / sigma_v at the switch zone after filling (ratio of "
     "the window means)")),
    ("switch_ratio_discharge", "-", "sigma_h / sigma_v at the switch zone during discharge"),
    ("switch_ratio_cv_fill", "-", ("coefficient of variation (std / mean) of the sampled ratio "
     "sigma_h / sigma_v in the filling window")),
    ("switch_ratio_cv_discharge", "-", ("coefficient of variation of the sampled ratio in the "
     "discharge window: small = continuum-like, large = anisotropic")),
    ("wall_peak_fill", "Pa", "switch-zone peak of the wall normal stress after filling"),
    ("wall_peak_z_fill", "m", "height of that peak"),
    ("wall_peak_discharge", "Pa", "switch-zone peak of the wall normal stress during discharge"),
    ("wall_peak_z_discharge", "m", "height of that peak"),
    ("wall_peak_change_pct", "%", ("change from the filling peak to the discharge peak, each "
     "at its own height (wall_peak_z_fill, wall_peak_z_discharge: they may lie on different "
     "walls)")),
    ("wall_at_fill_peak_change_pct", "%", ("change of the wall normal stress at the filling "
     "peak's height, filling -> discharge: the same place")),
    ("coordination_fill", "-", ("coordination number C_n (eq. 10) in the band across the silo "
     "at the junction, filling window mean")),
    ("coordination_discharge", "-", "the same, discharge window mean"),
    ("coordination_change_pct", "%", "its change, filling -> discharge"),
    ("janssen_K_fill", "-", "Janssen K fitted to the cell walls after filling, mu_w = tan phi_P"),
    ("janssen_K_fill_err", "-", ("its standard error (over half of K: K is poorly determined, "
     "as the run report says)")),
    ("janssen_K_fill_above_1", "", ("true where janssen_K_fill is above 1 by more than its "
     "error, as the run report flags it: no K of a fill at rest (Jaky: K0 = 1 - sin phi < 1), "
     "and the EN 1991-4 loads of the row come from it; false otherwise and without a fit")),
    ("wall_friction_mobilised_fill", "-", ("mobilised wall friction sum(tau)/sum(sigma_n) on the "
     "cell-wall bins of the Janssen fit after filling (tan phi_P when fully mobilised, as "
     "Janssen and EN 1991-4 assume)")),
    ("wall_friction_negative_fill", "", ("true where wall_friction_mobilised_fill is below 0, as "
     "the run report flags it: the walls' friction on the grains points down, the cell walls "
     "carry none of the fill's weight; false otherwise and without it")),
    ("en1991_4_class", "", "EN 1991-4 slenderness class: slender, intermediate, squat, retaining"),
    ("en1991_4_hopper_class", "", "EN 1991-4 hopper class: steep, shallow or flat"),
    ("en1991_4_hopper_p_n_fill", "Pa", ("EN 1991-4 hopper normal pressure at the transition, "
     "filling (F_f p_vft)")),
    ("en1991_4_hopper_p_n_discharge", "Pa", ("EN 1991-4 hopper normal pressure at the "
     "transition, discharge (F_e p_vft)")),
    ("discharge_rate", "kg/s", ("steady discharge rate W through the slot of thickness t "
     "(material.thickness; not per metre of it)")),
    ("discharge_rate_err", "kg/s", "its standard error (5 block slopes)"),
    ("window_emptied_start_pct", "%", ("share of the fill's mass discharged when the "
     "discharge window starts")),
    ("window_emptied_end_pct", "%", "the same when the discharge window ends"),
    ("mass_flow_index", "-", "v_wall / v_axis above the junction"),
    ("dead_fraction", "-", ("fraction of the grains in a dead zone (at rest to the end of "
                            "the discharge window)")),
    ("flow_pattern", "", "mass flow, funnel flow, clogged, or unknown (MFI not measured)"),
    ("segregation_first", "-", ("mass mean diameter of the first tenth of the discharged "
                                "mass over the fill's (1: no size segregation)")),
    ("segregation_last", "-", "the same of the last tenth"),
    ("junction_z", "m", "height of the cell-hopper junction above the outlet"),
    ("fill_level", "m", "fill level after settling: mean of the 5 highest grain tops (events)"),
    ("bulk_density", "kg/m^3", "bulk density rho_b of the settled packing under the free surface"),
    ("n_poured", "-", "grains poured"),
    ("lost_count", "-", "grains lost through a wall (too soft contacts), 0 when none"),
    ("discharged_fraction", "-", ("share of the mass at the gate's opening that left through "
     "the outlet")),
    ("discharge_end_reason", "", "what ended the discharge: fraction, time or clog"),
    ("steps", "-", "time steps"),
    ("dt", "s", "time step"),
]
CIRCLE_QUANTITIES: list[tuple[str, str, str]] = [
    ("sigma_h_fill", "Pa", "horizontal stress in the circle after filling"),
    ("sigma_h_discharge", "Pa", "horizontal stress in the circle during discharge"),
    ("sigma_h_change_pct", "%", "change of the horizontal stress"),
    ("sigma_v_fill", "Pa", "vertical stress in the circle after filling"),
    ("sigma_v_discharge", "Pa", "vertical stress in the circle during discharge"),
    ("sigma_v_change_pct", "%", "change of the vertical stress"),
    ("ratio_cv_discharge", "-", "coefficient of variation of sigma_h / sigma_v, discharge"),
]
NAN = float("nan")


def as_float(value: Any) -> float:
    """``value`` as a float; NaN for what is not a number (None, "", text)."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return NAN


def _ratio_stats(sh: np.ndarray, sv: np.ndarray) -> tuple[float, float]:
    """(ratio of the window means, coefficient of variation std/mean of the sampled ratio).

    The sampled ratio leaves out samples where the circle is almost unloaded (sigma_v below
    ``UNLOADED`` times its median over the window): a ratio of two near-zero numbers is noise,
    not anisotropy."""
    ok = np.isfinite(sh) & np.isfinite(sv) & (sv > 0)
    if not ok.any():
        return NAN, NAN
    ratio_of_means = float(np.mean(sh[ok]) / np.mean(sv[ok]))
    ok = loaded(sv, ok)
    r = sh[ok] / sv[ok]
    mean = float(np.mean(r))
    cv = float(np.std(r) / abs(mean)) if r.size >= 2 and mean != 0 else NAN
    return ratio_of_means, cv


def wall_circle_indices(names: list[str]) -> list[int]:
    """The circles whose mean is 'the switch zone': the two default circles against the walls
    at the junction (switch_left, switch_right) when present, else every circle."""
    idx = [names.index(n) for n in WALL_CIRCLES if n in names]
    return idx if idx else list(range(len(names)))


@dataclass
class SwitchSeries:
    """Stress time series at the switch zone of one run (for Fig. 7)."""

    time: np.ndarray  # [s]
    phase: np.ndarray  # 0 fill, 1 settle, 2 discharge
    sigma_h: np.ndarray  # [Pa]
    sigma_v: np.ndarray  # [Pa]
    t_open: float  # gate opening [s]


def switch_series(folder: Path | str) -> SwitchSeries | None:
    """The switch-zone sigma_h, sigma_v (mean of the wall circles) of a run against time."""
    import h5py

    path = Path(folder) / "results.h5"
    with h5py.File(path, "r") as h5:
        if "measure" not in h5 or "circles" not in h5["measure"]:
            return None
        m = h5["measure"]
        names = [n.decode() if isinstance(n, bytes) else str(n) for n in m["circles/name"][()]]
        stress = m["circles/stress"][()]
        t, phase = m["time"][()], m["phase"][()]
        t_open = float(h5["events"].attrs.get("discharge_start_time", NAN))
    idx = wall_circle_indices(names)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN samples (empty circles)
        sh = np.nanmean(stress[:, idx, 0], axis=1) if stress.size else np.zeros(0)
        sv = np.nanmean(stress[:, idx, 1], axis=1) if stress.size else np.zeros(0)
    return SwitchSeries(t, phase, sh, sv, t_open)


# Raise when summarise_run gives other numbers for the same results.h5, so that a study's
# finished runs are summarised again (execute.read_summary) instead of keeping stale numbers:
# 2: the default switch zone reaches at most half-way down the hopper (its wall peak moved);
# the columns janssen_K_fill_err, window_emptied_start_pct / _end_pct; 3: coordination_*;
# 4: wall_at_fill_peak_change_pct, wall_friction_mobilised_fill; 5: the flags
# janssen_K_fill_above_1, wall_friction_negative_fill; 6: the dead-zone fraction (so the
# flow pattern) of the grains there as the gate opened, not those lost through a wall before;
# 7: nor those lost through a wall after (measure.discharge.lost_grains; in a file written
# before the flag of those lost before, the grains below the outlet at the opening); the bulk
# density by each disk's area in its band, not whole grains by their centres; lost_count;
# 8: no steady rate from a plateau (a run clogged after two grains); the dead zone up to the
# discharge window's end, where results.h5 has max_displacement_window.
ANALYSIS_VERSION = 8


def summarise_run(folder: Path | str) -> dict[str, Any]:
    """The per-run quantities of :data:`COLUMNS` (and per-circle ones) from a results folder."""
    from silodem.report.analysis import analyse, window_mean
    from silodem.report.flags import above_hydrostatic, walls_held_up
    from silodem.report.load import load_results
    from silodem.report.numbers import percent_change

    res = load_results(folder)
    a = analyse(res)
    ev = res.events
    out: dict[str, Any] = {c: NAN for c, _, _ in COLUMNS}
    out.update(junction_z=as_float(a.geom.get("z_j")), fill_level=as_float(ev.get("fill_level")),
               bulk_density=as_float(a.rho_b),
               n_poured=int(ev.get("n_poured", 0)), lost_count=int(ev.get("lost_count", 0)),
               discharged_fraction=as_float(ev.get("discharged_fraction")),
               discharge_end_reason=str(ev.get("discharge_end_reason", "")),
               steps=int(res.attrs.get("steps", 0)), dt=as_float(res.attrs.get("dt")),
               flow_pattern="", en1991_4_class="", en1991_4_hopper_class="",
               janssen_K_fill_above_1=False, wall_friction_negative_fill=False)
    if "fill" in a.mu_mobilised:
        out["wall_friction_mobilised_fill"] = as_float(a.mu_mobilised["fill"])
        out["wall_friction_negative_fill"] = bool(walls_held_up(a.mu_mobilised["fill"]))
    if "fill" in a.janssen:
        out["janssen_K_fill"] = as_float(a.janssen["fill"].K)
        out["janssen_K_fill_err"] = as_float(a.janssen["fill"].K_err)
        out["janssen_K_fill_above_1"] = bool(above_hydrostatic(a.janssen["fill"]))
    en = a.en1991_4
    out["en1991_4_class"] = str(en.get("kind", ""))
    hopper = en.get("hopper", {})
    out["en1991_4_hopper_class"] = str(hopper.get("kind", ""))
    for key, p_n in (("fill", "p_nf"), ("discharge", "p_ne")):
        if p_n in hopper:  # the last height of the hopper curve is the transition
            out[f"en1991_4_hopper_p_n_{key}"] = as_float(hopper[p_n][-1])
    m = res.group("measure")
    if m is not None and a.windows:
        t, phase = m["time"], m["phase"]
        (f0, f1), (d0, d1) = a.windows["fill"], a.windows["discharge"]
        masks = {"fill": (t >= f0) & (t <= f1) & (phase == SETTLE),
                 "discharge": (t >= d0) & (t <= d1) & (phase == DISCHARGE)}
        band = m.get("band", {}).get("coordination")
        if band is not None:
            for key, mask in masks.items():
                out[f"coordination_{key}"] = window_mean(band[mask])
            out["coordination_change_pct"] = percent_change(out["coordination_fill"],
                                                     out["coordination_discharge"])
        c = m["circles"]
        names = [str(n) for n in c["name"]]
        stress = c["stress"]

        def window_stats(sh: np.ndarray, sv: np.ndarray, prefix: str) -> None:
            for key, mask in masks.items():
                h, v = window_mean(sh[mask]), window_mean(sv[mask])
                out[f"{prefix}sigma_h_{key}"], out[f"{prefix}sigma_v_{key}"] = h, v
                ratio, cv = _ratio_stats(sh[mask], sv[mask])
                if prefix == "switch_":
                    out[f"switch_ratio_{key}"] = ratio
                    out[f"switch_ratio_cv_{key}"] = cv
                elif key == "discharge":
                    out[f"{prefix}ratio_cv_discharge"] = cv
            for comp in ("sigma_h", "sigma_v"):
                out[f"{prefix}{comp}_change_pct"] = percent_change(out[f"{prefix}{comp}_fill"],
                                                            out[f"{prefix}{comp}_discharge"])

        if names:
            idx = wall_circle_indices(names)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # empty circles give NaN
                window_stats(np.nanmean(stress[:, idx, 0], axis=1),
                             np.nanmean(stress[:, idx, 1], axis=1), "switch_")
            for k, name in enumerate(names):
                window_stats(stress[:, k, 0], stress[:, k, 1], f"circle_{name}_")
    for key in ("fill", "discharge"):
        if key in a.peaks:
            out[f"wall_peak_{key}"], out[f"wall_peak_z_{key}"] = map(as_float, a.peaks[key])
    out["wall_peak_change_pct"] = percent_change(out["wall_peak_fill"], out["wall_peak_discharge"])
    if a.wall_at_fill_peak is not None:
        out["wall_at_fill_peak_change_pct"] = as_float(a.wall_at_fill_peak[3])
    flow = a.flow
    if "rate" in flow:
        out["discharge_rate"], out["discharge_rate_err"] = as_float(flow["rate"].rate), \
            as_float(flow["rate"].err)
    if "window_emptied" in flow:
        out["window_emptied_start_pct"], out["window_emptied_end_pct"] = (
            100.0 * as_float(v) for v in flow["window_emptied"])
    if "pattern" in flow:
        out["mass_flow_index"] = as_float(flow["mfi"])
        out["dead_fraction"] = as_float(flow["dead_fraction"])
        out["flow_pattern"] = str(flow["pattern"])
    if "composition" in flow:
        ratio = flow["composition"].diameter_ratio
        out["segregation_first"], out["segregation_last"] = as_float(ratio[0]), \
            as_float(ratio[-1])
    return {k: (v.item() if isinstance(v, np.generic) else v) for k, v in out.items()}


# --- the table -------------------------------------------------------------------------------


def table_columns(grid_keys: list[str], rows: list[dict[str, Any]]) -> list[str]:
    """Column order: id, slug, seed, the grid keys, COLUMNS, then the per-circle columns."""
    fixed = ["id", "slug", "seed", *grid_keys, *(c for c, _, _ in COLUMNS)]
    extra = sorted({k for r in rows for k in r} - set(fixed))
    return fixed + extra


def table_rows(plan: StudyPlan,
               summaries: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per planned run that has a summary, in plan order."""
    rows = []
    for run in plan.runs:
        summary = summaries.get(run.id)
        if summary is None:
            continue
        row: dict[str, Any] = {"id": run.id, "slug": run.slug, "seed": run.seed}
        row.update(run.point)
        row.update({k: v for k, v in summary.items() if k not in row})
        rows.append(row)
    return rows


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)  # shortest text that reads back to the same double; 'nan' for NaN
    if isinstance(value, list | tuple):
        return " ".join(_cell(v) for v in value)
    return str(value)


def table_csv(columns: list[str], rows: list[dict[str, Any]]) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        writer.writerow([_cell(row.get(c)) for c in columns])
    return buf.getvalue()


def read_table(path: Path | str) -> list[dict[str, str]]:
    """The rows of a results.csv as dicts of strings."""
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))
