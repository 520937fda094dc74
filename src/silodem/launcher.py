"""The ``silodem`` script and ``python -m silodem``: import the command line, then run it.

Importing it takes a good part of a second (typer, numpy, the config schema), before
:func:`silodem.cli.main` can turn Ctrl-C into one line; an interrupt during that import ends
here in the same line and exit code 130 instead of a traceback."""

from __future__ import annotations

import sys


def main() -> None:
    """Import :mod:`silodem.cli` under a Ctrl-C guard and run its ``main``."""
    try:
        from silodem.cli import main as cli_main
    except KeyboardInterrupt:
        sys.stderr.write("interrupted\n")
        raise SystemExit(130) from None
    cli_main()
