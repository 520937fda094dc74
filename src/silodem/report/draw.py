"""Drawing helpers shared by the report's figures: walls, grains, force networks, phases."""

from __future__ import annotations

import io
import os
import textwrap
from typing import TYPE_CHECKING, Any, BinaryIO

import matplotlib

matplotlib.use("Agg")
import numpy as np
import numpy.typing as npt
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import EllipseCollection, LineCollection

from silodem.measure.stress import contact_points_walls
from silodem.report.numbers import loaded
from silodem.silo.frames import WallGeometry
from silodem.silo.geometry import gate_shift

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.colors import Colormap
    from matplotlib.figure import Figure

PHASE_COLORS = {0: ("#e8f0fb", "filling"), 1: ("#eef7e8", "settling"),
                2: ("#fbeee6", "discharge")}


def tight_layout(fig: Figure, **kw: Any) -> None:
    """``fig.tight_layout(**kw)``, once, on an Agg canvas, leaving no layout engine on ``fig``.

    ``Figure.tight_layout`` leaves a placeholder layout engine behind, and ``savefig`` then
    makes a whole extra (non-rendering) draw pass of the figure before the real one; without
    an engine the PNG is byte-identical and saving takes about a quarter less time.  On a
    bare ``Figure`` (no canvas) the layout measures the text on a throw-away renderer; on
    the figure's own Agg canvas ``savefig`` reuses that renderer and its cached text sizes."""
    if not isinstance(fig.canvas, FigureCanvasAgg):
        FigureCanvasAgg(fig)
    fig.tight_layout(**kw)
    fig.set_layout_engine(None)


def legend_right(ax: Axes, **kw: Any) -> None:
    """The legend of ``ax`` outside it, on its right: a legend inside the axes hides the
    curves it lies on (Fig. 7's sigma_v plateau of settling, Fig. 2's end of discharge).
    ``tight_layout`` then makes room for it."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, **kw)


def legend_below(fig: Figure, ax: Axes, fontsize: float = 7, ncol: int = 2,
                 wrap: int = 58) -> None:
    """The legend of ``ax`` under the plot, in ``ncol`` columns (labels wrapped at ``wrap``
    characters), the figure made taller by the legend's height, then ``tight_layout`` over the
    rest: a long legend (the stress profiles' dozen curves) inside the axes hides data.  Use
    it in place of ``tight_layout``."""
    handles, labels = ax.get_legend_handles_labels()
    if not handles:
        tight_layout(fig)
        return
    if not isinstance(fig.canvas, FigureCanvasAgg):
        FigureCanvasAgg(fig)
    labels = [textwrap.fill(label, wrap) for label in labels]
    leg = fig.legend(handles, labels, loc="lower center", ncol=ncol, fontsize=fontsize,
                     frameon=False)
    height_px = leg.get_window_extent(fig.canvas.get_renderer()).height + 6.0
    w, h = fig.get_size_inches()
    fig.set_size_inches(w, h + height_px / fig.dpi)
    tight_layout(fig, rect=(0.0, height_px / fig.bbox.height, 1.0, 1.0))


PNG_COMPRESSION = 1
"""zlib level of the PNGs of the report and the run's pictures: the same pixels as the
default level 6, encoded in half the time, for files about 7 % larger."""


def save_png(fig: Figure, target: str | os.PathLike | BinaryIO) -> None:
    """Save ``fig`` as a PNG to ``target`` (a file name or a binary file), at
    ``PNG_COMPRESSION``."""
    fig.savefig(target, format="png", pil_kwargs={"compress_level": PNG_COMPRESSION})


def png_bytes(fig: Figure) -> bytes:
    """``fig`` as PNG bytes (``save_png``)."""
    buf = io.BytesIO()
    save_png(fig, buf)
    return buf.getvalue()


def walls_at(walls: dict[str, Any], events: dict[str, Any], time: float,
             active: np.ndarray) -> dict[str, Any]:
    """``walls`` (results.h5 /walls, the silo as built) as they stood at ``time`` [s]: a
    gate sliding open, still in place (``active``), moved as far as it had slid
    (``silo.geometry.gate_shift``); the same dict when no wall had moved."""
    geometry = WallGeometry.of(walls)
    shift = gate_shift(events, geometry.names, geometry.ax, geometry.bx, time)
    shift = shift * np.asarray(active, dtype=bool)
    if not shift.any():
        return walls
    return {**walls, "ax": np.asarray(walls["ax"]) + shift, "bx": np.asarray(walls["bx"]) + shift}


def draw_walls(ax: Axes, walls: dict[str, Any], active: np.ndarray | None = None) -> None:
    """Wall segments; withdrawn walls (the open gate) dotted."""
    act = walls["active"] if active is None else active
    for k in range(len(walls["ax"])):
        ax.plot([walls["ax"][k], walls["bx"][k]], [walls["ay"][k], walls["by"][k]],
                "-" if act[k] else ":", color="k", lw=1.6, zorder=5)


def grain_disks(ax: Axes, p: dict[str, np.ndarray], autolim: bool = True,
                **kw: Any) -> EllipseCollection:
    """The grains ``p`` (x, y, radius [m]) as disks to scale, added to ``ax`` and returned
    (``kw``: the collection's colours, colour map, ...; ``autolim=False`` leaves the axes'
    data limits alone, for axes whose limits are fixed, as an animation's).

    One EllipseCollection in data units: the same disks as a PatchCollection of Circles, but
    made and drawn several times faster (no Patch object per grain).  The collection's own
    data limits are its centres only, so the disks' extents are added to the axes' limits, as
    the Circles' were."""
    radius = np.asarray(p["radius"], dtype=float)
    centres = np.column_stack([p["x"], p["y"]]).astype(float)
    disks = EllipseCollection(2.0 * radius, 2.0 * radius, np.zeros_like(radius), units="xy",
                              offsets=centres, offset_transform=ax.transData, **kw)
    ax.add_collection(disks, autolim=autolim)
    if autolim and radius.size:
        ax.update_datalim(np.concatenate([centres - radius[:, None], centres + radius[:, None]]))
    return disks


def draw_grains(ax: Axes, p: dict[str, np.ndarray], color: str = "#e4ddcf",
                edge: str = "#9c9280", **kw: Any) -> None:
    """The grains ``p`` as disks to scale, filled with ``color``, outlined in ``edge``."""
    grain_disks(ax, p, facecolor=color, edgecolor=edge, linewidth=0.3, **kw)


def draw_force_network(ax: Axes, snap: dict[str, Any], walls: dict[str, Any],
                       fmax: float | None = None, cmap: str | Colormap = "inferno_r",
                       max_width: float = 4.0, events: dict[str, Any] | None = None
                       ) -> tuple[LineCollection | None, float]:
    """Grains, and every touching contact as a line whose width and colour grow with its normal
    force (grain-grain: between the centres; grain-wall: from the centre to the wall, a
    sliding gate where it stood at the snapshot's time, from the run's ``events``).
    Returns the line collection (for a colour bar) and the force scale [N]."""
    p, c, wc = snap["particles"], snap["contacts"], snap["wall_contacts"]
    draw_grains(ax, p)
    active = snap.get("walls_active")
    if events is not None and active is not None:
        walls = walls_at(walls, events, float(snap["@attrs"].get("time", np.nan)), active)
    draw_walls(ax, walls, active)
    segs, forces = [], []
    if c["fn"].size:
        segs.append(np.stack([np.column_stack([p["x"][c["i"]], p["y"][c["i"]]]),
                              np.column_stack([p["x"][c["j"]], p["y"][c["j"]]])], axis=1))
        forces.append(c["fn"])
    if wc["fn"].size:
        g = wc["grain"]
        cx, cy = contact_points_walls(p["x"], p["y"], g, wc["wall"], walls["ax"], walls["ay"],
                                      walls["bx"], walls["by"])
        segs.append(np.stack([np.column_stack([p["x"][g], p["y"][g]]),
                              np.column_stack([cx, cy])], axis=1))
        forces.append(wc["fn"])
    if not segs:
        return None, 0.0
    seg = np.concatenate(segs)
    f = np.concatenate(forces)
    scale = float(fmax if fmax else (f.max() or 1.0))
    lc = LineCollection(seg, linewidths=0.15 + max_width * f / scale, cmap=cmap, zorder=4)
    lc.set_array(f)
    lc.set_clim(0.0, scale)
    ax.add_collection(lc)
    return lc, scale


# the measurement circles' colours (Okabe & Ito's palette, told apart by readers of every
# kind of colour vision) and markers (for a reader who cannot tell any colours, and in print):
# circle k has the same style in every figure of a report (Figs. 2 and 7); the switch zone's
# left and right circles were green and red, alike to a red-green colour-blind reader
CIRCLE_COLORS = ("#0072B2", "#E69F00", "#009E73", "#D55E00", "#CC79A7", "#56B4E9")
CIRCLE_MARKERS = ("o", "s", "^", "D", "v", "P")
CIRCLE_MARKS = 12  # markers along a curve of circle samples


def circle_style(k: int, samples: int) -> dict[str, Any]:
    """Matplotlib line keywords of measurement circle ``k`` on a curve of ``samples`` points:
    its colour and marker (:data:`CIRCLE_COLORS`, :data:`CIRCLE_MARKERS`), about
    :data:`CIRCLE_MARKS` markers along it."""
    return {"color": CIRCLE_COLORS[k % len(CIRCLE_COLORS)],
            "marker": CIRCLE_MARKERS[k % len(CIRCLE_MARKERS)], "ms": 5,
            "markevery": max(1, samples // CIRCLE_MARKS)}


def shade_phases(ax: Axes, x: npt.ArrayLike, phase: npt.ArrayLike) -> None:
    """Shade the filling, settling and discharge periods along the x axis (time or steps)."""
    x = np.asarray(x)
    phase = np.asarray(phase)
    if x.size == 0:
        return
    seen = set()
    start = 0
    for k in range(1, x.size + 1):
        if k == x.size or phase[k] != phase[start]:
            code = int(phase[start])
            color, label = PHASE_COLORS.get(code, ("#ffffff", ""))
            ax.axvspan(x[start], x[k - 1], color=color, zorder=0,
                       label=None if code in seen else label)
            seen.add(code)
            start = k


RATIO_TOP = 3.0  # sigma_h / sigma_v axes end here: near-empty zones give spikes far above it


def ratio_axis(ax: Axes, *curves: npt.ArrayLike) -> None:
    """Limit a stress-ratio axis to [0, RATIO_TOP] and, when a drawn value lies above that,
    say so in the panel instead of cutting the curve silently."""
    ax.set_ylim(0, RATIO_TOP)
    values = np.concatenate([np.ravel(np.asarray(c, dtype=float)) for c in curves] or [[]])
    top = np.max(values[np.isfinite(values)], initial=-np.inf)
    if top > RATIO_TOP:
        digits = next(d for d in range(3, 18) if float(f"{top:.{d}g}") > RATIO_TOP)
        # in an opaque box above the traces (a spike showed through one of alpha 0.85)
        ax.text(0.99, 0.97, f"axis cut at {RATIO_TOP:g}: values up to {top:.{digits}g}",
                transform=ax.transAxes, ha="right", va="top", fontsize=7, color="0.35",
                zorder=5, bbox={"facecolor": "white", "edgecolor": "none", "pad": 1.0})


def loaded_ratio(sh: npt.ArrayLike, sv: npt.ArrayLike) -> np.ndarray:
    """sigma_h / sigma_v [-] per sample, NaN where the circle is almost unloaded: sigma_v
    under ``UNLOADED`` (0.1) x the median of its positive values over the series, the rule by
    which a study's CV of the ratio (``silodem.report.numbers.loaded``) and its Fig. 7 leave
    samples out.  A ratio of two near-zero stresses (the start of filling, an emptied silo:
    sigma_v of 32 Pa against a median of 1e4 Pa gave 43.5) is noise, not anisotropy.  (The
    study report's Fig. 7 draws it too.)"""
    sh = np.asarray(sh, dtype=float)
    sv = np.asarray(sv, dtype=float)
    ok = loaded(sv, np.isfinite(sv) & (sv > 0))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(ok, sh / sv, np.nan)


def rolling_mean(y: npt.ArrayLike, n: int) -> np.ndarray:
    """Centred running mean over n samples (NaN-aware)."""
    y = np.asarray(y, dtype=float)
    if n <= 1 or y.size < n:
        return y
    ok = np.isfinite(y)
    k = np.ones(n)
    num = np.convolve(np.where(ok, y, 0.0), k, mode="same")
    den = np.convolve(ok.astype(float), k, mode="same")
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, num / den, np.nan)


def silo_axes(ax: Axes, geom: dict[str, float], margin: float = 0.3) -> None:
    ax.set_aspect("equal")
    ax.set_xlim(-margin, geom["B"] + margin)
    ax.set_ylim(-0.6, geom["top"] + margin)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
