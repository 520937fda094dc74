"""The bench silo packed, at about 3e5 grains, against LAMMPS (docs/performance.md, Targets).

    python benchmarks/packed_vs_lammps.py [--nx 946] [--ny 200] [--settle 20000] [--steps 1000]

``silodem bench --n 302764`` builds the deck's silo with NY = 2 NX: a column 217 m tall that
is still falling after the matrix's 1500 settling steps (no grain touches another), and that,
given 30,000 steps, lands and bounces as a whole (mean vertical velocity +9.9 m/s).  Here the
deck's silo is made wide instead (NX = 946, NY = 200: 299,882 grains in a column 70 m tall,
the scaling run's height), so that ``--settle`` steps pack it: the grains land, the column
compacts and discharges through the slot, the grains that leave re-entering at the top.
silodem (1 thread) then LAMMPS (1 rank, the deck run by ``silodem.bench.run_lammps``) run the
same SETTLE untimed and STEPS timed steps, one after the other in this process session.

Prints, as JSON lines: during silodem's settling, the touching grain-grain contacts per grain
and the grains' mean vertical velocity (the state: packed when the contacts level off and the
velocity is near 0); then each code's particle-steps per second over the timed steps, its
neighbour-list builds there, and the ratio.
"""

from __future__ import annotations

import argparse
import json
import resource
import time

import numba

from silodem import bench
from silodem.engine.quantities import grain_contacts


def state(sim, step: int, since: float) -> dict:
    """Contacts per grain and mean vertical velocity [m/s] of the grains now."""
    n = sim.particles.n
    return {"step": step, "contacts_per_grain": 2 * grain_contacts(sim).i.size / n,
            "mean_vy": float(sim.particles.vy[:n].mean()),
            "wall_s": round(time.perf_counter() - since, 1)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--nx", type=int, default=946)
    ap.add_argument("--ny", type=int, default=200)
    ap.add_argument("--settle", type=int, default=20000, help="untimed steps")
    ap.add_argument("--steps", type=int, default=1000, help="timed steps")
    args = ap.parse_args()
    numba.set_num_threads(1)
    sim, _, top = bench.build(args.nx, args.ny)
    t0 = time.perf_counter()
    quarters = [args.settle // 4] * 3 + [args.settle - 3 * (args.settle // 4)]
    done = 0
    for chunk in quarters:
        bench.advance(sim, top, chunk)
        done += chunk
        print(json.dumps(state(sim, done, t0)), flush=True)
    builds = sim.neighbors.rebuilds
    t1 = time.perf_counter()
    bench.advance(sim, top, args.steps)
    seconds = time.perf_counter() - t1
    n = sim.particles.n
    out = {"nx": args.nx, "ny": args.ny, "settle": args.settle, "steps": args.steps, "n": n,
           "silodem_M_per_s": n * args.steps / seconds / 1e6,
           "silodem_builds": sim.neighbors.rebuilds - builds,
           "silodem_peak_MB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
           "end": state(sim, done + args.steps, t0)}
    print(json.dumps(out), flush=True)
    lam = bench.run_lammps(args.nx, args.ny, 1, args.steps, args.settle)
    out.update(lammps_n=lam.n, lammps_M_per_s=lam.particle_steps_per_s / 1e6,
               lammps_builds=lam.list_builds)
    out["ratio"] = out["silodem_M_per_s"] / out["lammps_M_per_s"]
    print(json.dumps(out), flush=True)


if __name__ == "__main__":
    main()
