"""The ``silodem`` command line: :func:`main` is the entry point (``silodem = silodem.cli:main``).

Importing the two command modules registers their commands on :data:`app`, in the order
``silodem --help`` lists them.
"""

from silodem.cli import commands_run, commands_tools  # noqa: F401  (registers the commands)
from silodem.cli.app import app
from silodem.cli.entry import main

__all__ = ["app", "main"]
