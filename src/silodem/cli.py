"""The ``silodem`` command line.

Every bad input (file, scenario, ``--set``, option value, usage) ends in exactly one line on
stderr and exit code 2, never a traceback: see :func:`main`.
"""

from __future__ import annotations

import importlib
import os
import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from silodem.errors import InputError, RunInterrupted, UnstableRunError, one_line
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


def _numba_max_threads() -> int:
    import numba

    return int(numba.config.NUMBA_NUM_THREADS)


def _check_threads(threads: int | None) -> None:
    if threads is None:
        return
    top = _numba_max_threads()
    if not 1 <= threads <= top:
        raise InputError(
            f"--threads must be an integer from 1 to {top} (the number of threads numba may "
            f"use here, NUMBA_NUM_THREADS); got {threads}"
        )


def _config(source: str, sets: list[str] | None, quick: bool):
    cfg = load_config(source, sets or [])
    return quick_variant(cfg) if quick else cfg


def _given(ctx: typer.Context, name: str) -> bool:
    """True when the parameter ``name`` came from the command line (not its default)."""
    source = ctx.get_parameter_source(name)
    return source is not None and source.name != "DEFAULT"


def _check_out(out: Path) -> None:
    """Refuse an --out that is a file, lies under a file, or holds an unfinished run."""
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out} is a file, not a folder; give a folder for the results "
                         "(created if missing)")
    for folder in (out, *out.parents):
        if folder.exists():
            if not folder.is_dir():
                raise InputError(f"--out {out}: {folder} is a file, not a folder")
            if not os.access(folder, os.W_OK | os.X_OK):
                raise InputError(f"--out {out}: no permission to write in {folder}")
            break
    if (out / "checkpoint.h5").exists():
        raise InputError(f"--out {out} holds an unfinished run (checkpoint.h5); continue it with "
                         f"'silodem run --resume {out}', or delete {out / 'checkpoint.h5'} to "
                         "start afresh there")


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

      silodem run paper-case1 --quick   (the flat silo, small and fast)

      silodem run my.toml --set fill.n_particles=300 --out runs/test

      silodem run --resume runs/test    (continue a run stopped by Ctrl-C or a crash)

    Checkpoints are saved while it runs; Ctrl-C (SIGINT) or SIGTERM saves one and stops.
    Exit codes: 0 done, 2 bad input, 3 unstable run stopped, 130/143 stopped by SIGINT/SIGTERM.
    """
    _check_threads(threads)
    if resume is not None:
        _resume(ctx, resume, threads)
        return
    cfg = _config(source, sets, quick)
    out_dir = out if out is not None else Path("runs") / cfg.name
    _check_out(out_dir)

    from silodem.run import run_simulation  # imports numba: only when running

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

    Save it to start your own case:

      silodem show paper-case2 > my.toml   (edit my.toml, then: silodem run my.toml)
    """
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
    browser. Figures also go to DIR/figures/*.png. Example:

      silodem plot runs/paper-case2
    """
    from silodem.report import write_report  # matplotlib, scipy: only when plotting

    path = write_report(run_dir)
    Console().print(f"report: {path}", markup=False, highlight=False, soft_wrap=True)


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
    lammps: Annotated[bool, typer.Option("--lammps", help="Also run the same silo with LAMMPS "
                                         "(`lmp`, Debian package lammps) and print the ratio.")] = False,
) -> None:
    """Measure particle-steps per second on a dense, steadily discharging flat-bottomed silo
    built to match the reference LAMMPS deck (docs/performance.md). Example:

      silodem bench --n 30000 --threads 1 --lammps
    """
    if n < 10 or n > 20_000_000:
        raise InputError(f"--n must be between 10 and 20000000 grains, got {n}")
    if steps < 1 or settle < 0:
        raise InputError(f"--steps must be >= 1 and --settle >= 0, got {steps} and {settle}")
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
    if len(results) > 1:
        ratio = results[0].particle_steps_per_s / results[1].particle_steps_per_s
        console.print(f"silodem / LAMMPS = {ratio:.2f}", markup=False, highlight=False)


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


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the app; bad input -> one line on stderr and exit code 2."""
    command = typer.main.get_command(app)
    no_args = _click_types("NoArgsIsHelpError")
    usage = _click_types("UsageError")
    other = _click_types("ClickException")
    abort = _click_types("Abort") + (typer.Abort, KeyboardInterrupt)
    try:
        result = command.main(args=argv, prog_name="silodem", standalone_mode=False)
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
        _error("interrupted", 130)
    raise SystemExit(result if isinstance(result, int) else 0)
