"""The commands beyond one run: ``sweep`` (a parametric study on Dask), ``bench`` (particle-steps
per second against LAMMPS) and ``validate`` (the physics against analytic and published
results)."""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from silodem.cli.app import app, check_out, check_threads, fail
from silodem.errors import InputError, short_repr

PLAN_NOTICE_RUNS = 1000  # a study this large says so before it plans (seconds of checks)


@app.command()
def sweep(
    study: Annotated[
        str,
        typer.Argument(metavar="STUDY|FILE.toml",
                       help="An embedded study (paper-study) or a study file (docs/sweeps.md).",
                       show_default=False),
    ],
    out: Annotated[
        Path | None,
        typer.Option("--out", "-o", metavar="DIR",
                     help="Study folder: runs/<id>/ per run, results.csv, report.html. "
                     "Default: studies/<study name> (studies/<name>-quick with --quick).",
                     show_default=False),
    ] = None,
    scheduler: Annotated[
        str | None,
        typer.Option("--scheduler", metavar="ADDRESS",
                     help="Address of a running Dask scheduler, e.g. tcp://10.0.0.5:8786 "
                     "(started with 'dask scheduler'; its workers must see DIR). Default: a "
                     "local cluster on this machine.", show_default=False),
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option("--workers", "-w", metavar="N",
                     help="Local cluster: N single-threaded worker processes (default: one per "
                     "core). With --scheduler: wait until N workers have joined.",
                     show_default=False),
    ] = None,
    quick: Annotated[
        bool,
        typer.Option("--quick", help="Run the small silo of every case (as 'silodem run "
                     "--quick'): a first try of a study in minutes."),
    ] = False,
) -> None:
    """Run a parametric study: every combination of the study's grid, for each seed, on Dask.

    Each run goes into its own folder DIR/runs/<id>/, written completely or not at all; running
    the same command again skips the finished runs, so an interrupted study (Ctrl-C, a crash, a
    dead worker) is resumed by repeating it. A worker that dies mid-run loses nothing: its run
    is done again by another worker. At the end: DIR/results.csv (one row per run) and
    DIR/report.html (the paper's Figs. 7 and 8 for every case, heat maps over the grid).
    Examples:

      silodem sweep paper-study --quick      (16 small runs on this machine)

      silodem sweep my-study.toml --out studies/mine --workers 4

      silodem sweep paper-study --scheduler tcp://127.0.0.1:8786

    Exit codes: 0 every run finished, 1 some runs failed (listed), 2 bad input, 130/143
    stopped by SIGINT/SIGTERM (the finished runs are kept: repeat the command to go on; the
    one line says how many).
    """
    import signal
    import warnings

    from silodem.api import SilodemWarning
    from silodem.errors import RunInterrupted, Terminated
    from silodem.study import expand, load_study, run_study
    from silodem.study.api import REPLACING
    from silodem.study.cluster import (
        check_workers,
        default_workers,
        shutdown_shield,
        workers_phrase,
    )
    from silodem.study.execute import (
        check_study_folder,
        failed_runs_text,
        is_finished,
        other_study_note,
        replaced_study_file,
        stopped_sweep_text,
    )

    check_workers(workers, "--workers", local=scheduler is None)
    if scheduler is not None and not scheduler.strip():
        raise InputError("--scheduler needs an address, e.g. tcp://127.0.0.1:8786")

    loaded = load_study(study)
    planned = len(loaded.spec.seeds) * math.prod(len(v) for v in loaded.spec.grid.values())
    if planned >= PLAN_NOTICE_RUNS:  # each run's config is built and checked: ~3 ms a run
        err = Console(stderr=True, soft_wrap=True)
        err.print(f"silodem: checking the {planned} runs of the study "
                  f"(about {planned * 3e-3:.0f} s)...", markup=False, highlight=False)
    plan = expand(loaded, quick=quick)
    out_dir = out if out is not None else Path("studies") / (plan.name + ("-quick" if quick
                                                                           else ""))
    # a file, or a folder the system will not make, refused before the plan is said; the
    # study's folder itself is made when its runs start (not for a scheduler that never
    # answers)
    check_out(out_dir, make=False)
    check_study_folder(out_dir)  # (before anything is said or written)
    where = (f"the Dask scheduler at {scheduler}" if scheduler is not None else
             f"a local cluster of {workers_phrase(workers or default_workers())}")
    console = Console(soft_wrap=True)

    def say(text: str) -> None:
        console.print(text, markup=False, highlight=False)

    todo = sum(not is_finished(out_dir / "runs" / r.id) for r in plan.runs)
    say(f"silodem: study '{plan.name}'{' (--quick)' if quick else ''}: {len(plan.runs)} runs "
        f"-> {out_dir}; " + (f"the {todo} not finished yet run on {where}" if todo else
                             "all finished already: nothing to run"))
    replacing = other_study_note(plan, out_dir)  # (said once the sweep has replaced it)
    said_replacing: list[str] = []
    shown = warnings.showwarning

    def say_warning(message, category, *args, **kwargs) -> None:
        """The API's warnings said the command line's way as they happen, before the first
        run: that it replaced the study file (said only at the end before: hours later), that
        finished runs were computed by other code."""
        if category is not SilodemWarning:
            shown(message, category, *args, **kwargs)
            return
        replaced = str(message).startswith(REPLACING)
        if replaced:
            said_replacing.append(str(message))
        Console(stderr=True, soft_wrap=True).print(
            f"silodem: {'' if replaced else 'warning: '}{message}", markup=False,
            highlight=False)

    try:
        _quiet_dask_client()  # (imports distributed: a good part of a second)
        with warnings.catch_warnings():
            warnings.showwarning = say_warning  # (silodem.api shows each SilodemWarning)
            outcome = run_study(plan, out_dir, scheduler=scheduler, workers=workers,
                                progress=True)
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM (errors.Terminated); the cluster is
        # closed: count what is kept, say how to go on (a bare 'interrupted' before)
        signum = signal.SIGTERM if isinstance(exc, Terminated) else signal.SIGINT
        with shutdown_shield(stopping=True):
            text = stopped_sweep_text(plan, out_dir, signum)
        raise RunInterrupted(text, signum) from None
    finally:  # replaced, but stopped before it could say so (a scheduler that cannot be
        # reached leaves it be)
        if replacing is not None and not said_replacing and replaced_study_file(plan, out_dir):
            Console(stderr=True, soft_wrap=True).print(replacing, markup=False,
                                                       highlight=False)
    say(f"{outcome.computed} computed, {outcome.skipped} already finished, "
        f"{len(outcome.failed)} failed, in {outcome.wall_s:.1f} s")
    say(f"table: {outcome.table_path}")
    say(f"report: {outcome.report_path}")
    if outcome.undrawn:
        name, error = next(iter(outcome.undrawn.items()))
        say(f"warning: {len(outcome.undrawn)} figure(s) of the report could not be drawn and "
            f"are left out (first: {name}: {error})")
    if outcome.unsummarised:
        first_id, first_error = next(iter(outcome.unsummarised.items()))
        say(f"warning: {len(outcome.unsummarised)} finished run(s) could not be summarised, "
            f"their cells are empty (first: {first_id}: {first_error}); delete the run's "
            "folder and run the command again to redo it")
    if outcome.failed:
        fail(failed_runs_text(outcome.failed, len(plan.runs), out_dir), 1)


def _quiet_dask_client() -> None:
    """Only critical records from Dask's client logger: a lost scheduler printed 'Failed to
    reconnect to scheduler after 10.00 seconds, closing client' with a time stamp in the
    middle of the sweep's lines, while the sweep reports the loss itself (each run it
    cancelled fails naming it, and the command says to run it again)."""
    import logging

    import distributed  # noqa: F401 - it configures its loggers when imported

    logging.getLogger("distributed.client").setLevel(logging.CRITICAL)


# the bench process's resident memory before any grain: Python, numba and LLVM
# (docs/performance.md, "Memory")
BASE_MB = "185-230"
_MAX_BENCH_STEPS = 10**12  # as silo.checks.MAX_STEPS; a 64-bit step count beyond is an overflow


@app.command()
def bench(
    n: Annotated[int, typer.Option("--n", help="Number of grains, 10 to 20,000,000 (about; "
                                   "the lattice of the reference deck decides the exact "
                                   "count).")] = 31700,
    threads: Annotated[int, typer.Option("--threads", help="CPU threads of the kernels "
                                         "(and MPI ranks of LAMMPS with --lammps).")] = 1,
    steps: Annotated[int, typer.Option("--steps", help="Timed steps.")] = 2000,
    settle: Annotated[int, typer.Option("--settle", help="Untimed steps first (compilation, "
                                        "fall, start of the flow), as the deck's SETTLE.")] = 10000,
    rows: Annotated[int | None, typer.Option(
        "--rows", help="The deck's NY (column height: 0.352 NY m; 4 to --n / 4) instead of "
        "NY = 2 NX; the silo is widened to about --n grains. A tall column is still falling "
        "after --settle steps: --rows 200 --settle 20000 times a packed, discharging "
        "3e5-grain silo (docs/performance.md).")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    lammps: Annotated[bool, typer.Option(
        "--lammps",
        help="Also run the same silo with LAMMPS (`lmp`, Debian package lammps) "
        "and print the ratio.",
    )] = False,
) -> None:
    """Measure particle-steps per second on a dense, steadily discharging flat-bottomed silo
    built to match the reference LAMMPS deck (docs/performance.md). Example:

      silodem bench --n 30000 --threads 1 --lammps
    """
    if n < 10 or n > 20_000_000:
        raise InputError(f"--n must be between 10 and 20000000 grains, got {short_repr(n)}")
    if not (1 <= steps <= _MAX_BENCH_STEPS and 1 <= settle <= _MAX_BENCH_STEPS):
        # (--settle 0 timed the kernels' compilation and the first list build)
        raise InputError(f"--steps and --settle must each be from 1 to "
                         f"{_MAX_BENCH_STEPS:.0e} (the kernels compile in the untimed "
                         f"--settle steps); got {short_repr(steps)} and {short_repr(settle)}")
    if rows is not None and not 4 <= rows <= n // 4:
        raise InputError(f"--rows must be from 4 to --n / 4 = {n // 4} (a column at least "
                         f"4 grains wide), got {short_repr(rows)}")
    check_threads(threads)
    from silodem import bench as benchmark

    err = Console(stderr=True, soft_wrap=True)

    def say(text: str) -> None:  # (stderr: --json's stdout holds the JSON alone)
        err.print(f"silodem bench: {text}...", markup=False, highlight=False)

    try:
        results = benchmark.bench(n, threads, steps, settle, lammps, rows=rows, say=say)
    except benchmark.LammpsFailed as exc:  # (a traceback before)
        fail(f"error: {exc}", 1)
    if as_json:
        print(benchmark.as_json(results))
        return
    console = Console(soft_wrap=True)
    for r in results:
        console.print(r.line(), markup=False, highlight=False)
    # (not over n: at 31,700 grains that gave 7,688 bytes per grain, 25 times the state's)
    console.print(f"peak memory {results[0].peak_memory_bytes / 1e6:.0f} MB, whole process "
                  f"(Python, numba and LLVM take about {BASE_MB} MB of it before any grain; "
                  "a grain about 300-400 bytes: docs/performance.md)", markup=False,
                  highlight=False)
    on = benchmark.machine()
    console.print(f"machine: {on['cpu']}, {on['cpus']} CPUs", markup=False, highlight=False)
    if len(results) > 1:
        ratio = results[0].particle_steps_per_s / results[1].particle_steps_per_s
        console.print(f"silodem / LAMMPS = {ratio:.2f}", markup=False, highlight=False)
        if results[1].n != results[0].n:
            # LAMMPS's create_atoms drops lattice sites that lie on the fill region's edge at
            # some NX, NY (its own round-off); the ratio is per particle-step, so still fair
            console.print(f"note: LAMMPS created {results[1].n} grains, silodem "
                          f"{results[0].n}: sites on the fill region's edge round differently",
                          markup=False, highlight=False)


@app.command()
def validate(
    quick: Annotated[
        bool,
        typer.Option("--quick", help="Only the particle-impact cases (linear, Chung & Ooi's "
                     "tests, Hertz-Mindlin), the settled column and the trajectories against "
                     "LAMMPS (the subset CI runs; well under a minute). The full suite adds the "
                     "Janssen and Beverloo silos (10-19 minutes on two cores)."),
    ] = False,
    cases: Annotated[
        list[str] | None,
        typer.Option("--case", metavar="NAME", help="Run only this family of cases "
                     "(repeatable): impacts, chung_ooi, hertz_mindlin, statics, lammps, "
                     "janssen (2-4 minutes), beverloo (about 11)."),
    ] = None,
    as_json: Annotated[
        bool,
        typer.Option("--json", help="Print the records as one JSON list (case, quantity, "
                     "expected, got, tolerance, tolerance_kind, unit, pass, note; a value "
                     "reported, not checked, has tolerance_kind 'info' and tolerance null, "
                     "and expected null unless given for comparison) and nothing else on "
                     "stdout; progress goes to stderr."),
    ] = False,
    out: Annotated[
        Path,
        typer.Option("--out", "-o", metavar="DIR", help="Folder for the figures (PNG)."),
    ] = Path("validation"),
) -> None:
    """Check the physics against analytic solutions and published results: normal impacts
    (spring-dashpot solution, Schwager & Poeschel 2007), Chung & Ooi (2011) benchmark tests
    4-8 adapted to disks, the Hertz-Mindlin law against Hertz and Mindlin, a settled column
    (walls carry the weight), grain trajectories against LAMMPS (where lmp is installed),
    and with the full suite Janssen's wall pressures and Beverloo's discharge rates
    (docs/validation.md).

    Prints a table (case, quantity, expected, got, tolerance, pass) and writes figures into
    DIR. Exit codes: 0 every check passed, 1 a check failed, 2 bad input, 130 / 143
    interrupted (Ctrl-C / SIGTERM). Examples:

      silodem validate --quick

      silodem validate --case janssen --case hertz_mindlin

      silodem validate --out validation --json > validation.json
    """
    from silodem.validate.runner import check_cases, print_table, run_validation

    if cases and quick:
        raise InputError("give --quick or --case, not both (--case runs the named families "
                         "whole)")
    try:
        check_cases(cases or ())
    except ValueError as err:
        raise InputError(f"--case: {err}") from None
    check_out(out)  # after the checks: a refused command makes no folder
    err = Console(stderr=True, soft_wrap=True)
    result = run_validation(quick=quick, out=out, only=cases or None,  # imports numba
                            progress=lambda msg: err.print(msg, markup=False, highlight=False))
    if as_json:
        sys.stdout.write(result.to_json() + "\n")
    else:
        print_table(result, Console(width=None if sys.stdout.isatty() else 160))
    if not result.passed:
        raise typer.Exit(code=1)
