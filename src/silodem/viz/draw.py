"""Drawing a frame: disks to scale, the force network (line width ~ normal force, with a key
of three widths), the walls; grains under ``RASTER_BELOW_PX`` across as cells of pixels
(``viz.raster``: mean colour per cell, chains' opacity ~ the cell's largest normal force).

``FrameArtist`` owns one matplotlib figure (Agg canvas, no pyplot) and redraws only what changes
from frame to frame, so animations render fast.  Colour scales and the force-line scale are
fixed over all the frames of a run (``viz.scales``), so frames (and the report's pictures) compare.
"""

from __future__ import annotations

import io
import itertools
import math
import numbers
from collections.abc import Iterable

import matplotlib

matplotlib.use("Agg")
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.collections import LineCollection
from matplotlib.colors import BoundaryNorm, Normalize, to_rgb
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from silodem.report.draw import PNG_COMPRESSION, grain_disks
from silodem.silo.frames import Frame, Frames
from silodem.viz.raster import (
    RASTER_BELOW_PX,
    pixel_count_and_mean,
    pixel_index,
    pixel_max,
    raster_shape,
)
from silodem.viz.scales import (
    CHAIN_ALPHA,
    chain_alphas,
    chain_widths,
    every_frame,
    key_forces,
    most_grains,
    positive_percentile,
    settled_or_all,
)
from silodem.viz.title import (
    ELLIPSIS,
    FIELD_GAP,
    ONE_LINE_SIZES,
    TITLE_LINES,
    TITLE_MARGIN,
    TITLE_PAD,
    TITLE_SIZES,
    TOP_MIN,
    fit_title,
    lines_height,
    shortened,
    text_size,
    text_width,
    title_lines,
    title_tokens,
)

COLORS = ("velocity", "force", "coordination", "none")
_LABELS = {"velocity": "grain speed |v| [m/s]",
           "force": "sum of the grain's contact normal forces [N]",
           "coordination": "coordination number (contacts per grain) [-]"}
# grain colours: low ends pale for speed and force (the red chains of grains at rest read on
# them); all colour-blind safe (ColorBrewer YlGnBu, viridis)
_CMAPS = {"velocity": "YlGnBu", "force": "YlGnBu", "coordination": "viridis"}
CHAIN_COLOR = "#c0152f"
PLAIN_GRAIN = "#ddd5c4"
_MAX_COORD = 7
HEIGHT_PX = (200, 8000)  # the heights [px] a figure may have (room for its axes and key)
# the widest figure [px]: libx264 refused a 26,800 px wide frame (a silo 70 m wide and 1 m
# tall), after every frame had been drawn; wider silos get a lower figure
WIDTH_PX_MAX = 8000


KEY_GAP = 14  # px between the plot, the colour bar and the force key
_BAR_WIDTH = 16  # px: the colour bar
_BAR_COLUMN = 92  # px: the colour bar with its ticks and its label, rotated, on one line
# the colour bar's label, rotated along the bar: on one line at 8 pt where the figure has room
# for it, else smaller or on more lines (``bar_label``); its ends at least _LABEL_END px over the
# figure's bottom and at most that over the plot's top (TITLE_PAD under the title)
_LABEL_SIZES = (8.0, 7.0)  # pt, largest first (7: the tick labels' size)
_LABEL_LINES = 3  # at most
_LABEL_END = 4


def _legend_size_px(kw: dict) -> tuple[float, float]:
    """(width, height) [px at 100 dpi] of a figure legend made with ``kw``, measured on a
    scratch figure (its size does not depend on the figure's)."""
    fig = Figure(figsize=(4, 4), dpi=100)
    canvas = FigureCanvasAgg(fig)
    box = fig.legend(**kw).get_window_extent(canvas.get_renderer())
    return float(box.width), float(box.height)


def bar_label(text: str, room: float) -> tuple[str, float, float, float]:
    """The colour bar's label ``text`` set to run at most ``room`` px along the bar: (its
    lines, font size [pt], length and thickness [px]).  On one line at the largest of
    ``_LABEL_SIZES`` it fits at, else on two lines (then up to ``_LABEL_LINES``) at the largest
    size they fit at, broken between words: before a bracket, as "coordination number" over
    "(contacts per grain) [-]", where that fits, else where the longest line is shortest.
    Where nothing fits (a very low figure), the shortest of them."""
    words = text.split(" ")
    shortest = None
    for lines in range(1, min(_LABEL_LINES, len(words)) + 1):
        for size in _LABEL_SIZES:
            fits = []
            for breaks in itertools.combinations(range(1, len(words)), lines - 1):
                cut = [0, *breaks, len(words)]
                set_as = "\n".join(" ".join(words[a:b]) for a, b in itertools.pairwise(cut))
                length, thickness = text_size(set_as, size)
                if length <= room:  # (first the fewest breaks not before a bracket)
                    fits.append((sum(words[k][0] not in "([" for k in breaks), length,
                                 set_as, thickness))
                if shortest is None or length < shortest[2]:
                    shortest = (set_as, size, length, thickness)
            if fits:
                _, length, set_as, thickness = min(fits)
                return set_as, size, length, thickness
    return shortest


def _even16(px: float) -> int:
    return max(16, round(px / 16.0) * 16)


class FrameArtist:
    """Draws the frames of ``frames`` coloured by ``color`` on a figure ``height_px`` tall."""

    def __init__(self, frames: Frames, color: str = "velocity", height_px: int = 800,
                 title: str | None = None, titles: Iterable[str] | None = None) -> None:
        """``title``: the scenario's name in the default title (``draw``); ``titles``: the
        titles ``draw`` will be given, if not the default one: the figure keeps room over the
        plot for the longest of them (at small heights on two lines)."""
        if not isinstance(frames, Frames):
            raise TypeError(f"frames must be a run's Frames (silodem.silo.frames.read_frames); "
                             f"got a {type(frames).__name__}")
        if color not in COLORS:
            raise ValueError(f"color must be one of {', '.join(COLORS)}; got {color!r}")
        if isinstance(height_px, bool) or not isinstance(height_px, numbers.Integral) \
                or not HEIGHT_PX[0] <= height_px <= HEIGHT_PX[1]:
            raise ValueError(f"height_px must be an integer from {HEIGHT_PX[0]} to "
                             f"{HEIGHT_PX[1]}; got {height_px!r}")
        self.frames = frames
        self.color = color
        self.title = title if title is not None else str(frames.scenario)
        walls = frames.walls
        r_max = frames.largest_radius() or 0.1  # (read column-wise, not frame by frame)
        xs = np.concatenate([walls.ax, walls.bx])
        ys = np.concatenate([walls.ay, walls.by])
        margin = max(0.05 * (ys.max() - ys.min()), 3 * r_max)
        self.xlim = (float(xs.min()) - margin, float(xs.max()) + margin)
        self.ylim = (float(ys.min()) - 5.5 * r_max, float(ys.max()) + margin)

        # scales fixed over the run, taken from the settled packing (the end of filling) so that
        # the impacts of pouring do not flatten the static force network; all the frames
        # (read a block at a time) only where that has no value, and for the velocity colour
        ref = [frames.end_of_filling()] if len(frames) else []
        self.force_scale = settled_or_all(
            90.0, [f.contacts["fn"] for f in ref] + [f.wall_contacts["fn"] for f in ref],
            lambda: every_frame(frames, lambda f: f.contacts["fn"]))
        if color == "velocity":
            top = positive_percentile(every_frame(frames, Frame.speed), 95.0, 1.0)
            self.norm = Normalize(0.0, top)
        elif color == "force":
            top = settled_or_all(95.0, [f.normal_force_sum() for f in ref],
                                  lambda: every_frame(frames, Frame.normal_force_sum))
            self.norm = Normalize(0.0, 1.2 * top)
        elif color == "coordination":
            self.norm = BoundaryNorm(np.arange(-0.5, _MAX_COORD + 1.0), 256)
        else:
            self.norm = None
        self.cmap = matplotlib.colormaps[_CMAPS[color]] if color in _CMAPS else None

        # the figure [px]: axes sized to the silo (equal scales); right of them a column with
        # the force key at the top and the colour bar under it (beside it where that leaves
        # the bar shorter than 40 % of the plot or than its label): no key hides a grain or
        # a wall
        dpi = 100
        aspect = (self.xlim[1] - self.xlim[0]) / (self.ylim[1] - self.ylim[0])
        left, bottom = 62, 45
        gap = KEY_GAP
        # the colour bar at least as long as its label (rotated along it) and 40 % of the plot
        bar_min, label_w = text_size(_LABELS[color], _LABEL_SIZES[0]) \
            if self.norm is not None else (0.0, 0.0)

        def layout(h: int, top: int) -> tuple[bool, dict, float, bool, int, tuple, int]:
            """For a figure h px tall: (grains drawn as pixels, the key's legend arguments,
            its height [px], key beside the bar, right margin [px], the colour bar's label
            (``bar_label``), the colour bar's column [px])."""
            plot_h = h - bottom - top
            # the label between the figure's bottom and the title: where it does not fit on
            # one line at 8 pt (under about 290 px) smaller or on more lines, the column wider
            label = bar_label(_LABELS[color], h - top) if self.norm is not None else None
            bar_col = gap + _BAR_COLUMN + max(0, math.ceil(label[3] - label_w)) \
                if label is not None else 0
            # grains under RASTER_BELOW_PX across even at their largest: cells of pixels
            raster = 2.0 * r_max * plot_h / (self.ylim[1] - self.ylim[0]) < RASTER_BELOW_PX
            key_kw = self._key_arguments(raster)
            key_w, key_h = _legend_size_px(key_kw)
            beside = self.norm is not None and \
                plot_h - key_h - gap < max(0.4 * plot_h, bar_min)
            key_col = gap + key_w + 8
            right = round((bar_col + key_col if beside else max(bar_col, key_col)) + 8)
            return raster, key_kw, key_h, beside, right, label, bar_col

        # the title: room over the plot for the longest title to be drawn (the default one
        # with the run's widest time, phase and grain count), on one line, else on two
        n_most, t_last = most_grains(frames), float(np.max(frames.times, initial=0.0))
        widest_phase = max(("fill", "settle", "discharge"),
                           key=lambda ph: text_width(f"{ph:<9}", TITLE_SIZES[0]))
        longest = [title_tokens(t) for t in titles or ()] or \
            [self._default_tokens(self.title, t_last, widest_phase, n_most)]
        for lines in range(1, TITLE_LINES + 1):
            top = max(TOP_MIN, math.ceil(TITLE_PAD + lines_height(lines) + TITLE_MARGIN))
            h = _even16(height_px)
            self.raster, key_kw, key_h, beside, right, label, bar_col = layout(h, top)
            for _ in range(3):  # (a lower figure may draw pixels, whose key differs: once)
                widest_plot = WIDTH_PX_MAX - left - right - 16  # (room for rounding to 16 px)
                if aspect * (h - bottom - top) <= widest_plot:
                    break
                # a wide silo: a lower figure, not a wider one
                h = max(96, 16 * int((widest_plot / aspect + bottom + top) // 16))
                self.raster, key_kw, key_h, beside, right, label, bar_col = layout(h, top)
            plot_h = h - bottom - top
            plot_w = aspect * plot_h
            w = _even16(left + plot_w + right)
            self._title_lines_max = lines
            # from the plot's left edge where the title fits there on one line at full size
            for x0 in (left, TITLE_MARGIN):
                self._title_x0, self._title_room = x0, w - x0 - TITLE_MARGIN
                fitted = [fit_title(t, self._title_room, lines) for t in longest]
                # (on one line no smaller than ONE_LINE_SIZES, or on the lines reserved)
                fits = all(f is not None and (lines == TITLE_LINES or f[0] >= ONE_LINE_SIZES[-1])
                           for f in fitted)
                if fits and (x0 != left or all(f == (TITLE_SIZES[0], []) for f in fitted)):
                    break
            if fits:
                break
        # the default title's size and lines for every frame (a frame's is no wider) and, if
        # it does not fit even so, the scenario's name shortened to fit (both its ends kept:
        # the runs of a study differ at the end)
        def shown(k: int) -> str:  # k characters of the name: its middle left out
            name = self.title
            return name if k == len(name) else \
                name[:(k + 1) // 2] + ELLIPSIS + name[len(name) - k // 2:]

        k, self._default_fit = shortened(
            lambda k: self._default_tokens(shown(k), t_last, widest_phase, n_most),
            len(self.title), self._title_room, self._title_lines_max)
        self._title_name = shown(k)
        self.height_px = h
        self.width_px = w
        self._title_y0 = bottom + plot_h + TITLE_PAD
        diameter_px = 2.0 * r_max * plot_h / (self.ylim[1] - self.ylim[0])
        self.raster_shape = raster_shape(plot_h, plot_w, diameter_px)
        self.fig = Figure(figsize=(w / dpi, h / dpi), dpi=dpi, facecolor="white")
        self.canvas = FigureCanvasAgg(self.fig)
        ax = self.fig.add_axes((left / w, bottom / h, plot_w / w, plot_h / h))
        ax.set_aspect("equal")
        ax.set_xlim(*self.xlim)
        ax.set_ylim(*self.ylim)
        ax.set_xlabel("x [m]", fontsize=8)
        ax.set_ylabel("z [m]", fontsize=8)
        ax.tick_params(labelsize=7)
        plot_right, plot_top = left + plot_w, bottom + plot_h
        key_left = plot_right + (bar_col if beside else 0) + gap
        # the key of the force lines' widths, fixed over the run like their scale
        self.force_key = self.fig.legend(loc="upper left",
                                         bbox_to_anchor=(key_left / w, plot_top / h), **key_kw)
        if self.norm is not None:
            bar_top = plot_top if beside else plot_top - key_h - gap
            bar_bottom = bottom + (0.1 * plot_h if beside else 0.0)
            cax = self.fig.add_axes(((plot_right + gap) / w, bar_bottom / h, _BAR_WIDTH / w,
                                     (bar_top - bar_bottom) / h))
            cb = self.fig.colorbar(ScalarMappable(norm=self.norm, cmap=self.cmap), cax=cax)
            set_as, size, length, _ = label
            cb.set_label(set_as, fontsize=size)
            if length > bar_top - bar_bottom:  # a low figure: a label longer than the bar,
                # moved down from the bar's middle to end under the title, over the figure's
                # bottom (it is centred on the bar, ends sticking out)
                middle = min(max(0.5 * (bar_top + bar_bottom), _LABEL_END + 0.5 * length),
                             plot_top + _LABEL_END - 0.5 * length)
                cb.ax.yaxis.label.set_y((middle - bar_bottom) / (bar_top - bar_bottom))
            cb.ax.tick_params(labelsize=7)
            if color == "coordination":
                cb.set_ticks(range(_MAX_COORD + 1))
        self.ax = ax
        self.wall_lines = [ax.plot([walls.ax[k], walls.bx[k]], [walls.ay[k], walls.by[k]],
                                   color="k", lw=1.6, solid_capstyle="round")[0]
                           for k in range(len(walls))]
        # the title over the plot, its bottom TITLE_PAD px over it (set by draw)
        self.text = self.fig.text(self._title_x0 / w, self._title_y0 / h, "", ha="left",
                                  va="bottom", fontsize=TITLE_SIZES[0], parse_math=False)
        self._artists: list = []

    def _key_arguments(self, raster: bool) -> dict:
        """The legend arguments of the force lines' key: three widths, or for grains drawn as
        pixels one width at the opacity of a cell whose largest force is f."""
        if raster:
            handles = [Line2D([], [], color=CHAIN_COLOR, solid_capstyle="butt", lw=5.0,
                              alpha=float(chain_alphas(f, self.force_scale)), label=f"{f:g} N")
                       for f in key_forces(self.force_scale, raster=True)]
        else:
            handles = [Line2D([], [], color=CHAIN_COLOR, alpha=CHAIN_ALPHA, solid_capstyle="round",
                              lw=float(chain_widths(f, self.force_scale)), label=f"{f:g} N")
                       for f in key_forces(self.force_scale)]
        title = "largest contact normal\nforce in each cell" if raster else "contact normal force"
        return {"handles": handles, "title": title, "fontsize": 7, "title_fontsize": 7,
                "framealpha": 0.85, "handlelength": 2.2, "borderaxespad": 0.0}

    # --- drawing ------------------------------------------------------------------------------
    def draw(self, frame: Frame, title: str | None = None) -> None:
        for artist in self._artists:
            artist.remove()
        self._artists = []
        p = frame.particles
        x, y, r = (p[k].astype(float) for k in ("x", "y", "radius"))
        if self.raster:
            self._draw_pixels(frame, x, y)
        else:
            self._draw_disks(frame, x, y, r)
        shift, walls = self.frames.wall_shift(frame.time), self.frames.walls
        for k, line in enumerate(self.wall_lines):
            on = bool(frame.walls_active[k]) if k < frame.walls_active.size else True
            dx = shift[k] if on else 0.0  # (a sliding gate where it is; once gone, where it was)
            line.set_xdata([walls.ax[k] + dx, walls.bx[k] + dx])
            line.set_linestyle("-" if on else ":")
            line.set_alpha(1.0 if on else 0.5)
        self._set_title(frame, title)

    # --- the title ----------------------------------------------------------------------------
    @staticmethod
    def _default_tokens(name: str, time: float, phase: str, n: int
                        ) -> list[tuple[str, str, int]]:
        """The default title's pieces: on one line "name   t = time s   phase   n grains"."""
        head = title_tokens(name)
        head[-1] = (head[-1][0], FIELD_GAP, 0)
        return [*head, (f"t = {time:6.2f} s", FIELD_GAP, 0), (f"{phase:<9}", FIELD_GAP, 0),
                (f"{n} grains", "", 3)]

    def _set_title(self, frame: Frame, title: str | None) -> None:
        """Set the title's text and size: the default one (``title`` None) at the size and
        with the line breaks fixed for the run where the frame's fits them (it does unless
        a font draws some digits wider), any other to fit (``title.fit_title``), shortened with
        an ellipsis where even two lines of 7 pt are too few."""
        room, lines = self._title_room, self._title_lines_max
        fit = None
        if title is None:
            tokens = self._default_tokens(self._title_name, frame.time, frame.phase, frame.n)
            fit = self._default_fit
            if fit is not None and any(text_width(x, fit[0]) > room
                                       for x in title_lines(tokens, fit[1])):
                fit = None
            title = "".join(p + s for p, s, _ in tokens)
        if fit is None:
            def shown(k: int) -> list[tuple[str, str, int]]:
                return title_tokens(title if k == len(title) else title[:k] + ELLIPSIS)

            k, fit = shortened(shown, len(title), room, lines)
            tokens = shown(k)
        size, breaks = fit if fit is not None else (TITLE_SIZES[-1], [])
        self.text.set_fontsize(size)
        self.text.set_text("\n".join(title_lines(tokens, breaks)))

    def _draw_disks(self, frame: Frame, x: np.ndarray, y: np.ndarray, r: np.ndarray) -> None:
        """The grains of ``frame`` as disks to scale, its contacts as lines whose width grows
        with the normal force (``chain_widths``)."""
        ax = self.ax
        if frame.n:
            kw: dict = {"facecolors": PLAIN_GRAIN} if self.norm is None else {
                "array": self._values(frame), "cmap": self.cmap, "norm": self.norm}
            disks = grain_disks(ax, {"x": x, "y": y, "radius": r}, autolim=False,
                                edgecolors="#5c5346", linewidths=0.3, zorder=2, **kw)
            self._artists.append(disks)
        segs, fn = self._chains(frame, x, y)
        if fn.size:
            widths = chain_widths(fn, self.force_scale)
            chains = LineCollection(segs, linewidths=widths, colors=CHAIN_COLOR,
                                    alpha=CHAIN_ALPHA, capstyle="round", zorder=3)
            ax.add_collection(chains, autolim=False)
            self._artists.append(chains)

    def _draw_pixels(self, frame: Frame, x: np.ndarray, y: np.ndarray) -> None:
        """The grains and chains of ``frame`` as two images of cells of the plot's pixels
        (``raster_shape``): a cell with grains' centres in it takes their mean colour value (or
        the plain grain colour); the chains' cell is opaque in proportion to the largest normal
        force of the contacts centred in it (``chain_alphas``)."""
        shape, extent = self.raster_shape, (*self.xlim, *self.ylim)
        index = pixel_index(x, y, self.xlim, self.ylim, shape)
        values = self._values(frame) if self.norm is not None else None
        count, mean = pixel_count_and_mean(index, values, shape)
        if self.norm is None:
            grains = np.empty((*shape, 4))
            grains[..., :3] = to_rgb(PLAIN_GRAIN)
        else:
            grains = self.cmap(self.norm(np.nan_to_num(mean)))
        grains[..., 3] = count > 0
        segs, fn = self._chains(frame, x, y)
        middle = segs.mean(axis=1) if fn.size else np.zeros((0, 2))
        force = pixel_max(pixel_index(middle[:, 0], middle[:, 1], self.xlim, self.ylim, shape),
                          fn, shape)
        chains = np.empty((*shape, 4))
        chains[..., :3] = to_rgb(CHAIN_COLOR)
        chains[..., 3] = chain_alphas(force, self.force_scale)
        for rgba, z in ((grains, 2), (chains, 3)):
            self._artists.append(self.ax.imshow(rgba, extent=extent, origin="lower",
                                                interpolation="nearest", zorder=z))
        self.ax.set_xlim(*self.xlim)  # (imshow sets the limits to its extent: the same)
        self.ax.set_ylim(*self.ylim)
        self.ax.set_aspect("equal")

    def _values(self, frame: Frame) -> np.ndarray:
        if self.color == "velocity":
            return frame.speed().astype(float)
        if self.color == "force":
            return frame.normal_force_sum().astype(float)
        return np.minimum(frame.coordination(), _MAX_COORD).astype(float)

    def _chains(self, frame: Frame, x: np.ndarray, y: np.ndarray):
        c, w = frame.contacts, frame.wall_contacts
        wx, wy = self.frames.walls.closest_points(w["wall"], x[w["grain"]], y[w["grain"]],
                                                  self.frames.wall_shift(frame.time))
        a = np.concatenate([np.column_stack([x[c["i"]], y[c["i"]]]),
                            np.column_stack([x[w["grain"]], y[w["grain"]]])])
        b = np.concatenate([np.column_stack([x[c["j"]], y[c["j"]]]),
                            np.column_stack([wx, wy])])
        fn = np.concatenate([c["fn"], w["fn"]]).astype(float)
        keep = fn > 0
        return np.stack([a[keep], b[keep]], axis=1), fn[keep]

    # --- output -------------------------------------------------------------------------------
    def rgb(self) -> np.ndarray:
        """The drawn figure as an (H, W, 3) uint8 array."""
        self.canvas.draw()
        return np.asarray(self.canvas.buffer_rgba())[..., :3].copy()

    def png(self) -> bytes:
        buf = io.BytesIO()
        self.fig.savefig(buf, format="png", dpi=self.fig.dpi,
                         pil_kwargs={"compress_level": PNG_COMPRESSION})  # as the report's
        return buf.getvalue()
