"""report.html: one self-contained page (figures as base64 PNG, no external files or scripts)."""

from __future__ import annotations

import base64
import html
import re
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from silodem.atomic import write_atomic
from silodem.report import figures_flow as ff
from silodem.report import figures_stress as fs
from silodem.report.analysis import BATCHES, UNSETTLED, Analysis, analyse
from silodem.report.draw import png_bytes
from silodem.report.flags import overpacked
from silodem.report.load import load_results
from silodem.report.numbers import UNLOADED
from silodem.report.unfinished import banner_html, note_line
from silodem.scenario_files import QUICK_SUFFIX


@dataclass(frozen=True)
class FigureSpec:
    name: str  # file name without .png
    paper: str  # the paper's figure it reproduces ("" if new)
    caption: str  # with {fill}, {discharge}, {fill_window}: see caption_for
    make: Callable[[Analysis], object]

    def caption_for(self, a: Analysis) -> str:
        """The caption with the windows named as the run's numbers and figure titles name
        them (:attr:`Analysis.labels`): "after filling", or for a run stopped before settling
        ended "late in the unfinished settling"; {fill_window} says which time the fill
        window averages over."""
        unsettled = a.labels["fill"] == UNSETTLED
        window = ("the last window of the settling reached: the run stopped before settling "
                  "ended" if unsettled else "the last window of settling")
        text = self.caption.format(**a.labels, fill_window=window)
        if "discharge" in text and "discharge_start_time" not in a.res.events:
            # (the captions spoke of discharge panels not drawn)
            text += NO_DISCHARGE if not a.res.cfg.discharge.enabled else NOT_REACHED
        return text


NO_DISCHARGE = " This run has no discharge: only what comes before it is drawn."
NOT_REACHED = " The run stopped before its discharge: only what comes before it is drawn."

FIGURES = [
    FigureSpec("fig2_coordination", "Fig. 2",
               "Coordination number C_n = sum(n_c)/N_p (eq. 10) against cycles (their time "
               "along the top), in a band across "
               "the silo at the cell-hopper junction (over the floor in a flat silo) and in the "
               "measurement circles. Shading: "
               "filling, settling, discharge. Ordered packings of equal disks give 4 (square) "
               "and 6 (triangular), Table 3.", fs.fig_coordination),
    FigureSpec("fig3a_horizontal_filling", "Fig. 3a",
               "Horizontal stress along the silo wall {fill} (time average over {fill_window}): "
               "wall normal stress per bin, near-wall Love-Weber sigma_xx, "
               "Janssen's 2D slot solution (K fitted with mu_w = tan phi_P, and the paper's "
               "K = 0.4) in the cell, EN 1991-4's filling load for a squat or intermediate "
               "silo (§5.3) and its hopper filling load (§6) where they apply (the key "
               "numbers say why one is left out), and, in a hopper silo, Walker's slice "
               "solution in the hopper: the planar (wedge) form that a 2D hopper needs and "
               "the paper's conical eq. 12. The legend lists the curves drawn.",
               lambda a: fs.fig_horizontal(a, "fill")),
    FigureSpec("fig3b_vertical_filling", "Fig. 3b",
               "Vertical stress along the silo wall {fill}: Love-Weber sigma_zz near the "
               "walls and over the cross-section, Janssen's sigma_v, the hydrostatic line, and, "
               "in a hopper silo, the planar and conical hopper solutions.",
               lambda a: fs.fig_vertical(a, "fill")),
    FigureSpec("fig4_switch_zone_network", "Fig. 4",
               "Contact force network at the switch zone after filling and during discharge "
               "(same force scale): line width and colour grow with the normal force.",
               ff.fig_switch_network),
    FigureSpec("fig5_force_network", "Fig. 5",
               "Intergranular force network in the whole silo after filling and during "
               "discharge (same force scale); grain-wall contacts are drawn to the wall.",
               ff.fig_network),
    FigureSpec("fig6_horizontal_discharge", "Fig. 6",
               "Horizontal stress along the silo wall during discharge (time average over the "
               "discharge window), with the profile {fill}, Janssen's solution (K refitted), "
               "EN 1991-4's discharge loads on the vertical and hopper walls where they apply, "
               "Walker's hopper solutions with the discharge window's q and D in a hopper silo, "
               "and the switch-zone peak. The legend lists the curves drawn.",
               lambda a: fs.fig_horizontal(a, "discharge")),
    FigureSpec("fig7_switch_zone_evolution", "Fig. 7",
               "Horizontal and vertical stress at the switch zone (measurement circles) and "
               "their ratio through filling, settling and discharge. The ratio leaves out the "
               f"samples whose sigma_v is under {UNLOADED:g} x its median over the run (the "
               "same rule as a study's CV of the ratio): a ratio of two near-zero stresses, as "
               "at the start of filling and in the emptied silo, is noise; where a 0.2 s stretch "
               "has no sample left, the curve has a gap.", fs.fig_evolution),
    FigureSpec("fig8_change", "Fig. 8",
               "Percentage change of the switch-zone stresses from the end of filling to the "
               "discharge window, with error bars of +- 1 standard error: each window's mean "
               f"gets the batch-means error of its samples (in {BATCHES} consecutive blocks, "
               "since successive samples are correlated), propagated to the change. A change "
               "within its error (pale bar) is not resolved by this run: its sign may be "
               "noise.", fs.fig_change),
    FigureSpec("stress_fields", "",
               "Bulk density and Love-Weber stresses sigma_xx, sigma_zz (compression "
               "positive) on a grid of measure.field_cell: each grain's mass shared among the "
               "cells by the area of its disk in each, its contacts' stress in the cell of its "
               "centre (or, with measure.field_kernel = 'gaussian', a Gaussian of width "
               "measure.field_width at the cell centres): the settled packing, and the mean "
               "over the discharge window; the walls as they stood then (dotted: withdrawn, "
               "the open gate). Arching shows as "
               "sigma_zz that stops growing with depth and bends towards the walls.",
               fs.fig_fields),
    FigureSpec("wall_shear", "",
               "Wall friction along the silo wall, against its fully mobilised value "
               "tan(phi_P) sigma_n (on the hopper walls, of walls.hopper_friction_deg where "
               "it is set): Janssen's theory assumes full mobilisation.",
               fs.fig_wall_shear),
    FigureSpec("vertical_discharge", "",
               "Vertical stress along the silo wall during discharge (time average over the "
               "discharge window; the paper's Fig. 3b is of the filled silo): "
               "Love-Weber sigma_zz near the walls and over the cross-section, with the "
               "near-wall profile {fill}, Janssen's sigma_v (K refitted), the hydrostatic line "
               "and, in a hopper silo, Walker's hopper solutions with the discharge window's q.",
               lambda a: fs.fig_vertical(a, "discharge")),
    FigureSpec("discharge_rate", "",
               "Discharged mass and mass flow rate; the steady rate is the slope between 15 % "
               "and 75 % of the discharged mass, its error the standard error of 5 block "
               "slopes; where the gate slides open (discharge.gate_speed), a dashed line marks "
               "the moment it cleared the outlet.", ff.fig_discharge_rate),
    FigureSpec("velocity_field", "",
               "Mean grain velocity on a grid over the discharge window, and the flow pattern "
               "as measured in this run: mass flow when the mass flow index v_wall / v_axis "
               "in a band of the cell just above the junction (above the floor of a flat "
               "silo) reaches measure.mass_flow_index_threshold and no grain stays in a dead "
               "zone, funnel flow otherwise. It is not Jenike's classification of a hopper "
               "design by its slope and wall friction.", ff.fig_velocity),
    FigureSpec("discharge_composition", "",
               "Size segregation in the discharge: the grains that left, in the order they "
               "left, cut into ten parts of equal mass; each part's mass mean diameter "
               "sum(m d) / sum(m) over that of the grains in the silo at the gate opening "
               "(1 throughout: no segregation), with the band 90 % of random departure orders "
               "of the same grains fall in (what chance alone gives: one tenth in ten lies "
               "outside it by chance), and, for a mixture of a few sizes, each size's "
               "share of each part's mass beside its share of the fill.", ff.fig_composition),
    FigureSpec("dead_zones", "",
               "Grains at the gate opening coloured by the time they left the silo; the dead "
               "zone in black: the grains that neither left nor moved a grain radius from "
               "the gate opening to the end of the discharge window (the velocity field's), "
               "whether or not the emptying silo drew them out later.", ff.fig_dead_zones),
]


def render_figures(a: Analysis, fig_dir: Path) -> list[tuple[FigureSpec, bytes]]:
    """Render every figure the data allows; write each PNG to ``fig_dir``; return them."""
    fig_dir.mkdir(parents=True, exist_ok=True)
    out = []
    for spec in FIGURES:
        fig = spec.make(a)
        if fig is None:
            (fig_dir / f"{spec.name}.png").unlink(missing_ok=True)  # no stale picture
            continue
        png = png_bytes(fig)
        write_atomic(fig_dir / f"{spec.name}.png", png)
        out.append((spec, png))
    return out


LOST_UNPHYSICAL = 0.05  # a share of the poured grains lost through the walls that no real silo


def unphysical_html(a: Analysis) -> str:
    """The box at the top of report.html for a run whose packing no real silo has: a bulk
    density above the grains' own (they overlap far beyond a contact's range) or more than
    ``LOST_UNPHYSICAL`` of the poured grains lost through the walls; "" otherwise.  Its key
    numbers were shown as a sound run's (paper-case1 --quick: 2256 kg/m^3 from grains of
    1607, 43 % lost), with the flags in single rows further down."""
    cfg, events = a.res.cfg, a.res.events
    said = []
    if overpacked(a.rho_b, cfg.material.density):
        said.append(f"its bulk density, {a.rho_b:.0f} kg/m^3, is above the grains' own "
                    f"{cfg.material.density:g}")
    poured, lost = int(events.get("n_poured", 0)), int(events.get("lost_count", 0))
    if poured and lost > LOST_UNPHYSICAL * poured:
        said.append(f"{lost} of its {poured} grains ({100 * lost / poured:.0f} %) were lost "
                    "through the walls")
    if not said:
        return ""
    text = (f"Not a physical packing: {'; '.join(said)}. The stresses, densities and rates "
            "below are not a silo's; the warnings say what to change (for overlapping grains, "
            "the contact stiffness to use) before reading them.")
    return f"<p class='unfinished' id='unphysical'>{html.escape(text)}</p>"


def description_html(cfg) -> str:
    """The config's description and, for a config named after an embedded scenario whose
    values it changed (``scenario_files.changes_from_scenario``), what it changed: a flat silo
    of mixed grains made from paper-case2 with --set showed case 2's description alone, and a
    stiffened case 1 opened with its "grains overlap by about their radius" as fact.  The
    description is then said to be the scenario's, unless the config gave its own."""
    from silodem.scenario_files import changes_from_scenario

    text = html.escape(cfg.description)
    changed = changes_from_scenario(cfg)
    if changed is None or not changed[1]:
        return f"<p>{text}</p>"
    name, keys = changed
    scenario = html.escape(name) + (" --quick" if cfg.name != name else "")
    listed = html.escape("; ".join(keys))
    if any(key.startswith("description = ") for key in keys):  # the config's own words
        return (f"<p>{text}</p><p>This run's config is named after the scenario {scenario} "
                f"and differs from it in: {listed}.</p>")
    return (f"<p>The scenario {scenario}, after which this run's config is named: {text}</p>"
            f"<p>This run differs from it in: {listed}; where the description speaks of "
            "these, it is the scenario's, not this run's.</p>")


def quick_caveat(hopper: bool) -> str:
    """What a --quick silo is for (``scenario_files.quick_variant``): a ``hopper`` silo's
    hopper is then a few grains tall (the note said so of flat silos too, and gave case 2's
    grain count in every report)."""
    return ("A --quick silo is small: 0.6 of the cell width with the same outlet, 0.36 of the "
            f"grains{', a hopper a few grains tall' if hopper else ''}. It checks a setup in "
            "seconds; its stresses, flow pattern, dead zones and fill -> discharge changes (its "
            "discharge window falls while the silo is emptying fast) are not those of the "
            "full-size silo.")


# the style and the table of a run's report.html and a study's (study/report.py); a table of
# class long-first may break its first column's long words (switch_centre,
# discharge_end_reason) anywhere, so that it fits a phone's width (400 px) with no sideways
# scrolling; in print, no figure is cut from its caption, no heading from what follows
PAGE_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;max-width:1100px;
margin:2em auto;padding:0 1em;color:#222;line-height:1.45}
h1{font-size:1.6em;margin-bottom:.2em}h2{margin-top:1.8em;border-bottom:1px solid #ddd}
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ddd;padding:4px 8px;
text-align:left;font-size:.92em;vertical-align:top}th{background:#f4f4f4}
figure{margin:1.5em 0;padding:.5em;border:1px solid #eee;background:#fff}
figure img{max-width:100%;height:auto;display:block;margin:auto}
figcaption{font-size:.92em;color:#444;margin-top:.4em}.warn{color:#8a4b00}
.unfinished{border:2px solid #c77700;background:#fff4e0;padding:.6em .9em;color:#5a3200}
pre{background:#f7f7f7;padding:.8em;overflow:auto;font-size:.85em;white-space:pre-wrap;
overflow-wrap:anywhere}table.long-first td:first-child{overflow-wrap:anywhere}
@media print{body{max-width:none;margin:0}figure{break-inside:avoid}h2{break-after:avoid}}
"""


def html_table(rows: list[tuple[str, ...]], head: tuple[str, ...], cls: str = "") -> str:
    """An HTML table of ``rows`` under the column names ``head`` (header cells of their
    columns), every cell escaped; ``cls``: its class attribute ("": none)."""
    h = "".join(f"<th scope='col'>{html.escape(c)}</th>" for c in head)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>"
                   for r in rows)
    attr = f" class='{html.escape(cls)}'" if cls else ""
    return f"<table{attr}><tr>{h}</tr>{body}</table>"


def page_head(title: str, css: str) -> str:
    """The start of a run's or a study's page, to its <body>: the charset, a viewport at the
    device's width (a phone laid the page out 1100 px wide and shrank it), the title, ``css``."""
    return ("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
            "<meta name='viewport' content='width=device-width, initial-scale=1'>"
            f"<title>{html.escape(title)}</title><style>{css}</style></head><body>")


ALT_CHARS = 150  # an image's alt text is its caption's first clause, cut to this length


_CLAUSE_END = re.compile(r"\.\s+(?=[A-Z])|[:;]\s")  # (not the point of "eq. 10")


def alt_text(caption: str) -> str:
    """A figure's alt text: its caption's first clause (to the first ': ', '; ' or a full
    stop before a capital), at most :data:`ALT_CHARS` characters, cut at a word.  A screen
    reader read the file name ("fig2 underscore coordination"); the caption that follows the
    image says the rest."""
    end = _CLAUSE_END.search(caption)
    text = caption[:end.start()] if end else caption.rstrip(".")
    if text.count("(") > text.count(")"):  # a clause ended inside a parenthesis: without it
        text = text[:text.rfind("(")].rstrip(" ,")
    if len(text) > ALT_CHARS:
        text = text[:ALT_CHARS].rsplit(" ", 1)[0] + " ..."
    return text


def figure_html(name: str, png: bytes, caption: str, label: str = "") -> str:
    """A <figure> with ``png`` inline (the page stays one file), its alt text from the
    caption (:func:`alt_text`), and the caption after the bold ``label`` ("": none)."""
    b64 = base64.b64encode(png).decode("ascii")
    bold = f"<b>{html.escape(label)}</b> " if label else ""
    return (f"<figure id='{html.escape(name)}'><img alt='{html.escape(alt_text(caption))}' "
            f"src='data:image/png;base64,{b64}'><figcaption>{bold}{html.escape(caption)}"
            "</figcaption></figure>")


# the meaning and unit of each event (results.h5 /events; docs/output.md)
EVENT_MEANINGS = {
    "n_poured": "grains poured",
    "fill_time": "time the filling took [s]",
    "settle_time": "time the settling took [s]",
    "settle_criterion_value": ("settling criterion at its end (force ratio [-] or mean "
                               "kinetic energy [J])"),
    "fill_level": "fill level after settling [m]",
    "discharge_start_time": "time the gate opened (or began to slide open) [s]",
    "gate_opening_time": ("time the sliding gate took to clear the outlet (outlet width / "
                          "discharge.gate_speed) [s]"),
    "initial_mass": "mass in the silo (a slot of thickness t) when the gate opened [kg]",
    "discharge_end_reason": "what ended the discharge (fraction, time or clog)",
    "discharge_time": "time the discharge took [s]",
    "discharged_fraction": "share of the initial mass discharged [-]",
    "lost_count": "grains that slipped out through a wall (warned) [-]",
}


def _event_rows(events: dict) -> list[tuple[str, str, str]]:
    """(event, value, its meaning and unit) for the run events table."""
    out = []
    for k, v in events.items():
        if isinstance(v, float | np.floating):
            v = f"{v:.6g}"
        out.append((k, str(v), EVENT_MEANINGS.get(k, "")))
    return out


def _snapshot_name(view: str) -> str:
    """The figure name of a force-network view ("end-of-filling" -> network_end_of_filling)."""
    return f"network_{view.replace('-', '_')}"


_SNAPSHOT_CAPTIONS = {
    "end-of-filling": "Force network at the end of filling (settled), from the saved frames.",
    "early-discharge": "Force network early in the discharge (15 % of the discharge time).",
    "late-discharge": "Force network late in the discharge (75 % of the discharge time).",
}


def render_snapshots(folder: Path, fig_dir: Path,
                     unreadable: list[str] | None = None) -> list[tuple[str, str, bytes]]:
    """Force-network pictures of the end of filling, early and late discharge (from the
    frames recorder, silodem.viz); written to ``fig_dir/network_<view>.png``.  Frames that
    cannot be read (none in the file, a segment file missing or damaged: NoFramesError,
    one line naming the file) give no pictures, and the reason is appended to
    ``unreadable``."""
    from silodem.viz import force_network_pngs

    try:
        pngs = force_network_pngs(folder / "results.h5")
    except (ValueError, OSError) as exc:  # NoFramesError (a ValueError), or h5py's own
        pngs = {}
        if unreadable is not None:
            unreadable.append(str(exc))
    out = []
    for view, caption in _SNAPSHOT_CAPTIONS.items():
        name = _snapshot_name(view)
        if view not in pngs:
            (fig_dir / f"{name}.png").unlink(missing_ok=True)
            continue
        write_atomic(fig_dir / f"{name}.png", pngs[view])
        out.append((name, caption, pngs[view]))
    return out


def _left_out_snapshots(a: Analysis, missing: list[str], unreadable: str) -> str:
    """Why the network snapshots ``missing`` are not on the page."""
    text = f"Left out: {', '.join(missing)}; they are drawn from the frames saved beside " \
        "results.h5 (frames/), "
    if unreadable:
        return text + f"which cannot be read: {unreadable}."
    if a.unfinished and a.res.cfg.discharge.enabled and \
            "discharge_start_time" not in a.res.events:
        return text + "which hold no frame of that moment: the run stopped before its discharge."
    if "discharge_start_time" in a.res.events:
        return text + ("which hold no frame near that moment (output.frame_interval too long "
                       "for the discharge).")
    return text + ("which hold no frame of that moment (a run without discharge has none of "
                   "it).")


def _snapshot_caption(a: Analysis, name: str, caption: str) -> str:
    """The caption of a network snapshot; the "end of filling" of a run stopped before
    settling ended is the last frame it saved."""
    if name == _snapshot_name("end-of-filling") and a.labels["fill"] == UNSETTLED:
        phase = "filling" if a.res.attrs.get("phase") == "fill" else "settling"
        return (f"Force network at the last saved frame of the unfinished {phase} (the run "
                "stopped before settling ended: no settled packing), from the saved frames.")
    return caption


def build_html(a: Analysis, figures: list[tuple[FigureSpec, bytes]],
               snapshots: list[tuple[str, str, bytes]] = (), unreadable: str = "") -> str:
    """The page; ``unreadable``: why the saved frames could not be read ("" if they could)."""
    res = a.res
    cfg = res.cfg
    title = f"silodem report: {cfg.name}"
    head = page_head(title, PAGE_CSS)
    hopper = cfg.silo.kind == "hopper"
    angle = (f" The hopper angle of the config, theta = "
             f"{cfg.silo.hopper_angle_from_horizontal_deg:g} deg, is measured from the "
             "horizontal; hopper theory uses alpha = 90 - theta from the vertical." if hopper
             else " The silo has a flat bottom (no hopper).")
    source = res.attrs.get("silodem_source")
    source = f" (source {html.escape(str(source))})" if source is not None else ""
    intro = (f"<p>silodem {html.escape(str(res.attrs.get('silodem_version', '?')))}{source}, seed "
             f"{cfg.seed}, time step {res.attrs.get('dt', float('nan')):.3g} s. Stresses are "
             "compressive positive [Pa]: a 2D force per unit length divided by the grains' "
             f"out-of-plane thickness t = {cfg.material.thickness:g} m.{angle} Results: "
             "results.h5 in this page's folder, status "
             f"{html.escape(str(res.attrs.get('status', '?')))}.</p>")
    parts = [head, f"<h1>{html.escape(title)}</h1>", banner_html(a), unphysical_html(a),
             description_html(cfg), intro]
    if cfg.name.endswith(QUICK_SUFFIX):  # (scenario_files.quick_variant names it so)
        parts.append(f"<p class='warn'>{html.escape(quick_caveat(cfg.silo.kind == 'hopper'))}"
                     "</p>")
    if res.warnings:
        parts.append("<h2>Warnings</h2><ul>" + "".join(
            f"<li class='warn'>{html.escape(w)}</li>" for w in res.warnings) + "</ul>")
    parts.append("<h2>Key numbers</h2>")
    parts.append(html_table(a.numbers, ("quantity", "value", "unit"), cls="long-first")
                 if a.numbers else
                 "<p>No measurements in this results file: the run took no measurement "
                 "sample (measure.interval longer than the run), or it was made without the "
                 "measurements. The figures that need them are left out.</p>")
    parts.append("<h2>Figures</h2>")
    if hopper:
        parts.append("<p>A 2D silo is a plane-strain slot with a wedge hopper: the hopper curves "
                     "labelled PLANAR are Walker's slice solution for a wedge (m = 0); the "
                     "paper's eq. 12 is the conical form (m = 1), which doubles the wall support "
                     "of a slice and so underestimates the stresses of a 2D hopper "
                     "(docs/theory.md).</p>")
    drawn = {spec.name for spec, _ in figures}
    left_out = [f"{spec.name}" + (f" ({spec.paper})" if spec.paper else "")
                for spec in FIGURES if spec.name not in drawn]
    if left_out:  # a figure with no data is not drawn: say which, not leave a silent gap
        parts.append(f"<p class='warn'>Left out for lack of data in this run: "
                     f"{html.escape(', '.join(left_out))} (the key numbers' n/a rows and the "
                     "warnings say what is missing).</p>")
    for spec, png in figures:
        label = f"{spec.paper} equivalent." if spec.paper else ""
        parts.append(figure_html(spec.name, png, spec.caption_for(a), label))
    parts.append("<h2>Force network snapshots</h2>")
    if len(snapshots) < len(_SNAPSHOT_CAPTIONS):
        shown = {name for name, _, _ in snapshots}
        missing = [_snapshot_name(view) for view in _SNAPSHOT_CAPTIONS
                   if _snapshot_name(view) not in shown]
        parts.append(f"<p class='warn'>{html.escape(_left_out_snapshots(a, missing, unreadable))}"
                     "</p>")
    for name, caption, png in snapshots:
        parts.append(figure_html(name, png, _snapshot_caption(a, name, caption)))
    parts.append("<h2>Run events</h2>" + html_table(
        _event_rows(res.events), ("event", "value", "meaning [unit]"), cls="long-first"))
    parts.append("<h2>Configuration</h2><pre>" + html.escape(res.config_toml) + "</pre>")
    parts.append("</body></html>")
    return "\n".join(parts)


def write_report(folder: Path | str, *, note: Callable[[str], None] | None = None) -> Path:
    """Re-render every figure from ``folder``/results.h5 and write ``folder``/report.html.

    The results.h5 of an unfinished run (its ``status`` not "complete") gets a box at the top
    of the page saying so (``report.unfinished``), and, once the page is written, one line
    to ``note`` (``silodem plot`` prints it on stderr; None: not said)."""
    folder = Path(folder)
    unreadable: list[str] = []
    with warnings.catch_warnings():
        # a quantity with no data (no grain in a window, a field at rest) is NaN or an empty
        # arrow in its figure and says so there; numpy's and matplotlib's warnings about
        # the empty means and zero lengths behind it are not for the user's terminal
        warnings.simplefilter("ignore", RuntimeWarning)
        a = analyse(load_results(folder))
        figures = render_figures(a, folder / "figures")
        snapshots = render_snapshots(folder, folder / "figures", unreadable)
    path = folder / "report.html"
    write_atomic(path, build_html(a, figures, snapshots, " ".join(unreadable))
                 .encode("utf-8"))
    line = note_line(a, folder)
    if line is not None and note is not None:
        note(line)
    return path
