"""What the lanes of ``engine/lanes.py`` are worth: the scaling silo with the step's arrays in
their lanes (``LANE_BYTES`` as built) against all in one lane (``LANE_BYTES = 0``: every array
at one offset within a 4 KB page, as plain numpy arrays of 128 KB or more lie), alternating,
one process per run, 1 thread (docs/performance.md, "Cost per particle-step against N").

    python benchmarks/lanes_ab.py [--copies 1 10 100] [--rounds 3] [--settle 3000]
                                  [--steps 1000]

Prints core-ns per particle-step of each run, with and without the list builds.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

RUN = """
import dataclasses, json
from silodem.engine import lanes
if {lane_bytes} is not None:
    lanes.LANE_BYTES = {lane_bytes}
from silodem.bench import run_silodem
r = dataclasses.asdict(run_silodem(10_000, 1, {steps}, {settle}, rows=200, copies={copies}))
print(json.dumps(r))
"""


def one_run(copies: int, lane_bytes: int | None, settle: int, steps: int) -> dict:
    code = RUN.format(lane_bytes=lane_bytes, steps=steps, settle=settle, copies=copies)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    return json.loads(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--copies", type=int, nargs="+", default=[1, 10, 100])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--settle", type=int, default=3000)
    ap.add_argument("--steps", type=int, default=1000)
    args = ap.parse_args()
    for copies in args.copies:
        for round_ in range(1, args.rounds + 1):
            for name, lane_bytes in (("one lane", 0), ("lanes", None)):
                r = one_run(copies, lane_bytes, args.settle, args.steps)
                ns = 1e9 * r["seconds"] / (r["n"] * r["steps"])
                bare = 1e9 * (r["seconds"] - r["build_seconds"]) / (r["n"] * r["steps"])
                print(f"N={r['n']:8d} round {round_} {name:9s} {ns:6.1f} core-ns per "
                      f"particle-step ({bare:5.1f} without list builds, {r['list_builds']} "
                      "builds)", flush=True)


if __name__ == "__main__":
    main()
