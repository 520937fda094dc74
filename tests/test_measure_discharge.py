"""The discharge measurements (``measure.discharge``) on mass records whose rate is known:
exact lines and parabolas, and a discharge with random, independent increments whose error
follows from the theory of least squares on a random walk."""

from __future__ import annotations

import numpy as np
import pytest

from silodem.measure.discharge import (
    classify_flow,
    dead_zone,
    discharge_composition,
    flow_composition,
    flow_rate_series,
    mass_flow_index,
    steady_rate,
)


def test_steady_rate_is_the_slope_between_the_start_up_and_the_emptying():
    """m(t): a start-up (a parabola from rest), then a steady rate W, then the silo empties
    (a parabola down to rest).  With the steady part covering 10-90 % of the final mass, the
    15-75 % window lies inside it: the slope is W exactly and the batch-means error is 0."""
    W, t_up, t_steady, t_end = 2.5, 0.4, 8.0, 0.8  # [kg/s], [s]
    t = np.linspace(0.0, t_up + t_steady + t_end, 4001)
    m_up = 0.5 * W * t_up  # mass at the end of the start-up (rate from 0 to W linearly)
    m = np.where(t < t_up, 0.5 * W * t**2 / t_up, m_up + W * (t - t_up))
    late = t > t_up + t_steady
    s = t[late] - (t_up + t_steady)
    m[late] = m_up + W * t_steady + W * s - 0.5 * W * s**2 / t_end
    total = m_up + W * t_steady + 0.5 * W * t_end
    assert m.max() == pytest.approx(total)
    est = steady_rate(t, m)
    assert est.rate == pytest.approx(W, rel=1e-12)
    assert est.err == pytest.approx(0.0, abs=1e-9 * W)
    # the window's ends: where m first reaches 15 % and last stays under 75 % of the total
    assert est.t0 == pytest.approx(t_up + (0.15 * total - m_up) / W, abs=t[1] - t[0])
    assert est.t1 == pytest.approx(t_up + (0.75 * total - m_up) / W, abs=t[1] - t[0])


def test_steady_rate_error_is_that_of_a_random_walk():
    """m(t) = W t + B(t), B a random walk with diffusion D [kg^2/s] (grains leave one by one,
    independently): the least-squares slope over a window of length T has variance
    6 D / (5 T) (the integral of (u - 1/2)(v - 1/2) min(u, v) over the unit square is 1/120,
    times 144), and the five block slopes are independent, each with 6 D / (5 T/5), so the
    batch-means error squared has that same expectation.  2000 records: the spread of the
    rates and the mean squared error both agree with 6 D / (5 T) within their sampling
    error (2.2 % and 3.2 % standard deviations; asserted within 4.5 of them)."""
    rng = np.random.default_rng(7)
    W, D, duration, n = 3.0, 0.04, 10.0, 5000
    t = np.linspace(0.0, duration, n + 1)
    dt = t[1] - t[0]
    rates, errs2, windows = [], [], []
    for _ in range(2000):
        walk = np.concatenate([[0.0], np.cumsum(rng.normal(0.0, np.sqrt(D * dt), n))])
        est = steady_rate(t, W * t + walk)
        rates.append(est.rate)
        errs2.append(est.err**2)
        windows.append(est.t1 - est.t0)
    expected = 6.0 * D / (5.0 * np.mean(windows))  # the window is 60 % of the run, +- noise
    assert np.mean(rates) == pytest.approx(W, abs=4.5 * np.sqrt(expected / 2000))
    assert np.var(rates, ddof=1) == pytest.approx(expected, rel=4.5 * np.sqrt(2 / 1999))
    # err^2 is expected / 4 times a chi-square of 4 degrees of freedom: sd 1/sqrt(2) of it
    assert np.mean(errs2) == pytest.approx(expected, rel=4.5 * np.sqrt(0.5 / 2000))


def test_steady_rate_blocks_are_disjoint_batches():
    """Samples at t = 0, 1, ..., 20 s put the inner block edges (4, 8, 12, 16 s) on samples.
    Batch means need disjoint batches: the blocks are written out here by hand, [0, 4), [4, 8),
    [8, 12), [12, 16), [16, 20], and the error is the standard error of their five slopes."""
    t = np.arange(21.0)
    m = 1.0 + 2.0 * t + np.array([0.3, -0.1, 0.4, -0.2] * 5 + [0.1])  # wiggles, all m > 0
    est = steady_rate(t, m, lo=0.0, hi=1.0, blocks=5)
    hand = [range(4), range(4, 8), range(8, 12), range(12, 16), range(16, 21)]
    slopes = [np.polyfit(t[list(k)], m[list(k)], 1)[0] for k in hand]
    assert est.rate == pytest.approx(np.polyfit(t, m, 1)[0], rel=1e-12)
    assert est.err == pytest.approx(np.std(slopes, ddof=1) / np.sqrt(5), rel=1e-12)


def test_steady_rate_without_a_record_is_nan():
    for t, m in [([0.0, 1.0], [0.0, 1.0]), ([0.0, 1.0, 2.0], [0.0, 0.0, 0.0]),
                 ([0.0, 1.0, 2.0], [np.nan] * 3)]:
        assert np.isnan(steady_rate(t, m).rate)


def test_a_missing_rate_or_error_says_why():
    """Each way ``steady_rate`` gives no rate, or a rate without an error, is said in words
    (a run of 5 grains read "n/a +- n/a" in the report).  Five grains, 20 % of the mass each,
    sampled so that the mass jumps from 0 past 15 % to 20 %, then past 75 %: 2 samples in the
    interval.  Three samples in it, one in each of 3 of the 5 blocks: a slope (20 kg/s, the
    straight line through them) but no block with the 3 samples of a slope of its own."""
    assert steady_rate([0.0, 1.0], [0.0, 1.0]).why == (
        "2 samples of the discharged mass: at least 3 are needed")
    assert steady_rate([0.0, 1.0, 2.0], [0.0] * 3).why == "no grain left the outlet"
    jumps = steady_rate(np.arange(6.0), [0.0, 20.0, 20.0, 100.0, 100.0, 100.0])
    assert np.isnan(jumps.rate) and jumps.why == (
        "2 samples in 15 - 75 % of the discharged mass, where the rate is fitted: too few "
        "grains left, or they left together")
    three = steady_rate(np.arange(5.0), [0.0, 20.0, 40.0, 60.0, 100.0])
    assert three.rate == pytest.approx(20.0, rel=1e-12) and np.isnan(three.err)
    assert three.why == ("no error: 0 of the fitted interval's 5 blocks hold 3 samples for a "
                         "slope, and batch means need 2")
    t = np.linspace(0.0, 2.0, 201)
    assert steady_rate(t, 5.0 * t).why == ""  # a rate and its error


def test_no_rate_from_two_grains_before_an_arch():
    """Two grains out, then an arch: the mass between 15 % and 75 % of its final value is the
    one plateau of the first grain, whose fitted slope was round-off (-6.5e-14 kg/s in a
    clogged run, and a Beverloo C of -3.4e-16 from it). No grain left in the interval: no
    rate.  A third grain makes the interval hold a step, and the rate is the fitted slope."""
    t = np.linspace(0.0, 2.0, 201)
    two = np.where(t >= 0.3, 23.79, 0.0) + np.where(t >= 0.38, 28.69, 0.0)
    assert np.isnan(steady_rate(t, two).rate)
    assert steady_rate(t, two).why == (
        "no grain left within 15 - 75 % of the discharged mass, where the rate is fitted")
    three = np.where(t >= 0.3, 20.0, 0.0) + np.where(t >= 0.5, 20.0, 0.0) + \
        np.where(t >= 0.7, 20.0, 0.0)
    est = steady_rate(t, three)
    sel = (three >= 0.15 * 60.0) & (three <= 0.75 * 60.0)
    assert est.rate == pytest.approx(np.polyfit(t[sel], three[sel], 1)[0], rel=1e-12)
    assert est.rate > 0


def test_flow_rate_series_differentiates_a_parabola_exactly():
    """A centred difference of m = a t^2 over any window is the exact derivative 2 a t at the
    window's centre; near the ends the window is cut and centred elsewhere: there the rate is
    a (t_a + t_b), still exact for the window it has."""
    a = 0.7
    t = np.arange(321) / 64.0  # 0 ... 5 s; t +- 0.25 exact in binary: windows of 33 samples
    times, rate = flow_rate_series(t, a * t**2, width=0.5)
    assert np.array_equal(times, t)
    inner = (t >= 0.25) & (t <= 4.75)
    np.testing.assert_allclose(rate[inner], 2 * a * t[inner], rtol=1e-12, atol=1e-12)
    assert np.all(np.isfinite(rate)) and np.all(rate >= 0.0)
    assert rate[0] == pytest.approx(a * (t[0] + 0.25), rel=1e-12)  # window [0, 0.25]
    assert rate[-1] == pytest.approx(a * (4.75 + t[-1]), rel=1e-12)


def test_mass_flow_index_is_the_ratio_of_the_mean_velocities_while_the_band_is_covered():
    """Only the samples with the free surface above band_top + margin and both velocities
    measured count; the ratio is of the means, not the mean of the ratios."""
    v_axis = np.array([-2.0, -1.0, -3.0, -1.0, np.nan])
    v_wall = np.array([-1.0, -0.6, 99.0, np.nan, -5.0])
    level = np.array([5.0, 4.0, 1.0, 5.0, 5.0])  # sample 2's surface is below the band
    mfi = mass_flow_index(v_wall, v_axis, level, band_top=2.0, margin=0.5)
    assert mfi == pytest.approx((-1.0 - 0.6) / (-2.0 - 1.0), rel=1e-15)
    assert np.isnan(mass_flow_index(v_wall, v_axis, level, band_top=10.0, margin=0.5))


def test_dead_grains_never_left_nor_moved_a_radius_and_mass_flow_needs_none():
    """Dead: never left (no exit time) and never moved a grain radius; mass flow needs both
    the index at the threshold or above and (almost) no dead grains."""
    exit_time = np.array([np.nan, np.nan, 3.0, np.nan])
    moved = np.array([0.001, 0.2, 0.001, 0.0049])
    np.testing.assert_array_equal(dead_zone(exit_time, moved, 0.005),
                                  [True, False, False, True])
    assert classify_flow(0.3, 0.0) == "mass flow"
    assert classify_flow(0.29, 0.0) == "funnel flow"
    assert classify_flow(0.8, 0.01) == "funnel flow"
    assert classify_flow(0.8, 0.5, threshold=0.9) == "funnel flow"
    assert classify_flow(float("nan"), 0.0) == "unknown"


def test_composition_of_a_discharge_where_the_small_grains_leave_first():
    """Ten grains of r = 1 (mass 1 each) leave, then ten of r = 2 (mass 4): 50 in all, five
    to a tenth. The small ones fill the first two tenths (middles 0.5 ... 9.5 of 50); the
    fill's mass mean diameter is 2 (10 x 1 + 10 x 8) / 50 = 3.6, so the first tenths read
    2 / 3.6 = 5/9 and the rest 4 / 3.6 = 10/9; by mass the fill is 20 % small, 80 % large."""
    r = np.array([1.0] * 10 + [2.0] * 10)
    t = np.arange(20.0)
    c = discharge_composition(t, r)
    assert c.fill_diameter == pytest.approx(3.6, rel=1e-15)
    np.testing.assert_allclose(c.diameter_ratio, [5 / 9] * 2 + [10 / 9] * 8, rtol=1e-14)
    np.testing.assert_allclose(c.fraction, np.arange(0.05, 1.0, 0.1), rtol=1e-14)
    np.testing.assert_array_equal(c.sizes, [1.0, 2.0])
    np.testing.assert_allclose(c.fill_share, [0.2, 0.8], rtol=1e-15)
    np.testing.assert_array_equal(c.size_share[:, 0], [1, 1] + [0] * 8)


def test_composition_without_segregation_reads_one_in_every_tenth():
    """Each tenth holds one grain of r = 2 and four of r = 1 (mass 8: the large one's middle at
    8 k + 2, the small ones' at 8 k + 4.5 ... 7.5): every tenth is the fill. A grain that never
    left (r = 3) counts in the fill, and so in the reference, not in the tenths."""
    r = np.tile([2.0, 1.0, 1.0, 1.0, 1.0], 10)
    t = np.arange(50.0)
    c = discharge_composition(t, r)
    np.testing.assert_allclose(c.diameter_ratio, 1.0, rtol=1e-14)
    np.testing.assert_allclose(c.size_share, [[0.5, 0.5]] * 10, rtol=1e-14)
    stayed = discharge_composition(np.append(t, np.nan), np.append(r, 3.0))
    d_fill = 2 * (10 * 8 + 40 * 1 + 27) / (10 * 4 + 40 * 1 + 9)  # sum m d / sum m
    assert stayed.fill_diameter == pytest.approx(d_fill, rel=1e-15)
    np.testing.assert_allclose(stayed.diameter_ratio, 2 * 120 / 80 / d_fill, rtol=1e-14)


def test_the_flow_records_composition_leaves_out_the_grains_lost_before_the_opening():
    """The interleaved discharge above as results.h5's measure/flow, with two grains of r = 3
    that never left: one lost through a wall before the gate opened, which was not in the silo
    then and so is not in the reference (every tenth reads 1, as without it), and one lost
    after, which was and is (the reference of the grain that stayed above). A file written
    before the flags tells the first by its centre below the outlet (z0 < 0)."""
    r = np.append(np.tile([2.0, 1.0, 1.0, 1.0, 1.0], 10), [3.0, 3.0])
    t = np.append(np.arange(50.0), [np.nan, np.nan])
    z0 = np.append(np.full(50, 0.5), [-0.02, 0.4])
    flow = {"exit_time": t, "r0": r, "z0": z0,
            "lost_before_discharge": np.arange(52) == 50,
            "lost_during_discharge": np.arange(52) == 51}
    d_fill = 2 * (10 * 8 + 40 * 1 + 27) / (10 * 4 + 40 * 1 + 9)
    for record in (flow, {k: flow[k] for k in ("exit_time", "r0", "z0")}):
        c = flow_composition(record)
        assert c.fill_diameter == pytest.approx(d_fill, rel=1e-15)
        np.testing.assert_allclose(c.diameter_ratio, 2 * 120 / 80 / d_fill, rtol=1e-14)
    counted_both = discharge_composition(t, r)  # (what the lost one would have made it)
    assert counted_both.fill_diameter == pytest.approx(2 * (120 + 54) / (80 + 18), rel=1e-15)
    assert flow_composition({**flow, "lost_before_discharge": np.ones(52, bool)}) is None


def test_the_chance_band_is_the_scatter_of_random_orders_of_the_same_grains():
    """A 50/50 mixture by number of r = 0.08 and 0.12 m, 2000 grains: the band (5th and 95th
    percentiles of each tenth's ratio over 200 random orders) against a brute-force reference
    of 2000 other random orders, each tenth's mass mean diameter taken grain by grain. The
    percentiles of 200 draws scatter by about 0.0016 here, so they agree within 0.006. The
    small grains leaving first lie far outside it; one size has a band of exactly 1. The band
    of each size's share of a tenth's mass against the same reference."""
    rng = np.random.default_rng(7)
    r = rng.permutation(np.repeat([0.08, 0.12], 1000))
    c = discharge_composition(np.arange(2000.0), r)
    fill_d = 2 * np.sum(r**3) / np.sum(r**2)
    reference, small_shares = [], []
    for _ in range(2000):
        order = rng.permutation(r)
        mass = order**2
        middle = (np.cumsum(mass) - 0.5 * mass) / mass.sum()
        tenth = np.minimum((middle * 10).astype(int), 9)
        reference.append([2 * np.sum(order[tenth == k] ** 3) / np.sum(order[tenth == k] ** 2)
                          for k in range(10)])
        small_mass = [np.sum(order[tenth == k] ** 2 * (order[tenth == k] == 0.08))
                      / np.sum(order[tenth == k] ** 2) for k in range(10)]
        small_shares.append(small_mass)
    lo, hi = np.percentile(np.array(reference) / fill_d, [5.0, 95.0], axis=0)
    np.testing.assert_allclose(c.chance_lo, lo, atol=6e-3)
    np.testing.assert_allclose(c.chance_hi, hi, atol=6e-3)
    # the small grains' share of each tenth's mass (the fill's: 64 / (64 + 144) = 0.3077)
    # scatters by about +-0.047; the 5th percentile of 200 draws by about 0.0045: within 0.012
    share_lo, share_hi = np.percentile(np.array(small_shares), [5.0, 95.0], axis=0)
    np.testing.assert_allclose(c.sizes, [0.08, 0.12])
    np.testing.assert_allclose(c.share_lo[:, 0], share_lo, atol=0.012)
    np.testing.assert_allclose(c.share_hi[:, 0], share_hi, atol=0.012)
    np.testing.assert_allclose(c.share_lo[:, 1], 1 - c.share_hi[:, 0], atol=1e-12)
    assert np.all((share_lo < 64 / 208) & (64 / 208 < share_hi))
    assert np.all(c.chance_hi - c.chance_lo > 0.02)  # a real scatter, about +-1.7 %
    small_first = discharge_composition(np.arange(2000.0), np.sort(r))
    assert small_first.diameter_ratio[0] < small_first.chance_lo[0] - 0.1  # (16 / 21.5)
    assert small_first.diameter_ratio[-1] > small_first.chance_hi[-1] + 0.05  # (24 / 21.5)
    one = discharge_composition(np.arange(50.0), np.full(50, 0.1))
    assert np.all(one.chance_lo == one.diameter_ratio) and np.all(
        one.chance_hi == one.diameter_ratio)
    np.testing.assert_allclose(one.diameter_ratio, 1.0, rtol=1e-14)


def test_composition_needs_a_grain_per_tenth_and_lists_sizes_of_a_mixture_only():
    assert discharge_composition(np.arange(9.0), np.ones(9)) is None
    r = np.random.default_rng(3).uniform(1.0, 2.0, 200)  # 200 distinct sizes: no list
    c = discharge_composition(np.arange(200.0), r)
    assert c.sizes.size == 0 and c.size_share.shape == (10, 0)
