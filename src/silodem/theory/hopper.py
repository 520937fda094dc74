"""Walker (1966): the slice method in hoppers, planar (2D wedge) and conical; the paper's
eq. (12); Walker's distribution factor.

Angles: the config gives the hopper wall slope theta FROM THE HORIZONTAL
(``silo.hopper_angle_from_horizontal_deg``); hopper theory (Walker, Jenike, Nedderman) uses the
half-angle alpha FROM THE VERTICAL, alpha = 90 deg - theta (:func:`alpha_from_theta`).

Planar (2D, wedge) versus conical hoppers: the differential slice balance of a hopper reads, with
h the height above the (virtual) apex and m = 0 for a wedge, m = 1 for a cone,

    h d(sigma_v)/dh = n sigma_v - gamma h,   n = (m + 1) [D (1 + mu_w / tan(alpha)) - 1]

whose solution with sigma_v(H) = q at the transition h = H is

    sigma_v(h) = gamma h / (n - 1) [1 - (h/H)^(n-1)] + q (h/H)^n.

A 2D DEM hopper is a wedge (plane strain): m = 0.  The paper's eq. (12) is the conical form
(m = 1, D = 1, its n_i = n - 1); it overstates the wall support of a 2D slice by a factor of two
(perimeter/area of a cone 2/x, of a wedge 1/x) and so underpredicts the hopper stresses.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from silodem.theory import _checks as ck


def alpha_from_theta(theta_from_horizontal_deg: float) -> float:
    """Hopper half-angle from the vertical alpha [deg] = 90 - theta (theta from the horizontal,
    in [0, 90])."""
    ck.between("alpha_from_theta", "theta_from_horizontal_deg", theta_from_horizontal_deg,
               0.0, 90.0, lo_in=True, hi_in=True)
    return 90.0 - float(theta_from_horizontal_deg)


def _alpha(func: str, alpha_deg) -> None:
    """A hopper's half-angle from the vertical: 0 < alpha < 90 deg."""
    ck.between(func, "alpha_deg", alpha_deg, 0.0, 90.0)


def apex_below_outlet(outlet_width: float, alpha_deg: float) -> float:
    """Depth of the virtual apex of a hopper under its outlet [m]: (D/2) / tan(alpha).

    Slice theory measures heights h from the apex, where the hopper walls would meet.
    outlet_width >= 0 [m], 0 < alpha < 90 deg."""
    ck.non_negative("apex_below_outlet", "outlet_width", outlet_width)
    _alpha("apex_below_outlet", alpha_deg)
    return 0.5 * outlet_width / math.tan(math.radians(alpha_deg))


def _exponent(alpha_deg, mu_w, D, planar):
    """:func:`walker_exponent` unchecked."""
    m = 0 if planar else 1
    return (m + 1) * (D * (1.0 + mu_w / math.tan(math.radians(alpha_deg))) - 1.0)


def _check_slice(func: str, alpha_deg, mu_w, D, planar) -> None:
    """The hopper and material of the slice solution: 0 < alpha < 90 deg, mu_w >= 0, D > 0,
    planar a bool."""
    _alpha(func, alpha_deg)
    ck.non_negative(func, "mu_w", mu_w)
    ck.positive(func, "D", D)
    ck.flag(func, "planar", planar)


def walker_exponent(alpha_deg: float, mu_w: float, D: float = 1.0, planar: bool = True) -> float:
    """Exponent n of the hopper slice solution [-].

    n = (m + 1) [D (1 + mu_w / tan(alpha)) - 1],  m = 0 planar wedge (2D), m = 1 cone.

    alpha: half-angle from the vertical [deg]; mu_w = tan(phi_w) wall friction [-]; D = sigma_n /
    sigma_v, Walker's distribution factor (wall normal stress over mean vertical stress) [-].
    With D = 1 and m = 1, n = 2 (1 + mu_w/tan(alpha)) - 2 = n_i + 1 with the paper's
    n_i = 2 (1 + tan(phi_P)/tan(alpha)) - 3.  Source: Walker (1966), Chem. Eng. Sci. 21, 975;
    Nedderman (1992), the method of differential slices.  ValueError unless 0 < alpha < 90 deg,
    mu_w >= 0, D > 0 and planar is a bool.
    """
    _check_slice("walker_exponent", alpha_deg, mu_w, D, planar)
    return _exponent(alpha_deg, mu_w, D, planar)


def _one_minus_power(log_x, a: float):
    """(1 - x^a) / a from ln x, continuous through a = 0, where it is -ln x (expm1: no
    cancellation for a near 0)."""
    return -log_x if abs(a) < 1e-12 else -np.expm1(a * log_x) / a


def _sigma_v(h, H, q, gamma, alpha_deg, mu_w, D, planar):
    """:func:`hopper_sigma_v` unchecked."""
    h = np.asarray(h, dtype=float)
    n = _exponent(alpha_deg, mu_w, D, planar)
    x = np.clip(h / H, 1e-300, None)
    log_x = np.log(x)
    with np.errstate(over="ignore", invalid="ignore"):  # at the apex for n < 0: see below
        sigma = gamma * h * _one_minus_power(log_x, n - 1.0) + q * np.exp(n * log_x)
    # at the apex sigma_v -> (gamma H / (1 - n) + q) (h/H)^n: 0 for n > 0, infinite for n < 0
    # (the clipped x above leaves q 1e-300^n there, far from 0 for n near 0)
    if n > 0.0:
        apex = 0.0
    else:
        c = gamma * H / (1.0 - n) + q
        apex = c if n == 0.0 else math.copysign(math.inf, c) if c else 0.0
    return np.where(h == 0.0, apex, sigma)[()]  # [()]: a scalar for a scalar h


def _check_heights(func: str, h, H, q, gamma, alpha_deg, mu_w, D, planar) -> np.ndarray:
    """The arguments of the slice solution, ``h`` as an array in [0, H]."""
    ck.positive(func, "H", H)
    ck.number(func, "q", q)
    ck.non_negative(func, "gamma", gamma)
    _check_slice(func, alpha_deg, mu_w, D, planar)
    h = ck.array(func, "h", h)
    ck.within(func, "h", h, 0.0, H, "H")
    return h


def hopper_sigma_v(h: npt.ArrayLike, H: float, q: float, gamma: float, alpha_deg: float,
                   mu_w: float, D: float = 1.0, planar: bool = True) -> np.ndarray | float:
    """Mean vertical stress [Pa] at height ``h`` [m] above the apex of a hopper (slice method).

    sigma_v(h) = gamma h / (n - 1) [1 - (h/H)^(n-1)] + q (h/H)^n      (n from walker_exponent)

    solves h d(sigma_v)/dh = n sigma_v - gamma h with sigma_v(H) = q, the slice balance
    d(A sigma_v)/dh = -gamma A + P sigma_n (tan(alpha) + mu_w), sigma_n = D sigma_v, with A = 2 h
    tan(alpha), P = 2 (wedge, per unit thickness) or A = pi (h tan(alpha))^2, P = 2 pi h
    tan(alpha) (cone).  H: height of the transition above the apex [m]; q: mean vertical stress
    on the transition from the cell above [Pa]; gamma = rho_b g [N/m^3]; n = 1 is the limit
    gamma h ln(H/h) + q h/H.  Source: Walker (1966); Nedderman (1992), the method of
    differential slices.  ValueError unless 0 <= h <= H (the hopper, apex to transition),
    H > 0, q finite (a measured q may be of either sign; the solution is linear in it),
    gamma >= 0, and the conditions of :func:`walker_exponent`.
    """
    h = _check_heights("hopper_sigma_v", h, H, q, gamma, alpha_deg, mu_w, D, planar)
    return _sigma_v(h, H, q, gamma, alpha_deg, mu_w, D, planar)


def hopper_wall_normal(h: npt.ArrayLike, H: float, q: float, gamma: float, alpha_deg: float,
                       mu_w: float, D: float = 1.0, planar: bool = True) -> np.ndarray | float:
    """Hopper wall normal stress [Pa]: sigma_n = D sigma_v (:func:`hopper_sigma_v`)."""
    h = _check_heights("hopper_wall_normal", h, H, q, gamma, alpha_deg, mu_w, D, planar)
    return D * _sigma_v(h, H, q, gamma, alpha_deg, mu_w, D, planar)


def paper_eq12(z_below_transition: npt.ArrayLike, h_prime: float, q: float, gamma: float,
               alpha_deg: float, mu_w: float) -> np.ndarray | float:
    """The paper's eq. (12) as printed [Pa], with its hopper angle read as alpha, the half-angle
    from the vertical (docs/theory.md; the paper writes one theta for this angle and for
    the hopper slopes of its cases, which the config reads from the horizontal):

    sigma = gamma [(h' - z)/n_i + (q/gamma - h'/n_i) (1 - z/h')^(n_i + 1)],
    n_i = 2 (1 + tan(phi_P)/tan(alpha)) - 3,

    z measured down from the transition, h' the distance from the transition to the apex [m].
    It equals :func:`hopper_sigma_v` with planar=False, D = 1, h = h' - z, H = h'.  With x =
    1 - z/h' it reads gamma h' x (1 - x^n_i) / n_i + q x^(n_i + 1), whose limit at n_i = 0
    (mu_w = tan(alpha) / 2, e.g. alpha = 45 deg, mu_w = 0.5) is -gamma h' x ln x + q x; it is
    computed so, with (1 - x^n_i) / n_i = -expm1(n_i ln x) / n_i (the printed form cancels
    near n_i = 0: 1.7e-5 of sigma lost at n_i = 1e-11).
    ValueError unless 0 <= z <= h', h' > 0, q finite, gamma > 0 (the form as printed divides
    by it), 0 < alpha < 90 deg and mu_w >= 0.
    """
    func = "paper_eq12"
    ck.positive(func, "h_prime", h_prime)
    ck.number(func, "q", q)
    ck.positive(func, "gamma", gamma)
    _alpha(func, alpha_deg)
    ck.non_negative(func, "mu_w", mu_w)
    z = ck.array(func, "z_below_transition", z_below_transition)
    ck.within(func, "z_below_transition", z, 0.0, h_prime, "h_prime")
    n_i = 2.0 * (1.0 + mu_w / math.tan(math.radians(alpha_deg))) - 3.0
    x = 1.0 - z / h_prime
    log_x = np.log(np.clip(x, 1e-300, None))  # (x = 0 at the apex: x times it is 0)
    return gamma * h_prime * x * _one_minus_power(log_x, n_i) + q * x ** (n_i + 1.0)


def walker_distribution_factor(delta_deg: float, phi_w_deg: float, alpha_deg: float) -> float:
    """Walker's distribution factor D = sigma_n / sigma_v at a hopper wall [-].

    D = (1 + sin(delta) cos(2 omega)) / (1 - sin(delta) cos(2 (alpha + omega))),
    2 omega = phi_w + arcsin(sin(phi_w) / sin(delta)),

    from the Mohr circle of a material at yield (effective angle of internal friction delta) in
    the passive (flowing) state at a wall of friction angle phi_w, with the vertical stress at
    the wall taken as the mean vertical stress (Walker's assumption).  alpha: half-angle from
    the vertical [deg].  For alpha = 0 it is the vertical-wall K of Walker/Nedderman; for a
    vertical smooth wall (alpha = 0 and phi_w = 0) Rankine's passive K =
    (1 + sin delta)/(1 - sin delta).  The passive state only: it is the stress distribution
    of a flowing hopper, not of one being filled.  ValueError unless 0 < delta < 90 deg,
    0 <= phi_w <= delta and 0 <= alpha < 90 deg.
    Source: Walker (1966); Nedderman (1992), the method of differential slices.
    """
    func = "walker_distribution_factor"
    ck.between(func, "delta_deg", delta_deg, 0.0, 90.0)
    ck.number(func, "phi_w_deg", phi_w_deg)
    if not 0.0 <= phi_w_deg <= delta_deg:
        raise ValueError(f"{func}: phi_w_deg must lie in [0, delta_deg = {ck.show(delta_deg)}] "
                         f"(phi_w must not exceed delta); got {ck.show(phi_w_deg)}")
    ck.between(func, "alpha_deg", alpha_deg, 0.0, 90.0, lo_in=True)
    s = math.sin(math.radians(delta_deg))
    pw = math.radians(phi_w_deg)
    # min: sin(phi_w) / sin(delta) is 1 at phi_w = delta, and never above it but by round-off
    two_omega = pw + math.asin(min(math.sin(pw) / s, 1.0))
    a2 = 2.0 * math.radians(alpha_deg)
    return (1.0 + s * math.cos(two_omega)) / (1.0 - s * math.cos(a2 + two_omega))
