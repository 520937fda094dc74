"""Figures of the grains: force networks (the paper's Figs. 4 and 5) and the discharge (flow
rate, velocity field, dead zones).  Each function returns a matplotlib Figure or None."""

from __future__ import annotations

import numpy as np
from matplotlib import colormaps
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import Polygon

from silodem.measure.discharge import lost_grains
from silodem.report.analysis import DEAD_TO, Analysis
from silodem.report.draw import (
    draw_force_network,
    draw_grains,
    draw_walls,
    grain_disks,
    legend_right,
    silo_axes,
    tight_layout,
)
from silodem.report.key_numbers import mfi_where
from silodem.report.numbers import significant
from silodem.silo.geometry import silo_shape


def _snaps(a: Analysis) -> list[tuple[str, dict]]:
    out = []
    for name, label in (("settled", "after filling"), ("discharge", "during discharge")):
        s = a.res.snapshot(name)
        if s is not None:
            out.append((label + f", t = {s['@attrs'].get('time', np.nan):.2f} s", s))
    return out


def _common_scale(snaps) -> float:
    f = [np.concatenate([s["contacts"]["fn"], s["wall_contacts"]["fn"]]) for _, s in snaps]
    f = np.concatenate(f) if f else np.zeros(0)
    return float(f.max()) if f.size and f.max() > 0 else 1.0


def fig_network(a: Analysis) -> Figure | None:
    """Fig. 5: the contact force network in the whole silo, after filling and during
    discharge, line width and colour proportional to the normal force (same scale)."""
    snaps = _snaps(a)
    if not snaps:
        return None
    walls = a.res.group("walls")
    fmax = _common_scale(snaps)
    fig = Figure(figsize=(4.4 * len(snaps) + 1.2, 7.6), dpi=110, layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(snaps)))
    lc = None
    for ax, (title, snap) in zip(axes, snaps):
        lc, _ = draw_force_network(ax, snap, walls, fmax, events=a.res.events)
        silo_axes(ax, a.geom)
        ax.set_title(f"force network {title}", fontsize=9)
    if lc is not None:
        fig.colorbar(lc, ax=list(axes), shrink=0.6, label="normal contact force [N]")
    return fig


def fig_switch_network(a: Analysis) -> Figure | None:
    """Fig. 4: the force network zoomed on the switch zone, after filling and during
    discharge (same force scale): does the stress increase or decrease there?"""
    snaps = _snaps(a)
    if not snaps:
        return None
    walls = a.res.group("walls")
    g = a.geom
    zc = 0.5 * (a.switch[0] + a.switch[1])
    half = max(1.2, 0.5 * (a.switch[1] - a.switch[0]) + 0.6)
    xs = [(-0.2, min(g["B"], 2 * half) + 0.1)]
    walls_seen = "both walls" if g["B"] <= 2 * half else "left wall"  # a narrow silo: whole
    fmax = _common_scale(snaps)
    ys = (max(zc - half, -0.3), zc + half)
    # the height that an equal-aspect panel 3.6 in wide needs, with room for the title and
    # the x label (a fixed 4.6 in cut the titles of a tall zoom, e.g. a 75-deg hopper's)
    tall = (ys[1] - ys[0]) / (xs[0][1] - xs[0][0])
    fig = Figure(figsize=(4.6 * len(snaps) + 1.2, min(max(3.6 * tall + 1.0, 3.0), 9.0)),
                 dpi=110, layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(snaps)))
    lc = None
    for ax, (title, snap) in zip(axes, snaps):
        lc, _ = draw_force_network(ax, snap, walls, fmax, max_width=6.0, events=a.res.events)
        ax.set_aspect("equal")
        ax.set_xlim(*xs[0])
        ax.set_ylim(*ys)
        ax.axhspan(*a.switch, color="#f6e7b5", alpha=0.35, zorder=0)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("z [m]")
        ax.set_title(f"switch zone ({walls_seen}), {title}", fontsize=9)
    if lc is not None:
        fig.colorbar(lc, ax=list(axes), shrink=0.8, label="normal contact force [N]")
    return fig


def fig_discharge_rate(a: Analysis) -> Figure | None:
    """Discharged mass and mass flow rate against time, with the steady rate and its error,
    and where a gate slides open, the moment it clears the outlet (event gate_opening_time)."""
    f = a.flow
    if "t" not in f or f["t"].size < 2:
        return None
    fig = Figure(figsize=(9, 6.5), dpi=100)
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    t, m, r = f["t"], f["mass"], f["rate"]
    ax1.plot(t, m, color="k", lw=1.5, label="discharged mass")
    if np.isfinite(r.rate):
        # the least-squares line itself: through the centroid of the samples it fitted (it
        # went through the mass at the interval's middle, up to 5 grains under the curve)
        tt, fitted = np.array([r.t0, r.t1]), (t >= r.t0) & (t <= r.t1)
        tc, mc = float(t[fitted].mean()), float(m[fitted].mean())
        ax1.plot(tt, mc + r.rate * (tt - tc), color="#d62728", lw=2.5,
                 alpha=0.8, label=f"steady rate W = {significant(r.rate, 4)} +- "
                 f"{significant(r.err, 2)} kg/s")  # (as the key numbers write it)
    ax1.set_ylabel("mass [kg]")
    ax1.legend(fontsize=8)
    ts, rs = f["series"]
    ax2.plot(ts, rs, color="k", lw=1.2, label="flow rate (0.25 s window)")
    if np.isfinite(r.rate):
        ax2.axhspan(r.rate - r.err, r.rate + r.err, color="#d62728", alpha=0.25)
        ax2.axhline(r.rate, color="#d62728", lw=1.5, label="steady rate +- standard error")
        ax2.axvspan(r.t0, r.t1, color="0.9", zorder=0, label="interval of the steady fit")
    clear = float(a.res.events.get("gate_opening_time", 0.0))  # a gate that slides open
    if clear > 0.0:
        for ax in (ax1, ax2):
            ax.axvline(clear, color="0.35", lw=1.0, ls="--",
                       label="outlet clear: the sliding gate open" if ax is ax2 else None)
    ax2.set_xlabel("time since the gate began to open [s]" if clear > 0.0 else
                   "time since the gate opened [s]")
    ax2.set_ylabel("mass flow rate [kg/s]")
    ax2.legend(fontsize=8)
    tight_layout(fig)
    return fig


def fig_velocity(a: Analysis) -> Figure | None:
    """Mean velocity field over the discharge window: speed map and arrows."""
    f = a.res.group("measure", "flow")
    if f is None or f["grid"]["@attrs"].get("samples", 0) == 0:
        return None
    gr = f["grid"]
    xe, ze, vx, vz = gr["x_edges"], gr["z_edges"], gr["vx"], gr["vz"]
    occ = gr["occupancy"]
    speed = np.where(occ > 0.05, np.hypot(vx, vz), np.nan)
    fig = Figure(figsize=(6.2, 8.2), dpi=100)
    ax = fig.subplots()
    # the scale from 0: a slow (near dead) region reads as dark, whatever the fastest speed
    pm = ax.pcolormesh(xe, ze, speed.T, cmap="viridis", shading="flat", vmin=0.0)
    # the cells cut by a hopper wall drawn only inside the silo, as the fields' figure does
    pm.set_clip_path(Polygon(silo_shape(a.res.cfg).outline(), transform=ax.transData))
    xc, zc = 0.5 * (xe[:-1] + xe[1:]), 0.5 * (ze[:-1] + ze[1:])
    X, Z = np.meshgrid(xc, zc, indexing="ij")
    ok = np.isfinite(speed)
    ax.quiver(X[ok], Z[ok], vx[ok], vz[ok], color="w", scale_units="xy", angles="xy",
              width=0.004)
    draw_walls(ax, a.res.group("walls"))
    silo_axes(ax, a.geom)
    w0, w1 = a.windows.get("discharge", (np.nan, np.nan))
    ax.set_title(f"mean velocity during discharge (t = {w0:.2f}-{w1:.2f} s)\n"
                 f"flow pattern: {a.flow.get('pattern', 'n/a')}, mass flow index v_wall / "
                 f"v_axis = {a.flow.get('mfi', np.nan):.2f}\n(measured {mfi_where(a)})",
                 fontsize=9)
    fig.colorbar(pm, ax=ax, shrink=0.6, label="speed [m/s]")
    return fig


# plasma without its darkest third: its first colour, a navy, was hard to tell from the dead
# zone's black (a bottom row that left at once read as dead); from 0.35 on, every colour has a
# contrast of 3:1 or more against black, WCAG 2.1's least for graphical objects (SC 1.4.11)
EXIT_CMAP = ListedColormap(colormaps["plasma"](np.linspace(0.35, 1.0, 256)), name="plasma_light")


def lost_note(before: int, during: int) -> str:
    """The dead-zone map's words for ``before`` grains lost through a wall before the gate
    opened and ``during`` after it (not both 0)."""
    total = before + during
    head = f"{total} grain{'s' if total > 1 else ''} lost through a wall"
    if before and during:
        return f"{head}: {before} before the gate opened, {during} after"
    return f"{head} {'before' if before else 'after'} the gate opened"


def fig_dead_zones(a: Analysis) -> Figure | None:
    """The grains at the gate opening coloured by the time they left; the dead zone (neither
    left nor moved more than a grain radius up to the discharge window's end,
    ``measure.discharge.dead_zone``) in black, whenever they left; the grains lost through a wall,
    before the gate opened or after (``measure.discharge.lost_grains``), as dashed outlines,
    neither left nor dead."""
    f = a.res.group("measure", "flow")
    if f is None or f["uid"].size == 0 or "dead" not in a.flow:
        return None
    fig = Figure(figsize=(6.2, 8.2), dpi=100)
    ax = fig.subplots()
    p = {"x": f["x0"], "y": f["z0"], "radius": f["r0"]}
    exit_t = f["exit_time"]
    before, during = lost_grains(f)
    lost = before | during
    dead = a.flow.get("dead", np.zeros(exit_t.size, bool)) & ~lost
    left = np.isfinite(exit_t) & ~lost & ~dead
    stayed = ~left & ~dead & ~lost
    draw_grains(ax, {k: v[stayed] for k, v in p.items()}, color="#cccccc", edge="#999999")
    draw_grains(ax, {k: v[dead] for k, v in p.items()}, color="k", edge="k")
    pc = grain_disks(ax, {k: v[left] for k, v in p.items()}, cmap=EXIT_CMAP, edgecolor="none",
                     array=exit_t[left])
    if lost.any():
        grain_disks(ax, {k: v[lost] for k, v in p.items()}, facecolors="none",
                    edgecolors="#555555", linewidths=0.8, linestyles="--")
    draw_walls(ax, a.res.group("walls"), np.ones(len(a.res.group("walls")["ax"]), bool))
    silo_axes(ax, a.geom)
    note = f"\ndashed: {lost_note(int(before.sum()), int(during.sum()))}" if lost.any() else ""
    # the grains that were no longer in the silo at the opening (the closed gate lets none
    # out: each fell out through a wall) are not on the map, yet counted in the run's total
    gone = int(a.res.events.get("n_poured", f["uid"].size)) - int(f["uid"].size)
    if gone > 0:
        note += (f"\n{'more: ' if lost.any() else ''}{gone} grain{'s' if gone > 1 else ''} "
                 "fell out through a wall before the gate opened (not drawn)")
    to = a.flow.get("dead_to", DEAD_TO)
    share = a.flow.get("dead_fraction", 0.0)
    share = (f"{100 * share:.1f} % of the grains" if np.isfinite(share) else
             "none told: no grain had left by then")
    ax.set_title(f"when each grain left the silo\nblack: dead zone, at rest to {to} "
                 f"({share})\n"
                 f"grey: still inside at the end{note}", fontsize=9)
    if left.any():
        fig.colorbar(pc, ax=ax, shrink=0.6, label="exit time after the gate opened [s]")
    return fig


def fig_composition(a: Analysis) -> Figure | None:
    """Size segregation in the discharge (``measure.discharge.discharge_composition``): each
    tenth of the discharged mass's mass mean diameter over the fill's, with the band chance
    alone gives, and for a mixture of a few sizes each size's share of that tenth's mass
    beside its share of the fill, with its band too.  None for grains all of one size: a
    flat line at 1 in a band of no width (the key numbers say so)."""
    c = a.flow.get("composition")
    if c is None or c.one_size:
        return None
    mixture = c.sizes.size > 1
    fig = Figure(figsize=(10.5, 6.5 if mixture else 3.8), dpi=100)  # (legends on the right)
    axes = fig.subplots(2 if mixture else 1, 1, sharex=True, squeeze=False)[:, 0]
    x = 100 * c.fraction
    ax = axes[0]
    ax.axhline(1.0, color="0.5", lw=1, ls="--", label="the fill's (no segregation)")
    ax.fill_between(x, c.chance_lo, c.chance_hi, color="0.85",
                    label="chance: 90 % of random\ndeparture orders of the\nsame grains")
    ax.plot(x, c.diameter_ratio, "o-", color="k", lw=1.5,
            label="each tenth of the discharged mass")
    ax.set_ylabel("mass mean diameter /\nthe fill's [-]")
    legend_right(ax, fontsize=8)  # (inside, it hid the tenths in the band's middle)
    if mixture:
        ax2 = axes[1]
        for j, size in enumerate(c.sizes):
            line = ax2.plot(x, 100 * c.size_share[:, j], "o-", lw=1.5,
                            label=f"r = {significant(size, 3)} m")[0]
            ax2.axhline(100 * c.fill_share[j], color=line.get_color(), lw=1, ls="--")
            ax2.fill_between(x, 100 * c.share_lo[:, j], 100 * c.share_hi[:, j],
                             color=line.get_color(), alpha=0.18, lw=0,
                             label=f"chance, r = {significant(size, 3)} m")
        ax2.set_ylabel("share of the tenth's mass [%]\n(dashed: of the fill's;\n"
                       "bands: chance, as above)")
        legend_right(ax2, fontsize=8)
    axes[-1].set_xlabel("discharged mass, middle of each tenth [%]")
    tight_layout(fig)
    return fig
