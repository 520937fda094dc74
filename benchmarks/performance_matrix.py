"""Throughput of silodem and LAMMPS on the benchmark silo over N, threads and MPI ranks.

    python benchmarks/performance_matrix.py [--out docs/performance.json] [--quick]
        [--passes 3]
    python benchmarks/performance_matrix.py --scaling [--passes 3] [--out docs/scaling.json]
        [--settle 3000] [--steps 1000]

Each row runs `silodem bench --json [--lammps]` in a fresh process (so compilation and memory are
per row).  Steps per size are chosen so a row takes minutes, not hours; both codes always run the
same deck with the same SETTLE and STEPS.  The plot goes next to the JSON (.png).

With ``--passes P`` the whole sweep runs P times, one pass after the other, and each code's
best (highest) throughput per N and thread count is kept, the ratio taken between the two
bests; every pass's figures stay in the row (``passes``).  This 2-core VM lends its second
core elsewhere now and then, which costs a short run (990 grains: a step of 35 us) up to a
third of its speed, for either code; the best of a few passes is what each code can do.

``--scaling`` measures the cost per particle-step against N on 1, 3, 10, 30 and 100 copies of
one silo (NX = 32, NY = 200) side by side, so that every N is in the same flow state: with
NY = 2 NX a tall column is still mostly falling, and a silo made wider with one outlet has a
smaller share of flowing grains; both flatter large N.  Each row also gives the cost without
the neighbour-list builds and their number.  After the default 3000 settling steps most grains
still fall (8 % of the candidates touch); ``--settle 10000`` measures the packed, discharging
silo (72 % touch), where each step costs two to three times as much.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

#       N,        settle, steps
PLAN = [(1_000, 10_000, 2_000), (10_000, 10_000, 2_000), (31_700, 10_000, 2_000),
        (100_000, 3_000, 500), (300_000, 1_500, 200), (1_000_000, 600, 100)]


def best_of(runs: list[dict]) -> dict:
    """One row from several passes of the same N and thread count: silodem's fastest pass,
    with LAMMPS's fastest pass (if run) and their ratio, and every pass's two figures."""
    best = dict(max(runs, key=lambda r: r["particle_steps_per_s"]))
    best["passes"] = [{"silodem": r["particle_steps_per_s"],
                       "lammps": r.get("lammps", {}).get("particle_steps_per_s")}
                      for r in runs]
    lam = [r["lammps"] for r in runs if "lammps" in r]
    if lam:
        best["lammps"] = max(lam, key=lambda r: r["particle_steps_per_s"])
        best["ratio_vs_lammps"] = (best["particle_steps_per_s"]
                                   / best["lammps"]["particle_steps_per_s"])
    return best


def row(n: int, threads: int, settle: int, steps: int, lammps: bool) -> dict:
    cmd = [sys.executable, "-m", "silodem", "bench", "--n", str(n), "--threads", str(threads),
           "--settle", str(settle), "--steps", str(steps), "--json"]
    if lammps:
        cmd.append("--lammps")
    out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    return json.loads(out)


# copies of one silo (NX = 32, NY = 200: 10,144 grains) side by side, each with its own radii
# (``bench.build``): N from 1e4 to 1e6, and every silo does the same kind and amount of work
# at every N, so the cost per particle-step shows what N alone costs (caches, memory), not a
# different flow state (a wider silo with one outlet has a smaller share of flowing grains)
SCALING_COPIES = [1, 3, 10, 30, 100]
SCALING_N, SCALING_ROWS, SCALING_SETTLE, SCALING_STEPS = 10_000, 200, 3_000, 1_000


def scaling_row(copies: int, threads: int, settle: int = SCALING_SETTLE,
                steps: int = SCALING_STEPS) -> dict:
    code = ("import json, dataclasses; from silodem.bench import run_silodem; "
            f"r = run_silodem({SCALING_N}, {threads}, {steps}, {settle}, "
            f"rows={SCALING_ROWS}, copies={copies}); print(json.dumps(dataclasses.asdict(r)))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    return json.loads(out)


def scaling(out: Path, threads_list: list[int], passes: int = 1, settle: int = SCALING_SETTLE,
            steps: int = SCALING_STEPS) -> None:
    """``passes`` sweeps over N, one after the other (so a slow spell of the machine hits one
    pass, not one N); then the best (lowest) cost per N and thread count, and its spread."""
    rows = []
    for pass_ in range(1, passes + 1):
        for copies in SCALING_COPIES:
            for threads in threads_list:
                r = scaling_row(copies, threads, settle, steps)
                r["ns_per_particle_step"] = 1e9 * threads / r["particle_steps_per_s"]
                r["settle"], r["ny"], r["pass"] = settle, SCALING_ROWS, pass_
                r["copies"] = copies
                r["ns_without_builds"] = (1e9 * threads * (r["seconds"] - r["build_seconds"])
                                          / (r["n"] * r["steps"]))
                rows.append(r)
                print(f"pass {pass_} N={r['n']:8d} ({copies} x NX={r['nx']}, NY={r['ny']}) "
                      f"threads={threads} {r['particle_steps_per_s'] / 1e6:7.2f} M/s  "
                      f"{r['ns_per_particle_step']:6.1f} core-ns per particle-step "
                      f"({r['ns_without_builds']:5.1f} without list builds, "
                      f"{r['list_builds']} builds)  "
                      f"mem {r['peak_memory_bytes'] / 1e6:6.0f} MB", flush=True)
                out.write_text(json.dumps(rows, indent=1))
    for threads in threads_list:
        best = {}
        for r in rows:
            if r["threads"] == threads:
                best[r["n"]] = min(best.get(r["n"], float("inf")), r["ns_per_particle_step"])
        costs = list(best.values())
        print(f"threads={threads} best of {passes}: "
              + ", ".join(f"{n}: {c:.1f}" for n, c in best.items())
              + f" core-ns; largest / smallest = {max(costs) / min(costs):.2f}")


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 4.2), dpi=120)
    for threads, style in ((1, "-o"), (2, "-s")):
        sel = [r for r in rows if r["threads"] == threads]
        if not sel:
            continue
        ax.plot([r["n"] for r in sel], [r["particle_steps_per_s"] / 1e6 for r in sel], style,
                label=f"silodem, {threads} thread{'s' * (threads > 1)}")
        lam = [r for r in sel if "lammps" in r]
        ax.plot([r["n"] for r in lam], [r["lammps"]["particle_steps_per_s"] / 1e6 for r in lam],
                style.replace("-", "--"), mfc="none",
                label=f"LAMMPS, {threads} rank{'s' * (threads > 1)}")
    ax.set_xscale("log")
    ax.set_xlabel("grains N")
    ax.set_ylabel("M particle-steps / s")
    ax.set_title("benchmark silo (shared/bench/lammps-silo2d.in)", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="docs/performance.json")
    ap.add_argument("--quick", action="store_true", help="only N <= 31,700")
    ap.add_argument("--max-lammps-n", type=int, default=1_000_000)
    ap.add_argument("--threads", default="1,2", help="comma-separated thread/rank counts")
    ap.add_argument("--scaling", action="store_true",
                    help="cost per particle-step against N at a fixed column height")
    ap.add_argument("--passes", type=int, default=1,
                    help="sweeps over N; the best of them is kept")
    ap.add_argument("--settle", type=int, default=SCALING_SETTLE,
                    help="--scaling: settling steps before the timed ones")
    ap.add_argument("--steps", type=int, default=SCALING_STEPS, help="--scaling: timed steps")
    args = ap.parse_args()
    if args.scaling:
        scaling(Path(args.out), [int(t) for t in args.threads.split(",")], args.passes,
                args.settle, args.steps)
        return
    runs: dict[tuple[int, int], list[dict]] = {}
    rows: list[dict] = []
    for pass_ in range(1, args.passes + 1):
        for n, settle, steps in PLAN:
            if args.quick and n > 31_700:
                break
            for threads in [int(t) for t in args.threads.split(",")]:
                r = row(n, threads, settle, steps, lammps=n <= args.max_lammps_n)
                r["settle"] = settle
                runs.setdefault((n, threads), []).append(r)
                lam = r.get("lammps", {}).get("particle_steps_per_s")
                print(f"pass {pass_} N={r['n']:8d} threads={threads} silodem "
                      f"{r['particle_steps_per_s'] / 1e6:7.2f} M/s  mem "
                      f"{r['peak_memory_bytes'] / 1e6:6.0f} MB"
                      + (f"  LAMMPS {lam / 1e6:7.2f} M/s  ratio {r['ratio_vs_lammps']:.2f}"
                         if lam else ""), flush=True)
                rows = [best_of(v) for v in runs.values()]
                Path(args.out).write_text(json.dumps(rows, indent=1))
    for r in rows:
        lam = r.get("lammps", {}).get("particle_steps_per_s")
        print(f"best of {len(r['passes'])}: N={r['n']:8d} threads={r['threads']} silodem "
              f"{r['particle_steps_per_s'] / 1e6:7.2f} M/s"
              + (f"  LAMMPS {lam / 1e6:7.2f} M/s  ratio {r['ratio_vs_lammps']:.2f}"
                 if lam else ""))
    plot(rows, Path(args.out).with_suffix(".png"))


if __name__ == "__main__":
    main()
