"""The title over a picture of the grains (``viz.draw.FrameArtist``), fitted to the figure.

The title stands over the plot: on one line from the plot's left edge where it fits there at
full size, else across the figure's width, on one line down to 8 pt, else on two lines (broken
between its fields first, then between words, then after a - _ or /) down to 7 pt (the tick
labels' size); the figure keeps room for the longest title it will draw, and a scenario name
too long even so is shortened with an ellipsis in its middle.  Widths are measured by
matplotlib's renderer, as the figure draws the text.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Iterable

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

TITLE_SIZES = (9.0, 8.5, 8.0, 7.5, 7.0)  # pt, largest first
ONE_LINE_SIZES = (9.0, 8.5, 8.0)  # pt: a title on one line rather than two down to this
TITLE_LINES = 2  # at most
TITLE_PAD = 8  # px between the plot's top and the title's bottom
TITLE_MARGIN = 7  # px between the title and the figure's top (and left and right) edges
TOP_MIN = 28  # px over the plot: a title of one line
FIELD_GAP = "   "  # between the fields of the default title
_IN_WORD = re.compile(r"[^-_/]*[-_/]+|[^-_/]+")
ELLIPSIS = "\u2026"


def title_tokens(text: str) -> list[tuple[str, str, int]]:
    """``text`` cut where a line may break: (piece, the separator after it, how natural a
    break after it is: 0 between fields (after a comma or two spaces or more), 1 between
    words, 2 inside a word after - _ or /, 3 none (the end))."""
    parts = re.split(r"(,\s+|\s{2,}|\s)", text)
    out: list[tuple[str, str, int]] = []
    for k in range(0, len(parts), 2):
        sep = parts[k + 1] if k + 1 < len(parts) else ""
        pieces = _IN_WORD.findall(parts[k]) or [parts[k]]
        out += [(piece, "", 2) for piece in pieces[:-1]]
        out.append((pieces[-1], sep, 3 if not sep else 1 if sep == " " else 0))
    return out


def title_lines(tokens: list[tuple[str, str, int]], breaks: Iterable[int]) -> list[str]:
    """The lines of ``tokens`` broken before each token of ``breaks`` (a separator at a
    break: its comma kept, its spaces dropped)."""
    lines, line, sep = [], "", ""
    breaks = set(breaks)
    for k, (piece, after, _) in enumerate(tokens):
        if k in breaks:
            lines.append((line + sep.rstrip()).rstrip())
            line = piece
        else:
            line += sep + piece
        sep = after
    return [*lines, line.rstrip()]


@functools.cache
def _scratch_text():
    """A text on a scratch figure, and its renderer, to measure text with."""
    fig = Figure(figsize=(4, 4), dpi=100)
    return fig.text(0, 0, "", parse_math=False, va="bottom"), FigureCanvasAgg(fig).get_renderer()


@functools.lru_cache(maxsize=4096)
def text_size(text: str, size: float) -> tuple[float, float]:
    """(width, height) [px at 100 dpi] of ``text`` (its lines as a figure's text sets them,
    no math parsed) at ``size`` [pt]; (0, 0) for no text."""
    if not text:
        return 0.0, 0.0
    scratch, renderer = _scratch_text()
    scratch.set_text(text)
    scratch.set_fontsize(size)
    box = scratch.get_window_extent(renderer)
    return float(box.width), float(box.height)


def text_width(line: str, size: float) -> float:
    """Width [px] of one line of text at ``size`` [pt] (``text_size``)."""
    return text_size(line, size)[0]


def lines_height(lines: int, size: float = TITLE_SIZES[0]) -> float:
    """Height [px] of ``lines`` lines of text at ``size`` [pt] (``text_size``)."""
    return text_size("\n".join(["Ag"] * lines), size)[1]


def _second_line_at(tokens: list[tuple[str, str, int]], level: int, room: float,
                    size: float) -> int | None:
    """The first token that can start a second line (the break before it at most ``level``)
    with both lines no wider than ``room`` [px] at ``size`` [pt]: the name alone over the
    time, phase and grains, a moment's label over its time; None if there is none."""
    for k in range(1, len(tokens)):
        if tokens[k - 1][2] <= level and \
                all(text_width(x, size) <= room for x in title_lines(tokens, [k])):
            return k
    return None


def fit_title(tokens: list[tuple[str, str, int]], room: float,
              max_lines: int) -> tuple[float, list[int]] | None:
    """(font size [pt], line breaks) to set ``tokens`` in at most ``max_lines`` (1 or 2)
    lines no wider than ``room`` [px]: one line at the largest of ``ONE_LINE_SIZES`` it fits
    at, else two (broken between fields, else words, else inside words) at the largest of
    ``TITLE_SIZES``, else (one line allowed) one line at a smaller size; None if none fits."""
    for size in ONE_LINE_SIZES:
        if text_width(title_lines(tokens, [])[0], size) <= room:
            return size, []
    if max_lines >= 2:
        for level in (0, 1, 2):
            for size in TITLE_SIZES:
                k = _second_line_at(tokens, level, room, size)
                if k is not None:
                    return size, [k]
    for size in TITLE_SIZES[len(ONE_LINE_SIZES):]:
        if text_width(title_lines(tokens, [])[0], size) <= room:
            return size, []
    return None


def shortened(make, longest: int, room: float,
              max_lines: int) -> tuple[int, tuple[float, list[int]] | None]:
    """(k, fit) for the largest k <= ``longest`` whose tokens ``make(k)`` fit
    (``fit_title``; k = 0 when none does, with its fit or None)."""
    fit = fit_title(make(longest), room, max_lines)
    if fit is not None:
        return longest, fit
    lo, hi = 0, longest - 1
    while lo < hi:  # (fitting grows no worse as k falls)
        mid = (lo + hi + 1) // 2
        if fit_title(make(mid), room, max_lines) is None:
            hi = mid - 1
        else:
            lo = mid
    return lo, fit_title(make(lo), room, max_lines)
