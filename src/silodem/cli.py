"""The ``silodem`` command line.

Every bad input (file, scenario, ``--set``, option value, usage) ends in exactly one line on
stderr and exit code 2, never a traceback: see :func:`main`.
"""

from __future__ import annotations

import importlib
import math
import os
import signal
import sys
import threading
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from silodem.errors import InputError, RunInterrupted, Terminated, UnstableRunError, one_line
from silodem.scenario_files import (
    DEFAULT_SCENARIO,
    config_to_toml,
    list_scenarios,
    load_config,
    quick_variant,
)

app = typer.Typer(
    name="silodem",
    help=(
        "Simulate the filling and discharge of 2D silos with the Discrete Element Method. "
        "Start with 'silodem scenarios' to see the ready-made cases, 'silodem show NAME' to "
        "read every value of one, and 'silodem run' to run one (paper-case2 by default)."
    ),
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
    context_settings={"help_option_names": ["-h", "--help"]},
)

SourceArg = Annotated[
    str,
    typer.Argument(
        metavar="[SCENARIO|FILE.toml]",
        help="An embedded scenario name (see 'silodem scenarios') or the path of a TOML "
        "config file.",
        show_default=True,
    ),
]
SetOpt = Annotated[
    list[str] | None,
    typer.Option(
        "--set",
        "-s",
        metavar="KEY=VALUE",
        help="Override one config value, e.g. --set material.kn=2e7 or "
        "--set silo.kind=flat. KEY is the dotted path of 'silodem show'; VALUE is read as "
        'TOML (number, true/false, "text"). Repeat for several values.',
        show_default=False,
    ),
]
QuickOpt = Annotated[
    bool,
    typer.Option(
        "--quick",
        help="Shrink the case to a small silo (cell and walls x 0.6, about a third of the "
        "grains, shorter time limits) that runs in well under a minute: a first try.",
    ),
]


def _check_threads(threads: int | None) -> None:
    from silodem.run import check_threads

    check_threads(threads, "--threads")


def _config(source: str, sets: list[str] | None, quick: bool):
    cfg = load_config(source, sets or [])
    return quick_variant(cfg) if quick else cfg


def _given(ctx: typer.Context, name: str) -> bool:
    """True when the parameter ``name`` came from the command line (not its default)."""
    source = ctx.get_parameter_source(name)
    return source is not None and source.name != "DEFAULT"


def _check_out(out: Path) -> None:
    from silodem.run import check_out

    check_out(out, "--out")


def _resume(ctx: typer.Context, folder: Path, threads: int | None) -> None:
    given = [flag for name, flag in (("source", "SCENARIO|FILE"), ("sets", "--set"),
                                     ("quick", "--quick"), ("out", "--out"))
             if _given(ctx, name)]
    if given:
        raise InputError(f"--resume continues a run with the config saved in its checkpoint: "
                         f"give no {', '.join(given)} with it")
    if folder.exists() and not folder.is_dir():
        raise InputError(f"--resume {folder} is a file; give the results folder of the run")
    from silodem.run import resume_simulation  # imports numba: only when running

    console = Console()
    console.print(f"silodem: resuming the run in {folder}", markup=False, highlight=False,
                  soft_wrap=True)
    summary = resume_simulation(folder, threads=threads, progress=True)
    for line in summary.lines():
        console.print(line, markup=False, highlight=False, soft_wrap=True)


@app.command()
def run(
    ctx: typer.Context,
    source: SourceArg = DEFAULT_SCENARIO,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            "-o",
            metavar="DIR",
            help="Folder for the results (config, data, plots). Default: runs/<config name>.",
            show_default=False,
        ),
    ] = None,
    sets: SetOpt = None,
    threads: Annotated[
        int | None,
        typer.Option(
            "--threads",
            "-t",
            metavar="N",
            help="Number of CPU threads for the compiled kernels (1 to the number numba "
            "allows). Default: numba's default, all cores.",
            show_default=False,
        ),
    ] = None,
    quick: QuickOpt = False,
    resume: Annotated[
        Path | None,
        typer.Option(
            "--resume",
            metavar="DIR",
            help="Continue the interrupted run whose results folder is DIR from its "
            "checkpoint.h5, with the config saved there (give no SCENARIO, --set, --quick or "
            "--out). It ends exactly as an uninterrupted run would.",
            show_default=False,
        ),
    ] = None,
) -> None:
    """Fill a silo with grains, let them settle, then open the outlet and discharge it.

    Writes the results into a folder and prints a summary. Examples:

      silodem run                       (the paper's hopper case, paper-case2)

      silodem run paper-case2 --quick   (the hopper case, small and fast)

      silodem run my.toml --set fill.n_particles=300 --out runs/test

      silodem run --resume runs/test    (continue a run stopped by Ctrl-C or a crash)

    Checkpoints are saved while it runs; Ctrl-C (SIGINT) or SIGTERM saves one and stops.
    Exit codes: 0 done, 2 bad input, 3 unstable run stopped, 130/143 stopped by SIGINT/SIGTERM.
    """
    _check_threads(threads)
    if resume is not None:
        _resume(ctx, resume, threads)
        return
    from silodem.study.spec import study_text

    if study_text(source) is not None:
        raise InputError(f"{source} is a study (a grid of runs): run it with 'silodem sweep "
                         f"{source}'")
    cfg = _config(source, sets, quick)
    out_dir = out if out is not None else Path("runs") / cfg.name
    from silodem.run import run_simulation  # imports numba: only when running
    from silodem.silo.checks import check_numbers

    check_numbers(cfg)  # values that make no run together: refused before any folder is made
    _check_out(out_dir)

    console = Console()
    console.print(
        f"silodem: running '{cfg.name}' -> {out_dir}", markup=False, highlight=False, soft_wrap=True
    )
    summary = run_simulation(cfg, out_dir, threads=threads, progress=True)
    for line in summary.lines():
        console.print(line, markup=False, highlight=False, soft_wrap=True)


@app.command()
def scenarios() -> None:
    """List the ready-made scenarios shipped with silodem."""
    items = list_scenarios()
    width = max((len(name) for name, _ in items), default=0)
    for name, description in items:
        typer.echo(f"{name:<{width}}  {description}")
    typer.echo("")
    typer.echo("See all values of one: silodem show NAME    Run one: silodem run NAME")


@app.command()
def show(
    source: SourceArg = DEFAULT_SCENARIO,
    sets: SetOpt = None,
    quick: QuickOpt = False,
) -> None:
    """Print the complete config of a scenario or file as TOML, every default included.
    A study (paper-study, or a study file) is printed as it is written.

    Save it to start your own case:

      silodem show paper-case2 > my.toml   (edit my.toml, then: silodem run my.toml)

      silodem show paper-study > my-study.toml   (then: silodem sweep my-study.toml)
    """
    from silodem.study.spec import study_text

    text = study_text(source)
    if text is not None:
        if sets or quick:
            raise InputError(f"{source} is a study: --set and --quick apply to scenarios (put "
                             "fixed values in the study's [set] table; 'silodem sweep --quick' "
                             "shrinks every run)")
        sys.stdout.write(text if text.endswith("\n") else text + "\n")
        return
    cfg = _config(source, sets, quick)
    sys.stdout.write(config_to_toml(cfg))


@app.command()
def plot(
    run_dir: Annotated[
        Path,
        typer.Argument(metavar="DIR", help="The results folder of a run (silodem run --out DIR).",
                       show_default=False),
    ],
) -> None:
    """Re-draw every figure of a run from DIR/results.h5 (nothing is re-run) and write
    DIR/report.html: one page with the figures, the key numbers and the config, to open in a
    browser. Figures also go to DIR/figures/*.png, and settled.png and final.png are drawn
    again (and DIR/vtk/fields_*.vtu, where the run wrote VTK files). Example:

      silodem plot runs/paper-case2
    """
    from silodem.output import write_views  # matplotlib, scipy: only when plotting
    from silodem.report import write_report

    try:
        path = write_report(run_dir)
        write_views(run_dir)
    except (ValueError, IndexError, KeyError, TypeError, AttributeError) as exc:
        # what numbers of the wrong shape or kind raise in the figures (LinAlgError is a
        # ValueError); a disk or memory error stays what it is
        raise InputError(f"{run_dir}: its results.h5 could not be drawn "
                         f"({type(exc).__name__}: {one_line(exc)})") from None
    Console().print(f"report: {path}", markup=False, highlight=False, soft_wrap=True)


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

    Exit codes: 0 every run finished, 1 some runs failed (listed), 2 bad input.
    """
    from silodem.study import expand, load_study, run_study
    from silodem.study.execute import check_workers, default_workers

    check_workers(workers, "--workers")
    if scheduler is not None and not scheduler.strip():
        raise InputError("--scheduler needs an address, e.g. tcp://127.0.0.1:8786")

    loaded = load_study(study)
    planned = len(loaded.spec.seeds) * math.prod(len(v) for v in loaded.spec.grid.values())
    if planned >= PLAN_NOTICE_RUNS:  # each run's config is built and checked: ~3 ms a run
        Console(stderr=True).print(f"silodem: checking the {planned} runs of the study "
                                   f"(about {planned * 3e-3:.0f} s)...", markup=False,
                                   highlight=False, soft_wrap=True)
    plan = expand(loaded, quick=quick)
    out_dir = out if out is not None else Path("studies") / (plan.name + ("-quick" if quick
                                                                           else ""))
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(f"--out {out_dir} is a file, not a folder")
    where = (f"the Dask scheduler at {scheduler}" if scheduler is not None else
             f"a local cluster of {workers or default_workers()} single-threaded workers")
    console = Console()

    def say(text: str) -> None:
        console.print(text, markup=False, highlight=False, soft_wrap=True)

    say(f"silodem: study '{plan.name}'{' (--quick)' if quick else ''}: {len(plan.runs)} runs "
        f"-> {out_dir}; those not finished yet run on {where}")
    outcome = run_study(plan, out_dir, scheduler=scheduler, workers=workers, progress=True)
    say(f"{outcome.computed} computed, {outcome.skipped} already finished, "
        f"{len(outcome.failed)} failed, in {outcome.wall_s:.1f} s")
    say(f"table: {outcome.table_path}")
    say(f"report: {outcome.report_path}")
    if outcome.failed:
        first_id, first_error = next(iter(outcome.failed.items()))
        _error(f"error: {len(outcome.failed)} of {len(plan.runs)} runs failed (first: "
               f"{first_id}: {first_error}); see {out_dir / 'report.html'}; run the command "
               "again to retry them", 1)


_MAX_BENCH_STEPS = 10**12  # as silo.checks.MAX_STEPS; a 64-bit step count beyond is an overflow


@app.command()
def bench(
    n: Annotated[int, typer.Option("--n", help="Number of grains (about; the lattice of the "
                                   "reference deck decides the exact count).")] = 31700,
    threads: Annotated[int, typer.Option("--threads", help="CPU threads of the kernels "
                                         "(and MPI ranks of LAMMPS with --lammps).")] = 1,
    steps: Annotated[int, typer.Option("--steps", help="Timed steps.")] = 2000,
    settle: Annotated[int, typer.Option("--settle", help="Untimed steps first (compilation, "
                                        "fall, start of the flow), as the deck's SETTLE.")] = 10000,
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
        raise InputError(f"--n must be between 10 and 20000000 grains, got {n}")
    if not (1 <= steps <= _MAX_BENCH_STEPS and 0 <= settle <= _MAX_BENCH_STEPS):
        raise InputError(f"--steps must be from 1 and --settle from 0, each to "
                         f"{_MAX_BENCH_STEPS:.0e}; got {steps} and {settle}")
    _check_threads(threads)
    from silodem import bench as benchmark

    results = benchmark.bench(n, threads, steps, settle, lammps)
    if as_json:
        print(benchmark.as_json(results))
        return
    console = Console()
    for r in results:
        console.print(r.line(), markup=False, highlight=False)
    console.print(f"peak memory {results[0].peak_memory_bytes / 1e6:.0f} MB "
                  f"({results[0].peak_memory_bytes / results[0].n:.0f} bytes per grain, "
                  "whole process)", markup=False, highlight=False)
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
def animate(
    run_dir: Annotated[
        Path,
        typer.Argument(metavar="DIR", help="The results folder of a run (silodem run --out DIR).",
                       show_default=False),
    ],
    color: Annotated[
        str,
        typer.Option("--color", "-c", metavar="velocity|force|coordination",
                     help="Colour the grains by speed, by the sum of their contact normal "
                     "forces, or by their number of contacts."),
    ] = "velocity",
    fmt: Annotated[
        str | None,
        typer.Option("--format", "-f", metavar="mp4|gif",
                     help="Video format. Default: from --out's suffix, else mp4.",
                     show_default=False),
    ] = None,
    fps: Annotated[
        int, typer.Option("--fps", metavar="N", help="Frames per second of the video (1-60).")
    ] = 10,
    out: Annotated[
        Path | None,
        typer.Option("--out", "-o", metavar="FILE",
                     help="Where to write the video. Default: DIR/animation.mp4 (or .gif).",
                     show_default=False),
    ] = None,
) -> None:
    """Make a video of a run's filling and discharge from its saved frames.

    Grains are drawn to scale and coloured, the force chains drawn with a width that grows with
    the normal force. One video frame per saved frame (output.frame_interval). Examples:

      silodem animate runs/paper-case2

      silodem animate runs/test --color force --format gif --fps 15
    """
    from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeElapsedColumn
    from rich.progress import Progress as Bar

    from silodem.viz.animate import plan_animation, render_animation  # matplotlib: when used

    plan = plan_animation(run_dir, out, color=color, fmt=fmt, fps=fps)
    with Bar(TextColumn("rendering"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
             console=Console(stderr=True), transient=False) as bar:
        task = bar.add_task("frames", total=len(plan.frames))
        result = render_animation(plan, lambda done, _: bar.update(task, completed=done))
    Console().print(f"animation: {result.frames} frames ({result.width}x{result.height} px, "
                    f"{fps} fps) in {result.seconds:.1f} s -> {result.path}", markup=False,
                    highlight=False, soft_wrap=True)


@app.command()
def validate(
    quick: Annotated[
        bool,
        typer.Option("--quick", help="Only the particle-impact cases (linear, Chung & Ooi's "
                     "tests, Hertz-Mindlin), the settled column and the trajectories against "
                     "LAMMPS (the subset CI runs; well under a minute). The full suite adds the "
                     "Janssen and Beverloo silos (15-20 minutes on two cores)."),
    ] = False,
    cases: Annotated[
        list[str] | None,
        typer.Option("--case", metavar="NAME", help="Run only this family of cases "
                     "(repeatable): impacts, chung_ooi, hertz_mindlin, statics, lammps, "
                     "janssen (about 4 minutes), beverloo (about 15)."),
    ] = None,
    as_json: Annotated[
        bool,
        typer.Option("--json", help="Print the records as one JSON list (case, quantity, "
                     "expected, got, tolerance, tolerance_kind, unit, pass, note) and nothing "
                     "else on stdout; progress goes to stderr."),
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
    DIR. Exit code 0 when every check passes, 1 when one fails. Examples:

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
    _check_out(out)  # after the checks: a refused command makes no folder
    err = Console(stderr=True)
    result = run_validation(quick=quick, out=out, only=cases or None,  # imports numba
                            progress=lambda msg: err.print(msg, markup=False, highlight=False))
    if as_json:
        sys.stdout.write(result.to_json() + "\n")
    else:
        print_table(result, Console(width=None if sys.stdout.isatty() else 160))
    if not result.passed:
        raise typer.Exit(code=1)


def _error(message: str, code: int = 2) -> None:
    sys.stderr.write(one_line(message) + "\n")
    sys.stderr.flush()
    raise SystemExit(code)


def _click_types(name: str) -> tuple[type[BaseException], ...]:
    """Class ``name`` of click's exceptions, from click and from typer's vendored copy."""
    found = []
    for module in ("typer._click.exceptions", "click.exceptions"):
        try:
            cls = getattr(importlib.import_module(module), name, None)
        except ImportError:
            continue
        if isinstance(cls, type):
            found.append(cls)
    return tuple(found)


def _stop_on_sigterm():
    """SIGTERM raises ``Terminated`` (a KeyboardInterrupt) instead of killing the process
    silently, so it ends like Ctrl-C: one line, exit code 143, temporary files removed.  A run
    installs its own handlers while it goes (safety.RunGuard).  Returns the handler it
    replaced (None outside the main thread, where signals cannot be set)."""
    if threading.current_thread() is not threading.main_thread():
        return None

    def terminated(signum, frame):
        _SIGTERM_SEEN.append(signum)  # click turns the exception into a plain Abort / 130
        raise Terminated

    _SIGTERM_SEEN.clear()
    return signal.signal(signal.SIGTERM, terminated)


_SIGTERM_SEEN: list[int] = []


def _interrupted() -> None:
    """One line and exit code 143 after a SIGTERM, 130 after Ctrl-C."""
    if _SIGTERM_SEEN:
        _error("interrupted (SIGTERM)", 143)
    _error("interrupted", 130)


PLAN_NOTICE_RUNS = 1000  # a study this large says so before it plans (seconds of checks)
PATH_FLAGS = ("--out", "-o", "--resume")  # options that take a path
FOLDER_COMMANDS = ("plot", "animate")  # commands whose argument is a results folder


def _empty_path(args: list[str]) -> str | None:
    """The option or argument given an empty path, if any: click reads '' as the current
    folder, so `--out ''` (an unset shell variable) would write, and first clear, a run's
    files in the working folder."""
    for k, arg in enumerate(args):
        if arg in PATH_FLAGS and k + 1 < len(args) and not args[k + 1].strip():
            return arg
        if arg.startswith(tuple(f"{flag}=" for flag in PATH_FLAGS)) and \
                not arg.partition("=")[2].strip():
            return arg.partition("=")[0]
    if args and args[0] in FOLDER_COMMANDS:  # their options all take a value: DIR is the
        for k in range(1, len(args)):       # argument that follows no option
            if not args[k].strip() and not args[k - 1].startswith("-"):
                return f"{args[0]} DIR"
    return None


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the app; bad input -> one line on stderr and exit code 2."""
    args = list(sys.argv[1:] if argv is None else argv)
    numba_threads = os.environ.get("NUMBA_NUM_THREADS", "1").strip() or "1"
    if not numba_threads.isdigit() or int(numba_threads) < 1:
        _error(f"error: NUMBA_NUM_THREADS={numba_threads!r}: must be a whole number of threads "
               "from 1 (or unset)")
    empty = _empty_path(args)
    if empty is not None:
        _error(f"error: {empty}: an empty path (give a folder or file name; '.' for this one)")
    command = typer.main.get_command(app)
    no_args = _click_types("NoArgsIsHelpError")
    usage = _click_types("UsageError")
    other = _click_types("ClickException")
    abort = _click_types("Abort") + (typer.Abort, KeyboardInterrupt)
    previous = _stop_on_sigterm()
    try:
        result = command.main(args=args, prog_name="silodem", standalone_mode=False)
    except InputError as exc:
        message = str(exc)
        _error(message if message.startswith("config error:") else f"error: {message}")
    except UnstableRunError as exc:
        _error(f"run stopped: {exc}", 3)
    except RunInterrupted as exc:
        _error(f"interrupted: {exc}", exc.exit_code)
    except no_args as exc:
        sys.stdout.write(exc.ctx.get_help() + "\n")
        raise SystemExit(0) from None
    except usage as exc:
        hint = f" (see '{exc.ctx.command_path} --help')" if exc.ctx is not None else ""
        _error(f"usage error: {exc.format_message()}{hint}", 2)
    except other as exc:
        _error(f"error: {exc.format_message()}", getattr(exc, "exit_code", 1))
    except abort:
        _interrupted()
    except OSError as exc:  # a path given that the system refuses (name too long, ...)
        where = f": {exc.filename}" if exc.filename else ""
        _error(f"error: {exc.strerror or exc}{where}", 2)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    if result == 130:  # typer turns a KeyboardInterrupt that no command caught into 130
        _interrupted()
    raise SystemExit(result if isinstance(result, int) else 0)
