"""What blocking in time could give the one-thread step, measured at a fixed neighbour list
(docs/performance.md, "Cost per particle-step against N").

    python benchmarks/time_blocking.py [--copies 1 10 100] [--levels 4 8] [--rounds 6]
                                       [--grains-per-strip 2000] [--same-copies]

The packed scaling silo (``performance_matrix.py --scaling``'s silo, ``bench.build(...,
copies=k)``) at every size, its state made from one settled silo: the silo is settled 10,000
steps, then copy c takes the state the same silo reached 53 c steps later (every copy in its
own flow state, as after a long settling of k silos, but built in seconds); then 300 steps
and a fresh list.  ``--same-copies`` gives every copy the same state instead: see below.

On that list, from the same state each time, the engine's kernels take ``L`` single steps
(``contact.pair_forces``, then ``integrate.walls_and_leapfrog``, one thread), against a
*wave* of ``L`` steps: the strips of cell rows taken in units (even strip 2k with odd strip
2k - 1: zero the sums, pair loop of both, leap-frog of both), unit k of level l + 1 right
after unit k + 1 of level l, so that a grain's state is used ``L`` times while it is in cache.
Every grain receives its force terms in the order of the two passes, so the wave must give
the same bits; the script checks that it does.  No list test runs inside the wave: this
measures what the kernels would gain, not a step loop that must also decide, at every level,
whether the list still holds (performance.md says why that is the hard part).

``--grains-per-strip`` cuts the strips finer than the engine's 64 (whole cell rows, at most
one row each) for both variants: a wave spans about L + 1 units, and at 1e6 grains with 64
strips a unit is 32,000 grains, so a wave of 4 levels outgrows the 32 MB L3 cache.

Why not the same state in every copy: with 100 identical copies every cell row repeats one
silo's pattern of touching and non-touching pairs 100 times, which the branch predictor
learns; the single steps at 1e6 grains then cost no more than one silo's (40.5 against 41.0
ns per particle-step in the thirty-fifth session, and 44.2 against 40.9 with every copy in
its own state), hiding what the size costs.

Prints ns per particle-step (median and minimum over the rounds after the first) of both
variants at every size.
"""

from __future__ import annotations

import argparse
import time

import numba
import numpy as np
from performance_matrix import SCALING_N, SCALING_ROWS

from silodem.bench import COPY_GAP, advance, build, widened_size
from silodem.engine.cells import first_grains, strip_rows
from silodem.engine.contact import pair_forces
from silodem.engine.integrate import walls_and_leapfrog

NX = widened_size(SCALING_N, SCALING_ROWS)
_pairs = pair_forces.serial
_leap = walls_and_leapfrog.serial
GRAIN_FIELDS = ("x", "y", "vx", "vy", "omega", "radius", "mass", "inv_mass", "fx", "fy",
                "torque")
STATE_P = ("x", "y", "vx", "vy", "omega", "fx", "fy", "torque")  # what a step changes
STATE_NB = ("pair_fs", "pair_fn", "wc_fs", "wc_fn", "wc_fx", "wc_fy")


@numba.njit
def steps(levels, wave, strip_start, blocks, i_start, i_apart, pair_j, pair_fs, pair_fn,
          w_start, wc_w, wc_fs, wc_fn, wc_fx, wc_fy, walls, x, y, vx, vy, omega, radius, mass,
          inv_mass, fx, fy, torque, x_ref, y_ref, kn, ks, mu, zeta, allow_tension, alpha,
          gravity, dt, runs, wall_gap, fast):
    """``levels`` steps of the strips ``blocks[0]:blocks[1]`` (all of them), with no list
    test and no fast grains listed: as the engine takes them (``wave`` False: the pair loop
    over all strips, then the leap-frog over all grains), or as a skewed wave over units of
    two strips (module docstring).  Unit k is strips 2k - 1 and 2k: given the run of strips
    2k - 1 ... 2k (``blocks`` is overwritten), the engine's kernels do exactly that unit (the
    pair loop zeroes the sums of strips 2k, 2k + 1, works strip 2k, then strip 2k - 1; the
    leap-frog moves both)."""
    n_strips = strip_start.shape[0] - 1
    n_units = n_strips // 2 + 1 if wave else 1
    for front in range(n_units + levels - 1 if wave else levels):
        for level in range(levels if wave else 1):
            # unit k at this level, right after unit k + 1 one level down
            k = front - level if wave else 0
            if k < 0 or k >= n_units:
                continue
            if wave:
                blocks[0] = max(2 * k - 1, 0)
                blocks[1] = min(2 * k + 1, n_strips)
            _pairs(strip_start, blocks, i_start, i_apart, pair_j, pair_fs, pair_fn,
                   x, y, vx, vy, omega, radius, inv_mass, fx, fy, torque,
                   kn, ks, mu, zeta, allow_tension, dt)
            _leap(strip_start, blocks, w_start, wc_w, wc_fs, wc_fn, wc_fx, wc_fy, walls,
                  x, y, vx, vy, omega, fx, fy, torque, radius, mass, x_ref, y_ref, gravity,
                  zeta, allow_tension, alpha, dt, runs, False, wall_gap, 0.0, 1.0, fast)


def packed_silos(copies: list[int], same: bool, log=print) -> list:
    """The scaling silo at each number of copies, in packed, discharging states taken from
    one settled silo (module docstring), each with a fresh list."""
    single, _, top = build(NX, SCALING_ROWS)
    advance(single, top, 10_000)
    states = []
    while len(states) < max(copies):
        states.append({k: single.particles.view(k).copy() for k in GRAIN_FIELDS})
        if not same:
            advance(single, top, 53)
    sims = []
    for k in copies:
        sim, width, top = build(NX, SCALING_ROWS, copies=k)
        p = sim.particles
        for name in GRAIN_FIELDS:
            shift = width + COPY_GAP if name == "x" else 0.0
            getattr(p, name)[:p.n] = np.concatenate(
                [s[name] + c * shift for c, s in enumerate(states[:k])])
        sim.invalidate()
        advance(sim, top, 300)
        sim.invalidate()
        advance(sim, top, 1)  # a fresh list, built right before this step
        sims.append(sim)
        log(f"N={p.n:8d} built", flush=True)
    return sims


def finer_strips(sim, grains_per_strip: int) -> None:
    """Cut the list's strips into about n / ``grains_per_strip`` runs of whole cell rows
    (at least the engine's 64)."""
    nb = sim.neighbors
    ncx, ncy = int(nb.cell_grid[3]), int(nb.cell_grid[4])
    count = max(64, sim.particles.n // grains_per_strip)
    nb.strip_start = first_grains(nb.cell_start, ncx, strip_rows(nb.cell_start, ncx, ncy, count))


def kernel_args(sim, blocks: np.ndarray) -> tuple:
    p, nb, w, law = sim.particles, sim.neighbors, sim.walls, sim.law
    return (nb.strip_start, blocks, nb.i_start, nb.i_apart, nb.pair_j, nb.pair_fs, nb.pair_fn,
            nb.w_start, nb.wc_w, nb.wc_fs, nb.wc_fn, nb.wc_fx, nb.wc_fy, w.arrays(),
            p.x, p.y, p.vx, p.vy, p.omega, p.radius, p.mass, p.inv_mass, p.fx, p.fy,
            p.torque, p.x_ref, p.y_ref, law.kn, law.ks, law.mu, law.zeta, law.allow_tension,
            law.local_damping, sim.gravity, sim.dt, nb.step_report(1), nb.wall_gap, nb.fast)


def state(sim) -> list[np.ndarray]:
    p, nb = sim.particles, sim.neighbors
    return ([getattr(p, k)[:p.n].copy() for k in STATE_P]
            + [getattr(nb, k).copy() for k in STATE_NB])


def put(sim, values: list[np.ndarray]) -> None:
    p, nb = sim.particles, sim.neighbors
    for k, v in zip(STATE_P + STATE_NB, values):
        (getattr(p, k)[:p.n] if k in STATE_P else getattr(nb, k))[:] = v


def timed(levels: int, wave: bool, args: tuple) -> float:
    t = time.perf_counter()
    steps(levels, wave, *args)
    return time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--copies", type=int, nargs="+", default=[1, 10, 100])
    ap.add_argument("--levels", type=int, nargs="+", default=[4, 8])
    ap.add_argument("--rounds", type=int, default=6)
    ap.add_argument("--grains-per-strip", type=int, default=2000)
    ap.add_argument("--same-copies", action="store_true",
                    help="every copy in the same state (the branch predictor learns it)")
    args = ap.parse_args()
    numba.set_num_threads(1)
    sims = packed_silos(args.copies, args.same_copies)
    for sim in sims:
        finer_strips(sim, args.grains_per_strip)
    for levels in args.levels:
        times = {id(sim): ([], []) for sim in sims}
        for _ in range(args.rounds):  # the sizes in turn: they share the machine's speed
            for sim in sims:
                nb = sim.neighbors
                everything = np.array([0, nb.strip_start.size - 1], dtype=nb.strip_start.dtype)
                start = state(sim)
                single, wave = times[id(sim)]
                single.append(timed(levels, False, kernel_args(sim, everything)))
                reference = state(sim)
                put(sim, start)
                wave.append(timed(levels, True, kernel_args(sim, everything.copy())))
                if not all(np.array_equal(a, b) for a, b in zip(reference, state(sim))):
                    raise SystemExit(f"N={sim.particles.n}: the wave's bits differ from the "
                                     "single steps'")
                put(sim, start)
        for sim in sims:
            n = sim.particles.n
            ns = [1e9 * np.array(t[1:]) / (n * levels) for t in times[id(sim)]]
            print(f"L={levels} N={n:8d} strips={sim.neighbors.strip_start.size - 1:4d}  "
                  f"single steps {np.median(ns[0]):5.1f} (min {ns[0].min():5.1f})  wave "
                  f"{np.median(ns[1]):5.1f} (min {ns[1].min():5.1f}) ns per particle-step, "
                  "same bits", flush=True)

if __name__ == "__main__":
    main()
