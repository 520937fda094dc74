"""Silo theory (silodem.theory) against independent references: direct numerical integration of
the slice force balances (scipy solve_ivp), hydrostatics, statics of a deep column, Rankine,
and a brute-force Mohr-circle construction."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp, trapezoid
from scipy.optimize import brentq

from silodem import theory as th

RHO_B, G = 700.0, 9.81
GAMMA = RHO_B * G


# --- Janssen -----------------------------------------------------------------------------------


@pytest.mark.parametrize("K,mu,B", [(0.4, 0.45, 3.4), (0.6, 0.2, 1.0), (1.2, 0.9, 0.5)])
def test_janssen_solves_the_slice_balance_of_a_slot(K, mu, B):
    # slice of width B, two walls: B d(sigma_v)/dz = gamma B - 2 mu K sigma_v
    sol = solve_ivp(lambda z, s: [GAMMA - 2.0 * mu * K * s[0] / B], (0.0, 6.0), [0.0],
                    rtol=1e-11, atol=1e-9, dense_output=True)
    z = np.linspace(0.05, 6.0, 40)
    ref = sol.sol(z)[0]
    got = th.janssen_sigma_v(z, RHO_B, G, B, K, mu)
    # the closed form against scipy at rtol 1e-11 (measured within 2e-12)
    np.testing.assert_allclose(got, ref, rtol=1e-9)
    np.testing.assert_allclose(th.janssen_sigma_h(z, RHO_B, G, B, K, mu), K * ref, rtol=1e-9)


def test_deep_janssen_column_hangs_on_its_walls():
    # far below the surface the two walls carry the whole weight: 2 tau = gamma B
    B, K, mu = 2.0, 0.5, 0.4
    tau = th.janssen_wall_shear(1e3, RHO_B, G, B, K, mu)
    assert 2.0 * tau == pytest.approx(GAMMA * B, rel=1e-9)
    _, p_w, _ = th.en1991_4_filling(1e3, GAMMA, K, mu, B / 2.0)
    assert 2.0 * p_w == pytest.approx(GAMMA * B, rel=1e-9)
    # near the surface: hydrostatic-like, sigma_v = gamma z
    assert th.janssen_sigma_v(1e-4, RHO_B, G, B, K, mu) == pytest.approx(GAMMA * 1e-4, rel=1e-4)


@pytest.mark.parametrize("K,mu", [(0.4, 0.45), (0.7, 0.25), (0.3, 0.8)])
def test_janssen_fit_recovers_K_and_mu_from_synthetic_profiles(K, mu):
    B = 3.4
    depth = np.linspace(0.1, 4.5, 18)
    exact = th.janssen_sigma_h(depth, RHO_B, G, B, K, mu)
    fit = th.fit_janssen(depth, exact, RHO_B, G, B)
    assert fit.K == pytest.approx(K, rel=1e-4)
    assert fit.mu_w == pytest.approx(mu, rel=1e-4)
    # with 2 % noise and mu_w known, K scales the profile: known to about 0.02 / sqrt(n)
    # (n points); within five such
    rng = np.random.default_rng(3)
    noisy = exact * (1.0 + 0.02 * rng.standard_normal(depth.size))
    assert th.fit_janssen(depth, noisy, RHO_B, G, B, mu_w=mu).K == pytest.approx(
        K, rel=5 * 0.02 / np.sqrt(depth.size))
    # K and mu_w together, on a deep profile (it pins the asymptote, hence mu_w): within five
    # of the fit's own standard errors, which are small (about 1 % over 300 noise draws, where
    # they came out calibrated: the errors over their standard errors had a spread of 0.9-1.15)
    deep = np.linspace(0.1, 20.0, 60)
    noisy = th.janssen_sigma_h(deep, RHO_B, G, B, K, mu) * (
        1.0 + 0.02 * rng.standard_normal(deep.size))
    fit = th.fit_janssen(deep, noisy, RHO_B, G, B)
    assert abs(fit.K - K) <= 5 * fit.K_err and fit.K_err < 0.02 * K
    assert abs(fit.mu_w - mu) <= 5 * fit.mu_w_err and fit.mu_w_err < 0.02 * mu


# --- Walker's hopper slice solution -------------------------------------------------------------


def _slice_ode(alpha_deg, mu, D, planar):
    """d(A sigma)/dh = -gamma A + P D sigma (tan(alpha) + mu), written for sigma(h)."""
    ta = math.tan(math.radians(alpha_deg))

    def area(h):
        return 2.0 * h * ta if planar else math.pi * (h * ta) ** 2

    def d_area(h):
        return 2.0 * ta if planar else 2.0 * math.pi * h * ta * ta

    def perimeter(h):
        return 2.0 if planar else 2.0 * math.pi * h * ta

    def rhs(h, s):
        a = area(h)
        return [(-GAMMA * a + perimeter(h) * D * s[0] * (ta + mu) - d_area(h) * s[0]) / a]

    return rhs


CASES = [  # alpha from the vertical [deg], mu_w, D, q [Pa]
    (45.0, math.tan(math.radians(24.0)), 1.0, 15000.0),  # paper case 2
    (20.0, 0.3, 1.0, 8000.0),
    (60.0, 0.6, 1.0, 0.0),  # n < 1 for the wedge
    (30.0, 0.5, 1.4, 12000.0),  # Walker distribution factor
    (35.0, 0.7002075382097097, 1.0, 5000.0),  # wedge n = 1 exactly: mu = tan(alpha)
]


@pytest.mark.parametrize("planar", [True, False], ids=["planar", "conical"])
@pytest.mark.parametrize("alpha,mu,D,q", CASES)
def test_hopper_solution_matches_numerical_integration_of_the_slice_balance(alpha, mu, D, q,
                                                                            planar):
    if abs(mu - math.tan(math.radians(alpha))) < 1e-9:
        mu = math.tan(math.radians(alpha))
    H = 1.7
    h_end = 0.2
    sol = solve_ivp(_slice_ode(alpha, mu, D, planar), (H, h_end), [q], method="DOP853",
                    rtol=1e-12, atol=1e-10, dense_output=True)
    h = np.linspace(H, h_end, 30)
    ref = sol.sol(h)[0]
    got = th.hopper_sigma_v(h, H, q, GAMMA, alpha, mu, D, planar)
    # against scipy's DOP853 at rtol 1e-12 (measured within 5e-12)
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-9 * max(q, GAMMA * H))
    np.testing.assert_allclose(th.hopper_wall_normal(h, H, q, GAMMA, alpha, mu, D, planar),
                               D * ref, rtol=1e-9, atol=1e-9 * max(q, GAMMA * H))


def test_smooth_hopper_with_isotropic_wall_stress_is_hydrostatic():
    # mu_w = 0 and D = 1: the grains act as a fluid, sigma = q + gamma (H - h)
    H, q = 2.0, 3000.0
    h = np.linspace(0.1, H, 25)
    for planar in (True, False):
        got = th.hopper_sigma_v(h, H, q, GAMMA, 30.0, 0.0, 1.0, planar)
        np.testing.assert_allclose(got, q + GAMMA * (H - h), rtol=1e-12)


def test_paper_eq12_is_the_conical_form_with_D_1():
    alpha, mu, q, H = 45.0, math.tan(math.radians(24.0)), 12000.0, 1.7
    z = np.linspace(0.0, 1.2, 13)  # down from the transition
    paper = th.paper_eq12(z, H, q, GAMMA, alpha, mu)
    np.testing.assert_allclose(paper, th.hopper_sigma_v(H - z, H, q, GAMMA, alpha, mu, 1.0,
                                                        planar=False), rtol=1e-12)
    # the planar exponent is half the conical one (m = 0 instead of 1), for D = 1
    assert th.walker_exponent(alpha, mu, planar=True) == pytest.approx(
        0.5 * th.walker_exponent(alpha, mu, planar=False))


def test_paper_eq12_at_n_i_0_is_its_limit():
    """alpha = 45 deg, mu_w = 0.5: n_i = 2 (1 + 0.5) - 3 = 0, where eq. (12) as printed divides
    by zero; its limit solves the conical slice balance (D = 1), integrated numerically."""
    H, q, h_end = 1.7, 12000.0, 0.2
    sol = solve_ivp(_slice_ode(45.0, 0.5, 1.0, planar=False), (H, h_end), [q], method="DOP853",
                    rtol=1e-12, atol=1e-10, dense_output=True)
    z = np.linspace(0.0, H - h_end, 20)
    np.testing.assert_allclose(th.paper_eq12(z, H, q, GAMMA, 45.0, 0.5), sol.sol(H - z)[0],
                               rtol=1e-9, atol=1e-9 * max(q, GAMMA * H))


def test_alpha_is_the_complement_of_theta():
    assert th.alpha_from_theta(60.0) == 30.0
    assert th.apex_below_outlet(1.0, 45.0) == pytest.approx(0.5)
    # a steep hopper (alpha = 30 deg from the vertical): the walls from the outlet's edges,
    # x = D/2 - h tan(alpha), meet at h = (D/2) / tan 30 = 0.866 D under the outlet; with
    # alpha and theta swapped it would be 0.289 D
    assert th.apex_below_outlet(1.0, 30.0) == pytest.approx(math.sqrt(3) / 2, rel=1e-12)


# --- Walker's distribution factor -----------------------------------------------------------


def _brute_force_D(delta_deg, phi_w_deg, alpha_deg):
    """Mohr circle (p = 1, radius sin delta) rotated until the traction on the right hopper wall
    has tau/sigma_n = tan(phi_w) with friction acting up the wall; passive = larger sigma_n."""
    s = math.sin(math.radians(delta_deg))
    a = math.radians(alpha_deg)
    n = np.array([-math.cos(a), math.sin(a)])  # into the grains
    t = np.array([math.sin(a), math.cos(a)])  # up the wall
    mu = math.tan(math.radians(phi_w_deg))

    def tensor(psi):
        e1 = np.array([math.cos(psi), math.sin(psi)])
        e3 = np.array([-math.sin(psi), math.cos(psi)])
        return (1 + s) * np.outer(e1, e1) + (1 - s) * np.outer(e3, e3)

    def f(psi):
        sig = tensor(psi)
        return t @ sig @ n - mu * (n @ sig @ n)

    grid = np.linspace(0.0, math.pi, 2001)
    vals = [f(p) for p in grid]
    roots = [brentq(f, grid[k], grid[k + 1], xtol=1e-15) for k in range(len(grid) - 1)
             if vals[k] * vals[k + 1] < 0]
    best = max(roots, key=lambda p: n @ tensor(p) @ n)
    sig = tensor(best)
    return (n @ sig @ n) / sig[1, 1]


@pytest.mark.parametrize("delta,phi_w,alpha", [(40, 20, 25), (30, 24, 45), (35, 10, 0),
                                               (45, 30, 60)])
def test_walker_distribution_factor_matches_a_mohr_circle_construction(delta, phi_w, alpha):
    assert th.walker_distribution_factor(delta, phi_w, alpha) == pytest.approx(
        _brute_force_D(delta, phi_w, alpha), rel=1e-8)


def test_walker_factor_of_a_smooth_vertical_wall_is_rankine_passive():
    delta = 33.0
    rankine = math.tan(math.radians(45 + delta / 2)) ** 2
    assert th.walker_distribution_factor(delta, 0.0, 0.0) == pytest.approx(rankine, rel=1e-12)


# --- Beverloo and EN 1991-4 -----------------------------------------------------------------------


def test_beverloo_2d_rate_scales_as_d_minus_kd_to_three_halves_and_inverts_for_c():
    w1 = th.beverloo_2d(1.0, 0.2, RHO_B, G, C=1.0, k=1.5)
    w2 = th.beverloo_2d(1.7, 0.2, RHO_B, G, C=1.0, k=1.5)
    assert w2 / w1 == pytest.approx(((1.7 - 0.3) / (1.0 - 0.3)) ** 1.5)
    assert w1 == pytest.approx(RHO_B * math.sqrt(G) * 0.7**1.5)
    assert th.beverloo_2d_C(2.5 * w1, 1.0, 0.2, RHO_B, G, k=1.5) == pytest.approx(2.5)
    assert th.beverloo_2d(0.25, 0.2, RHO_B, G, C=1.0, k=1.5) == 0.0


def test_a_parameter_the_model_does_not_depend_on_has_no_finite_error():
    """curve_fit's pseudo-inverse (its bounded, trust-region method) gives a parameter that the
    model ignores a variance of 0: a Janssen K with mu_w = tan 89 deg (its curve at its
    asymptote, 119 Pa, from the first bin on; the wall bins of such a run at 4.8-14 kPa) came
    out as 1 +- 0 (an audit).  Such a parameter now has an infinite variance; one the model
    does use keeps its finite one."""
    from silodem.theory._fit import curve_fit_quiet

    x = np.array([0.0, 1.0, 2.0, 3.0])
    y = np.array([0.1, 1.9, 4.2, 5.9])
    popt, pcov = curve_fit_quiet(lambda xx, a, b: a * xx, x, y, p0=[1.0, 1.0],
                                 bounds=([0.0, 0.0], [5.0, 5.0]))  # (trust region, as the fits)
    assert popt[0] == pytest.approx(np.sum(x * y) / np.sum(x * x), rel=1e-6)
    assert 0 < pcov[0, 0] < np.inf and pcov[1, 1] == np.inf
    depth = np.array([1.9535, 1.5685, 1.1835, 0.7985, 0.4135])
    sigma_h = np.array([11252.0, 14392.0, 6976.1, 5682.9, 4767.6])
    fit = th.fit_janssen(depth, sigma_h, 680.32, 9.81, 2.04, mu_w=math.tan(math.radians(89.0)))
    assert not np.isfinite(fit.K_err)


def test_janssen_free_fit_of_a_hydrostatic_profile_says_mu_w_is_at_its_bound():
    """sigma_h = K rho g depth (no wall support): the free fit takes mu_w to its lower bound and
    K to the hydrostatic K; a Janssen profile is not flagged."""
    z = np.linspace(0.2, 4.0, 20)
    flat = th.fit_janssen(z, 0.5 * 700 * 9.81 * z, 700, 9.81, 3.4)
    assert flat.mu_w_at_bound and flat.K == pytest.approx(0.5, rel=1e-5)
    curved = th.fit_janssen(z, th.janssen_sigma_h(z, 700, 9.81, 3.4, 0.5, 0.4), 700, 9.81, 3.4)
    assert not curved.mu_w_at_bound and (curved.K, curved.mu_w) == pytest.approx((0.5, 0.4))


def test_beverloo_narrow_widths_are_nedderman_s_two_conditions():
    """A rate independent of the silo's width B needs B >= 2.5 D and B >= D + 30 d (Nedderman
    1992, as Mankoc et al. 2007 quote it): each width B is under is listed, none for a silo
    wide enough; B equal to a width (exact in binary) is wide enough for it."""
    assert th.beverloo_narrow_widths(3.4, 1.0, 0.2) == [("D + 30 d", pytest.approx(7.0))]
    assert th.beverloo_narrow_widths(2.0, 1.0, 0.2) == [("2.5 D", 2.5),
                                                        ("D + 30 d", pytest.approx(7.0))]
    assert th.beverloo_narrow_widths(3.0, 1.4, 0.05) == [("2.5 D", pytest.approx(3.5))]
    assert th.beverloo_narrow_widths(4.75, 1.0, 0.125) == []  # D + 30 d = 4.75 exactly
    assert th.beverloo_narrow_widths(2.5, 1.0, 0.03125) == []  # 2.5 D = 2.5 exactly
    with pytest.raises(ValueError, match="beverloo_narrow_widths: B"):
        th.beverloo_narrow_widths(0.0, 1.0, 0.1)


def test_beverloo_fit_errors_match_the_scatter_of_noisy_fits():
    """The standard errors the two fits report (covariance of the least squares, propagated to
    C and k) against a brute-force reference: the spread of the constants fitted to 600 sets of
    rates drawn from the law with 2 % Gaussian noise.  Agreement within 10 % (the spread of a
    standard deviation of 600 draws is 3 %; the fits are non-linear in C and k)."""
    d, rho, g, t = 0.01, 2000.0, 9.81, 0.01
    D = np.array([6.0, 8.0, 10.0, 13.0, 17.0, 22.0]) * d
    W0 = np.array([th.beverloo_2d(x, d, rho, g, 0.6, 1.4, t) for x in D])
    err = 0.02 * W0
    rng = np.random.default_rng(7)
    fixed, free = [], []
    for _ in range(600):
        W = W0 + err * rng.standard_normal(D.size)
        fixed.append(th.fit_beverloo_three_halves(D, W, d, rho, g, t, W_err=err))
        free.append(th.fit_beverloo_free(D, W, err, d, rho, g, t))
    exact_fixed = th.fit_beverloo_three_halves(D, W0, d, rho, g, t, W_err=err)
    exact_free = th.fit_beverloo_free(D, W0, err, d, rho, g, t)
    assert (exact_fixed.C, exact_fixed.k) == pytest.approx((0.6, 1.4), rel=1e-9)
    assert (exact_free.C, exact_free.k, exact_free.b) == pytest.approx((0.6, 1.4, 1.5), rel=1e-6)
    for fits, exact, names in ((fixed, exact_fixed, ("C", "k")),
                               (free, exact_free, ("C", "k", "b"))):
        for name in names:
            spread = np.std([getattr(f, name) for f in fits], ddof=1)
            assert getattr(exact, f"{name}_err") == pytest.approx(spread, rel=0.10), name


def test_beverloo_fit_without_rate_errors_takes_its_errors_from_three_widths_scatter():
    """Without W_err the straight line W^(2/3) against D takes its errors from the scatter
    about it, with N - 2 degrees of freedom, from three widths on (it reported NaN below
    four). Over 4000 sets of three rates with the same Gaussian noise in each W^(2/3) (the
    least squares' own assumption; 1 % of their mean), the mean reported
    variance of the slope's constant C equals the variance of the fitted C (an unbiased
    estimate; its spread over 4000 draws is about 4 %, and C ~ slope^(3/2) is mildly
    non-linear), and k likewise: within 10 % in the standard deviations."""
    d, rho, g, t = 0.01, 2000.0, 9.81, 0.01
    D = np.array([8.0, 13.0, 20.0]) * d
    y0 = np.array([th.beverloo_2d(x, d, rho, g, 0.6, 1.4, t) for x in D]) ** (2.0 / 3.0)
    rng = np.random.default_rng(11)
    noise = 0.01 * y0.mean()
    fits = [th.fit_beverloo_three_halves(
        D, (y0 + noise * rng.standard_normal(3)) ** 1.5, d, rho, g, t) for _ in range(4000)]
    for name in ("C", "k"):
        values = np.array([getattr(f, name) for f in fits])
        reported = np.array([getattr(f, f"{name}_err") for f in fits])
        assert np.all(np.isfinite(reported))
        assert math.sqrt(np.mean(reported**2)) == pytest.approx(np.std(values, ddof=1),
                                                                rel=0.10), name


def test_en1991_4_discharge_magnifies_the_janssen_filling_load():
    z = np.linspace(0.0, 5.0, 11)
    p_h, p_w, p_v = th.en1991_4_filling(z, GAMMA, 0.5, 0.4, 1.7)
    np.testing.assert_allclose(p_h, th.janssen_sigma_h(z, RHO_B, G, 3.4, 0.5, 0.4), rtol=1e-12)
    np.testing.assert_allclose(p_v, th.janssen_sigma_v(z, RHO_B, G, 3.4, 0.5, 0.4), rtol=1e-12)
    p_he, p_we = th.en1991_4_discharge(z, GAMMA, 0.5, 0.4, 1.7)
    # the discharge factors of slender silos, EN 1991-4:2006 §5.2.2.2: C_h = 1.15, C_w = 1.10
    np.testing.assert_allclose(p_he, 1.15 * p_h)
    np.testing.assert_allclose(p_we, 1.10 * p_w)


@pytest.mark.parametrize(("K", "mu", "A_over_U", "phi_r", "h_o"), [
    (0.5, 0.4, 1.7, 25.0, 0.0),        # a levelled top
    (0.5, 0.445, 1.7, 30.0, 0.25),     # the heap of a 3.4 m silo at about 30 deg
    (0.6, 0.3, 1.0, 45.0, 2.777777777777778),  # n = -1: h_o / z_o = tan / (1 + tan) = 1/2
])
def test_en1991_4_squat_filling_solves_the_slice_balance(K, mu, A_over_U, phi_r, h_o):
    """§5.3.1.1: the vertical stress gamma z_V and the wall friction mu p_hf of the standard
    must satisfy the slice balance A d(p_v)/dz = gamma A - U mu p_h, integrated numerically
    from p_v = gamma h_o at the highest wall contact; p_h is 0 there and tends to
    p_ho = gamma A / (U mu) far down (the walls then carry the whole weight)."""
    z_end = 12.0

    def slope(z, s):
        p_h, _, _ = th.en1991_4_filling_squat(z, GAMMA, K, mu, A_over_U, phi_r, h_o)
        return [GAMMA - mu * float(p_h) / A_over_U]

    sol = solve_ivp(slope, (h_o, z_end), [GAMMA * h_o], rtol=1e-11, atol=1e-8,
                    dense_output=True)
    z = np.linspace(h_o, z_end, 30)
    p_h, p_w, p_v = th.en1991_4_filling_squat(z, GAMMA, K, mu, A_over_U, phi_r, h_o)
    np.testing.assert_allclose(p_v, sol.sol(z)[0], rtol=1e-7)
    np.testing.assert_allclose(p_w, mu * p_h, rtol=1e-14)
    assert p_h[0] == 0.0
    deep, _, _ = th.en1991_4_filling_squat(1e7, GAMMA, K, mu, A_over_U, phi_r, h_o)
    assert float(deep) == pytest.approx(GAMMA * A_over_U / mu, rel=1e-3)
    # above the highest wall contact the walls carry nothing and p_v is the weight above
    top = np.linspace(0.0, h_o, 5)
    p_h, p_w, p_v = th.en1991_4_filling_squat(top, GAMMA, K, mu, A_over_U, phi_r, h_o)
    assert np.all(p_h == 0.0) and np.all(p_w == 0.0)
    np.testing.assert_allclose(p_v, GAMMA * top, rtol=1e-14)


def test_en1991_4_squat_filling_hand_worked_below_a_heap():
    """§5.3.1.1 by hand, h_o > 0 (the slice-balance test above cannot see a wrong n or Y_R,
    as p_h and z_V share them): K = 0.5, mu = 0.4, A/U = 1.7 give z_o = 8.5 m; h_o = 1.7 m
    = z_o / 5 and phi_r = 45 deg give n = -(1 + 1)(1 - 1/5) = -1.6.  At z = 8.5 m
    (z - h_o)/(z_o - h_o) + 1 = 2: Y_R = 1 - 2^-1.6 = 0.670123,
    z_V = 1.7 - (6.8 - 13.6^-0.6 / 6.8^-1.6) / (-0.6) = 1.7 + 6.8 (1 - 2^-0.6) / 0.6 = 5.556122;
    at z = 22.1 m the bracket is 4: Y_R = 1 - 4^-1.6 = 0.891181, z_V = 8.100213."""
    p_ho = GAMMA * 0.5 * 8.5
    p_h, p_w, p_v = th.en1991_4_filling_squat([8.5, 22.1], GAMMA, 0.5, 0.4, 1.7, 45.0, 1.7)
    np.testing.assert_allclose(p_h, p_ho * np.array([0.670123, 0.891181]), rtol=1e-6)
    np.testing.assert_allclose(p_w, 0.4 * p_ho * np.array([0.670123, 0.891181]), rtol=1e-6)
    np.testing.assert_allclose(p_v, GAMMA * np.array([5.556122, 8.100213]), rtol=1e-6)


@pytest.mark.parametrize("phi_r", [1e-9, 1e-6, 0.0])
def test_en1991_4_squat_filling_is_continuous_at_n_minus_1(phi_r):
    """With h_o = 0 and phi_r -> 0, n -> -1 and z_V -> z_o ln(1 + z / z_o) (the slice balance
    with Y_R = 1 - z_o / (z + z_o), integrated by hand): no cancellation just off n = -1."""
    K, mu, A_over_U, z = 0.5, 0.4, 1.7, np.array([0.5, 3.0, 20.0])
    z_o = A_over_U / (K * mu)
    _, _, p_v = th.en1991_4_filling_squat(z, GAMMA, K, mu, A_over_U, phi_r, 0.0)
    np.testing.assert_allclose(p_v, GAMMA * z_o * np.log1p(z / z_o), rtol=1e-7)


def test_en1991_4_squat_filling_refuses_a_heap_deeper_than_z_o():
    with pytest.raises(ValueError, match="h_o"):  # z_o = 1.7 / (0.5 * 0.4) = 8.5 m
        th.en1991_4_filling_squat(1.0, GAMMA, 0.5, 0.4, 1.7, 30.0, 8.5)


@pytest.mark.parametrize("phi_r", [10.0, 30.0, 40.0])
def test_en1991_4_h_o_is_the_level_of_a_heap_of_equal_volume(phi_r):
    """h_o is the height above the wall contacts of the level surface holding the same volume
    as the heap at the angle of repose: integrate the heap profile numerically (planar: over
    the width; circular: over the area of a disk of radius r)."""
    d_c, tan = 3.4, math.tan(math.radians(phi_r))
    x = np.linspace(0.0, d_c / 2, 200_001)
    heap = (d_c / 2 - x) * tan  # height above the wall contacts at the distance x from the axis
    planar = trapezoid(heap, x) / (d_c / 2)
    circular = trapezoid(heap * 2 * np.pi * x, x) / (np.pi * (d_c / 2) ** 2)
    assert th.en1991_4_h_o(d_c, phi_r) == pytest.approx(planar, rel=1e-9)
    assert th.en1991_4_h_o(d_c, phi_r, planar=False) == pytest.approx(circular, rel=1e-9)


@pytest.mark.parametrize(("h_c", "C_h", "C_w"), [
    (3.4, 1.0, 1.0),                # squat: the discharge loads are the filling loads
    (1.5 * 3.4, 1.075, 1.05),       # intermediate: C_S = h_c/d_c - 1 = 0.5
    (1.999999 * 3.4, 1.15, 1.10),   # ... meeting the slender values at h_c/d_c = 2
    (2.0 * 3.4, 1.15, 1.10),        # slender, §5.2.2.2
    (5.0 * 3.4, 1.15, 1.10),
])
def test_en1991_4_discharge_factors_by_class(h_c, C_h, C_w):
    """EN 1991-4:2006 §5.2.2.2 (slender: 1.15, 1.10) and §5.3.2.2 (intermediate: 1 + 0.15 C_S,
    1 + 0.1 C_S with C_S = h_c/d_c - 1; squat: 1): values worked by hand from the text, and
    continuous at the class limits."""
    got = th.en1991_4_discharge_factors(h_c, 3.4, flat_bottom=True)
    assert got == pytest.approx((C_h, C_w), abs=1e-6)


def test_en1991_4_discharge_factors_refuse_a_retaining_silo():
    with pytest.raises(ValueError, match="retaining"):
        th.en1991_4_discharge_factors(1.0, 3.4, flat_bottom=True)


@pytest.mark.parametrize(("h_c", "d_c", "kind"), [
    (6.8, 3.4, "slender"), (10.0, 3.4, "slender"),          # h_c/d_c >= 2
    (4.0, 3.4, "intermediate"), (6.7, 3.4, "intermediate"),  # 1 < h_c/d_c < 2: paper case 2
    (3.4, 3.4, "squat"), (1.5, 3.4, "squat"),                # 0.4 < h_c/d_c <= 1
    (1.36, 3.4, "retaining"), (0.5, 3.4, "retaining"),       # flat bottom, h_c/d_c <= 0.4
])
def test_en1991_4_slenderness_classes(h_c, d_c, kind):
    # the class limits of EN 1991-4:2006 §1.5 (slender >= 2, squat <= 1, retaining: a flat
    # bottom and <= 0.4; with a hopper a silo that low is squat)
    assert th.en1991_4_slenderness(h_c, d_c, flat_bottom=True) == kind
    hopper = "squat" if kind == "retaining" else kind
    assert th.en1991_4_slenderness(h_c, d_c, flat_bottom=False) == hopper


def test_en1991_4_slenderness_refuses_a_silo_without_walls():
    with pytest.raises(ValueError, match="positive"):
        th.en1991_4_slenderness(0.0, 3.4, flat_bottom=True)


# EN 1991-4 §6, hopper loads: (beta from the vertical, K, mu_h, S) in both classes
HOPPERS = [
    (20.0, 0.5, 0.4, 2),  # steep cone: 2 mu_h tan(beta) = 0.29 < 1 - K
    (20.0, 0.5, 0.4, 1),  # steep wedge
    (40.0, 0.55, math.tan(math.radians(24.0)), 1),  # shallow wedge (the report's tiny hopper)
    (45.0, 0.45, 0.458, 2),  # shallow cone: 2 mu_h tan(beta) = 0.92 > 1 - K
]


def _en_mu_eff_and_F_f(beta, K, mu_h):
    """mu_eff and F_f as EN 1991-4 prints them: mu_h in a steep hopper (tan(beta) < (1 - K) /
    (2 mu_h)), mu_heff = (1 - K) / (2 tan(beta)) in a shallow one; F_f = 1 - b / (1 + tan(beta)
    / mu_eff), b = 0.2."""
    t = math.tan(math.radians(beta))
    mu = mu_h if t < (1.0 - K) / (2.0 * mu_h) else (1.0 - K) / (2.0 * t)
    return mu, 1.0 - 0.2 / (1.0 + t / mu)


@pytest.mark.parametrize(("beta", "K", "mu_h", "S"), HOPPERS)
def test_en1991_4_hopper_filling_is_the_standards_p_v_and_solves_the_slice_balance(beta, K,
                                                                                    mu_h, S):
    """§6.3.2 / §6.4.2: p_v as the standard prints it, gamma h_h / (n - 1) [x/h_h - (x/h_h)^n]
    + p_vft (x/h_h)^n with n = S (1 - b) mu_eff cot(beta), and the same p_v from the slice
    balance of a wedge (S = 1) or a cone (S = 2) with p_n = F_f p_v, integrated numerically
    from p_vft at the transition; p_n = F_f p_v and p_t = mu_eff p_n."""
    h_h, p_vft = 2.5, 9000.0
    mu, F_f = _en_mu_eff_and_F_f(beta, K, mu_h)
    n = S * 0.8 * mu / math.tan(math.radians(beta))
    x = np.linspace(h_h, 0.3, 25)
    r = x / h_h
    printed = GAMMA * h_h / (n - 1.0) * (r - r**n) + p_vft * r**n
    sol = solve_ivp(_slice_ode(beta, mu, F_f, S == 1), (h_h, 0.3), [p_vft], method="DOP853",
                    rtol=1e-12, atol=1e-10, dense_output=True)
    load = th.en1991_4_hopper_filling(x, h_h, p_vft, GAMMA, beta, K, mu_h, planar=S == 1)
    assert load.kind == ("steep" if mu == mu_h else "shallow")
    assert (load.mu_eff, load.F) == (pytest.approx(mu, rel=1e-14), pytest.approx(F_f, rel=1e-14))
    assert load.n == pytest.approx(n, rel=1e-12)
    np.testing.assert_allclose(load.p_v, printed, rtol=1e-10)
    np.testing.assert_allclose(load.p_v, sol.sol(x)[0], rtol=1e-7)
    np.testing.assert_allclose(load.p_n, F_f * printed, rtol=1e-10)
    np.testing.assert_allclose(load.p_t, mu * F_f * printed, rtol=1e-10)


def test_en1991_4_hopper_filling_hand_worked():
    """A steep cone, beta = 20 deg, K = 0.5, mu_h = 0.4: tan 20 = 0.363970, so
    F_f = 1 - 0.2 / (1 + 0.909924) = 0.895284 and n = 2 (0.8)(0.4) / 0.363970 = 1.758386.
    At x = h_h / 2 with h_h = 2 m, p_vft = 10 kPa and gamma = 6867 N/m^3:
    p_v = 6867 * 2 / 0.758386 (0.5 - 0.5^1.758386) + 10000 * 0.5^1.758386
    = 18109.52 (0.5 - 0.295579) + 2955.79 = 6657.76 Pa, p_nf = 5960.58 Pa."""
    load = th.en1991_4_hopper_filling(1.0, 2.0, 1.0e4, GAMMA, 20.0, 0.5, 0.4, planar=False)
    assert (load.F, load.n) == (pytest.approx(0.895284, rel=1e-6),
                                pytest.approx(1.758386, rel=1e-6))
    assert float(load.p_v) == pytest.approx(6657.76, rel=1e-6)
    assert float(load.p_n) == pytest.approx(5960.58, rel=1e-6)


@pytest.mark.parametrize(("beta", "K", "mu_h", "S"), HOPPERS[:2])
@pytest.mark.parametrize("phi_i", [30.0, 42.0])
def test_en1991_4_steep_hopper_discharge_uses_the_standards_F_e(beta, K, mu_h, S, phi_i):
    """§6.3.3: F_e = (1 + sin(phi_i) cos(eps)) / (1 - sin(phi_i) cos(2 beta + eps)), eps =
    phi_wh + arcsin(sin(phi_wh) / sin(phi_i)), phi_wh = arctan(mu_h), as printed; p_ne =
    F_e p_v with p_v from the slice balance with p_n = F_e p_v (integrated numerically)."""
    h_h, p_vft = 2.5, 9000.0
    s, phi_wh = math.sin(math.radians(phi_i)), math.atan(mu_h)
    eps = phi_wh + math.asin(math.sin(phi_wh) / s)
    F_e = (1 + s * math.cos(eps)) / (1 - s * math.cos(2 * math.radians(beta) + eps))
    x = np.linspace(h_h, 0.3, 25)
    sol = solve_ivp(_slice_ode(beta, mu_h, F_e, S == 1), (h_h, 0.3), [p_vft], method="DOP853",
                    rtol=1e-12, atol=1e-10, dense_output=True)
    load = th.en1991_4_hopper_discharge(x, h_h, p_vft, GAMMA, beta, K, mu_h, phi_i,
                                        planar=S == 1)
    assert load.kind == "steep" and load.F == pytest.approx(F_e, rel=1e-12)
    np.testing.assert_allclose(load.p_n, F_e * sol.sol(x)[0], rtol=1e-7)
    np.testing.assert_allclose(load.p_t, mu_h * load.p_n, rtol=1e-14)


@pytest.mark.parametrize(("beta", "K", "mu_h", "S"), HOPPERS[2:])
def test_en1991_4_shallow_hopper_discharges_with_its_filling_loads(beta, K, mu_h, S):
    """§6.4.3: a shallow hopper's discharge loads are its filling loads (phi_i plays no part)."""
    x = np.linspace(0.3, 2.5, 9)
    fill = th.en1991_4_hopper_filling(x, 2.5, 9000.0, GAMMA, beta, K, mu_h, S == 1)
    dis = th.en1991_4_hopper_discharge(x, 2.5, 9000.0, GAMMA, beta, K, mu_h, 35.0, S == 1)
    assert dis.kind == fill.kind == "shallow"
    np.testing.assert_array_equal(dis.p_n, fill.p_n)


def test_en1991_4_hopper_classes_meet_at_the_steep_limit():
    """At tan(beta) = (1 - K) / (2 mu_h) the mobilised friction of a shallow hopper, (1 - K) /
    (2 tan(beta)), is mu_h: the loads of the two classes agree on either side of the limit."""
    K, mu_h = 0.5, 0.4
    limit = math.degrees(math.atan((1 - K) / (2 * mu_h)))
    below = th.en1991_4_hopper_filling(1.0, 2.0, 1e4, GAMMA, limit - 1e-7, K, mu_h)
    above = th.en1991_4_hopper_filling(1.0, 2.0, 1e4, GAMMA, limit + 1e-7, K, mu_h)
    assert (below.kind, above.kind) == ("steep", "shallow")
    assert above.mu_eff == pytest.approx(mu_h, rel=1e-6)
    assert float(above.p_n) == pytest.approx(float(below.p_n), rel=1e-6)
    # flat: walls within 5 deg of the horizontal (beta > 85 deg from the vertical)
    assert th.en1991_4_hopper_kind(85.1, K, mu_h) == "flat"
    assert th.en1991_4_hopper_kind(84.9, K, mu_h) == "shallow"


def test_en1991_4_hopper_loads_refuse_a_flat_bottom_and_a_shallow_hopper_with_K_1():
    with pytest.raises(ValueError, match="flat bottom"):
        th.en1991_4_hopper_filling(1.0, 2.0, 1e4, GAMMA, 87.0, 0.5, 0.4)
    with pytest.raises(ValueError, match="K < 1"):  # K >= 1: never steep, mu_heff <= 0
        th.en1991_4_hopper_filling(1.0, 2.0, 1e4, GAMMA, 45.0, 1.3, 0.4)


def test_en1991_4_phi_i_from_K():
    """K = 1.1 (1 - sin(phi_i)): K = 0.55 is sin(phi_i) = 1/2, phi_i = 30 deg; none for
    K >= 1.1."""
    assert th.en1991_4_phi_i_from_K(0.55) == pytest.approx(30.0, rel=1e-12)
    assert math.isnan(th.en1991_4_phi_i_from_K(1.32))


def test_beverloo_free_fit_starts_inside_its_bounds_for_outlets_near_one_diameter():
    """k is bounded above by 0.95 min(D)/d; with the narrowest outlet at 1 d that bound is
    0.95, under the usual start k = 1, which scipy refuses.  Exact rates of the law
    (C = 0.6, k = 0.5, b = 3/2) must be fitted back."""
    d, rho, g, t = 0.01, 700.0, 9.81, 0.01
    D = d * np.array([1.0, 1.5, 2.0, 3.0, 4.0, 6.0])
    W = np.array([th.beverloo_2d(x, d, rho, g, 0.6, 0.5, t) for x in D])
    fit = th.fit_beverloo_free(D, W, 0.01 * W, d, rho, g, t)
    assert (fit.C, fit.k, fit.b) == pytest.approx((0.6, 0.5, 1.5), rel=1e-6)


def test_beverloo_fit_refuses_rates_that_do_not_grow_with_the_outlet():
    D = np.array([0.05, 0.08, 0.12])
    with pytest.raises(ValueError, match="do not grow"):
        th.fit_beverloo_three_halves(D, np.array([3.0, 2.0, 1.0]), 0.01, 700.0, 9.81, 0.01)


@pytest.mark.parametrize("F, mu, beta", [(1.44, 0.3, 20.0), (1.1, 0.0, 35.0), (2.0, 0.6, 10.0)])
def test_en1991_4_printed_exponent_is_the_cone_slice_balance_and_one_less_for_a_wedge(F, mu,
                                                                                      beta):
    """EN 1991-4:2006 §6.3.1 prints n = S (F mu cot(beta) + F) - 2: for a cone (S = 2) the
    slice balance's 2 [F (1 + mu cot(beta)) - 1] (Walker's with D = F), for a wedge (S = 1)
    one less than the slice balance's F (1 + mu cot(beta)) - 1, which the hopper loads use."""
    cot = 1.0 / math.tan(math.radians(beta))
    assert th.en1991_4_printed_exponent(F, mu, beta, planar=False) == pytest.approx(
        2 * (F * (1 + mu * cot) - 1), rel=1e-12)
    assert th.en1991_4_printed_exponent(F, mu, beta) == pytest.approx(
        F * (1 + mu * cot) - 2, rel=1e-12)
    load = th.en1991_4_hopper_discharge(1.0, 2.0, 3e4, 16e3, beta, 0.2, mu, 60.0)
    assert load.n == pytest.approx(th.en1991_4_printed_exponent(load.F, mu, beta) + 1,
                                   rel=1e-12)


@pytest.mark.parametrize("n_i", [1e-10, 1e-11, 2e-12, -3e-11])
def test_paper_eq12_keeps_its_precision_next_to_n_i_0(n_i):
    """Just outside the switch to the n_i = 0 limit, eq. (12) as printed cancels: at n_i =
    1e-11 it lost 1.7e-5 of sigma.  It equals the conical Walker form (D = 1), which has no
    such cancellation, to 1e-12.  mu_w = tan(alpha) (1 + n_i) / 2 sets n_i."""
    alpha, H, q = 45.0, 1.7, 12000.0
    mu = math.tan(math.radians(alpha)) * (1.0 + n_i) / 2.0
    z = np.linspace(0.0, 1.2, 13)
    np.testing.assert_allclose(th.paper_eq12(z, H, q, GAMMA, alpha, mu),
                               th.hopper_sigma_v(H - z, H, q, GAMMA, alpha, mu, 1.0,
                                                 planar=False), rtol=1e-12)


def test_janssen_and_en1991_4_filling_of_nearly_frictionless_walls_are_hydrostatic():
    """A wall friction so small that 2 K mu_w / B (or K mu / (A/U)) is under 1e-304: Janssen's
    rho_b g B / (2 K mu_w) overflowed and sigma_v came back inf, and EN 1991-4's p_ho Y_J was
    inf x 0 = NaN.  Both are the hydrostatic load (to 1e-12): the walls carry nothing."""
    z = np.array([0.0, 0.5, 3.0, 40.0])
    for mu in (1e-305, 1e-309):
        np.testing.assert_allclose(th.janssen_sigma_v(z, 800.0, 9.81, 3.4, 0.4, mu),
                                   800.0 * 9.81 * z, rtol=1e-12)
        p_h, _, p_v = th.en1991_4_filling(z, GAMMA, 0.4, mu, 1.7)
        np.testing.assert_allclose(p_v, GAMMA * z, rtol=1e-12)
        np.testing.assert_allclose(p_h, 0.4 * GAMMA * z, rtol=1e-12)


@pytest.mark.parametrize("mu", [1e-9, 1e-12, 1e-15])
def test_en1991_4_squat_filling_of_a_smooth_wall_keeps_its_precision(mu):
    """With a smooth wall z_o = A / (K mu U) is huge and x = z / z_o tiny; 1 - (1 + x)^n formed
    from 1 + x lost 3.5e-4 of p_h at mu = 1e-12 (and p_v rose above the hydrostatic gamma z),
    all of it at 1e-15.  The series in x of the standard's formulas (h_o = 0, n = -(1 + tan
    phi_r)): p_h = gamma K z (-n) (1 + (n - 1) x / 2 + ...), p_v = gamma z (1 + n x / 2 + ...),
    so p_v never exceeds gamma z."""
    K, A_over_U, phi_r = 0.4, 1.7, 24.0
    n = -(1.0 + math.tan(math.radians(phi_r)))
    z = np.array([0.01, 1.0, 10.0])
    x = z * K * mu / A_over_U
    p_h, _, p_v = th.en1991_4_filling_squat(z, GAMMA, K, mu, A_over_U, phi_r, 0.0)
    np.testing.assert_allclose(p_h, GAMMA * K * z * -n * (1.0 + (n - 1.0) * x / 2.0),
                               rtol=1e-12)
    np.testing.assert_allclose(p_v, GAMMA * z * (1.0 + n * x / 2.0), rtol=1e-12)
    assert np.all(p_v <= GAMMA * z)
