"""SIGINT and SIGTERM noted while a block runs (``noted_signals``): the one mechanism behind
the sweep's cluster start-up, where a signal must wait, and the drawing of a run, of
'silodem plot' and of 'silodem animate', where a signal's KeyboardInterrupt may be dropped by
the code it interrupts.  (A run's own stop at the end of a chunk is
``safety.RunGuard.signals``.)  ``signal_of``: the signal behind a KeyboardInterrupt."""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Iterator

from silodem.errors import Terminated

NOTED = (signal.SIGINT, signal.SIGTERM)


def signal_of(exc: KeyboardInterrupt) -> int:
    """The signal behind a KeyboardInterrupt: SIGTERM for ``errors.Terminated`` (the command
    line's SIGTERM), else SIGINT."""
    return signal.SIGTERM if isinstance(exc, Terminated) else signal.SIGINT


@contextlib.contextmanager
def noted_signals(*, hold: bool) -> Iterator[list[int]]:
    """Note SIGINT and SIGTERM in the list yielded while the block runs, then restore the
    handlers they had.

    ``hold=False``: each signal that has a Python handler also goes to that handler at once
    (raising KeyboardInterrupt or ``errors.Terminated``); SIG_DFL and SIG_IGN keep what they
    do.  Drawing with matplotlib, such a KeyboardInterrupt was sometimes raised inside a
    weakref callback, where Python drops it: the note still says the signal came, and
    ``sys.unraisablehook`` keeps quiet about it (it printed "Exception ignored in ..." and a
    traceback of ``Terminated`` before the command's one line).

    ``hold=True``: nothing acts inside the block; after it, each signal that came is raised
    again, once, SIGTERM first, under the handler it had.  Raised in the middle of
    distributed's start-up, either ended in its tracebacks, and a SIGINT ignored there
    (SIG_IGN) was lost.

    Outside the main thread (a notebook's worker thread) no handler can be set: the block
    runs as it is and the list stays empty."""
    noted: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield noted
        return
    before = {s: signal.getsignal(s) for s in NOTED}
    if not hold:
        before = {s: h for s, h in before.items() if callable(h)}

    def note(signum, frame):
        noted.append(signum)
        if not hold:
            before[signum](signum, frame)

    try:
        with handled_by(note, before), _quiet_about_interrupts(not hold):
            yield noted
    finally:
        if hold:
            for s in sorted(set(noted), reverse=True):  # SIGTERM (15) first: the stronger
                signal.raise_signal(s)


@contextlib.contextmanager
def _quiet_about_interrupts(quiet: bool) -> Iterator[None]:
    """While the block runs (if ``quiet``), a KeyboardInterrupt that Python cannot raise (in
    a callback, a finaliser) is dropped without its "Exception ignored" report; any other
    such exception is reported as before."""
    if not quiet:
        yield
        return
    previous = sys.unraisablehook

    def hook(unraisable) -> None:
        if not isinstance(unraisable.exc_value, KeyboardInterrupt):
            previous(unraisable)

    sys.unraisablehook = hook
    try:
        yield
    finally:
        sys.unraisablehook = previous


@contextlib.contextmanager
def handled_by(handler, before: dict) -> Iterator[None]:
    """The signals that are keys of ``before`` go to ``handler`` while the block runs; then
    each gets back its handler in ``before`` (SIG_DFL for None: one set outside Python)."""
    for s in before:
        signal.signal(s, handler)
    try:
        yield
    finally:
        for s, previous in before.items():
            signal.signal(s, signal.SIG_DFL if previous is None else previous)
