"""Beverloo: the steady discharge rate of a flat-bottomed 2D silo against the 2D Beverloo law.

    W = C rho_b sqrt(g) (D - k d)^(3/2) t            (Beverloo, Leniger & van de Velde 1961;
                                                        in 2D the exponent is 3/2: Mankoc et al.
                                                        2007, Janda et al. 2012)

Set-up: ``SiloRun`` on one flat-bottomed silo for every outlet, as in Beverloo's own bin with
exchangeable orifices: grains of mean diameter d = 1 cm (radii uniform in [0.4 d, 0.6 d],
thickness d), grain and wall friction tan(26.57 deg) = 0.5, restitution 0.5, k_n = k_s = 8e4 N/m
(overlaps below 1 % of the radius); outlet widths D/d = 6, 9, 13.5, 20, 30; cell width
B = 1.02 max(2.5 D, D + 30 d) for the widest outlet, 76.5 d (walls far enough from every outlet
not to matter); filled by pouring to a height H = B (>= 2.5 D, Beverloo's condition); the gate
is then withdrawn and every grain that leaves is put back at a random free place in a band of
20 d above the surface (``discharge.reinsert``), so that the fill height, hence the rate, stays
steady.  The run stops after one silo-full of grains or at a time limit chosen to let about
1500 grains pass at the smallest outlet (:func:`max_time`).

Why one silo: the rate of this model grows with the pressure above the outlet (about as
P^0.3; docs/validation.md, section 5).  A silo scaled with each outlet (B ~ D + 30 d, H = B)
has a bottom pressure that doubles from D = 6 d to 30 d, which inflated the fitted exponent
to 1.61 +- 0.04; with one silo and one fill height every outlet sees the same pressure.

Measured: the steady rate W = slope of the discharged mass m(t) from 20 % to 95 % of the mass
that left (the start-up and the last, partly counted samples left out), with its batch-means
standard error (``measure.discharge.steady_rate``), averaged over two fills (seeds 1, 2); the
bulk density rho_b of the settled fill (each disk by its area in the band,
``measure.fields.band_solid_area``).

Checks: the exponent b of W = A (D - k d)^b fitted with A, k and b free is 1.5 +- 0.1; the rate
at D = 9 d changes by no more than 5 % when the fill height is doubled (H = B -> 2 B).
Reported: C and k of the law with the exponent fixed at 3/2 (W^(2/3) is linear in D), and k of
the free fit.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from silodem.config import Config
from silodem.measure.discharge import RateEstimate, mean_of_runs, steady_rate
from silodem.measure.fields import band_solid_area
from silodem.silo.procedure import SiloRun
from silodem.theory import BeverlooFit, fit_beverloo_free, fit_beverloo_three_halves
from silodem.validate.records import Record, absolute, info, rel

CASE = "Beverloo"
D_GRAIN = 0.01  # mean grain diameter d [m]
WIDTHS = (6.0, 9.0, 13.5, 20.0, 30.0)  # D/d
FILL = 1.0  # fill height H / B, the same silo and height for every outlet (H >= 2.5 D)
HEIGHT_CHECK = (9.0, 2.0)  # D/d of the fill-height check, and the factor on H
BAND = 20.0  # re-insertion band above the surface / d
SEEDS = (1, 2)  # independent fills per outlet width; their rates are averaged
EXPONENT_TOL = 0.1
HEIGHT_TOL = 0.05
HEIGHT_NOTE = ("with this contact law the rate grows with H (+7 to +10 % for 2 x H), in LAMMPS "
               "too, with 100 x stiffer grains and under the Hertz-Mindlin law: "
               "docs/validation.md, section 5")
G = 9.81


@dataclass(frozen=True)
class Discharge:
    D: float  # outlet width [m]
    B: float  # cell width [m]
    H: float  # fill height [m]
    n: int  # grains
    rate: float  # steady rate [kg/s]
    err: float  # standard error [kg/s]
    rho_b: float  # bulk density of the settled fill [kg/m^3]
    passed: int  # grains that left during the run
    end: str  # why the discharge stopped
    t: np.ndarray  # time after the gate opened [s]
    m: np.ndarray  # discharged mass [kg]


def grains_for(B: float, H: float) -> int:
    """Grains that fill a width B to a height H [m] at a solid fraction of 0.82 (radii uniform
    in [0.4 d, 0.6 d]: mean area pi d^2 (1 + 0.2^2/3) / 4)."""
    area = math.pi * D_GRAIN**2 * (1.0 + 0.2**2 / 3.0) / 4.0
    return round(0.82 * B * H / area)


def cell_width(D_over_d: float = max(WIDTHS)) -> float:
    """B = 1.02 max(2.5 D, D + 30 d) [m] for an outlet D (default: the widest, the one silo
    used for every outlet)."""
    return 1.02 * max(2.5 * D_over_d, D_over_d + 30.0) * D_GRAIN


def config(D_over_d: float, H_over_B: float, max_time: float, seed: int = 1) -> Config:
    d = D_GRAIN
    D = D_over_d * d
    B = cell_width()
    H = H_over_B * B
    grain = {"density": 2500.0, "radius_min": 0.4 * d, "radius_max": 0.6 * d, "thickness": d,
             "kn": 8e4, "ks": 8e4, "friction_deg": 26.57, "restitution": 0.5}
    return Config.model_validate({
        "name": f"validate-beverloo-D{D_over_d:g}-H{H_over_B:g}B", "seed": seed,
        "description": "validation: Beverloo discharge with re-insertion (silodem validate)",
        "material": grain,
        "walls": {"kn": 8e4, "ks": 8e4, "friction_deg": 26.57},
        "silo": {"kind": "flat", "cell_width": B, "wall_height": H + (BAND + 2.0) * d,
                 "outlet_width": D},
        "fill": {"method": "pour", "n_particles": grains_for(B, H), "rate": 20000.0,
                 "band_height": BAND * d},
        "settle": {"criterion": "kinetic_energy", "threshold": 1e-9, "max_time": 1.0,
                   "min_time": 0.3},
        "discharge": {"enabled": True, "reinsert": True, "stop_fraction": 1.0,
                      "max_time": max_time, "clog_time": 1.0},
        "output": {"png": False, "sample_interval": 0.01},
        "checkpoint": {"enabled": False},
    })


def max_time(D_over_d: float) -> float:
    """Enough time for about 1500 grains at the smallest outlets (W ~ D^1.5) [s]."""
    return float(np.clip(6.0 * (6.0 / D_over_d) ** 1.5, 1.5, 6.0))


def discharge_curve(run: SiloRun) -> tuple[np.ndarray, np.ndarray]:
    """Time since the gate opened [s] and discharged mass [kg], over the discharge phase."""
    ts = run.series.as_arrays()
    sel = ts["phase"] == 2
    t0 = float(run.events["discharge_start_time"])
    return ts["time"][sel] - t0, ts["discharged_mass"][sel]


def rate_of(t: np.ndarray, m: np.ndarray) -> RateEstimate:
    """The steady rate of a discharge curve: the slope from 20 % to 95 % of the mass that left
    (``measure.discharge.steady_rate``; ``.rate``, ``.err`` in kg/s)."""
    return steady_rate(t, m, lo=0.2, hi=0.95)


def variant_rate(cfg: Config) -> dict:
    """Run a variant of the case's config (the experiments of docs/validation.md, section 5:
    ``docs/validation/stiffness.py``, ``hertz_height.py``) and return what they print: the
    time step ``dt`` [s], the steady rate ``W`` and its error ``err`` [kg/s], the grains that
    ``passed`` and the run's ``wall_s`` [s]."""
    start = time.perf_counter()
    run = SiloRun(cfg)
    run.run()
    rate = rate_of(*discharge_curve(run))
    return {"dt": run.sim.dt, "W": rate.rate, "err": rate.err,
            "passed": int(run.state.discharged_count),
            "wall_s": round(time.perf_counter() - start, 1)}


def discharge(D_over_d: float, H_over_B: float = FILL, seed: int = 1) -> Discharge:
    cfg = config(D_over_d, H_over_B, max_time(D_over_d), seed)
    run = SiloRun(cfg)
    run.run()
    t, m = discharge_curve(run)
    r = rate_of(t, m)
    snap = run.snapshots["settled"].particles
    d = D_GRAIN
    level = float(run.events["fill_level"])
    lo, hi = 2.0 * d, level - 2.0 * d
    solid = band_solid_area(snap["y"], snap["radius"], lo, hi)
    rho_b = cfg.material.density * solid / ((hi - lo) * cfg.silo.cell_width)
    return Discharge(cfg.silo.outlet_width, cfg.silo.cell_width, level, cfg.fill.n_particles,
                     r.rate, r.err, rho_b, run.state.discharged_count,
                     str(run.events.get("discharge_end_reason", "")), t, m)


@dataclass(frozen=True)
class Rate:
    """The mean steady rate of independent fills at one outlet width and fill height."""

    D: float  # [m]
    B: float  # [m]
    H: float  # mean fill level [m]
    rate: float  # [kg/s]
    err: float  # standard error: batch-means errors combined, or the seeds' spread if larger
    runs: list[Discharge]


def mean_rate(D_over_d: float, H_over_B: float = FILL) -> Rate:
    runs = [discharge(D_over_d, H_over_B, seed) for seed in SEEDS]
    rate, err = mean_of_runs([r.rate for r in runs], [r.err for r in runs])
    return Rate(runs[0].D, runs[0].B, float(np.mean([r.H for r in runs])), rate, err, runs)


def run(quick: bool = False) -> tuple[list[Record], dict]:
    rates = [mean_rate(w) for w in WIDTHS]
    D_h, factor = HEIGHT_CHECK
    base = next((r for r, w in zip(rates, WIDTHS) if w == D_h), None) or mean_rate(D_h)
    tall = mean_rate(D_h, factor * FILL)
    d, t = D_GRAIN, D_GRAIN
    rho_b = float(np.mean([run.rho_b for r in rates for run in r.runs]))
    D = np.array([r.D for r in rates])
    W = np.array([r.rate for r in rates])
    W_err = np.array([r.err for r in rates])
    free = fit_beverloo_free(D, W, W_err, d, rho_b, G, t)
    try:
        fixed, fixed_note = fit_beverloo_three_halves(D, W, d, rho_b, G, t), ""
    except ValueError as exc:  # rates that do not grow with D (the exponent check fails too)
        fixed, fixed_note = BeverlooFit(float("nan"), float("nan"), 1.5, float("nan")), str(exc)
    records: list[Record] = []
    for r in rates:
        each = ", ".join(f"{run.rate:.4g}" for run in r.runs)
        passed = sum(run.passed for run in r.runs)
        ends = ",".join(sorted({run.end for run in r.runs}))
        records.append(info(f"{CASE}, D/d = {r.D / d:g}, B/d = {r.B / d:.3g}, "
                            f"{r.runs[0].n} grains, re-insertion, {len(r.runs)} fills",
                            "steady discharge rate W", r.rate, "kg/s",
                            note=f"+- {r.err:.2g} kg/s; fills: {each}; {passed} grains passed; "
                            f"stopped by {ends}"))
    label = f"{CASE}, {len(rates)} outlet widths D/d = {WIDTHS[0]:g}..{WIDTHS[-1]:g}"
    records += [
        absolute(label, "exponent b of W = A (D - k d)^b (A, k, b fitted)", 1.5, free.b,
                 EXPONENT_TOL, note=f"2D Beverloo: 3/2; fit +- {free.b_err:.2g}"),
        info(label, "free fit: k", free.k),
        info(label, "C of W = C rho_b sqrt(g) (D - k d)^1.5 t", fixed.C, note=fixed_note),
        info(label, "k of W = C rho_b sqrt(g) (D - k d)^1.5 t", fixed.k, note=fixed_note),
        info(label, "bulk density rho_b of the settled fills", rho_b, "kg/m^3"),
        rel(f"{CASE}, D/d = {D_h:g}, fill height {base.H / d:.0f} d -> {tall.H / d:.0f} d",
            f"steady rate at {factor:.3g} x the fill height", base.rate, tall.rate, HEIGHT_TOL,
            "kg/s", note=f"Beverloo: independent of the fill height; +- {base.err:.2g} and "
            f"{tall.err:.2g} kg/s; {HEIGHT_NOTE}"),
    ]
    data = {"rates": rates, "base": base, "tall": tall, "free": free, "fixed": fixed,
            "rho_b": rho_b, "d": d, "t": t, "g": G}
    return records, data
