"""The performance benchmark: a dense, steadily discharging flat-bottomed silo.

It is built to match ``benchmarks/lammps-silo2d.in`` (a copy of the project's reference deck
``shared/bench/lammps-silo2d.in``) so that silodem and LAMMPS do the same work:

* box 0 <= x <= W = 0.22 NX, grains on a square lattice of spacing 0.22 m in
  0.11 <= x <= W - 0.11, 0.2 <= y <= H - 0.4 with H = 0.22 * 1.6 * NY, diameters uniform in
  [0.18, 0.22] m, density 835 kg/m^3, unit thickness (paper case 2);
* vertical walls x = 0 and x = W, a floor at y = 0 in two pieces with a centred slot of width
  1.2 m, the floor pieces 0.2 m thick (their inner ends are walls too, and the edges where
  the two faces meet are contact points, as the corners of the deck's block regions are);
* contact stiffness k_n = k_s = 5e6 N/m (grain stiffness 1e7 N/m in series), friction
  tan 25 deg between grains and tan 24 deg with the walls, restitution 0.5;
* grains leaving through the slot re-enter at the top (LAMMPS: periodic y over [-2, H]); as in
  LAMMPS, a grain is moved across that boundary when the neighbour list is rebuilt;
* dt = 2e-4 s; SETTLE untimed steps (fall, settle, start of flow; compilation happens here),
  then STEPS timed steps.

Throughput is reported as particle-steps per second: N * STEPS / (wall time of the timed steps).

The grains are disks of unit thickness (mass 835 pi r^2).  The deck's ``set density 835``
gives LAMMPS's grains the mass of spheres in 2D (835 * 4/3 pi r^3, 7.5 times lighter), so its
grains rebound with e ~ 0.8; the work per step, which is what is compared, is about the same
(docs/performance.md, "Method").
"""

from __future__ import annotations

import json
import math
import os
import platform
import re
import resource
import shutil
import subprocess
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from silodem.engine.contact import GrainLaw, damping_ratio_from_restitution
from silodem.engine.particles import Particles
from silodem.engine.simulation import Simulation
from silodem.engine.walls import Walls

SPACING = 0.22  # lattice spacing [m]
Y_BOTTOM = -2.0  # lower end of the periodic direction in the deck [m]
DT = 2.0e-4  # [s]
K_CONTACT = 5.0e6  # [N/m]
SLOT = 1.2  # outlet width [m]
MU_GRAIN = math.tan(math.radians(25.0))  # grain-grain friction (paper case 2)
MU_WALL = math.tan(math.radians(24.0))  # grain-wall friction
RESTITUTION = 0.5
COPY_GAP = 1.0  # between side-by-side copies (build) [m]: > 3 r_max + skin, a wall's reach


@dataclass
class BenchResult:
    code: str
    n: int
    threads: int
    steps: int
    seconds: float
    particle_steps_per_s: float
    peak_memory_bytes: int | None  # whole process's peak RSS; None: not measured (LAMMPS)
    nx: int
    ny: int
    list_builds: int  # neighbour-list builds during the timed steps
    build_seconds: float  # time spent building them [s] (LAMMPS: its "Neigh" time)

    def line(self) -> str:
        return (f"{self.code:8s} n = {self.n:8d}  threads/ranks = {self.threads}  "
                f"steps = {self.steps}  {self.seconds:8.3f} s  "
                f"{self.particle_steps_per_s / 1e6:8.3f} M particle-steps/s  "
                f"{self.list_builds} list builds")


def lattice_size(n: int) -> tuple[int, int]:
    """(NX, NY) with NY = 2 NX whose lattice holds about n grains (NX=100 -> 31,700)."""
    nx = max(4, round(math.sqrt(n / 3.17)))
    return nx, 2 * nx


def deck_lattice(nx: int, ny: int) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Lattice sites of the deck's `create_atoms` (lattice sq 0.22, origin 0.5 0.5)."""
    width = nx * SPACING
    top = ny * SPACING * 1.6
    xs = SPACING * (np.arange(nx + 1) + 0.5)
    ys = SPACING * (np.arange(int(top / SPACING) + 1) + 0.5)
    eps = 1e-9
    xs = xs[(xs >= 0.11 - eps) & (xs <= width - 0.11 + eps)]
    ys = ys[(ys >= 0.2 - eps) & (ys <= top - 0.4 + eps)]
    gx, gy = np.meshgrid(xs, ys)
    return gx.ravel(), gy.ravel(), width, top


def build(nx: int, ny: int, seed: int = 12345, skin: float = 0.05,
          copies: int = 1) -> tuple[Simulation, float, float]:
    """The deck's silo (``copies = 1``), or ``copies`` such silos side by side, ``COPY_GAP``
    apart, each with its own walls, outlet and grains: N grows while every silo does the same
    kind and amount of work, which isolates what the system size alone costs (``--scaling``).
    The first silo is the deck's; each other draws its own radii from the same distribution
    (the same lattice), so that the silos are alike but not identical.  Identical silos stay
    identical to round-off for thousands of steps (3000 from the lattice), and then every cell
    row repeats one silo's pattern of touching and apart pairs ``copies`` times, which the
    branch predictor learns: 100 such copies ran the step faster per grain than one silo
    (docs/performance.md, "Cost per particle-step against N").  Returns the simulation, the
    width of one silo [m] and the top of the lattice [m]."""
    x0, y0, width, top = deck_lattice(nx, ny)
    rng = np.random.default_rng(seed)
    radii = [0.5 * (0.18 + 0.04 * rng.random(x0.size)) for _ in range(copies)]
    # copies COPY_GAP apart: no grain is then a contact candidate of a grain or a wall of
    # another copy (side by side, a grain pressed against its silo's left wall was within
    # reach of the next silo's right wall and of the grains behind it)
    pitch = width + COPY_GAP
    x = np.concatenate([x0 + c * pitch for c in range(copies)])
    y, radius = np.tile(y0, copies), np.concatenate(radii)
    p = Particles(x.size)
    p.add(x, y, radius, 835.0)
    k_grain = 2 * K_CONTACT  # two equal grains in series give K_CONTACT
    k_wall = 2 * K_CONTACT  # grain in series with wall gives K_CONTACT
    w = Walls()
    kw = k_grain * k_wall / (k_grain + k_wall)
    for c in range(copies):
        a, b = c * pitch, c * pitch + width
        xl, xr = a + width / 2 - SLOT / 2, a + width / 2 + SLOT / 2
        tag = f"_{c}" if copies > 1 else ""
        # side walls twice as high as the column: a grain thrown above the top stays in its
        # silo, as between the deck's infinite xplane walls
        w.add("left" + tag, (a, 2 * top), (a, Y_BOTTOM), kw, kw, MU_WALL, one_sided=True)
        w.add("right" + tag, (b, Y_BOTTOM), (b, 2 * top), kw, kw, MU_WALL, one_sided=True)
        w.add("floor_left" + tag, (a, 0.0), (xl, 0.0), kw, kw, MU_WALL, one_sided=True)
        w.add("slot_left" + tag, (xl, 0.0), (xl, -0.2), kw, kw, MU_WALL, one_sided=True)
        w.add("slot_right" + tag, (xr, -0.2), (xr, 0.0), kw, kw, MU_WALL, one_sided=True)
        w.add("floor_right" + tag, (xr, 0.0), (b, 0.0), kw, kw, MU_WALL, one_sided=True)
    law = GrainLaw(kn=K_CONTACT, ks=K_CONTACT, mu=MU_GRAIN,
                   zeta=damping_ratio_from_restitution(RESTITUTION))
    sim = Simulation(p, w, law, dt=DT, gravity=9.81, skin=skin)
    return sim, width, top


def reenter(sim: Simulation, top: float) -> int:
    """Grains below the periodic boundary re-enter at the top, moved up by top - Y_BOTTOM (the
    deck's periodic y over [Y_BOTTOM, top], ``top`` [m]); called
    right before a neighbour-list build, which then lists them at their new place.  Returns
    the number of grains moved.

    Unlike LAMMPS's, these grains do not touch across the boundary, so a grain can re-enter
    onto one that re-entered just before it.  With the deck's mixed sizes no run has shown
    harm (speeds stay below those of the free fall); grains all of one size fall through the
    slot in line, and there the overlaps throw grains out of the silo (docs/validation.md,
    section 5)."""
    y = sim.particles.view("y")
    low = y < Y_BOTTOM
    if np.any(low):
        y[low] += top - Y_BOTTOM
    return int(low.sum())


def advance(sim: Simulation, top: float, steps: int) -> None:
    if not sim.before_rebuild:
        sim.before_rebuild.append(lambda s: reenter(s, top))
    sim.run(steps)


def widened_size(n: int, rows: int) -> int:
    """NX of a silo of about ``n`` grains whose column is ``rows`` (NY) high: the deck's
    lattice holds about 1.6 NY - 3 grains per column (``run_silodem(rows=...)``)."""
    return max(4, round(n / (1.6 * rows - 3)))


def run_silodem(n: int, threads: int, steps: int, settle: int,
                rows: int | None = None, copies: int = 1,
                say: Callable[[str], None] = lambda text: None) -> BenchResult:
    """Throughput of silodem on the benchmark silo of about ``n`` grains.  ``rows`` fixes the
    deck's NY (column height) and widens the silo instead; ``copies`` puts that many such
    silos side by side (N = copies x n), so that every N is in the same flow state (used for
    the cost-per-particle-step scaling; the default, NY = 2 NX and one silo, matches
    ``--lammps``).  ``say`` is told each stage as it begins (the command line's progress,
    outside the timed steps)."""
    import numba

    numba.set_num_threads(threads)
    if rows is None:
        nx, ny = lattice_size(n)
    else:
        nx, ny = widened_size(n, rows), rows
    say(f"building the silo ({nx} x {ny} lattice{f', {copies} copies' if copies > 1 else ''})")
    sim, _, top = build(nx, ny, copies=copies)
    say(f"{sim.particles.n} grains: {settle} untimed steps (the kernels compile here)")
    advance(sim, top, settle)
    builds = sim.neighbors.rebuilds
    build_time = [0.0]
    rebuild = sim.neighbors.rebuild

    def timed_rebuild(*args):
        t = time.perf_counter()
        rebuild(*args)
        build_time[0] += time.perf_counter() - t

    sim.neighbors.rebuild = timed_rebuild  # this run only: time the list builds
    say(f"{steps} timed steps")
    t0 = time.perf_counter()
    advance(sim, top, steps)
    seconds = time.perf_counter() - t0
    builds = sim.neighbors.rebuilds - builds
    n_real = sim.particles.n
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    return BenchResult("silodem", n_real, threads, steps, seconds, n_real * steps / seconds,
                       peak, nx, ny, builds, build_time[0])


def deck_path() -> Path:
    return Path(str(resources.files("silodem") / "benchmarks" / "lammps-silo2d.in"))


_LOOP = re.compile(r"Loop time of ([0-9.eE+-]+) on (\d+) procs for (\d+) steps with (\d+) atoms")
_BUILDS = re.compile(r"Neighbor list builds = (\d+)")
_NEIGH = re.compile(r"^Neigh\s*\|\s*([0-9.eE+-]+)", re.MULTILINE)


def lammps_executable() -> str | None:
    """The LAMMPS command (Debian's ``lmp``, or the serial / MPI names of other builds), or
    None when it is not installed."""
    return shutil.which("lmp") or shutil.which("lmp_serial") or shutil.which("lmp_mpi")


def last_loop(stdout: str) -> tuple[float, int, int, int]:
    """The last "Loop time" line of a LAMMPS log: (seconds, ranks, steps, atoms)."""
    seconds, procs, steps, atoms = _LOOP.findall(stdout)[-1]
    return float(seconds), int(procs), int(steps), int(atoms)


class LammpsFailed(RuntimeError):
    """LAMMPS ran but gave no timing (its own error, a crash): its last words, one line."""


def lammps_command(ranks: int) -> list[str]:
    """``lmp`` (under ``mpirun -np ranks`` for ranks > 1); FileNotFoundError (one line) when
    either is not installed, found before any run (it was found after silodem's)."""
    lmp = lammps_executable()
    if lmp is None:
        raise FileNotFoundError(
            "LAMMPS not found: install Debian's package (apt-get install lammps)")
    if ranks == 1:
        return [lmp]
    mpirun = shutil.which("mpirun")
    if mpirun is None:
        raise FileNotFoundError("mpirun not found (Debian package openmpi-bin)")
    return [mpirun, "--allow-run-as-root", "--oversubscribe", "-np", str(ranks), lmp]


def run_lammps(nx: int, ny: int, ranks: int, steps: int, settle: int) -> BenchResult:
    """Run the reference deck with Debian's `lmp` (and `mpirun -np ranks` for ranks > 1)."""
    cmd = [*lammps_command(ranks), "-in", str(deck_path()), "-var", "NX", str(nx),
           "-var", "NY", str(ny), "-var", "STEPS", str(steps), "-var", "SETTLE", str(settle),
           "-log", "none"]
    with tempfile.TemporaryDirectory() as tmp:
        proc = subprocess.run(cmd, cwd=tmp, capture_output=True, text=True, check=False,
                              env={**os.environ, "OMP_NUM_THREADS": "1"})
    if proc.returncode != 0 or len(_LOOP.findall(proc.stdout)) < 2:
        lines = [line.strip() for line in (proc.stdout + proc.stderr).splitlines()
                 if line.strip()]
        errors = [line for line in lines if line.startswith("ERROR")]
        said = (errors or lines or ["no output"])[-1]
        raise LammpsFailed(f"LAMMPS failed (exit {proc.returncode}): {said[:300]}")
    seconds, procs, nsteps, atoms = last_loop(proc.stdout)
    builds = _BUILDS.findall(proc.stdout)
    neigh = _NEIGH.findall(proc.stdout)
    return BenchResult("lammps", atoms, int(procs), nsteps, seconds, atoms * nsteps / seconds,
                       None, nx, ny, int(builds[-1]) if builds else -1,
                       float(neigh[-1]) if neigh else float("nan"))


def bench(n: int, threads: int, steps: int, settle: int, lammps: bool,
          rows: int | None = None,
          say: Callable[[str], None] = lambda text: None) -> list[BenchResult]:
    """silodem's run, and with ``lammps`` the deck's on the same lattice (NX, NY).  ``rows``:
    the deck's NY, the silo widened to about ``n`` grains (``run_silodem``); ``say``: told
    each stage as it begins."""
    if lammps:
        lammps_command(threads)  # installed? (before minutes of silodem's run)
    results = [run_silodem(n, threads, steps, settle, rows=rows, say=say)]
    if lammps:
        r = results[0]
        say(f"LAMMPS on the same lattice: {settle} untimed and {steps} timed steps "
            f"({threads} rank{'s' if threads > 1 else ''})")
        results.append(run_lammps(r.nx, r.ny, threads, steps, settle))
    return results


def machine() -> dict:
    """What the figures were measured on: the CPU's model name (Linux's /proc/cpuinfo, else
    ``platform.processor()``) and the CPUs this process may use.  Throughput moves with the
    machine (docs/performance.md), so a figure is read with its machine."""
    cpu = ""
    try:
        for row in Path("/proc/cpuinfo").read_text().splitlines():
            if row.startswith("model name"):
                cpu = row.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    from silodem.study.cluster import default_workers  # the cores this process may use

    return {"cpu": cpu or platform.processor() or platform.machine(), "cpus": default_workers()}


def as_json(results: list[BenchResult]) -> str:
    first = asdict(results[0])
    if len(results) > 1:
        first["lammps"] = asdict(results[1])
        first["ratio_vs_lammps"] = results[0].particle_steps_per_s / results[1].particle_steps_per_s
    first["machine"] = machine()
    return json.dumps(first)
