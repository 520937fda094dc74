"""Grain-by-grain comparison of silodem and LAMMPS on the benchmark silo's outlet, with the
options the ``lammps`` case of ``silodem validate`` fixes (``silodem.validate.lammps``, whose
docstring gives the set-up; docs/validation.md, section 6).

    python docs/validation/lammps_trajectory.py [--grains N] [--spacing S] [--steps K]
                                                [--every E] [--seed R] [--radii equal|mixed]
                                                [--tension]

Prints, every E steps, the largest position difference between the two codes [m] and the
lowest grain's height.  ``--radii mixed`` draws radii in 0.09-0.11 m (the damping then differs:
LAMMPS scales it with m_eff, silodem with sqrt(m_eff)); ``--tension`` lets the damped normal
force pull in both codes (LAMMPS then caps the shear force at mu |F_n|, silodem at 0).
Needs ``lmp`` (Debian package ``lammps``)."""

from __future__ import annotations

import argparse

import numpy as np

from silodem import bench
from silodem.validate.lammps import cloud, run_lammps, run_silodem


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--grains", type=int, default=60)
    ap.add_argument("--spacing", type=float, default=0.3)
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--every", type=int, default=250)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--radii", choices=["equal", "mixed"], default="equal")
    ap.add_argument("--tension", action="store_true")
    args = ap.parse_args()
    state = cloud(args.grains, args.spacing, args.seed, args.radii == "mixed")
    ours = run_silodem(state, args.steps, args.every, args.tension)
    theirs = run_lammps(state, args.steps, args.every, args.tension)
    for k, (a, b) in enumerate(zip(ours, theirs)):
        print(f"step {k * args.every:6d}  t = {k * args.every * bench.DT:6.3f} s  "
              f"max |dx| = {np.abs(a - b).max():.3e} m  lowest y = {a[:, 1].min():7.3f} m")


if __name__ == "__main__":
    main()
