"""Where the time goes: each part of the timestep of the benchmark silo, per grain.

    python benchmarks/profile_step.py [--copies 1,10,100] [--settle 10000] [--steps 500]
        [--threads 1] [--json out.json]

For each size, ``copies`` silos of the scaling benchmark (NX = 32, NY = 200, 10,144 grains
each, side by side; ``performance_matrix.py --scaling``) run SETTLE untimed steps, then STEPS
timed steps in which every neighbour-list build and each kernel inside it is timed.  Then, on
a copy of the final state, the two step kernels are called one after the other for 10-50
steps on the same list, each call timed (median): the grain-grain pair loop
(``contact.pair_forces``) and the wall contacts with the leap-frog
(``integrate.walls_and_leapfrog``).  "rest" is the timed run less those two and the builds:
the list tests (``list_validity``), the listing of fast grains for them, and the Python
around the compiled step loop.

All figures are nanoseconds per grain: per step for the step's parts, and per build for the
build's kernels (a build's share of a step is its cost times builds / steps).  ``--settle
10000`` is the packed, discharging silo (about 72 % of the candidates touching); 3000 the
mostly falling one (8 %).
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import json
import time
from pathlib import Path

import numba
import numpy as np

import silodem.engine.neighbors as nbm
from silodem.bench import advance, build
from silodem.engine.contact import pair_forces
from silodem.engine.integrate import walls_and_leapfrog

BUILD_KERNELS = ["_pairs_of", "_compact_touching_first", "_old_index", "_carry_pairs",
                 "_wall_candidates_of", "_compact", "_carry_walls"]
BUILD_FUNCTIONS = ["cell_list", "strip_rows", "walls_by_cell", "first_grains"]


class _Timed:
    """A kernel of ``neighbors`` whose picked variants add their time to ``acc[name]``."""

    def __init__(self, name, kernel, acc):
        self.name, self.kernel, self.acc = name, kernel, acc

    def pick(self, n, threads=None):
        return _timer(self.name, self.kernel.pick(n, threads), self.acc)


def _timer(name, f, acc):
    def g(*args, **kwargs):
        t = time.perf_counter()
        out = f(*args, **kwargs)
        acc[name] += time.perf_counter() - t
        return out
    return g


@contextlib.contextmanager
def builds_timed(sim, acc):
    """While open, every list build of ``sim`` adds its time to ``acc["build"]`` and each
    kernel inside it to ``acc[name]`` [s]; on closing, everything is as it was."""
    saved = {name: getattr(nbm, name) for name in BUILD_KERNELS + BUILD_FUNCTIONS}
    p, nb = sim.particles, sim.neighbors
    try:
        for name in BUILD_KERNELS:
            setattr(nbm, name, _Timed(name, saved[name], acc))
        for name in BUILD_FUNCTIONS:
            setattr(nbm, name, _timer(name, saved[name], acc))
        p.permute = _timer("permute", p.permute, acc)
        nb.rebuild = _timer("build", nb.rebuild, acc)
        yield acc
    finally:
        for name, f in saved.items():
            setattr(nbm, name, f)
        p.__dict__.pop("permute", None)
        nb.__dict__.pop("rebuild", None)


def step_kernels(sim, threads, reps):
    """Median time [s] of the pair loop and of the walls + leap-frog, called one after the
    other as in the step loop, on a copy of the current state (which they advance ``reps``
    steps on the current list; the simulation itself is not changed).  No copy is made
    between calls, so each call finds in the caches what it would find in a run."""
    p, nb, law, w = sim.particles, sim.neighbors, sim.law, sim.walls
    parallel = pair_forces.pick(p.n, threads) is pair_forces.parallel
    pair = pair_forces.parallel if parallel else pair_forces.serial
    move = walls_and_leapfrog.parallel if parallel else walls_and_leapfrog.serial
    blocks = nb.blocks(threads if parallel else 1)
    runs = nb.step_report(threads if parallel else 1)
    x, y, vx, vy, omega, fx, fy, torque = (a.copy() for a in (
        p.x, p.y, p.vx, p.vy, p.omega, p.fx, p.fy, p.torque))
    pair_fs, pair_fn = nb.pair_fs.copy(), nb.pair_fn.copy()
    wc = [a.copy() for a in (nb.wc_fs, nb.wc_fn, nb.wc_fx, nb.wc_fy)]
    t_pair, t_move = [], []
    for _ in range(reps):
        t0 = time.perf_counter()
        pair(nb.strip_start, blocks, nb.i_start, nb.i_apart, nb.pair_j, pair_fs, pair_fn,
             x, y, vx, vy, omega, p.radius, p.inv_mass, fx, fy, torque, law.kn, law.ks,
             law.mu, law.zeta, law.allow_tension, sim.dt)
        t1 = time.perf_counter()
        move(nb.strip_start, blocks, nb.w_start, nb.wc_w, *wc, w.arrays(), x, y, vx, vy,
             omega, fx, fy, torque, p.radius, p.mass, p.x_ref, p.y_ref, sim.gravity,
             law.zeta, law.allow_tension, law.local_damping, sim.dt, runs, False,
             nb.wall_gap, 0.0, 0.25 * nb.skin**2, nb.fast)
        t2 = time.perf_counter()
        t_pair.append(t1 - t0)
        t_move.append(t2 - t1)
    return float(np.median(t_pair)), float(np.median(t_move))


def profile(copies, settle, steps, threads):
    numba.set_num_threads(threads)
    sim, _, top = build(32, 200, copies=copies)
    advance(sim, top, settle)
    acc = collections.defaultdict(float)
    builds0 = sim.neighbors.rebuilds
    with builds_timed(sim, acc):
        t = time.perf_counter()
        advance(sim, top, steps)
        whole = time.perf_counter() - t
    builds = sim.neighbors.rebuilds - builds0
    n = sim.particles.n
    reps = min(50, max(10, int(3e6 / n)))
    pair, move = step_kernels(sim, threads, reps)
    per_step = 1e9 / (n * steps)
    row = {"n": n, "copies": copies, "threads": threads, "settle": settle, "steps": steps,
           "builds": builds,
           "candidates_per_grain": sim.neighbors.pair_j.size / n,
           "touching_share": float(np.mean(sim.neighbors.pair_fn > 0.0)),
           "whole_step": whole * per_step, "pair_loop": pair * 1e9 / n,
           "walls_and_leapfrog": move * 1e9 / n, "builds_per_step": acc["build"] * per_step}
    row["rest"] = row["whole_step"] - row["pair_loop"] - row["walls_and_leapfrog"] \
        - row["builds_per_step"]
    per_build = 1e9 / (n * max(builds, 1))
    row["build_parts"] = {k: v * per_build for k, v in acc.items()}
    row["build_parts"]["(rest of the build)"] = (
        acc["build"] - sum(v for k, v in acc.items() if k != "build")) * per_build
    return row


def show(row):
    print(f"N = {row['n']:,} ({row['copies']} silos), {row['threads']} thread(s), settle "
          f"{row['settle']}, {row['steps']} steps, {row['builds']} builds; "
          f"{row['candidates_per_grain']:.2f} candidates per grain, "
          f"{100 * row['touching_share']:.0f} % touching")
    for part in ("pair_loop", "walls_and_leapfrog", "builds_per_step", "rest", "whole_step"):
        print(f"  {part:28s} {row[part]:6.1f} ns per grain and step")
    parts = sorted(row["build_parts"].items(), key=lambda kv: -kv[1])
    for name, ns in parts:
        print(f"    {name:26s} {ns:6.1f} ns per grain and build")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--copies", default="1,10,100", help="comma-separated silo counts")
    ap.add_argument("--settle", type=int, default=10_000)
    ap.add_argument("--steps", type=int, default=500)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--json", type=Path, help="also write the rows here")
    args = ap.parse_args()
    rows = []
    for c in [int(c) for c in args.copies.split(",")]:
        rows.append(profile(c, args.settle, args.steps, args.threads))
        show(rows[-1])
        if args.json:
            args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
