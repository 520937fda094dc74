"""The commands on one run: ``run`` (and ``--resume``), ``scenarios``, ``show``, ``plot`` and
``animate``."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from silodem.cli.app import (
    QuickOpt,
    SetOpt,
    SourceArg,
    app,
    check_out,
    check_threads,
    given,
    read_config,
    runnable_config,
)
from silodem.errors import InputError, RunInterrupted, one_line
from silodem.scenario_files import DEFAULT_SCENARIO, config_to_toml, list_scenarios
from silodem.signals import noted_signals, signal_of


def _stop_if(noted: list[int]) -> None:
    """End as interrupted when a Ctrl-C or SIGTERM came while drawing, even if its
    KeyboardInterrupt was dropped by a callback (a weakref's) and the drawing went on: the
    entry point then prints one line and exits 130 (143 after a SIGTERM)."""
    if noted:
        raise KeyboardInterrupt


def _print_summary(console: Console, summary) -> None:
    """The run's summary on stdout; the warnings it printed on stderr as they came are only
    counted when stderr is the same stream (a terminal, or ``2>&1``)."""
    try:
        same = os.path.samestat(os.fstat(sys.stdout.fileno()), os.fstat(sys.stderr.fileno()))
    except (OSError, ValueError):  # a stream with no file behind it (captured, closed)
        same = False
    for line in summary.lines(shown_above=same):
        console.print(line, markup=False, highlight=False)


def _run_and_print(console: Console, start) -> None:
    """Run (``start()`` returns its RunSummary) and print the summary.  A signal once the run
    has ended, while the summary is printed, ends the command with a line that says so and
    where the complete results are (130 or 143), not the bare 'interrupted' of a signal
    before the run."""
    summary = None
    try:
        summary = start()
        _print_summary(console, summary)
    except KeyboardInterrupt as exc:
        if summary is None:  # not from the run, which ends in its own line
            raise
        raise RunInterrupted(f"after the run had ended, while its summary was printed; nothing "
                             f"is lost: its results are complete in {summary.out_dir}",
                             signal_of(exc)) from None


def _resume(ctx: typer.Context, folder: Path, threads: int | None) -> None:
    extra = [flag for name, flag in (("source", "SCENARIO|FILE"), ("sets", "--set"),
                                     ("quick", "--quick"), ("out", "--out"))
             if given(ctx, name)]
    if extra:
        raise InputError(f"--resume continues a run with the config saved in its checkpoint: "
                         f"give no {', '.join(extra)} with it")
    if folder.exists() and not folder.is_dir():
        raise InputError(f"--resume {folder} is a file; give the results folder of the run")
    from silodem.run import read_checkpoint, resume_simulation  # imports numba: only when running
    from silodem.run_folder import check_not_in_use

    check_not_in_use(folder)  # (a run still writing there: refused before a word is said)
    checkpoint = read_checkpoint(folder)  # a one-line error before anything is announced
    console = Console(soft_wrap=True)
    console.print(f"silodem: resuming the run in {folder}", markup=False, highlight=False)
    _run_and_print(console, lambda: resume_simulation(folder, threads=threads, progress=True,
                                                      checkpoint=checkpoint))


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
    Exit codes: 0 done, 1 a file not written (a full disk), 2 bad input, 3 unstable run
    stopped, 130/143 stopped by SIGINT/SIGTERM.
    """
    check_threads(threads)
    if resume is not None:
        _resume(ctx, resume, threads)
        return
    from silodem.study.spec import study_text

    if study_text(source) is not None:
        raise InputError(f"{source} is a study (a grid of runs): run it with 'silodem sweep "
                         f"{source}'")
    notes: list[str] = []
    # values that make no run together are refused before any folder is made
    cfg = runnable_config(source, sets, quick, notes)
    out_dir = out if out is not None else Path("runs") / cfg.name
    from silodem.run import run_simulation  # imports numba: only when running
    from silodem.run_folder import check_config_kept, check_not_in_use, replacing_note

    check_not_in_use(out_dir)  # (a run writing there: not 'an unfinished run' to resume)
    check_out(out_dir)
    replacing = replacing_note(out_dir, "--out")  # (a finished run was replaced unsaid)
    check_config_kept(source, out_dir, cfg)

    console = Console(soft_wrap=True)
    console.print(f"silodem: running '{cfg.name}' -> {out_dir}", markup=False, highlight=False)
    if replacing is not None:
        notes.append(f"silodem: {replacing}")
    for note in notes:
        Console(stderr=True, soft_wrap=True).print(note, markup=False, highlight=False)
    _run_and_print(console, lambda: run_simulation(cfg, out_dir, threads=threads, progress=True))


@app.command()
def scenarios() -> None:
    """List the ready-made scenarios shipped with silodem, and its parametric studies."""
    from silodem.study.spec import list_studies

    items, studies = list_scenarios(), list_studies()
    width = max((len(name) for name, _ in items + studies), default=0)
    for name, description in items:
        typer.echo(f"{name:<{width}}  {description}")
    typer.echo("")
    typer.echo("See all values of one: silodem show NAME    Run one: silodem run NAME")
    if studies:
        typer.echo("")
        typer.echo("Studies (many runs over a grid of values, docs/sweeps.md):")
        for name, description in studies:
            typer.echo(f"{name:<{width}}  {description}")
        typer.echo("")
        typer.echo("Read one: silodem show NAME    Run it: silodem sweep NAME [--quick]")


@app.command()
def show(
    source: SourceArg = DEFAULT_SCENARIO,
    sets: SetOpt = None,
    quick: QuickOpt = False,
) -> None:
    """Print the complete config of a scenario or file as TOML, every default included.
    A study (paper-study, or a study file) is printed as it is written. Values that are each
    valid but that 'silodem run' refuses together are printed all the same, with a note on
    stderr saying why (exit code 0: the printed config is there to be edited).

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
    from silodem.cli.entry import numba_threads_usable

    notes: list[str] = []
    cfg = read_config(source, sets, quick, notes)
    sys.stdout.write(config_to_toml(cfg))
    for note in notes:
        sys.stderr.write(note + "\n")
    if not numba_threads_usable():  # the checks import numba, which would refuse with a
        return  # traceback: show computes nothing, and works whatever NUMBA_NUM_THREADS says
    from silodem.silo.checks import check_numbers

    try:  # values each valid that make no run together: printed (to be edited), and said
        check_numbers(cfg)
    except InputError as exc:
        sys.stderr.write(f"silodem: note: 'silodem run' refuses this config as it stands: "
                         f"{exc}\n")


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
    again where the run drew them (output.png), as is DIR/vtk/fields_*.vtu where the run
    wrote VTK files. Example:

      silodem plot runs/paper-case2
    """
    from silodem.output import write_views  # matplotlib, scipy: only when plotting
    from silodem.report import write_report

    unfinished: list[str] = []  # the line saying so, for an unfinished run's results.h5
    try:
        with noted_signals(hold=False) as noted:
            path = write_report(run_dir, note=unfinished.append)
            write_views(run_dir)
    except (ValueError, IndexError, KeyError, TypeError, AttributeError) as exc:
        # what numbers of the wrong shape or kind raise in the figures (LinAlgError is a
        # ValueError); a disk or memory error stays what it is
        raise InputError(f"{run_dir}: its results.h5 could not be drawn "
                         f"({type(exc).__name__}: {one_line(exc)})") from None
    _stop_if(noted)
    for line in unfinished:
        Console(stderr=True).print(line, markup=False, highlight=False, soft_wrap=True)
    Console().print(f"report: {path}", markup=False, highlight=False, soft_wrap=True)


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
                     help="Where to write the video (a name without a suffix gets .mp4 or .gif). "
                     "Default: DIR/animation.mp4 (or .gif).",
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
    err = Console(stderr=True, soft_wrap=True)  # (a log file gets no bar: rich wrote its
    # last state there, bar characters and all; the closing line says what was drawn)
    with Bar(TextColumn("rendering"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
             console=err, transient=False, disable=not err.is_terminal) as bar, \
            noted_signals(hold=False) as noted:
        task = bar.add_task("frames", total=len(plan.frames))
        result = render_animation(plan, lambda done, _: bar.update(task, completed=done))
    _stop_if(noted)
    played = f"{result.frames / result.fps:.3g} s of video at {result.fps:.3g} fps"
    if result.fps != fps:
        played += f" for --fps {fps}: a GIF's delays are whole hundredths of a second"
    Console(soft_wrap=True).print(  # (the drawing's time said as such: it read as the length)
        f"animation: {result.frames} frames ({result.width}x{result.height} px, {played}), "
        f"drawn in {result.seconds:.1f} s -> {result.path}", markup=False, highlight=False)
