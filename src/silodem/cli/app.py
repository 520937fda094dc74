"""The ``silodem`` Typer app, the options several commands share, and their small helpers.

The commands are in :mod:`silodem.cli.commands_run` (one run: run, scenarios, show, plot,
animate) and :mod:`silodem.cli.commands_tools` (sweep, bench, validate); the entry point that
turns every bad input into one line and exit code 2 is :mod:`silodem.cli.entry`.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from silodem.errors import one_line, shorten
from silodem.scenario_files import load_config, quick_overrides, quick_variant

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


def _print_version(asked: bool) -> None:
    if asked:
        from silodem import __version__

        print(f"silodem {__version__}")
        raise typer.Exit()


@app.callback()
def _options(
    version: Annotated[bool, typer.Option(
        "--version", callback=_print_version, is_eager=True,
        help="Print silodem's version and exit (results.h5 and the report record it; a "
        "study's run ids depend on it).")] = False,
) -> None:
    pass


SourceArg = Annotated[
    str,
    typer.Argument(
        metavar="SCENARIO|FILE.toml",
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
        "grains, shorter time limits) that runs in well under a minute: a first try. It "
        "applies after --set, so it shrinks the values --set gave too.",
    ),
]


def check_threads(threads: int | None) -> None:
    """Refuse a ``--threads`` value the kernels cannot run with (InputError)."""
    from silodem.run import check_threads as check

    check(threads, "--threads")


def read_config(source: str, sets: list[str] | None, quick: bool,
                notes: list[str] | None = None):
    """The validated Config of a scenario name or TOML file, with ``--set`` and ``--quick``;
    ``notes`` gets the line saying which --set values --quick changed (the command prints it
    once its checks have passed: an error stays the only line on stderr)."""
    cfg = load_config(source, sets or [])
    if not quick:
        return cfg
    small = quick_variant(cfg)
    changed = quick_overrides(cfg, small, sets or [])
    if changed and notes is not None:  # a value typed on the command line, changed unsaid
        notes.append(f"silodem: --quick changed what --set gave: {changed} (it shrinks the "
                     "silo after --set)")
    return small


def runnable_config(source: str, sets: list[str] | None, quick: bool,
                    notes: list[str] | None = None):
    """:func:`read_config`, then the checks of values that make no run together
    (``silo.checks.check_numbers``): an InputError naming the ``--set`` values that broke a
    config that runs without them, as a schema check's does (``load_config``)."""
    from silodem.errors import InputError
    from silodem.scenario_files import QUICK_SUFFIX, breaking_sets
    from silodem.silo.checks import check_numbers

    cfg = read_config(source, sets, quick, notes)
    try:
        check_numbers(cfg)
    except InputError as exc:
        def runs_with(items: list[str], quick: bool = quick) -> bool:
            try:
                check_numbers(read_config(source, items, quick))
            except InputError:
                return False
            return True

        message = str(exc)
        if sets and runs_with([]):
            culprits = ", ".join(map(shorten, breaking_sets(list(sets), runs_with)))
            message += f" (after --set {culprits})"
        if quick:  # the shrunk config's numbers (3600000 grains in 15 s) are in no file
            name = cfg.name.removesuffix(QUICK_SUFFIX)
            message = (f"--quick cannot shrink '{name}': {message}"
                       if runs_with(list(sets or []), quick=False) else
                       f"{message}; these are the values of the --quick variant ('silodem "
                       f"show {source} --quick' prints them)")
        if message == str(exc):
            raise
        raise InputError(message) from None
    return cfg


def given(ctx: typer.Context, name: str) -> bool:
    """True when the parameter ``name`` came from the command line (not its default)."""
    source = ctx.get_parameter_source(name)
    return source is not None and source.name != "DEFAULT"


def check_out(out: Path, *, make: bool = True) -> None:
    """Refuse (InputError) an ``--out`` folder that is a file, cannot be written or holds an
    unfinished run; create it (with ``make`` False, only try)."""
    from silodem.run import check_out as check

    check(out, "--out", make=make)


def fail(message: str, code: int = 2) -> None:
    """Print ``message`` as one line on stderr and exit with ``code``."""
    sys.stderr.write(one_line(message) + "\n")
    sys.stderr.flush()
    raise SystemExit(code)
