"""Grain by grain against LAMMPS: the same grains, the same law, the same walls, the same steps.

A cloud of grains of one size (radius 0.1 m, density 835 kg/m^3, unit thickness) is dropped
with random velocities and spins onto the floor and the outlet of ``silodem bench``'s silo
(NX = 20: B = 4.4 m, a 1.2 m slot between two floor pieces 0.2 m thick), and silodem and
LAMMPS (Thompson et al. 2022, Comp. Phys. Comm. 271, 108171; Debian package ``lammps``,
command ``lmp``) run it from the same state for the same steps of dt = 2e-4 s.  LAMMPS runs
gran/hooke/history between grains and wall/gran hooke/history on the side planes and on the
floor blocks (a block pushes from its nearest point, corners included), with silodem's law:
k_n = 5e6 N/m and k_s = 2.5e6 N/m (not the bench's k_s = k_n: a law that used k_n for the
shear spring would pass there), friction tan 25 deg (grains) and tan 24 deg (walls), no shear
dashpot,
disk masses (``set density/disc``) and inertia (``nve/sphere disc``), the normal damping of
e = 0.5 (gamma_n = 2 zeta sqrt(k / m_eff), exact for grains of one size) and the damped normal
force clipped at 0 (``limit_damping``, which also makes the Coulomb cap 0 there).

Both integrators take the same positions: LAMMPS's velocity Verlet evaluates the forces at
x(t) with v(t - dt/2), as silodem's leap-frog does, so silodem starts from LAMMPS's v(0) less
half a step of gravity (no contacts at the start).  The positions then agree to round-off
while the laws and the walls agree, and part where a contact differs: the tension cap differs
(LAMMPS without ``limit_damping`` keeps mu |F_n| when the damped normal force pulls) by
6e-4 m within 500 steps, and grains of mixed sizes (LAMMPS damps in proportion to m_eff,
silodem to sqrt(m_eff)) by 5e-4 m; an uncapped convex corner (silodem before the eighth
session) parted by 3e-5 m within five steps of the first touch.  The one difference left is
second order: LAMMPS projects the shear displacement onto the new tangent plane each step,
silodem turns the shear force with the contact, a relative (d theta)^2 / 2 per step, about
1e-7 over a collision; chaos amplifies it once grains collide again and again.

Checked (the records): the largest position difference over all grains, in two clouds, at a
step before chaos has grown it: 20 grains apart (walls only: the floor, both outlet edges and
faces, the fall below) after 1,500 steps, and 60 grains that collide with each other and the
walls after 1,000 steps; tolerance 1e-6 m (1e-5 of a radius), below every law difference
above by 30 times or more.  Without ``lmp`` the family reports that and checks nothing.

The Hertz-Mindlin law (twenty-first session): the colliding cloud again with LAMMPS's
gran/hertz/history and wall/gran hertz/history, frictionless and undamped.  LAMMPS's normal
force sqrt(R* delta) K_n delta is silodem's 2/3 (2 E*) sqrt(R*) delta^(3/2) with
K_n = 4/3 E* (``HERTZ_KN``); its dashpot (as delta^(1/2)) and its shear law (a shear
displacement times the current stiffness, where silodem adds increments of the force) are
other models than silodem's, so only the elastic normal law is compared, grain by grain.
"""

from __future__ import annotations

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
from silodem.validate.records import Record

NX = 20
RADIUS = 0.1  # [m]
DENSITY = 835.0  # [kg/m^3]
K = bench.K_CONTACT  # [N/m]
# the shear stiffness, half of k_n: with k_s = k_n everywhere (as in every other check) a
# law that used k_n for the shear spring passed the whole suite
KS = 0.5 * K  # [N/m]
MU_GRAIN, MU_WALL = bench.MU_GRAIN, bench.MU_WALL  # the bench's law
ZETA = damping_ratio_from_restitution(bench.RESTITUTION)
TOLERANCE = 1e-6  # [m]
HERTZ_KN = 1e8  # LAMMPS's K_n = 4/3 E* of the Hertz cloud [Pa]; silodem's 2 E* is 3/2 of it
# (name, grains, lattice spacing [m], steps, Hertz-Mindlin law)
CLOUDS = (("walls only, 20 grains apart", 20, 0.42, 1500, False),
          ("colliding cloud, 60 grains", 60, 0.30, 1000, False),
          ("Hertz law, colliding cloud, 60 grains", 60, 0.30, 1000, True))


def cloud(n: int, spacing: float, seed: int = 1, mixed: bool = False) -> dict[str, np.ndarray]:
    """n grains on a lattice of 10 columns over the outlet, the lowest row 0.3 m above the
    floor (+- 2 cm), velocities up to 1 m/s and spins up to 5 rad/s in any direction; radii
    0.1 m, or 0.09-0.11 m with ``mixed``.  A spacing of 0.42 m keeps a row's grains apart."""
    rng = np.random.default_rng(seed)
    i = np.arange(n)
    cols = 10
    x = (NX * bench.SPACING / 2 + spacing * (i % cols - (cols - 1) / 2)
         + 0.02 * rng.uniform(-1, 1, n))
    y = 0.3 + spacing * (i // cols) + 0.02 * rng.uniform(-1, 1, n)
    radius = 0.5 * (0.18 + 0.04 * rng.random(n)) if mixed else np.full(n, RADIUS)
    return {"x": x, "y": y, "radius": radius, "vx": rng.uniform(-1, 1, n),
            "vy": rng.uniform(-1, 1, n), "omega": rng.uniform(-5, 5, n)}


def run_silodem(state: dict[str, np.ndarray], steps: int, every: int,
                tension: bool = False, hertz: bool = False) -> list[np.ndarray]:
    """Positions (n, 2) [m] in the order of ``state``, every ``every`` steps from step 0;
    ``hertz``: the frictionless, undamped Hertz law of ``HERTZ_KN`` instead of the bench's."""
    silo, _, _ = bench.build(NX, 4)  # the bench's walls and law (zeta = ZETA); not its grains
    law = dataclasses.replace(silo.law, ks=KS, allow_tension=tension)
    silo.walls.ks[:] = KS
    if hertz:
        kn = 1.5 * HERTZ_KN  # 2 E*
        law = dataclasses.replace(law, kn=kn, ks=kn, mu=0.0, zeta=0.0, hertz=True)
        for name in ("kn", "ks"):
            getattr(silo.walls, name)[:] = kn
        silo.walls.mu[:] = 0.0
    p = Particles(len(state["x"]))
    p.add(state["x"], state["y"], state["radius"], DENSITY, vx=state["vx"],
          vy=state["vy"] + 0.5 * bench.DT * 9.81, omega=state["omega"])
    sim = Simulation(p, silo.walls, law, dt=bench.DT, gravity=9.81, skin=0.05)
    frames = []
    for k in range(steps // every + 1):
        if k:
            sim.run(every)
        order = np.argsort(p.view("uid"))
        frames.append(np.column_stack([p.view("x")[order], p.view("y")[order]]))
    return frames


def _f(v) -> str:
    """A float written so that it reads back as the same double."""
    return repr(float(v))


def lammps_input(state: dict[str, np.ndarray], steps: int, every: int,
                 tension: bool = False, hertz: bool = False) -> tuple[str, str]:
    """(data file, input deck) of the same grains, walls and law."""
    width = NX * bench.SPACING
    n = len(state["x"])
    s = {k: [_f(v) for v in vals] for k, vals in state.items()}
    atoms = "\n".join(f"{i + 1} 1 {_f(2 * state['radius'][i])} {DENSITY} {s['x'][i]} "
                      f"{s['y'][i]} 0.0" for i in range(n))
    vels = "\n".join(f"{i + 1} {s['vx'][i]} {s['vy'][i]} 0.0 0.0 0.0 {s['omega'][i]}"
                     for i in range(n))
    data = (f"silodem cloud\n\n{n} atoms\n1 atom types\n\n0.0 {_f(width)} xlo xhi\n"
            f"-2.0 20.0 ylo yhi\n-0.5 0.5 zlo zhi\n\nAtoms # sphere\n\n{atoms}\n\n"
            f"Velocities\n\n{vels}\n")
    mass = DENSITY * math.pi * RADIUS**2
    gamma_grain = 2 * ZETA * math.sqrt(K / (mass / 2))  # [1/s], per unit m_eff
    gamma_wall = 2 * ZETA * math.sqrt(K / mass)
    xl, xr = width / 2 - bench.SLOT / 2, width / 2 + bench.SLOT / 2
    limit = "" if tension else " limit_damping"
    wall = f"hooke/history {K} {_f(KS)} {_f(gamma_wall)} 0.0 {_f(MU_WALL)} 0{limit}"
    pair = f"gran/hooke/history {K} {_f(KS)} {_f(gamma_grain)} 0.0 {_f(MU_GRAIN)} 0{limit}"
    if hertz:  # frictionless and undamped: the elastic normal law alone
        wall = f"hertz/history {_f(HERTZ_KN)} {_f(HERTZ_KN)} 0.0 0.0 0.0 0"
        pair = f"gran/{wall}"
    deck = f"""units si
dimension 2
atom_style sphere
boundary f p p
comm_modify vel yes
read_data data.txt
set group all density/disc {DENSITY}
neighbor 0.05 bin
neigh_modify delay 0 every 1 check yes
pair_style {pair}
pair_coeff * *
timestep {bench.DT}
fix 1 all nve/sphere disc
fix 2 all gravity 9.81 vector 0 -1 0
fix 3 all enforce2d
fix walls all wall/gran {wall} xplane 0.0 {_f(width)}
region bl block -1 {_f(xl)} -0.2 0.0 -0.5 0.5 side out units box
region br block {_f(xr)} {_f(width + 1)} -0.2 0.0 -0.5 0.5 side out units box
fix botl all wall/gran/region {wall} region bl
fix botr all wall/gran/region {wall} region br
thermo {every}
dump d all custom {every} traj.txt id xu yu
dump_modify d sort id format float %.17g
run {steps}
"""
    return data, deck


def run_lammps(state: dict[str, np.ndarray], steps: int, every: int,
               tension: bool = False, hertz: bool = False) -> list[np.ndarray]:
    """As :func:`run_silodem`, by ``lmp`` (unwrapped positions)."""
    n = len(state["x"])
    with tempfile.TemporaryDirectory() as tmp:
        data, deck = lammps_input(state, steps, every, tension, hertz)
        (Path(tmp) / "data.txt").write_text(data)
        (Path(tmp) / "deck.in").write_text(deck)
        lmp = bench.lammps_executable() or "lmp"
        subprocess.run([lmp, "-in", "deck.in", "-log", "none", "-echo", "none"], cwd=tmp,
                       check=True, capture_output=True, text=True)
        lines = (Path(tmp) / "traj.txt").read_text().splitlines()
    frames = []
    for start in range(0, len(lines), n + 9):  # 9 header lines per frame
        rows = np.array([ln.split() for ln in lines[start + 9:start + 9 + n]], dtype=float)
        frames.append(rows[:, 1:3])
    return frames


def divergence(state: dict[str, np.ndarray], steps: int, every: int,
               tension: bool = False, hertz: bool = False) -> np.ndarray:
    """The largest position difference between the two codes [m], every ``every`` steps."""
    ours = run_silodem(state, steps, every, tension, hertz)
    theirs = run_lammps(state, steps, every, tension, hertz)
    return np.array([np.abs(a - b).max() for a, b in zip(ours, theirs)])


def run(quick: bool = False) -> tuple[list[Record], dict]:
    """The family's records and figure data (the divergence against the step per cloud)."""
    if bench.lammps_executable() is None:
        return [Record("LAMMPS trajectories", "lmp found", None, None, None, kind="info",
                       note="LAMMPS (Debian package lammps) absent: not compared")], {}
    records, curves = [], {}
    every = 50  # steps between the compared frames
    for name, n, spacing, steps, hertz in CLOUDS:
        try:
            dev = divergence(cloud(n, spacing), 2 * steps, every, hertz=hertz)
        except (OSError, subprocess.CalledProcessError) as err:  # a failed lmp fails the check
            detail = getattr(err, "stderr", "") or str(err)
            records.append(Record(f"LAMMPS trajectories, {name}", "lmp ran", 1.0, 0.0, 0.0,
                                  kind="abs", note=f"lmp failed: {detail.strip()[-200:]}"))
            continue
        curves[name] = (np.arange(dev.size) * every, dev, steps)
        records.append(Record(
            f"LAMMPS trajectories, {name}", f"largest position difference after {steps} steps",
            0.0, float(dev[steps // every]), TOLERANCE, kind="abs", unit="m",
            note=("frictionless, undamped Hertz: gran/hertz/history, wall/gran" if hertz else
                  "same grains, law and walls in LAMMPS (gran/hooke/history, wall/gran)")))
    return records, curves
