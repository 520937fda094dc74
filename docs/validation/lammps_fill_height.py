"""The fill-height dependence of the discharge rate in silodem and in LAMMPS, on the same silo
with the same contact law (docs/validation.md, section 5, seventh and eighth sessions).

    python docs/validation/lammps_fill_height.py [NY ...] [--seeds S ...] [--tension]
                                             # default: NY = 40 80 160, seed 12345

The silo is the one of ``silodem bench`` and its LAMMPS deck (``benchmarks/lammps-silo2d.in``):
paper case 2 (k_n = k_s = 5e6 N/m, grain friction tan 25 deg, wall friction tan 24 deg,
e = 0.5), d = 0.18-0.22 m, an outlet of D = 1.2 m = 6 d, NX = 20 lattice columns (B = 4.4 m =
22 d), NY lattice rows of grains, dt = 2e-4 s; grains leaving through the outlet re-enter at
the top (periodic y), so the fill height stays what NY makes it.  The two codes run the same
law here: the deck is run with gamma_t = 0 and dampflag 0 (the paper's model has no shear
dashpot; the shipped deck has LAMMPS's default gamma_t = gamma_n / 2) and with
``limit_damping``, which clips the damped normal force at 0 and so sets the Coulomb cap to 0
where it would pull, as silodem's default law does (docs/validation/lammps_trajectory.py
checks grain by grain that the two codes then follow the same trajectories).  With
``--tension`` both keep a pulling normal force; LAMMPS then caps the shear force at
mu |F_n| while silodem caps it at 0, so the laws differ in that phase of a contact.

Counted: the grains that have left, against time (LAMMPS: minus the sum of the periodic image
counts iy; silodem: the grains moved to the top at each list build, ``bench.reenter``), sampled
every 0.2 s over ``SECONDS`` after ``SETTLE`` steps; the steady rate is the slope from 10 % to
100 % of the count with its batch-means error (``measure.discharge.steady_rate``).  Needs
``lmp`` (Debian package ``lammps``).  Prints one JSON line per NY and code."""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import re
import subprocess
import tempfile
from pathlib import Path

import numba
import numpy as np

from silodem import bench
from silodem.measure.discharge import steady_rate

NX = 20
SETTLE = 25_000  # steps: fall, settle, start of the flow (5 s)
SECONDS = 30.0  # of steady discharge measured
SAMPLE = 1000  # steps between samples (0.2 s)
# LAMMPS damps a contact with m_eff gamma_n v_n, silodem with 2 zeta sqrt(k m_eff) v_n: the same
# for two 26.2 kg disks at gamma_n = 267 1/s (the deck's value), and for a disk on a wall
# (m_eff = m) at gamma_n = 2 zeta sqrt(k / m) = 188 1/s (zeta = 0.2155 for e = 0.5,
# contact.damping_ratio_from_restitution; m = 26.2 kg for d = 0.2 m)
WALL_GAMMA = 2 * 0.2155 * (5.0e6 / 26.2) ** 0.5


def _swap(deck: str, old: str, new: str) -> str:
    """``deck`` with ``old`` replaced; an error if the deck no longer holds ``old`` (a silent
    no-op would compare the two codes on different laws)."""
    if old not in deck:
        raise ValueError(f"the benchmark deck has no {old!r}")
    return deck.replace(old, new)


def lammps_deck(seed: int, tension: bool) -> str:
    """The benchmark deck with the shear dashpot off, disk masses, the wall damping of
    silodem, the diameters drawn with ``seed`` and a running count of the wraps; without
    ``tension`` the damped normal force is clipped at 0 (``limit_damping``), and with it the
    Coulomb cap, as in silodem's default law."""
    limit = "" if tension else " limit_damping"
    deck = bench.deck_path().read_text()
    deck = _swap(deck, "random(0,1,12345)", f"random(0,1,{seed})")
    deck = _swap(deck, "267.0 NULL 0.466 1", f"267.0 0.0 0.466 0{limit}")
    deck = _swap(deck, "267.0 NULL 0.445 1", f"{WALL_GAMMA:.1f} 0.0 0.445 0{limit}")
    deck = _swap(deck, "set             group all density 835",
                 "set             group all density/disc 835")
    deck = re.sub(r"^thermo_style.*$", "compute im all property/atom iy\n"
                  "compute wraps all reduce sum c_im\n"
                  "thermo_style    custom step c_wraps", deck, flags=re.MULTILINE)
    return re.sub(r"^thermo\s+\d+", f"thermo          {SAMPLE}", deck, flags=re.MULTILINE)


def run_lammps(ny: int, seed: int, tension: bool) -> subprocess.Popen:
    tmp = Path(tempfile.mkdtemp())
    (tmp / "deck.in").write_text(lammps_deck(seed, tension))
    steps = round(SECONDS / bench.DT)
    lmp = bench.lammps_executable()
    if lmp is None:
        raise SystemExit("LAMMPS not found: install Debian's package (apt-get install lammps)")
    return subprocess.Popen(
        [lmp, "-in", "deck.in", "-var", "NX", str(NX), "-var", "NY", str(ny), "-var",
         "SETTLE", str(SETTLE), "-var", "STEPS", str(steps), "-log", "none", "-echo", "none"],
        cwd=tmp, stdout=subprocess.PIPE, text=True)


def lammps_counts(proc: subprocess.Popen) -> tuple[np.ndarray, np.ndarray, int]:
    out, _ = proc.communicate()
    rows = []
    for part in out.split("Step")[2:]:  # the timed run's thermo block
        for line in part.splitlines()[1:]:
            f = line.split()
            if len(f) == 2 and f[0].isdigit():
                rows.append((int(f[0]) * bench.DT, -float(f[1])))
    n = int(re.findall(r"with (\d+) atoms", out)[-1])
    t, c = np.array(rows).T
    return t, c - c[0], n


def silodem_counts(ny: int, seed: int, tension: bool) -> tuple[np.ndarray, np.ndarray, int]:
    numba.set_num_threads(1)
    sim, _, top = bench.build(NX, ny, seed=seed)
    sim.law = dataclasses.replace(sim.law, allow_tension=tension)
    passed = [0]

    def reenter(s):
        passed[0] += bench.reenter(s, top)

    sim.before_rebuild.append(reenter)
    sim.run(SETTLE)
    start = passed[0]
    t, c = [], []
    for k in range(round(SECONDS / bench.DT) // SAMPLE + 1):
        if k:
            sim.run(SAMPLE)
        t.append(k * SAMPLE * bench.DT)
        c.append(passed[0] - start)
    return np.array(t), np.array(c, dtype=float), sim.particles.n


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("ny", nargs="*", type=int, default=[40, 80, 160])
    ap.add_argument("--seeds", nargs="+", type=int, default=[12345])
    ap.add_argument("--tension", action="store_true",
                    help="both codes keep the damped normal force when it pulls (LAMMPS then "
                    "still caps the shear force at mu |F_n|, silodem at 0)")
    args = ap.parse_args()
    for ny, seed in itertools.product(args.ny, args.seeds):
        proc = run_lammps(ny, seed, args.tension)  # on the other core while silodem runs here
        results = {"silodem": silodem_counts(ny, seed, args.tension),
                   "lammps": lammps_counts(proc)}
        for code, (t, c, n) in results.items():
            r = steady_rate(t, c, lo=0.1, hi=1.0)
            print(json.dumps({"code": code, "NX": NX, "NY": ny, "seed": seed, "n": n,
                              "grains_per_s": round(r.rate, 3), "err": round(r.err, 3),
                              "passed": int(c[-1]), "seconds": SECONDS,
                              "tension": args.tension}), flush=True)


if __name__ == "__main__":
    main()
