"""Frames of very many grains drawn as pixels (viz/raster.py, FrameArtist): the binning against
a brute-force loop over the pixels, and the drawn images against the same reference."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.colors import to_rgb
from reliability_helpers import benchmark_module

from silodem.silo.frames import Frames
from silodem.viz.draw import CHAIN_ALPHA, CHAIN_COLOR, FrameArtist
from silodem.viz.raster import RASTER_BELOW_PX, pixel_count_and_mean, pixel_index, pixel_max


def _brute_force(x, y, v, xlim, ylim, shape):
    """count, mean and maximum of ``v`` per pixel, each point's pixel found by comparing it
    with every pixel edge (a pixel holds [left, right) x [bottom, top)), the rest by a loop."""
    nrow, ncol = shape
    x_edges = xlim[0] + (xlim[1] - xlim[0]) / ncol * np.arange(ncol + 1)
    y_edges = ylim[0] + (ylim[1] - ylim[0]) / nrow * np.arange(nrow + 1)
    col = (x[:, None] >= x_edges[None, :]).sum(axis=1) - 1
    row = (y[:, None] >= y_edges[None, :]).sum(axis=1) - 1
    count, total, top = np.zeros(shape), np.zeros(shape), np.zeros(shape)
    for r, c, value in zip(row, col, v, strict=True):
        if 0 <= r < nrow and 0 <= c < ncol:
            count[r, c] += 1
            total[r, c] += value
            top[r, c] = max(top[r, c], value)
    with np.errstate(invalid="ignore"):
        return count, total / count, top


def test_pixel_binning_matches_a_loop_over_the_pixels():
    """Points in and around a 7 x 5 pixel grid (some outside on every side): the count, the
    mean and the maximum per pixel equal those of a loop over the points."""
    rng = np.random.default_rng(7)
    xlim, ylim, shape = (-1.0, 2.5), (0.5, 3.0), (5, 7)
    x = rng.uniform(-1.5, 3.0, 400)
    y = rng.uniform(0.0, 3.5, 400)
    v = rng.uniform(0.0, 4.0, 400)
    count, mean, top = _brute_force(x, y, v, xlim, ylim, shape)
    assert 0 < count.sum() < 400  # some points are outside
    index = pixel_index(x, y, xlim, ylim, shape)
    assert np.sum(index < 0) == 400 - count.sum()
    got_count, got_mean = pixel_count_and_mean(index, v, shape)
    np.testing.assert_array_equal(got_count, count)
    np.testing.assert_allclose(got_mean, mean, rtol=1e-12, equal_nan=True)
    np.testing.assert_array_equal(pixel_max(index, v, shape), top)
    assert np.isnan(pixel_count_and_mean(index, None, shape)[1]).all()


def _many_grains(side: int = 400) -> Frames:
    """``side``^2 grains filling a 1 m box, radius 0.48 x the spacing, F_n = column + 1 [N],
    speed (row + 1) / side [m/s] (``benchmarks/frame_drawing.py``'s lattice)."""
    return benchmark_module("frame_drawing").lattice_frames(side, radius_fraction=0.48, seed=3)


def _px_per_m(artist: FrameArtist) -> float:
    """Pixels per metre of the artist's plot, from the axes' size on the canvas."""
    artist.canvas.draw()
    return artist.ax.get_window_extent().height / (artist.ylim[1] - artist.ylim[0])


@pytest.mark.parametrize("color", ["none", "velocity"])
def test_a_frame_of_grains_under_two_pixels_is_drawn_as_pixels(color):
    """160,000 grains 2.4 mm across filling a 1 m box, 800 px tall: under RASTER_BELOW_PX, so drawn
    as two images of cells of the plot's pixels, each cell at least two grain diameters wide
    (so the packed lattice leaves none empty).  The grains' image: opaque exactly where the loop
    finds grains' centres, in the plain grain colour or the colour map at the pixel's mean
    speed; the chains' image: opacity CHAIN_ALPHA x (largest F_n of the contacts centred in the
    cell) / (the force scale: the settled frame's 90th percentile of F_n), at most CHAIN_ALPHA."""
    frames = _many_grains()
    artist = FrameArtist(frames, color, height_px=800)
    frame = frames[0]
    r_max = float(frame.particles["radius"].max())
    px_per_m = _px_per_m(artist)
    assert 2 * r_max * px_per_m < RASTER_BELOW_PX and artist.raster
    cell = (artist.ylim[1] - artist.ylim[0]) / artist.raster_shape[0]  # [m]
    assert cell >= 2 * (2 * r_max) and cell == pytest.approx(
        (artist.xlim[1] - artist.xlim[0]) / artist.raster_shape[1], rel=0.02)
    artist.draw(frame)
    grains, chains = (im.get_array() for im in artist.ax.images)
    x, y = frame.particles["x"].astype(float), frame.particles["y"].astype(float)
    speed = np.hypot(frame.particles["vx"], frame.particles["vy"]).astype(float)
    count, mean, _ = _brute_force(x, y, speed, artist.xlim, artist.ylim, artist.raster_shape)
    np.testing.assert_array_equal(grains[..., 3], (count > 0).astype(float))
    has = count > 0
    # the lattice fills the box: no cell wholly inside it is left empty
    rows, cols = artist.raster_shape
    left = artist.xlim[0] + (artist.xlim[1] - artist.xlim[0]) / cols * np.arange(cols)
    bottom = artist.ylim[0] + (artist.ylim[1] - artist.ylim[0]) / rows * np.arange(rows)
    inner = np.outer((bottom >= 0) & (bottom + cell <= 1), (left >= 0) & (left + cell <= 1))
    assert inner.sum() > 100 and has[inner].all()
    if color == "none":
        np.testing.assert_allclose(grains[has][:, :3], np.tile(to_rgb("#ddd5c4"), (has.sum(), 1)))
    else:
        expected = artist.cmap(artist.norm(mean[has]))[:, :3]
        np.testing.assert_allclose(grains[has][:, :3], expected, atol=1e-12)
    c = frame.contacts
    mid_x = 0.5 * (x[c["i"]] + x[c["j"]])
    mid_y = 0.5 * (y[c["i"]] + y[c["j"]])
    _, _, force = _brute_force(mid_x, mid_y, c["fn"].astype(float), artist.xlim, artist.ylim,
                               artist.raster_shape)
    scale = np.percentile(c["fn"].astype(float), 90)
    expected_alpha = CHAIN_ALPHA * np.minimum(force / scale, 1)
    np.testing.assert_allclose(chains[..., 3], expected_alpha, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(chains[0, 0, :3], to_rgb(CHAIN_COLOR))
    assert 0 < chains[..., 3].max() <= CHAIN_ALPHA
    rgb = artist.rgb()
    assert rgb.shape == (artist.height_px, artist.width_px, 3)


def test_grains_two_pixels_across_or_more_are_drawn_as_disks():
    """The same lattice with 400 grains a side drawn 1600 px tall: the largest grain is over
    RASTER_BELOW_PX across, so the disks and lines of every frame are drawn as before (no
    image)."""
    frames = _many_grains(400)
    artist = FrameArtist(frames, "none", height_px=1600)
    diameter = 2 * float(frames[0].particles["radius"].max())
    assert diameter * _px_per_m(artist) >= RASTER_BELOW_PX and not artist.raster
    artist.draw(frames[0])
    assert not artist.ax.images and len(artist.ax.collections) == 2


def test_the_colour_scale_over_many_grains_is_taken_from_a_thinned_sample(monkeypatch):
    """The velocity colour scale is the 95th percentile of the speeds over all frames; where
    the frames hold more than SCALE_SAMPLE values, every k-th is kept (about SCALE_SAMPLE in
    all).  On the 160,000-grain lattice (speeds (row + 1) / 400, uniform over the rows) with a
    sample of 4000, the scale is within 0.5 % of the 95th percentile of every speed."""
    from silodem.silo.frames import Frame
    from silodem.viz import scales

    frames = _many_grains()
    speeds = frames[0].speed().astype(float)
    monkeypatch.setattr(scales, "SCALE_SAMPLE", 4000)
    kept = scales.every_frame(frames, Frame.speed)
    assert sum(v.size for v in kept) == 4000
    top = FrameArtist(frames, "velocity").norm.vmax
    assert top == pytest.approx(np.percentile(speeds, 95.0), rel=5e-3)
    monkeypatch.setattr(scales, "SCALE_SAMPLE", 10**9)  # all of them: the exact percentile
    assert FrameArtist(frames, "velocity").norm.vmax == pytest.approx(
        np.percentile(speeds, 95.0), rel=1e-6)


def test_a_wide_silo_gets_a_lower_figure_not_one_wider_than_the_codec_takes():
    """A flat silo 70 m wide and 1 m tall drawn 800 px tall was 26,800 px wide, which libx264
    refused after every frame had been drawn: the figure is at most WIDTH_PX_MAX wide, lower
    instead, with equal scales on both axes (metres per pixel the same in x and z)."""
    from silodem.silo.frames import WallGeometry
    from silodem.viz.draw import WIDTH_PX_MAX

    lattice = _many_grains(10)
    walls = WallGeometry(["floor", "left", "right"], np.array([0.0, 0.0, 70.0]),
                         np.array([0.0, 1.0, 1.0]), np.array([70.0, 0.0, 70.0]), np.zeros(3))
    frames = Frames(list(lattice), walls, {}, {}, "wide")
    artist = FrameArtist(frames, "velocity", height_px=800)
    assert artist.width_px <= WIDTH_PX_MAX and artist.height_px < 800
    artist.draw(frames[0])
    assert artist.rgb().shape[:2] == (artist.height_px, artist.width_px)
    box = artist.ax.get_window_extent()
    m_per_px = [(hi - lo) / size for (lo, hi), size in
                ((artist.ax.get_xlim(), box.width), (artist.ax.get_ylim(), box.height))]
    assert m_per_px[0] == pytest.approx(m_per_px[1], rel=0.02)
    assert box.width > 0.9 * (WIDTH_PX_MAX - 200)  # the room is used, not a thin strip
