"""Where the time goes: each part of the timestep of the benchmark silo, per grain.

    python benchmarks/profile_step.py [--copies 1,10,100] [--settle 10000] [--steps 500]
        [--threads 1] [--json out.json]

For each size, ``copies`` silos of the scaling benchmark (NX = 32, NY = 200, 10,144 grains
each, side by side; ``performance_matrix.py --scaling``) run SETTLE untimed steps, then STEPS
timed steps of the compiled step loop (``Simulation.run``), in which every neighbour-list
build and each kernel inside it is timed: the whole step and the builds.  A copy of the
settled simulation then takes the same STEPS with ``Simulation.run`` and its step loop
``simulation._steps`` run by Python instead of compiled (``stepped``: the same code, kernels,
tests and builds in the same order, with the same bits), each part timed: the
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
import time
from pathlib import Path

import numba
import numpy as np

import silodem.engine.neighbors as nbm
from silodem.bench import advance, build
from silodem.engine import simulation
from silodem.engine.contact import pair_forces, pair_forces_hertz
from silodem.engine.integrate import walls_and_leapfrog, walls_and_leapfrog_hertz
from silodem.engine.list_validity import list_expired, must_rebuild
from silodem.jit import _renamed

BUILD_KERNELS = ["_pairs_of", "_compact_touching_first", "_old_index", "_carry_pairs",
                 "_wall_candidates_of", "_compact", "_carry_walls"]
BUILD_FUNCTIONS = ["cell_list", "strip_rows", "walls_by_cell", "first_grains"]
MOVE_COLLECT = 27  # the position of ``collect`` among walls_and_leapfrog's arguments


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
    """Advance ``sim`` by ``steps`` steps with ``Simulation.run`` itself, but with its compiled
    step loop replaced by the same function, ``simulation._steps``, run by Python over the
    same compiled kernels wrapped in timers: the same order, list tests and builds, the same
    bits, and each part's time added to ``acc`` [s]: "build" (with the hooks before it),
    "pair_loop", "walls_and_leapfrog", "test_by_cells" (the list test on the steps whose
    global test failed). Calling a compiled function from Python costs a few microseconds
    that the compiled step loop does not pay (about 1 ns per grain at 1e4 grains); each part
    is counted less that cost, timed on calls that do no work. What a step does besides these
    parts (the global test, Python) is its whole time less them. Returns the number of steps
    in which the leap-frog listed the fast grains and in which the test by cells ran."""
    p, nb = sim.particles, sim.neighbors
    threads = numba.get_num_threads()
    variant = "parallel" if pair_forces.pick(p.n, threads) is pair_forces.parallel else "serial"
    pair = getattr(pair_forces_hertz if sim.law.hertz else pair_forces, variant)
    move = getattr(walls_and_leapfrog_hertz if sim.law.hertz else walls_and_leapfrog, variant)
    clock = time.perf_counter
    counts = {"listed": 0, "tested": 0}

    def call_cost(call, *args):  # [s], median of calls that do no work
        times = []
        for _ in range(21):
            t = clock()
            call(*args)
            times.append(clock() - t)
        return float(np.median(times))

    no_blocks = np.zeros(1, dtype=nb.strip_start.dtype)
    no_runs = np.zeros((0, 8))

    def timed_pair(*args):
        t = clock()
        pair(*args)
        acc["pair_loop"] += clock() - t - cost["pair_loop"]

    def timed_move(*args):
        counts["listed"] += bool(args[MOVE_COLLECT])
        t = clock()
        out = move(*args)
        acc["walls_and_leapfrog"] += clock() - t - cost["walls_and_leapfrog"]
        return out

    def timed_test(bound, drift, wall_drift, skin, cell_test, *rest):
        if not list_expired(bound, drift, wall_drift, skin):  # the global test keeps the list
            return False
        counts["tested"] += bool(cell_test)
        t = clock()
        out = must_rebuild(bound, drift, wall_drift, skin, cell_test, *rest)
        acc["test_by_cells"] += clock() - t - cost["test_by_cells"]
        return out

    # the kernels' call costs, on calls with no strips to work (list test: bound 0, kept)
    walls = sim.walls.arrays()
    cost = {
        "pair_loop": call_cost(
            pair, nb.strip_start, no_blocks, nb.i_start, nb.i_apart, nb.pair_j, nb.pair_fs,
            nb.pair_fn, p.x, p.y, p.vx, p.vy, p.omega, p.radius, p.inv_mass, p.fx, p.fy,
            p.torque, 0.0, 0.0, 0.0, 0.0, False, sim.dt),
        "walls_and_leapfrog": call_cost(
            move, nb.strip_start, no_blocks, nb.w_start, nb.wc_w, nb.wc_fs, nb.wc_fn, nb.wc_fx,
            nb.wc_fy, walls, p.x, p.y, p.vx, p.vy, p.omega, p.fx, p.fy, p.torque, p.radius,
            p.mass, p.x_ref, p.y_ref, 0.0, 0.0, False, 0.0, sim.dt, no_runs, False,
            nb.wall_gap, 0.0, 1.0, nb.fast),
        "test_by_cells": call_cost(
            must_rebuild, 0.0, 0.0, 0.0, nb.skin, sim.cell_test, p.n, no_runs, nb.fast, p.x,
            p.y, p.x_ref, p.y_ref, p.radius, nb.i_start, nb.pair_j, nb.cell_grid,
            nb.cell_start)}

    python_steps = _renamed(simulation._steps, "_timed", {
        "_pair_forces": timed_pair, "_walls_and_leapfrog": timed_move,
        "must_rebuild": timed_test})
    build_timer = _timer("build", sim._rebuild_list, acc)
    saved = simulation.STEPS
    simulation.STEPS = {key: python_steps for key in saved}
    sim._rebuild_list = build_timer
    try:
        sim.run(steps)
    finally:
        simulation.STEPS = saved
        del sim._rebuild_list
    return counts["listed"], counts["tested"]


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
    for name in ("x", "y", "vx", "vy", "omega"):  # the same steps, the same bits
        assert np.array_equal(twin.particles.view(name), sim.particles.view(name)), name
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
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
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
