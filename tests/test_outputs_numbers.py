"""Numbers and labels of the study report, the force-network drawings, /frames and the VTK
files, checked against values from outside the code under test.

* The study report (``silodem.study.report``): a real plan (3 hopper slopes x 2 x 2 friction
  angles x 2 seeds) with synthetic table rows whose seed means and standard deviations have
  closed forms; the run table, the regime labels, the Fig. 8 bars, the heat maps and the Fig. 7
  panels are compared with them (docs/sweeps.md defines what each shows).
* The drawings (``silodem.viz.draw``, ``silodem.viz.network``): frames built by hand, with
  binary-exact coordinates and forces, drawn; the matplotlib artists (LineCollection segments
  and widths, EllipseCollection sizes and colour arrays, colour limits, wall line styles) are
  compared with the documented mapping (docs/visualisation.md, the module docstrings).
* /frames and the VTK files (``silodem.silo.frames``, ``silodem.viz.vtk``): one tiny real run
  whose state is copied straight from the engine's arrays each time the frames recorder saves
  something; results.h5 (read with h5py following docs/output.md) and the .vtu files (meshio)
  must hold that state.  tests/test_visualisation.py already compares the VTK files with the
  frames for positions, radius, velocity, spin, force, coordination, uid, the grain-grain
  lines and the wall ends; here: the frames against the engine, and the VTK fields it leaves
  out.
"""

from __future__ import annotations

import itertools
import math
import statistics
from html.parser import HTMLParser
from pathlib import Path
from xml.etree import ElementTree as ET

import h5py
import meshio
import numpy as np
import pytest
from matplotlib.collections import EllipseCollection, LineCollection
from matplotlib.colors import to_rgba
from measure_helpers import tiny_hopper_config

from silodem.config import Output
from silodem.run import run_simulation
from silodem.silo import frame_store
from silodem.silo.frame_store import FramesRecorder
from silodem.silo.frames import Frame, Frames, WallGeometry, read_frames
from silodem.study import expand, load_study
from silodem.study.report import (
    fig_change,
    fig_evolution,
    fig_heatmaps,
    layout_of,
    regime,
    write_study_report,
)
from silodem.viz.draw import FrameArtist
from silodem.viz.network import select_frame

REL = 1e-12  # exact constructions: only float round-off
F32_ULP = 2.0**-23  # relative spacing of float32 numbers (frames and VTK store float32)


# =============================================================================================
# 1. The study report
# =============================================================================================
STUDY = """\
name = "numbers"
description = "synthetic rows with closed-form seed means"
base = "paper-case2"
seeds = [1, 2]
[set]
"silo.wall_height" = 8.5
"fill.n_particles" = 480
[grid]
"silo.hopper_angle_from_horizontal_deg" = [35, 45, 55]
"material.friction_deg" = [20, 30]
"walls.friction_deg" = [10, 45]
"""
THETAS = [35, 45, 55]
# the other keys' combinations, first key slowest (docs/sweeps.md: plan order)
COLS = [(20, 10), (20, 45), (30, 10), (30, 45)]
CV = "switch_ratio_cv_discharge"
# value of a run at row r (theta), column c, seed index s (0: seed 1, 1: seed 2):
# base + r * per_row + c * per_col + (+spread if s == 0 else -spread)
LINEAR = {
    "switch_sigma_h_change_pct": (-20.0, 10.0, 1.0, 2.5),
    "switch_sigma_v_change_pct": (5.0, -10.0, -1.0, 1.5),
    "switch_ratio_discharge": (0.5, 0.25, 0.125, 0.0625),
    "wall_peak_fill": (2000.0, 500.0, 50.0, 25.0),
    "wall_peak_discharge": (1000.0, 1000.0, 100.0, 50.0),
    "janssen_K_fill": (0.5, 0.125, 0.0625, 0.03125),
    "wall_friction_mobilised_fill": (0.0625, 0.015625, 0.03125, 0.0078125),
    "discharge_rate": (12.5, 2.0, 0.5, 0.25),
    "mass_flow_index": (0.25, 0.25, 0.125, 0.0625),
    "coordination_discharge": (2.5, 0.25, 0.125, 0.0625),
    "wall_peak_change_pct": (-30.0, 5.0, 1.0, 0.5),
    "wall_at_fill_peak_change_pct": (-40.0, 4.0, 2.0, 1.0),
    "window_emptied_end_pct": (30.0, 8.0, 1.0, 0.5),
}
FAILED_AT = (1, 2, 1)  # this run failed: no row
NAN_AT = {("switch_sigma_h_change_pct", 2, 3, 1), ("discharge_rate", 0, 1, 0),
          ("discharge_rate", 0, 1, 1), (CV, 2, 0, 0), ("wall_peak_discharge", 1, 1, 0)}
FAILURE = "unstable: grain 17 left through a wall"
# the heat maps of docs/sweeps.md, in its order
HEATMAP_COLUMNS = ["switch_sigma_h_change_pct", "switch_sigma_v_change_pct",
                   "switch_ratio_discharge", CV, "wall_peak_fill", "wall_peak_discharge",
                   "janssen_K_fill", "wall_friction_mobilised_fill", "discharge_rate",
                   "mass_flow_index", "coordination_discharge"]


def _value(column: str, r: int, c: int, s: int) -> float:
    """The synthetic value of ``column`` for run (r, c, s) (NaN where NAN_AT says)."""
    if (column, r, c, s) in NAN_AT:
        return math.nan
    if column == CV:  # 0.125 .. 0.875, exactly 0.5 when r + c + s = 3
        return 0.125 * (r + c + s + 1)
    base, per_row, per_col, spread = LINEAR[column]
    return base + per_row * r + per_col * c + (spread if s == 0 else -spread)


def _pattern(r: int, c: int, s: int) -> str:
    if ("discharge_rate", r, c, s) in NAN_AT:
        return ""  # no discharge measured: shown as n/a
    return "mass flow" if (r + c) % 2 == 0 else "funnel flow"


def _seed_values(column: str, r: int, c: int) -> list[float]:
    """The finite values over the seeds of grid point (r, c), failed runs left out."""
    vals = [_value(column, r, c, s) for s in (0, 1) if (r, c, s) != FAILED_AT]
    return [v for v in vals if math.isfinite(v)]


def _seed_mean(column: str, r: int, c: int) -> float:
    vals = _seed_values(column, r, c)
    return statistics.fmean(vals) if vals else math.nan


def _seed_std(column: str, r: int, c: int) -> float:
    """Standard deviation over the seeds: the sample estimate (n - 1); 0 for one value."""
    vals = _seed_values(column, r, c)
    return statistics.stdev(vals) if len(vals) > 1 else 0.0


def _index(run) -> tuple[int, int, int]:
    p = run.point
    r = THETAS.index(p["silo.hopper_angle_from_horizontal_deg"])
    c = COLS.index((p["material.friction_deg"], p["walls.friction_deg"]))
    return r, c, [1, 2].index(run.seed)


def _shown_ok(text: str, value: float, digits: int) -> bool:
    """``text`` is ``value`` to ``digits`` significant digits ('n/a' for NaN)."""
    if not math.isfinite(value):
        return text == "n/a"
    if value == 0.0:
        return float(text) == 0.0
    half_unit = 0.5 * 10.0 ** (math.floor(math.log10(abs(value))) - digits + 1)
    return abs(float(text) - value) <= half_unit * (1 + 1e-9)


class _Tables(HTMLParser):
    """The text of every cell of every <table> of a page."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: list[list[list[str]]] = []
        self._cell: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        if tag == "table":
            self.tables.append([])
        elif tag == "tr":
            self.tables[-1].append([])
        elif tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self.tables[-1][-1].append("".join(self._cell))
            self._cell = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    root = tmp_path_factory.mktemp("study")
    (root / "numbers.toml").write_text(STUDY, encoding="utf-8")
    plan = expand(load_study(str(root / "numbers.toml")))
    rows, failed = [], {}
    for run in plan.runs:
        r, c, s = _index(run)
        if (r, c, s) == FAILED_AT:
            failed[run.id] = FAILURE
            continue
        row = {"id": run.id, "slug": run.slug, "seed": run.seed, **run.point,
               "flow_pattern": _pattern(r, c, s)}
        row.update({col: _value(col, r, c, s) for col in [*LINEAR, CV]})
        rows.append(row)
    out = root / "out"
    _write_switch_series(plan, out)
    return plan, rows, failed, out


def test_regime_threshold_is_the_documented_one():
    """docs/sweeps.md: a ratio CV above 0.5 is 'anisotropic', otherwise 'continuum-like'; a CV
    that could not be measured (NaN) has no regime."""
    assert regime(0.5) == "continuum-like"  # not above 0.5
    assert regime(math.nextafter(0.5, 1.0)) == "anisotropic"
    assert regime(0.0) == regime(0.499) == "continuum-like"
    assert regime(0.875) == regime(3.0) == "anisotropic"
    assert regime(math.nan) == "n/a"


def test_run_table_shows_every_runs_numbers_and_regime(study):
    """The table of report.html (docs/sweeps.md, 'a table of every run'): each cell is the
    row's value to 3 significant digits (the discharge rate to 4), the regime from the doc's
    threshold on the row's CV (0.125 .. 0.875 in the construction, 0.5 on the boundary), the
    failed run with its error; the study table counts 23 of 24 runs finished and 1 failed."""
    plan, rows, failed, out = study
    page = write_study_report(plan, out, rows, failed, where="here").read_text("utf-8")
    parser = _Tables()
    parser.feed(page)
    meta = {row[0]: row[1] for row in parser.tables[0][1:]}
    assert meta["runs finished / planned"] == "23 / 24"
    assert meta["failed"] == "1"
    from silodem import __version__

    assert meta["silodem"] == __version__  # which code made the study
    assert "above 0.5 'anisotropic', else 'continuum-like'" in page.replace("&#x27;", "'")
    table = next(t for t in parser.tables if t[0][0] == "run")
    assert table[0][1:] == ["change sigma_h [%]", "change sigma_v [%]",
                            "sigma_h/sigma_v discharge [-]", "CV of the ratio [-]", "regime",
                            "wall peak change, peak to peak [%]",
                            "wall change at the filling peak's height [%]",
                            "emptied at the window's end [%]", "discharge rate [kg/s]",
                            "flow pattern"]
    body = table[1:]
    assert len(body) == len(plan.runs) == 24
    columns = [("switch_sigma_h_change_pct", 3), ("switch_sigma_v_change_pct", 3),
               ("switch_ratio_discharge", 3), (CV, 3)]
    regimes = set()
    for run, cells in zip(plan.runs, body, strict=True):
        r, c, s = _index(run)
        assert cells[0] == run.label
        if (r, c, s) == FAILED_AT:
            assert cells[1:] == [FAILURE]
            continue
        for text, (col, digits) in zip(cells[1:5], columns, strict=True):
            assert _shown_ok(text, _value(col, r, c, s), digits), (run.id, col, text)
        cv = _value(CV, r, c, s)
        expected = "n/a" if math.isnan(cv) else "anisotropic" if cv > 0.5 else "continuum-like"
        assert cells[5] == expected, (run.id, cv)
        regimes.add(expected)
        assert _shown_ok(cells[6], _value("wall_peak_change_pct", r, c, s), 3)
        assert _shown_ok(cells[7], _value("wall_at_fill_peak_change_pct", r, c, s), 3)
        assert _shown_ok(cells[8], _value("window_emptied_end_pct", r, c, s), 3)
        assert _shown_ok(cells[9], _value("discharge_rate", r, c, s), 4)
        assert cells[10] == (_pattern(r, c, s) or "n/a")
    assert regimes == {"n/a", "anisotropic", "continuum-like"}
    # a finished run whose results.h5 could not be read: its reason, not a row of n/a
    broken = dict(rows[0], summary_error="OSError: truncated file")
    page = write_study_report(plan, out, [broken, *rows[1:]], failed, where="here")
    parser = _Tables()
    parser.feed(page.read_text("utf-8"))
    first = next(t for t in parser.tables if t[0][0] == "run")[1]
    why = "finished, but its results.h5 could not be read: OSError: truncated file"
    assert first[1:] == [why]


def test_fig8_bars_are_seed_means_with_seed_deviations(study):
    """Figs. 8a/8b (docs/sweeps.md): the change of sigma_h (a) and sigma_v (b), bars grouped by
    the first grid key (theta), one bar per (phi_G, phi_P); height = mean over the seeds of the
    rows, error bar = their sample standard deviation, ddof 1 (closed forms: mean of base +-
    spread, deviation spread * sqrt(2); one value, deviation 0, where a seed failed or is
    NaN)."""
    from matplotlib.container import BarContainer

    plan, rows, _, _ = study
    fig = fig_change(plan, {r["id"]: r for r in rows}, layout_of(plan))
    axes = [ax for ax in fig.axes if ax.containers]
    assert len(axes) == 2
    for ax, column in zip(axes, ("switch_sigma_h_change_pct", "switch_sigma_v_change_pct"),
                          strict=True):
        bars = [b for b in ax.containers if isinstance(b, BarContainer)]
        assert len(bars) == len(COLS)
        for c, (container, (phi_g, phi_p)) in enumerate(zip(bars, COLS, strict=True)):
            assert container.get_label() == f"phiG={phi_g} deg, phiP={phi_p} deg"
            segments = container.errorbar.lines[2][0].get_segments()
            for r, patch in enumerate(container.patches):
                centre = patch.get_x() + patch.get_width() / 2
                assert r - 0.5 < centre < r + 0.5  # in the group of theta[r]
                assert patch.get_height() == pytest.approx(_seed_mean(column, r, c), rel=REL)
                (x0, lo), (x1, hi) = segments[r]
                assert x0 == x1 == pytest.approx(centre, rel=REL)
                assert (hi + lo) / 2 == pytest.approx(_seed_mean(column, r, c), rel=REL)
                assert (hi - lo) / 2 == pytest.approx(_seed_std(column, r, c), rel=REL, abs=0)
        # within a group the bars follow the columns, left to right
        for r in range(len(THETAS)):
            xs = [b.patches[r].get_x() for b in bars]
            assert xs == sorted(xs)
    ticks = [t.get_text() for t in axes[1].get_xticklabels()]
    assert ticks == [f"theta={t} deg" for t in THETAS]
    assert list(axes[1].get_xticks()) == [0, 1, 2]


def test_heatmaps_are_seed_means_of_the_documented_quantities(study):
    """docs/sweeps.md: heat maps of the change of sigma_h, of sigma_v, sigma_h / sigma_v in
    discharge, its CV, the wall peak after filling and in discharge, Janssen's K and the
    mobilised wall friction after filling, the discharge rate and the mass flow index,
    rows = theta, columns = (phi_G, phi_P), seed means written in the cells ('n/a' where no
    seed has a value).  The change maps are centred on zero, both on one range: +- the largest
    |mean| of either (they stand side by side and share their colours); the two wall-peak
    maps share the range of both."""
    plan, rows, _, _ = study
    changes = [_seed_mean(column, r, c) for column in HEATMAP_COLUMNS
               if column.endswith("change_pct")
               for r in range(len(THETAS)) for c in range(len(COLS))]
    lim = max(abs(v) for v in changes if not np.isnan(v))
    peaks = [v for column in ("wall_peak_fill", "wall_peak_discharge")
             for r in range(len(THETAS)) for c in range(len(COLS))
             if not np.isnan(v := _seed_mean(column, r, c))]
    fig = fig_heatmaps(plan, {r["id"]: r for r in rows}, layout_of(plan))
    maps = [ax for ax in fig.axes if ax.images]
    assert len(maps) == len(HEATMAP_COLUMNS)
    for ax, column in zip(maps, HEATMAP_COLUMNS, strict=True):
        expected = np.array([[_seed_mean(column, r, c) for c in range(len(COLS))]
                             for r in range(len(THETAS))])
        data = np.ma.filled(ax.images[0].get_array().astype(float), np.nan)
        assert data.shape == expected.shape
        assert np.array_equal(np.isnan(data), np.isnan(expected)), column
        ok = ~np.isnan(expected)
        np.testing.assert_allclose(data[ok], expected[ok], rtol=REL, atol=0, err_msg=column)
        texts = {tuple(np.round(t.get_position()).astype(int)): t.get_text() for t in ax.texts}
        for (r, c), v in np.ndenumerate(expected):
            assert _shown_ok(texts[(c, r)], v, 3), (column, r, c, texts[(c, r)])
        assert not any(t.endswith("*") for t in texts.values())  # no fit errors in these rows
        if column.endswith("change_pct"):
            assert ax.images[0].get_clim() == pytest.approx((-lim, lim), rel=REL)
        if column.startswith("wall_peak_"):  # (the peaks too: after filling, in discharge)
            assert ax.images[0].get_clim() == pytest.approx((min(peaks), max(peaks)), rel=REL)
        assert [t.get_text() for t in ax.get_yticklabels()] == [f"theta={t} deg" for t in THETAS]
        assert [t.get_text() for t in ax.get_xticklabels()] == [
            f"phiG={g} deg, phiP={p} deg" for g, p in COLS]
    assert any(np.isnan(_seed_mean("discharge_rate", r, c)) for r in range(3) for c in range(4))


def test_heatmap_of_K_stars_the_cells_where_a_run_poorly_determines_it(study):
    """As the run report says of K (error over half of it: poorly determined), the K map
    stars the cells where any seed's K has an error over half its value or no finite error;
    a row without the error column (a study written before it) is not starred."""
    plan, rows, _, _ = study
    shaky = {(2, 0, 1): 0.6, (0, 3, 0): math.nan, (1, 1, 0): 0.5}  # error / K; 0.5 is not over
    with_err = []
    for row in rows:
        r, c, s = _index(next(run for run in plan.runs if run.id == row["id"]))
        row = dict(row, janssen_K_fill_err=shaky.get((r, c, s), 0.1) * row["janssen_K_fill"])
        if (r, c, s) == (1, 2, 0):  # the only run at (1, 2): an old row, not starred
            del row["janssen_K_fill_err"]
        with_err.append(row)
    fig = fig_heatmaps(plan, {r["id"]: r for r in with_err}, layout_of(plan))
    ax = [a for a in fig.axes if a.images][HEATMAP_COLUMNS.index("janssen_K_fill")]
    starred = {tuple(np.round(t.get_position()).astype(int))[::-1] for t in ax.texts
               if t.get_text().endswith("*")}
    assert starred == {(2, 0), (0, 3)}
    assert "poorly determined (error over half the value)" in ax.get_title()
    others = [a for a in fig.axes if a.images and a is not ax]
    assert not any(t.get_text().endswith("*") for a in others for t in a.texts)


# --- Fig. 7: the switch-zone series of every case ----------------------------------------------
N_SAMPLES, DT_MEAS = 60, 0.02  # 0.2 s running mean = 10 samples = one period of PERIOD
# mean zero over its 10 samples, not over any 5 consecutive ones (nor 4, 6, 8, 12 ...)
PERIOD = [0.0, 400.0, -200.0, 600.0, -800.0, 300.0, 100.0, -700.0, 500.0, -200.0]


def _case_levels(r: int, c: int, s: int) -> tuple[float, float]:
    """(mean sigma_h, sigma_v) [Pa] of the switch zone of run (r, c, s)."""
    h, v = 2000.0 + 1000.0 * r + 250.0 * c, 4000.0 + 500.0 * c
    return (h, v) if s == 0 else (3 * h, 2 * v)  # the second seed: other levels


def _write_switch_series(plan, out: Path) -> None:
    """results.h5 of every run with the datasets Fig. 7 reads (docs/output.md /measure): the
    circles against the walls at the junction (switch_left, switch_right) are level -+ 1000 Pa
    (sigma_h) and -+ 500 Pa (sigma_v) plus a period-10 wiggle on sigma_h; the centre circle,
    not part of the switch zone, is 9e6 Pa."""
    t = DT_MEAS * np.arange(N_SAMPLES)
    phase = np.where(np.arange(N_SAMPLES) < 20, 0, np.where(np.arange(N_SAMPLES) < 35, 1, 2))
    wiggle = np.array([PERIOD[k % 10] for k in range(N_SAMPLES)])
    for run in plan.runs:
        r, c, s = _index(run)
        h, v = _case_levels(r, c, s)
        stress = np.full((N_SAMPLES, 3, 3), 9.0e6)
        stress[:, 0, 0], stress[:, 2, 0] = h - 1000 + wiggle, h + 1000 + wiggle
        stress[:, 0, 1], stress[:, 2, 1] = v - 500, v + 500
        folder = out / "runs" / run.id
        folder.mkdir(parents=True)
        with h5py.File(folder / "results.h5", "w") as f:
            m = f.create_group("measure")
            m["time"], m["phase"] = t, phase.astype(np.int8)
            m["circles/name"] = np.array([b"switch_left", b"switch_centre", b"switch_right"])
            m["circles/stress"] = stress
            f.create_group("events").attrs["discharge_start_time"] = t[35]


def test_fig7_panels_show_each_cases_switch_zone_series(study):
    """Fig. 7 (docs/sweeps.md): panel (theta[r], combination c) shows the first seed's switch
    zone (mean of the two circles against the walls) against time: sigma_h and sigma_v as 0.2 s
    running means [kPa], and the ratio sigma_h / sigma_v sampled (grey) and as a running mean.
    Closed forms: the mean of the two wall circles is level + wiggle; the wiggle has period 10
    samples and mean zero over a period only, so a 10-sample (0.2 s) mean is the level wherever
    the window is whole, and shorter windows are not."""
    plan, _, _, out = study
    lay = layout_of(plan)
    t = DT_MEAS * np.arange(N_SAMPLES)
    wiggle = np.array([PERIOD[k % 10] for k in range(N_SAMPLES)])
    inner = slice(5, N_SAMPLES - 5)  # samples whose centred 10-sample window is whole
    for ratio in (False, True):
        fig = fig_evolution(plan, out, lay, ratio=ratio)
        panels = np.array(fig.axes[: len(THETAS) * len(COLS)]).reshape(len(THETAS), len(COLS))
        for (r, c), ax in np.ndenumerate(panels):
            h, v = _case_levels(r, c, 0)
            lines = [ln for ln in ax.get_lines() if len(ln.get_xdata()) == N_SAMPLES]
            assert len(lines) == 2
            for ln in lines:
                assert np.array_equal(ln.get_xdata(), t)
            if ratio:
                raw, smooth = (np.asarray(ln.get_ydata(), dtype=float) for ln in lines)
                np.testing.assert_allclose(raw, (h + wiggle) / v, rtol=REL, atol=0)
                np.testing.assert_allclose(smooth[inner], h / v, rtol=REL, atol=0)
            else:
                sh, sv = (np.asarray(ln.get_ydata(), dtype=float) for ln in lines)
                np.testing.assert_allclose(sh[inner], h / 1e3, rtol=REL, atol=0)
                np.testing.assert_allclose(sv, v / 1e3, rtol=REL, atol=0)
        if not ratio:  # one stress scale for every case, from 0 to over the largest trace
            tops = [max(np.nanmax(ln.get_ydata()) for ln in ax.get_lines()) for ax in panels.flat]
            assert {ax.get_ylim() for ax in panels.flat} == {(0.0, 1.05 * max(tops))}


# =============================================================================================
# 2. Force-network drawings
# =============================================================================================
# walls: floor, left side, gate, a 45 deg slope; all coordinates binary-exact
WALLS = WallGeometry(["floor", "left", "gate", "slope"], np.array([0.0, 0.0, 2.0, 3.0]),
                     np.array([0.0, 2.0, 0.0, 0.0]), np.array([2.0, 0.0, 3.0, 4.0]),
                     np.array([0.0, 0.0, 0.0, 1.0]))
FLOOR, LEFT, GATE, SLOPE = range(4)


def _frame(time, phase, xy, contacts, wall_contacts, first_speed, gate_open=False) -> Frame:
    """A frame of grains at ``xy``, radii 1/16, 1/8, 3/16 in turn, grain k moving at
    0.625 (first_speed + k) m/s ((3/8, -1/2) x that: a 3-4-5 triangle), forces given as
    (i, j, fn, fs) and (grain, wall, fn, fs)."""
    n = len(xy)
    k = np.arange(n)
    speed_unit = (first_speed + k).astype(np.float32)
    particles = {"x": np.float32([p[0] for p in xy]), "y": np.float32([p[1] for p in xy]),
                 "vx": 0.375 * speed_unit, "vy": -0.5 * speed_unit,
                 "omega": np.zeros(n, np.float32),
                 "radius": np.float32(0.0625) * (1 + k % 3).astype(np.float32),
                 "fx": np.zeros(n, np.float32), "fy": np.zeros(n, np.float32),
                 "uid": 100 + k}
    c = np.array(contacts, dtype=float).reshape(-1, 4)
    w = np.array(wall_contacts, dtype=float).reshape(-1, 4)
    return Frame(time, int(time * 1000), phase, particles,
                 {"i": c[:, 0].astype(np.int32), "j": c[:, 1].astype(np.int32),
                  "fn": c[:, 2].astype(np.float32), "fs": c[:, 3].astype(np.float32)},
                 {"grain": w[:, 0].astype(np.int32), "wall": w[:, 1].astype(np.int32),
                  "fn": w[:, 2].astype(np.float32), "fs": w[:, 3].astype(np.float32)},
                 np.array([True, True, not gate_open, True]))


# the settled packing: positive normal forces 1 .. 11 (9 grain pairs, 2 walls) -> its 90th
# percentile is 10; a pair and a wall contact with F_n = 0 (shear only: touching, not drawn)
SETTLED_XY = [(0.25 + 0.25 * k, 0.375) for k in range(8)] + [
    (3.25, 0.75), (2.5, 0.25), (0.125, 1.5), (-0.25, -0.5)]
SETTLED_C = [(k, k + 1, k + 1.0, 0.25) for k in range(7)] + [
    (0, 10, 8.0, 0.0), (8, 9, 9.0, -0.5), (9, 2, 0.0, 0.5)]
SETTLED_W = [(8, SLOPE, 10.0, 0.0), (11, FLOOR, 11.0, 1.0), (10, LEFT, 0.0, 0.25)]
FILL_XY = [(0.5, 1.0), (0.75, 1.0), (2.75, 0.125), (1.0, 1.5)]
FILL_C, FILL_W = [(0, 1, 3.0, 0.0)], [(2, GATE, 1.5, 0.0)]  # gate point (2.75, 0)
DIS_XY = [(0.5, 0.5), (0.75, 0.5), (1.0, 0.5), (1.25, 0.5), (0.25, 1.0)]
DIS_C = [(0, 1, 4.0, 0.0), (1, 2, 100.0, 0.0), (2, 3, 0.0625, 0.0)]
DIS_W = [(4, LEFT, 2.0, 0.0), (3, FLOOR, 6.0, 0.0)]
# the contact points on the walls, by hand, per frame and grain: on the slope (3,0)-(4,1) seen
# from (3.25, 0.75): (3.5, 0.5); the floor's end (0, 0) from (-0.25, -0.5) (beyond the
# segment: its end point); the gate below (2.75, 0.125); the left wall beside (0.25, 1); the
# floor below (1.25, 0.5)
HAND_WALL_POINTS = {1: {8: (3.5, 0.5), 11: (0.0, 0.0)}, 0: {2: (2.75, 0.0)},
                    2: {4: (0.0, 1.0), 3: (1.25, 0.0)}}


def _frames(settled_factor: float = 1.0, discharge_factor: float = 1.0) -> Frames:
    """Filling (4 grains), the settled packing (12), a discharge frame with the gate open (5):
    21 grains in all moving at 0.625 x 1 .. 21 m/s.  The factors scale the normal forces of the
    settled and of the discharge frame."""
    def scaled(rows, f):
        return [(a, b, fn * f, fs) for a, b, fn, fs in rows]

    frames = [_frame(1.0, "fill", FILL_XY, FILL_C, FILL_W, 1),
              _frame(2.0, "settle", SETTLED_XY, scaled(SETTLED_C, settled_factor),
                     scaled(SETTLED_W, settled_factor), 5),
              _frame(3.0, "discharge", DIS_XY, scaled(DIS_C, discharge_factor),
                     scaled(DIS_W, discharge_factor), 17, gate_open=True)]
    return Frames(frames, WALLS, {"discharge_start_time": 2.0, "discharge_time": 2.0}, {},
                  "synthetic")


def _closest_on_segment(wall: int, x: float, y: float) -> tuple[float, float]:
    """Brute force: the point of segment ``wall`` nearest to (x, y), by sampling 2^16 + 1
    points of the segment (exact for the binary-exact points of these tests)."""
    s = np.linspace(0.0, 1.0, 2**16 + 1)
    px = WALLS.ax[wall] + s * (WALLS.bx[wall] - WALLS.ax[wall])
    py = WALLS.ay[wall] + s * (WALLS.by[wall] - WALLS.ay[wall])
    k = int(np.argmin((px - x) ** 2 + (py - y) ** 2))
    return float(px[k]), float(py[k])


def _drawn(artist: FrameArtist, frame: Frame) -> dict[tuple, float]:
    """{(start, end) of each drawn force line: its width [pt]}."""
    artist.draw(frame)
    chains = [c for c in artist.ax.collections if isinstance(c, LineCollection)]
    assert len(chains) == 1
    lc = chains[0]
    colours = lc.get_colors()
    assert all(rgba[0] > 0.6 and rgba[1] < 0.2 and rgba[2] < 0.3 for rgba in colours)  # red
    widths = lc.get_linewidths()
    segs = lc.get_segments()
    assert len(widths) == len(segs)
    return {(tuple(map(float, s[0])), tuple(map(float, s[1]))): float(w)
            for s, w in zip(segs, widths, strict=True)}


def _expected_lines(frame: Frame) -> dict[tuple, float]:
    """{(start, end): F_n} of the contacts with F_n > 0: centre to centre, or centre to the
    nearest point of the wall (docs/visualisation.md)."""
    x, y = frame.particles["x"].astype(float), frame.particles["y"].astype(float)
    out = {}
    c, w = frame.contacts, frame.wall_contacts
    for i, j, fn in zip(c["i"], c["j"], c["fn"], strict=True):
        if fn > 0:
            out[((x[i], y[i]), (x[j], y[j]))] = float(fn)
    for g, wall, fn in zip(w["grain"], w["wall"], w["fn"], strict=True):
        if fn > 0:
            out[((x[g], y[g]), _closest_on_segment(wall, x[g], y[g]))] = float(fn)
    return out


def test_force_lines_join_the_contact_points_with_width_proportional_to_fn():
    """Force chains (docs/visualisation.md, viz/draw.py): one line per contact with a normal
    force, from centre to centre or to the wall's nearest point (by hand: (3.5, 0.5) on the
    slope, the floor's end (0, 0), (2.75, 0) on the gate, (0, 1) and (1.25, 0)), width
    proportional to F_n on one scale for the whole run: width / F_n is the same for every
    contact of every frame except the extremes (a width cap at 100 and 1/16 N may apply), and
    the width never decreases with F_n."""
    frames = _frames()
    artist = FrameArtist(frames, "none")
    pairs = []  # (F_n, width) over all frames
    for frame in frames:
        drawn = _drawn(artist, frame)
        expected = _expected_lines(frame)
        assert drawn.keys() == expected.keys()
        pairs += [(expected[k], drawn[k]) for k in expected]
    # the brute-force nearest points agree with the ones worked out by hand
    for k, hand in ((1, HAND_WALL_POINTS[1]), (0, HAND_WALL_POINTS[0]),
                    (2, HAND_WALL_POINTS[2])):
        lines = _expected_lines(frames[k])
        for grain, point in hand.items():
            xy = tuple(float(v) for v in (frames[k].particles["x"][grain],
                                          frames[k].particles["y"][grain]))
            assert (xy, point) in lines
    assert len(pairs) == 9 + 2 + 2 + 5
    per_newton = [w / fn for fn, w in pairs if 0.5 <= fn <= 11.0]
    assert len(per_newton) == 9 + 2 + 2 + 3
    assert per_newton == pytest.approx([per_newton[0]] * len(per_newton), rel=REL)
    by_force = sorted(pairs)
    assert all(a[1] <= b[1] for a, b in itertools.pairwise(by_force))


def test_line_width_scale_is_taken_from_the_settled_packing():
    """docs/visualisation.md: the line-width scale is fixed over the run and taken from the
    settled packing.  Doubling the settled packing's forces doubles the scale (widths of that
    frame unchanged, width / F_n of every frame halved); tripling the discharge frame's forces
    alone changes nothing in the scale."""
    base = FrameArtist(_frames(), "none")
    louder = FrameArtist(_frames(discharge_factor=3.0), "none")
    assert _drawn(louder, louder.frames[1]) == pytest.approx(_drawn(base, base.frames[1]),
                                                             rel=REL)
    other = FrameArtist(_frames(settled_factor=2.0, discharge_factor=3.0), "none")
    frames_a, frames_b = base.frames, other.frames
    settled_a, settled_b = _drawn(base, frames_a[1]), _drawn(other, frames_b[1])
    assert settled_a.keys() == settled_b.keys()
    for key, width in settled_a.items():
        assert settled_b[key] == pytest.approx(width, rel=REL)
    fn_a, fn_b = _expected_lines(frames_a[1]), _expected_lines(frames_b[1])
    k_a = {k: settled_a[k] / fn_a[k] for k in fn_a}
    k_b = {k: settled_b[k] / fn_b[k] for k in fn_b}
    assert all(k_b[k] == pytest.approx(k_a[k] / 2, rel=REL) for k in k_a)
    dis_b, fn_dis_b = _drawn(other, frames_b[2]), _expected_lines(frames_b[2])
    unit_a = next(iter(k_a.values()))
    for key, fn in fn_dis_b.items():
        if 1.0 <= fn <= 20.0:  # 3 x (2, 4, 6) N: within the settled range of run B
            assert dis_b[key] / fn == pytest.approx(unit_a / 2, rel=REL)


def test_grains_drawn_to_scale_and_coloured_by_the_documented_quantity():
    """Grains to scale (docs/visualisation.md): disk diameters 2 r in data units at the grain
    centres; the colour array is |v| (3-4-5 triangles: 0.625 k m/s), the sum of each grain's
    contact normal forces, or its number of touching contacts (grains and walls, F_n = 0 shear
    contacts included), recomputed by loops over the contacts."""
    frames = _frames()
    first_speed = {0: 1, 1: 5, 2: 17}
    for colour in ("velocity", "force", "coordination"):
        artist = FrameArtist(frames, colour)
        for k, frame in enumerate(frames):
            artist.draw(frame)
            disks = [c for c in artist.ax.collections if isinstance(c, EllipseCollection)]
            assert len(disks) == 1
            d = disks[0]
            p = frame.particles
            n = frame.n
            np.testing.assert_array_equal(d.get_widths(), 2 * p["radius"].astype(float))
            np.testing.assert_array_equal(d.get_heights(), 2 * p["radius"].astype(float))
            np.testing.assert_array_equal(
                np.asarray(d.get_offsets()), np.column_stack([p["x"], p["y"]]).astype(float))
            if colour == "velocity":
                expected = 0.625 * (first_speed[k] + np.arange(n))
            else:
                expected = np.zeros(n)
                rows = [(i, j, fn) for i, j, fn in zip(frame.contacts["i"], frame.contacts["j"],
                                                       frame.contacts["fn"], strict=True)]
                walls = zip(frame.wall_contacts["grain"], frame.wall_contacts["fn"], strict=True)
                for i, j, fn in rows:
                    for g in (i, j):
                        expected[g] += float(fn) if colour == "force" else 1
                for g, fn in walls:
                    expected[g] += float(fn) if colour == "force" else 1
            np.testing.assert_array_equal(np.asarray(d.get_array(), dtype=float), expected)


def test_colour_limits_are_the_documented_run_wide_ones():
    """Colour scales fixed over the run (docs/visualisation.md): speed from 0 to the 95th
    percentile of |v| over all frames (21 grains at 0.625 x 1 .. 21 m/s: 0.625 x 20 = 12.5;
    the settled packing alone would give 0.625 x 15.45); the force colour from 0 to a limit
    taken from the settled packing (doubling its forces doubles it, tripling the discharge
    frame's changes nothing); coordination in unit bins centred on 0, 1, 2, ..."""
    frames = _frames()
    speeds = np.sort(0.625 * np.arange(1, 22))
    h = 0.95 * (speeds.size - 1)  # linear interpolation between order statistics
    p95 = speeds[int(h)] + (h - int(h)) * (speeds[int(h) + 1] - speeds[int(h)])
    assert p95 == pytest.approx(12.5, rel=REL)
    vel = FrameArtist(frames, "velocity").norm
    assert (vel.vmin, vel.vmax) == (0.0, pytest.approx(p95, rel=REL))
    force_a = FrameArtist(frames, "force").norm
    force_b = FrameArtist(_frames(settled_factor=2.0, discharge_factor=3.0), "force").norm
    force_c = FrameArtist(_frames(discharge_factor=3.0), "force").norm
    assert force_a.vmin == force_b.vmin == 0.0
    assert force_b.vmax == pytest.approx(2 * force_a.vmax, rel=REL)
    assert force_c.vmax == pytest.approx(force_a.vmax, rel=REL)
    coord = FrameArtist(frames, "coordination").norm
    for count in range(7):
        assert coord(np.array([count - 0.49, count + 0.49]))[0] == coord(np.array([count]))[0]
        assert coord(np.array([count + 1.0]))[0] > coord(np.array([count]))[0]


def test_walls_are_drawn_end_to_end_and_dotted_when_open():
    """Walls A -> B as in the frames' wall table; the open gate of the discharge frame dotted,
    every other wall (and the gate before it opens) solid (docs/visualisation.md)."""
    frames = _frames()
    artist = FrameArtist(frames, "none")
    for frame in frames:
        artist.draw(frame)
        for k, line in enumerate(artist.wall_lines):
            assert list(line.get_xdata()) == [WALLS.ax[k], WALLS.bx[k]]
            assert list(line.get_ydata()) == [WALLS.ay[k], WALLS.by[k]]
            dotted = frame.phase == "discharge" and k == GATE
            assert line.get_linestyle() == (":" if dotted else "-")
            assert to_rgba(line.get_color()) == to_rgba("k")


def test_network_moments_are_the_documented_frames():
    """viz/network.py, docs/visualisation.md: end of filling = the last frame before the gate
    opened; early / late discharge = the discharge frame nearest to 15 % / 75 % of the
    discharge duration after the opening (t_open = 2, duration 2: 2.3 and 3.5 s); a number =
    the nearest frame.  Frame times chosen so that each answer is unique by hand."""
    times = [(0.5, "fill"), (1.0, "fill"), (2.0, "settle"), (2.25, "discharge"),
             (2.5, "discharge"), (3.25, "discharge"), (3.625, "discharge"),
             (4.0, "discharge")]
    frames = Frames([_frame(t, ph, [(0.5, 0.5)], [], [], 1) for t, ph in times], WALLS,
                    {"discharge_start_time": 2.0, "discharge_time": 2.0}, {}, "s")
    assert select_frame(frames, "end-of-filling").time == 2.0
    assert select_frame(frames, "settled").time == 2.0
    assert select_frame(frames, "early-discharge").time == 2.25  # |2.25 - 2.3| < |2.5 - 2.3|
    assert select_frame(frames, "late-discharge").time == 3.625  # 0.125 < 0.25 from 3.5
    assert select_frame(frames, "final").time == 4.0
    assert select_frame(frames, 3.4).time == 3.25
    assert select_frame(frames, 0.7).time == 0.5


def test_a_discharge_moment_with_no_frame_near_it_has_no_picture():
    """Frames 1000 s apart left one discharge frame, the run's last: the picture captioned
    "early in the discharge (15 % of the discharge time)" showed 100 % of it (an audit).  A
    discharge moment's frame must lie within 0.3 of the duration of it (half the span between
    15 % and 75 %): t_open = 2, duration 2, so early is 2.3 +- 0.6 s and late 3.5 +- 0.6 s."""
    from silodem.viz.network import force_network_pngs

    times = [(1.0, "fill"), (2.0, "settle"), (3.0, "discharge"), (4.0, "discharge")]
    frames = Frames([_frame(t, ph, [(0.5, 0.5)], [], [], 1) for t, ph in times], WALLS,
                    {"discharge_start_time": 2.0, "discharge_time": 2.0}, {}, "s")
    with pytest.raises(ValueError, match="no 'early-discharge' picture: the saved frame nearest "
                       "to 15 % of the discharge time is at 50 % of it"):
        select_frame(frames, "early-discharge")  # 3.0 is 0.7 s from 2.3: too far
    assert select_frame(frames, "late-discharge").time == 3.0  # 0.5 s from 3.5: near enough
    assert sorted(force_network_pngs(frames)) == ["end-of-filling", "late-discharge"]


# =============================================================================================
# 3. /frames and VTK files of a real run, against the engine's state
# =============================================================================================
PARTICLE_FIELDS = ("x", "y", "vx", "vy", "omega", "radius", "fx", "fy")
PHASE_CODE = {"fill": 0, "settle": 1, "discharge": 2}  # docs/output.md
# float32 rounding of a coordinate of a silo a few metres across (2 ulp at 4 m)
POINT_TOL = 2 * float(np.spacing(np.float32(4.0)))


def _engine_state(run) -> dict:
    """The state as the engine holds it: its live grain arrays and its contact arrays, where a
    pair or wall contact that does not touch stores F_n = F_s = 0 (ARCHITECTURE.md)."""
    sim, p, nb = run.sim, run.sim.particles, run.sim.neighbors
    n = p.n
    state = {"time": float(sim.time), "steps": int(sim.steps), "phase": run.phase,
             "active": np.array(run.walls.active, dtype=bool)}
    state.update({k: np.array(getattr(p, k)[:n]) for k in (*PARTICLE_FIELDS, "uid")})
    touch = (nb.pair_fn != 0) | (nb.pair_fs != 0)
    state["pairs"] = {"i": np.array(nb.pair_i)[touch], "j": np.array(nb.pair_j)[touch],
                      "fn": np.array(nb.pair_fn)[touch], "fs": np.array(nb.pair_fs)[touch]}
    wt = (nb.wc_fn != 0) | (nb.wc_fs != 0)
    state["walls"] = {"grain": np.array(nb.wc_i)[wt], "wall": np.array(nb.wc_w)[wt],
                      "fn": np.array(nb.wc_fn)[wt], "fs": np.array(nb.wc_fs)[wt]}
    return state


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A tiny hopper run (frames every 0.1 s, VTK every 0.5 s; the frames written out to
    segment files whenever they pass 20 kB, and at every save); each time the frames recorder
    keeps a frame or writes VTK files, the engine's state is copied here."""
    out = tmp_path_factory.mktemp("frames") / "run"
    cfg = tiny_hopper_config(report=False)
    cfg = cfg.model_copy(update={"output": Output(png=False, vtk_interval=0.5)})
    frame_states, vtk_states, walls = [], [], {}
    record, phase_ended = FramesRecorder.record, FramesRecorder.phase_ended

    def capture(rec, run, n_frames, n_vtk):
        if not walls:
            walls.update(names=list(run.walls.names),
                         **{k: np.array(getattr(run.walls, k)) for k in ("ax", "ay", "bx", "by")})
        if rec.count > n_frames or len(rec.vtk_times) > n_vtk:
            state = _engine_state(run)
            if rec.count > n_frames:
                frame_states.append(state)
            if len(rec.vtk_times) > n_vtk:
                vtk_states.append(state)

    def spy_record(self, run):
        before = self.count, len(self.vtk_times)
        record(self, run)
        capture(self, run, *before)

    def spy_phase_ended(self, run, phase):
        before = self.count, len(self.vtk_times)
        phase_ended(self, run, phase)
        capture(self, run, *before)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(FramesRecorder, "record", spy_record)
        mp.setattr(FramesRecorder, "phase_ended", spy_phase_ended)
        mp.setattr(frame_store, "PENDING_BYTES", 20_000)  # segments written while recording
        run_simulation(cfg, out, progress=False)
    assert len(frame_states) >= 50 and len(vtk_states) >= 10
    assert len(list((out / "frames").glob("frames-*.h5"))) >= 5
    return out, frame_states, vtk_states, walls


def _by_uid(uid: np.ndarray) -> np.ndarray:
    return np.argsort(uid, kind="stable")


def _check_frame(state: dict, tables: dict) -> None:
    """``tables`` (particles / contacts / wall_contacts arrays of one frame) hold ``state``:
    every grain field equal to the engine's, rounded to float32 once; the same touching
    contacts, matched through the grains' permanent ids, with their forces."""
    p = tables["particles"]
    assert np.array_equal(np.sort(p["uid"]), np.sort(state["uid"]))
    mine, theirs = _by_uid(state["uid"]), _by_uid(p["uid"])
    for key in PARTICLE_FIELDS:
        assert p[key].dtype == np.float32, key
        assert np.array_equal(p[key][theirs], state[key][mine].astype(np.float32)), key
    uid_f, uid_s = p["uid"], state["uid"]
    pairs, c = state["pairs"], tables["contacts"]
    engine = {tuple(sorted((uid_s[i], uid_s[j]))): (fn, fs) for i, j, fn, fs in
              zip(pairs["i"], pairs["j"], pairs["fn"], pairs["fs"], strict=True)}
    saved = {tuple(sorted((uid_f[i], uid_f[j]))): (fn, fs) for i, j, fn, fs in
             zip(c["i"], c["j"], c["fn"], c["fs"], strict=True)}
    assert len(saved) == c["i"].size == len(engine) == pairs["i"].size
    assert saved.keys() == engine.keys()
    for key, (fn, fs) in engine.items():
        assert saved[key] == (np.float32(fn), np.float32(fs)), key
    w, ws = tables["wall_contacts"], state["walls"]
    engine_w = {(uid_s[g], wall): (fn, fs) for g, wall, fn, fs in
                zip(ws["grain"], ws["wall"], ws["fn"], ws["fs"], strict=True)}
    saved_w = {(uid_f[g], wall): (fn, fs) for g, wall, fn, fs in
               zip(w["grain"], w["wall"], w["fn"], w["fs"], strict=True)}
    assert len(saved_w) == w["grain"].size and saved_w.keys() == engine_w.keys()
    for key, (fn, fs) in engine_w.items():
        assert saved_w[key] == (np.float32(fn), np.float32(fs)), key


def test_results_walls_hold_the_geometry_and_series_stiffness_with_units(recorded):
    """results.h5 /walls as docs/output.md has it: the segments the run had [m], and the
    contact stiffnesses of grain and wall in series, k_g k_w / (k_g + k_w) [N/m] (PFC2D's
    convention, written here from the config), each dataset with its unit."""
    out, _, _, walls = recorded
    cfg = tiny_hopper_config(report=False)
    with h5py.File(out / "results.h5", "r") as f:
        g = f["walls"]
        assert [n.decode() for n in g["name"][()]] == walls["names"]
        for key in ("ax", "ay", "bx", "by"):
            assert np.array_equal(g[key][()], walls[key]) and g[key].attrs["unit"] == "m"
        for key in ("kn", "ks"):
            k_g, k_w = getattr(cfg.material, key), getattr(cfg.walls, key)
            np.testing.assert_allclose(g[key][()], k_g * k_w / (k_g + k_w), rtol=1e-12)
            assert g[key].attrs["unit"] == "N/m"


def test_frames_in_results_h5_hold_the_engine_state(recorded):
    """results.h5 /frames read with h5py by the layout of docs/output.md (frame k owns rows
    offset[k]:offset[k+1]; contact indices count from the frame's first grain): one frame per
    recorder save, time / step / phase code / walls in place as the run had them, offsets = the
    running sums of the engine's grain and touching-contact counts, every field the engine's
    value (float32), and read_frames gives the same."""
    out, states, _, _ = recorded
    with h5py.File(out / "results.h5", "r") as f:
        g = f["frames"]
        data = {}
        g.visititems(lambda name, obj: data.__setitem__(name, obj[()])
                     if isinstance(obj, h5py.Dataset) else None)
        assert g.attrs["count"] == len(states)
    assert np.array_equal(data["time"], [s["time"] for s in states])
    assert np.array_equal(data["step"], [s["steps"] for s in states])
    assert np.array_equal(data["phase"], [PHASE_CODE[s["phase"]] for s in states])
    assert np.array_equal(data["walls_active"], np.stack([s["active"] for s in states]))
    assert {s["phase"] for s in states} == set(PHASE_CODE)
    for name, count in (("particle_offset", lambda s: s["uid"].size),
                        ("contact_offset", lambda s: s["pairs"]["i"].size),
                        ("wall_contact_offset", lambda s: s["walls"]["grain"].size)):
        running = np.cumsum([0] + [count(s) for s in states])
        assert np.array_equal(data[name], running), name
    assert data["contact_offset"][-1] > 1000 and data["wall_contact_offset"][-1] > 100
    po, co, wo = data["particle_offset"], data["contact_offset"], data["wall_contact_offset"]
    fields = {"particles": (*PARTICLE_FIELDS, "uid"), "contacts": ("i", "j", "fn", "fs"),
              "wall_contacts": ("grain", "wall", "fn", "fs")}
    frames = read_frames(out / "results.h5")
    assert len(frames) == len(states)
    for k, state in enumerate(states):
        rows = {"particles": slice(po[k], po[k + 1]), "contacts": slice(co[k], co[k + 1]),
                "wall_contacts": slice(wo[k], wo[k + 1])}
        tables = {t: {key: data[f"{t}/{key}"][rows[t]] for key in keys}
                  for t, keys in fields.items()}
        _check_frame(state, tables)
        f = frames[k]
        assert (f.time, f.step, f.phase) == (state["time"], state["steps"], state["phase"])
        _check_frame(state, {"particles": f.particles, "contacts": f.contacts,
                             "wall_contacts": f.wall_contacts})


def test_frame_quantities_equal_loops_over_the_engine_contacts(recorded):
    """Frame.coordination(), normal_force_sum(), force(), speed() (docs/visualisation.md) of
    every saved frame against loops over the engine's touching contacts: counts exactly, sums
    of F_n to float32 rounding (2 ulp), |F| and |v| to float32 rounding."""
    out, states, _, _ = recorded
    frames = read_frames(out / "results.h5")
    for f, s in zip(frames, states, strict=True):
        index = {u: k for k, u in enumerate(s["uid"].tolist())}
        order = np.array([index[u] for u in f.particles["uid"].tolist()])
        count, fsum = np.zeros(s["uid"].size), np.zeros(s["uid"].size)
        for i, j, fn in zip(s["pairs"]["i"], s["pairs"]["j"], s["pairs"]["fn"], strict=True):
            count[i] += 1
            count[j] += 1
            fsum[i] += fn
            fsum[j] += fn
        for g, fn in zip(s["walls"]["grain"], s["walls"]["fn"], strict=True):
            count[g] += 1
            fsum[g] += fn
        assert np.array_equal(f.coordination(), count[order])
        np.testing.assert_allclose(f.normal_force_sum(), fsum[order], rtol=2 * F32_ULP, atol=0)
        np.testing.assert_allclose(f.force(), np.hypot(s["fx"], s["fy"])[order],
                                   rtol=2 * F32_ULP, atol=1e-30)
        np.testing.assert_allclose(f.speed(), np.hypot(s["vx"], s["vy"])[order],
                                   rtol=2 * F32_ULP, atol=1e-30)


def test_vtk_fields_hold_the_engine_state(recorded):
    """The VTK fields tests/test_visualisation.py does not check, against the engine's state at
    each VTK output (docs/visualisation.md): the .pvd times are the run's times exactly;
    particles: force_vector = (fx, fy, 0), normal_force_sum = the loop sum of F_n over the
    grain's contacts; contacts: one line per touching contact with kind 0 / 1, normal and shear
    force of that contact, a grain-wall line from the centre to the wall's nearest point
    (the orthogonal projection onto the segment's line, clamped to the segment, computed
    here; to float32 rounding); walls: every segment
    A -> B exactly, wall_id indexing /walls/name."""
    out, _, states, walls = recorded
    vtk = out / "vtk"
    pvd = [(float(d.get("timestep")), d.get("file"))
           for d in ET.parse(vtk / "particles.pvd").getroot().iter("DataSet")]
    assert [t for t, _ in pvd] == [s["time"] for s in states]
    with h5py.File(out / "results.h5", "r") as f:
        names = [n.decode() for n in f["walls/name"][()]]
    assert names == walls["names"]
    geometry = WallGeometry(walls["names"], walls["ax"], walls["ay"], walls["bx"], walls["by"])
    checked_wall_lines = 0
    for k, s in enumerate(states):
        n = s["uid"].size
        m = meshio.read(vtk / f"particles_{k:06d}.vtu")
        pd = m.point_data
        index = {u: q for q, u in enumerate(s["uid"].tolist())}
        order = np.array([index[u] for u in pd["uid"].tolist()])
        fv = pd["force_vector"]
        assert fv.dtype == np.float32
        assert np.array_equal(fv[:, 0], s["fx"][order].astype(np.float32))
        assert np.array_equal(fv[:, 1], s["fy"][order].astype(np.float32))
        assert not fv[:, 2].any()
        fsum = np.zeros(n)
        for i, j, fn in zip(s["pairs"]["i"], s["pairs"]["j"], s["pairs"]["fn"], strict=True):
            fsum[i] += fn
            fsum[j] += fn
        for g, fn in zip(s["walls"]["grain"], s["walls"]["fn"], strict=True):
            fsum[g] += fn
        np.testing.assert_allclose(pd["normal_force_sum"], fsum[order], rtol=2 * F32_ULP,
                                   atol=0)
        # contacts: read only when there are some (meshio 5.3 cannot read an empty one)
        n_pairs, n_walls = s["pairs"]["i"].size, s["walls"]["grain"].size
        cname = vtk / f"contacts_{k:06d}.vtu"
        piece = ET.parse(cname).getroot().find(".//Piece")
        assert int(piece.get("NumberOfCells")) == n_pairs + n_walls
        if n_pairs + n_walls:
            mc = meshio.read(cname)
            assert np.array_equal(mc.points[:n], m.points)  # the grains first, same order
            lines = mc.cells_dict["line"]
            kind = mc.cell_data["kind"][0]
            fn_c, fs_c = mc.cell_data["normal_force"][0], mc.cell_data["shear_force"][0]
            assert np.count_nonzero(kind == 0) == n_pairs
            assert np.count_nonzero(kind == 1) == n_walls
            uid_pt = pd["uid"]  # the first n points are the grains, in particle-file order
            uid_s = s["uid"]
            pairs = {tuple(sorted((uid_s[i], uid_s[j]))): (np.float32(fn), np.float32(fs))
                     for i, j, fn, fs in zip(*(s["pairs"][q] for q in ("i", "j", "fn", "fs")),
                                             strict=True)}
            wall_of = {(uid_s[g], np.float32(fn), np.float32(fs)): wall
                       for g, wall, fn, fs in zip(*(s["walls"][q] for q in
                                                    ("grain", "wall", "fn", "fs")),
                                                  strict=True)}
            assert len(wall_of) == n_walls
            for (a, b), kd, fn, fs in zip(lines, kind, fn_c, fs_c, strict=True):
                if kd == 0:
                    assert a < n and b < n
                    assert pairs[tuple(sorted((uid_pt[a], uid_pt[b])))] == (fn, fs)
                    continue
                assert a < n <= b
                wall = wall_of[(uid_pt[a], fn, fs)]
                gx, gy = (float(v) for v in mc.points[a, :2])
                px, py = _closest_on_segment_of(geometry, wall, gx, gy)
                for got, want in zip(mc.points[b, :2], (px, py), strict=True):
                    assert abs(float(got) - want) <= POINT_TOL
                checked_wall_lines += 1
        mw = meshio.read(vtk / f"walls_{k:06d}.vtu")
        ends = mw.points[mw.cells_dict["line"]]
        ids = mw.cell_data["wall_id"][0]
        assert sorted(ids.tolist()) == list(range(len(names)))
        for (a, b), wid in zip(ends, ids, strict=True):
            assert tuple(a) == (walls["ax"][wid], walls["ay"][wid], 0.0)
            assert tuple(b) == (walls["bx"][wid], walls["by"][wid], 0.0)
    assert checked_wall_lines > 50


def _closest_on_segment_of(geometry: WallGeometry, wall: int, x: float, y: float):
    """The point of segment A-B nearest to (x, y): the orthogonal projection onto the line,
    clamped to the segment (float64)."""
    ax, ay, bx, by = (float(getattr(geometry, c)[wall]) for c in ("ax", "ay", "bx", "by"))
    dx, dy = bx - ax, by - ay
    t = min(max(((x - ax) * dx + (y - ay) * dy) / (dx * dx + dy * dy), 0.0), 1.0)
    return ax + t * dx, ay + t * dy
