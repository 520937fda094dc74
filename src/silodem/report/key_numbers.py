"""The report's key numbers in words: the (quantity, value, unit) rows of report.html's table
and of ``api.RunResults.numbers()``, written from an
:class:`~silodem.report.analysis.Analysis` by :func:`add_numbers` (the last thing
:func:`~silodem.report.analysis.analyse` does), each number with its error and what the
flags (:mod:`silodem.report.flags`) say of it; :func:`mfi_where`, where the mass flow index is
measured, is shared with the flow figure."""

from __future__ import annotations

import math

import numpy as np

from silodem import theory as th
from silodem.measure.wall_profiles import rises_past
from silodem.report import eurocode
from silodem.report.analysis import (
    BATCHES,
    DEAD_TO,
    UNSETTLED,
    WALKER_D_BOUNDS,
    Analysis,
    above_coulomb,
    density_band,
    no_settled_fill,
)
from silodem.report.flags import (
    ABOVE_HYDROSTATIC,
    WALLS_HELD_UP,
    above_hydrostatic,
    free_fit_undetermined,
    overpacked,
    undetermined_why,
    walls_held_up,
)
from silodem.report.numbers import pascals, poorly_determined, resolved, significant
from silodem.silo import sizes


def mfi_where(a: Analysis) -> str:
    """Where the mass flow index is measured, in words: "in the cell just above the junction,
    z = 1.4 - 2.1 m" (above the floor in a flat silo): the flow pattern is read there, in
    this run, not from the hopper's slope and wall friction as Jenike's chart classifies a
    design."""
    where = ("in the cell just above the junction" if a.res.cfg.silo.kind == "hopper"
             else "just above the floor")
    band = a.flow.get("mfi_band")
    return where + (f", z = {_fmt(band[0], 3)} - {_fmt(band[1], 3)} m" if band else "")


def _fmt(v: float, digits: int = 4) -> str:
    return significant(v, digits)


def _bulk_density_text(rho_b: float, rho_grain: float) -> str:
    """rho_b, flagged when it exceeds the grains' own density (:func:`overpacked`)."""
    if overpacked(rho_b, rho_grain):
        return (f"{_fmt(rho_b)} (above the grain density {_fmt(rho_grain)}: the grains overlap "
                "far beyond a contact's range; stiffer contacts are needed)")
    return _fmt(rho_b)


def _fitted(value: float, error: float, *notes: str) -> str:
    """'value +- error', saying so when the error is more than half the value (a fit to few
    or noisy wall bins: a K of 1.29 +- 0.69 is no measurement of K), with any further
    ``notes`` in the same parentheses, after it; an error that is not finite says that the
    data do not determine the value (``theory._fit.curve_fit_quiet``)."""
    said = (("not determined: the wall bins do not fix it (no finite error)",)
            if not math.isfinite(error) else
            ("poorly determined: the error is over half the value",)
            if poorly_determined(value, error) else ()) + notes
    text = f"{_fmt(value, 3)} +- {_fmt(error, 2)}"
    return text + (f" ({'; '.join(said)})" if said else "")


def _chance_words(c) -> str:
    """What chance says of a composition's tenths (``measure.discharge.random_order_band``):
    each tenth has its own band, so the tenths outside theirs are named with it (the range
    of all the bands, quoted alone, held the one tenth called outside)."""
    ratio, lo, hi = c.diameter_ratio, c.chance_lo, c.chance_hi
    outside = np.flatnonzero((ratio < lo) | (ratio > hi))
    head = (f"chance alone (random departure orders of these grains) gives each tenth a band, "
            f"together {_fmt(np.nanmin(lo), 3)} - {_fmt(np.nanmax(hi), 3)}: ")
    if outside.size == 0:
        return head + "every tenth within its own"
    named = [f"tenth {k + 1} ({_fmt(ratio[k], 3)}, its band {_fmt(lo[k], 3)} - "
             f"{_fmt(hi[k], 3)})" for k in outside[:3]]
    more = f" and {outside.size - 3} more" if outside.size > 3 else ""
    return (head + f"{outside.size} of {ratio.size} tenths outside their own: "
            + ", ".join(named) + more)


def _janssen_K(fit: th.JanssenFit, key: str, mobilised: float = float("nan")) -> str:
    """K +- its error, with what the fit's error and a K above 1 (:func:`above_hydrostatic`)
    say; after filling, a fit with mu_w given above the ``mobilised`` friction the walls
    carry also says that K takes up the friction they leave out (docs/theory.md)."""
    notes: tuple[str, ...] = ()
    if above_hydrostatic(fit):
        notes = (ABOVE_HYDROSTATIC[key],)
        if key == "fill" and not fit.mu_w_fitted and mobilised < fit.mu_w:
            missing = (f"with mu_w = {_fmt(fit.mu_w, 3)} where the walls mobilise "
                       f"{_fmt(mobilised, 3)}, the fit puts the missing friction into K")
            notes += (missing,)
    return _fitted(fit.K, fit.K_err, *notes)


def _clogged_after(a: Analysis, rate) -> str:
    """' (then the outlet clogged, after x % of the mass had left ...)' when the discharge
    ended in a clog after a flow that gave a steady rate; else ''.  A silo that clogged after
    12 % of its mass had left gave a rate, a Beverloo C and 'mass flow' without a word of the
    clog (an audit)."""
    events = a.res.events
    if events.get("discharge_end_reason") != "clog" or rate is None or \
            not np.isfinite(rate.rate):
        return ""
    share = 100.0 * float(events.get("discharged_fraction", np.nan))
    return (f" (then the outlet clogged, after {_fmt(share, 3)} % of the mass had left: "
            "the flow before the clog)")


def _narrow_for_beverloo(B: float, D: float, d: float) -> str:
    """' (the silo is narrow for Beverloo's law: ...)' when a silo of width B [m] is narrower
    than the widths from which the rate no longer depends on it
    (``theory.beverloo_narrow_widths``); '' when it is wide enough.  An outlet of 0.93 B gave
    a C as if the walls had no part in the flow (an audit)."""
    short = [f"{what} = {_fmt(need, 3)} m" for what, need in th.beverloo_narrow_widths(B, D, d)]
    if not short:
        return ""
    return (" (the silo is narrow for Beverloo's law, whose rate is independent of the width "
            "B from B = 2.5 D and D + 30 d on (Nedderman 1992): here B = "
            f"{_fmt(B, 3)} m, under {' and '.join(short)}, so this C holds the walls' effect "
            "on the flow too)")


CHANGE_ERROR = f" (+- its standard error: batch means, {BATCHES} blocks a window)"


def change_text(pct: float, err: float, why: str = "") -> str:
    """A change [%] as the key numbers write it: '53.2 +- 12'; one within its error 'not
    resolved' (:func:`~silodem.report.numbers.resolved`); 'n/a' without a value, followed
    by ``why`` in parentheses when given (:func:`change_missing`)."""
    if not math.isfinite(pct):
        return "n/a" + (f" ({why})" if why else "")
    text = f"{_fmt(pct, 3)} +- {_fmt(err, 2)}"
    if not resolved(pct, err):
        text += (" (within its error: not resolved)" if math.isfinite(err)
                 else " (no error: too few samples; not resolved)")
    return text


def change_missing(before: float, after: float, where: str) -> str:
    """Why the change fill -> discharge of a stress from ``before`` to ``after`` [Pa] is not a
    number (:func:`~silodem.report.numbers.percent_change`), in words (``where``: 'in the
    circle'), or "": no contact in the place in a window (its window mean is NaN:
    ``analysis.window_mean``), or a filling value of 0, against which no relative change can
    be told.  Five grains left the circles empty during discharge, and the rows read 'h n/a,
    v n/a' without a reason (an audit)."""
    if not math.isfinite(before):
        return f"no contact {where} after filling"
    if before == 0.0:
        return f"0 Pa {where} after filling: no relative change from 0"
    if not math.isfinite(after):
        return f"no contact {where} during discharge"
    return ""


def _circle_change(row: dict) -> str:
    """The circle's 'h <change>, v <change>' [%], or one 'n/a (why)' when both are missing
    for one reason."""
    comps = ("sigma_h", "sigma_v")
    whys = [change_missing(row[c + "_fill"], row[c + "_discharge"], "in the circle")
            for c in comps]
    if whys[0] and whys[0] == whys[1]:
        return f"n/a ({whys[0]})"
    return ", ".join(
        f"{c[-1]} {change_text(row[c + '_change_pct'], row[c + '_change_pct_err'], why)}"
        for c, why in zip(comps, whys, strict=True))


LOST = ("grains lost through a wall (pushed through by too soft contacts: the numbers below "
        "describe the grains that stayed)")


def lost_row(a: Analysis) -> None:
    """Into ``a.numbers``: how many grains the run lost through a wall (``/events``
    ``lost_count``, of ``n_poured``), when it lost any: the warnings say it as it came, and
    the table, read without them, says it once."""
    lost = int(a.res.events.get("lost_count", 0) or 0)
    if lost <= 0:
        return
    poured = int(a.res.events.get("n_poured", 0) or 0)
    share = f" of the {poured} poured ({100.0 * lost / poured:.0f} %)" if poured > 0 else ""
    a.numbers.append((LOST, f"{lost}{share}", "-"))


def _peak_note(edge, z: float) -> str:
    """What the switch zone's largest wall stress at ``z`` [m] is: on the hopper wall or not,
    and whether the profile (``edge``: z, sigma_n, on_vertical) goes on rising past the zone,
    so that the largest value is the zone's edge on a growing stress, not a local peak."""
    k = np.flatnonzero(edge.z == z)
    hopper = k.size > 0 and not bool(edge.on_vertical[k[0]])
    where = " (hopper wall)" if hopper else ""
    past = rises_past(edge.z, edge.sigma_n, z)
    if past is None:
        return where
    return (f"{where}: the zone's {'lowest' if past == 'below' else 'highest'} wall bin, on a "
            f"stress that goes on rising {'down' if past == 'below' else 'up'} the wall, not a "
            "local peak")


def _largest_row(edge, switch: tuple[float, float], label: str) -> tuple[str, str, str]:
    """The largest wall normal stress on the side walls (``edge``'s profile) and where: the
    switch-zone peak is the largest within the zone only, and a case-2 run's largest
    discharge pressure, 30 % above it, lay on the hopper wall below the zone."""
    sigma = np.where(np.isfinite(edge.sigma_n), edge.sigma_n, -np.inf)
    if not np.isfinite(sigma).any():
        return (f"largest wall normal stress on the side walls, {label}", "n/a (no bin)", "Pa")
    k = int(np.argmax(sigma))
    v, z = float(sigma[k]), float(edge.z[k])
    where = ("in the switch zone" if switch[0] <= z <= switch[1] else
             f"{'below' if z < switch[0] else 'above'} the switch zone")
    wall = "vertical wall" if edge.on_vertical[k] else "hopper wall"
    return (f"largest wall normal stress on the side walls, {label}",
            f"{pascals(v)} at z = {_fmt(z, 3)} m ({wall}, {where})", "Pa")


def _pour_row(a: Analysis) -> None:
    """The grains poured and the time the filling took, with the mean rate: ``fill.rate`` is
    an upper bound (a batch places only the grains that find room in the pouring band), and
    paper-case2 asks for 250 grains/s and pours about 83/s."""
    f, ev = a.res.cfg.fill, a.res.events
    if f.method != "pour" or "n_poured" not in ev or "fill_time" not in ev:
        return
    count, seconds = int(ev["n_poured"]), float(ev["fill_time"])
    if seconds <= 0:
        return
    label = (f"grains poured, time the filling took, mean rate (fill.rate = {f.rate:g} "
             "grains/s is an upper bound)")
    value = f"{count} in {_fmt(seconds, 3)} s: {_fmt(count / seconds, 3)} grains/s"
    a.numbers.append((label, value, "-"))


def _fill_mass(a: Analysis) -> float:
    """The mass in the silo at the end of settling [kg]: the event ``initial_mass`` (the gate
    opened), else, in a run without discharge, the /settled grains' rho pi r^2 t (the share of
    the weight on the gate was left out there); NaN without either."""
    if "initial_mass" in a.res.events:
        return float(a.res.events["initial_mass"])
    settled = a.res.snapshot("settled")
    if not isinstance(settled, dict) or "particles" not in settled:
        return float("nan")
    m = a.res.cfg.material
    r = np.asarray(settled["particles"]["radius"], dtype=float)
    return float(m.density * np.pi * np.sum(r * r) * m.thickness)


def _bottom_rows(a: Analysis) -> None:
    """The load of the fill on the silo's bottom after filling (the floor and the closed
    gate; a hopper silo's gate), with its share of the fill's weight (the walls carry the
    rest); in a flat silo its mean pressure against Janssen's sigma_v at the floor (K fitted,
    mu_w = tan phi_P) and the hydrostatic rho_b g h."""
    force, pressure = a.bottom
    weight = _fill_mass(a) * a.geom["g"]
    if not np.isfinite(force):
        return
    flat = a.res.cfg.silo.kind == "flat"
    what = "the floor and the closed gate" if flat else "the closed gate"
    share = (f" ({_fmt(100 * force / weight, 3)} %)" if np.isfinite(weight) and weight > 0
             else "")
    when = a.labels["fill"]  # (an unsettled run's: the last window of its settling)
    label = (f"load on {what} {when}, slot of thickness t = {_fmt(a.geom['t'], 3)} m (its "
             "share of the fill's weight m g; the walls carry the rest)")
    a.numbers.append((label, f"{force:,.0f}{share}", "N"))
    depth = a.surface["fill"]
    if not flat or "fill" not in a.janssen or not np.isfinite(depth):
        return
    g = a.geom
    jan = th.janssen_sigma_v(depth, a.rho_b, g["g"], g["B"], a.janssen["fill"].K,
                             g["mu_wall"])
    label = (f"mean pressure on the bottom {when} / Janssen sigma_v at the floor (K fitted, "
             "mu_w = tan phi_P) / hydrostatic rho_b g h")
    value = (f"{pascals(pressure)} / {pascals(float(jan))} / "
             f"{pascals(a.rho_b * g['g'] * depth)}")
    a.numbers.append((label, value, "Pa"))


def add_numbers(a: Analysis) -> None:
    """Into ``a.numbers``: the key numbers, (quantity, value, unit) rows."""
    n = a.numbers
    g = a.geom
    hopper = a.res.cfg.silo.kind == "hopper"
    if hopper:
        n.append(("cell width B / outlet D / junction z_j",
                  f"{g['B']:.3g} / {g['D']:.3g} / {g['z_j']:.3g}", "m"))
        n.append(("hopper half-angle from the vertical alpha (= 90 - theta)",
                  f"{g['alpha']:.3g}", "deg"))
    else:  # (a junction of 0 read as a hopper's, at the floor)
        n.append(("cell width B / outlet D (a flat bottom: no cell-hopper junction)",
                  f"{g['B']:.3g} / {g['D']:.3g}", "m"))
    if hopper and g["mu_hopper"] != g["mu_wall"]:  # (its theory used it, unsaid)
        n.append((("wall friction tan phi_P of the cell / of the hopper walls "
                  "(walls.hopper_friction_deg)"),
                  f"{_fmt(g['mu_wall'], 3)} / {_fmt(g['mu_hopper'], 3)}", "-"))
    n.append(("grain radii (shares by number) / mean diameter d",
              f"{sizes.describe(a.res.cfg.material)} / {g['d']:.3g}", "m"))
    _pour_row(a)
    lost_row(a)
    surface = ("free surface after filling (mean top of the grain columns, one diameter "
               "wide; the run's fill level is the mean top of its 5 highest grains)")
    why = no_settled_fill(a)  # an n/a says what is missing
    n.append((surface, _fmt(a.surface["fill"]) if np.isfinite(a.surface["fill"]) or not why
              else f"n/a ({why})", "m"))
    top = a.surface["fill"]
    cell = not np.isfinite(top) or density_band(g["z_j"], top, g["d"])[0] > 0.0
    where = "cell" if cell else "whole fill: under 4 grain diameters of it above the junction"
    n.append((f"bulk density rho_b ({where})",
              _bulk_density_text(a.rho_b, a.res.cfg.material.density)
              if np.isfinite(a.rho_b) or not why else f"n/a ({why})", "kg/m^3"))
    zone = ("switch zone" if hopper else "switch zone (a flat silo has no junction: a band "
            "over the floor, set for comparison with a hopper's)")
    n.append((zone, f"{a.switch[0]:.3g} - {a.switch[1]:.3g}", "m"))
    for key, label in a.labels.items():
        if key in a.peaks:
            v, z = a.peaks[key]
            value = (f"{pascals(v)} at z = {_fmt(z, 3)} m{_peak_note(a.edge[key], z)}" if v > 0
                     else f"{pascals(v)}: no grain pressed on the walls of the switch zone")
            n.append((f"switch-zone peak of the wall normal stress, {label}", value, "Pa"))
    for key, label in a.labels.items():
        if key in a.edge:
            n.append(_largest_row(a.edge[key], a.switch, label))
    for key, label in a.labels.items():
        if key in a.mu_mobilised:
            what = (f"mobilised wall friction sum(tau)/sum(sigma_n) on the cell-wall bins of "
                    f"the Janssen fit, {label} (tan phi_P = {_fmt(g['mu_wall'], 3)})")
            mu = a.mu_mobilised[key]  # tau_down: the grains' downward traction on the wall
            n.append((what, _fmt(mu, 3) + (f" ({WALLS_HELD_UP})" if walls_held_up(mu) else ""),
                      "-"))
        what = f"Janssen K fitted to the cell wall profile, {label} (mu_w = tan phi_P)"
        if key in a.janssen:
            value = _janssen_K(a.janssen[key], key, a.mu_mobilised.get(key, np.nan))
            n.append((what, value, "-"))
        elif key in a.janssen_missing:  # said, not left out without a word
            n.append((what, f"n/a ({a.janssen_missing[key]})", "-"))
    if a.janssen_free is not None and free_fit_undetermined(a.janssen_free):
        j = a.janssen_free
        why = (f"not determined (K = {_fmt(j.K, 3)} +- {_fmt(j.K_err, 2)}): "
               f"{undetermined_why(j, g['B'])}; not drawn")
        n.append(("Janssen free fit after filling: K, mu_w", why, "-"))
    elif a.janssen_free is not None:
        j = a.janssen_free
        mu = ("~0 (at the fit's lower bound: the profile shows no wall support)"
              if j.mu_w_at_bound else _fitted(j.mu_w, j.mu_w_err))
        if above_coulomb(j, g["mu_wall"]):
            mu += (f"; above tan phi_P = {_fmt(g['mu_wall'], 3)}, the most friction the walls "
                   "can carry: this profile does not follow Janssen's law")
        elif not j.mu_w_at_bound and j.mu_w > g["mu_wall"] * (1.0 + 1e-6):  # (within its
            # error: not flagged as the law's failure, but no reading of the walls either)
            mu += (f"; above tan phi_P = {_fmt(g['mu_wall'], 3)}, the most friction the walls "
                   "can carry, if within its error: no measure of the walls' friction")
        value = f"{_janssen_K(j, 'fill')}, {mu}"
        n.append(("Janssen free fit after filling: K, mu_w", value, "-"))
    _bottom_rows(a)
    if "fill" in a.janssen and "fill" in a.peaks:
        v, z = a.peaks["fill"]
        # Janssen is the cell's theory: a peak on the hopper walls is set against the cell's
        # sigma_h where the cell ends, at the junction
        jan = th.janssen_sigma_h(a.surface["fill"] - max(z, g["z_j"]), a.rho_b, g["g"],
                                 g["B"], a.janssen["fill"].K, g["mu_wall"])
        label = ("switch-zone peak / Janssen sigma_h at its height" + (
            " (at the junction for a peak below it)" if hopper else "") + ", after filling")
        value = _fmt(v / jan, 3) if jan > 0 else "n/a"
        K = a.janssen["fill"]
        if jan > 0 and poorly_determined(K.K, K.K_err):
            value += (f" (K = {_fmt(K.K, 3)} +- {_fmt(K.K_err, 2)} is poorly determined: a "
                      "ratio to a curve the run does not measure)")
        n.append((label, value, "-"))
    n.extend(eurocode.key_numbers(a.en1991_4, a.res.cfg.measure))
    for key, hop in a.hopper.items():
        when = a.labels[key]
        label = (f"measured mean vertical stress q at the junction level, {when} (hopper "
                 "theory input)")
        n.append((label, pascals(hop["q"]), "Pa"))
        if "D_fit" in hop:  # (no error: a bounded 1-parameter fit, often to a few bins)
            label = (f"Walker distribution factor D fitted on the hopper walls (planar), {when}, "
                     f"to {hop['D_bins']} wall bins")
            value = _fmt(hop["D_fit"], 3)
            if hop.get("D_at_bound"):
                lo, hi = WALKER_D_BOUNDS
                value += (f" (the end of the range searched, {_fmt(lo)} - {_fmt(hi)}: the wall "
                          "bins lie beyond every curve of the range, so D is not determined)")
            n.append((label, value, "-"))
    window = a.res.cfg.measure.window
    # an unfinished run stopped in its discharge: the stop, not the discharge's end, cut the
    # discharge window short
    stopped = a.unfinished and a.res.attrs.get("phase") == "discharge"
    for key, label in (("fill", "after filling (the end of settling)"),
                       ("discharge", "during discharge")):
        if key not in a.windows:
            continue
        start, end = a.windows[key]
        if key == "fill" and a.labels["fill"] == UNSETTLED:  # said always: no settled fill
            what = (f"averaging window {UNSETTLED}: the last measure.window = {window:g} s of "
                    "the settling reached (the run stopped before settling ended)")
            if end - start < window:
                what += ", cut short: less settling than that was reached"
        elif end - start < window:
            why = ("settling lasted less than" if key == "fill" else
                   "the run stopped within" if stopped else "the discharge ended within")
            what = f"averaging window {label}, cut short: {why} measure.window = {window:g} s"
        else:
            continue
        n.append((what, f"{start:.3f} - {end:.3f} ({end - start:.3g} s)", "s"))
    if "window_emptied" in a.flow:  # the discharge stresses depend on it (a quick silo
        # empties by half in the same 1 s window a full one loses a tenth in)
        start, end = a.flow["window_emptied"]
        n.append(("share of the fill's mass discharged at the discharge window's start / end",
                  f"{100 * start:.0f} / {100 * end:.0f}", "%"))
    if a.change_missing:  # one row that says why, not "h n/a %, v n/a %" for each circle
        n.append(("change fill -> discharge", f"n/a ({a.change_missing})", "%"))
    else:
        for name, row in a.change.items():
            if name == "wall peak":
                label = ("change fill -> discharge, wall peak: the switch zone's largest wall "
                         f"normal stress in each window, at z = {_fmt(row['z_fill'], 3)} m "
                         f"-> {_fmt(row['z_discharge'], 3)} m" + CHANGE_ERROR)
                why = change_missing(row["sigma_h_fill"], row["sigma_h_discharge"],
                                     "on the switch zone's walls")
                n.append((label, change_text(row["sigma_h_change_pct"],
                                             row["sigma_h_change_pct_err"], why), "%"))
                continue
            n.append((f"change fill -> discharge, {name}{CHANGE_ERROR}", _circle_change(row),
                      "%"))
        same = a.wall_at_fill_peak
        if same is not None and same[0] != a.change.get("wall peak", {}).get("z_discharge"):
            z, f, dd, pct = same  # (at one height the peak-to-peak row says it already)
            label = (f"wall normal stress at the filling peak's height z = {_fmt(z, 3)} m, "
                     "after filling -> during discharge (the same place)")
            why = change_missing(f, dd, "on the wall at that height")
            value = (f"{pascals(f)} -> {pascals(dd)} "
                     f"({change_text(pct, a.wall_at_fill_peak_err, why)} %)")
            n.append((label, value, "Pa"))
    f = a.flow
    if "rate" in f:
        r = f["rate"]
        label = f"steady discharge rate W (of a slot of thickness t = {_fmt(a.geom['t'], 3)} m)"
        opening = float(a.res.events.get("gate_opening_time", 0.0))
        whole = r.t1 <= opening  # (the fit's end read as the outlet's clearing before)
        sliding = (f" (fitted from {_fmt(r.t0, 3)} to {_fmt(r.t1, 3)} s after the opening; "
                   f"the gate slid open until {_fmt(opening, 3)} s: "
                   + ("all of it of a partly open outlet)" if whole else
                      "its start of a partly open outlet)")
                   if np.isfinite(r.rate) and r.t0 < opening else "")
        value = (f"n/a ({r.why})" if not np.isfinite(r.rate) else
                 f"{_fmt(r.rate)} +- {_fmt(r.err, 2)}" + (f" ({r.why})" if r.why else ""))
        n.append((label, f"{value}{sliding}{_clogged_after(a, r)}", "kg/s"))
    if "pattern" in f:
        where = mfi_where(a)
        n.append((f"mass flow index v_wall / v_axis, {where}", _fmt(f["mfi"], 3), "-"))
        n.append((f"dead-zone fraction of the grains (at rest to {f.get('dead_to', DEAD_TO)})",
                  _fmt(f["dead_fraction"], 3), "-"))
        threshold = a.res.cfg.measure.mass_flow_index_threshold
        label = (f"flow pattern, measured: mass flow if v_wall / v_axis >= {threshold:g} "
                 f"({where}) and no dead zone; not Jenike's hopper design chart")
        clogged = _clogged_after(a, f.get("rate")) if f["pattern"] != "clogged" else ""
        n.append((label, f["pattern"] + clogged, ""))
    if "composition" in f:
        c = f["composition"]
        label = ("size segregation in the discharge: mass mean diameter of the first and last "
                 f"tenth of the discharged mass (and the least and largest tenth) over the "
                 f"fill's, {_fmt(c.fill_diameter, 3)} m (1: none)")
        if c.one_size:  # (read as "1 / 1 (1 - 1); chance ... 1 - 1" by an audit)
            value = (f"n/a (the grains are all of one size, r = {_fmt(c.sizes[0], 3)} m: "
                     "there are no sizes to segregate)")
        else:
            value = (f"{_fmt(c.diameter_ratio[0], 3)} / {_fmt(c.diameter_ratio[-1], 3)} "
                     f"({_fmt(np.nanmin(c.diameter_ratio), 3)} - "
                     f"{_fmt(np.nanmax(c.diameter_ratio), 3)}); " + _chance_words(c))
        n.append((label, value, "-"))
    if "beverloo_C" in f:
        slope = (" (Beverloo's law is for a flat bottom: through a hopper C also depends on "
                 "its slope)" if hopper else "")
        n.append((f"Beverloo 2D constant C implied by W (k = 1.5){slope}",
                  _fmt(f["beverloo_C"], 3) + _narrow_for_beverloo(g["B"], g["D"], g["d"]), "-"))
