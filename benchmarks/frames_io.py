"""What saving frames costs a run, and what looking at them costs (docs/output.md, thirty-fourth
session): a quick paper-case2 run with many frames and frequent saves, in a process of its own,
then its frames read back and gone through once in this one. (``--grains 3000`` becomes 1080
under ``--quick``, and the quick silo takes 178 of them before ``fill.max_time`` stops the
pour: the figures in docs/output.md are of that run.)

    python benchmarks/frames_io.py [--grains 3000] [--frame-interval 0.002]
                                   [--every-steps 1000] [--out DIR]

Prints the run's wall time and peak memory (the child's maximum resident set), the frames,
segment files and bytes written, and the time and memory (tracemalloc: NumPy's arrays) of
``read_frames`` and of one pass over every frame.
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path


def run(out: Path, grains: int, frame_interval: float, every_steps: int) -> tuple[float, int]:
    """Wall time [s] and peak resident memory [B] of the run."""
    sets = [f"fill.n_particles={grains}", f"output.frame_interval={frame_interval}",
            f"checkpoint.every_steps={every_steps}", "output.png=false", "measure.report=false"]
    args = [sys.executable, "-m", "silodem", "run", "paper-case2", "--quick", "--out", str(out)]
    for item in sets:
        args += ["--set", item]
    t0 = time.perf_counter()
    subprocess.run(args, check=True, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    return wall, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--grains", type=int, default=3000)
    ap.add_argument("--frame-interval", type=float, default=0.002)
    ap.add_argument("--every-steps", type=int, default=1000)
    ap.add_argument("--out", type=Path, default=None)
    a = ap.parse_args()
    from silodem.silo.frames import read_frames

    with tempfile.TemporaryDirectory() as tmp:
        out = a.out or Path(tmp) / "run"
        wall, peak = run(out, a.grains, a.frame_interval, a.every_steps)
        segments = sorted((out / "frames").glob("frames-*.h5"))
        seg_bytes = sum(p.stat().st_size for p in segments)
        print(f"run: {wall:.1f} s, peak memory {peak / 1e6:.0f} MB; results.h5 "
              f"{(out / 'results.h5').stat().st_size / 1e6:.2f} MB, {len(segments)} segment "
              f"files, {seg_bytes / 1e6:.1f} MB")
        tracemalloc.start()
        t0 = time.perf_counter()
        frames = read_frames(out / "results.h5")
        t_read = time.perf_counter() - t0
        held = tracemalloc.get_traced_memory()[0]
        t0 = time.perf_counter()
        rows = sum(frame.n for frame in frames)
        t_pass = time.perf_counter() - t0
        peak_pass = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        print(f"read_frames: {len(frames)} frames, {rows} grain rows; {t_read:.2f} s, "
              f"{held / 1e6:.2f} MB held; one pass over every frame {t_pass:.1f} s, "
              f"peak {peak_pass / 1e6:.1f} MB")


if __name__ == "__main__":
    main()
