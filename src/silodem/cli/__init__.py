"""The ``silodem`` command line: :func:`main` is the entry point (the ``silodem`` script calls it
through :mod:`silodem.launcher`, which guards its import against Ctrl-C).

Importing the two command modules registers their commands on :data:`app`, in the order
``silodem --help`` lists them.
"""

from silodem.cli import commands_run, commands_tools  # noqa: F401  (registers the commands)
from silodem.cli.app import app
from silodem.cli.entry import main

__all__ = ["app", "main"]
