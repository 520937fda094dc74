"""Figures of stresses and contacts: the paper's Figs. 2, 3a, 3b, 6, 7 and 8, and the wall
shear.  Each function takes an :class:`~silodem.report.analysis.Analysis` and returns a
matplotlib Figure (or None when the data is missing)."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure
from matplotlib.legend_handler import HandlerTuple
from matplotlib.patches import Patch, Polygon

from silodem import theory as th
from silodem.report.analysis import BATCHES, Analysis, above_coulomb
from silodem.report.draw import (
    circle_style,
    draw_walls,
    legend_below,
    legend_right,
    loaded_ratio,
    ratio_axis,
    rolling_mean,
    shade_phases,
    silo_axes,
    tight_layout,
    walls_at,
)
from silodem.report.eurocode import wedge_exponent_departs
from silodem.report.flags import (
    ABOVE_HYDROSTATIC_SHORT,
    WALLS_HELD_UP_SHORT,
    above_hydrostatic,
    free_fit_undetermined,
    walls_held_up,
)
from silodem.report.numbers import UNLOADED, poorly_determined, resolved
from silodem.silo.geometry import silo_shape

PAPER_K = 0.4  # the paper's Janssen coefficient during filling


CUT_BELOW = 0.8  # a profile's z axis ends above the fill when that is under 0.8 of the wall
MARGIN = 0.2  # ... at the fill's top plus this share of it (at least two grain diameters)


def profile_top(a: Analysis) -> float:
    """Upper end [m] of the z axis of the wall profiles (Figs. 3a, 3b, 6, wall shear): the
    highest of the free surface after filling and of the profiles' loaded bins (a finite
    stress above 0, of any window), plus ``MARGIN`` of it, at least two mean diameters, when
    that lies under ``CUT_BELOW`` of the wall's top; else the wall's top.  Above the fill the
    profiles are zero, and a quick case 1 (a 1 m fill in a 3.6 m silo) left 70 % of each plot
    empty.  The junction and the switch zone lie under the fill and stay in view."""
    top = a.geom["top"]
    highest = [a.surface.get("fill", np.nan)]
    for e in a.edge.values():
        highest += [e.z[np.isfinite(v) & (v > 0)] for v in (e.sigma_n, np.abs(e.tau_down))]
    for st in a.strips.values():
        highest += [st["z"][np.isfinite(st[k]) & (st[k] > 0)]
                    for k in ("near_xx", "near_zz", "slice_zz")]
    z = np.concatenate([np.ravel(h) for h in highest])
    z = z[np.isfinite(z)]
    if not z.size:
        return top
    h = float(z.max())
    end = h + max(MARGIN * h, 2.0 * a.geom["d"])
    return end if end < CUT_BELOW * top else top


def _z_axis(ax, a: Analysis) -> None:
    """z [m] from 0 to :func:`profile_top`; the label of an axis cut above the fill says where
    the wall ends (in the label, where no legend or curve can hide it)."""
    end = profile_top(a)
    ax.set_ylim(0, end)
    if end < a.geom["top"]:
        ax.set_ylabel(f"z [m] (axis cut above the fill; the wall's top: z = "
                      f"{a.geom['top']:.3g} m)")
    else:
        ax.set_ylabel("z [m]")


def _zone(ax, a: Analysis) -> None:
    g = a.geom
    if g["z_j"] > 0:
        ax.axhline(g["z_j"], color="0.3", lw=0.8, ls="--", label=f"junction z = {g['z_j']:.2f} m")
    ax.axhspan(*a.switch, color="#f6e7b5", alpha=0.6, zorder=0, label="switch zone")


def fig_coordination(a: Analysis) -> Figure | None:
    """Fig. 2: coordination number against cycles at the junction and in the circles, with
    the time [s] they make (cycles x dt) along the top."""
    m = a.res.group("measure")
    if m is None:
        return None
    fig = Figure(figsize=(11, 6.4), dpi=100)
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    step, phase = m["step"], m["phase"]
    band = m["band"]
    for ax in (ax1, ax2):
        shade_phases(ax, step, phase)
    lo, hi = band["@attrs"]["z_lo"], band["@attrs"]["z_hi"]
    ax1.plot(step, band["coordination"], color="k", lw=0.8, alpha=0.35, label="samples")
    ax1.plot(step, rolling_mean(band["coordination"], 9), color="k", lw=1.6,
             label=f"band {lo:.2f} < z < {hi:.2f} m\nacross the silo (running mean)")
    ax1.set_ylabel("coordination number C_n [-]")
    where = ("at the cell-hopper junction" if a.res.cfg.silo.kind == "hopper"
             else "in the band over the floor")
    ax1.set_title(f"(a) {where} (eq. 10: C_n = sum n_c / N_p)", fontsize=10)
    dt = float(a.res.attrs.get("dt", np.nan))  # the paper's cycles, and the time they make
    if np.isfinite(dt) and dt > 0.0:
        seconds = ax1.secondary_xaxis("top", functions=(lambda s: s * dt, lambda t: t / dt))
        seconds.set_xlabel("time [s]", fontsize=9)
    c = m["circles"]
    for k, name in enumerate(c["name"]):
        ax2.plot(step, rolling_mean(c["coordination"][:, k], 9), lw=1.4, label=str(name),
                 **circle_style(k, step.size))
    ax2.set_ylabel("C_n [-]")
    ax2.set_xlabel("cycles (time steps)")
    ax2.set_title("(b) in the measurement circles", fontsize=10)
    peak = max(np.nanmax(band["coordination"], initial=0.0),
               np.nanmax(c["coordination"], initial=0.0))
    for ax in (ax1, ax2):
        ax.axhline(4.0, color="0.5", lw=0.7, ls=":", label="C_n = 4 (square packing)")
        ax.set_ylim(0, max(6.5, 1.05 * peak))
        legend_right(ax, fontsize=8)
    tight_layout(fig)
    return fig


def _flagged(label: str, *notes: str) -> str:
    """``label`` with the ``notes`` that hold ("" ones left out) in one parenthesis."""
    said = [n for n in notes if n]
    return label + (f" ({'; '.join(said)})" if said else "")


def janssen_label(fit: th.JanssenFit, key: str) -> str:
    """The legend's flag on a fitted Janssen K of the window ``key``: the key numbers' (a K
    above 1 by more than its error, :func:`~silodem.report.flags.above_hydrostatic`), short;
    "" when there is none."""
    return ABOVE_HYDROSTATIC_SHORT[key] if above_hydrostatic(fit) else ""


def _janssen_curves(ax, a: Analysis, key: str, which: str) -> None:
    """Janssen's sigma_h or sigma_v (``which``: "h" or "v") with the window's fitted K (its
    error in the legend; a thin line, "poorly determined", where the error is over half of
    K), the paper's K = 0.4 and, after filling, the free fit; a fitted K above 1 says so in
    its legend, as in the key numbers."""
    g = a.geom
    surf = a.surface[key]
    if not np.isfinite(surf) or not np.isfinite(a.rho_b):
        return
    z = np.linspace(g["z_j"], surf, 80)
    depth = surf - z
    f = th.janssen_sigma_h if which == "h" else th.janssen_sigma_v
    j = a.janssen.get(key)
    if j is not None:  # with its error, and thin where that is over half of K, as the key
        # numbers say it (a K of 1.32 +- 0.72 was the boldest curve, without a word)
        poor = poorly_determined(j.K, j.K_err)
        err = f" +- {j.K_err:.2g}" if np.isfinite(j.K_err) else ""
        label = _flagged(f"Janssen 2D, K = {j.K:.2f}{err} fitted, mu_w = tan phi_P",
                         "poorly determined" if poor else "", janssen_label(j, key))
        ax.plot(f(depth, a.rho_b, g["g"], g["B"], j.K, g["mu_wall"]), z, color="#1f77b4",
                lw=1.2 if poor else 2, label=label)
    ax.plot(f(depth, a.rho_b, g["g"], g["B"], PAPER_K, g["mu_wall"]), z, color="#1f77b4",
            lw=1.2, ls="--", label="Janssen 2D, K = 0.4 (paper)")
    if key == "fill" and a.janssen_free is not None \
            and not free_fit_undetermined(a.janssen_free):  # (K = 31 +- nothing was drawn)
        jf = a.janssen_free
        label = _flagged(f"Janssen free fit K = {jf.K:.2f}, mu_w = {jf.mu_w:.2g}",
                         "> tan phi_P: not Janssen" if above_coulomb(jf, g["mu_wall"]) else "",
                         janssen_label(jf, "fill"))
        ax.plot(f(depth, a.rho_b, g["g"], g["B"], jf.K, max(jf.mu_w, 1e-9)), z, color="#17becf",
                lw=1.2, ls="-.", label=label)
    if which == "v":
        ax.plot(a.rho_b * g["g"] * depth, z, color="0.5", lw=1, ls=":",
                label="hydrostatic rho_b g depth")


def _hopper_curves(ax, a: Analysis, which: str, key: str = "fill") -> None:
    """Walker's slice solutions with the window's own q (and D fitted to its hopper walls)."""
    h = a.hopper.get(key)
    if not h:
        return
    ax.plot(h["planar"], h["z"], color="#d62728", lw=2,
            label="Walker slice, PLANAR wedge (2D), D = 1")
    ax.plot(h["conical"], h["z"], color="#d62728", lw=1.2, ls="--",
            label="Walker slice, conical (form of paper eq. 12, virtual apex), D = 1")
    if which == "h" and "planar_D" in h:
        ax.plot(h["planar_D"], h["z"], color="#ff9896", lw=1.5, ls="-.",
                label=f"planar, D = {h['D_fit']:.2f} fitted (sigma_n = D sigma_v)"
                + (", at its range's end: not determined" if h.get("D_at_bound") else ""))


def _en1991_4_curve(ax, a: Analysis, key: str) -> None:
    """EN 1991-4's loads with the depth from the filled silo's surface (the standard's loads
    are those of the full silo).  Vertical walls: the filling load p_hf after filling (only for
    §5.3: for a slender silo it is the fitted Janssen curve already drawn), the fixed
    discharge load p_he = C_h p_hf during discharge.  Hopper walls (§6): the normal pressure
    F_f p_v after filling, F_e p_v during discharge.  The labels give the class and rule, and
    the K of filling when it is above 1 (``en["K_above_1"]``: the loads are the standard's
    formulas fed a K no fill at rest has, as the key numbers say)."""
    en = a.en1991_4
    if "p_hf" not in en:
        return
    if key == "discharge" or en["section"] == "5.3":
        what = "filling p_hf" if key == "fill" else f"discharge {en['C_h']:.3g} p_hf"
        K = (f"K of filling = {en['K']:.2f} ({ABOVE_HYDROSTATIC_SHORT['fill']})"
             if en.get("K_above_1") else "K of filling")
        inputs = f"{K}, h_c/d_c = {en['ratio']:.2f}: {en['kind']}"
        if en["section"] == "5.3":
            inputs += f", h_o = {en['h_o']:.2f} m, phi_r = {en['phi_r']:.3g} deg"
        if key == "discharge":  # the standard's discharge load is the full silo's
            inputs += f"; the full silo's, surface at z = {a.surface['fill']:.2f} m"
        ax.plot(en["p_hf"] if key == "fill" else en["p_he"], en["z"], color="#9467bd", lw=1.4,
                ls=(0, (5, 2)), label=f"EN 1991-4 §{en['section']} {what} ({inputs})")
    h = en.get("hopper", {})
    p_n = h.get("p_nf" if key == "fill" else "p_ne")
    if p_n is not None:
        what = "filling F_f p_v" if key == "fill" else "discharge F_e p_v"
        full = "" if key == "fill" else "; the full silo's"
        if key == "discharge" and wedge_exponent_departs(h):  # (the key numbers give both
            # exponents; the legend said §6 with no word that its n is not the printed one)
            full += (f"; wedge exponent n = {h['n_e']:.3g} by the slice balance, not "
                     f"§6.3.1's printed {h['n_e_printed']:.3g}")
        ax.plot(p_n, h["z"], color="#9467bd", lw=1.4, ls=(0, (1, 1)),
                label=f"EN 1991-4 §6 hopper {what} ({h['kind']}, p_vft = p_vf at the junction"
                f"{full})")


def _from_zero(ax) -> None:
    """A stress axis from zero, with a margin of 2 % of its length below it: a wall bin at
    0 Pa keeps its whole marker (the axis line hid half of it)."""
    right = ax.get_xlim()[1]
    ax.set_xlim(-0.02 * right, right)


def fig_horizontal(a: Analysis, key: str = "fill") -> Figure | None:
    """Figs. 3a (after filling) and 6 (during discharge): horizontal stress along the wall."""
    e = a.edge.get(key)
    if e is None:
        return None
    fig = Figure(figsize=(7.5, 7.5), dpi=100)
    ax = fig.subplots()
    _zone(ax, a)
    if key == "discharge" and "fill" in a.edge:
        f = a.edge["fill"]
        ax.plot(f.sigma_n, f.z, color="0.6", lw=1, marker=".", label=f"wall, {a.labels['fill']}")
    for side, (z, sn) in e.sides.items():
        ax.plot(sn, z, ls="none", marker="<" if side == "left" else ">", ms=5, alpha=0.6,
                label=f"{side} wall")
    ax.plot(e.sigma_n, e.z, color="k", lw=1.8, marker="o", ms=4,
            label="wall normal stress (both sides)")
    s = a.strips.get(key)
    if s is not None:
        ax.plot(s["near_xx"], s["z"], color="#2ca02c", lw=1.2, marker="s", ms=3,
                label="sigma_xx near the walls (Love-Weber strips)")
    _janssen_curves(ax, a, key, "h")
    _en1991_4_curve(ax, a, key)
    _hopper_curves(ax, a, "h", key)
    if key in a.peaks and np.isfinite(a.peaks[key][0]):
        v, z = a.peaks[key]
        ax.plot([v], [z], marker="*", ms=16, color="#e6550d", ls="none",
                label=f"switch-zone peak {v:,.0f} Pa at z = {z:.2f} m")
    on_hopper = " (normal stress on the hopper)" if a.res.cfg.silo.kind == "hopper" else ""
    ax.set_xlabel(f"horizontal stress sigma_h on the wall{on_hopper} [Pa]")
    _from_zero(ax)
    _z_axis(ax, a)
    title = a.labels[key]
    t0, t1 = a.windows.get(key, (np.nan, np.nan))
    ax.set_title(f"Horizontal stress along the silo wall, {title} (t = {t0:.2f}-{t1:.2f} s)",
                 fontsize=10)
    legend_below(fig, ax)
    return fig


def fig_vertical(a: Analysis, key: str = "fill") -> Figure | None:
    """Fig. 3b (after filling) and its counterpart during discharge: vertical stress along
    the wall (Love-Weber), the discharge's with the profile after filling in grey."""
    s = a.strips.get(key)
    if s is None:
        return None
    fig = Figure(figsize=(7.5, 7.5), dpi=100)
    ax = fig.subplots()
    _zone(ax, a)
    if key == "discharge" and "fill" in a.strips:
        f = a.strips["fill"]
        ax.plot(f["near_zz"], f["z"], color="0.6", lw=1, marker=".",
                label=f"sigma_zz near the walls, {a.labels['fill']}")
    ax.plot(s["near_zz"], s["z"], color="k", lw=1.8, marker="o", ms=4,
            label="sigma_zz near the walls (Love-Weber strips)")
    ax.plot(s["slice_zz"], s["z"], color="#2ca02c", lw=1.4, marker="s", ms=3,
            label="sigma_zz, mean over the cross-section")
    _janssen_curves(ax, a, key, "v")
    _hopper_curves(ax, a, "v", key)
    ax.set_xlabel("vertical stress sigma_v [Pa]")
    _from_zero(ax)
    _z_axis(ax, a)
    t0, t1 = a.windows.get(key, (np.nan, np.nan))
    when = f" (t = {t0:.2f}-{t1:.2f} s)" if key == "discharge" else ""
    ax.set_title(f"Vertical stress along the silo wall, {a.labels[key]}{when}", fontsize=10)
    legend_below(fig, ax)
    return fig


def fig_wall_shear(a: Analysis) -> Figure | None:
    """Wall shear (friction) along the silo edges, with full mobilisation mu_w sigma_n; a
    window whose mobilised friction on the Janssen fit's bins is negative says so in its
    legend (:func:`~silodem.report.flags.walls_held_up`, as in the key numbers)."""
    if not a.edge:
        return None
    fig = Figure(figsize=(7.5, 6.5), dpi=100)
    ax = fig.subplots()
    _zone(ax, a)
    for key, color in (("fill", "#1f77b4"), ("discharge", "#d62728")):
        e = a.edge.get(key)
        if e is None:
            continue
        when = a.labels[key]
        held_up = walls_held_up(a.mu_mobilised.get(key, np.nan))
        ax.plot(e.tau_down, e.z, color=color, marker="o", ms=4, lw=1.5,
                label=_flagged(f"downward shear on the wall, {when}",
                               WALLS_HELD_UP_SHORT if held_up else ""))
        mu = np.where(e.on_vertical, a.geom["mu_wall"], a.geom["mu_hopper"])  # [-]
        ax.plot(mu * e.sigma_n, e.z, color=color, lw=1, ls="--",
                label=f"tan(phi_P) sigma_n (fully mobilised), {when}")
    ax.axvline(0, color="0.4", lw=0.6)
    ax.set_xlabel("wall shear stress [Pa]")
    _z_axis(ax, a)
    ax.set_title("Wall friction along the silo wall", fontsize=10)
    legend_below(fig, ax)  # (inside, it hid the switch zone's points or the top's curves)
    return fig


def fig_evolution(a: Analysis) -> Figure | None:
    """Fig. 7: horizontal and vertical stress and their ratio at the switch zone in time."""
    m = a.res.group("measure")
    if m is None:
        return None
    t, phase = m["time"], m["phase"]
    c = m["circles"]
    n_smooth = max(1, round(0.2 / a.res.cfg.measure.interval))
    fig = Figure(figsize=(11.5, 7.5), dpi=100)
    ax1, ax2 = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    for ax in (ax1, ax2):
        shade_phases(ax, t, phase)
    ratios = []
    for k, name in enumerate(c["name"]):
        style = circle_style(k, t.size)
        sh, sv = c["stress"][:, k, 0], c["stress"][:, k, 1]
        ax1.plot(t, rolling_mean(sh, n_smooth), lw=1.5, label=f"{name}: sigma_h", **style)
        ax1.plot(t, rolling_mean(sv, n_smooth), lw=1.2, ls="--", label=f"{name}: sigma_v",
                 **style)
        # the ratio of each sample, almost unloaded ones left out (as a study's CV and its
        # Fig. 7 do), then the running mean of what is left
        ratios.append(rolling_mean(loaded_ratio(sh, sv), n_smooth))
        ax2.plot(t, ratios[-1], lw=1.3, label=str(name), **style)
    wb = a.res.group("measure", "wall_bins")
    if wb is not None:
        names = list(a.res.group("walls")["name"])
        edges = [names.index(n) for n in names if n.endswith(("_wall", "_hopper"))]
        sel = np.isin(wb["wall"], edges) & (wb["z"] >= a.switch[0]) & (wb["z"] <= a.switch[1])
        if sel.any():
            ax1.plot(t, rolling_mean(wb["normal"][:, sel].mean(axis=1), n_smooth), color="k",
                     lw=1.2, alpha=0.7, label="wall normal stress, mean over the switch zone")
    ax1.set_ylabel("stress [Pa]")
    ax1.set_ylim(bottom=0)
    legend_right(ax1, fontsize=7)
    ax1.set_title("Stresses at the switch zone during silo use (running mean over 0.2 s)",
                  fontsize=10)
    ax2.set_ylabel("sigma_h / sigma_v [-]")
    ax2.set_title(f"sigma_h / sigma_v, running mean over 0.2 s (samples with sigma_v under "
                  f"{UNLOADED:g} x its median over the run left out)", fontsize=9)
    ratio_axis(ax2, *ratios)
    ax2.set_xlabel("time [s]")
    legend_right(ax2, fontsize=7)
    tight_layout(fig)
    return fig


def fig_change(a: Analysis) -> Figure | None:
    """Fig. 8: percentage change of the switch-zone stresses from filling to discharge, each
    bar with its standard error (batch means of each window, propagated); a bar within its
    error (not resolved) is drawn pale."""
    if not a.change:
        return None
    names = list(a.change)
    if not np.isfinite([a.change[n].get(f"{c}_change_pct", np.nan) for n in names
                        for c in ("sigma_h", "sigma_v")]).any():
        return None
    fig = Figure(figsize=(10, 4.8), dpi=100)  # (room for the legend on the right)
    ax = fig.subplots()
    x = np.arange(len(names))
    kinds = ((-0.2, "sigma_h", "horizontal stress", "#1f77b4"),
             (0.2, "sigma_v", "vertical stress", "#ff7f0e"))
    for shift, comp, label, color in kinds:
        pct = np.array([a.change[n].get(f"{comp}_change_pct", np.nan) for n in names])
        err = np.array([a.change[n].get(f"{comp}_change_pct_err", np.nan) for n in names])
        bars = ax.bar(x + shift, pct, 0.4, yerr=np.nan_to_num(err), color=color, label=label,
                      capsize=3, error_kw={"elinewidth": 1.0, "ecolor": "k"})
        for bar, p, e in zip(bars, pct, err):
            if np.isfinite(p) and not resolved(p, e):
                bar.set_alpha(0.35)
    ax.axhline(0, color="k", lw=0.8)
    # the wall peak's bar is the wall normal stress, each window's largest in the switch zone
    ticks = ["wall peak (normal,\neach window's own)" if n == "wall peak" else n for n in names]
    ax.set_xticks(x, ticks, fontsize=8)
    ax.set_ylabel("change, discharge vs end of filling [%]")
    ax.set_title("Change of the switch-zone stresses from filling to discharge\n(error bars: "
                 f"+- 1 standard error, batch means of each window's samples in {BATCHES} "
                 "blocks)", fontsize=10)
    # the key drawn from the colours, not from each kind's first bar (drawn pale when its
    # change was not resolved), with the pale bars' key in both colours (it was grey)
    handles = [Patch(color=color) for *_, color in kinds]
    pale = tuple(Patch(color=color, alpha=0.35) for *_, color in kinds)
    legend_right(ax, handles=[*handles, pale],
                 labels=[label for _, _, label, _ in kinds]
                 + ["pale: within its error, not resolved"],
                 handler_map={tuple: HandlerTuple(ndivide=None)}, fontsize=8)
    tight_layout(fig)
    return fig


def window_time(a: Analysis, window: str) -> float:
    """The moment the field window ``window`` is drawn at [s]: its snapshot's (NaN without)."""
    snap = a.res.snapshot(window)
    return float(snap["@attrs"].get("time", np.nan)) if isinstance(snap, dict) else np.nan


def walls_active_in(a: Analysis, window: str) -> np.ndarray:
    """Which walls stand [bool per wall] in the field window ``window``: the walls_active of
    the snapshot of that moment (/settled for "settled", /measure/discharge_snapshot for
    "discharge"); without the snapshot, all of them while settling (the gate opens only for
    the discharge) and the run's last state (/walls/active) during discharge."""
    walls = a.res.group("walls")
    snap = a.res.snapshot(window)
    if isinstance(snap, dict) and "walls_active" in snap:
        return np.asarray(snap["walls_active"], dtype=bool)
    if window == "settled":
        return np.ones(len(walls["ax"]), dtype=bool)
    return np.asarray(walls.get("active", np.ones(len(walls["ax"]))), dtype=bool)


def fig_fields(a: Analysis) -> Figure | None:
    """Bulk density and the Love-Weber stresses sigma_xx, sigma_zz on the field grid, of the
    settled packing and averaged over the discharge window (one row each)."""
    f = a.res.group("measure", "fields")
    if f is None:
        return None
    rows = [(w, f[w]) for w in ("settled", "discharge")
            if w in f and f[w]["@attrs"].get("samples", 0) > 0]
    if not rows:
        return None
    xe, ze = f["x_edges"], f["z_edges"]
    inside = silo_shape(a.res.cfg).outline()
    # constrained: the colour bars' labels keep clear of the next panel's axis label
    fig = Figure(figsize=(12, 5.2 * len(rows)), dpi=90, layout="constrained")
    fig.get_layout_engine().set(wspace=0.08)
    axes = np.atleast_2d(fig.subplots(len(rows), 3))
    # one colour scale per quantity, shared by the two rows
    quantities = [("bulk density [kg/m^3]", lambda g: g["density"], "cividis"),
                  ("sigma_xx [Pa]", lambda g: g["stress"][..., 0], "magma"),
                  ("sigma_zz [Pa]", lambda g: g["stress"][..., 1], "magma")]
    for col, (label, get, cmap) in enumerate(quantities):
        values = [get(g) for _, g in rows]
        finite = np.concatenate([v[np.isfinite(v)] for v in values])
        top = (float(np.percentile(finite, 99)) if finite.size else 0.0) or 1.0
        for row, ((window, _), v) in enumerate(zip(rows, values)):
            ax = axes[row, col]
            pm = ax.pcolormesh(xe, ze, v.T, cmap=cmap, vmin=0.0, vmax=top, shading="flat")
            # a cell cut by a hopper wall holds the value of its inside part (A_c, fields.py)
            pm.set_clip_path(Polygon(inside, transform=ax.transData))
            active = walls_active_in(a, window)
            draw_walls(ax, walls_at(a.res.group("walls"), a.res.events,
                                    window_time(a, window), active), active)
            silo_axes(ax, a.geom)
            ax.set_title(f"{label.split(' [')[0]}, {window}", fontsize=9)
            fig.colorbar(pm, ax=ax, shrink=0.7, label=label)
    return fig
