"""The ``silodem`` script and ``python -m silodem``: import the command line, then run it.

Importing it takes a good part of a second (typer, numpy, the config schema), before
:func:`silodem.cli.main` can turn Ctrl-C into one line; an interrupt during that import ends
here in the same line and exit code 130 instead of a traceback."""

from __future__ import annotations

import codecs
import contextlib
import os
import signal
import sys


class ReaderGone:
    """A text stream (``sys.stdout``, ``sys.stderr``) whose writes go nowhere once its reader
    has gone (EPIPE: ``silodem show paper-case2 | head -3``), so the command goes on and exits
    with its own code: click ended any command at once with exit code 1 and no word, a finished
    run and a validation whose checks all passed alike.  Only the text shown is lost; what the
    command writes into files is not.  The stream's file descriptor is pointed at /dev/null,
    so the buffer's last flush, at exit too, has somewhere to go.  Its ``buffer`` (the bytes
    beneath, which click writes to where the text stream's encoding is not one it trusts) is
    wrapped alike."""

    def __init__(self, stream) -> None:
        self._stream = stream

    def _gone(self) -> None:
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
        except OSError:  # (no /dev/null: the writes keep failing, and are dropped)
            return
        try:
            os.dup2(devnull, self._stream.fileno())
        except (OSError, ValueError):  # no descriptor: its writes keep failing, and are dropped
            pass
        finally:
            os.close(devnull)

    def write(self, text):
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            self._gone()
            return len(text)

    def flush(self) -> None:
        try:
            self._stream.flush()
        except BrokenPipeError:
            self._gone()
            with contextlib.suppress(BrokenPipeError):
                self._stream.flush()

    def __getattr__(self, name: str):
        if name == "_stream":  # (not set yet: a copy, an unpickling)
            raise AttributeError(name)
        if name == "buffer":
            return ReaderGone(self._stream.buffer)
        return getattr(self._stream, name)


def _bytes_back_or_escape(err: UnicodeError) -> tuple[str | bytes, int]:
    """An encoding error handler: a run of the surrogates by which Python holds the bytes of
    a file name its locale could not decode ('surrogateescape': 'Grüße' under LANG=C) is
    written as those bytes, so that the path printed is the one on disk and can be pasted
    back; any other character the encoding lacks as its backslash escape."""
    if not isinstance(err, UnicodeEncodeError):
        raise err
    out = b"".join(bytes([ord(c) - 0xDC00]) if "\udc80" <= c <= "\udcff" else
                   c.encode("ascii", "backslashreplace") for c in err.object[err.start:err.end])
    return out, err.end


OUTPUT_ERRORS = "silodem-output"  # the error handler of stdout and stderr
codecs.register_error(OUTPUT_ERRORS, _bytes_back_or_escape)


def main() -> None:
    """Import :mod:`silodem.cli` under a Ctrl-C guard and run its ``main``, with output that
    a reader who has gone does not stop (``ReaderGone``); then answer a signal during the
    interpreter's exit in one line (``exit_on_signals``)."""
    for name in ("stdout", "stderr"):
        stream = getattr(sys, name)
        if stream is None or isinstance(stream, ReaderGone) or not hasattr(stream, "fileno"):
            continue
        # a character the stream's encoding lacks (PYTHONIOENCODING=ascii: the config's '§')
        # is written as an escape, not a UnicodeEncodeError's traceback; the bytes of a file
        # name that the locale could not decode go out as they came (OUTPUT_ERRORS)
        with contextlib.suppress(AttributeError, ValueError, OSError):
            stream.reconfigure(errors=OUTPUT_ERRORS)
        setattr(sys, name, ReaderGone(stream))
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
