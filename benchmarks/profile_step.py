"""Where the time goes: each part of the timestep of the benchmark silo, per grain.

    python benchmarks/profile_step.py [--copies 1,10,100] [--settle 10000] [--steps 500]
        [--threads 1] [--json out.json]

For each size, ``copies`` silos of the scaling benchmark (NX = 32, NY = 200, 10,144 grains
each, side by side; ``performance_matrix.py --scaling``) run SETTLE untimed steps, then STEPS
timed steps of the compiled step loop (``Simulation.run``), in which every neighbour-list
build and each kernel inside it is timed: the whole step and the builds.  A copy of the
settled simulation then takes the same STEPS one at a time from Python (``stepped``: the
same kernels, tests and builds in the same order, with the same bits), each part timed: the
grain-grain pair loop (``contact.pair_forces``), the wall contacts with the leap-frog
(``integrate.walls_and_leapfrog``) and the list test by cells (``list_validity``, on the
steps whose global test failed).  "rest" is the whole step less the builds and those three
parts: the global list test and the Python around the compiled step loop.

All figures are nanoseconds per grain: per step for the step's parts, and per build for the
build's kernels (a build's share of a step is its cost times builds / steps).  ``--settle
10000`` is the packed, discharging silo (about 72 % of the candidates touching); 3000 the
mostly falling one (8 %).
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import copy
import json
import math
import time
from pathlib import Path

import numba
import numpy as np

import silodem.engine.neighbors as nbm
from silodem.bench import advance, build
from silodem.engine.contact import pair_forces
from silodem.engine.integrate import walls_and_leapfrog
from silodem.engine.list_validity import global_bound, list_expired, must_rebuild

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


def stepped(sim, steps, acc):
    """Advance ``sim`` by ``steps`` steps as ``Simulation.run`` does (the same compiled
    kernels, list tests and builds, in the same order, with the same bits; walls at rest), but
    one step at a time from Python, adding each part's time to ``acc`` [s]: "build" (with the
    hooks before it), "pair_loop", "walls_and_leapfrog", "test_by_cells" (the list test on
    the steps whose global test failed).  Calling a compiled function from Python costs a
    few microseconds that the compiled step loop does not pay (about 1 ns per grain at 1e4
    grains); each part is counted less that cost, timed on calls that do no work.  What a
    step does besides these parts (the global test, Python) is its whole time less them.
    Returns the number of steps in which the leap-frog listed the fast grains and in which
    the test by cells ran."""
    p, nb, w, law, dt = sim.particles, sim.neighbors, sim.walls, sim.law, sim.dt
    if w.moving():
        raise ValueError("stepped() follows Simulation.run for walls at rest only")
    threads = numba.get_num_threads()
    parallel = pair_forces.pick(p.n, threads) is pair_forces.parallel
    pair = pair_forces.parallel if parallel else pair_forces.serial
    move = walls_and_leapfrog.parallel if parallel else walls_and_leapfrog.serial
    clock = time.perf_counter

    def pair_loop(blocks):
        pair(nb.strip_start, blocks, nb.i_start, nb.i_apart, nb.pair_j, nb.pair_fs, nb.pair_fn,
             p.x, p.y, p.vx, p.vy, p.omega, p.radius, p.inv_mass, p.fx, p.fy, p.torque,
             law.kn, law.ks, law.mu, law.zeta, law.allow_tension, dt)

    def walls_and_move(blocks, runs, collect):
        return move(nb.strip_start, blocks, nb.w_start, nb.wc_w, nb.wc_fs, nb.wc_fn, nb.wc_fx,
                    nb.wc_fy, w.arrays(), p.x, p.y, p.vx, p.vy, p.omega, p.fx, p.fy,
                    p.torque, p.radius, p.mass, p.x_ref, p.y_ref, sim.gravity, law.zeta,
                    law.allow_tension, law.local_damping, dt, runs, collect, nb.wall_gap,
                    sim._wall_drift, 0.25 * nb.skin * nb.skin, nb.fast)

    def list_test(bound, runs):
        return must_rebuild(bound, sim._drift, sim._wall_drift, nb.skin, sim.cell_test, p.n,
                            runs, nb.fast, p.x, p.y, p.x_ref, p.y_ref, p.radius, nb.i_start,
                            nb.pair_j, nb.cell_grid, nb.cell_start)

    def call_cost(call, *args):  # [s], median of calls that do no work
        times = []
        for _ in range(21):
            t = clock()
            call(*args)
            times.append(clock() - t)
        return float(np.median(times))

    no_blocks = np.zeros(1, dtype=nb.strip_start.dtype)
    cost = {"pair_loop": call_cost(pair_loop, no_blocks),
            "walls_and_leapfrog": call_cost(walls_and_move, no_blocks, np.zeros((0, 8)), False),
            "test_by_cells": call_cost(list_test, 0.0, np.zeros((0, 8)))}  # bound 0: kept

    listed = tested = 0
    for step in range(steps):
        # Simulation.run asks the list test once when called, then after each step
        if sim.needs_rebuild or (step == 0 and sim._list_expired()):
            t = clock()
            sim._rebuild_list()
            acc["build"] += clock() - t
        blocks = nb.blocks(threads if parallel else 1)
        runs = nb.step_report(threads if parallel else 1)
        bound = global_bound(sim._drift, *sim._spread)
        collect = sim.cell_test and bound >= 0.5 * nb.skin
        t0 = clock()
        pair_loop(blocks)
        t1 = clock()
        max_d2, *spread = walls_and_move(blocks, runs, collect)
        t2 = clock()
        acc["pair_loop"] += t1 - t0 - cost["pair_loop"]
        acc["walls_and_leapfrog"] += t2 - t1 - cost["walls_and_leapfrog"]
        listed += collect
        sim.steps += 1
        sim.time += dt
        sim._drift, sim._spread = math.sqrt(max_d2), tuple(spread)
        bound = global_bound(sim._drift, *sim._spread)
        if list_expired(bound, sim._drift, sim._wall_drift, nb.skin):  # the global test
            t = clock()
            sim._stale = list_test(bound, runs)
            acc["test_by_cells"] += clock() - t - cost["test_by_cells"]
            tested += sim.cell_test
    return listed, tested


def profile(copies, settle, steps, threads):
    numba.set_num_threads(threads)
    sim, _, top = build(32, 200, copies=copies)
    advance(sim, top, settle)
    twin = copy.deepcopy(sim)  # the step-by-step run takes the same steps from the same state
    acc = collections.defaultdict(float)
    builds0 = sim.neighbors.rebuilds
    with builds_timed(sim, acc):
        t = time.perf_counter()
        advance(sim, top, steps)
        whole = time.perf_counter() - t
    builds = sim.neighbors.rebuilds - builds0
    n = sim.particles.n
    parts = collections.defaultdict(float)
    builds0 = twin.neighbors.rebuilds
    listed, tested = stepped(twin, steps, parts)
    per_step = 1e9 / (n * steps)
    row = {"n": n, "copies": copies, "threads": threads, "settle": settle, "steps": steps,
           "builds": builds,
           "candidates_per_grain": sim.neighbors.pair_j.size / n,
           "touching_share": float(np.mean(sim.neighbors.pair_fn > 0.0)),
           "whole_step": whole * per_step, "builds_per_step": acc["build"] * per_step,
           "stepped_builds": twin.neighbors.rebuilds - builds0,
           "steps_listing_fast_grains": listed, "steps_with_test_by_cells": tested}
    for part in ("pair_loop", "walls_and_leapfrog", "test_by_cells"):
        row[part] = parts[part] * per_step
    row["rest"] = row["whole_step"] - row["builds_per_step"] - sum(
        row[part] for part in ("pair_loop", "walls_and_leapfrog", "test_by_cells"))
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
    print(f"  then {row['steps']} steps one by one: {row['stepped_builds']} builds, fast grains "
          f"listed in {row['steps_listing_fast_grains']} steps, the test by cells in "
          f"{row['steps_with_test_by_cells']}")
    for part in ("pair_loop", "walls_and_leapfrog", "test_by_cells", "builds_per_step", "rest",
                 "whole_step"):
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
