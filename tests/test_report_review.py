"""The run report's figures after a visual review: the walls of the stress fields as they
stood, the switch-zone ratio without its near-empty samples, profile axes cut above a low
fill, the errors of the fill -> discharge changes, and where the flow pattern is read.

Expected values are worked by hand from the constructed series (the synthetic results of
test_report_numbers) or from what the silo procedure does (the gate is closed until the
discharge starts)."""

from __future__ import annotations

import copy
import dataclasses
import math
import statistics

import h5py
import numpy as np
import pytest
from matplotlib.colors import to_hex
from matplotlib.container import BarContainer
from matplotlib.patches import Rectangle
from measure_helpers import tiny_hopper_config
from test_report_numbers import SURF_FILL, _number, _pct, write_synthetic

from silodem.report import figures_stress as fs
from silodem.report.analysis import EdgeProfile, analyse, batch_mean_error
from silodem.report.html import FIGURES
from silodem.report.load import load_results
from silodem.report.numbers import percent_change_error, resolved, significant
from silodem.run import run_simulation


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """Analysis of a small hopper run with discharge (its results.h5 has every group)."""
    out = tmp_path_factory.mktemp("review") / "run"
    run_simulation(tiny_hopper_config(), out, progress=False)
    return analyse(load_results(out))


@pytest.fixture(scope="module")
def synth(tmp_path_factory):
    return analyse(load_results(write_synthetic(tmp_path_factory.mktemp("synth") / "run")))


def _caption(name: str) -> str:
    return next(spec.caption for spec in FIGURES if spec.name == name)


# --- 1. the stress fields draw the walls as they stood ---------------------------------------

def _gate_styles(fig, walls) -> dict[str, str]:
    """Row ("settled", "discharge") -> linestyle of the gate's line in that row's maps."""
    gate = list(walls["name"]).index("gate")
    xy = ([walls["ax"][gate], walls["bx"][gate]], [walls["ay"][gate], walls["by"][gate]])
    styles: dict[str, set[str]] = {}
    for ax in fig.axes:
        row = ax.get_title().rsplit(", ", 1)[-1]
        for line in ax.get_lines():
            if np.allclose(line.get_xdata(), xy[0]) and np.allclose(line.get_ydata(), xy[1]):
                styles.setdefault(row, set()).add(line.get_linestyle())
    assert all(len(s) == 1 for s in styles.values()), styles
    return {row: s.pop() for row, s in styles.items()}


def test_stress_fields_draw_the_gate_closed_when_settled_and_open_in_discharge(run):
    """The gate is withdrawn only when the discharge starts (silo.procedure): the settled
    row draws it solid, the discharge row dotted (docs: dotted = withdrawn).  Before, both
    rows drew the run's last state, the open gate."""
    walls = run.res.group("walls")
    gate = list(walls["name"]).index("gate")
    assert not walls["active"][gate]  # the last state: open (what both rows drew)
    assert run.res.snapshot("settled")["walls_active"].all()
    assert _gate_styles(fs.fig_fields(run), walls) == {"settled": "-", "discharge": ":"}


def test_walls_of_a_field_window_without_its_snapshot():
    """No snapshot: every wall stands while settling; the discharge takes /walls/active."""
    walls = {"ax": np.zeros(3), "active": np.array([True, True, False])}
    res = type("Res", (), {"group": lambda self, name: walls,
                           "snapshot": lambda self, name: None})()
    a = type("A", (), {"res": res})()
    assert fs.walls_active_in(a, "settled").tolist() == [True, True, True]
    assert fs.walls_active_in(a, "discharge").tolist() == [True, True, False]


# --- 2. the ratio of Fig. 7 leaves out near-empty samples ------------------------------------

def test_fig7_ratio_leaves_out_the_samples_with_almost_no_vertical_stress(tmp_path):
    """Three circles, sigma_h / sigma_v = 0.5, 1 and 0.5 wherever they are loaded, and one
    near-empty stretch each: circle 0 sample 40 (sigma_v = 1e-3 Pa, ratio 5e4), circle 1
    sample 60 (sigma_v = 50 Pa < 0.1 x its median 2000 Pa, ratio 3), circle 2 samples 0-9
    (sigma_v = 20 Pa < 0.1 x 600 Pa, ratio 5).  Drawn: 0.5, 1, 0.5 or a gap, never more;
    nothing above the axis' end of 3 is left to name."""
    folder = write_synthetic(tmp_path / "run")
    with h5py.File(folder / "results.h5", "r+") as h5:
        stress = h5["measure/circles/stress"][()]
        stress[:, 0, :2] = [500.0, 1000.0]
        stress[40, 0, :2] = [50.0, 1e-3]
        stress[:, 1, :2] = [2000.0, 2000.0]
        stress[60, 1, :2] = [150.0, 50.0]
        stress[:, 2, :2] = [300.0, 600.0]
        stress[:10, 2, :2] = [100.0, 20.0]
        h5["measure/circles/stress"][...] = stress
    a = analyse(load_results(folder))
    fig = fs.fig_evolution(a)
    ax2 = next(ax for ax in fig.axes if ax.get_ylabel() == "sigma_h / sigma_v [-]")
    ratios = {line.get_label(): np.asarray(line.get_ydata(), dtype=float)
              for line in ax2.get_lines()}
    for name, value in (("switch_left", 0.5), ("switch_centre", 1.0), ("switch_right", 0.5)):
        r = ratios[name]
        assert np.all(r[np.isfinite(r)] == pytest.approx(value, rel=1e-12)), name
    assert np.isfinite(ratios["switch_left"]).all()  # one sample left out: its neighbours
    assert np.isnan(ratios["switch_right"][:4]).all()  # 0.2 s with no loaded sample: a gap
    assert not ax2.texts  # no "axis cut at 3" left
    assert "under 0.1 x its median over the run left out" in ax2.get_title()
    assert "under 0.1 x its median over the run" in _caption("fig7_switch_zone_evolution")


# --- 3. profile axes end above a low fill ----------------------------------------------------

def _edge(z, sigma_n, tau_down) -> EdgeProfile:
    z = np.asarray(z, dtype=float)
    return EdgeProfile(z, np.asarray(sigma_n, float), np.asarray(tau_down, float),
                       np.ones(z.size, bool), {})


def test_profile_top_is_the_fill_plus_a_margin_when_the_fill_is_low(synth):
    """Wall 2.4 m tall (cut only when the axis would end under 0.8 x 2.4 = 1.92 m), mean
    diameter 0.1 m.  Loaded bins up to 1.25 m (the 1.75 m bin is 0), surface 1.1 m: the axis
    ends at 1.25 + max(0.2 x 1.25, 2 x 0.1) = 1.5 m; with a 0.2 m grain 1.25 + 0.4 = 1.65 m;
    a surface of 1.7 m gives 1.7 x 1.2 = 2.04 m > 1.92 m: the whole wall, as does a run with
    no surface and no loaded bin."""
    a = copy.copy(synth)
    a.geom = {**synth.geom, "top": 2.4, "d": 0.1}
    a.edge = {"fill": _edge([0.25, 0.75, 1.25, 1.75], [900, 500, 100, 0], [50, 20, 0, 0])}
    a.strips = {"fill": {"z": np.array([0.2, 0.6, 1.0]), "near_xx": np.array([1.0, 1.0, 0.0]),
                         "near_zz": np.array([1.0, 1.0, np.nan]),
                         "slice_zz": np.array([1.0, 1.0, 1.0])}}
    a.surface = {"fill": 1.1, "discharge": 0.5}
    assert fs.profile_top(a) == pytest.approx(1.5, rel=1e-12)
    a.geom = {**a.geom, "d": 0.2}
    assert fs.profile_top(a) == pytest.approx(1.65, rel=1e-12)
    a.surface = {"fill": 1.7, "discharge": 0.5}
    assert fs.profile_top(a) == 2.4
    a.surface = {"fill": math.nan}
    a.edge, a.strips = {"fill": _edge([0.25], [0.0], [0.0])}, {}
    assert fs.profile_top(a) == 2.4


def test_profile_figures_end_their_z_axis_above_a_low_fill(synth):
    """The synthetic silo: wall 2.4 m (the tiny hopper's), surface 1.36 m, loaded wall bins up
    to 1.25 m once the shear of the unloaded bins above is taken away, Love-Weber strips to
    0.98 m: Figs. 3a, 3b, 6 and the wall shear end at 1.36 x 1.2 = 1.632 m and say where the
    wall ends; with the shear there (a stress drawn at 2.25 m) they keep the whole wall."""
    a = copy.copy(synth)
    a.edge = {k: dataclasses.replace(e, tau_down=np.where(e.sigma_n > 0, e.tau_down, 0.0))
              for k, e in synth.edge.items()}
    figs = [fs.fig_horizontal(a, "fill"), fs.fig_vertical(a, "fill"),
            fs.fig_horizontal(a, "discharge"), fs.fig_wall_shear(a)]
    for fig in figs:
        ax = fig.axes[0]
        assert ax.get_ylim() == pytest.approx((0.0, 1.2 * SURF_FILL), rel=1e-12)
        assert ax.get_ylabel() == "z [m] (axis cut above the fill; the wall's top: z = 2.4 m)"
    ax = fs.fig_wall_shear(synth).axes[0]
    assert ax.get_ylim() == (0.0, 2.4) and ax.get_ylabel() == "z [m]"


# --- 4. the changes fill -> discharge carry their errors -------------------------------------

def test_batch_mean_error_by_hand():
    """Ten samples in 5 blocks of 2: block means 2, 2, 3, 2, 3, their standard deviation
    sqrt(0.3), over sqrt(5): sqrt(0.06).  NaN samples are skipped; under 5 samples: NaN."""
    v = [1, 3, 2, 2, 5, 1, 0, 4, 3, 3]
    assert batch_mean_error(v) == pytest.approx(math.sqrt(0.06), rel=1e-12)
    assert batch_mean_error(v[:2] + [np.nan] + v[2:]) == pytest.approx(math.sqrt(0.06),
                                                                      rel=1e-12)
    assert math.isnan(batch_mean_error([1.0, 2.0, 3.0, 4.0]))
    assert batch_mean_error([7.0] * 5) == 0.0


def test_percent_change_error_and_resolution_by_hand():
    """2000 +- 100 -> 3000 +- 300: +50 %, error 100 sqrt((300/2000)^2 + (3000 x 100/2000^2)^2)
    = 100 sqrt(0.028125) = 16.8 %: resolved; +10 % +- 16.8 % is not, nor is a change with no
    error."""
    err = percent_change_error(2000.0, 100.0, 3000.0, 300.0)
    assert err == pytest.approx(100 * math.sqrt(0.0225 + 0.005625), rel=1e-12)
    assert resolved(50.0, err) and resolved(-50.0, err)
    assert not resolved(10.0, err) and not resolved(-10.0, err)
    assert not resolved(50.0, math.nan)
    assert math.isnan(percent_change_error(0.0, 1.0, 3000.0, 300.0))


def _se(block_means: list[float]) -> float:
    return statistics.stdev(block_means) / math.sqrt(len(block_means))


# the synthetic switch_left circle (test_report_numbers): 6 fill samples in blocks of
# 2, 1, 1, 1, 1 and 8 discharge samples in blocks of 2, 2, 2, 1, 1
LEFT_H = (10000 / 6, _se([2000, 1500, 2500, 2000, 0]), 1800.0, _se([1800] * 3 + [2200, 1400]))
LEFT_V = (20000 / 6, _se([4000] * 4 + [0]), 4000.0, 0.0)
# the wall peaks: 4500 x (0.5, 1.5, 0.75, 1.25, 1, 1) at z = 0.5 m, 6500 x (0.5, 1.5) x 4 at
# z = 0.375 m
PEAK = (4500.0, 4500 * _se([1.0, 0.75, 1.25, 1.0, 1.0]), 6500.0, 6500 * _se([1, 1, 1, 0.5, 1.5]))


def _pct_err(f, f_err, d, d_err) -> float:
    return 100.0 * math.sqrt((d_err / f) ** 2 + (d * f_err / f**2) ** 2)


def test_changes_of_the_report_carry_their_batch_means_errors(synth):
    row = synth.change["switch_left"]
    for comp, (f, f_err, d, d_err) in (("sigma_h", LEFT_H), ("sigma_v", LEFT_V)):
        assert row[f"{comp}_fill_err"] == pytest.approx(f_err, rel=1e-12)
        assert row[f"{comp}_discharge_err"] == pytest.approx(d_err, rel=1e-12, abs=1e-9)
        assert row[f"{comp}_change_pct_err"] == pytest.approx(_pct_err(f, f_err, d, d_err),
                                                               rel=1e-12)
    peak = synth.change["wall peak"]
    assert peak["sigma_h_change_pct_err"] == pytest.approx(_pct_err(*PEAK), rel=1e-12)
    # the key numbers: +8 % +- 29 % and +20 % +- 29 % are within their errors
    h, v = _pct(LEFT_H[0], LEFT_H[2]), _pct(LEFT_V[0], LEFT_V[2])
    h_err, v_err = _pct_err(*LEFT_H), _pct_err(*LEFT_V)
    assert h < h_err and v < v_err
    within = " (within its error: not resolved)"
    assert _number(synth, "change fill -> discharge, switch_left") == (
        f"h {significant(h, 3)} +- {significant(h_err, 2)}{within}, "
        f"v {significant(v, 3)} +- {significant(v_err, 2)}{within}")
    # the peak-to-peak change, +44 % +- 26 %, is resolved
    text = _number(synth, "change fill -> discharge, wall peak")
    assert text == f"{significant(_pct(4500, 6500), 3)} +- {significant(_pct_err(*PEAK), 2)}"


def test_fig8_draws_the_errors_and_pales_the_changes_within_them(synth):
    """Bars' error bars are +- the errors above; the switch_left bars (within their errors)
    are pale, the centre's sigma_v bar (+50 % +- 0: constant in both windows) is not."""
    fig = fs.fig_change(synth)
    ax = fig.axes[0]
    bars = {c.get_label(): c for c in ax.containers if isinstance(c, BarContainer)}
    names = [t.get_text() for t in ax.get_xticklabels()]
    left, centre = names.index("switch_left"), names.index("switch_centre")
    for label, case in (("horizontal stress", LEFT_H), ("vertical stress", LEFT_V)):
        container = bars[label]
        segment = container.errorbar.lines[2][0].get_segments()[left]
        assert 0.5 * (segment[1][1] - segment[0][1]) == pytest.approx(_pct_err(*case),
                                                                       rel=1e-9)
        assert container.patches[left].get_alpha() == 0.35
    assert bars["vertical stress"].patches[centre].get_alpha() is None
    assert "not resolved" in _caption("fig8_change")
    # the key of the pale bars is drawn in the bars' own two colours, pale (it was grey)
    legend = ax.get_legend()
    assert [t.get_text() for t in legend.get_texts()] == [
        "horizontal stress", "vertical stress", "pale: within its error, not resolved"]
    keys = [(to_hex(r.get_facecolor(), keep_alpha=False), r.get_alpha())
            for r in legend.findobj(Rectangle) if r is not legend.legendPatch]
    colours = [to_hex(bars[name].patches[centre].get_facecolor(), keep_alpha=False)
               for name in ("horizontal stress", "vertical stress")]
    # each kind's key in full colour (switch_left's pale first bar gave it a pale key) and the
    # pale bars' key in both colours, pale
    assert keys == [(colours[0], None), (colours[1], None), (colours[0], 0.35),
                    (colours[1], 0.35)]


# --- 5. where the flow pattern is read ---------------------------------------------------------

def test_the_flow_pattern_says_where_it_is_measured(synth):
    """The band of the mass flow index (mfi_band_lo/hi = 0.6/0.9 m in the synthetic file)
    lies in the cell just above the junction; the label says it and that this is no Jenike
    chart; a flat silo's is just above the floor."""
    label = next(q for q, _, _ in synth.numbers if q.startswith("flow pattern"))
    assert label == ("flow pattern, measured: mass flow if v_wall / v_axis >= 0.3 (in the cell "
                     "just above the junction, z = 0.6 - 0.9 m) and no dead zone; not "
                     "Jenike's hopper design chart")
    assert any(q == "mass flow index v_wall / v_axis, in the cell just above the junction, "
               "z = 0.6 - 0.9 m" for q, _, _ in synth.numbers)
    from silodem.report.key_numbers import mfi_where

    flat = copy.copy(synth)
    flat.res = copy.copy(synth.res)
    cfg = synth.res.cfg
    flat.res.cfg = cfg.model_copy(update={"silo": cfg.silo.model_copy(update={"kind": "flat"})})
    assert mfi_where(flat) == "just above the floor, z = 0.6 - 0.9 m"
    caption = _caption("velocity_field")
    assert "just above the junction" in caption and "not Jenike's" in caption
