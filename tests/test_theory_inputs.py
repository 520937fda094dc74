"""Bad input to silodem.theory: a one-line ValueError that names the function and the argument,
never a deep traceback from numpy, scipy or math, nor a silent wrong number; and the edge
values the report, study and validation code pass still accepted."""

from __future__ import annotations

import math

import numpy as np
import pytest

from silodem import theory as th

NAN = float("nan")
G = 700.0 * 9.81
Z = np.linspace(0.0, 4.0, 9)
SH = th.janssen_sigma_h(Z[1:], 700.0, 9.81, 3.4, 0.4, 0.45)
X = np.linspace(0.0, 2.0, 9)  # heights above a hopper's apex, h_h = 2
DW = np.array([0.06, 0.08, 0.1, 0.13, 0.17])  # outlet widths [m], grains d = 0.01
WW = np.array([th.beverloo_2d(x, 0.01, 2000.0, 9.81, 0.6, 1.4, 0.01) for x in DW])


def _args(base, **changes):
    return {**base, **changes}


JANSSEN = {"depth": Z, "rho_b": 700.0, "g": 9.81, "B": 3.4, "K": 0.4, "mu_w": 0.45}
FIT_J = {"depth": Z[1:], "sigma_h": SH, "rho_b": 700.0, "g": 9.81, "B": 3.4}
SLICE = {"h": X, "H": 2.0, "q": 9000.0, "gamma": G, "alpha_deg": 30.0, "mu_w": 0.3}
EQ12 = {"z_below_transition": X, "h_prime": 2.0, "q": 9000.0, "gamma": G, "alpha_deg": 30.0,
        "mu_w": 0.3}
WDF = {"delta_deg": 30.0, "phi_w_deg": 20.0, "alpha_deg": 25.0}
HOPPER = {"x": X, "h_h": 2.0, "p_vft": 9000.0, "gamma": G, "beta_deg": 20.0, "K": 0.5,
          "mu_h": 0.3}  # steep: 2 mu_h tan(beta) = 0.22 < 1 - K; arctan(mu_h) = 16.7 deg
DISCHARGE = {**HOPPER, "phi_i_deg": 35.0}
WALL = {"depth": Z, "gamma": G, "K": 0.5, "mu": 0.4, "A_over_U": 1.7}
SQUAT = {**WALL, "phi_r_deg": 30.0, "h_o": 0.2}
BEV = {"D": 0.1, "d": 0.01, "rho_b": 2000.0, "g": 9.81, "C": 0.6, "k": 1.4, "thickness": 0.01}
BEV_C = {"rate": 1.0, **{k: v for k, v in BEV.items() if k != "C"}}
FREE = {"D": DW, "W": WW, "W_err": 0.02 * WW, "d": 0.01, "rho_b": 2000.0, "g": 9.81, "t": 0.01}
THREE = {k: v for k, v in FREE.items() if k != "W_err"}

# (function, keyword arguments, the argument named at the start of the message)
BAD = [
    *[(f, _args(JANSSEN, **change), name)
      for f in ("janssen_sigma_v", "janssen_sigma_h", "janssen_wall_shear")
      for name, change in [
          ("B", {"B": 0.0}), ("B", {"B": -3.4}), ("B", {"B": NAN}),
          ("K", {"K": 0.0}), ("K", {"K": -0.4}), ("K", {"K": np.array([0.4, 0.5])}),
          ("mu_w", {"mu_w": -0.1}), ("mu_w", {"mu_w": NAN}),
          ("rho_b", {"rho_b": -700.0}), ("g", {"g": -9.81}), ("g", {"g": True}),
          ("depth", {"depth": "deep"}), ("depth", {"depth": None})]],
    ("fit_janssen", _args(FIT_J, rho_b=0.0), "rho_b"),
    ("fit_janssen", _args(FIT_J, g=0.0), "g"),
    ("fit_janssen", _args(FIT_J, B=0.0), "B"),
    ("fit_janssen", _args(FIT_J, B=NAN), "B"),
    ("fit_janssen", _args(FIT_J, mu_w=-0.1), "mu_w"),
    ("fit_janssen", _args(FIT_J, mu_w=NAN), "mu_w"),
    ("fit_janssen", _args(FIT_J, sigma_h=SH[:-1]), "depth and sigma_h"),
    ("fit_janssen", _args(FIT_J, sigma_h=["a"] * SH.size), "sigma_h"),
    # Walker's slice method
    ("alpha_from_theta", {"theta_from_horizontal_deg": -10.0}, "theta_from_horizontal_deg"),
    ("alpha_from_theta", {"theta_from_horizontal_deg": 100.0}, "theta_from_horizontal_deg"),
    ("alpha_from_theta", {"theta_from_horizontal_deg": "45"}, "theta_from_horizontal_deg"),
    *[("apex_below_outlet", {"outlet_width": 0.5, "alpha_deg": a}, "alpha_deg")
      for a in (0.0, -30.0, 90.0, 180.0, 200.0)],
    ("apex_below_outlet", {"outlet_width": -0.5, "alpha_deg": 30.0}, "outlet_width"),
    ("walker_exponent", {"alpha_deg": 0.0, "mu_w": 0.3}, "alpha_deg"),
    ("walker_exponent", {"alpha_deg": 200.0, "mu_w": 0.3}, "alpha_deg"),
    ("walker_exponent", {"alpha_deg": 30.0, "mu_w": -0.3}, "mu_w"),
    ("walker_exponent", {"alpha_deg": 30.0, "mu_w": 0.3, "D": 0.0}, "D"),
    ("walker_exponent", {"alpha_deg": 30.0, "mu_w": 0.3, "planar": "no"}, "planar"),
    ("walker_exponent", {"alpha_deg": 30.0, "mu_w": 0.3, "planar": 1}, "planar"),
    *[(f, _args(SLICE, **change), name)
      for f in ("hopper_sigma_v", "hopper_wall_normal")
      for name, change in [
          ("alpha_deg", {"alpha_deg": 0.0}), ("alpha_deg", {"alpha_deg": -30.0}),
          ("alpha_deg", {"alpha_deg": 180.0}), ("H", {"H": 0.0}), ("H", {"H": -2.0}),
          ("h", {"h": X + 0.5}), ("h", {"h": X - 0.5}), ("h", {"h": NAN}),
          ("q", {"q": NAN}), ("gamma", {"gamma": -G}), ("D", {"D": -1.0}),
          ("planar", {"planar": "no"})]],
    ("paper_eq12", _args(EQ12, z_below_transition=2.5), "z_below_transition"),
    ("paper_eq12", _args(EQ12, z_below_transition=-0.1), "z_below_transition"),
    ("paper_eq12", _args(EQ12, h_prime=0.0), "h_prime"),
    ("paper_eq12", _args(EQ12, alpha_deg=0.0), "alpha_deg"),
    ("paper_eq12", _args(EQ12, gamma=0.0), "gamma"),
    ("paper_eq12", _args(EQ12, mu_w=-0.3), "mu_w"),
    ("walker_distribution_factor", _args(WDF, delta_deg=0.0, phi_w_deg=0.0), "delta_deg"),
    ("walker_distribution_factor", _args(WDF, delta_deg=-40.0), "delta_deg"),
    ("walker_distribution_factor", _args(WDF, delta_deg=100.0), "delta_deg"),
    ("walker_distribution_factor", _args(WDF, phi_w_deg=-20.0), "phi_w_deg"),
    ("walker_distribution_factor", _args(WDF, phi_w_deg=40.0), "phi_w_deg"),
    ("walker_distribution_factor", _args(WDF, alpha_deg=-5.0), "alpha_deg"),
    ("walker_distribution_factor", _args(WDF, alpha_deg=90.0), "alpha_deg"),
    # EN 1991-4, the hopper
    ("en1991_4_hopper_kind", {"beta_deg": 30.0, "K": 0.5, "mu_h": NAN}, "mu_h"),
    ("en1991_4_hopper_kind", {"beta_deg": 30.0, "K": NAN, "mu_h": 0.4}, "K"),
    ("en1991_4_hopper_kind", {"beta_deg": 30.0, "K": -0.5, "mu_h": 0.4}, "K"),
    ("en1991_4_hopper_kind", {"beta_deg": 30.0, "K": 0.5, "mu_h": -0.4}, "mu_h"),
    ("en1991_4_hopper_kind", {"beta_deg": 0.0, "K": 0.5, "mu_h": 0.4}, "beta_deg"),
    *[(f, _args(HOPPER if "filling" in f else DISCHARGE, **change), name)
      for f in ("en1991_4_hopper_filling", "en1991_4_hopper_discharge")
      for name, change in [
          ("mu_h", {"mu_h": NAN}), ("K", {"K": NAN}), ("K", {"K": 0.0}),
          ("beta_deg", {"beta_deg": 90.0}), ("b", {"b": 5.0}), ("b", {"b": 1.0}),
          ("b", {"b": -0.1}), ("h_h", {"h_h": 0.0}), ("x", {"x": X + 0.1}),
          ("x", {"x": -0.1}), ("p_vft", {"p_vft": -1.0}), ("gamma", {"gamma": -G}),
          ("planar", {"planar": "no"})]],
    *[("en1991_4_hopper_discharge", _args(DISCHARGE, phi_i_deg=phi), "phi_i_deg")
      for phi in (10.0, 0.0, -35.0, NAN, 90.0)],
    # EN 1991-4, the vertical walls
    *[(f, _args(WALL, **change), name)
      for f in ("en1991_4_filling", "en1991_4_discharge")
      for name, change in [
          ("K", {"K": 0.0}), ("K", {"K": -0.5}), ("mu", {"mu": 0.0}),
          ("A_over_U", {"A_over_U": 0.0}), ("A_over_U", {"A_over_U": -1.7}),
          ("gamma", {"gamma": -G}), ("depth", {"depth": "deep"})]],
    ("en1991_4_discharge", _args(WALL, C_h=0.5), "C_h"),
    ("en1991_4_discharge", _args(WALL, C_w=-1.0), "C_w"),
    ("en1991_4_filling_squat", _args(SQUAT, K=-0.5), "K"),
    ("en1991_4_filling_squat", _args(SQUAT, A_over_U=-1.7), "A_over_U"),
    ("en1991_4_filling_squat", _args(SQUAT, mu=0.0), "mu"),
    ("en1991_4_filling_squat", _args(SQUAT, phi_r_deg=90.0), "phi_r_deg"),
    ("en1991_4_filling_squat", _args(SQUAT, phi_r_deg=-10.0), "phi_r_deg"),
    ("en1991_4_filling_squat", _args(SQUAT, h_o=NAN), "h_o"),
    ("en1991_4_filling_squat", _args(SQUAT, h_o=-1.0), "h_o"),
    ("en1991_4_filling_squat", _args(SQUAT, h_o=8.5), "h_o"),  # z_o = 1.7 / 0.2 = 8.5 m
    *[("en1991_4_h_o", {"d_c": 2.0, "phi_r_deg": phi}, "phi_r_deg")
      for phi in (90.0, 100.0, -30.0)],
    ("en1991_4_h_o", {"d_c": 0.0, "phi_r_deg": 30.0}, "d_c"),
    ("en1991_4_h_o", {"d_c": 2.0, "phi_r_deg": 30.0, "planar": "no"}, "planar"),
    ("en1991_4_slenderness", {"h_c": 1.0, "d_c": 5.0, "flat_bottom": "no"}, "flat_bottom"),
    ("en1991_4_slenderness", {"h_c": NAN, "d_c": 5.0, "flat_bottom": True}, "h_c"),
    ("en1991_4_slenderness", {"h_c": 1.0, "d_c": 0.0, "flat_bottom": True}, "d_c"),
    ("en1991_4_discharge_factors", {"h_c": 7.0, "d_c": 3.4, "flat_bottom": "no"},
     "flat_bottom"),
    ("en1991_4_discharge_factors", {"h_c": 7.0, "d_c": -3.4, "flat_bottom": True}, "d_c"),
    ("en1991_4_phi_i_from_K", {"K": NAN}, "K"),
    ("en1991_4_phi_i_from_K", {"K": "0.5"}, "K"),
    # Beverloo
    *[("beverloo_2d", _args(BEV, **change), name) for name, change in [
        ("g", {"g": -9.81}), ("D", {"D": np.array([0.1, 0.2])}), ("D", {"D": 0.0}),
        ("rho_b", {"rho_b": -2000.0}), ("thickness", {"thickness": -0.01}),
        ("C", {"C": -0.6}), ("d", {"d": 0.0}), ("k", {"k": NAN})]],
    ("beverloo_2d_C", _args(BEV_C, rate=NAN), "rate"),
    ("beverloo_2d_C", _args(BEV_C, g=-9.81), "g"),
    ("beverloo_2d_C", _args(BEV_C, D=np.array([0.1, 0.2])), "D"),
    *[("fit_beverloo_free", _args(FREE, **change), name) for name, change in [
        ("D must hold at least 4", {"D": DW[:2], "W": WW[:2], "W_err": WW[:2]}),
        ("D must hold at least 4", {"D": DW[:3], "W": WW[:3], "W_err": WW[:3]}),
        ("D must hold at least 4", {"D": [], "W": [], "W_err": []}),
        ("D must hold at least 4", {"D": [0.1, 0.1, 0.2, 0.2, 0.3], "W": WW}),
        ("D, W and W_err", {"D": np.append(DW, 0.3)}), ("W", {"W": np.where(DW > 0.1, WW, 0)}),
        ("W", {"W": np.where(DW > 0.1, WW, NAN)}), ("W_err", {"W_err": 0 * WW}),
        ("W_err", {"W_err": None}), ("D", {"D": -DW}), ("t", {"t": 0.0}),
        ("rho_b", {"rho_b": 0.0}), ("g", {"g": 0.0}), ("d", {"d": 0.0}),
        ("D", {"D": DW[None, :]})]],
    *[("fit_beverloo_three_halves", _args(THREE, **change), name) for name, change in [
        ("D must hold at least 2", {"D": [0.1], "W": [1.0]}),
        ("D must hold at least 2", {"D": [], "W": []}),
        ("D must hold at least 2", {"D": [0.1, 0.1, 0.1], "W": [1.0, 1.1, 1.2]}),
        ("D and W", {"W": WW[:-1]}), ("D, W and W_err", {"W_err": WW[:-1]}),
        ("W_err", {"W_err": np.full(DW.size, NAN)}), ("W", {"W": -WW}), ("d", {"d": 0.0}),
        ("t", {"t": 0.0}), ("rho_b", {"rho_b": -1.0}), ("g", {"g": NAN})]],
]


def _call(func, kwargs):
    return getattr(th, func)(**kwargs)


@pytest.mark.parametrize(("func", "kwargs", "name"), BAD,
                         ids=[f"{f}-{n}-{i}" for i, (f, _, n) in enumerate(BAD)])
def test_bad_input_is_refused_naming_the_function_and_the_argument(func, kwargs, name):
    with pytest.raises(ValueError, match=rf"^{func}: {name}\b"):
        _call(func, kwargs)


def test_every_refusal_is_one_line_with_the_value_got():
    for func, kwargs, name in BAD:
        with pytest.raises(ValueError) as err:
            _call(func, kwargs)
        message = str(err.value)
        assert "\n" not in message and len(message) < 200, message
        assert "; got " in message or name.startswith("D must hold") or "must have the same" \
            in message, message


def test_messages_say_what_is_allowed_and_what_came():
    with pytest.raises(ValueError) as err:
        th.janssen_sigma_v(1.0, 700.0, 9.81, 0.0, 0.4, 0.4)
    assert str(err.value) == "janssen_sigma_v: B must be a positive finite number; got 0.0"
    with pytest.raises(ValueError) as err:
        th.en1991_4_hopper_discharge(1.0, 2.0, 1e4, G, 20.0, 0.5, 0.3, 10)
    assert str(err.value) == ("en1991_4_hopper_discharge: phi_i_deg must be >= arctan(mu_h) = "
                              "16.7 deg in a steep hopper; got 10")
    with pytest.raises(ValueError, match="phi_w must not exceed delta"):
        th.walker_distribution_factor(30.0, 40.0, 10.0)
    with pytest.raises(ValueError, match=r"got 3$"):
        th.fit_beverloo_free(DW[:3], WW[:3], WW[:3], 0.01, 2000.0, 9.81, 0.01)
    with pytest.raises(ValueError, match=r"same length; got 4 and 3$"):
        th.fit_janssen(Z[1:5], SH[:3], 700.0, 9.81, 3.4)


def test_the_values_callers_pass_are_accepted():
    """Edge values the report, the study, the validation and silo.checks pass: g = 0 (the
    config allows it), smooth walls (mu_w = 0: hydrostatic), mu_w at the fit's bound, a large
    fitted K, heights exactly at the apex and at the transition, q = 0, a level top (phi_r =
    0), NumPy scalars and ints, NumPy bools as flags."""
    f64 = np.float64
    assert th.janssen_sigma_v(2.0, 700.0, 0.0, 3.4, 0.4, 0.45) == 0.0
    assert th.janssen_sigma_v(2.0, 700, 9.81, 3.4, 0.4, 0) == pytest.approx(700 * 9.81 * 2.0)
    assert np.all(np.isfinite(th.janssen_sigma_h(Z, f64(700), f64(9.81), 3, 50.0, 1e-6)))
    assert th.janssen_sigma_v(-1.0, 700.0, 9.81, 3.4, 0.4, 0.45) == 0.0  # above the surface
    h = np.array([0.0, 1.0, 2.0])
    assert np.all(np.isfinite(th.hopper_sigma_v(h, 2.0, 0.0, G, 30.0, 0.3)))
    assert np.isfinite(th.hopper_wall_normal(2.0, f64(2.0), -5.0, 0.0, f64(30), 0, 1.4, False))
    load = th.en1991_4_hopper_filling(h, 2.0, 0.0, G, 20.0, 0.5, 0.3, planar=np.bool_(True))
    assert load.p_v[-1] == 0.0 and np.all(np.isfinite(load.p_n))
    assert th.en1991_4_h_o(3.4, 0.0) == 0.0
    assert th.en1991_4_slenderness(7, 3, np.bool_(False)) == "slender"
    assert math.isnan(th.en1991_4_phi_i_from_K(1.32)) and math.isnan(th.en1991_4_phi_i_from_K(0))
    assert th.beverloo_2d(0.01, 0.01, 700.0, 9.81, 0.6, 1.4) == 0.0  # D <= k d: no flow
    assert th.beverloo_2d(0.1, 0.01, 700.0, 9.81, 0.6, -0.5) > 0.0  # a fitted k may be < 0
    assert math.isnan(th.beverloo_2d_C(1.0, 0.1, 0.01, 700.0, 0.0, 1.5))
    # fit_janssen leaves NaN points out on purpose
    z = np.append(Z[1:], [NAN, 2.0])
    s = np.append(SH, [1e3, NAN])
    assert th.fit_janssen(z, s, 700.0, 9.81, 3.4).n_points == SH.size


def test_shallow_hopper_discharge_needs_no_phi_i_above_phi_wh():
    """phi_i plays no part in a shallow hopper's discharge loads (its filling loads): a phi_i
    below arctan(mu_h) is refused only in a steep hopper."""
    x = np.linspace(0.3, 2.5, 5)
    dis = th.en1991_4_hopper_discharge(x, 2.5, 9000.0, G, 45.0, 0.45, 0.458, 10.0, False)
    assert dis.kind == "shallow"


def test_the_slice_stress_at_the_apex_of_a_hopper_with_n_below_zero_is_infinite(recwarn):
    """n < 0 (a steep hopper, smooth walls, D < 1: alpha = 60 deg, mu_w = 0.1, D = 0.7 give
    n = -0.26): sigma_v ~ (gamma H / (1 - n) + q) (h/H)^n grows without bound towards the
    apex.  h = 0 returned NaN with overflow warnings; it is now +inf (-inf for a q negative
    enough), without a warning, and the heights above it are unchanged."""
    n = th.walker_exponent(60.0, 0.1, 0.7)
    assert n == pytest.approx(0.7 * (1.0 + 0.1 / math.tan(math.radians(60.0))) - 1.0)
    h = np.array([0.0, 1e-6, 0.5, 1.0])
    got = th.hopper_sigma_v(h, 1.0, 1000.0, G, 60.0, 0.1, 0.7)
    assert got[0] == math.inf and got[-1] == pytest.approx(1000.0)
    c = G * 1.0 / (1.0 - n) + 1000.0  # the leading term's coefficient near the apex
    assert got[1] == pytest.approx(c * 1e-6**n, rel=1e-3)
    assert th.hopper_sigma_v(0.0, 1.0, -c - 1.0, G, 60.0, 0.1, 0.7) == -math.inf
    # n just above 0 (D = 1 here: n = 0.1 cot 60 deg = 0.058): the limit at the apex is 0,
    # which the clipped height left as q 1e-300^n (1.4e-14 here, 1.0 at n = 0.01); a scalar
    # height gives a scalar either way
    small = th.hopper_sigma_v(0.0, 1.0, 1000.0, G, 60.0, 0.1, 1.0)
    assert small == 0.0 and np.ndim(small) == 0
    assert np.ndim(th.hopper_sigma_v(0.0, 1.0, 1000.0, G, 60.0, 0.1, 0.7)) == 0
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]
