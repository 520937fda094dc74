"""The numbers a user reads in a run's report.html (``silodem.report.analysis.analyse``) and in
a study's results.csv (``silodem.study.table``), checked against values from outside the code.

* Synthetic results.h5 files written here with h5py following docs/output.md, whose series are
  built so that every reported number has a closed form (window means, ratios, coefficients of
  variation, % changes, profile peaks, a discharged mass exactly linear in time, grains placed by
  hand for the surface height and the bulk density, a wall profile that is exactly Janssen's).
* One tiny real run (tests/measure_helpers.py), whose numbers are recomputed here with plain
  NumPy on the raw datasets of its results.h5, from the definitions in docs/measurements.md and
  docs/sweeps.md, without calling the code under test.

Geometry of ``tiny_hopper_config``: B = 1.2 m, D = 0.4 m, theta = 50 deg, radii in
[0.045, 0.055] m (mean diameter d = 0.1 m), rho = 800 kg/m^3, t = 1 m, phi_P = 24 deg.
"""

from __future__ import annotations

import copy
import dataclasses
import itertools
import math
import types
from pathlib import Path

import h5py
import numpy as np
import pytest
from measure_helpers import tiny_hopper_config

from silodem.output import write_text
from silodem.report.analysis import (
    analyse,
    column_tops,
    surface_height,
)
from silodem.report.eurocode import _hopper_numbers, add_loads, highest_wall_contact, hopper_loads
from silodem.report.key_numbers import _fmt, add_numbers
from silodem.report.load import load_results
from silodem.report.numbers import pascals, significant
from silodem.run import run_simulation
from silodem.scenario_files import config_to_toml
from silodem.study.table import (
    COLUMNS,
    _ratio_stats,
    read_table,
    summarise_run,
    table_columns,
    table_csv,
    table_rows,
)

REL = 1e-12  # exact constructions: only float round-off
FIT_REL = 1e-9  # least-squares optimisers (curve_fit) on exact data, far above their round-off
NAN = float("nan")

# --- the tiny hopper, from its config numbers and the formulas of docs/measurements.md --------
B, D_OUT, THETA, G = 1.2, 0.4, 50.0, 9.81
DIAM = 0.045 + 0.055  # mean diameter = 2 x mean radius of radii uniform in [r_min, r_max]
RHO, THICK = 800.0, 1.0
MU_WALL = math.tan(math.radians(24.0))  # tan(phi_P)
Z_J = 0.5 * (B - D_OUT) * math.tan(math.radians(THETA))  # z_j = (B - D)/2 tan(theta)
SWITCH = (Z_J - 2 * DIAM, Z_J + 2 * DIAM)  # junction +- two mean diameters
N_COLS = 12  # columns of width d across B = 1.2 m

# --- the synthetic run: time grid and windows ---------------------------------------------------
# measure samples every 1/16 s, at k/16 + 1/32 (binary-exact, never on a window edge);
# phase 0 (fill) up to t = 2.625, 1 (settle) up to the gate opening T_OPEN = 3, then 2.
WINDOW, DELAY, T_OPEN = 0.5, 0.25, 3.0
T_MEAS = np.arange(80) / 16 + 1 / 32
FILL_K = np.arange(42, 48)  # settle samples in [T_OPEN - WINDOW, T_OPEN]: 2.65625 .. 2.96875
DIS_K = np.arange(52, 60)  # discharge samples in [T_OPEN + DELAY, + WINDOW]: 3.28125 .. 3.71875
JUNK = 9.0e6  # value of every sample outside the windows: any leak shows


def _phase(t: np.ndarray, settle_from: float = 2.625) -> np.ndarray:
    return np.where(t < settle_from, 0, np.where(t < T_OPEN, 1, 2)).astype(np.int8)


# switch-zone circles in the fill window (6 samples); the last sample is almost unloaded
FILL_LEFT_H = [1500, 2500, 1500, 2500, 2000, 0]
FILL_RIGHT_H = [2500, 3500, 2500, 3500, 3000, 80]
FILL_LEFT_V = [4000] * 5 + [0]
FILL_RIGHT_V = [6000] * 5 + [200]
# ... and in the discharge window (8 samples)
DIS_LEFT_H = [2200, 1400] * 4
DIS_RIGHT_H = [2600, 1800] * 4
DIS_V = [4000] * 8
CENTRE = {"fill": (0.0, 1.0e6), "discharge": (7000.0, 1.5e6)}  # (sigma_h, sigma_v)

# wall bins: z of the bins of the vertical wall (top to bottom) and of the hopper wall
Z_CELL = [2.25, 1.75, 1.25, 1.0, 0.75, 0.625, 0.5]
Z_HOP = [0.375, 0.25, 0.125]
K_TRUE = 0.55  # the cell bins after filling follow Janssen with this K and mu_w = tan(phi_P)
PEAK_FILL = {0.625: 3000.0, 0.5: 4500.0, 0.375: 4000.0, 0.25: 9000.0, 0.125: 6000.0}
PROFILE_DIS = {2.25: 0.0, 1.75: 0.0, 1.25: 500.0, 1.0: 1000.0, 0.75: 12000.0, 0.625: 5000.0,
               0.5: 6000.0, 0.375: 6500.0, 0.25: 20000.0, 0.125: 8000.0}
TAU_CELL = {1.25: 100.0, 1.0: 300.0, 0.75: 500.0}  # downward wall shear on the cell bins
C_FILL = [0.5, 1.5, 0.75, 1.25, 1.0, 1.0]  # sample factors, mean exactly 1
C_DIS = [0.5, 1.5] * 4

# grains of the settled snapshot: a lattice of 7 rows x 12 columns, a top grain per column
LATTICE_Y = [0.55, 0.65, 0.75, 0.85, 0.95, 1.05, 1.15]
TOP_Y = [1.30 + 0.01 * (c % 3) for c in range(N_COLS)]
R_COL = [0.045 if c % 2 == 0 else 0.055 for c in range(N_COLS)]
SURF_FILL = 1.36  # mean over the columns of (top grain centre + 0.05) = 1.35 + 0.01 * mean(c%3)
SHIFT_DIS = 0.25  # the discharge snapshot is the same packing, 0.25 m lower
# bulk density: the grains' solid area in the band [z_j + d, surface - d) = [0.577, 1.26) m:
# the 6 rows at 0.65-1.15 m whole (12 columns, pi r^2 each), the part above the band's foot of
# the row at 0.55 m (0.027 m under it), and the part under the band's top of the top grains
# (r = 0.05 m) whose disk reaches below 1.26 m (centre 0.04 m above it: c % 3 == 0); a
# disk's part beyond a line h < r from its centre is the circular segment
# r^2 acos(h / r) - h sqrt(r^2 - h^2); the hopper grain (top at 0.35 m) is under the band
BAND = (Z_J + DIAM, SURF_FILL - DIAM)


def _segment(r, h):
    """The part [m^2] of a disk of radius r beyond a line at signed distance h from its centre
    (0 for h >= r, pi r^2 for h <= -r): r^2 acos(h / r) - h sqrt(r^2 - h^2)."""
    h = np.clip(h, -r, r)
    return r * r * np.arccos(h / r) - h * np.sqrt(r * r - h * h)


RHO_B = RHO * (6 * math.pi * sum(r * r for r in R_COL)
               + sum(_segment(r, BAND[0] - LATTICE_Y[0]) for r in R_COL)
               + sum(_segment(0.05, y - BAND[1]) for y in TOP_Y)
               ) / (B * (BAND[1] - BAND[0]))

W_RATE = 64.0  # discharged mass m = W (t - t_open - 0.25) between 0 and M_TOTAL
M_TOTAL = 80.0
T_SERIES = np.arange(320) / 64 + 1 / 128  # the /timeseries sample times


def _janssen_sigma_h(depth, K, mu=MU_WALL, rho_b=RHO_B):
    """Janssen's 2D slot (docs/theory.md), written out here."""
    c = 2.0 * K * mu / B
    return K * rho_b * G / c * (1.0 - np.exp(-c * np.asarray(depth, dtype=float)))


def _profile_fill() -> dict[float, float]:
    prof = {2.25: 0.0, 1.75: 0.0}
    for z in (1.25, 1.0, 0.75):
        prof[z] = float(_janssen_sigma_h(SURF_FILL - z, K_TRUE))
    prof.update(PEAK_FILL)
    return prof


def _config():
    cfg = tiny_hopper_config()
    return cfg.model_copy(update={"measure": cfg.measure.model_copy(
        update={"window": WINDOW, "discharge_delay": DELAY})})


def _particles(shift: float = 0.0) -> dict[str, np.ndarray]:
    x, y, r = [], [], []
    for c in range(N_COLS):
        for yy in LATTICE_Y:
            x.append(0.1 * c + 0.05)
            y.append(yy - shift)
            r.append(R_COL[c])
        x.append(0.1 * c + 0.02)  # near the column's left edge, inside it
        y.append(TOP_Y[c] - shift)
        r.append(0.05)
    x.append(0.6)  # one grain in the hopper, under the band
    y.append(0.3 - shift)
    r.append(0.05)
    n = len(x)
    return {"x": np.array(x), "y": np.array(y), "radius": np.array(r),
            "uid": np.arange(n, dtype=np.int64), "vx": np.zeros(n), "vy": np.zeros(n)}


def _write_group(g: h5py.Group, data: dict) -> None:
    for key, val in data.items():
        if isinstance(val, dict):
            _write_group(g.create_group(key), val)
        elif isinstance(val, list) and val and isinstance(val[0], str):
            g.create_dataset(key, data=np.array(val, dtype=h5py.string_dtype()))
        else:
            g.create_dataset(key, data=np.asarray(val))


def write_synthetic(folder: Path, *, discharge: bool = True, settle: bool = True,
                    mass_flow: bool = False) -> Path:
    """A results folder whose results.h5 follows docs/output.md, filled with the series above.

    ``discharge=False``: a run without discharge (no discharge samples, no gate opening event,
    no /measure/flow); ``settle=False``: no settling sample (the fill window is empty);
    ``mass_flow``: the flow group of a mass-flow discharge (MFI exactly 0.3, no dead grain)."""
    folder.mkdir(parents=True)
    cfg = _config()
    t = T_MEAS
    phase = _phase(t, 2.625 if settle else T_OPEN)
    S = t.size
    # circles: switch_left, switch_centre, switch_right
    stress = np.full((S, 3, 3), JUNK)
    if settle:
        stress[FILL_K, 0, 0], stress[FILL_K, 0, 1] = FILL_LEFT_H, FILL_LEFT_V
        stress[FILL_K, 2, 0], stress[FILL_K, 2, 1] = FILL_RIGHT_H, FILL_RIGHT_V
        stress[FILL_K, 1, 0], stress[FILL_K, 1, 1] = CENTRE["fill"]
    stress[DIS_K, 0, 0], stress[DIS_K, 0, 1] = DIS_LEFT_H, DIS_V
    stress[DIS_K, 2, 0], stress[DIS_K, 2, 1] = DIS_RIGHT_H, DIS_V
    stress[DIS_K, 1, 0], stress[DIS_K, 1, 1] = CENTRE["discharge"]
    # wall bins: left wall A (top) -> B (bottom), right wall bottom -> top, likewise hoppers
    tangent = np.array([[0.0, -1.0], [0.0, 1.0],
                        [math.cos(math.radians(THETA)), -math.sin(math.radians(THETA))],
                        [math.cos(math.radians(THETA)), math.sin(math.radians(THETA))],
                        [1.0, 0.0]])
    bins = ([(0, z) for z in Z_CELL] + [(1, z) for z in Z_CELL[::-1]]
            + [(2, z) for z in Z_HOP] + [(3, z) for z in Z_HOP[::-1]] + [(4, 0.0), (4, 0.0)])
    wall = np.array([w for w, _ in bins])
    zb = np.array([z for _, z in bins])
    normal = np.full((S, len(bins)), JUNK)
    shear = np.full((S, len(bins)), JUNK)
    for key, ks, cs, prof in (("fill", FILL_K, C_FILL, _profile_fill()),
                              ("discharge", DIS_K, C_DIS, PROFILE_DIS)):
        if key == "fill" and not settle:
            continue
        for b, (w, z) in enumerate(bins):
            if w == 4:
                continue
            left = w in (0, 2)
            p = prof[z] * (1.25 if left else 0.75)  # sides differ, their mean is prof[z]
            tau = TAU_CELL.get(z, 5.0e5)  # 5e5: bins that mu_mobilised must leave out
            down = tau + (50.0 if left else -50.0)  # mean of both sides: tau
            s = down if tangent[w, 1] < 0 else -down  # shear is along A -> B
            normal[ks, b] = [p * c for c in cs]
            shear[ks, b] = [s * c for c in cs]
    # profiles: only the slice zz of the first bin above the junction matters (hopper q)
    z_edges = np.array([0.0, 0.5 * Z_J, Z_J, Z_J + 0.2, Z_J + 0.4, Z_J + 0.6])
    slices = np.full((S, 5, 3), 3.0e6)
    if settle:
        slices[FILL_K, 2, 1] = [5200.0, 4800.0, NAN, 5100.0, 4900.0, 5000.0]
    slices[DIS_K, 2, 1] = [6400.0, 5600.0, NAN, 6200.0, 5800.0, 6000.0, 6100.0, 5900.0]
    measure = {
        "time": t, "step": np.arange(S) * 100, "phase": phase,
        "circles": {"name": ["switch_left", "switch_centre", "switch_right"],
                    "x": [0.4, 0.6, 0.8], "z": [Z_J] * 3, "radius": [0.4] * 3,
                    "stress": stress},
        "wall_bins": {"wall": wall, "z": zb, "x": np.zeros(len(bins)),
                      "tangent": tangent, "normal": normal, "shear": shear},
        "profiles": {"z_edges": z_edges, "left": np.full((S, 5, 3), 1.0e3),
                     "right": np.full((S, 5, 3), 1.0e3), "slices": slices},
    }
    if discharge:
        measure["discharge_snapshot"] = {"particles": _particles(SHIFT_DIS)}
        n = 20
        exit_time = np.array([0.1 * (k + 1) for k in range(15)] + [NAN] * 5)
        max_disp = np.array([0.0] * 15 + [0.01, 0.02, 0.049, 0.051, 0.3])
        level = [1.4, 1.35, 1.3, 1.25, 1.2, 1.1, 1.0, 0.9]
        v_wall = [-0.2, NAN, -0.1, -0.3, -5.0, -5.0, -5.0, -5.0]
        v_axis = [-0.8, -0.5, -0.6, -0.4, -0.01, -0.01, -0.01, -0.01]
        if mass_flow:
            exit_time[15:] = 1.5
            v_wall = [-0.375, NAN, -0.375, -0.375, -5.0, -5.0, -5.0, -5.0]
            v_axis = [-1.25, -1.25, -1.25, -1.25, -0.01, -0.01, -0.01, -0.01]
        measure["flow"] = {
            "uid": np.arange(n), "x0": np.zeros(n), "z0": np.zeros(n), "r0": np.full(n, 0.05),
            "exit_time": exit_time, "max_displacement": max_disp,
            "mass_flow_index": {"time": np.arange(8) * 0.1, "level": level, "v_wall": v_wall,
                                "v_axis": v_axis, "n_wall": np.ones(8), "n_axis": np.ones(8)}}
    keep = np.ones(S, bool) if discharge else phase < 2
    if not discharge:
        for grp in ("circles", "wall_bins", "profiles"):
            for key, val in measure[grp].items():
                if key in ("stress", "normal", "shear", "left", "right", "slices"):
                    measure[grp][key] = val[keep]
        for key in ("time", "step", "phase"):
            measure[key] = measure[key][keep]
    ts_t = T_SERIES if discharge else T_SERIES[T_SERIES < T_OPEN]
    ts_phase = _phase(ts_t, 2.625 if settle else T_OPEN)
    mass = np.where(ts_phase == 2, np.clip(W_RATE * (ts_t - T_OPEN - 0.25), 0.0, M_TOTAL), 0.0)
    events = {"n_poured": 150, "fill_level": 1.25, "fill_time": 2.625,
              "discharged_fraction": 0.75 if discharge else 0.0}
    if discharge:
        events.update(discharge_start_time=T_OPEN, discharge_end_reason="fraction",
                      initial_mass=M_TOTAL / 0.75)
    with h5py.File(folder / "results.h5", "w") as h5:
        h5.attrs.update({"status": "complete", "phase": "done", "time": float(t[-1]),
                         "steps": 12345, "silodem_version": "test", "scenario": cfg.name,
                         "seed": cfg.seed, "dt": 1.5e-4, "dt_crit": 7.5e-4,
                         "config_toml": config_to_toml(cfg)})
        _write_group(h5.create_group("timeseries"),
                     {"time": ts_t, "phase": ts_phase.astype(float), "discharged_mass": mass})
        _write_group(h5.create_group("measure"), measure)
        h5["measure"].attrs["interval"] = 1 / 16
        if discharge:
            h5["measure/flow"].attrs.update({"t_open": T_OPEN, "window_start": DELAY,
                                             "window": WINDOW, "mfi_band_lo": 0.6,
                                             "mfi_band_hi": 0.9})
        _write_group(h5.create_group("walls"), {
            "name": ["left_wall", "right_wall", "left_hopper", "right_hopper", "gate"],
            "ax": np.zeros(5), "ay": np.zeros(5), "bx": np.zeros(5), "by": np.zeros(5)})
        ev = h5.create_group("events")
        ev.attrs.update(events)
        h5.create_dataset("warnings", data=np.array([], dtype=h5py.string_dtype()))
        _write_group(h5.create_group("settled"), {"particles": _particles()})
        h5["settled"].attrs["time"] = 2.96875
    return folder


@pytest.fixture(scope="module")
def synth(tmp_path_factory):
    """(analysis, summary) of the full synthetic run."""
    folder = write_synthetic(tmp_path_factory.mktemp("synth") / "run")
    return analyse(load_results(folder)), summarise_run(folder)


def _pct(before: float, after: float) -> float:
    return 100.0 * (after - before) / before  # docs/sweeps.md: 100 (discharge - fill) / fill


def _is(value, expected, rel=REL) -> bool:
    """value == expected up to ``rel``, NaN equal to NaN only."""
    if isinstance(expected, float) and math.isnan(expected):
        return isinstance(value, float) and math.isnan(value)
    return value == pytest.approx(expected, rel=rel, abs=0.0)


def _check(row: dict, expected: dict, rel=REL) -> None:
    bad = {k: (row.get(k), v) for k, v in expected.items() if not _is(row.get(k), v, rel)}
    assert not bad, bad


# switch zone = mean of the two wall circles, sample by sample (docs/sweeps.md)
SW_FILL_H = (2000 + 3000 + 2000 + 3000 + 2500 + 40) / 6  # = 2090
SW_FILL_V = (5 * 5000 + 100) / 6
SW_DIS_H, SW_DIS_V = 2000.0, 4000.0  # means of 2400, 1600, ... and of 4000


def test_switch_zone_window_means_ratio_cv_and_change(synth):
    """The switch-zone columns of a study's table on the synthetic run.  Expected values are
    the closed forms of the constructed series: the window means of (left + right)/2 (samples
    outside the windows, and the two fill-phase samples inside the time window of the fill, are
    9e6 and must be left out); the ratio of those means; the coefficient of variation of the
    sampled ratio with the almost unloaded last fill sample (sigma_v = 100 Pa < 10 % of the
    median 5000 Pa) left out: kept ratios 0.4, 0.6, 0.4, 0.6, 0.5 -> mean 0.5, std sqrt(0.008);
    discharge ratios 0.6, 0.4 alternating -> 0.1 / 0.5.  The std is the population one (NumPy's
    default, ddof = 0), the usual reading of std / mean of a window's samples."""
    _, s = synth
    _check(s, {
        "switch_sigma_h_fill": SW_FILL_H, "switch_sigma_v_fill": SW_FILL_V,
        "switch_sigma_h_discharge": SW_DIS_H, "switch_sigma_v_discharge": SW_DIS_V,
        "switch_sigma_h_change_pct": _pct(SW_FILL_H, SW_DIS_H),
        "switch_sigma_v_change_pct": _pct(SW_FILL_V, SW_DIS_V),
        "switch_ratio_fill": 12540 / 25100, "switch_ratio_discharge": 0.5,
        "switch_ratio_cv_fill": math.sqrt(0.008) / 0.5, "switch_ratio_cv_discharge": 0.2})
    # "ratio of the window means" is the ratio of the two table columns
    assert s["switch_ratio_fill"] == pytest.approx(
        s["switch_sigma_h_fill"] / s["switch_sigma_v_fill"], rel=REL)


def test_per_circle_columns_and_the_report_change(synth):
    """Per-circle columns of the table and the report's change fill -> discharge (Fig. 8).
    Expected: means of the constructed per-circle series; the centre circle has sigma_h = 0
    after filling, so its % change has no base and must be NaN (not inf, no exception); its
    sampled ratio is constant in discharge, so its coefficient of variation is exactly 0."""
    a, s = synth
    expected = {
        "switch_left": {"sigma_h_fill": 10000 / 6, "sigma_v_fill": 20000 / 6,
                        "sigma_h_discharge": 1800.0, "sigma_v_discharge": 4000.0},
        "switch_right": {"sigma_h_fill": 15080 / 6, "sigma_v_fill": 30200 / 6,
                         "sigma_h_discharge": 2200.0, "sigma_v_discharge": 4000.0},
        "switch_centre": {"sigma_h_fill": 0.0, "sigma_v_fill": 1.0e6,
                          "sigma_h_discharge": 7000.0, "sigma_v_discharge": 1.5e6},
    }
    cv = {"switch_left": 0.1 / 0.45, "switch_right": 0.1 / 0.55, "switch_centre": 0.0}
    for name, e in expected.items():
        e["sigma_h_change_pct"] = (_pct(e["sigma_h_fill"], e["sigma_h_discharge"])
                                   if e["sigma_h_fill"] else NAN)
        e["sigma_v_change_pct"] = _pct(e["sigma_v_fill"], e["sigma_v_discharge"])
        _check(a.change[name], e)
        _check(s, {f"circle_{name}_{k}": v for k, v in e.items()})
        assert s[f"circle_{name}_ratio_cv_discharge"] == pytest.approx(cv[name], rel=REL,
                                                                        abs=1e-15)
    assert math.isnan(s["circle_switch_centre_sigma_h_change_pct"])
    assert s["circle_switch_centre_sigma_v_change_pct"] == pytest.approx(50.0, rel=REL)


def test_switch_zone_stays_in_the_upper_half_of_a_short_hopper():
    """Junction +- two mean diameters, at most half the hopper's height z_j = (B - D)/2
    tan(theta): paper case 2 keeps 1.2 +- 0.4 m; its --quick variant (B = 2.04 m, z_j =
    0.52 m) gets +- 0.26 m, not a zone down to 0.12 m, where the outlet's own stress
    concentration was reported as the switch's peak."""
    from silodem.measure.regions import switch_zone
    from silodem.report.analysis import silo_shape
    from silodem.scenario_files import load_config, quick_variant

    for cfg in (load_config("paper-case2"), quick_variant(load_config("paper-case2"))):
        s, m = cfg.silo, cfg.material
        z_j = 0.5 * (s.cell_width - s.outlet_width) * math.tan(
            math.radians(s.hopper_angle_from_horizontal_deg))
        half = min(2 * (m.radius_min + m.radius_max), 0.5 * z_j)
        assert switch_zone(cfg, silo_shape(cfg)) == pytest.approx((z_j - half, z_j + half))
    assert half == pytest.approx(0.26)  # the quick variant's: half its hopper


def test_wall_profile_and_switch_zone_peak(synth):
    """Time-averaged edge profile (both sides averaged, sorted by z) and the switch-zone peak.
    Expected: the constructed profile (left = 1.25 P, right = 0.75 P, sample factors of mean 1,
    9e6 outside the windows); the peak is the largest value with z_j - 2d <= z <= z_j + 2d
    (0.277 .. 0.677 m): 4500 Pa at z = 0.5 after filling (not the 9000 Pa at z = 0.25 below the
    zone), 6500 Pa at z = 0.375 during discharge (not the 12000 Pa at z = 0.75 above it).
    The downward shear traction of every bin, vertical and inclined walls alike, is the
    constructed one: TAU_CELL on the cell bins, 5e5 Pa elsewhere (sides tau +- 50 Pa, stored
    along A -> B, so with the opposite sign on a wall whose tangent points up; sample factors
    of mean 1) -- a sign taken from the tangent, not the tangent's length sin(theta)."""
    a, s = synth
    assert a.switch == pytest.approx(SWITCH, rel=REL)
    for key, prof in (("fill", _profile_fill()), ("discharge", PROFILE_DIS)):
        e = a.edge[key]
        zs = sorted(prof)
        assert e.z.tolist() == zs
        assert e.sigma_n == pytest.approx([prof[z] for z in zs], rel=REL)
        assert e.tau_down == pytest.approx([TAU_CELL.get(z, 5.0e5) for z in zs], rel=REL)
        assert e.on_vertical.tolist() == [z in Z_CELL for z in zs]
        left_z, left_sn = e.sides["left"]
        assert left_sn == pytest.approx([1.25 * prof[z] for z in zs], rel=REL)
        assert left_z.tolist() == zs
    assert a.peaks["fill"] == pytest.approx((4500.0, 0.5), rel=REL)
    assert a.peaks["discharge"] == pytest.approx((6500.0, 0.375), rel=REL)
    _check(s, {"wall_peak_fill": 4500.0, "wall_peak_z_fill": 0.5,
               "wall_peak_discharge": 6500.0, "wall_peak_z_discharge": 0.375,
               "wall_peak_change_pct": _pct(4500.0, 6500.0),
               "wall_at_fill_peak_change_pct": _pct(4500.0, 6000.0)})
    _check(a.change["wall peak"], {"sigma_h_fill": 4500.0, "sigma_h_discharge": 6500.0,
                                   "sigma_h_change_pct": _pct(4500.0, 6500.0),
                                   "z_fill": 0.5, "z_discharge": 0.375})
    assert a.wall_at_fill_peak == pytest.approx((0.5, 4500.0, 6000.0, _pct(4500.0, 6000.0)),
                                                rel=REL)


def test_surface_height_and_bulk_density(synth):
    """Free surface and bulk density from grains placed by hand.  Surface: the top of the
    highest grain in each of the 12 columns of width d = 0.1 m, averaged: tops 1.35, 1.36, 1.37
    repeating -> 1.36 m (1.11 m for the discharge snapshot, 0.25 m lower).  Bulk density: the
    grains' solid area in the band [z_j + d, surface - d) (RHO_B: whole disks and circular
    segments) times rho, over the band's area B (hi - lo)."""
    a, _ = synth
    assert a.surface["fill"] == pytest.approx(SURF_FILL, rel=REL)
    assert a.surface["discharge"] == pytest.approx(SURF_FILL - SHIFT_DIS, rel=REL)
    assert a.rho_b == pytest.approx(RHO_B, rel=REL)
    # the last column is as wide as the others: a grain only in [1.1, 1.2) decides its top
    snap = {"particles": {"x": np.array([1.05, 1.15]), "y": np.array([1.0, 0.5]),
                          "radius": np.array([0.05, 0.05])}}
    assert surface_height(snap, B, DIAM) == pytest.approx((1.05 + 0.55) / 2, rel=REL)
    # the columns that hold grains, from the left wall to the right one
    snap = {"particles": {"x": np.array([1.15, 0.05, 0.65]), "y": np.array([0.5, 0.7, 0.9]),
                          "radius": np.array([0.05, 0.05, 0.05])}}
    np.testing.assert_allclose(column_tops(snap, B, DIAM), [0.75, 0.95, 0.55])


def test_mobilised_wall_friction_and_janssen_fits(synth):
    """Mobilised wall friction sum(tau)/sum(sigma_n) over the cell-wall bins above the switch
    zone and under the surface (z = 1.25, 1.0, 0.75; the bins above the surface and in the
    switch zone carry a shear of 5e5 Pa that must be left out): (100 + 300 + 500) / sum of the
    three Janssen values.  Those values are Janssen's sigma_h with K = 0.55 and mu_w = tan 24
    deg, so the fit with mu_w = tan(phi_P) must give K = 0.55 and the free fit (K, mu_w) =
    (0.55, tan 24 deg), up to the optimiser's convergence (FIT_REL)."""
    a, summary = synth
    prof = _profile_fill()
    assert a.mu_mobilised["fill"] == pytest.approx(
        900.0 / (prof[1.25] + prof[1.0] + prof[0.75]), rel=REL)
    assert summary["wall_friction_mobilised_fill"] == a.mu_mobilised["fill"]  # results.csv
    assert a.janssen["fill"].K == pytest.approx(K_TRUE, rel=FIT_REL)
    assert a.janssen["fill"].mu_w == MU_WALL
    assert a.janssen_free.K == pytest.approx(K_TRUE, rel=FIT_REL)
    assert a.janssen_free.mu_w == pytest.approx(MU_WALL, rel=FIT_REL)
    # during discharge (surface 1.11 m): z = 1.25 is above it, z = 1.0 and 0.75 are in
    assert a.mu_mobilised["discharge"] == pytest.approx((300.0 + 500.0) / (1000.0 + 12000.0),
                                                        rel=REL)


def test_hopper_theory_input_q(synth):
    """q, the hopper theory's input, per window: the window mean of the full-width slice
    sigma_zz in the first profile bin above the junction; one NaN sample (empty bin) is
    skipped: (5200 + 4800 + 5100 + 4900 + 5000) / 5 = 5000 Pa after filling, 42000 / 7 =
    6000 Pa during discharge.  Slice heights are measured from the hopper's virtual apex,
    D/2 / tan(alpha) under the outlet (docs/theory.md), so H = z_j + that depth."""
    a, _ = synth
    assert a.hopper["fill"]["q"] == pytest.approx(5000.0, rel=REL)
    assert a.hopper["discharge"]["q"] == pytest.approx(6000.0, rel=REL)
    for key in ("fill", "discharge"):
        assert a.hopper[key]["H"] == pytest.approx(
            Z_J + 0.5 * D_OUT / math.tan(math.radians(90.0 - THETA)), rel=REL)


def test_walker_d_fit_recovers_the_d_of_an_exact_planar_profile(synth):
    """Hopper-wall bins set to D sigma_v with D = 1.7 (fill) and 2.4 (discharge), sigma_v from
    the wedge's slice balance integrated here numerically down from the junction (sigma_v = q
    there): the window's bounded fit gives each D back and uses the window's own q.  The slice
    balance (docs/theory.md, Walker 1966), h up from the virtual apex, wedge A = 2 h tan(alpha),
    wall length P = 2 per unit thickness, sigma_n = D sigma_v:
    d(A sigma_v)/dh = -gamma A + P D sigma_v (tan(alpha) + mu_w)."""
    import copy

    from scipy.integrate import solve_ivp

    from silodem.report.analysis import EdgeProfile, _walker

    a, _ = synth
    g = a.geom
    gamma, tan_a, mu = a.rho_b * g["g"], math.tan(math.radians(g["alpha"])), g["mu_wall"]
    H = g["z_j"] + g["apex"]
    z_bins = np.array([0.1, 0.2, 0.3])
    for key, D_true in (("fill", 1.7), ("discharge", 2.4)):
        q = a.hopper[key]["q"]
        def slice_balance(h, s, D=D_true):  # A s' = -A' s - gamma A + P D s (tan_a + mu)
            A = 2.0 * h * tan_a
            return [(-2.0 * tan_a * s[0] - gamma * A + 2.0 * D * s[0] * (tan_a + mu)) / A]

        sol = solve_ivp(slice_balance, (H, g["apex"] + 0.05), [q],
                        dense_output=True, rtol=1e-10, atol=1e-6)
        sigma_v = sol.sol(z_bins + g["apex"])[0]
        b = copy.copy(a)
        b.edge = {key: EdgeProfile(z=z_bins, sigma_n=D_true * sigma_v,
                                   tau_down=np.zeros(3), on_vertical=np.zeros(3, bool),
                                   sides={})}
        hop = _walker(b, key)
        assert hop["q"] == a.hopper[key]["q"]
        assert hop["D_bins"] == 3
        assert hop["D_fit"] == pytest.approx(D_true, rel=1e-4) and not hop["D_at_bound"]


def test_a_walker_d_at_the_end_of_its_range_is_said_to_be_undetermined(synth):
    """Hopper wall bins below every curve of D in 0.2 - 5 (walls that carry nothing: a run of
    one grain) stop the fit at 5, where the wall stress falls fastest toward the apex (a run
    with friction of 89 deg stopped at 0.2).  The report gave such a D as a fitted one without
    a word (an audit); it now says it is the range's end."""
    from silodem.report.analysis import EdgeProfile, _walker
    from silodem.report.key_numbers import add_numbers

    a, _ = synth
    b = copy.copy(a)
    b.hopper = dict(a.hopper)
    for key in ("fill", "discharge"):
        b.edge = {**a.edge, key: EdgeProfile(z=np.array([0.1, 0.2, 0.3]), sigma_n=np.zeros(3),
                                             tau_down=np.zeros(3), on_vertical=np.zeros(3, bool),
                                             sides={})}
        b.hopper[key] = _walker(b, key)
        assert b.hopper[key]["D_fit"] == pytest.approx(5.0, abs=1e-4)
        assert b.hopper[key]["D_at_bound"]
    b.numbers = []
    add_numbers(b)
    said = ("(the end of the range searched, 0.2 - 5: the wall bins lie beyond every curve of "
            "the range, so D is not determined)")
    for when in ("after filling", "during discharge"):
        text = _number(b, f"Walker distribution factor D fitted on the hopper walls (planar), "
                          f"{when}")
        assert text == f"5 {said}"


def test_a_window_cut_short_by_the_phase_is_reported_as_cut(synth):
    """Settling began at 2.625 s and the gate opened at 3 s: the 0.5 s window 'after
    filling' holds the settle samples from 2.65625 s only, and was reported as 2.5 - 3 s
    without a word.  It is now the samples' span, with a key-number row that says so; the
    discharge window, whose samples reach within one sampling interval (1/16 s) of its end,
    stays whole."""
    a, _ = synth
    first = T_MEAS[FILL_K[0]]
    assert a.windows["fill"] == (first, T_OPEN) and first > T_OPEN - WINDOW + 1 / 16
    assert a.windows["discharge"] == (T_OPEN + DELAY, T_OPEN + DELAY + WINDOW)
    label = ("averaging window after filling (the end of settling), cut short: settling "
             f"lasted less than measure.window = {WINDOW:g} s")
    assert _number(a, label) == f"{first:.3f} - {T_OPEN:.3f} ({T_OPEN - first:.3g} s)"
    assert not [row for row in a.numbers if row[0].startswith("averaging window during")]


@pytest.mark.parametrize("settled_for, first, cut", [
    (0.99976, 4.0202, False),  # one time step short: no sample lost, the window whole
    (0.5, 4.51, True),         # half the window: cut to its samples
    (0.99976, 4.3, True)])     # whole settling, samples missing (a resume): cut to them
def test_a_settling_short_of_the_window_by_less_than_a_sample_interval_cuts_nothing(
        settled_for, first, cut):
    """Settling that lasted 0.99976 s against a 1 s window (one time step short) lost no
    sample, yet its first sample lay a fraction of a step more than the 0.02 s interval
    inside the window, and the report called the window cut short. The gate opens at 5 s;
    samples every 84 steps of 2.38e-4 s (0.019995 s) from ``first``. The window is cut to its
    samples where settling was shorter than the window by more than an interval, or where
    its samples begin more than an interval after the settling did."""
    import types

    from silodem.report.analysis import DISCHARGE, SETTLE, _window_masks

    t = np.concatenate([np.arange(first, 5.0 + 1e-9, 0.019995), [5.3, 5.5, 6.0]])
    phase = np.where(t <= 5.0, SETTLE, DISCHARGE)
    measure = {"time": t, "phase": phase, "@attrs": {"interval": 0.02}}
    res = types.SimpleNamespace(
        cfg=types.SimpleNamespace(measure=types.SimpleNamespace(window=1.0, interval=0.02,
                                                                discharge_delay=0.5)),
        events={"discharge_start_time": 5.0, "settle_time": settled_for},
        group=lambda name: measure if name == "measure" else None)
    assert _window_masks(res)[1]["fill"] == ((first if cut else 4.0), 5.0)


def test_discharge_rate_is_the_slope_of_a_linear_mass_record(synth):
    """Discharged mass m = 64 (t - t_open - 0.25) kg, 0 before, 80 kg (empty) after: between
    15 % and 75 % of the final mass it is exactly linear, so the steady rate is its slope,
    64 kg/s, and every block slope is 64 too, so the standard error is 0 (up to round-off, a
    bound far below any real error).  The sliding 0.25 s rate is 64 wherever its window lies
    in the linear part.  Beverloo C = W / (rho_b sqrt(g) (D - 1.5 d)^1.5 t) (docs/theory.md)."""
    a, s = synth
    r = a.flow["rate"]
    assert r.rate == pytest.approx(W_RATE, rel=REL)
    assert abs(r.err) <= 1e-9 * W_RATE
    assert s["discharge_rate"] == pytest.approx(W_RATE, rel=REL)
    assert abs(s["discharge_rate_err"]) <= 1e-9 * W_RATE
    # the window's ends, 0.25 and 0.75 s after the gate opened, of M_TOTAL / 0.75 in all: the
    # mass record sampled every 1/64 s, 1/128 s off the window's start (linear interpolation
    # of the clipped ramp there: 0.25 kg)
    m0 = M_TOTAL / 0.75
    assert s["window_emptied_start_pct"] == pytest.approx(100 * 0.25 / m0, rel=REL)
    assert s["window_emptied_end_pct"] == pytest.approx(100 * W_RATE * 0.5 / m0, rel=REL)
    t, rate = a.flow["series"]
    inner = (t >= 0.25 + 0.125) & (t <= 1.5 - 0.125)
    assert inner.sum() > 40
    assert rate[inner] == pytest.approx(np.full(inner.sum(), W_RATE), rel=REL)
    C = W_RATE / (RHO_B * math.sqrt(G) * (D_OUT - 1.5 * DIAM) ** 1.5 * THICK)
    assert a.flow["beverloo_C"] == pytest.approx(C, rel=REL)
    # the synthetic silo has a hopper: the row says Beverloo's law is a flat bottom's
    row = _number(a, "Beverloo 2D constant C implied by W (k = 1.5) (Beverloo's law is for a "
                  "flat bottom: through a hopper C also depends on its slope)")
    assert _first_float(row) == pytest.approx(C, rel=5e-3)
    # B = 1.2 m is over 2.5 D = 1 m but under D + 30 d = 3.4 m (Nedderman 1992): too narrow
    # for a rate independent of the walls, and said with the one condition it misses
    assert row.endswith("here B = 1.2 m, under D + 30 d = 3.4 m, so this C holds the walls' "
                        "effect on the flow too)")


def test_beverloo_c_says_when_the_silo_is_narrow_for_the_law(synth):
    """Nedderman's (1992) conditions for a rate independent of the silo's width, B >= 2.5 D
    and B >= D + 30 d: an outlet of 0.93 B gave a C with no word of the walls (an audit).
    Each missed condition is named with its width; a silo wide for both gets no note."""
    a, _ = synth
    label = "Beverloo 2D constant C implied by W"
    for B_, D_, d_, said in ((1.9 / 0.93, 1.9, 0.2, "under 2.5 D = 4.75 m and D + 30 d = 7.9 m"),
                             (6.0, 1.0, 0.2, "under D + 30 d = 7 m"),
                             (3.0, 1.4, 0.05, "under 2.5 D = 3.5 m"),
                             (4.75, 1.0, 0.125, None), (2.5, 1.0, 0.03125, None)):
        b = copy.copy(a)
        b.geom, b.numbers = {**a.geom, "B": B_, "D": D_, "d": d_}, []
        add_numbers(b)
        row = _number(b, label)
        if said is None:  # B = D + 30 d, then B = 2.5 D, exactly (in binary): wide enough
            assert row == significant(a.flow["beverloo_C"], 3)
        else:
            assert f"B = {significant(B_, 3)} m, {said}, so this C" in row


def test_flow_pattern_dead_fraction_and_mass_flow_index(synth, tmp_path):
    """Funnel-flow case: 3 of 20 grains never left and moved less than d/2 = 0.05 m (0.051 and
    0.3 m moved too far; grains that left count as not dead even with a displacement of 0):
    dead fraction 0.15.  MFI = mean v_wall / mean v_axis over the samples whose surface is
    above band_hi + (band_hi - band_lo) = 1.2 m and where both are measured: samples 0, 2, 3
    -> (-0.6/3) / (-1.8/3) = 1/3; dead grains make it funnel flow.  Mass-flow case: MFI =
    -0.375 / -1.25 = 0.3 exactly, the threshold (mass flow when MFI >= 0.3), no dead grain."""
    a, s = synth
    assert a.flow["dead_fraction"] == pytest.approx(0.15, rel=REL)
    assert a.flow["dead"].tolist() == [False] * 15 + [True, True, True, False, False]
    assert a.flow["mfi"] == pytest.approx(1 / 3, rel=REL)
    assert a.flow["pattern"] == "funnel flow"
    _check(s, {"dead_fraction": 0.15, "mass_flow_index": 1 / 3})
    assert s["flow_pattern"] == "funnel flow"
    # grains of one size (r0 = 0.05 m for all): no size segregation to report
    assert s["segregation_first"] == s["segregation_last"] == 1.0
    folder = write_synthetic(tmp_path / "mass", mass_flow=True)
    s2 = summarise_run(folder)
    assert s2["mass_flow_index"] == 0.3 and s2["dead_fraction"] == 0.0
    assert s2["flow_pattern"] == "mass flow"


def test_no_flow_by_the_windows_end_reads_no_dead_zone_and_no_pattern(tmp_path):
    """A slow gate: the first grain leaves 0.8 s after the opening, after the discharge
    window's end (0.25 + 0.5 s).  Every grain is at rest in the window and the column's
    descent is 0, so a quarter of it lets no grain count as dead: the report said "dead-zone
    fraction 0" and "mass flow" (MFI from the velocities of grains at rest; an audit).  The
    dead fraction, MFI and pattern are not read then, and the dead-zone map says why."""
    import matplotlib.pyplot as plt

    from silodem.report.analysis import NO_FLOW
    from silodem.report.figures_flow import fig_dead_zones

    folder = write_synthetic(tmp_path / "slow", mass_flow=True)
    with h5py.File(folder / "results.h5", "r+") as h5:
        ts = h5["timeseries"]
        later = np.clip(W_RATE * (ts["time"][:] - T_OPEN - 0.8), 0.0, M_TOTAL)
        ts["discharged_mass"][...] = np.where(ts["phase"][:] == 2, later, 0.0)
    a = analyse(load_results(folder))
    assert np.isfinite(a.flow["rate"].rate)  # the flow after the window is still a flow
    assert a.flow["pattern"] == NO_FLOW
    assert np.isnan(a.flow["dead_fraction"]) and np.isnan(a.flow["mfi"])
    fig = fig_dead_zones(a)
    assert "none told: no grain had left by then" in fig.axes[0].get_title()
    plt.close(fig)


def test_a_rate_read_before_a_clog_says_the_outlet_clogged(tmp_path):
    """A silo that clogged after 12 % of its mass had left still has a steady rate, fitted to
    the flow before the clog; the report gave it, and 'mass flow', without a word of the clog
    (an audit).  Both rows now say it."""
    folder = write_synthetic(tmp_path / "clog", mass_flow=True)
    with h5py.File(folder / "results.h5", "r+") as h5:
        h5["events"].attrs.update({"discharge_end_reason": "clog", "discharged_fraction": 0.12})
    a = analyse(load_results(folder))
    said = " (then the outlet clogged, after 12 % of the mass had left: the flow before the clog)"
    assert _number(a, "steady discharge rate W").endswith(said)
    assert _number(a, "flow pattern, measured") == "mass flow" + said
    a_flowing = analyse(load_results(write_synthetic(tmp_path / "flowing", mass_flow=True)))
    assert "clogged" not in _number(a_flowing, "steady discharge rate W")


def test_a_rate_and_changes_not_read_say_why(tmp_path):
    """A run of 5 grains: the rate row read "n/a +- n/a" and each circle's change "h n/a, v
    n/a", without a reason (an audit).  Two grains out, then an arch: no grain left within
    15 - 75 % of the discharged mass, where the rate is fitted (``steady_rate``).  A circle
    with no contact in the discharge window (its stress samples NaN there) has no change."""
    folder = write_synthetic(tmp_path / "arch", mass_flow=True)
    with h5py.File(folder / "results.h5", "r+") as h5:
        ts = h5["timeseries"]
        after = ts["time"][:] - T_OPEN
        two = np.where(after >= 0.3, 23.79, 0.0) + np.where(after >= 0.38, 28.69, 0.0)
        ts["discharged_mass"][...] = np.where(ts["phase"][:] == 2, two, 0.0)
        stress = h5["measure/circles/stress"]
        gone = stress[...]
        gone[DIS_K, 0, :] = np.nan  # switch_left: no contact in the discharge window
        stress[...] = gone
    a = analyse(load_results(folder))
    assert _number(a, "steady discharge rate W") == (
        "n/a (no grain left within 15 - 75 % of the discharged mass, where the rate is fitted)")
    assert _number(a, "change fill -> discharge, switch_left") == (
        "n/a (no contact in the circle during discharge)")


def test_a_switch_zone_peak_of_nothing_is_not_placed_at_a_height(synth):
    """A run of 5 grains, none in the switch zone: the report gave its wall-stress "peak" as
    "0 at z = 1.05 m" (an audit), the height of the first of equal zero bins.  A zero peak is
    now said to be no grain pressing on those walls, with no height."""
    from silodem.report.key_numbers import add_numbers

    a, _ = synth
    b = copy.copy(a)
    b.peaks = {**a.peaks, "fill": (0.0, 1.05)}
    b.numbers = []
    add_numbers(b)
    assert _number(b, "switch-zone peak of the wall normal stress, after filling") == (
        "0: no grain pressed on the walls of the switch zone")
    assert " at z = " in _number(b, "switch-zone peak of the wall normal stress, during")


def test_a_same_place_change_from_nothing_says_why(synth):
    """The stress at the filling peak's height, after filling -> during discharge: from a
    filling stress of 0 no relative change can be told, and the row says so, as the circles'
    and the wall peak's rows do (it read a bare 'n/a')."""
    a, _ = synth
    b = copy.copy(a)
    z, _, dd, _ = a.wall_at_fill_peak
    b.wall_at_fill_peak, b.numbers = (z, 0.0, dd, NAN), []
    add_numbers(b)
    assert _number(b, f"wall normal stress at the filling peak's height z = {_fmt(z, 3)} m") \
        == (f"0 -> {pascals(dd)} (n/a (0 Pa on the wall at that height after filling: no "
            "relative change from 0) %)")


def test_plain_columns_copy_the_run(synth):
    """The columns copied from the run: junction height (B - D)/2 tan(theta), and the events
    and attributes written into the synthetic file."""
    _, s = synth
    _check(s, {"junction_z": Z_J, "fill_level": 1.25, "discharged_fraction": 0.75,
               "dt": 1.5e-4, "bulk_density": RHO_B})
    assert (s["n_poured"], s["steps"], s["discharge_end_reason"]) == (150, 12345, "fraction")
    assert s["lost_count"] == 0  # the file has no lost_count: no grain was lost


def _number(a, start: str) -> str:
    rows = [v for label, v, _ in a.numbers if label.startswith(start)]
    assert len(rows) == 1, (start, a.numbers)
    return rows[0]


def _first_float(text: str) -> float:
    return float(text.split()[0].replace(",", ""))


def test_key_numbers_of_the_report(synth):
    """The 'Key numbers' table of report.html shows the expected values, rounded as printed
    (4 significant digits by default: relative error <= 5e-4; 3 digits: 5e-3; Pa to the unit).
    Expected values as in the tests above; the peak / Janssen ratio is 4500 Pa over Janssen's
    sigma_h with K = 0.55 at the depth 1.36 - 0.5 m; 'n/a' where a change has no base."""
    a, _ = synth
    # the config's radii (module docstring): d = 0.045 + 0.055
    assert _number(a, "grain radii (shares by number) / mean diameter d") == (
        "uniform in [0.045, 0.055] / 0.1")
    assert _first_float(_number(a, "free surface after filling")) == pytest.approx(
        SURF_FILL, rel=5e-4)
    assert _first_float(_number(a, "bulk density")) == pytest.approx(RHO_B, rel=5e-4)
    assert _number(a, "switch-zone peak of the wall normal stress, after filling") == (
        "4,500 at z = 0.5 m")
    # during discharge the zone's largest, 6500 Pa at its lowest bin (the hopper's 0.375 m),
    # has 20000 Pa under it at 0.25 m: the zone's edge on a rising stress, not a peak
    assert _number(a, "switch-zone peak of the wall normal stress, during discharge") == (
        "6,500 at z = 0.375 m (hopper wall): the zone's lowest wall bin, on a stress that goes "
        "on rising down the wall, not a local peak")
    # ... which the largest of the whole wall names, with where it lies (the profiles' 9000
    # and 20000 Pa at z = 0.25 m, PEAK_FILL and PROFILE_DIS, under the zone)
    assert _number(a, "largest wall normal stress on the side walls, after filling") == (
        "9,000 at z = 0.25 m (hopper wall, below the switch zone)")
    assert _number(a, "largest wall normal stress on the side walls, during discharge") == (
        "20,000 at z = 0.25 m (hopper wall, below the switch zone)")
    ratio = 4500.0 / float(_janssen_sigma_h(SURF_FILL - 0.5, K_TRUE))
    assert float(_number(a, "switch-zone peak / Janssen")) == pytest.approx(ratio, rel=5e-3)
    # a peak below the junction, on the hopper walls: the cell's Janssen where the cell ends
    import copy

    from silodem.report.key_numbers import add_numbers

    below = copy.copy(a)
    below.peaks, below.numbers = {**a.peaks, "fill": (4500.0, 0.3)}, []
    add_numbers(below)
    ratio = 4500.0 / float(_janssen_sigma_h(SURF_FILL - Z_J, K_TRUE))
    assert float(_number(below, "switch-zone peak / Janssen")) == pytest.approx(ratio, rel=5e-3)
    # with K poorly determined (error over half of it) the ratio says so
    loose = copy.copy(below)
    loose.janssen = {**a.janssen, "fill": dataclasses.replace(a.janssen["fill"], K_err=0.4)}
    loose.numbers = []
    add_numbers(loose)
    value = _number(loose, "switch-zone peak / Janssen")
    assert float(value.split()[0]) == pytest.approx(ratio, rel=5e-3)
    assert value.endswith("(K = 0.55 +- 0.4 is poorly determined: a ratio to a curve the run "
                          "does not measure)")
    assert _first_float(_number(a, "Janssen K fitted to the cell wall profile, after")) == (
        pytest.approx(K_TRUE, rel=5e-3))
    assert _number(a, "measured mean vertical stress q at the junction level, after") == "5,000"
    assert _number(a, "measured mean vertical stress q at the junction level, during") == "6,000"
    rate = _number(a, "steady discharge rate W (of a slot of thickness t = ")
    assert _first_float(rate) == pytest.approx(W_RATE, rel=5e-4)
    assert "slid open" not in rate  # the gate was removed at once
    # a gate that slid open over 100 s: the whole fit lies within the slide, and the row says so
    slid = copy.copy(a)
    slid.res = dataclasses.replace(a.res, events={**a.res.events, "gate_opening_time": 100.0})
    slid.numbers = []
    add_numbers(slid)
    t0, t1 = a.flow["rate"].t0, a.flow["rate"].t1
    assert _number(slid, "steady discharge rate W").endswith(
        f"(fitted from {significant(t0, 3)} to {significant(t1, 3)} s after the opening; the "
        "gate slid open until 100 s: all of it of a partly open outlet)")
    # one that cleared the outlet within the fit: its end is the fit's, not the clearing
    half = copy.copy(a)
    middle = 0.5 * (t0 + t1)
    half.res = dataclasses.replace(a.res, events={**a.res.events, "gate_opening_time": middle})
    half.numbers = []
    add_numbers(half)
    assert _number(half, "steady discharge rate W").endswith(
        f"(fitted from {significant(t0, 3)} to {significant(t1, 3)} s after the opening; the "
        f"gate slid open until {significant(middle, 3)} s: its start of a partly open outlet)")
    # the discharge window, 0.25-0.75 s after the gate opened: m = W (t - 0.25) of the
    # initial M_TOTAL / 0.75, so 0 and 64 x 0.5 / 106.7 = 30 % discharged
    assert _number(a, "share of the fill's mass discharged at the discharge window") == "0 / 30"
    assert _number(a, "flow pattern") == "funnel flow"
    # grains of one size cannot segregate: the row says so rather than "1 / 1 (1 - 1)" and a
    # band of chance of no width (an audit), and the figure of flat lines is left out
    assert _number(a, "size segregation in the discharge") == (
        "n/a (the grains are all of one size, r = 0.05 m: there are no sizes to segregate)")
    assert a.flow["composition"].diameter_ratio == pytest.approx(np.ones(10), rel=REL)
    from silodem.report.figures_flow import fig_composition

    assert fig_composition(a) is None
    assert float(_number(a, "dead-zone fraction")) == pytest.approx(0.15, rel=5e-3)
    assert float(_number(a, "mass flow index")) == pytest.approx(1 / 3, rel=5e-3)
    # (the centre's sigma_v is constant in each window: its change has no spread, +- 0)
    assert _number(a, "change fill -> discharge, switch_centre") == (  # [%]
        "h n/a (0 Pa in the circle after filling: no relative change from 0), v 50 +- 0")
    # the peaks lie at different heights (0.5 and 0.375 m): the row says so, and the stress
    # at the filling peak's height (6000 Pa there in discharge) is the same-place change
    peak = _number(a, "change fill -> discharge, wall peak: the switch zone's largest wall "
                   "normal stress in each window, at z = 0.5 m -> 0.375 m")
    assert _first_float(peak) == pytest.approx(_pct(4500.0, 6500.0), rel=5e-3)
    same = _number(a, "wall normal stress at the filling peak's height z = 0.5 m")  # [Pa]
    assert same.startswith(f"4,500 -> 6,000 ({significant(_pct(4500.0, 6000.0), 3)} +- ")
    # peaks at one height: the peak-to-peak row is the same-place change, given once
    one = copy.copy(a)
    one.change = {**a.change, "wall peak": {**a.change["wall peak"], "z_discharge": 0.5}}
    one.numbers = []
    add_numbers(one)
    assert not [r for r in one.numbers if r[0].startswith("wall normal stress at the filling")]


def test_bulk_density_above_the_grain_density_is_flagged(synth):
    """A bulk density above the grains' own (porosity < 0: paper case 1's soft springs gave
    2,302 kg/m^3 from grains of 1,607) cannot come from grains that touch as contacts should:
    the key number says so.  The synthetic silo's rho_b (below rho = 800) is printed plain."""
    a, _ = synth
    assert RHO_B < RHO and _number(a, "bulk density") == significant(RHO_B, 4)
    assert _number(a, "bulk density rho_b (cell)") == significant(RHO_B, 4)
    # a fill under 4 diameters above the junction: measured over the whole fill, and said
    thin = copy.copy(a)
    thin.surface, thin.numbers = {**a.surface, "fill": Z_J + 3.5 * DIAM}, []
    add_numbers(thin)
    assert _number(thin, "bulk density rho_b (whole fill: under 4 grain diameters of it above "
                   "the junction)") == significant(RHO_B, 4)
    b = copy.copy(a)
    b.rho_b = 1.25 * RHO
    b.numbers = []
    add_numbers(b)
    assert _number(b, "bulk density") == (
        "1000 (above the grain density 800: the grains overlap far beyond a contact's range; "
        "stiffer contacts are needed)")


def test_en1991_4_loads_of_the_report(synth):
    """EN 1991-4 on the synthetic silo: h_c = surface - z_j = 1.36 - 0.4 tan 50 = 0.883 m over
    B = 1.2 m is 0.736, a squat silo with a hopper, so §5.3 with discharge magnifiers 1 and 1.
    The wall columns' tops are 1.35 and 1.37 m, above the 1.36 m surface: h_o = 0.  phi_r is
    phi_G = 25 deg (no angle of repose set).  p_hf is §5.3.1.1 written out here:
    p_ho (1 - (z / z_o + 1)^n), p_ho = gamma K z_o, z_o = (B/2) / (K mu), n = -(1 + tan phi_r),
    with K = 0.55 of the filling fit and gamma = rho_b g."""
    a, _ = synth
    en = a.en1991_4
    h_c = SURF_FILL - Z_J
    assert (en["kind"], en["section"]) == ("squat", "5.3")
    assert en["h_c"] == pytest.approx(h_c, rel=REL)
    assert (en["h_o"], en["phi_r"], en["C_h"], en["C_w"]) == (0.0, 25.0, 1.0, 1.0)
    z_o = (B / 2) / (K_TRUE * MU_WALL)
    n = -(1.0 + math.tan(math.radians(25.0)))
    depth = SURF_FILL - en["z"]
    p_hf = RHO_B * G * K_TRUE * z_o * (1.0 - (depth / z_o + 1.0) ** n)
    np.testing.assert_allclose(en["p_hf"], p_hf, rtol=1e-6)  # K from curve_fit
    np.testing.assert_allclose(en["p_he"], p_hf, rtol=1e-6)
    np.testing.assert_allclose(en["p_wf"], MU_WALL * p_hf, rtol=1e-6)
    assert en["z"][0] == pytest.approx(Z_J, rel=REL) and en["z"][-1] == SURF_FILL
    row = _number(a, "EN 1991-4 slenderness")
    assert float(row.split(":")[0]) == pytest.approx(h_c / B, rel=5e-3)
    assert row.endswith("squat, loads of §5.3 drawn")
    assert _number(a, "EN 1991-4 discharge magnifiers") == "1, 1"
    # the loads take the wall friction fully mobilised; the cell walls carry 900 Pa of shear
    # on the three fitted bins (test_mobilised_wall_friction_and_janssen_fits), a share of it
    prof = _profile_fill()
    share = 900.0 / (prof[1.25] + prof[1.0] + prof[0.75]) / MU_WALL
    assert _number(a, "EN 1991-4 loads' wall friction") == f"{significant(100 * share, 2)} %"
    assert 0.5 < share < 1  # (0.663) over FEW_MOBILISED = 0.5: no caveat
    b = copy.copy(a)  # a quarter mobilised (0.061 of 0.445 in the quick case 2: 14 %)
    b.en1991_4, b.numbers = {**a.en1991_4, "mobilised": 0.25}, []
    add_numbers(b)
    assert _number(b, "EN 1991-4 loads' wall friction") == (
        "25 %: the settled silo does not show the wall support these loads assume; read them "
        "as the standard's, not as a model of this silo")


def test_en1991_4_hopper_loads_of_the_report(synth):
    """EN 1991-4 §6 on the synthetic hopper (beta = 90 - 50 = 40 deg from the vertical, K =
    0.55, mu_h = tan 24 deg): 2 mu_h tan(beta) = 0.747 > 1 - K = 0.45, a shallow hopper, so
    mu_heff = (1 - K) / (2 tan beta), F_f = 1 - 0.2 / (1 + tan(beta) / mu_heff), n = (1 - 0.2)
    mu_heff cot(beta) (a wedge, S = 1), and the discharge loads are the filling ones.  p_vft is
    §5.3's p_vf = gamma z_V at the transition (h_o = 0: z_V = z_o ((h_c/z_o + 1)^(m+1) - 1) /
    (m + 1), m = -(1 + tan 25 deg)); p_nf = F_f p_v with p_v as the standard prints it, x from
    the virtual apex D/2 / tan(beta) under the outlet.  phi_i from K = 1.1 (1 - sin phi_i) is
    30 deg."""
    a, _ = synth
    h = a.en1991_4["hopper"]
    beta, gamma = 40.0, RHO_B * G
    t = math.tan(math.radians(beta))
    mu = (1 - K_TRUE) / (2 * t)
    F_f = 1 - 0.2 / (1 + t / mu)
    n = 0.8 * mu / t
    z_o, m, h_c = (B / 2) / (K_TRUE * MU_WALL), -(1 + math.tan(math.radians(25.0))), SURF_FILL - Z_J
    p_vft = gamma * z_o * ((h_c / z_o + 1) ** (m + 1) - 1) / (m + 1)
    apex = 0.5 * D_OUT / t
    h_h, x = Z_J + apex, h["z"] + apex
    p_v = gamma * h_h / (n - 1) * (x / h_h - (x / h_h) ** n) + p_vft * (x / h_h) ** n
    assert h["kind"] == "shallow" and h["phi_i"] == pytest.approx(30.0, rel=1e-6)
    assert (h["mu_eff"], h["F_f"], h["F_e"]) == (pytest.approx(mu, rel=1e-6),
                                                 pytest.approx(F_f, rel=1e-6),
                                                 pytest.approx(F_f, rel=1e-6))
    assert h["p_vft"] == pytest.approx(p_vft, rel=1e-6)  # K from curve_fit
    np.testing.assert_allclose(h["p_nf"], F_f * p_v, rtol=1e-6)
    np.testing.assert_allclose(h["p_ne"], F_f * p_v, rtol=1e-6)
    assert h["z"][0] == 0.0 and h["z"][-1] == pytest.approx(Z_J, rel=REL)
    row = _number(a, "EN 1991-4 §6 hopper class")
    assert row.startswith("shallow, mu_eff ") and row.endswith("F_e = F_f (shallow hopper)")
    at_top = _number(a, "EN 1991-4 hopper normal pressure at the transition")
    assert at_top == f"{F_f * p_vft:,.0f} / {F_f * p_vft:,.0f}"
    # the study table's columns (docs/sweeps.md) hold the same numbers
    s = synth[1]
    assert (s["en1991_4_class"], s["en1991_4_hopper_class"]) == ("squat", "shallow")
    assert s["janssen_K_fill"] == pytest.approx(K_TRUE, rel=FIT_REL)
    assert s["en1991_4_hopper_p_n_fill"] == pytest.approx(F_f * p_vft, rel=1e-6)
    assert s["en1991_4_hopper_p_n_discharge"] == pytest.approx(F_f * p_vft, rel=1e-6)


def test_en1991_4_steep_hopper_of_the_report_takes_phi_i_from_K(synth):
    """K = 0.2 makes the synthetic hopper steep (2 mu_h tan 40 deg = 0.747 < 1 - K = 0.8): the
    discharge load is F_e p_v with F_e from phi_i = arcsin(1 - K / 1.1) (K = 1.1 (1 - sin
    phi_i)) and phi_wh = phi_P = 24 deg, as EN 1991-4 prints it, and p_v of the slice balance
    with p_n = F_e p_v (a wedge: n = F_e (1 + mu_h cot(beta)) - 1); p_ne = F_e p_vft at the
    transition.  The only test of the report's steep path."""
    a, _ = synth
    h = hopper_loads(a, 0.2, 20000.0)
    s, phi_wh, beta = 1 - 0.2 / 1.1, math.atan(MU_WALL), math.radians(40.0)
    eps = phi_wh + math.asin(math.sin(phi_wh) / s)
    F_e = (1 + s * math.cos(eps)) / (1 - s * math.cos(2 * beta + eps))
    n = F_e * (1 + MU_WALL / math.tan(beta)) - 1
    apex = 0.5 * D_OUT / math.tan(beta)
    h_h, x = Z_J + apex, h["z"] + apex
    p_v = RHO_B * G * h_h / (n - 1) * (x / h_h - (x / h_h) ** n) + 20000.0 * (x / h_h) ** n
    assert h["kind"] == "steep" and h["mu_eff"] == pytest.approx(MU_WALL, rel=1e-12)
    assert h["phi_i"] == pytest.approx(math.degrees(math.asin(s)), rel=1e-12)
    assert h["F_e"] == pytest.approx(F_e, rel=1e-12)
    np.testing.assert_allclose(h["p_ne"], F_e * p_v, rtol=1e-9)
    assert h["p_ne"][-1] == pytest.approx(F_e * 20000.0, rel=1e-12)
    # the key numbers give the exponent used and the one EN 1991-4 §6.3.1 prints,
    # S (F mu cot(beta) + F) - 2 with S = 1: exactly 1 lower for a wedge
    printed = F_e * MU_WALL / math.tan(beta) + F_e - 2
    assert (h["n_e"], h["n_e_printed"]) == (pytest.approx(n, rel=1e-12),
                                            pytest.approx(printed, rel=1e-12))
    rows = []
    _hopper_numbers(rows, h)
    assert rows[-1][0].startswith("EN 1991-4 hopper discharge exponent n")
    assert rows[-1][1] == f"{n:.3g} / {printed:.3g}"
    # and the curve's legend says its exponent is not the printed one (it said only "§6")
    from matplotlib.figure import Figure

    from silodem.report.figures_stress import _en1991_4_curve

    b = copy.copy(a)
    b.en1991_4 = {**a.en1991_4, "hopper": h}
    ax = Figure().subplots()
    _en1991_4_curve(ax, b, "discharge")
    legend = [t for t in (ln.get_label() for ln in ax.lines) if "§6 hopper discharge" in t]
    assert len(legend) == 1 and (f"wedge exponent n = {n:.3g} by the slice balance, not "
                                 f"§6.3.1's printed {printed:.3g}") in legend[0], legend
    ax = Figure().subplots()
    _en1991_4_curve(ax, b, "fill")
    assert not [ln for ln in ax.lines if "wedge exponent" in ln.get_label()]


def test_en1991_4_hopper_rules_are_left_out_for_K_at_least_1(synth):
    """K >= 1 (paper case 2 fits K = 1.3 with its 430 large grains) makes every hopper shallow
    (tan(beta) > (1 - K) / (2 mu_h) <= 0) with no positive mobilised friction: the key
    numbers say the rules do not apply and the figures draw no hopper curve."""
    from matplotlib.figure import Figure

    from silodem.report.figures_stress import _en1991_4_curve

    a, _ = synth
    b = copy.copy(a)
    b.en1991_4 = {**a.en1991_4, "hopper": hopper_loads(a, 1.32, 20000.0)}
    assert b.en1991_4["hopper"]["kind"] == "shallow" and "p_nf" not in b.en1991_4["hopper"]
    b.numbers = []
    add_numbers(b)
    assert _number(b, "EN 1991-4 §6 hopper class") == (
        "shallow: the rules do not apply (K = 1.32 >= 1 leaves a shallow hopper no mobilised "
        "friction)")
    ax = Figure().subplots()
    _en1991_4_curve(ax, b, "fill")
    assert [line.get_label()[:15] for line in ax.lines] == ["EN 1991-4 §5.3 "]
    # Fig. 6 draws the standard's discharge loads, those of the full silo, against a profile
    # measured as it empties: the labels say whose they are
    ax = Figure().subplots()
    _en1991_4_curve(ax, a, "discharge")
    labels = [line.get_label() for line in ax.lines]
    assert len(labels) == 2 and labels[0].endswith(
        f"; the full silo's, surface at z = {a.surface['fill']:.2f} m)")
    assert labels[1].endswith("; the full silo's)")


def test_en1991_4_skips_frictionless_walls(synth):
    """phi_P = 0 (allowed by the config) gives z_o = A/(K mu U) = infinity: the report leaves the
    EN loads out instead of raising ZeroDivisionError from analyse (and so from the study's
    table row and the API)."""
    a, _ = synth
    b = copy.copy(a)
    b.geom = {**a.geom, "mu_wall": 0.0}
    b.en1991_4 = {}
    add_loads(b, SURF_FILL)
    assert b.en1991_4 == {}


def test_a_fill_too_shallow_for_the_janssen_fit_says_why_and_keeps_its_en_class(synth):
    """Filled to 0.9 m, the synthetic silo has one cell-wall bin (z = 0.75) between the switch
    zone's top (z_j + 2 d) and the surface less half a diameter; the fit needs two.  The key
    numbers said nothing about Janssen then, and the EN 1991-4 rows vanished with it, though
    the class needs only h_c / B: now the Janssen row says why it is n/a, and the class row
    stays, with h_c = 0.9 - z_j and no loads."""
    from silodem.report.analysis import _fit_theory
    from silodem.silo.geometry import silo_shape

    a, _ = synth
    b = copy.copy(a)
    b.surface = {**a.surface, "fill": 0.9}
    b.janssen, b.janssen_free, b.janssen_missing = {}, None, {}
    b.mu_mobilised, b.hopper, b.en1991_4, b.numbers = {}, {}, {}, []
    _fit_theory(b, silo_shape(b.res.cfg))
    add_loads(b, 0.9)
    add_numbers(b)
    assert "fill" not in b.janssen and b.janssen_free is None
    assert _number(b, "Janssen K fitted to the cell wall profile, after filling") == (
        f"n/a (1 wall bin(s) on the cell walls between the switch zone's top, z = "
        f"{SWITCH[1]:.3g} m, and the surface, z = 0.9 m, less half a diameter; the fit needs 2)")
    assert "discharge" in b.janssen  # the discharge window's own surface is unchanged
    h_c = 0.9 - Z_J
    assert b.en1991_4 == {"kind": "squat", "section": "5.3", "h_c": pytest.approx(h_c, rel=REL),
                          "ratio": pytest.approx(h_c / B, rel=REL),
                          "missing": "no K: no Janssen fit after filling"}
    assert _number(b, "EN 1991-4 slenderness") == (
        f"{significant(h_c / B, 3)}: squat, no loads drawn (§5.3): no K: no Janssen fit after "
        "filling")
    assert not [row for row in b.numbers if "discharge magnifiers" in row[0]]


def test_highest_wall_contact_looks_one_column_from_each_wall():
    """EN 1991-4's highest solid-wall contact: the highest grain top within one column
    (B/12 = 0.1 m) of either wall; a side with no grain there is left out, not replaced by
    the next column."""
    snap = {"particles": {"x": np.array([0.05, 0.65, 1.05]), "y": np.array([0.7, 0.9, 0.8]),
                          "radius": np.array([0.05, 0.05, 0.05])}}
    assert highest_wall_contact(snap, B, DIAM) == pytest.approx(0.75, rel=REL)
    snap["particles"]["x"][0] = 1.15  # now right at the right wall, the left one bare
    assert highest_wall_contact(snap, B, DIAM) == pytest.approx(0.75, rel=REL)
    snap["particles"]["x"][0] = 0.35  # no grain by either wall
    assert math.isnan(highest_wall_contact(snap, B, DIAM))


def test_a_retaining_silo_is_named_but_gets_no_en_loads(synth):
    """A flat silo filled to h_c/d_c <= 0.4 is 'retaining' (EN 1991-4 §5.4, not built): the key
    numbers name the class and the figure draws no EN curve (no KeyError)."""
    from matplotlib.figure import Figure

    from silodem.report.figures_stress import _en1991_4_curve

    a, _ = synth
    b = copy.copy(a)
    b.en1991_4 = {"kind": "retaining", "section": "5.4", "h_c": 0.4, "ratio": 0.4 / B}
    b.numbers = []
    add_numbers(b)
    assert _number(b, "EN 1991-4 slenderness").endswith("retaining, no loads drawn (§5.4, not "
                                                        "built in silodem)")
    assert not [row for row in b.numbers if "discharge magnifiers" in row[0]]
    ax = Figure().subplots()
    for key in ("fill", "discharge"):
        _en1991_4_curve(ax, b, key)
    assert not ax.lines


TABLE_NAN_WITHOUT_DISCHARGE = [
    "switch_sigma_h_discharge", "switch_sigma_v_discharge", "switch_sigma_h_change_pct",
    "switch_sigma_v_change_pct", "switch_ratio_discharge", "switch_ratio_cv_discharge",
    "wall_peak_discharge", "wall_peak_z_discharge", "wall_peak_change_pct", "discharge_rate",
    "discharge_rate_err", "mass_flow_index", "dead_fraction", "window_emptied_start_pct",
    "window_emptied_end_pct"]


def test_a_run_without_discharge_gives_nan_discharge_columns(tmp_path):
    """No discharge sample (discharge disabled): every discharge quantity and every change is
    NaN ('could not be measured', docs/sweeps.md), while the fill columns keep the values of
    the full synthetic run (the fill window is the last 0.5 s of settling either way)."""
    folder = write_synthetic(tmp_path / "nodis", discharge=False)
    s = summarise_run(folder)
    _check(s, {k: NAN for k in TABLE_NAN_WITHOUT_DISCHARGE})
    # the report says once why there is no change, instead of "h n/a %, v n/a %" per circle
    a = analyse(load_results(folder))
    assert _number(a, "change fill -> discharge") == (
        "n/a (no measurement sample in the discharge window)")
    res = load_results(folder)
    res.cfg = res.cfg.model_copy(update={
        "discharge": res.cfg.discharge.model_copy(update={"enabled": False})})
    assert _number(analyse(res), "change fill -> discharge") == (
        "n/a (the run has no discharge: discharge.enabled = false)")
    _check(s, {"switch_sigma_h_fill": 2090.0, "switch_sigma_v_fill": SW_FILL_V,
               "switch_ratio_fill": 12540 / 25100, "wall_peak_fill": 4500.0,
               "switch_ratio_cv_fill": math.sqrt(0.008) / 0.5,
               "circle_switch_left_ratio_cv_discharge": NAN,
               "circle_switch_left_sigma_h_change_pct": NAN})
    assert s["flow_pattern"] == ""
    # the captions that speak of discharge panels say there are none (Figs. 4, 5 and 7 read
    # "after filling and during discharge"): of a run without discharge, or of one stopped
    # before it (discharge enabled, no opening); the others are as they were
    from silodem.report.html import FIGURES, NO_DISCHARGE, NOT_REACHED

    disabled = analyse(res)
    for b, note in ((disabled, NO_DISCHARGE), (a, NOT_REACHED)):
        captions = {spec.name: spec.caption_for(b) for spec in FIGURES}
        assert captions["fig5_force_network"].endswith("drawn to the wall." + note)
        assert not captions["fig3b_vertical_filling"].endswith(note)
    full = analyse(load_results(write_synthetic(tmp_path / "full")))
    assert not any(spec.caption_for(full).endswith((NO_DISCHARGE, NOT_REACHED))
                   for spec in FIGURES)


def test_an_empty_fill_window_gives_nan_fill_columns(tmp_path):
    """No settling sample (the gate opened right after filling): the fill window is empty, so
    the fill values are NaN and so is every change (NaN base), in the table and in the
    report's change rows; the discharge values keep their closed forms."""
    folder = write_synthetic(tmp_path / "nofill", settle=False)
    s = summarise_run(folder)
    _check(s, {"switch_sigma_h_fill": NAN, "switch_sigma_v_fill": NAN,
               "switch_ratio_fill": NAN, "switch_ratio_cv_fill": NAN,
               "switch_sigma_h_change_pct": NAN, "switch_sigma_v_change_pct": NAN,
               "wall_peak_fill": NAN, "wall_peak_change_pct": NAN,
               "circle_switch_right_sigma_v_fill": NAN,
               "circle_switch_right_sigma_v_change_pct": NAN,
               "switch_sigma_h_discharge": SW_DIS_H, "switch_ratio_cv_discharge": 0.2,
               "wall_peak_discharge": 6500.0})
    a = analyse(load_results(folder))
    _check(a.change["switch_left"], {"sigma_h_fill": NAN, "sigma_h_change_pct": NAN,
                                     "sigma_h_discharge": 1800.0})
    assert _number(a, "change fill -> discharge") == (
        "n/a (no measurement sample in the fill window)")
    assert "fill" not in a.peaks and a.peaks["discharge"] == pytest.approx((6500.0, 0.375))


def test_change_without_a_base_is_nan():
    """percent_change(fill, discharge) = 100 (discharge - fill) / fill (docs/sweeps.md; the
    report's and the study's), worked by hand; a zero, NaN or infinite base, or a NaN after,
    has no % change: NaN."""
    from silodem.report.numbers import percent_change

    assert percent_change(200.0, 150.0) == -25.0
    assert percent_change(-200.0, -100.0) == -50.0
    assert percent_change(4.0, 5.0) == 25.0
    for before, after in ((0.0, 5.0), (-0.0, 5.0), (NAN, 5.0), (math.inf, 5.0), (4.0, NAN)):
        assert math.isnan(percent_change(before, after)), (before, after)


def test_ratio_stats_by_hand():
    """_ratio_stats(sigma_h, sigma_v) = (ratio of the means, std/mean of the sampled ratio
    without the samples under 10 % of the median sigma_v), worked by hand: means 12/4 and
    12.2/4 with the unloaded sample (sigma_v = 0.2 < 0.1 x median 4) in them; ratios 0.5, 1.0,
    0.75 kept -> mean 0.75, population std sqrt(0.125 / 3).  No usable sample (empty, all NaN,
    sigma_v <= 0) gives NaN, NaN."""
    sh = np.array([2.0, 4.0, 3.0, 3.0])
    sv = np.array([4.0, 4.0, 4.0, 0.2])
    ratio, cv = _ratio_stats(sh, sv)
    assert ratio == pytest.approx(12.0 / 12.2, rel=REL)
    assert cv == pytest.approx(math.sqrt(0.125 / 3) / 0.75, rel=REL)
    for a, b in ((np.zeros(0), np.zeros(0)), (np.array([NAN]), np.array([NAN])),
                 (np.array([1.0, 2.0]), np.array([0.0, -1.0]))):
        r, c = _ratio_stats(a, b)
        assert math.isnan(r) and math.isnan(c)


# --- one real run: recompute from the raw datasets ---------------------------------------------


@pytest.fixture(scope="module")
def real_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("real") / "run"
    run_simulation(tiny_hopper_config(report=False), out, progress=False)  # no report.html
    return out


def _read(folder: Path) -> dict:
    with h5py.File(folder / "results.h5", "r") as h5:
        def get(path):
            return h5[path][()]
        raw = {"events": dict(h5["events"].attrs), "attrs": dict(h5.attrs),
               "flow_attrs": dict(h5["measure/flow"].attrs)}
        for p in ("measure/time", "measure/phase", "measure/circles/stress",
                  "measure/wall_bins/wall", "measure/wall_bins/z", "measure/wall_bins/normal",
                  "measure/band/coordination",
                  "timeseries/time", "timeseries/phase", "timeseries/discharged_mass",
                  "measure/flow/exit_time", "measure/flow/max_displacement",
                  "measure/flow/mass_flow_index/v_wall", "measure/flow/mass_flow_index/v_axis",
                  "measure/flow/mass_flow_index/level", "settled/particles/x",
                  "settled/particles/y", "settled/particles/radius"):
            raw[p] = get(p)
        raw["circles"] = [n.decode() if isinstance(n, bytes) else str(n)
                          for n in get("measure/circles/name")]
        raw["walls"] = [n.decode() if isinstance(n, bytes) else str(n) for n in get("walls/name")]
    return raw


def _recompute(raw: dict) -> dict:
    """The table's quantities from their definitions (docs/sweeps.md, docs/measurements.md)."""
    cfg = tiny_hopper_config()
    window, delay = cfg.measure.window, cfg.measure.discharge_delay
    t, phase = raw["measure/time"], raw["measure/phase"]
    t_open = float(raw["events"]["discharge_start_time"])
    edges = (t_open - window, t_open + delay, t_open + delay + window)
    # precondition: no sample on an edge, so open or closed windows are the same thing
    assert min(abs(t - e).min() for e in edges) > 1e-6
    win = {"fill": (phase == 1) & (t > t_open - window) & (t <= t_open),
           "discharge": (phase == 2) & (t > edges[1]) & (t < edges[2])}
    assert win["fill"].sum() >= 10 and win["discharge"].sum() >= 10
    stress = raw["measure/circles/stress"]
    names = raw["circles"]
    wall = [names.index("switch_left"), names.index("switch_right")]
    out: dict = {}

    def stats(sh, sv, prefix):
        for key, m in win.items():
            h, v = sh[m], sv[m]
            assert np.isfinite(h).all() and np.isfinite(v).all() and (v > 0).all()
            out[f"{prefix}sigma_h_{key}"], out[f"{prefix}sigma_v_{key}"] = h.mean(), v.mean()
            loaded = v >= 0.1 * np.median(v)
            r = h[loaded] / v[loaded]
            cv = r.std() / abs(r.mean())
            if prefix == "switch_":
                out[f"switch_ratio_{key}"] = h.mean() / v.mean()
                out[f"switch_ratio_cv_{key}"] = cv
            elif key == "discharge":
                out[f"{prefix}ratio_cv_discharge"] = cv
        for comp in ("sigma_h", "sigma_v"):
            out[f"{prefix}{comp}_change_pct"] = _pct(out[f"{prefix}{comp}_fill"],
                                                     out[f"{prefix}{comp}_discharge"])

    stats(stress[:, wall, 0].mean(axis=1), stress[:, wall, 1].mean(axis=1), "switch_")
    for k, name in enumerate(names):
        stats(stress[:, k, 0], stress[:, k, 1], f"circle_{name}_")
    # wall profile: both edges (vertical wall + hopper wall), window means, sides averaged
    wb, zb, nb = raw["measure/wall_bins/wall"], raw["measure/wall_bins/z"], \
        raw["measure/wall_bins/normal"]
    for key, m in win.items():
        side = {}
        for s in ("left", "right"):
            sel = np.isin(wb, [raw["walls"].index(f"{s}_wall"), raw["walls"].index(f"{s}_hopper")])
            order = np.argsort(zb[sel])
            side[s] = (zb[sel][order], nb[m][:, sel].mean(axis=0)[order])
        # mirror-image bins: the same heights up to round-off
        assert np.allclose(side["left"][0], side["right"][0], rtol=0.0, atol=1e-12)
        z, sn = side["left"][0], 0.5 * (side["left"][1] + side["right"][1])
        zone = (z >= SWITCH[0]) & (z <= SWITCH[1])
        k = np.flatnonzero(zone)[np.argmax(sn[zone])]
        out[f"wall_peak_{key}"], out[f"wall_peak_z_{key}"] = sn[k], z[k]
    out["wall_peak_change_pct"] = _pct(out["wall_peak_fill"], out["wall_peak_discharge"])
    # coordination number in the junction band: window means (eq. 10 per sample)
    band = raw["measure/band/coordination"]
    for key, m in win.items():
        assert np.isfinite(band[m]).all()
        out[f"coordination_{key}"] = band[m].mean()
    out["coordination_change_pct"] = _pct(out["coordination_fill"],
                                          out["coordination_discharge"])
    # steady rate: least squares between 15 % and 75 % of the final mass, 5 block slopes
    sel = raw["timeseries/phase"] == 2
    tt, mm = raw["timeseries/time"][sel] - t_open, raw["timeseries/discharged_mass"][sel]
    # how far the silo had emptied at the discharge window's ends: of the initial mass
    m0 = float(raw["events"]["initial_mass"])
    for name, edge in (("start", edges[1]), ("end", edges[2])):
        out[f"window_emptied_{name}_pct"] = 100.0 * np.interp(edge - t_open, tt, mm) / m0
    keep = (mm >= 0.15 * mm.max()) & (mm <= 0.75 * mm.max())
    ts, ms = tt[keep], mm[keep]

    def slope(x, y):
        return np.sum((x - x.mean()) * (y - y.mean())) / np.sum((x - x.mean()) ** 2)

    out["discharge_rate"] = slope(ts, ms)
    be = ts[0] + (ts[-1] - ts[0]) * np.arange(6) / 5
    assert min(abs(ts - e).min() for e in be[1:-1]) > 1e-6  # no sample on a block edge
    blocks = [(ts >= a) & (ts <= b) for a, b in itertools.pairwise(be)]
    assert min(b.sum() for b in blocks) >= 3
    slopes = np.array([slope(ts[b], ms[b]) for b in blocks])
    out["discharge_rate_err"] = slopes.std(ddof=1) / math.sqrt(5)
    # flow pattern
    fa = raw["flow_attrs"]
    lo, hi = float(fa["mfi_band_lo"]), float(fa["mfi_band_hi"])
    vw, va = raw["measure/flow/mass_flow_index/v_wall"], raw["measure/flow/mass_flow_index/v_axis"]
    ok = (raw["measure/flow/mass_flow_index/level"] > hi + (hi - lo)) & np.isfinite(vw) & \
        np.isfinite(va)
    out["mass_flow_index"] = vw[ok].mean() / va[ok].mean()
    dead = np.isnan(raw["measure/flow/exit_time"]) & \
        (raw["measure/flow/max_displacement"] < 0.5 * DIAM)
    out["dead_fraction"] = dead.mean()
    ev = raw["events"]
    out.update(junction_z=Z_J, fill_level=float(ev["fill_level"]),
               discharged_fraction=float(ev["discharged_fraction"]),
               dt=float(raw["attrs"]["dt"]))
    # surface: highest grain top in each of the 12 columns of width d; bulk density below it
    # (each grain's solid area in the band, by circular segments)
    x, y, r = (raw[f"settled/particles/{k}"] for k in ("x", "y", "radius"))
    col = np.clip(np.searchsorted(np.linspace(0.0, B, N_COLS + 1), x, side="right") - 1,
                  0, N_COLS - 1)
    surf = np.mean([(y + r)[col == c].max() for c in range(N_COLS) if (col == c).any()])
    lo_b, hi_b = Z_J + DIAM, surf - DIAM
    out["_surface"] = surf
    solid = _segment(r, lo_b - y) - _segment(r, hi_b - y)  # each disk's part in the band
    out["bulk_density"] = RHO * solid.sum() / (B * (hi_b - lo_b))
    return {k: float(v) for k, v in out.items()}


@pytest.fixture(scope="module")
def real(real_run):
    raw = _read(real_run)
    return raw, _recompute(raw), summarise_run(real_run), analyse(load_results(real_run))


def test_real_run_table_row_matches_a_recomputation(real):
    """Every number of the real run's table row equals its recomputation from the raw datasets
    (docs' definitions, plain NumPy here), up to float round-off: the means, ratios, coefficients
    of variation and changes exactly (REL); the least-squares rate and its error to 1e-9 (two
    different least-squares algorithms, same data)."""
    raw, recomputed, s, _ = real
    rates = {k: recomputed[k] for k in ("discharge_rate", "discharge_rate_err")}
    exp = {k: v for k, v in recomputed.items() if not k.startswith("_") and k not in rates}
    _check(s, exp)
    _check(s, rates, rel=1e-9)
    assert s["flow_pattern"] == ("mass flow" if exp["mass_flow_index"] >= 0.3
                                 and exp["dead_fraction"] < 0.01 else "funnel flow")
    ev = raw["events"]
    assert (s["n_poured"], s["steps"]) == (int(ev["n_poured"]), int(raw["attrs"]["steps"]))
    assert s["lost_count"] == int(ev.get("lost_count", 0))
    assert s["discharge_end_reason"] == str(ev["discharge_end_reason"])
    # conservation: the discharged fraction is the mass that left over the initial mass
    assert s["discharged_fraction"] == pytest.approx(
        raw["timeseries/discharged_mass"][-1] / float(ev["initial_mass"]), rel=REL)
    # every cell is a plain Python value (a NumPy scalar would be written 'np.float64(...)')
    assert {type(v) for v in s.values()} <= {float, int, str, bool}
    assert set(s) >= {c for c, _, _ in COLUMNS}


def test_real_run_report_matches_a_recomputation(real):
    """The report's surface height, bulk density, switch-zone peaks and rate on the real run
    equal their recomputation from the settled grains, the wall bins and the discharged mass."""
    _, exp, _, a = real
    assert a.surface["fill"] == pytest.approx(exp["_surface"], rel=REL)
    assert a.rho_b == pytest.approx(exp["bulk_density"], rel=REL)
    for key in ("fill", "discharge"):
        assert a.peaks[key] == pytest.approx(
            (exp[f"wall_peak_{key}"], exp[f"wall_peak_z_{key}"]), rel=REL)
    assert a.flow["rate"].rate == pytest.approx(exp["discharge_rate"], rel=1e-9)
    assert a.flow["mfi"] == pytest.approx(exp["mass_flow_index"], rel=REL)
    for name in ("switch_left", "switch_centre", "switch_right"):
        for comp in ("sigma_h", "sigma_v"):
            for key in ("fill", "discharge"):
                assert a.change[name][f"{comp}_{key}"] == pytest.approx(
                    exp[f"circle_{name}_{comp}_{key}"], rel=REL)


# the table's columns as docs/sweeps.md lists them, in its order
DOC_COLUMNS = [
    "switch_sigma_h_fill", "switch_sigma_h_discharge", "switch_sigma_h_change_pct",
    "switch_sigma_v_fill", "switch_sigma_v_discharge", "switch_sigma_v_change_pct",
    "switch_ratio_fill", "switch_ratio_discharge", "switch_ratio_cv_fill",
    "switch_ratio_cv_discharge", "wall_peak_fill", "wall_peak_z_fill", "wall_peak_discharge",
    "wall_peak_z_discharge", "wall_peak_change_pct", "wall_at_fill_peak_change_pct",
    "coordination_fill",
    "coordination_discharge", "coordination_change_pct", "janssen_K_fill", "janssen_K_fill_err",
    "janssen_K_fill_above_1", "wall_friction_mobilised_fill", "wall_friction_negative_fill",
    "en1991_4_class", "en1991_4_hopper_class", "en1991_4_hopper_p_n_fill",
    "en1991_4_hopper_p_n_discharge", "discharge_rate", "discharge_rate_err",
    "window_emptied_start_pct", "window_emptied_end_pct",
    "mass_flow_index", "dead_fraction", "flow_pattern", "segregation_first",
    "segregation_last", "junction_z", "fill_level",
    "bulk_density", "n_poured", "lost_count",
    "discharged_fraction", "discharge_end_reason", "steps", "dt"]


def _read_back(cell: str, value):
    if isinstance(value, bool):
        return cell == "true"
    if isinstance(value, float):
        return float(cell)
    if isinstance(value, int):
        return int(cell)
    return cell


def test_table_csv_round_trips_every_value(real, synth, tmp_path):
    """table_rows -> table_csv -> results.csv -> read_table gives back every value exactly
    (floats bit for bit, NaN as NaN, -0.0 with its sign, ints, strings with commas, quotes and
    a line break), rows in plan order (a run without a summary has no row), columns in the
    documented order: id, slug, seed, grid keys, the columns of docs/sweeps.md, then the extra
    (per-circle) ones sorted.  Expected values: the summaries given to it."""
    _, _, real_summary, _ = real
    _, synth_summary = synth
    odd = dict(synth_summary, discharge_rate=0.1, discharge_rate_err=1 / 3, dt=5e-324,
               fill_level=1.7976931348623157e308, wall_peak_z_fill=-0.0,
               switch_ratio_fill=math.inf, switch_ratio_discharge=NAN,
               n_poured=2**53 + 1, discharge_end_reason='clog, "arch"\nat the outlet',
               summary_error="ValueError: a, b")
    grid = ["silo.hopper_angle_from_horizontal_deg", "material.friction_deg"]
    runs = [types.SimpleNamespace(id=i, slug=f"slug-{i}", seed=seed,
                                  point={grid[0]: theta, grid[1]: phi})
            for i, seed, theta, phi in (("a", 7, 50.0, 25), ("b", 8, 35.0, 30),
                                        ("c", 9, 0.1, 20))]
    plan = types.SimpleNamespace(runs=runs)
    rows = table_rows(plan, {"c": odd, "a": real_summary})
    assert [r["id"] for r in rows] == ["a", "c"]
    assert rows[1][grid[0]] == 0.1 and rows[1]["seed"] == 9
    columns = table_columns(grid, rows)
    extra = sorted((set(real_summary) | set(odd)) - set(DOC_COLUMNS))
    assert columns == ["id", "slug", "seed", *grid, *DOC_COLUMNS, *extra]
    assert "summary_error" in extra and "circle_switch_left_sigma_h_fill" in extra
    path = tmp_path / "results.csv"
    write_text(path, table_csv(columns, rows))
    back = read_table(path)
    assert len(back) == 2
    for row, cells in zip(rows, back):
        assert list(cells) == columns
        for col in columns:
            value = row.get(col)
            if value is None:
                assert cells[col] == "", col
                continue
            got = _read_back(cells[col], value)
            if isinstance(value, float):
                assert (math.isnan(got) and math.isnan(value)) or (
                    got == value and math.copysign(1, got) == math.copysign(1, value)), col
            else:
                assert got == value, col
    assert back[1]["discharge_end_reason"] == 'clog, "arch"\nat the outlet'
    assert back[0]["flow_pattern"] == real_summary["flow_pattern"]


def test_numbers_are_written_with_their_significant_digits():
    """The reports' number format, worked by hand: 3 significant digits, and every integer digit
    from 10^3 on (a stress of 2053.4 Pa is '2053', not '2.05e+03'); an exponent only for very
    small or very large values; n/a for what is not a number."""
    from silodem.report.numbers import significant

    cases = [(2053.4, "2053"), (-2053.6, "-2054"), (999.6, "1000"), (123.44, "123"),
             (12.345, "12.3"), (0.012345, "0.0123"), (1.5e-5, "1.5e-05"), (0.0, "0"),
             (2.5e9, "2.5e+09"), (float("nan"), "n/a"), (float("inf"), "n/a"), (None, "n/a")]
    for value, text in cases:
        assert significant(value) == text, value
    assert significant(64.0, 4) == "64" and significant(12345.6, 4) == "12346"


def test_fits_whose_error_is_over_half_their_value_are_called_poorly_determined():
    """The quick hopper's Janssen K came out 1.29 +- 0.69 from six noisy wall bins, printed as
    a measurement; a fit error over half the value is now said to be one."""
    from silodem.report.key_numbers import _fitted

    assert _fitted(1.286, 0.69).endswith("(poorly determined: the error is over half the value)")
    assert _fitted(0.55, 0.012) == "0.55 +- 0.012"
    assert _fitted(0.4, NAN).endswith("(not determined: the wall bins do not fix it (no finite "
                                      "error))")  # no error estimate is no determination


def test_the_ratio_figure_leaves_out_the_samples_the_cv_leaves_out():
    """sigma_v of 2e-16 Pa made a ratio of 6e15 on the study's Fig. 7 while the CV left that
    sample out (sigma_v under UNLOADED = 0.1 x its median): the figure now leaves it out too,
    as the run report's Fig. 7 does (one function, ``report.draw.loaded_ratio``)."""
    from silodem.report.draw import loaded_ratio

    sv = np.array([2e-16, 1.0, 2.0, 3.0, 0.0, NAN])  # median of the positive ones: 1.5
    sh = np.array([1.0, 0.5, 1.0, 1.5, 1.0, 1.0])
    np.testing.assert_array_equal(loaded_ratio(sh, sv), [NAN, 0.5, 0.5, 0.5, NAN, NAN])


def test_en1991_4_loads_are_not_drawn_from_a_poorly_determined_k(synth):
    """The EN 1991-4 loads take K from the Janssen fit after filling; a K whose error is over
    half of it (the quick study's 3.1 +- 5.2) gave a hopper class and loads from noise: now
    the class alone, and the reason."""
    import copy
    import dataclasses

    from silodem.report import eurocode

    a, _ = synth
    assert "p_hf" in a.en1991_4  # the synthetic run's K_TRUE, fitted exactly: loads
    noisy = copy.copy(a)
    noisy.en1991_4 = {}
    noisy.janssen = {**a.janssen, "fill": dataclasses.replace(a.janssen["fill"], K=3.1,
                                                               K_err=5.2)}
    eurocode.add_loads(noisy, eurocode.highest_wall_contact(
        a.res.snapshot("settled"), a.geom["B"], a.geom["d"]))
    assert noisy.en1991_4["kind"] == a.en1991_4["kind"] and "p_hf" not in noisy.en1991_4
    assert noisy.en1991_4["missing"] == ("K = 3.1 +- 5.2 of the Janssen fit after filling is "
                                         "poorly determined")


def test_a_free_janssen_fit_above_the_coulomb_limit_is_flagged(synth):
    """A free fit's mu_w above tan(phi_P) by more than its error is friction no wall contact
    can carry (|F_t| <= mu F_n, Coulomb): the key number and the Fig. 3a legend say the profile
    does not follow Janssen (a study run gave mu_w = 0.81 +- 0.12 for tan phi_P = 0.176).
    The synthetic profile's mu_w = tan 24 deg is at the walls' own tan phi_P: not flagged;
    with walls of tan phi_P = 0.2 it is."""
    from silodem.report.analysis import above_coulomb
    from silodem.report.figures_stress import fig_horizontal

    a, _ = synth
    row = "Janssen free fit after filling: K, mu_w"
    assert "above tan phi_P" not in _number(a, row)
    assert not above_coulomb(a.janssen_free, MU_WALL)
    b = copy.copy(a)
    b.geom, b.numbers = {**a.geom, "mu_wall": 0.2}, []
    add_numbers(b)
    assert above_coulomb(b.janssen_free, 0.2)
    assert _number(b, row).endswith("; above tan phi_P = 0.2, the most friction the walls can "
                                    "carry: this profile does not follow Janssen's law")
    legend = fig_horizontal(b, "fill").legends[0]  # legend_below: the figure's
    labels = [" ".join(t.get_text().split()) for t in legend.get_texts()]
    assert any(t.endswith("(> tan phi_P: not Janssen)") for t in labels), labels
    # not judged: an exact fit to two bins (no error) and a fit at its lower bound (no wall
    # support), which the row calls ~0 already (frictionless walls: tan phi_P = 0)
    # above the limit within its error (a case-2 run: 0.515 +- 0.23 for 0.445): said, as no
    # measure of the walls, not as the law's failure
    c = copy.copy(a)
    c.janssen_free = dataclasses.replace(a.janssen_free, mu_w_err=0.1)
    c.geom, c.numbers = {**a.geom, "mu_wall": a.janssen_free.mu_w - 0.05}, []
    add_numbers(c)
    assert not above_coulomb(c.janssen_free, c.geom["mu_wall"])
    assert _number(c, row).endswith(
        f"; above tan phi_P = {_fmt(c.geom['mu_wall'], 3)}, the most friction the walls can "
        "carry, if within its error: no measure of the walls' friction")
    exact = dataclasses.replace(b.janssen_free, mu_w_err=math.nan)
    assert not above_coulomb(exact, 0.2)
    bound = dataclasses.replace(b.janssen_free, mu_w=1e-6, mu_w_err=4e-7)
    assert bound.mu_w_at_bound and not above_coulomb(bound, 0.0)


MU_ROW = "mobilised wall friction sum(tau)/sum(sigma_n) on the cell-wall bins of the Janssen fit"


def test_a_negative_mobilised_wall_friction_is_flagged(synth):
    """tau_down is the grains' downward shear traction on the walls (docs/measurements.md's
    tau, turned downward): a negative sum(tau)/sum(sigma_n) is friction on the grains that
    points down, net, so the cell walls carry none of the fill's weight (the statics check of
    docs/validation.md met one, -0.34 of the weight, a column that sprang back).  Both rows
    say so, in words, after the number; the synthetic run's positive friction (0.663 of tan
    phi_P after filling) and a share of 0.8 get none of it.  The threshold is the sign."""
    from silodem.report.eurocode import mobilisation_row

    a, _ = synth
    for key, label in (("fill", "after filling"), ("discharge", "during discharge")):
        assert a.mu_mobilised[key] > 0.0
        value = _number(a, f"{MU_ROW}, {label}")
        assert value == significant(a.mu_mobilised[key], 3)  # ordinary: the number alone
    assert _number(a, "EN 1991-4 loads' wall friction") == "66 %"
    b = copy.copy(a)
    b.mu_mobilised = {"fill": -0.0312, "discharge": -0.004}
    b.en1991_4 = {**a.en1991_4, "mobilised": -0.0312 / MU_WALL}
    b.numbers = []
    add_numbers(b)
    walls = ("negative: the walls' friction on the grains points down, net over these bins, so "
             "the cell walls carry none of the fill's weight but add to the load below (the "
             "grains hold the walls up): the reverse of the wall support Janssen assumes")
    assert _number(b, f"{MU_ROW}, after filling") == f"-0.0312 ({walls})"
    assert _number(b, f"{MU_ROW}, during discharge") == f"-0.004 ({walls})"
    assert _number(b, "EN 1991-4 loads' wall friction") == (
        "-7 %: negative: net, the walls' friction on the grains points down, so the cell walls "
        "carry none of the fill's weight (the grains hold them up), the reverse of the wall "
        "support these loads assume; read them as the standard's, not as a model of this silo")
    assert mobilisation_row(0.8)[1] == "80 %"
    assert mobilisation_row(-0.12)[1].startswith("-12 %: negative: net, the walls' friction")
    assert "the settled silo" not in mobilisation_row(-0.12)[1]  # not the under-a-half text
    assert mobilisation_row(0.0)[1].startswith("0 %: the settled silo does not show")


def test_a_janssen_k_above_1_is_flagged_after_filling_and_noted_during_discharge(synth):
    """K = sigma_h / sigma_v = 1 is the isotropic (hydrostatic) bound: a fill at rest under its
    own weight is on the active side (Jaky: K0 = 1 - sin phi < 1), so a K above 1 by more
    than its error after filling is flagged in words, on the fit with mu_w = tan phi_P and on
    the free fit; during discharge, where flowing grains can go passive (Jenike's and
    Walters' switch), the row says what it is, not that it is wrong.  An ordinary K (the
    synthetic 0.55, and 0.5) and a K within its error of 1 get no note; a K that is also
    poorly determined reads both in one parenthesis, and a poorly determined K that reaches
    1 within its error only the first."""
    from silodem.report.flags import ABOVE_HYDROSTATIC, above_hydrostatic
    from silodem.report.key_numbers import _janssen_K

    a, _ = synth
    fill_row = "Janssen K fitted to the cell wall profile, after filling"
    free_row = "Janssen free fit after filling: K, mu_w"
    assert "above 1" not in _number(a, fill_row) and "above 1" not in _number(a, free_row)
    j = a.janssen["fill"]
    ordinary = dataclasses.replace(j, K=0.5, K_err=0.02)
    assert not above_hydrostatic(ordinary) and _janssen_K(ordinary, "fill") == "0.5 +- 0.02"
    b = copy.copy(a)
    b.janssen = {"fill": dataclasses.replace(j, K=1.3, K_err=0.05),
                 "discharge": dataclasses.replace(j, K=1.4, K_err=0.1)}
    b.janssen_free = dataclasses.replace(a.janssen_free, K=1.45, K_err=0.2)
    b.numbers = []
    add_numbers(b)
    fill_note = ("above 1 by more than its error: as fitted, the walls are pressed harder than "
                 "the fill's vertical stress, a passive-like state, not the K of a fill at rest "
                 "under its own weight (Jaky: K0 = 1 - sin phi < 1)")
    assert ABOVE_HYDROSTATIC["fill"] == fill_note
    # the fit with mu_w = tan phi_P says where the walls mobilise less (0.684 of it here);
    # the free fit, whose mu_w is fitted, does not
    mob = a.mu_mobilised["fill"]
    assert _number(b, fill_row) == (
        f"1.3 +- 0.05 ({fill_note}; with mu_w = {significant(MU_WALL, 3)} where the walls "
        f"mobilise {significant(mob, 3)}, the fit puts the missing friction into K)")
    assert _number(b, free_row).startswith(f"1.45 +- 0.2 ({fill_note}), ")
    assert _janssen_K(b.janssen["fill"], "fill", MU_WALL) == f"1.3 +- 0.05 ({fill_note})"
    assert _number(b, "Janssen K fitted to the cell wall profile, during discharge") == (
        "1.4 +- 0.1 (above 1 by more than its error: a passive-like state, the walls pressed "
        "harder than the vertical stress, as flowing grains can set up (the switch of Jenike "
        "and Walters))")
    # within its error of 1 (the validation column's 1.05): not judged
    assert _janssen_K(dataclasses.replace(j, K=1.05, K_err=0.1), "fill") == "1.05 +- 0.1"
    # poorly determined: the quick hopper's 1.29 +- 0.69 reaches 1 within its error
    poor = "poorly determined: the error is over half the value"
    assert _janssen_K(dataclasses.replace(j, K=1.286, K_err=0.69), "fill") == (
        f"1.29 +- 0.69 ({poor})")
    assert _janssen_K(dataclasses.replace(j, K=3.1, K_err=1.8), "fill") == (
        f"3.1 +- 1.8 ({poor}; {fill_note})")
    assert _janssen_K(dataclasses.replace(j, K=3.1, K_err=NAN), "fill") == (
        "3.1 +- n/a (not determined: the wall bins do not fix it (no finite error))")  # (and
    # not judged against 1)


def test_grains_lost_through_a_wall_are_counted_in_the_key_numbers(synth):
    """A run that lost grains through a wall (paper-case1 --quick: 65 of its 166) says so in
    the key numbers, out of n_poured; one that lost none (the synthetic run) has no such row."""
    from silodem.report.key_numbers import LOST

    a, _ = synth
    assert not any(label == LOST for label, _, _ in a.numbers)
    b = copy.copy(a)
    b.res = copy.copy(a.res)
    b.res.events = {**a.res.events, "lost_count": 65, "n_poured": 166}
    b.numbers = []
    add_numbers(b)
    assert _number(b, LOST) == "65 of the 166 poured (39 %)"
    rows = [label for label, _, _ in b.numbers]
    assert rows.index(LOST) < rows.index("switch zone")  # before the numbers it qualifies


def test_the_tenths_outside_their_chance_band_are_named_with_their_own_band():
    """The segregation row quoted the range of all ten chance bands and then said one tenth
    lay outside, though every value quoted lay inside that range: each tenth has its own
    band. A 50/50 mixture by number of r = 0.08 and 0.12 m, 400 grains, the small ones
    leaving first: the tenths outside their own band (found here by comparing each tenth's
    ratio with its band) are counted, and the first three named with theirs."""
    from silodem.measure.discharge import discharge_composition
    from silodem.report.key_numbers import _chance_words

    r = np.sort(np.repeat([0.08, 0.12], 200))
    c = discharge_composition(np.arange(400.0), r)
    # by hand: the fill's d_m = 2 (0.08^3 + 0.12^3) / (0.08^2 + 0.12^2) = 0.21538 m; the
    # small grains, 30.8 % of the mass, make the first three tenths: 0.16 / 0.21538 = 0.743
    assert c.diameter_ratio[0] == pytest.approx(0.16 / (2 * 0.00224 / 0.0208), rel=1e-12)
    assert "tenth 1 (0.743, its band " in _chance_words(c)
    out = [k for k in range(10)
           if not c.chance_lo[k] <= c.diameter_ratio[k] <= c.chance_hi[k]]
    assert len(out) >= 4  # (the case this test is about: more than three to name)
    words = _chance_words(c)
    assert f"{len(out)} of 10 tenths outside their own: tenth {out[0] + 1} (" in words
    k = out[0]
    assert (f"tenth {k + 1} ({significant(c.diameter_ratio[k], 3)}, its band "
            f"{significant(c.chance_lo[k], 3)} - {significant(c.chance_hi[k], 3)})") in words
    assert words.endswith(f" and {len(out) - 3} more")
    assert words.count("its band") == 3


def test_a_flat_silo_gets_no_junction_and_a_hopper_lined_otherwise_its_friction(synth):
    """The key numbers gave a flat silo 'junction z_j = 0' and an unqualified switch zone,
    read as a hopper's at the floor; and the hopper walls' own friction, which the hopper
    theory used, was never shown. The synthetic hopper run (walls tan 24 deg = 0.445) with a
    hopper lined at tan 10 deg = 0.176, and the same run called flat."""
    a, _ = synth
    lined = copy.copy(a)
    lined.geom = {**a.geom, "mu_hopper": math.tan(math.radians(10.0))}
    lined.numbers = []
    add_numbers(lined)
    assert _number(lined, "wall friction tan phi_P of the cell / of the hopper walls") == (
        "0.445 / 0.176")
    assert not [q for q, _, _ in a.numbers if q.startswith("wall friction tan phi_P of")]
    flat = copy.copy(a)
    silo = a.res.cfg.silo.model_copy(update={"kind": "flat"})
    flat.res = dataclasses.replace(a.res, cfg=a.res.cfg.model_copy(update={"silo": silo}))
    flat.numbers = []
    add_numbers(flat)
    g = a.geom
    assert _number(flat, "cell width B / outlet D (a flat bottom: no cell-hopper junction)") \
        == f"{g['B']:.3g} / {g['D']:.3g}"
    rows = [q for q, _, _ in flat.numbers]
    assert "switch zone (a flat silo has no junction: a band over the floor, set for " \
           "comparison with a hopper's)" in rows
    assert not [q for q in rows if q.startswith(("cell width B / outlet D / junction",
                                                 "hopper half-angle"))]
