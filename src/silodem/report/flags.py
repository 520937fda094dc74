"""The judgements the reports pass on physically suspicious numbers, in one place: the key
numbers (:mod:`silodem.report.key_numbers`), the figures' legends
(:mod:`silodem.report.figures_stress`), the EN 1991-4 loads (:mod:`silodem.report.eurocode`),
and a study's results.csv and heat maps (:mod:`silodem.study.table`,
:mod:`silodem.study.report`) all ask these predicates, so each says the same of the same
number.  (A module of its own because ``eurocode``, which ``analysis`` imports, needs them
too.)"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from silodem.theory import JanssenFit


def above_hydrostatic(fit: JanssenFit) -> bool:
    """A Janssen K = sigma_h / sigma_v [-] above 1 by more than its standard error.  K = 1 is
    the isotropic, hydrostatic state (a fluid's); the Mohr-Coulomb states of a cohesionless
    fill lie between the active K_a = (1 - sin phi) / (1 + sin phi) < 1, sigma_v the major
    stress, and the passive K_p = 1 / K_a > 1, sigma_h the major stress.  A fill poured and
    settled under its own weight is on the active side: Jaky's K0 = 1 - sin phi (Nedderman
    1992, "Statics and kinematics of granular materials", on Janssen's K), and EN 1991-4's
    estimate K = 1.1 (1 - sin phi_i) (its section 4) is under 1 for any phi_i over 5.2 deg.
    So 1, not a tuned number, is the bound, and the fit's own error the margin: a K within its
    error of 1 (docs/validation.md's column, its wall friction mobilised by lowering the
    floor, fits 1.02-1.05, its near-wall stress tensor gives 0.99-1.12) is not judged, nor is
    a fit with no error (two bins: exact).  After filling the fit with mu_w = tan phi_P also
    puts into K the wall friction the walls do not mobilise (docs/theory.md): either way the
    number is no K of a settled fill, and the report says so.  During discharge a K above 1
    is no anomaly: flowing grains that converge below the (effective) transition go over to
    the passive state, the switch of Jenike and Johanson and of Walters (1973; Nedderman
    1992, on the stresses during discharge), which in funnel flow lies up in the cell; the
    report says what it is there, as a note, not a warning."""
    return math.isfinite(fit.K_err) and fit.K - fit.K_err > 1.0


def walls_held_up(mu_mobilised: float) -> bool:
    """A mobilised wall friction sum(tau_down) / sum(sigma_n) [-] (or its share of tan phi_P)
    below 0.  tau_down is the grains' shear traction on the walls counted downward
    (``analysis._edge``), so a negative sum is a net upward pull of the grains on the walls:
    the walls' friction on the grains points down, the cell walls carry none of the fill's
    weight and press it onto the fill below (as in a column that sprang back after settling,
    its wall friction reversed and locked in: docs/validation.md's statics check).  The
    threshold is the sign; NaN (no fit) is not judged."""
    return mu_mobilised < 0.0


def overpacked(rho_b: float, rho_grain: float) -> bool:
    """A bulk density rho_b [kg/m^3] above the grains' own rho_grain: only grains that
    overlap far more than a contact law allows pack more mass into an area than solid grain
    (porosity < 0), as paper case 1's soft Table 1 springs do; every stress measured on them
    is suspect.  NaN (no density) is not judged."""
    return rho_b > rho_grain


ABOVE_HYDROSTATIC = {  # what a K above 1 (above_hydrostatic) is, by window: the key numbers
    "fill": ("above 1 by more than its error: as fitted, the walls are pressed harder than the "
             "fill's vertical stress, a passive-like state, not the K of a fill at rest under "
             "its own weight (Jaky: K0 = 1 - sin phi < 1)"),
    "discharge": ("above 1 by more than its error: a passive-like state, the walls pressed "
                  "harder than the vertical stress, as flowing grains can set up (the switch "
                  "of Jenike and Walters)"),
}

ABOVE_HYDROSTATIC_SHORT = {  # the same in a figure's legend, by window
    "fill": "K above 1: not a fill at rest",
    "discharge": "K above 1: passive-like, as flowing grains can be",
}

WALLS_HELD_UP = (  # the mobilised wall friction below 0 (walls_held_up): the key numbers
    "negative: the walls' friction on the grains points down, net over these bins, so the cell "
    "walls carry none of the fill's weight but add to the load below (the grains hold the "
    "walls up): the reverse of the wall support Janssen assumes")

WALLS_HELD_UP_SHORT = "net negative on the fitted bins: the walls carry none of the weight"


FLAT_SHARE = 0.9  # a fitted curve whose sigma_h at its shallowest point is this share of the
# deepest's, or more, is called flat over the fitted depths (JanssenFit.shallow_to_deep) [-]


def undetermined_why(fit: JanssenFit, B: float) -> str:
    """Why a free fit's K is not determined (:func:`free_fit_undetermined`), from the fit:
    two bins, which any (K, mu_w) through them fits exactly with no error; a curve flat over
    the fitted depths (``FLAT_SHARE``), which any large K fits; or else a profile too
    scattered for its shape to fix K. ``B``: the silo's width [m]. (K = 1.30 +- 2.10 over a
    profile scattered between 1.7 and 19 kPa was said to be a flat one.)"""
    if fit.n_points <= 2:
        return (f"{fit.n_points} wall bins, which the curve passes through exactly, leaving K "
                "and mu_w no error")
    share = fit.shallow_to_deep(B)
    if not math.isfinite(share) or share >= FLAT_SHARE:
        return "the wall stress is nearly the same at every depth, which any large K fits"
    return (f"the profile scatters too much (rms {fit.rms:,.0f} Pa about the fitted curve) "
            "for its shape to fix K")


def free_fit_undetermined(fit: JanssenFit) -> bool:
    """A Janssen fit of both K and mu_w whose K has no finite error, or one larger than K
    (:func:`undetermined_why` says which cause: two bins, a flat profile or a scattered one).
    A wall stress nearly the same at every depth (a steep hopper's short cell, a smooth wall)
    fits any large K (sigma_h = rho_b g B / (2 mu_w) (1 - exp(-2 K mu_w z / B)) is then
    its asymptote throughout, and mu_w only sets its level).  K = 31.4 with no error and
    36 +- 3.6e8 were reported and drawn as results.  Not for a mu_w at its lower bound, where
    K is sigma_h / (rho_b g depth), determined."""
    if not fit.mu_w_fitted or fit.mu_w_at_bound:
        return False
    return not (math.isfinite(fit.K_err) and fit.K_err <= fit.K)
