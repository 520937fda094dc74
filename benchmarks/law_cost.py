"""What the Hertz-Mindlin law costs against the linear law, on the bench silo (docs/performance.md).

    python benchmarks/law_cost.py [--n 31700] [--steps 2000] [--settle 10000] [--repeat 3]

The silo of ``silodem bench`` (its lattice, re-entry at the top and time step), once with the
bench's linear law and once with the Hertz-Mindlin law of 2 E* = 8 G* = ``--modulus`` Pa for
grains and walls (3e8 Pa: tangent stiffnesses about the bench's 5e6 N/m at the packing's
overlaps, so the flow is alike and the time step stable), one thread, alternating in this
process ``--repeat`` times.  Prints particle-steps per second of each timed run and the
number of list builds in it.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numba

from silodem import bench


def timed(law: str, nx: int, ny: int, settle: int, steps: int, modulus: float):
    """(particle-steps per second, grains, list builds) of ``steps`` steps after ``settle``."""
    sim, _, top = bench.build(nx, ny)
    if law == "hertz":
        sim.law = dataclasses.replace(sim.law, kn=modulus, ks=modulus, hertz=True)
        sim.walls.kn[:] = modulus
        sim.walls.ks[:] = modulus
    bench.advance(sim, top, settle)
    builds = sim.neighbors.rebuilds
    start = time.perf_counter()
    bench.advance(sim, top, steps)
    seconds = time.perf_counter() - start
    return sim.particles.n * steps / seconds, sim.particles.n, sim.neighbors.rebuilds - builds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=31_700)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--settle", type=int, default=10_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--modulus", type=float, default=3e8, help="2 E* = 8 G* [Pa]")
    args = ap.parse_args()
    numba.set_num_threads(1)
    nx, ny = bench.lattice_size(args.n)
    for _ in range(args.repeat):
        for law in ("linear", "hertz"):
            rate, n, builds = timed(law, nx, ny, args.settle, args.steps, args.modulus)
            print(f"{law:7s} {n} grains: {rate / 1e6:6.2f} M particle-steps/s, "
                  f"{builds} list builds", flush=True)


if __name__ == "__main__":
    main()
