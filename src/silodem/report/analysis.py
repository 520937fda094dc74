"""From results.h5 to the numbers and curves of the report: time windows, wall and edge
profiles, the Janssen fit, the hopper theory, the switch-zone peak, the evolution at the switch
zone, and the discharge (rate, flow pattern, dead zones).  Units SI, stresses compressive
positive [Pa].  The key numbers' rows, in words, are written by
:mod:`silodem.report.key_numbers` (``analyse`` calls it last)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from silodem import theory as th
from silodem.measure import discharge as dis
from silodem.measure import regions
from silodem.measure.fields import band_solid_area
from silodem.measure.wall_profiles import bottom_load, peak_in_zone
from silodem.report import eurocode
from silodem.report.load import Results
from silodem.report.numbers import percent_change, percent_change_error
from silodem.silo.geometry import silo_shape

if TYPE_CHECKING:
    from silodem.config import Config
    from silodem.silo.geometry import SiloShape

SETTLE, DISCHARGE = 1, 2


@dataclass
class EdgeProfile:
    """Time-averaged wall stresses along the left and right edges of the silo (vertical wall,
    and hopper wall in a hopper silo; a flat silo's floor is not part of it), and their mean
    over both sides (sorted by z)."""

    z: np.ndarray  # bin centres [m]
    sigma_n: np.ndarray  # wall normal stress, both sides averaged [Pa]
    tau_down: np.ndarray  # downward shear traction on the wall [Pa]
    on_vertical: np.ndarray  # bin on a vertical wall [bool]
    sides: dict[str, tuple[np.ndarray, np.ndarray]]  # side -> (z, sigma_n)


@dataclass
class Analysis:
    res: Results
    geom: dict[str, float]
    windows: dict[str, tuple[float, float]]
    surface: dict[str, float]
    rho_b: float
    edge: dict[str, EdgeProfile] = field(default_factory=dict)
    strips: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    janssen: dict[str, th.JanssenFit] = field(default_factory=dict)  # mu_w = tan(phi_P)
    janssen_free: th.JanssenFit | None = None  # K and mu_w fitted after filling
    janssen_missing: dict[str, str] = field(default_factory=dict)  # window -> why no fit
    mu_mobilised: dict[str, float] = field(default_factory=dict)
    hopper: dict[str, dict[str, Any]] = field(default_factory=dict)  # window -> Walker
    peaks: dict[str, tuple[float, float]] = field(default_factory=dict)
    switch: tuple[float, float] = (0.0, 0.0)
    change: dict[str, dict[str, float]] = field(default_factory=dict)
    change_missing: str = ""  # why there is no change fill -> discharge at all ("": there is)
    # (z of the filling peak [m], stress there after filling, during discharge [Pa], change %)
    wall_at_fill_peak: tuple[float, float, float, float] | None = None
    wall_at_fill_peak_err: float = float("nan")  # the error of its change [%]
    flow: dict[str, Any] = field(default_factory=dict)
    en1991_4: dict[str, Any] = field(default_factory=dict)  # the standard's wall loads
    # after filling: (force [N], mean pressure [Pa]) on the floor and the closed gate
    bottom: tuple[float, float] = (float("nan"), float("nan"))
    numbers: list[tuple[str, str, str]] = field(default_factory=list)  # key_numbers.add_numbers

    @property
    def labels(self) -> dict[str, str]:
        """What the windows' numbers and figures are called: "after filling", "during
        discharge"; the fill window of a run stopped before settling ended is no settled
        fill (UNSETTLED)."""
        unsettled = self.unfinished and not self.settled
        return {**WINDOW_LABELS, **({"fill": UNSETTLED} if unsettled else {})}

    @property
    def measured(self) -> bool:
        return self.res.group("measure") is not None

    @property
    def unfinished(self) -> bool:
        """The results.h5 of a run that had not ended when it was written (:func:`unfinished`)."""
        return unfinished(self.res)

    @property
    def settled(self) -> bool:
        """Settling had ended (:func:`settle_end_time`)."""
        return settle_end_time(self.res) is not None


WINDOW_LABELS = {"fill": "after filling", "discharge": "during discharge"}
UNSETTLED = "late in the unfinished settling"  # the fill window's name when settling had not
# ended (the run stopped first): the last measure.window of the settling reached


def unfinished(res: Results) -> bool:
    """Whether ``res`` is the results.h5 of a run that had not ended when it was written: its
    attribute ``status`` is there and is not "complete" ("running", "interrupted" or
    "unstable", silodem.output.write_results).  (A file without it, from an older silodem,
    is taken as it is.)"""
    status = res.attrs.get("status")
    return status is not None and str(status) != "complete"


def settle_end_time(res: Results) -> float | None:
    """The time [s] settling ended (the gate opened, in a run with discharge): the event
    ``discharge_start_time``, else the time of the /settled snapshot, else the events
    ``fill_time`` + ``settle_time`` (filling starts at 0); None when none of them is there (a
    run stopped before settling ended)."""
    ev = res.events
    if "discharge_start_time" in ev:
        return float(ev["discharge_start_time"])
    settled = res.snapshot("settled")
    if isinstance(settled, dict) and "time" in settled.get("@attrs", {}):
        return float(settled["@attrs"]["time"])
    if "fill_time" in ev and "settle_time" in ev:
        return float(ev["fill_time"]) + float(ev["settle_time"])
    return None


def _window_masks(res: Results) -> tuple[dict[str, np.ndarray], dict[str, tuple[float, float]]]:
    m = res.group("measure")
    cfg = res.cfg.measure
    t, phase = m["time"], m["phase"]
    settle_t = t[phase == SETTLE]
    t_open = settle_end_time(res)  # the end of settling; in a run stopped before it, the
    if t_open is None:             # last settling sample: the last window of settling reached
        t_open = float(settle_t.max() if settle_t.size else t.max())
    fill = (t >= t_open - cfg.window) & (t <= t_open) & (phase == SETTLE)
    d0 = t_open + cfg.discharge_delay
    dwin = (phase == DISCHARGE) & (t >= d0) & (t <= d0 + cfg.window)
    # a settling shorter than the window (settle.min_time is 0.2 s) or a discharge that ended
    # inside it cuts the window short, which was reported whole: the first (last) sample
    # then bounds it, when it is more than a sampling interval inside
    f0, d1 = t_open - cfg.window, d0 + cfg.window
    step = float(m.get("@attrs", {}).get("interval", cfg.interval))  # as the samples were taken
    settled_for = res.events.get("settle_time")  # [s]: a settling shorter than the window
    # by less than a sample interval loses no sample (its first sample can still lie a
    # fraction of a step more than an interval inside: 0.99976 s of settling read "cut short")
    start = f0 if settled_for is None else max(f0, t_open - float(settled_for))
    short = fill.any() and ((settled_for is not None and float(settled_for) < cfg.window - step)
                            or t[fill].min() > start + step)  # (or samples missing)
    if fill.any() and short:
        f0 = float(t[fill].min())
    if dwin.any() and t[dwin].max() < d1 - step:
        d1 = float(t[dwin].max())
    return ({"fill": fill, "discharge": dwin}, {"fill": (f0, t_open), "discharge": (d0, d1)})


def column_tops(snap: dict[str, Any] | None, width: float, d: float) -> np.ndarray:
    """Top of the highest grain [m] in each of round(B/d) equal columns across the silo (each
    about d wide) that holds a grain, left to right; empty when there is no grain."""
    if snap is None or snap["particles"]["x"].size == 0:
        return np.empty(0)
    p = snap["particles"]
    x, top = p["x"], p["y"] + p["radius"]
    # round, not int: B/d = 12 can divide to 11.999999999999998 (a last column 2d wide)
    n_cols = max(1, round(width / d))
    cols = np.clip((x * (n_cols / width)).astype(int), 0, n_cols - 1)
    return np.array([top[cols == c].max() for c in np.unique(cols)])


def surface_height(snap: dict[str, Any] | None, width: float, d: float) -> float:
    """Mean height of the free surface [m] (EN 1991-4's equivalent surface): the mean of the
    :func:`column_tops`."""
    tops = column_tops(snap, width, d)
    return float(np.mean(tops)) if tops.size else float("nan")


def density_band(junction: float, surface: float, d: float) -> tuple[float, float]:
    """Heights [m] of the band the bulk density is measured in: the cell from one diameter
    ``d`` above the junction to one under the surface, or the whole fill (0 to the surface)
    when that band would be under 2 d."""
    lo, hi = junction + d, surface - d
    return (lo, hi) if hi - lo >= 2 * d else (0.0, surface)


def bulk_density(snap: dict[str, Any] | None, cfg: Config, shape: SiloShape,
                 surface: float) -> float:
    """Mass per volume of the grains in the cell [kg/m^3], between the junction (+1 diameter)
    and the surface (-1 diameter); in the whole silo if that band is too thin.  Each grain
    counts with the exact area of its disk inside the band (``measure.fields``'s rule for the
    density field: counting whole grains by their centres biased it by a few per cent)."""
    if snap is None:
        return float("nan")
    p = snap["particles"]
    d = regions.mean_diameter(cfg)
    lo, hi = density_band(shape.junction, surface, d)
    solid = band_solid_area(p["y"], p["radius"], lo, hi)
    area = shape.area_below(hi) - shape.area_below(lo)
    return cfg.material.density * solid / area if area > 0 else float("nan")


def _edge(res: Results, mask: np.ndarray) -> EdgeProfile | None:
    m = res.group("measure", "wall_bins")
    if m is None or not mask.any():
        return None
    names = list(res.group("walls")["name"])
    tang = m["tangent"]
    normal = m["normal"][mask].mean(axis=0)
    shear = m["shear"][mask].mean(axis=0)
    sides: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}
    for side in ("left", "right"):
        ws = [names.index(n) for n in (f"{side}_wall", f"{side}_hopper") if n in names]
        sel = np.isin(m["wall"], ws)
        z = m["z"][sel]
        ty = tang[m["wall"][sel], 1]
        down = -shear[sel] * np.sign(np.where(ty == 0, 1.0, ty))
        vertical = np.abs(ty) > 0.999
        order = np.argsort(z)
        sides[side] = (z[order], normal[sel][order], down[order], vertical[order])
    (zl, nl, dl, vl), (zr, nr, dr, _) = sides["left"], sides["right"]
    if zl.size == zr.size and np.allclose(zl, zr, atol=1e-6):
        z, sn, td = zl, 0.5 * (nl + nr), 0.5 * (dl + dr)
    else:
        z, sn, td = zl, nl, dl
    return EdgeProfile(z, sn, td, vl, {s: (v[0], v[1]) for s, v in sides.items()})


def _bottom(res: Results, mask: np.ndarray) -> tuple[float, float]:
    """(force [N], mean pressure [Pa]) on the silo's bottom over the window ``mask``
    (``wall_profiles.bottom_load``)."""
    m = res.group("measure", "wall_bins")
    if m is None or not mask.any() or "s0" not in m or "s1" not in m:
        return float("nan"), float("nan")
    return bottom_load(m["normal"][mask].mean(axis=0), m["s0"], m["s1"], m["wall"],
                       list(res.group("walls")["name"]), res.cfg.material.thickness)


def _strips(res: Results, mask: np.ndarray) -> dict[str, np.ndarray] | None:
    p = res.group("measure", "profiles")
    if p is None or not mask.any():
        return None
    ze = p["z_edges"]
    near = 0.5 * (np.nanmean(p["left"][mask], axis=0) + np.nanmean(p["right"][mask], axis=0))
    slices = np.nanmean(p["slices"][mask], axis=0)
    return {"z": 0.5 * (ze[:-1] + ze[1:]), "near_xx": near[:, 0], "near_zz": near[:, 1],
            "slice_xx": slices[:, 0], "slice_zz": slices[:, 1]}


def analyse(res: Results) -> Analysis:
    """Every derived number and curve of the report."""
    cfg = res.cfg
    shape = silo_shape(cfg)
    d = regions.mean_diameter(cfg)
    alpha = th.alpha_from_theta(cfg.silo.hopper_angle_from_horizontal_deg)
    apex = th.apex_below_outlet(cfg.silo.outlet_width, alpha) if shape.kind == "hopper" else 0.0
    geom = {"B": shape.width, "z_j": shape.junction, "D": cfg.silo.outlet_width,
            "top": shape.wall_top, "alpha": alpha, "apex": apex, "d": d,
            "t": cfg.material.thickness, "g": cfg.gravity,
            "mu_wall": math.tan(math.radians(cfg.walls.friction_deg)),
            "mu_hopper": cfg.walls.hopper_mu()}
    settled, dsnap = res.snapshot("settled"), res.snapshot("discharge")
    surface = {"fill": surface_height(settled, shape.width, d),
               "discharge": surface_height(dsnap, shape.width, d)}
    rho_b = bulk_density(settled, cfg, shape, surface["fill"])
    a = Analysis(res, geom, {}, surface, rho_b)
    a.switch = regions.switch_zone(cfg, shape)
    if not a.measured:
        return a
    masks, a.windows = _window_masks(res)
    for key, mask in masks.items():
        edge = _edge(res, mask)
        if edge is not None:
            a.edge[key] = edge
            a.peaks[key] = peak_in_zone(edge.z, edge.sigma_n, *a.switch)
        strips = _strips(res, mask)
        if strips is not None:
            a.strips[key] = strips
    if "fill" in masks:
        a.bottom = _bottom(res, masks["fill"])
    _fit_theory(a, shape)
    eurocode.add_loads(a, eurocode.highest_wall_contact(settled, shape.width, d))
    _evolution_change(a, masks)
    _flow(a, shape)
    # (imported here, not at the top: key_numbers imports this module's Analysis and helpers)
    from silodem.report.key_numbers import add_numbers

    add_numbers(a)
    return a


def no_settled_fill(a: Analysis) -> str:
    """Why the free surface and the bulk density (of the /settled snapshot) are not numbers;
    "" when they are."""
    settled = a.res.snapshot("settled")
    if settled is None:
        if a.unfinished and not a.settled:
            return (f"no settled snapshot: the run stopped {stopped_at(a.res)}, before "
                    "settling ended")
        return "results.h5 holds no /settled snapshot"
    if np.size(settled.get("particles", {}).get("x", ())) == 0:
        return "no grain in the settled snapshot"
    if not np.isfinite(a.surface["fill"]):
        return "no free surface in the settled snapshot"
    if not np.isfinite(a.rho_b):
        return "no area between the junction and the free surface to measure it in"
    return ""


def stopped_at(res: Results) -> str:
    """Where an unfinished run had come when its results.h5 was written: "in settle at
    t = 23.34 s" (its attributes ``phase`` and ``time``)."""
    phase, t = res.attrs.get("phase", "?"), res.attrs.get("time")
    when = f" at t = {float(t):.4g} s" if isinstance(t, int | float) else ""
    return f"in {phase}{when}"


def _fit_theory(a: Analysis, shape) -> None:
    """Janssen K per window (mu_w = tan(phi_P), the paper's assumption of fully mobilised wall
    friction), a free (K, mu_w) fit after filling, the mobilised wall friction, and, per window,
    the hopper slice solutions with that window's q and D (``_walker``)."""
    g = a.geom
    for key, e in a.edge.items():
        surface = a.surface[key]
        if not np.isfinite(surface) or not np.isfinite(a.rho_b):
            why = no_settled_fill(a)
            a.janssen_missing[key] = ("no free surface or bulk density measured"
                                      + (f"; {why}" if why else ""))
            continue
        depth = surface - e.z
        cell = e.on_vertical & (e.z > a.switch[1]) & (depth > 0.5 * g["d"])
        sn = e.sigma_n[cell]
        if cell.sum() < 2 or np.sum(sn) <= 0:
            a.janssen_missing[key] = (
                f"{int(cell.sum())} wall bin(s) on the cell walls between the switch zone's "
                f"top, z = {a.switch[1]:.3g} m, and the surface, z = {surface:.3g} m, less "
                "half a diameter; the fit needs 2" if cell.sum() < 2
                else "no normal stress on the cell walls above the switch zone")
            continue
        a.mu_mobilised[key] = float(np.sum(e.tau_down[cell]) / np.sum(sn))
        try:
            a.janssen[key] = th.fit_janssen(depth[cell], sn, a.rho_b, g["g"], g["B"],
                                            mu_w=g["mu_wall"])
            if key == "fill":
                a.janssen_free = th.fit_janssen(depth[cell], sn, a.rho_b, g["g"], g["B"])
        except (ValueError, RuntimeError) as exc:
            a.janssen_missing[key] = f"the fit failed: {exc}"
    if shape.kind == "hopper":
        for key in a.strips:
            hop = _walker(a, key)
            if hop:
                a.hopper[key] = hop


# the range Walker's distribution factor D is fitted in [-]; a D at either end is no fit (the
# wall bins lie below or above every curve of the range: a hopper carrying nearly nothing)
WALKER_D_BOUNDS = (0.2, 5.0)


def _walker(a: Analysis, key: str) -> dict[str, Any]:
    """Walker's slice solutions in the hopper for one window: q = the window's measured mean
    vertical stress just above the junction, D = 1 and D fitted (bounded, least squares) to
    the window's hopper-wall bins.  Empty when the window has no finite q."""
    g, strips = a.geom, a.strips[key]
    above = np.flatnonzero(strips["z"] > g["z_j"])
    if above.size == 0 or not np.isfinite(strips["slice_zz"][above[0]]) or \
            not np.isfinite(a.rho_b):
        return {}
    gamma = a.rho_b * g["g"]
    q = float(strips["slice_zz"][above[0]])
    H = g["z_j"] + g["apex"]
    z = np.linspace(0.0, g["z_j"], 60)
    h = z + g["apex"]
    mu_h = g["mu_hopper"]
    hop = {"z": z, "q": q, "H": H, "mu": mu_h,
           "planar": th.hopper_sigma_v(h, H, q, gamma, g["alpha"], mu_h, 1.0, True),
           "conical": th.hopper_sigma_v(h, H, q, gamma, g["alpha"], mu_h, 1.0, False)}
    e = a.edge.get(key)
    on_hopper = (~e.on_vertical & (e.z < g["z_j"]) & np.isfinite(e.sigma_n)) if e else None
    if on_hopper is not None and on_hopper.sum() >= 2:
        from scipy.optimize import minimize_scalar

        zh, sh = e.z[on_hopper], e.sigma_n[on_hopper]

        def err(D):
            pred = th.hopper_wall_normal(zh + g["apex"], H, q, gamma, g["alpha"], mu_h, D, True)
            return float(np.sum((pred - sh) ** 2))

        D = float(minimize_scalar(err, bounds=WALKER_D_BOUNDS, method="bounded").x)
        hop["D_fit"], hop["D_bins"] = D, int(on_hopper.sum())
        hop["D_at_bound"] = min(abs(D - b) for b in WALKER_D_BOUNDS) <= 1e-3 * D
        hop["planar_D"] = th.hopper_wall_normal(h, H, q, gamma, g["alpha"], mu_h, D, True)
    return hop


BATCHES = 5  # blocks of a window for the batch-means error (as dis.steady_rate's 5 blocks)


def batch_mean_error(values: npt.ArrayLike, blocks: int = BATCHES) -> float:
    """Standard error of the mean of a window's time samples [their unit], by batch means: the
    finite samples, in time order, cut into ``blocks`` consecutive blocks of (nearly) equal
    count (``np.array_split``), and the standard deviation (ddof = 1) of the block means over
    sqrt(blocks).  Successive samples are correlated (a stress swings over tenths of a second,
    sampled every 0.02 s), so the scatter of single samples over sqrt(n) would understate the
    error; means of blocks longer than that correlation are nearly independent (Flyvbjerg &
    Petersen 1989, J. Chem. Phys. 91, 461).  The steady discharge rate's error
    (``measure.discharge.steady_rate``) is the same estimate for a slope.  NaN with fewer
    finite samples than ``blocks``."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size < max(blocks, 2):
        return float("nan")
    means = np.array([b.mean() for b in np.array_split(v, blocks)])
    return float(np.std(means, ddof=1) / math.sqrt(blocks))


def window_mean(values: np.ndarray) -> float:
    """Mean of the finite values (``np.nanmean``); NaN, without numpy's warning, when there
    are none (a circle that held no contact in the whole window).  The report and a study's
    table (``study.table``) both take their window means here, so they agree to the bit."""
    if not np.isfinite(values).any():
        return float("nan")
    return float(np.nanmean(values))


def _evolution_change(a: Analysis, masks: dict[str, np.ndarray]) -> None:
    c = a.res.group("measure", "circles")
    if c is None:
        return
    stress = c["stress"]
    if not a.res.cfg.discharge.enabled:
        a.change_missing = "the run has no discharge: discharge.enabled = false"
    else:
        empty = [key for key in ("fill", "discharge") if not masks[key].any()]
        if empty:
            a.change_missing = f"no measurement sample in the {' and '.join(empty)} window"
            if a.unfinished:  # not a run too short for it: one that had not got there
                a.change_missing += f": the run stopped {stopped_at(a.res)}"
    for k, name in enumerate(c["name"]):
        row = {}
        for comp, label in ((0, "sigma_h"), (1, "sigma_v")):
            fill, dis_ = stress[masks["fill"], k, comp], stress[masks["discharge"], k, comp]
            _add_change(row, label, (window_mean(fill), batch_mean_error(fill)),
                        (window_mean(dis_), batch_mean_error(dis_)))
        a.change[str(name)] = row
    if "fill" in a.peaks and "discharge" in a.peaks:
        # the switch zone's largest wall normal stress in each window, wherever it lies (the
        # two may be on different walls), and the discharge window's stress at the height of
        # the filling peak: the same place; each with the batch-means error of its bin's
        # samples (the error of that bin's mean, not of which bin is the largest)
        (f, z_f), (dd, z_d) = a.peaks["fill"], a.peaks["discharge"]
        row = {}
        f_err = batch_mean_error(edge_samples(a.res, masks["fill"], z_f))
        _add_change(row, "sigma_h", (f, f_err),
                    (dd, batch_mean_error(edge_samples(a.res, masks["discharge"], z_d))))
        a.change["wall peak"] = {**row, "z_fill": z_f, "z_discharge": z_d}
        same = wall_stress_at(a.edge["discharge"], z_f)
        a.wall_at_fill_peak = (z_f, f, same, percent_change(f, same))
        a.wall_at_fill_peak_err = percent_change_error(
            f, f_err, same, batch_mean_error(edge_samples(a.res, masks["discharge"], z_f)))


def _add_change(row: dict[str, float], label: str, fill: tuple[float, float],
                discharge: tuple[float, float]) -> None:
    """Into ``row``: the window means ``label``_fill, ``label``_discharge [Pa] and their
    batch-means errors (``_err``), the change ``label``_change_pct [%] and its error
    ``label``_change_pct_err [%] (:func:`~silodem.report.numbers.percent_change_error`)."""
    (f, f_err), (d, d_err) = fill, discharge
    row[label + "_fill"], row[label + "_discharge"] = f, d
    row[label + "_fill_err"], row[label + "_discharge_err"] = f_err, d_err
    row[label + "_change_pct"] = percent_change(f, d)
    row[label + "_change_pct_err"] = percent_change_error(f, f_err, d, d_err)


def edge_samples(res: Results, mask: np.ndarray, z: float) -> np.ndarray:
    """The wall normal stress [Pa] of the edge bin at height ``z`` in each sample of ``mask``,
    as :func:`_edge` makes its profile: the mean of the left and right walls' bins when the two
    sides have bins at the same heights, else the left wall's; empty when no bin lies there."""
    m = res.group("measure", "wall_bins")
    if m is None or not mask.any():
        return np.zeros(0)
    names = list(res.group("walls")["name"])
    bins = {}  # side -> its bins' indices, sorted by z
    for side in ("left", "right"):
        ws = [names.index(n) for n in (f"{side}_wall", f"{side}_hopper") if n in names]
        k = np.flatnonzero(np.isin(m["wall"], ws))
        bins[side] = k[np.argsort(m["z"][k])]
    zl, zr = m["z"][bins["left"]], m["z"][bins["right"]]
    both = zl.size == zr.size and np.allclose(zl, zr, atol=1e-6)
    at = np.flatnonzero(np.isclose(zl, z, rtol=0.0, atol=1e-9))
    if not at.size:
        return np.zeros(0)
    normal = m["normal"][mask]
    left = normal[:, bins["left"][at[0]]]
    return 0.5 * (left + normal[:, bins["right"][at[0]]]) if both else left


def above_coulomb(fit: th.JanssenFit, mu_wall: float) -> bool:
    """A free Janssen fit whose mu_w lies above tan(phi_P) by more than its standard error:
    no wall contact can transmit a shear over mu_wall times its normal force (Coulomb), so
    the fit describes the curve's shape, not the walls' friction.  (A margin of 1e-6 mu_wall
    keeps an exact fit to a profile at the limit, its error ~1e-15, unflagged.)  A fit with no
    error (two bins: exact) or at its lower bound (no wall support) is not judged."""
    if not math.isfinite(fit.mu_w_err) or fit.mu_w_at_bound:
        return False
    return fit.mu_w - fit.mu_w_err > mu_wall * (1.0 + 1e-6)


def wall_stress_at(edge: EdgeProfile, z: float) -> float:
    """The wall normal stress [Pa] of ``edge``'s bin at height ``z`` (the bins are the same
    in every window); NaN if no bin lies there."""
    k = np.flatnonzero(np.isclose(edge.z, z, rtol=0.0, atol=1e-9))
    return float(edge.sigma_n[k[0]]) if k.size else float("nan")


DEAD_TO = "the discharge window's end"  # the dead zone's horizon, in words
# the flow pattern when no grain had left by the discharge window's end (a slow gate)
NO_FLOW = "none read: no grain had left by the discharge window's end"


def _dead_zone(f: dict, radius: float, descent: float = np.inf) -> tuple[np.ndarray, str]:
    """The dead zone (``measure.discharge.dead_zone``) up to the end of the discharge window
    (``_horizon``), ``descent`` [m] the column's mean descent by then (:func:`mean_descent`),
    and that horizon in words.  A results.h5 written before the window's record has only the
    whole discharge's displacements, and its dead zone is read over the whole discharge, as
    it was then."""
    if "max_displacement_window" not in f:
        return dis.dead_zone(f["exit_time"], f["max_displacement"], radius), "the run's end"
    return (dis.dead_zone(f["exit_time"], f["max_displacement_window"], radius, _horizon(f),
                          descent), DEAD_TO)


def _horizon(f: dict) -> float:
    """The end of the discharge window [s after the gate opened] (NaN in a file without)."""
    at = f["@attrs"]
    return float(at.get("window_start", np.nan)) + float(at.get("window", np.nan))


def mean_descent(t: np.ndarray, mass: np.ndarray, horizon: float, a: Analysis) -> float:
    """The column's mean descent [m] by ``horizon`` [s after the opening]: the mass through
    the outlet by then (``t``, ``mass``: the discharge's time series) over rho_b B t, the
    mass of a layer of the cell 1 m deep; inf where it cannot be told (no bulk density)."""
    per_metre = a.rho_b * a.geom["B"] * a.geom["t"]
    if t.size == 0 or not (np.isfinite(per_metre) and per_metre > 0):
        return np.inf
    descent = float(np.interp(horizon, t, mass)) / per_metre
    return descent if np.isfinite(descent) else np.inf  # (no window: the radius decides)


def _flow(a: Analysis, shape) -> None:
    res, cfg = a.res, a.res.cfg
    ts = res.group("timeseries")
    if ts is None or "discharge_start_time" not in res.events:
        return
    t0 = float(res.events["discharge_start_time"])
    sel = ts["phase"] == DISCHARGE
    t, mass = ts["time"][sel] - t0, ts["discharged_mass"][sel]
    rate = dis.steady_rate(t, mass)
    a.flow.update(t=t, mass=mass, rate=rate, series=dis.flow_rate_series(t, mass))
    mass0 = float(res.events.get("initial_mass", np.nan))
    window = a.windows.get("discharge")
    reached = float(res.attrs.get("time", np.inf)) if a.unfinished else np.inf
    if window and t.size and mass0 > 0 and reached >= window[0]:  # how far the silo had
        # emptied (not said of a window that an unfinished run never reached)
        a.flow["window_emptied"] = tuple(float(np.interp(w - t0, t, mass)) / mass0
                                         for w in a.windows["discharge"])
    f = res.group("measure", "flow")
    if f is None or f["uid"].size == 0:
        return
    band_lo, band_hi = float(f["@attrs"]["mfi_band_lo"]), float(f["@attrs"]["mfi_band_hi"])
    mi = f["mass_flow_index"]
    descent = mean_descent(t, mass, _horizon(f), a)
    dead, dead_to = _dead_zone(f, 0.5 * a.geom["d"], descent)
    before, during = dis.lost_grains(f)
    dead_frac = dis.dead_fraction(dead, before | during)
    flowed = descent > 0  # (nothing left by the window's end: every grain "at rest", none dead)
    if np.isfinite(rate.rate) and flowed:
        mfi = dis.mass_flow_index(mi["v_wall"], mi["v_axis"], mi["level"], band_hi,
                                  band_hi - band_lo)
        pattern = dis.classify_flow(mfi, dead_frac, cfg.measure.mass_flow_index_threshold)
    else:  # no steady flow to classify: the velocities of grains at rest are noise
        mfi = float("nan")
        pattern = ("clogged" if res.events.get("discharge_end_reason") == "clog" else
                   "unknown" if flowed else NO_FLOW)
    if not flowed:
        dead_frac = float("nan")
    a.flow.update(mfi=mfi, dead=dead, dead_to=dead_to, dead_fraction=dead_frac, pattern=pattern,
                  mfi_band=(band_lo, band_hi))
    composition = dis.flow_composition(f)
    if composition is not None:
        a.flow["composition"] = composition
    if np.isfinite(rate.rate) and np.isfinite(a.rho_b):
        a.flow["beverloo_C"] = th.beverloo_2d_C(rate.rate, cfg.silo.outlet_width, a.geom["d"],
                                                a.rho_b, cfg.gravity, 1.5, a.geom["t"])
