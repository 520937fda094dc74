"""Continuum silo theory to compare the simulations with (docs/theory.md), one module per
theory, every name importable from here (``from silodem import theory as th``):

- ``janssen``: Janssen (1895) for a 2D slot, and the fit of K to a wall profile;
- ``hopper``: Walker's (1966) slice method in planar and conical hoppers, the paper's eq. (12);
- ``beverloo``: Beverloo (1961) discharge rate in 2D, and its fits;
- ``en1991_4``: EN 1991-4:2006's wall loads (§5.2, §5.3) and hopper loads (§6).

Units are SI throughout: lengths [m], densities [kg/m^3], g [m/s^2], stresses [Pa], angles in
degrees where the argument name ends in ``_deg``.  Stresses are compressive positive (soil
mechanics).  The depth and height arguments (and the data of the fits) may be NumPy arrays;
the material and geometry parameters are scalars.  Bad input (a parameter out of its range,
NaN, a string, a bool for a number, a non-bool flag) is a one-line ValueError that names the
function, the argument, its allowed range and the value got (``_checks``).
"""

from silodem.theory.beverloo import (
    BeverlooFit,
    beverloo_2d,
    beverloo_2d_C,
    beverloo_narrow_widths,
    fit_beverloo_free,
    fit_beverloo_three_halves,
)
from silodem.theory.en1991_4 import (
    HopperLoad,
    en1991_4_discharge,
    en1991_4_discharge_factors,
    en1991_4_filling,
    en1991_4_filling_squat,
    en1991_4_h_o,
    en1991_4_hopper_discharge,
    en1991_4_hopper_filling,
    en1991_4_hopper_kind,
    en1991_4_phi_i_from_K,
    en1991_4_printed_exponent,
    en1991_4_slenderness,
)
from silodem.theory.hopper import (
    alpha_from_theta,
    apex_below_outlet,
    hopper_sigma_v,
    hopper_wall_normal,
    paper_eq12,
    walker_distribution_factor,
    walker_exponent,
)
from silodem.theory.janssen import (
    FIT_LOWER,
    JanssenFit,
    fit_janssen,
    janssen_sigma_h,
    janssen_sigma_v,
    janssen_wall_shear,
)

__all__ = [
    "FIT_LOWER",
    "BeverlooFit",
    "HopperLoad",
    "JanssenFit",
    "alpha_from_theta",
    "apex_below_outlet",
    "beverloo_2d",
    "beverloo_2d_C",
    "beverloo_narrow_widths",
    "en1991_4_discharge",
    "en1991_4_discharge_factors",
    "en1991_4_filling",
    "en1991_4_filling_squat",
    "en1991_4_h_o",
    "en1991_4_hopper_discharge",
    "en1991_4_hopper_filling",
    "en1991_4_hopper_kind",
    "en1991_4_phi_i_from_K",
    "en1991_4_printed_exponent",
    "en1991_4_slenderness",
    "fit_beverloo_free",
    "fit_beverloo_three_halves",
    "fit_janssen",
    "hopper_sigma_v",
    "hopper_wall_normal",
    "janssen_sigma_h",
    "janssen_sigma_v",
    "janssen_wall_shear",
    "paper_eq12",
    "walker_distribution_factor",
    "walker_exponent",
]
