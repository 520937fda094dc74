"""What drawing one frame of many grains costs (``FrameArtist``, the animation's and the
report's pictures; docs/visualisation.md): a synthetic settled frame of N grains on a jittered
square lattice in a 1 m box, each touching its right-hand neighbour, drawn 800 px tall as
disks and lines and as pixels (viz/raster.py), timed over a few draws.

    python benchmarks/frame_drawing.py [--grains 1e4 1e5 1e6] [--repeat 3]

Prints, per N, the seconds per frame (draw + render to RGB, median) of each way, and which
one ``FrameArtist`` picks for that N.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from silodem.silo.frames import Frame, Frames, WallGeometry
from silodem.viz.draw import FrameArtist


def lattice_frames(side: int, radius_fraction: float = 0.3, seed: int = 1) -> Frames:
    """One settle frame of ``side``^2 grains on a square lattice filling a 1 m box, radius
    ``radius_fraction`` x the spacing, shifted by up to a tenth of the spacing at random
    (walls: floor, left, right), each touching its right-hand neighbour with F_n = its column
    index + 1 [N], moving at (row + 1) / side m/s (tests/test_raster.py draws it too)."""
    step = 1.0 / side
    col, row = (a.ravel() for a in np.meshgrid(np.arange(side), np.arange(side)))
    jitter = np.random.default_rng(seed).uniform(-0.1, 0.1, (2, col.size))
    zeros = np.zeros(col.size, np.float32)
    particles = {"x": ((col + 0.5 + jitter[0]) * step).astype(np.float32),
                 "y": ((row + 0.5 + jitter[1]) * step).astype(np.float32),
                 "vx": zeros, "vy": (-(row + 1.0) / side).astype(np.float32), "omega": zeros,
                 "radius": np.full(col.size, radius_fraction * step, np.float32),
                 "fx": zeros, "fy": zeros, "uid": np.arange(col.size)}
    i = np.flatnonzero(col < side - 1)
    contacts = {"i": i.astype(np.int32), "j": (i + 1).astype(np.int32),
                "fn": (col[i] + 1.0).astype(np.float32), "fs": np.zeros(i.size, np.float32)}
    none = np.zeros(0, np.int32)
    walls = WallGeometry(["floor", "left", "right"], np.array([0.0, 0.0, 1.0]),
                         np.array([0.0, 1.0, 1.0]), np.array([1.0, 0.0, 1.0]), np.zeros(3))
    frame = Frame(1.0, 1000, "settle", particles, contacts,
                  {"grain": none, "wall": none, "fn": np.zeros(0, np.float32),
                   "fs": np.zeros(0, np.float32)}, np.ones(3, bool))
    return Frames([frame], walls, {}, {}, "lattice")


def seconds_per_frame(artist: FrameArtist, frame: Frame, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        artist.draw(frame)
        artist.rgb()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--grains", type=float, nargs="+", default=[1e4, 1e5, 1e6])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    print(f"{'grains':>9} {'disks [s]':>10} {'pixels [s]':>11}  picked")
    for n in args.grains:
        frames = lattice_frames(max(2, round(n ** 0.5)))
        artist = FrameArtist(frames, "velocity", height_px=800)
        picked = "pixels" if artist.raster else "disks"
        out = {}
        for raster in (False, True):
            artist.raster = raster  # both ways on the same figure
            out[raster] = seconds_per_frame(artist, frames[0], args.repeat)
        print(f"{frames[0].n:>9} {out[False]:>10.3f} {out[True]:>11.3f}  {picked}")


if __name__ == "__main__":
    main()
