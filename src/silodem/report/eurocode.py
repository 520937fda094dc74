"""EN 1991-4:2006 (Eurocode 1, part 4: silos) in the report: the loads of the filled silo's
classes on its vertical and hopper walls, and their key numbers (docs/theory.md, "EN
1991-4:2006").  The formulas are in :mod:`silodem.theory`; here they get the run's measured
inputs (K of the Janssen fit after filling, rho_b, the surface, the highest wall contact)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from silodem import theory as th
from silodem.report.flags import above_hydrostatic, walls_held_up
from silodem.report.numbers import pascals, poorly_determined, significant

if TYPE_CHECKING:
    from silodem.config import Measure
    from silodem.report.analysis import Analysis


def highest_wall_contact(snap: dict[str, Any] | None, width: float, d: float) -> float:
    """Height [m] of the highest grain top within one column (B / round(B/d), about d) of
    either wall, the higher of the two sides: EN 1991-4's highest solid-wall contact.  NaN
    when no grain is that close to a wall."""
    if snap is None or snap["particles"]["x"].size == 0:
        return float("nan")
    p = snap["particles"]
    column = width / max(1, round(width / d))
    near = (p["x"] < column) | (p["x"] >= width - column)
    return float((p["y"] + p["radius"])[near].max()) if near.any() else float("nan")


def add_loads(a: Analysis, wall_top: float) -> None:
    """EN 1991-4:2006 loads on the vertical walls of the filled silo, by its slenderness
    class: §5.2 (Janssen form) for slender silos, §5.3 for squat and intermediate ones, with
    K of the Janssen fit after filling, mu = tan(phi_P), gamma = rho_b g, h_c from the junction
    (or floor) to the equivalent surface, and h_o measured (the equivalent surface minus
    ``wall_top`` [m], the highest wall contact, at least 0); in a hopper silo also §6 on the
    hopper walls (:func:`hopper_loads`).  Sets ``a.en1991_4``, with the K used (``"K"``,
    ``"K_err"``) and ``"K_above_1"``, whether it is above 1 by more than its error
    (:func:`~silodem.report.flags.above_hydrostatic`): the loads are then still drawn from
    it, and the key numbers and the legends say that they are the standard's formulas fed a
    K no fill at rest has (:data:`K_ABOVE_1`).  Nothing for a retaining silo
    (§5.4, not built), nor without K (no Janssen fit after filling, or one whose error is
    over half of K: few or noisy wall bins) or where §5.3's form
    does not apply (h_o >= z_o): the class alone, with ``"missing"`` saying why.  Nothing
    at all for frictionless walls (mu = 0: z_o = A/(K mu U) is infinite)."""
    g = a.geom
    top, j = a.surface["fill"], a.janssen.get("fill")
    h_c = top - g["z_j"]
    if not (h_c > 0.0 and np.isfinite(a.rho_b) and g["mu_wall"] > 0.0):
        return
    flat = a.res.cfg.silo.kind != "hopper"
    kind = th.en1991_4_slenderness(h_c, g["B"], flat_bottom=flat)
    section = {"slender": "5.2", "retaining": "5.4"}.get(kind, "5.3")
    a.en1991_4 = {"kind": kind, "section": section, "h_c": h_c, "ratio": h_c / g["B"]}
    if kind == "retaining":  # the class in the key numbers, with no loads
        return
    if j is None:
        a.en1991_4["missing"] = "no K: no Janssen fit after filling"
        return
    if poorly_determined(j.K, j.K_err):  # (as the key numbers say: no measurement of K)
        a.en1991_4["missing"] = (f"K = {j.K:.3g} +- {j.K_err:.2g} of the Janssen fit after "
                                 "filling is poorly determined")
        return
    C_h, C_w = th.en1991_4_discharge_factors(h_c, g["B"], flat_bottom=flat)
    m = a.res.cfg.measure
    phi_r = (m.angle_of_repose_deg if m.angle_of_repose_deg is not None
             else a.res.cfg.material.friction_deg)
    h_o = max(0.0, top - wall_top) if np.isfinite(wall_top) else 0.0
    z = np.linspace(g["z_j"], top, 60)
    gamma, A_over_U = a.rho_b * g["g"], g["B"] / 2
    try:
        if kind == "slender":
            p_hf, p_wf, p_vf = th.en1991_4_filling(top - z, gamma, j.K, g["mu_wall"], A_over_U)
        else:
            p_hf, p_wf, p_vf = th.en1991_4_filling_squat(top - z, gamma, j.K, g["mu_wall"],
                                                         A_over_U, phi_r, h_o)
    except ValueError:  # h_o >= z_o (a heap deeper than z_o): the form does not apply
        a.en1991_4["missing"] = f"the form does not apply: h_o = {h_o:.3g} m >= z_o"
        return
    a.en1991_4.update(K=j.K, K_err=j.K_err, K_above_1=above_hydrostatic(j),
                      h_o=h_o, phi_r=phi_r, C_h=C_h, C_w=C_w, z=z, p_hf=p_hf, p_he=C_h * p_hf,
                      p_wf=p_wf, p_we=C_w * p_wf,
                      mobilised=a.mu_mobilised.get("fill", np.nan) / g["mu_wall"])
    if not flat:
        a.en1991_4["hopper"] = hopper_loads(a, j.K, float(p_vf[0]))


def hopper_loads(a: Analysis, K: float, p_vft: float) -> dict[str, Any]:
    """EN 1991-4:2006 §6 loads on the hopper walls (a planar wedge, S = 1) by the hopper's
    class, from p_vft [Pa] = C_b p_vf, the vertical walls' p_vf at the transition with C_b = 1
    (action assessment class 2, no dynamic solid), K of the Janssen fit after filling,
    mu_h = tan(phi_P), and for a steep hopper's discharge factor F_e the angle of internal
    friction that EN's K = 1.1 (1 - sin phi_i) gives for that K.  "kind" alone when the rules
    do not apply (a shallow hopper needs K < 1); no "p_ne" when F_e does not exist (phi_i <
    phi_wh)."""
    g = a.geom
    beta, mu_h = g["alpha"], g["mu_hopper"]
    out: dict[str, Any] = {"kind": th.en1991_4_hopper_kind(beta, K, mu_h), "K": K,
                           "p_vft": p_vft, "phi_i": th.en1991_4_phi_i_from_K(K)}
    z = np.linspace(0.0, g["z_j"], 60)
    args = (z + g["apex"], g["z_j"] + g["apex"], p_vft, a.rho_b * g["g"], beta, K, mu_h)
    try:
        fill = th.en1991_4_hopper_filling(*args)
    except ValueError:  # a flat bottom, or a shallow hopper with K >= 1: no rule applies
        return out
    out.update(z=z, mu_eff=fill.mu_eff, F_f=fill.F, p_nf=fill.p_n)
    try:
        dis = th.en1991_4_hopper_discharge(*args, out["phi_i"])
    except ValueError:  # phi_i < phi_wh: no passive stress state at this wall
        return out
    out.update(F_e=dis.F, p_ne=dis.p_n, n_e=dis.n,
               n_e_printed=th.en1991_4_printed_exponent(dis.F, mu_h, beta))
    return out


def wedge_exponent_departs(hopper: dict[str, Any]) -> bool:
    """Whether ``hopper`` (:func:`hopper_loads`) has discharge loads of a steep hopper, whose
    wedge exponent n_e (the slice balance's) is not §6.3.1's printed one, n_e_printed."""
    return "n_e" in hopper and hopper["kind"] == "steep"


K_ABOVE_1 = (  # the loads drawn from a K above 1 (add_loads' "K_above_1"), after its value
    "above 1 by more than its error, which no fill at rest has (EN 1991-4's own K = 1.1 "
    "(1 - sin phi_i) is under 1 for phi_i over 5.2 deg): these are the standard's formulas fed "
    "this K, not its loads for this material; the larger K brings the wall pressure to its deep "
    "value gamma A / (mu U), which K does not change, at a shallower depth")


def key_numbers(en: dict[str, Any], measure: Measure) -> list[tuple[str, str, str]]:
    """The report's key-number rows (quantity, value, unit) of :func:`add_loads`'s dict."""
    n: list[tuple[str, str, str]] = []
    if en:
        loads = (f"loads of §{en['section']} drawn" if "p_hf" in en
                 else f"no loads drawn (§{en['section']}): {en['missing']}" if "missing" in en
                 else f"no loads drawn (§{en['section']}, not built in silodem)")
        if en.get("K_above_1"):
            loads += (f" (from K = {significant(en['K'], 3)} +- {significant(en['K_err'], 2)} "
                      f"of the Janssen fit after filling, {K_ABOVE_1})")
        value = f"{significant(en['ratio'], 3)}: {en['kind']}, {loads}"
        n.append(("EN 1991-4 slenderness h_c/d_c (junction or floor to the surface, over B)",
                  value, "-"))
    if "p_hf" in en:
        if en["section"] == "5.3":
            source = ("measure.angle_of_repose_deg" if measure.angle_of_repose_deg is not None
                      else "phi_G, angle_of_repose_deg unset")
            label = ("EN 1991-4 §5.3 inputs: h_o measured (surface - highest wall contact), "
                     "angle of repose phi_r")
            value = f"{significant(en['h_o'], 3)} m, {significant(en['phi_r'], 3)} deg ({source})"
            n.append((label, value, ""))
        n.append(("EN 1991-4 discharge magnifiers C_h, C_w",
                  f"{significant(en['C_h'], 4)}, {significant(en['C_w'], 4)}", "-"))
        n.append(mobilisation_row(en["mobilised"]))
    if "hopper" in en:
        _hopper_numbers(n, en["hopper"])
    return n


FEW_MOBILISED = 0.5  # of tan(phi_P): below it the loads' wall friction is not measured


def mobilisation_row(share: float) -> tuple[str, str, str]:
    """The key number on the loads' assumption: EN's loads (and K, fitted with mu_w = tan
    phi_P) take the wall friction fully mobilised; the friction the cell walls mobilise after
    filling, sum(tau) / sum(sigma_n), as a share of tan(phi_P) (not the share of the fill's
    weight they carry, which the gate-load row gives).  Under FEW_MOBILISED the row says that
    the settled silo does not show the wall support the loads assume (its pressures are then
    nearer hydrostatic, and K takes up the missing friction).  Under 0 it says more: tau is
    the grains' shear traction on the walls, counted downward (wall_profiles' tau, along each
    wall's tangent, turned downward in ``analysis._edge``), so a negative sum is a net upward
    pull of the grains on the walls, the walls' friction on the grains pointing down: the
    cell walls carry none of the fill's weight and press it onto the fill below (as in a
    column that sprang back after settling, its wall friction reversed and locked in:
    docs/validation.md's statics check), not a smaller share of the support the loads
    assume."""
    label = ("EN 1991-4 loads' wall friction, mu = tan phi_P fully mobilised (as for K): the "
             "friction the cell walls mobilise after filling, sum(tau) / sum(sigma_n), as a "
             "share of tan phi_P")
    value = f"{significant(100 * share, 2)} %"
    if walls_held_up(share):
        value += (": negative: net, the walls' friction on the grains points down, so the cell "
                  "walls carry none of the fill's weight (the grains hold them up), the reverse "
                  "of the wall support these loads assume; read them as the standard's, not as "
                  "a model of this silo")
    elif share < FEW_MOBILISED:
        value += (": the settled silo does not show the wall support these loads assume; "
                  "read them as the standard's, not as a model of this silo")
    return label, value, ""


def _hopper_numbers(n: list, h: dict[str, Any]) -> None:
    """The key numbers of EN 1991-4's hopper loads (:func:`hopper_loads`)."""
    label = "EN 1991-4 §6 hopper class, wall friction mu_eff, F_f filling, F_e discharge"
    if "p_nf" not in h:
        why = ("a flat bottom" if h["kind"] == "flat" else
               f"K = {significant(h['K'], 3)} >= 1 leaves a shallow hopper no mobilised "
               "friction")
        n.append((label, f"{h['kind']}: the rules do not apply ({why})", "-"))
        return
    phi_i = f"phi_i = {significant(h['phi_i'], 3)} deg from K = 1.1 (1 - sin phi_i)"
    F_e = ("F_e = F_f (shallow hopper)" if h["kind"] == "shallow"
           else f"F_e {significant(h['F_e'], 3)} ({phi_i})" if "F_e" in h
           else f"F_e n/a ({phi_i} is below phi_P)")
    value = (f"{h['kind']}, mu_eff {significant(h['mu_eff'], 3)}, "
             f"F_f {significant(h['F_f'], 3)}, {F_e}")
    n.append((label, value, "-"))
    at_top = f"{pascals(h['p_nf'][-1])} / {pascals(h['p_ne'][-1]) if 'p_ne' in h else 'n/a'}"
    label = ("EN 1991-4 hopper normal pressure at the transition, filling / discharge "
             f"(p_vft = p_vf there = {pascals(h['p_vft'])} Pa)")
    n.append((label, at_top, "Pa"))
    if wedge_exponent_departs(h):
        label = ("EN 1991-4 hopper discharge exponent n: the wedge's slice balance (drawn) / "
                 "as printed in §6.3.1, S (F_e mu cot beta + F_e) - 2, which gives higher "
                 "pressures (docs/theory.md)")
        n.append((label, f"{significant(h['n_e'], 3)} / {significant(h['n_e_printed'], 3)}",
                  "-"))
