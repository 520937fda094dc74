"""Cost per particle-step against N, with the sizes run in turns in one process, so that
every size sees the same speed of the machine (docs/performance.md, "Cost per particle-step
against N").

    python benchmarks/interleaved_scaling.py [--copies 1 3 10 30 100] [--steps 1000]
                                             [--turn 50] [--settle 3000] [--threads 1]
                                             [--out docs/scaling-interleaved-falling.json]

The silo is ``performance_matrix.py --scaling``'s: ``copies`` copies of the bench silo (NX =
32, NY = 200: 10,144 grains) side by side, each discharging with its grains re-entering at
the top.  Every size is built and settled first (``--settle`` steps; 10000 for the packed
silo of ``performance_matrix.py --scaling --settle 10000``); then every size runs ``--turn``
steps in turn until each has run ``--steps``, list builds included.  All sizes run the same
steps, so they stay in the same flow state.  Prints each size's core-ns per particle-step
over all its turns, its ratio to the smallest size, and that ratio in each tenth of the run.

Why in turns: the test VM's speed moves between states up to about 1.5 times apart, on a
scale of milliseconds to minutes (one kernel call timed after another gave 9.3 and 14 ns per
grain on the same data), so runs of different sizes made one after another, minutes apart,
compare different machine speeds.  Here the sizes share them.  What it costs: after a large
size's turn, a small size starts with its state out of the caches (2 MB at 1e4 grains, about
0.2 ms to bring back, against 12 ms for its 50 steps: its figure is up to 2 % high).  Turns of
10 steps made that 10 % and the 1e4 figure higher than the 1e6 one.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numba
import numpy as np
from performance_matrix import SCALING_N, SCALING_ROWS

from silodem.bench import advance, build, widened_size

NX = widened_size(SCALING_N, SCALING_ROWS)  # as ``bench.run_silodem`` with rows


def measure(copies: list[int], steps: int, turn: int, settle: int,
            log=print) -> tuple[list, np.ndarray]:
    """Build and settle every size, then run them ``turn`` steps each in turn until each has
    run ``steps``.  Returns the simulations and the seconds of each turn (size x turn)."""
    sims = []
    for k in copies:
        sim, _, top = build(NX, SCALING_ROWS, copies=k)
        t = time.perf_counter()
        advance(sim, top, settle)
        log(f"N={sim.particles.n:8d} settled {settle} steps in "
            f"{time.perf_counter() - t:.1f} s")
        sims.append((sim, top))
    turns = steps // turn
    seconds = np.zeros((len(sims), turns))
    for k in range(turns):
        for m, (sim, top) in enumerate(sims):
            t = time.perf_counter()
            advance(sim, top, turn)
            seconds[m, k] = time.perf_counter() - t
    return [sim for sim, _ in sims], seconds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--copies", type=int, nargs="+", default=[1, 3, 10, 30, 100])
    ap.add_argument("--steps", type=int, default=1000, help="timed steps of every size")
    ap.add_argument("--turn", type=int, default=50, help="steps per turn")
    ap.add_argument("--settle", type=int, default=3000)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--out", help="also write the figures and every turn's time to this JSON")
    args = ap.parse_args()
    numba.set_num_threads(args.threads)
    sims, seconds = measure(args.copies, args.steps, args.turn, args.settle,
                            log=lambda line: print(line, flush=True))
    turns = seconds.shape[1]
    n = np.array([sim.particles.n for sim in sims], dtype=float)
    cost = 1e9 * args.threads * seconds / (n[:, None] * args.turn)  # per turn
    tenths = np.array_split(np.arange(turns), min(10, turns))  # the ratio in parts of the run
    print(f"core-ns per particle-step over {turns} turns of {args.turn} steps, every size in "
          "turn (ratio: to the smallest N; spread: the ratio in each tenth of the run)")
    rows = []
    for m in range(len(sims)):
        mean = cost[m].mean()
        parts = [cost[m, t].mean() / cost[0, t].mean() for t in tenths]
        print(f"  N={int(n[m]):8d} {mean:5.1f}  ratio {mean / cost[0].mean():.3f}  spread "
              f"{min(parts):.3f} ... {max(parts):.3f}", flush=True)
        rows.append({"n": int(n[m]), "copies": args.copies[m], "ns_per_particle_step": mean,
                     "ratio_to_smallest": mean / cost[0].mean(), "ratio_in_tenths": parts,
                     "seconds_per_turn": seconds[m].tolist()})
    if args.out:
        Path(args.out).write_text(json.dumps({**vars(args), "rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
