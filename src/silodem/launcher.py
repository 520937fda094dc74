"""The ``silodem`` script and ``python -m silodem``: import the command line, then run it.

Importing it takes a good part of a second (typer, numpy, the config schema), before
:func:`silodem.cli.main` can turn Ctrl-C into one line; an interrupt during that import ends
here in the same line and exit code 130 instead of a traceback."""

from __future__ import annotations

import os
import signal
import sys


def main() -> None:
    """Import :mod:`silodem.cli` under a Ctrl-C guard and run its ``main``; then answer a
    signal during the interpreter's exit in one line (``exit_on_signals``)."""
    try:
        from silodem.cli import main as cli_main
    except KeyboardInterrupt:
        sys.stderr.write("interrupted\n")
        raise SystemExit(130) from None
    code: int | str | None = 0
    try:
        cli_main()
    except SystemExit as exc:
        code = exc.code
        raise
    finally:
        exit_on_signals(0 if code is None else code)


def exit_on_signals(code: int | str = 0) -> None:
    """From now on SIGINT and SIGTERM end the process at once: with one line and 130 or 143
    after a command that succeeded (``code`` 0), else quietly with its own exit code (a
    second Ctrl-C after an 'interrupted' line printed a second line, and 130 for a failure).

    The command has ended (its exit code is on its way) but the interpreter's exit takes a
    good part of a second (numba's and dask's clean-up): a signal then killed the process
    without a word.  Only the script does this (``main``), never a process that calls
    :func:`silodem.cli.main` itself; a signal ignored where silodem started stays ignored."""
    def handler(signum: int, frame: object) -> None:
        if code != 0:  # its line is written already
            os._exit(code if isinstance(code, int) else 1)
        name = signal.Signals(signum).name
        with_flush = (sys.stdout, sys.stderr)
        for stream in with_flush:
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        os.write(2, f"interrupted ({name}): as silodem exited, after the command had "
                    "ended (nothing it wrote is lost)\n".encode())
        os._exit(128 + signum)

    for s in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(s) is not signal.SIG_IGN:
            signal.signal(s, handler)
