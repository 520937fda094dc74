"""Grain-by-grain comparison of silodem and LAMMPS on the benchmark silo's outlet
(docs/validation.md, section 5, eighth session).

    python docs/validation/lammps_trajectory.py [--grains N] [--steps S] [--seed K]
                                                [--radii equal|mixed]

A cloud of N grains (default 60) is dropped with random velocities and spins onto the floor and
the outlet of ``silodem bench``'s silo (NX = 20, B = 4.4 m, D = 1.2 m, floor pieces 0.2 m
thick), and both codes run it for S steps of dt = 2e-4 s from the same positions, velocities
and spins.  LAMMPS runs the benchmark deck's law (gran/hooke/history, wall/gran on the side
planes and on the floor blocks) with the parameters silodem uses to full precision: k_n = k_s =
5e6 N/m, friction tan 25 deg and tan 24 deg, no shear dashpot, disk masses and inertia, the
damping of silodem's e = 0.5 (gamma_n = 2 zeta sqrt(k / m_eff), exact for grains of one size),
tension allowed in both.

Both integrators are the same leap-frog in the positions (LAMMPS's velocity Verlet evaluates
forces with v(t - dt/2), as silodem does), so the positions agree to round-off as long as the
two laws and wall geometries agree; the first contact where they differ shows as a jump in the
largest position difference.  silodem stores v(t - dt/2): its initial velocities are LAMMPS's
v(0) less half a step of gravity.  Prints, every ``--every`` steps, the largest difference in
position between the two codes (m) and the number of grain-grain and grain-wall contacts.
Needs ``lmp`` (Debian package ``lammps``)."""

from __future__ import annotations

import argparse
import dataclasses
import math
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from silodem import bench
from silodem.engine.contact import damping_ratio_from_restitution
from silodem.engine.particles import Particles
from silodem.engine.simulation import Simulation

NX = 20
DENSITY = 835.0
K = 5.0e6
MU_GRAIN = math.tan(math.radians(25.0))
MU_WALL = math.tan(math.radians(24.0))
ZETA = damping_ratio_from_restitution(0.5)


def cloud(n: int, seed: int, mixed: bool, spacing: float = 0.3) -> dict[str, np.ndarray]:
    """n grains on a loose lattice of 10 columns over the outlet, the lowest row 0.3 m above
    the floor, velocities up to 1 m/s and spins up to 5 rad/s in any direction.  A spacing of
    0.42 m keeps the grains of one row apart (walls only)."""
    rng = np.random.default_rng(seed)
    width = NX * bench.SPACING
    cols = 10
    i = np.arange(n)
    x = width / 2 + spacing * (i % cols - (cols - 1) / 2) + 0.02 * rng.uniform(-1, 1, n)
    y = 0.3 + spacing * (i // cols) + 0.02 * rng.uniform(-1, 1, n)
    radius = 0.5 * (0.18 + 0.04 * rng.random(n)) if mixed else np.full(n, 0.1)
    return {"x": x, "y": y, "radius": radius, "vx": rng.uniform(-1, 1, n),
            "vy": rng.uniform(-1, 1, n), "omega": rng.uniform(-5, 5, n)}


def _f(v) -> str:
    """A float written so that it reads back to the same double."""
    return repr(float(v))


def run_silodem(state: dict[str, np.ndarray], steps: int, every: int,
                tension: bool) -> list[np.ndarray]:
    sim, _, _ = bench.build(NX, 4)  # the bench's walls; its grains are replaced below
    sim.law = dataclasses.replace(sim.law, zeta=ZETA, allow_tension=tension)
    p = Particles(len(state["x"]))
    # leap-frog stores v(t - dt/2): LAMMPS's v(0) less half a step of gravity (no contacts yet)
    p.add(state["x"], state["y"], state["radius"], DENSITY, vx=state["vx"],
          vy=state["vy"] + 0.5 * bench.DT * 9.81, omega=state["omega"])
    sim = Simulation(p, sim.walls, sim.law, dt=bench.DT, gravity=9.81, skin=0.05)
    frames = []
    for k in range(steps // every + 1):
        if k:
            sim.run(every)
        order = np.argsort(p.view("uid"))
        frames.append(np.column_stack([p.view("x")[order], p.view("y")[order]]))
    return frames


def lammps_input(state: dict[str, np.ndarray], steps: int, every: int,
                 tension: bool) -> tuple[str, str]:
    """(data file, input deck) of the same grains in the benchmark silo.  Without tension the
    deck clips the damped normal force at 0 (``limit_damping``), which also sets the Coulomb
    cap to 0 there, as silodem's law does."""
    width = NX * bench.SPACING
    n = len(state["x"])
    s = {k: [_f(v) for v in vals] for k, vals in state.items()}
    atoms = "\n".join(f"{i + 1} 1 {_f(2 * state['radius'][i])} {DENSITY} {s['x'][i]} "
                      f"{s['y'][i]} 0.0" for i in range(n))
    vels = "\n".join(f"{i + 1} {s['vx'][i]} {s['vy'][i]} 0.0 0.0 0.0 {s['omega'][i]}"
                     for i in range(n))
    data = (f"silodem cloud\n\n{n} atoms\n1 atom types\n\n0.0 {width!r} xlo xhi\n"
            f"-2.0 20.0 ylo yhi\n-0.5 0.5 zlo zhi\n\nAtoms # sphere\n\n{atoms}\n\n"
            f"Velocities\n\n{vels}\n")
    m_mean = DENSITY * math.pi * 0.1**2  # damping exact for grains of radius 0.1 m
    gamma_grain = 2 * ZETA * math.sqrt(K / (m_mean / 2))
    gamma_wall = 2 * ZETA * math.sqrt(K / m_mean)
    xl, xr = width / 2 - bench.SLOT / 2, width / 2 + bench.SLOT / 2
    limit = "" if tension else " limit_damping"
    wall = f"hooke/history {K} {K} {gamma_wall!r} 0.0 {MU_WALL!r} 0{limit}"
    deck = f"""units si
dimension 2
atom_style sphere
boundary f p p
comm_modify vel yes
read_data data.txt
set group all density/disc {DENSITY}
neighbor 0.05 bin
neigh_modify delay 0 every 1 check yes
pair_style gran/hooke/history {K} {K} {gamma_grain!r} 0.0 {MU_GRAIN!r} 0{limit}
pair_coeff * *
timestep {bench.DT}
fix 1 all nve/sphere disc
fix 2 all gravity 9.81 vector 0 -1 0
fix 3 all enforce2d
fix walls all wall/gran {wall} xplane 0.0 {width!r}
region bl block -1 {xl!r} -0.2 0.0 -0.5 0.5 side out units box
region br block {xr!r} {width + 1!r} -0.2 0.0 -0.5 0.5 side out units box
fix botl all wall/gran/region {wall} region bl
fix botr all wall/gran/region {wall} region br
thermo {every}
dump d all custom {every} traj.txt id xu yu
dump_modify d sort id format float %.17g
run {steps}
"""
    return data, deck


def run_lammps(state: dict[str, np.ndarray], steps: int, every: int,
               tension: bool) -> list[np.ndarray]:
    tmp = Path(tempfile.mkdtemp())
    data, deck = lammps_input(state, steps, every, tension)
    (tmp / "data.txt").write_text(data)
    (tmp / "deck.in").write_text(deck)
    subprocess.run(["lmp", "-in", "deck.in", "-log", "none", "-echo", "none"], cwd=tmp,
                   check=True, capture_output=True, text=True)
    frames, lines = [], (tmp / "traj.txt").read_text().splitlines()
    n = len(state["x"])
    for start in range(0, len(lines), n + 9):
        rows = np.array([line.split() for line in lines[start + 9:start + 9 + n]], dtype=float)
        frames.append(rows[:, 1:3])
    return frames


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--grains", type=int, default=60)
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--every", type=int, default=250)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--spacing", type=float, default=0.3)
    ap.add_argument("--radii", choices=["equal", "mixed"], default="equal")
    ap.add_argument("--tension", action="store_true",
                    help="both codes keep the damped normal force when it pulls")
    args = ap.parse_args()
    state = cloud(args.grains, args.seed, args.radii == "mixed", args.spacing)
    ours = run_silodem(state, args.steps, args.every, args.tension)
    theirs = run_lammps(state, args.steps, args.every, args.tension)
    for k, (a, b) in enumerate(zip(ours, theirs)):
        print(f"step {k * args.every:6d}  t = {k * args.every * bench.DT:6.3f} s  "
              f"max |dx| = {np.abs(a - b).max():.3e} m  lowest y = {a[:, 1].min():7.3f} m")


if __name__ == "__main__":
    main()
