"""The scales a run's pictures share, fixed over all its frames so that frames (and the
report's pictures) compare: the force lines' widths and opacities [pt, -] against the run's
force scale, its key's forces, and the percentiles of a quantity over the frames that set the
colour scales (read from a thinned sample where the frames hold many values)."""

from __future__ import annotations

import math

import numpy as np

from silodem.silo.frames import Frames, FramesFile

# force-line widths [pt]: CHAIN_WIDTH at the run's force scale, clipped to CHAIN_WIDTHS
CHAIN_WIDTH = 2.5
CHAIN_WIDTHS = (0.15, 6.0)


def chain_widths(fn: np.ndarray, force_scale: float) -> np.ndarray:
    """Line widths [pt] of contacts with normal forces ``fn`` [N]: proportional to the force,
    ``CHAIN_WIDTH`` at ``force_scale`` [N], clipped to ``CHAIN_WIDTHS``."""
    return np.clip(CHAIN_WIDTH * np.asarray(fn, dtype=float) / force_scale, *CHAIN_WIDTHS)


CHAIN_ALPHA = 0.9  # the opacity of a force line (and of a cell of chains at full force)


def chain_alphas(force_max: np.ndarray, force_scale: float) -> np.ndarray:
    """Opacity of the chains' cells of a frame drawn as pixels (``viz.raster``): proportional
    to the largest normal force [N] of the contacts centred in the cell, ``CHAIN_ALPHA`` (a
    force line's) from the run's force scale [N] up, as a line is ``CHAIN_WIDTH`` wide there."""
    return CHAIN_ALPHA * np.clip(np.asarray(force_max, dtype=float) / force_scale, 0.0, 1.0)


def key_forces(force_scale: float, raster: bool = False) -> list[float]:
    """Forces [N] for the line-width key: the run's force scale to one significant figure, and
    half and twice that, less any whose line would be clipped (``CHAIN_WIDTHS``: twice a scale
    rounded up, e.g. 1.5 -> 2, would be drawn 6.7 pt wide, which the network draws at 6).
    For a frame drawn as pixels (``raster``, opacity full from the scale up, ``chain_alphas``):
    a quarter, half and the whole of that force."""
    base = float(f"{force_scale:.0e}")
    if raster:
        return [0.25 * base, 0.5 * base, base]
    lo, hi = CHAIN_WIDTHS
    return [f for f in (0.5 * base, base, 2.0 * base)
            if lo <= CHAIN_WIDTH * f / force_scale <= hi]


def positive_percentile(values: list[np.ndarray], q: float,
                         default: float | None) -> float | None:
    """The ``q``-th percentile of the finite positive values, else ``default``."""
    data = np.concatenate([np.asarray(v, dtype=float).ravel() for v in values]) if values \
        else np.zeros(0)
    data = data[np.isfinite(data) & (data > 0)]
    return float(np.percentile(data, q)) if data.size else default


SCALE_SAMPLE = 8_000_000  # at most about this many values kept for a scale over all frames


def every_frame(frames: Frames, column) -> list[np.ndarray]:
    """``column(frame)`` of every frame, read a block at a time, each thinned to every k-th
    value where the frames hold more than SCALE_SAMPLE in all (k = ceil(values in the frame x
    frames / SCALE_SAMPLE)): a percentile of a million grains over 200 frames kept 800 MB."""
    out = []
    for frame in frames:
        values = np.asarray(column(frame))
        stride = max(1, math.ceil(values.size * len(frames) / SCALE_SAMPLE))
        out.append(values[::stride])
    return out


def settled_or_all(q: float, settled: list[np.ndarray], every) -> float:
    """The ``q``-th percentile of the positive values of the settled packing's frame, else
    of ``every()`` (all the frames' values, read only then), else 1."""
    top = positive_percentile(settled, q, None)
    return top if top is not None else positive_percentile(every(), q, 1.0)


def most_grains(frames: Frames) -> int:
    """The most grains in any frame (from the index of a results file's frames)."""
    if isinstance(frames.frames, FramesFile):
        n = np.diff(np.asarray(frames.frames.index["particle_offset"], dtype=np.int64))
        return int(n.max()) if n.size else 0
    return max((f.n for f in frames.frames), default=0)
