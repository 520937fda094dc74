"""The figures of the validation suite (PNG, matplotlib's Agg backend).  Each takes the data a
case family returned and a file path; they only draw."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

DPI = 90


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def tight_layout(fig) -> None:
    """The report's ``tight_layout`` (no layout engine left behind, so ``savefig`` draws once),
    imported when a figure is drawn: matplotlib stays out of ``silodem validate``'s start."""
    from silodem.report.draw import tight_layout as layout

    layout(fig)


def _save(fig, path: Path) -> Path:
    """PNG with a 256-colour palette (line plots lose nothing; the files are ~3x smaller)."""
    import io

    from PIL import Image

    path.parent.mkdir(parents=True, exist_ok=True)
    buf = io.BytesIO()
    fig.savefig(buf, dpi=DPI, format="png")
    _plt().close(fig)
    buf.seek(0)
    with Image.open(buf) as img:
        img.convert("RGB").quantize(colors=256).save(path, format="PNG", optimize=True)
    return path


def impacts(data: dict[str, Any], path: Path) -> Path:
    """Restitution and contact duration against e, analytic curves; error against dt."""
    from silodem.engine.contact import damping_ratio_from_restitution
    from silodem.validate.impacts import spring_dashpot

    plt = _plt()
    results, convergence = data["checked"], data["convergence"]
    fig, ax = plt.subplots(1, 3, figsize=(13, 4))
    es = np.linspace(0.1, 1.0, 91)
    refs = [spring_dashpot(1.0, 1.0, damping_ratio_from_restitution(e)) for e in es]
    ax[0].plot(es, [r.e for r in refs], "k-", lw=1, label="analytic, tension (e)")
    ax[0].plot(es, [r.e_star for r in refs], "k--", lw=1, label="analytic, no tension (e*)")
    ax[1].plot(es, [r.t_c * r.w0 / math.pi for r in refs], "k-", lw=1, label="pi/w_d")
    ax[1].plot(es, [r.t_star * r.w0 / math.pi for r in refs], "k--", lw=1,
               label="t* (no tension)")
    for r in results:
        mk = "o" if r.geometry == "disk-disk" else "s"
        col = "C0" if r.tension else "C3"
        ax[0].plot(r.e_nominal, r.e, mk, color=col, mfc="none", ms=5)
        ax[1].plot(r.e_nominal, r.t * r.w0 / math.pi, mk, color=col, mfc="none", ms=5)
    ax[0].set(xlabel="nominal restitution e", ylabel="restitution measured",
              title="normal impact: restitution")
    ax[1].set(xlabel="nominal restitution e", ylabel="contact duration x w0 / pi",
              title="normal impact: duration")
    for a in ax[:2]:
        a.plot([], [], "o", color="k", mfc="none", label="disk-disk")
        a.plot([], [], "s", color="k", mfc="none", label="disk-wall")
        a.plot([], [], "-", color="C0", label="DEM, tension")
        a.plot([], [], "-", color="C3", label="DEM, no tension")
        a.legend(fontsize=7)
    for (geometry, e), pts in convergence.items():
        if geometry != "disk-wall":  # disk-disk gives the same relative errors (scale-free)
            continue
        n = np.array([p[0] for p in pts], dtype=float)
        err = np.array([abs(p[1] if e < 1 else p[2]) for p in pts])
        what = "restitution" if e < 1 else "duration"
        ax[2].loglog(n, err, "o-", ms=4, label=f"e={e:g} ({what})")
    n = np.array([16.0, 2000.0])
    ax[2].loglog(n, 0.5 * 16.0 / n * 1e-1, "k:", lw=1, label="slope -1")
    ax[2].loglog(n, (16.0 / n) ** 2 * 1e-3, "k--", lw=1, label="slope -2")
    ax[2].axhline(5e-3, color="gray", lw=0.8)
    ax[2].axvline(data["silo_steps"], color="C1", lw=0.8, ls="--")
    ax[2].set(xlabel="steps per contact t_c/dt", ylabel="|relative error|",
              title="convergence (tension allowed; dashed: paper-case2 dt)")
    ax[2].legend(fontsize=7, loc="lower left")
    tight_layout(fig)
    return _save(fig, path)


def chung_ooi(data: dict[str, Any], path: Path) -> Path:
    from silodem.validate.chung_ooi import (
        KAPPA_DISK,
        rigid_wall_impact,
        sliding_limit,
        sticking_tangential_restitution,
    )

    plt = _plt()
    fig, ax = plt.subplots(2, 3, figsize=(13, 7.5))
    t4 = data["test4"]
    ang = t4["angle"]
    fine = np.linspace(1.0, 89.0, 300)
    rb = [rigid_wall_impact(t4["v"] * math.cos(math.radians(a)),
                            t4["v"] * math.sin(math.radians(a)), 0.0, t4["r"], t4["e"], t4["mu"])
          for a in fine]
    slide = np.array([r.sliding for r in rb])
    vt0 = t4["v"] * np.sin(np.radians(fine))
    curves = {
        "et": np.array([r.vt for r in rb]) / vt0,
        "omega": np.array([r.omega for r in rb]),
        "rebound": np.degrees(np.arctan2([r.vt for r in rb], [r.vn for r in rb])),
    }
    labels = {"et": "tangential restitution v_t'/v_t", "omega": "spin after [rad/s]",
              "rebound": "rebound angle [deg]"}
    for a, key in zip(ax[0], ("et", "omega", "rebound")):
        a.plot(fine[slide], curves[key][slide], "k-", lw=1, label="rigid body, gross sliding")
        a.plot(fine[~slide], curves[key][~slide], "k--", lw=1, label="rigid body, sticking")
        a.plot(ang, t4[key], "o", color="C0", mfc="none", ms=5, label="DEM")
        a.axvline(t4["limit"][0], color="gray", lw=0.8)
        a.set(xlabel="incident angle from the normal [deg]", ylabel=labels[key],
              title=f"test 4: |v| = {t4['v']} m/s, mu = {t4['mu']}")
        a.legend(fontsize=7)
    ax[0][0].axhline(sticking_tangential_restitution(), color="gray", lw=0.8, ls=":")
    k = sliding_limit()
    p = np.linspace(0.0, 10.5, 200)
    t5, t6 = data["test5"], data["test6"]
    ax[1][0].plot(p, np.where(p >= k, p - k, 0.0), "k-", lw=1, label="rigid body")
    ax[1][0].plot(t5["psi1"], t5["psi2"], "o", mfc="none", label="test 5 (varying v_t)")
    ax[1][0].plot(t6["psi1"], t6["psi2"], "s", mfc="none", label="test 6 (varying spin)")
    ax[1][0].set(xlabel="Psi_1 = u/(mu(1+e)v_n)", ylabel="Psi_2 = u'/(mu(1+e)v_n)",
                 title="tests 5-6: normalised recoil slip")
    ax[1][0].legend(fontsize=7)
    ax[1][1].plot(p, np.where(p >= k, -1.0 / KAPPA_DISK, -p / (1.0 + KAPPA_DISK)), "k-",
                  lw=1, label="rigid body")
    ax[1][1].plot(t5["psi1"], t5["spin"], "o", mfc="none", label="test 5: w'R/(mu(1+e)v_n)")
    ax[1][1].plot(t6["psi1"], t6["vt"], "s", mfc="none", label="test 6: v_t'/(mu(1+e)v_n)")
    ax[1][1].plot(p, np.where(p >= k, -1.0, -p / (1.0 + 1.0 / KAPPA_DISK)), "k:", lw=1)
    ax[1][1].set(xlabel="Psi_1", ylabel="normalised spin / rebound velocity",
                 title="tests 5-6: spin and rebound")
    ax[1][1].legend(fontsize=7)
    for key, mk in (("test7", "o"), ("test8", "s")):
        t = data[key]
        ax[1][2].plot(t["psi1"], t["spin1"], mk, mfc="none",
                      label=f"{key}: disk 1 (r2/r1 = {t['r2'] / t['r1']:g})")
        ax[1][2].plot(t["psi1"], t["spin2"], mk, label=f"{key}: disk 2")
    ax[1][2].plot(p, -np.minimum(p / k, 1.0) / KAPPA_DISK, "k-", lw=1, label="rigid body")
    ax[1][2].set(xlabel="Psi_1 = |u|/(mu(1+e)g_n)", ylabel="dw_i r_i m_i / (m* mu(1+e)g_n)",
                 title="tests 7-8: two disks")
    ax[1][2].legend(fontsize=7)
    tight_layout(fig)
    return _save(fig, path)


def hertz_mindlin(data: dict[str, Any], path: Path) -> Path:
    """F_n against the overlap of the undamped impacts with Hertz's law; restitution against
    impact speed."""
    plt = _plt()
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    for (geometry, (overlap, fn, k_hertz)), col in zip(data["law"].items(), ("C0", "C3")):
        d = np.linspace(0.0, overlap.max(), 200)
        ax[0].plot(d * 1e6, k_hertz * d**1.5, "-", color="k", lw=0.8)
        ax[0].plot(overlap[::20] * 1e6, fn[::20], "o", color=col, mfc="none", ms=4,
                   label=f"DEM, {geometry}")
    ax[0].plot([], [], "k-", lw=0.8, label="4/3 E* sqrt(R*) delta^(3/2)")
    ax[0].set(xlabel="overlap [um]", ylabel="normal force [N]",
              title="Hertz's force, undamped impact at 1 m/s")
    ax[0].legend(fontsize=8)
    for e, tension, v, got, expected in data["restitution"]:
        col = "C0" if tension else "C3"
        ax[1].plot(v, got, "o", color=col, mfc="none", ms=6)
        ax[1].plot(v, expected, "_", color="k", ms=14)
    ax[1].plot([], [], "o", color="C0", mfc="none", label="DEM, tension (e = 0.1, 0.5, 0.9)")
    ax[1].plot([], [], "o", color="C3", mfc="none", label="DEM, no tension")
    ax[1].plot([], [], "_", color="k", ms=14, label="e asked / e* integrated")
    ax[1].set(xscale="log", xlabel="impact speed [m/s]", ylabel="restitution",
              title="Tsuji's dashpot: one restitution at every speed")
    ax[1].legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, 0.86))
    tight_layout(fig)
    return _save(fig, path)


def statics(data: dict[str, Any], path: Path) -> Path:
    plt = _plt()
    fig, ax = plt.subplots(1, 2, figsize=(8, 5), gridspec_kw={"width_ratios": [1, 2]})
    from matplotlib.collections import PatchCollection
    from matplotlib.patches import Circle

    ax[0].add_collection(PatchCollection([Circle((x, y), r) for x, y, r in
                                          zip(data["x"], data["y"], data["r"])],
                                         facecolor="C0", edgecolor="k", lw=0.3))
    ax[0].set(xlim=(-0.05, data["width"] + 0.05), ylim=(-0.05, data["height"] * 0.8),
              aspect="equal", title="settled column")
    w = data["weight"]
    names = data["walls"]
    f = -data["mean_force"][:, 1] / w
    ax[1].bar(names + ["sum"], list(f) + [f.sum()], color=["C0"] * len(names) + ["C2"])
    ax[1].axhline(1.0, color="k", lw=0.8)
    ax[1].set(ylabel="downward force of the grains / weight",
              title="floor + walls carry the weight")
    tight_layout(fig)
    return _save(fig, path)


def janssen(data: dict[str, Any], path: Path) -> Path:
    """Wall normal stress against depth with the Janssen curves; friction and K profiles."""
    from silodem import theory as th

    plt = _plt()
    fig, ax = plt.subplots(1, 3, figsize=(13, 5), gridspec_kw={"width_ratios": [2, 1, 1]})
    depth, sn, cell = data["depth"], data["sigma_n"], data["cell"]
    ax[0].plot(sn[cell], depth[cell], ".", color="C0", ms=3, alpha=0.6,
               label="DEM wall normal stress (bins of 4 d, all fills)")
    edges = np.linspace(0.0, depth[cell].max(), 21)
    k = np.digitize(depth[cell], edges)
    means = [sn[cell][k == i].mean() if np.any(k == i) else np.nan for i in range(1, 21)]
    ax[0].plot(means, 0.5 * (edges[1:] + edges[:-1]), "o-", color="C0", lw=2, ms=4,
               label="mean over depth bins")
    z = np.linspace(0.0, depth[cell].max(), 200)
    rho, g, B = data["rho_b"], data["g"], data["B"]
    ax[0].plot(th.janssen_sigma_h(z, rho, g, B, data["K_fit"], data["mu_mob"]), z, "k-",
               label=f"Janssen fit: K = {data['K_fit']:.2f}, mu_w = {data['mu_mob']:.3f} "
               "(mobilised)")
    ax[0].plot(th.janssen_sigma_h(z, rho, g, B, data["K_tensor"], data["mu_w"]), z, "k--",
               label=f"Janssen with K_tensor = {data['K_tensor']:.2f}, tan(phi_w) = "
               f"{data['mu_w']:.3f}")
    ax[0].axvline(rho * g * B / (2 * data["mu_mob"]), color="k", ls=":", lw=1,
                  label="saturation rho_b g B / (2 mu_mob) (checked)")
    ax[0].axvline(rho * g * B / (2 * data["mu_w"]), color="gray", ls=":", lw=1,
                  label="saturation rho_b g B / (2 tan phi_w)")
    ax[0].axhline(3 * data["length"], color="C1", lw=0.8, label="3 Janssen lengths")
    ax[0].invert_yaxis()
    ax[0].set(xlabel="wall normal stress sigma_h [Pa]", ylabel="depth below the surface [m]",
              title="Janssen: 2D slot silo after the floor was lowered")
    ax[0].legend(fontsize=7, loc="upper right")
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = data["tau_down"][cell] / sn[cell]
    ax[1].plot(ratio, depth[cell], ".", ms=3)
    ax[1].axvline(data["mu_w"], color="k", lw=1, label="tan(phi_w)")
    ax[1].axvline(data["mu_mob"], color="C1", lw=1, ls="--", label="mobilised (all bins)")
    ax[1].set(xlim=(-0.1, 0.5), xlabel="tau / sigma_n at the wall", title="wall friction")
    ax[1].invert_yaxis()
    ax[1].legend(fontsize=7)
    sc = data["s_cell"]
    with np.errstate(invalid="ignore", divide="ignore"):
        kk = data["near"][sc, 0] / data["near"][sc, 1]
    ax[2].plot(kk, data["s_depth"][sc], ".", ms=3, label="sigma_xx/sigma_zz near the wall")
    ax[2].axvline(data["K_tensor"], color="C1", lw=1, ls="--", label="K_tensor (all bins)")
    ax[2].axvline(data["K_fit"], color="k", lw=1, label="K fitted (wall profile)")
    ax[2].set(xlim=(0, 2.5), xlabel="K", title="lateral stress ratio")
    ax[2].invert_yaxis()
    ax[2].legend(fontsize=7)
    tight_layout(fig)
    return _save(fig, path)


def beverloo(data: dict[str, Any], path: Path) -> Path:
    """Discharged mass against time; W^(2/3) against D (straight for the 3/2 law); log-log."""
    plt = _plt()
    fig, ax = plt.subplots(1, 3, figsize=(13, 4.2))
    runs, d = data["rates"], data["d"]
    for k, r in enumerate(runs):
        for j, one in enumerate(r.runs):
            ax[0].plot(one.t, one.m, "-", lw=1, color=f"C{k}",
                       label=f"D/d = {r.D / d:g}" if j == 0 else None)
    for r, ls in ((data["base"], ":"), (data["tall"], "--")):
        for j, one in enumerate(r.runs):
            ax[0].plot(one.t, one.m, ls, color="k", lw=1,
                       label=f"D/d = {r.D / d:g}, H = {r.H / d:.0f} d" if j == 0 else None)
    ax[0].set(xlabel="time after opening [s]", ylabel="discharged mass [kg]",
              title="discharge with re-insertion")
    ax[0].legend(fontsize=7)
    D = np.array([r.D for r in runs])
    W = np.array([r.rate for r in runs])
    err = np.array([r.err for r in runs])
    fixed, free = data["fixed"], data["free"]
    scale = data["rho_b"] * math.sqrt(data["g"]) * data["t"]
    x = np.linspace(0.0, D.max() * 1.05, 200)
    ax[1].errorbar(D / d, W ** (2 / 3), yerr=(2 / 3) * err * W ** (-1 / 3), fmt="o",
                   label="DEM (+- batch-means error)")
    ax[1].plot(x / d, (fixed.C * scale) ** (2 / 3) * np.maximum(x - fixed.k * d, 0.0), "k-",
               label=f"3/2 law: C = {fixed.C:.3g}, k = {fixed.k:.2f}")
    ax[1].set(xlabel="outlet width D/d", ylabel="W^(2/3) [(kg/s)^(2/3)]",
              title="Beverloo 2D: W^(2/3) linear in D")
    ax[1].legend(fontsize=7)
    xs = D - free.k * d
    ax[2].errorbar(xs / d, W, yerr=err, fmt="o", label="DEM")
    xx = np.linspace(xs.min() * 0.9, xs.max() * 1.1, 100)
    ax[2].loglog(xx / d, free.C * scale * xx**free.b, "k-",
                 label=f"free fit: b = {free.b:.3f} +- {free.b_err:.2g}, k = {free.k:.2f}")
    ax[2].loglog(xx / d, free.C * scale * xx**1.5 * (xs.mean() ** (free.b - 1.5)), "k:",
                 label="slope 3/2")
    ax[2].set(xlabel="(D - k d)/d", ylabel="W [kg/s]", title="exponent")
    ax[2].legend(fontsize=7)
    tight_layout(fig)
    return _save(fig, path)


def lammps(data: dict[str, Any], path: Path) -> Path:
    """The largest position difference between silodem and LAMMPS against the step."""
    from silodem.validate.lammps import TOLERANCE

    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for k, (name, (steps, dev, checked)) in enumerate(data.items()):
        ax.semilogy(steps[1:], np.maximum(dev[1:], 1e-17), color=f"C{k}", label=name)
        ax.axvline(checked, color=f"C{k}", lw=0.8, ls=":")
    ax.axhline(TOLERANCE, color="k", lw=0.8, ls="--", label="tolerance")
    if not data:
        ax.text(0.5, 0.5, "no comparison: lmp absent or failed", ha="center",
                transform=ax.transAxes)
    ax.set(xlabel="step (dt = 2e-4 s)", ylabel="largest position difference [m]",
           title="silodem against LAMMPS, grain by grain")
    ax.legend(fontsize=8)
    tight_layout(fig)
    return _save(fig, path)
