"""Frames of very many grains drawn as pixels: where even the largest grain is under
``RASTER_BELOW_PX`` pixels across, disks to scale cannot be told apart, and drawing a million
of them (and a million contact lines) through matplotlib took about 9 s a frame
(``FrameArtist``, 800 px tall).  Instead each pixel of the plot gets the grains (and the
contacts) whose centres fall in it, binned with ``np.bincount`` (cells of a few pixels where
the grains are nearly as large as one, ``raster_shape``): 0.2 s a frame at 1e6 grains
(``benchmarks/frame_drawing.py``).

Pure functions over arrays; ``FrameArtist`` turns their output into an image.
"""

from __future__ import annotations

import math

import numpy as np

RASTER_BELOW_PX = 2.0  # the largest grain's diameter [px] under which a frame is drawn as pixels


def raster_shape(plot_h: float, plot_w: float, diameter_px: float) -> tuple[int, int]:
    """(rows, columns) of the cells a frame is binned into on a plot ``plot_h`` x ``plot_w``
    pixels whose largest grain is ``diameter_px`` across: cells of a whole number of pixels,
    at least two grain diameters wide, so that a packed region (about one centre per squared
    diameter in 2D) leaves almost no cell empty; one pixel per cell for grains half a pixel
    across or less."""
    side = max(1, math.ceil(2.0 * diameter_px))
    return max(1, round(plot_h / side)), max(1, round(plot_w / side))


def pixel_index(x: np.ndarray, y: np.ndarray, xlim: tuple[float, float],
                ylim: tuple[float, float], shape: tuple[int, int]) -> np.ndarray:
    """The flat index ``row * ncol + col`` of the pixel holding each point (x, y) [m] on a
    grid of ``shape`` = (nrow, ncol) pixels spanning ``xlim`` x ``ylim`` (row 0 at the bottom,
    ``ylim[0]``); -1 for points outside it."""
    nrow, ncol = shape
    col = np.floor((np.asarray(x, dtype=float) - xlim[0]) * (ncol / (xlim[1] - xlim[0])))
    row = np.floor((np.asarray(y, dtype=float) - ylim[0]) * (nrow / (ylim[1] - ylim[0])))
    inside = (col >= 0) & (col < ncol) & (row >= 0) & (row < nrow)
    return np.where(inside, row * ncol + col, -1).astype(np.int64)


def pixel_count_and_mean(index: np.ndarray, values: np.ndarray | None,
                         shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """(count, mean) over the pixels (arrays of ``shape``): how many points fall in each (their
    ``index`` from ``pixel_index``; -1 is dropped), and the mean of their ``values`` (NaN where
    none does, and everywhere when ``values`` is None)."""
    size = shape[0] * shape[1]
    keep = index >= 0
    count = np.bincount(index[keep], minlength=size).astype(float)
    mean = np.full(size, np.nan)
    if values is not None:
        total = np.bincount(index[keep], weights=np.asarray(values, dtype=float)[keep],
                            minlength=size)
        has = count > 0
        mean[has] = total[has] / count[has]
    return count.reshape(shape), mean.reshape(shape)


def pixel_max(index: np.ndarray, values: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The largest of the non-negative ``values`` over the points in each pixel (``index``
    from ``pixel_index``); 0 where none is."""
    keep = index >= 0
    out = np.zeros(shape[0] * shape[1])
    np.maximum.at(out, index[keep], np.asarray(values, dtype=float)[keep])
    return out.reshape(shape)
