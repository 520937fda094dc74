"""Discharge: mass flow rate, flow pattern (mass flow / funnel flow) and dead zones.

* Steady discharge rate W [kg/s]: least-squares slope of the discharged mass m(t) over the
  part of the discharge where m is between ``lo`` and ``hi`` of its final value (the start-up
  after the gate opens and the emptying end are left out); its uncertainty is the standard
  error of the slopes of ``blocks`` consecutive blocks of that interval (batch means), which,
  unlike the residuals of one fit, is not fooled by the correlation of successive samples.
  No rate (NaN) when no grain left within that interval: the mass there is one plateau (two
  grains out before an arch, the first between ``lo`` and ``hi`` of the total), whose slope
  is round-off, not a flow.
* Mass flow index MFI = v_wall / v_axis [-]: mean vertical velocity of the grains within one
  diameter of the walls over that on the axis, in a band above the junction (the floor of a
  flat silo), while the free surface is well above the band.  Mass flow when MFI reaches a
  threshold (0.3: Johanson's index as used by Ketterhagen et al. 2009, Powder Technol. 195)
  and the dead zone holds under 1 % of the grains (``classify_flow``).
* Dead zone: grains that were in the silo when the gate opened and, up to the end of the
  discharge window (the horizon of the velocity field and the MFI), neither left nor moved
  more than a mean grain radius from their place, nor more than ``DEAD_SHARE`` of the
  column's mean descent (``dead_zone``).  Over the whole discharge, run until the
  silo is 90 % empty, the stagnant grains of a funnel flow creep and are finally pulled
  along as the last of the flow passes them: by then none had stayed within a radius.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt


@dataclass(frozen=True)
class RateEstimate:
    """Steady discharge rate [kg/s] with standard error [kg/s] over [t0, t1] [s]; ``why``
    says, in words, why the rate or its error is NaN ("" when both are numbers)."""

    rate: float
    err: float
    t0: float
    t1: float
    why: str = ""


def mean_of_runs(rates: npt.ArrayLike, errs: npt.ArrayLike) -> tuple[float, float]:
    """Mean [kg/s] of the steady rates of runs that differ only by their seed, and its standard
    error: the runs' errors combined, sqrt(sum err^2) / n, or the seeds' standard error of the
    mean, std / sqrt(n), if that is larger (the fills differ by more than one run's noise)."""
    rates = np.asarray(rates, dtype=float)
    errs = np.nan_to_num(np.asarray(errs, dtype=float))
    n = rates.size
    err = float(np.sqrt(np.sum(errs**2))) / n
    if n > 1:
        err = max(err, float(np.std(rates, ddof=1)) / float(np.sqrt(n)))
    return float(rates.mean()), err


def steady_rate(t: npt.ArrayLike, m: npt.ArrayLike, lo: float = 0.15, hi: float = 0.75,
                blocks: int = 5) -> RateEstimate:
    """Steady discharge rate from the discharged mass m(t) [kg] at times t [s] (see module)."""
    t = np.asarray(t, dtype=float)
    m = np.asarray(m, dtype=float)
    if t.size < 3 or not np.isfinite(m).any() or np.nanmax(m) <= 0:
        return _no_rate("no grain left the outlet" if t.size >= 3 else
                        f"{t.size} samples of the discharged mass: at least 3 are needed")
    total = np.nanmax(m)
    sel = (m >= lo * total) & (m <= hi * total)
    share = f"{100 * lo:.0f} - {100 * hi:.0f} % of the discharged mass"
    if sel.sum() < 3:  # (5 grains: the mass jumped past the interval in 2 samples)
        return _no_rate(f"{int(sel.sum())} samples in {share}, where the rate is fitted: too "
                        "few grains left, or they left together")
    ts, ms = t[sel], m[sel]
    if np.ptp(ms) == 0.0:  # one plateau: no grain left in the interval, no flow to fit
        return _no_rate(f"no grain left within {share}, where the rate is fitted")
    rate = float(np.polyfit(ts, ms, 1)[0])
    edges = np.linspace(ts[0], ts[-1], blocks + 1)
    slopes = []
    for a, b in itertools.pairwise(edges):
        # disjoint batches: half-open blocks, the last one closed (a sample on an inner edge
        # would otherwise count in two)
        k = (ts >= a) & ((ts < b) | (b == edges[-1]))
        if k.sum() >= 3 and np.ptp(ts[k]) > 0:
            slopes.append(np.polyfit(ts[k], ms[k], 1)[0])
    if len(slopes) < 2:
        return RateEstimate(rate, float("nan"), float(ts[0]), float(ts[-1]),
                            f"no error: {len(slopes)} of the fitted interval's {blocks} blocks "
                            "hold 3 samples for a slope, and batch means need 2")
    err = float(np.std(slopes, ddof=1) / np.sqrt(len(slopes)))
    return RateEstimate(rate, err, float(ts[0]), float(ts[-1]))


def _no_rate(why: str) -> RateEstimate:
    nan = float("nan")
    return RateEstimate(nan, nan, nan, nan, why)


def flow_rate_series(t: npt.ArrayLike, m: npt.ArrayLike,
                     width: float = 0.25) -> tuple[np.ndarray, np.ndarray]:
    """Mass flow rate [kg/s] against time: slope of m(t) [kg] over a sliding window of
    ``width`` seconds (a difference of the mass at the window's ends)."""
    t = np.asarray(t, dtype=float)
    m = np.asarray(m, dtype=float)
    if t.size < 2:
        return np.zeros(0), np.zeros(0)
    half = 0.5 * width
    a = np.searchsorted(t, t - half)
    b = np.clip(np.searchsorted(t, t + half, side="right") - 1, 0, t.size - 1)
    ok = t[b] > t[a]
    rate = np.full(t.size, np.nan)
    rate[ok] = (m[b[ok]] - m[a[ok]]) / (t[b[ok]] - t[a[ok]])
    return t, rate


def mass_flow_index(v_wall: npt.ArrayLike, v_axis: npt.ArrayLike, level: npt.ArrayLike,
                    band_top: float, margin: float) -> float:
    """MFI = mean(v_wall) / mean(v_axis) [-] over the samples whose free surface ``level`` [m]
    is above ``band_top + margin`` and where both velocities are measured (NaN if none)."""
    v_wall, v_axis, level = (np.asarray(v, dtype=float) for v in (v_wall, v_axis, level))
    ok = np.isfinite(v_wall) & np.isfinite(v_axis) & (level > band_top + margin)
    if not ok.any():
        return float("nan")
    va = float(np.mean(v_axis[ok]))
    return float(np.mean(v_wall[ok]) / va) if va != 0 else float("nan")


DEAD_SHARE = 0.25  # a dead grain moved less than this share of the column's mean descent


def dead_zone(exit_time: npt.ArrayLike, max_displacement: npt.ArrayLike,
              radius: float, horizon: float = np.inf, descent: float = np.inf) -> np.ndarray:
    """True for the grains that had not left by ``horizon`` [s after the gate opened] (exit
    time NaN or later) and never moved more than ``radius`` [m] up to it
    (``max_displacement`` [m], the largest distance from the grain's place at the opening up
    to the horizon), nor more than ``DEAD_SHARE`` of the column's mean ``descent`` [m] by
    then.  In a slow mass flow every grain descends, though by less than a radius within
    the window; a grain at the wall of a mass flow moves at least 0.3 times as fast as one
    on the axis (the mass-flow index's threshold), which moves at least at the mean: a
    quarter of the mean descent calls none of them dead."""
    exit_time = np.asarray(exit_time, dtype=float)
    stayed = np.isnan(exit_time) | (exit_time > horizon)
    return stayed & (np.asarray(max_displacement) < min(radius, DEAD_SHARE * descent))


DISCHARGE_PARTS = 10  # the discharged mass cut into this many equal shares


def mass_mean_diameter(radius: npt.ArrayLike) -> float:
    """The mass-weighted mean diameter sum(m d) / sum(m) [m] of disks of radii ``radius``
    [m], one density and thickness (m proportional to r^2); NaN for none."""
    r = np.asarray(radius, dtype=float)
    return float(2.0 * np.sum(r**3) / np.sum(r**2)) if r.size else float("nan")


@dataclass(frozen=True)
class Composition:
    """The sizes in a discharge, in ``DISCHARGE_PARTS`` equal shares of the discharged mass
    in the order it left (``discharge_composition``)."""

    fraction: np.ndarray  # the middle of each share, as a fraction of the discharged mass [-]
    diameter_ratio: np.ndarray  # each share's mass mean diameter over the fill's [-]
    fill_diameter: float  # the fill's mass mean diameter (grains at the gate opening) [m]
    sizes: np.ndarray  # the distinct radii, for a mixture of a few sizes (else empty) [m]
    size_share: np.ndarray  # (share, size): each size's share of the share's mass [-]
    fill_share: np.ndarray  # each size's share of the fill's mass [-]
    # diameter_ratio's 5th and 95th percentiles per share over random orders of the same
    # grains (``random_order_band``): what chance alone gives [-]
    chance_lo: np.ndarray
    chance_hi: np.ndarray
    # size_share's, the same way: (share, size) [-]
    share_lo: np.ndarray
    share_hi: np.ndarray

    @property
    def one_size(self) -> bool:
        """The grains are all of one size: every share is the fill, with no sizes to
        segregate (the report leaves its figure out and says so)."""
        return self.sizes.size == 1


CHANCE_ORDERS = 200  # random departure orders behind a composition's chance band
CHANCE_SEED = 20261125  # their generator's seed: the band is the same at every reading


def _share_index(r: np.ndarray, parts: int) -> np.ndarray:
    """The share of ``parts`` equal shares of the mass of disks of radii ``r`` [m], taken in
    that order, that each disk belongs to: the one its mass's middle falls in."""
    mass = r * r
    middle = (np.cumsum(mass) - 0.5 * mass) / np.sum(mass)
    return np.minimum((middle * parts).astype(np.int64), parts - 1)


def _share_ratios(r: np.ndarray, part: np.ndarray, parts: int, fill_d: float) -> np.ndarray:
    """Each of the ``parts`` shares' mass mean diameter over ``fill_d`` [-], the grains of
    radii ``r`` [m] in the shares ``part`` (:func:`_share_index`); NaN for a share no grain's
    middle falls in (a grain heavier than a share beside it)."""
    mass = r * r
    with np.errstate(invalid="ignore"):
        cubes = np.bincount(part, weights=mass * r, minlength=parts)
        return 2.0 * cubes / np.bincount(part, weights=mass, minlength=parts) / fill_d


def _size_shares(r: np.ndarray, part: np.ndarray, parts: int,
                 sizes: np.ndarray) -> np.ndarray:
    """(share, size): each of ``sizes``' share of each of the ``parts`` shares' mass [-], the
    grains of radii ``r`` [m] in the shares ``part``; NaN for a share no grain's middle falls
    in."""
    mass = r * r
    part_mass = np.bincount(part, weights=mass, minlength=parts)
    shares = np.zeros((parts, sizes.size))
    with np.errstate(invalid="ignore"):
        for j, size in enumerate(sizes):
            shares[:, j] = np.bincount(part, weights=mass * (r == size),
                                       minlength=parts) / part_mass
    return shares


def random_order_band(r: npt.ArrayLike, parts: int, fill_d: float,
                      orders: int = CHANCE_ORDERS,
                      sizes: npt.ArrayLike = ()) -> tuple[np.ndarray, ...]:
    """(5th, 95th percentile) of each share's ratio (:func:`_share_ratios`), then of each of
    ``sizes``' share of its mass ((share, size) arrays, :func:`_size_shares`), over
    ``orders`` random orders of the grains that left (radii ``r`` [m]), drawn with a fixed
    seed: the scatter that chance alone gives a discharge whose sizes do not segregate.  A
    share outside it shows segregation beyond chance (a permutation test at 10 %,
    two-sided, per share)."""
    r = np.asarray(r, dtype=float)
    sizes = np.asarray(sizes, dtype=float)
    rng = np.random.default_rng(CHANCE_SEED)
    ratios, shares = [], []
    for _ in range(orders):
        s = rng.permutation(r)
        part = _share_index(s, parts)
        ratios.append(_share_ratios(s, part, parts, fill_d))
        if sizes.size:  # (a mixture of a few sizes)
            shares.append(_size_shares(s, part, parts, sizes))
    lo, hi = np.nanpercentile(np.array(ratios), [5.0, 95.0], axis=0)
    if not sizes.size:
        return lo, hi, np.zeros((parts, 0)), np.zeros((parts, 0))
    share_lo, share_hi = np.nanpercentile(np.array(shares), [5.0, 95.0], axis=0)
    return lo, hi, share_lo, share_hi


def discharge_composition(exit_time: npt.ArrayLike, radius: npt.ArrayLike,
                          parts: int = DISCHARGE_PARTS, few: int = 8) -> Composition | None:
    """Size segregation in the discharge. The grains in the silo at the gate opening
    (radii ``radius`` [m]) that left (``exit_time`` finite [s]), taken in the order they
    left, are cut into ``parts`` shares of equal discharged mass (a grain belongs to the share
    in which the middle of its mass falls); each share's mass mean diameter
    (:func:`mass_mean_diameter`) over the fill's is 1 throughout when the sizes do not
    segregate. With at most ``few`` distinct radii (a discrete mixture), each size's share
    of each part's mass too, the normalised mass fraction of segregation studies being that
    over the fill's share. Both with the band chance alone gives (:func:`random_order_band`).
    None when fewer than ``parts`` grains left."""
    exit_time = np.asarray(exit_time, dtype=float)
    radius = np.asarray(radius, dtype=float)
    gone = np.isfinite(exit_time)
    if int(gone.sum()) < parts:
        return None
    order = np.argsort(exit_time[gone], kind="stable")
    r = radius[gone][order]
    part = _share_index(r, parts)
    fill_d = mass_mean_diameter(radius)
    sizes = np.unique(radius)
    if sizes.size > few:
        sizes = np.zeros(0)
    fill_share = np.array([np.sum(radius[radius == size] ** 2) for size in sizes]) / np.sum(
        radius**2)
    return Composition((np.arange(parts) + 0.5) / parts, _share_ratios(r, part, parts, fill_d),
                       fill_d, sizes, _size_shares(r, part, parts, sizes), fill_share,
                       *random_order_band(r, parts, fill_d, sizes=sizes))


def lost_grains(flow: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """(before, during): per grain of results.h5's ``measure/flow`` (a mapping of its
    datasets), True for the grains lost through a wall before the gate opened
    (``lost_before_discharge``; in a file written before that flag, those below the outlet,
    z0 < 0) and for those lost through a wall after it (``lost_during_discharge``; none in a
    file written before it).  Neither kind discharged."""
    z0 = np.asarray(flow["z0"], dtype=float)
    before = (np.asarray(flow["lost_before_discharge"], dtype=bool)
              if "lost_before_discharge" in flow else z0 < 0.0)
    during = (np.asarray(flow["lost_during_discharge"], dtype=bool)
              if "lost_during_discharge" in flow else np.zeros(z0.size, bool))
    return before, during & ~before  # (a file that flagged a grain twice: lost before)


def flow_composition(flow: Mapping[str, Any], parts: int = DISCHARGE_PARTS) -> Composition | None:
    """:func:`discharge_composition` of results.h5's ``measure/flow`` (a mapping of its
    datasets, radii ``r0`` at the gate opening): the grains lost through a wall before the
    gate opened (:func:`lost_grains`) were not in the silo then and are in neither count; those
    lost after it count in the fill's reference but never left."""
    before, _ = lost_grains(flow)
    return discharge_composition(np.asarray(flow["exit_time"], dtype=float)[~before],
                                 np.asarray(flow["r0"], dtype=float)[~before], parts)


def dead_fraction(dead: npt.ArrayLike, lost: npt.ArrayLike | None = None) -> float:
    """The fraction [-] of the grains in the silo as the gate opened that are in the dead zone
    (``dead``, :func:`dead_zone`): grains ``lost`` through a wall (either kind of
    :func:`lost_grains`; None: none) are in neither count.  NaN without a grain."""
    dead = np.asarray(dead, dtype=bool)
    there = ~np.asarray(lost, dtype=bool) if lost is not None else np.ones(dead.size, bool)
    return float(dead[there].mean()) if there.any() else float("nan")


def classify_flow(mfi: float, dead_fraction: float, threshold: float = 0.3) -> str:
    """'mass flow' when MFI >= threshold and no dead zone (< 1 % of the grains), else
    'funnel flow'; 'unknown' when the MFI could not be measured."""
    if not np.isfinite(mfi):
        return "unknown"
    return "mass flow" if mfi >= threshold and dead_fraction < 0.01 else "funnel flow"
