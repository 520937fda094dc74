"""The ``silodem`` entry point: runs the app and turns every bad input (file, scenario,
``--set``, option value, usage) into exactly one line on stderr and exit code 2, never a
traceback; a full disk (or another fault of the machine's, not the input's) ends with exit
code 1, an unstable run with 3, Ctrl-C with 130 and SIGTERM with 143."""

from __future__ import annotations

import errno
import importlib
import os
import signal
import sys
import threading

import typer

from silodem.cli.app import app, fail
from silodem.errors import InputError, RunInterrupted, Terminated, UnstableRunError, short_repr


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
        fail("interrupted (SIGTERM)", 143)
    fail("interrupted", 130)


NOT_INPUT = (errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.EFBIG)  # the machine's, not the input's
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


NO_KERNEL_COMMANDS = ("scenarios", "show")  # they never import numba

MAX_NUMBA_THREADS = 2**31 - 1
"""The largest NUMBA_NUM_THREADS: numba hands the count to its threading layer as a C int, so
a larger one wraps (10**50 became 0 threads, and the first parallel kernel failed)."""


def _numba_threads_ok(text: str) -> bool:
    """Whether ``text`` (NUMBA_NUM_THREADS, stripped) is a whole number from 1 to
    MAX_NUMBA_THREADS, written in ASCII digits (``str.isdigit`` also takes '²', which
    ``int`` refuses; and ``int`` refuses more than 4300 digits)."""
    return (text.isascii() and text.isdigit() and len(text) <= len(str(MAX_NUMBA_THREADS))
            and 1 <= int(text) <= MAX_NUMBA_THREADS)


def numba_threads_usable() -> bool:
    """Whether numba can be imported in this process: NUMBA_NUM_THREADS unset, or a whole
    number it takes (``_numba_threads_ok``)."""
    return _numba_threads_ok(os.environ.get("NUMBA_NUM_THREADS", "1").strip() or "1")


def _needs_kernels(args: list[str]) -> bool:
    """Whether the command may import numba (which refuses a NUMBA_NUM_THREADS below 1 with
    a traceback): not to list or show scenarios, or for --help and --version."""
    if not args or args[0] in NO_KERNEL_COMMANDS or args[0] == "--version":
        return False
    return not any(arg in ("--help", "-h") for arg in args)


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the app; bad input -> one line on stderr and exit code 2."""
    args = list(sys.argv[1:] if argv is None else argv)
    if os.environ.get("NUMBA_NUM_THREADS", "x").strip() == "":
        # blank is unset, as here; numba would print a parse error's traceback at its import
        del os.environ["NUMBA_NUM_THREADS"]
    numba_threads = os.environ.get("NUMBA_NUM_THREADS", "1").strip() or "1"
    if _needs_kernels(args) and not _numba_threads_ok(numba_threads):
        fail(f"error: NUMBA_NUM_THREADS={short_repr(numba_threads)}: must be a whole number of "
             f"threads from 1 to {MAX_NUMBA_THREADS} (or unset)")
    empty = _empty_path(args)
    if empty is not None:
        fail(f"error: {empty}: an empty path (give a folder or file name; '.' for this one)")
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
        fail(message if message.startswith("config error:") else f"error: {message}")
    except UnstableRunError as exc:
        fail(f"run stopped: {exc}", 3)
    except RunInterrupted as exc:
        fail(f"interrupted: {exc}", exc.exit_code)
    except no_args as exc:
        sys.stdout.write(exc.ctx.get_help() + "\n")
        raise SystemExit(0) from None
    except usage as exc:
        hint = f" (see '{exc.ctx.command_path} --help')" if exc.ctx is not None else ""
        fail(f"usage error: {exc.format_message()}{hint}", 2)
    except other as exc:
        fail(f"error: {exc.format_message()}", getattr(exc, "exit_code", 1))
    except abort:
        _interrupted()
    except OSError as exc:  # a path given that the system refuses (name too long, ...)
        where = f": {exc.filename}" if exc.filename else ""
        # a full disk or a failing one is no bad input: exit code 1, not 2
        fail(f"error: {exc.strerror or exc}{where}", 1 if exc.errno in NOT_INPUT else 2)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    if result == 130:  # typer turns a KeyboardInterrupt that no command caught into 130
        _interrupted()
    raise SystemExit(result if isinstance(result, int) else 0)
