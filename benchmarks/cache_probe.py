"""What the pair loop costs per grain against N (docs/performance-history.md, ninth and
fourteenth sessions).

    python benchmarks/cache_probe.py [--sizes 100x100 316x316 1000x1000] [--subset 12000]
                                     [--contacts random|all|none]

A dense lattice of grains at rest (no walls, no gravity), one thread, two candidates per
grain (the east and north neighbours).  ``--contacts random``: radii 0.09-0.105 m on a 0.2 m
lattice, a quarter of the candidates touching, at random; ``all``: radii 0.102-0.106 m, every
candidate touching; ``none``: radii 0.08-0.095 m, none touching (memory traffic and loop
only).  For each size it prints the median time per grain of ``contact.pair_forces`` over
all strips, and over the first strips holding at most ``--subset`` grains (at least one strip)
called again and again.  The force sums are recomputed each call from the same positions
(the shear history grows towards its Coulomb cap), so every call does the same work.

The calls repeat the same candidates in the same order, so on a small lattice the CPU's
branch predictor learns which candidates touch; on a large one it cannot, and the random
lattice then pays for mispredicted branches what the ``all`` and ``none`` lattices do not
(fourteenth session: the step between 1e4 and 1e5 grains that earlier sessions put down to
the L3 cache).
"""

from __future__ import annotations

import argparse
import time

import numba
import numpy as np

from silodem.engine.contact import GrainLaw, pair_forces
from silodem.engine.particles import Particles
from silodem.engine.simulation import Simulation
from silodem.engine.walls import Walls

# radius range [m] and position jitter [m] of each kind of lattice (0.2 m spacing)
CONTACTS = {"random": (0.09, 0.105, 0.005), "all": (0.102, 0.106, 0.001),
            "none": (0.08, 0.095, 0.001)}


def lattice(nx: int, ny: int, seed: int = 1, contacts: str = "random") -> Simulation:
    """nx x ny grains on a 0.2 m lattice, jittered, with a built neighbour list."""
    r_lo, r_hi, jitter = CONTACTS[contacts]
    rng = np.random.default_rng(seed)
    gx, gy = np.meshgrid(np.arange(nx) * 0.2, np.arange(ny) * 0.2)
    n = nx * ny
    p = Particles(n)
    p.add(gx.ravel() + rng.uniform(-jitter, jitter, n),
          gy.ravel() + rng.uniform(-jitter, jitter, n),
          rng.uniform(r_lo, r_hi, n), 1000.0, vx=rng.normal(0, 0.01, n),
          vy=rng.normal(0, 0.01, n))
    sim = Simulation(p, Walls(), GrainLaw(kn=1e5, ks=1e5, mu=0.5, zeta=0.1), dt=1e-5,
                     gravity=0.0, skin=0.05)
    sim.run(2)
    return sim


def ns_per_grain(sim: Simulation, most: int | None, calls: int) -> tuple[float, int]:
    """Median time of ``pair_forces`` per grain [ns] over the first strips that hold at most
    ``most`` grains (all strips if None; at least one), and that number of grains."""
    p, nb, law = sim.particles, sim.neighbors, sim.law
    k = nb.strip_start.size - 1
    if most is not None:
        k = max(1, int(np.searchsorted(nb.strip_start, most, side="right")) - 1)
    start = nb.strip_start[: k + 1].copy()
    blocks = np.array([0, k], dtype=start.dtype)  # one run of strips: one thread
    grains = int(start[-1])

    def once():
        pair_forces.serial(start, blocks, nb.i_start, nb.i_apart, nb.pair_j, nb.pair_fs,
                           nb.pair_fn, p.x, p.y, p.vx, p.vy, p.omega, p.radius, p.inv_mass,
                           p.fx, p.fy, p.torque,
                           law.kn, law.ks, law.mu, law.zeta, law.allow_tension, sim.dt)

    once()
    times = []
    for _ in range(max(calls, int(3e6 / grains))):
        t = time.perf_counter()
        once()
        times.append(time.perf_counter() - t)
    return float(np.median(times)) / grains * 1e9, grains


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", nargs="+", default=["100x100", "173x173", "316x316", "548x548",
                                                    "1000x1000"], help="NXxNY lattices")
    ap.add_argument("--subset", type=int, default=12_000,
                    help="most grains of the in-cache run")
    ap.add_argument("--calls", type=int, default=5, help="least number of timed calls")
    ap.add_argument("--contacts", choices=sorted(CONTACTS), default="random",
                    help="which candidates touch")
    args = ap.parse_args()
    numba.set_num_threads(1)
    for size in args.sizes:
        nx, ny = (int(v) for v in size.lower().split("x"))
        sim = lattice(nx, ny, contacts=args.contacts)
        n = sim.particles.n
        touching = np.count_nonzero(sim.neighbors.pair_fn) / n
        every, _ = ns_per_grain(sim, None, args.calls)
        part, grains = ns_per_grain(sim, args.subset, args.calls)
        print(f"{size:>10s} N = {n:8d}  {touching:.2f} touching per grain  pair loop "
              f"{every:6.2f} ns/grain over all strips, {part:6.2f} over the first "
              f"{grains} grains", flush=True)


if __name__ == "__main__":
    main()
