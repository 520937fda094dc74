"""The whole step of silodem and of LAMMPS on the same dense lattice, against N
(docs/performance.md).

    python benchmarks/lattice_vs_lammps.py [--sizes 100 173 316 548 1000]

The lattice of ``cache_probe.py`` (NX x NX disks, radii 0.09-0.105 m on a 0.2 m lattice, no
walls, no gravity, about 0.5 touching contacts per grain, no list rebuild in the timed steps),
one thread in silodem and one rank in LAMMPS (``lammps-lattice2d.in``, Debian's ``lmp``),
run one after the other in this process session, ``--repeat`` times each, alternating.
Prints, for each size, the best time per particle-step [ns] of each code over about ``--work``
particle-steps, and each code's cost relative to its own at the smallest size: how much each
pays once its state no longer fits in the cache.
"""

from __future__ import annotations

import argparse
import subprocess
import tempfile
import time
from pathlib import Path

import numba
from cache_probe import lattice

from silodem.bench import lammps_executable, last_loop

DECK = Path(__file__).with_name("lammps-lattice2d.in")


def silodem_ns(nx: int, steps: int) -> tuple[float, int]:
    """ns per particle-step of ``Simulation.run`` on the NX x NX lattice, and N."""
    sim = lattice(nx, nx)
    n = sim.particles.n
    t = time.perf_counter()
    sim.run(steps)
    return (time.perf_counter() - t) / (n * steps) * 1e9, n


def lammps_ns(lmp: str, nx: int, steps: int) -> tuple[float, int]:
    """ns per particle-step of the deck's timed run, and N."""
    with tempfile.TemporaryDirectory() as tmp:
        out = subprocess.run([lmp, "-in", str(DECK), "-var", "NX", str(nx), "-var", "STEPS",
                              str(steps), "-log", "none"], cwd=tmp, capture_output=True,
                             text=True, check=True).stdout
    seconds, _, done, atoms = last_loop(out)
    return seconds / (atoms * done) * 1e9, atoms


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", nargs="+", type=int, default=[100, 173, 316, 548, 1000],
                    help="grains per side of the lattice")
    ap.add_argument("--work", type=float, default=5e7, help="particle-steps per run")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each code per size (best)")
    args = ap.parse_args()
    lmp = lammps_executable()
    if lmp is None:
        raise SystemExit("LAMMPS not found: install Debian's package (apt-get install lammps)")
    numba.set_num_threads(1)
    first = None
    for nx in args.sizes:
        steps = max(20, int(args.work / nx**2))
        runs = [(silodem_ns(nx, steps), lammps_ns(lmp, nx, steps)) for _ in range(args.repeat)]
        (ours, n), (theirs, atoms) = min(r[0] for r in runs), min(r[1] for r in runs)
        first = first or (ours, theirs)
        print(f"N = {n:8d} ({atoms:8d} in LAMMPS), {steps:5d} steps: silodem {ours:6.1f} ns "
              f"({ours / first[0]:.2f} x its smallest), LAMMPS {theirs:6.1f} ns "
              f"({theirs / first[1]:.2f} x), LAMMPS / silodem {theirs / ours:.2f}", flush=True)


if __name__ == "__main__":
    main()
