"""The Dask side of a study: how many workers, a local cluster or a running scheduler's
client (``connect``), watching that the scheduler keeps workers during a sweep, and closing it
all down under a shield against a second Ctrl-C (``close_cluster``, ``shutdown_shield``).
What runs on the workers, and the study folder, are ``study.execute``'s."""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING

from silodem.errors import InputError, one_line, short_repr

if TYPE_CHECKING:
    from distributed import Client, LocalCluster

WORKER_WAIT_S = 120.0  # how long to wait for the first worker of an external scheduler
CONNECT_TIMEOUT_S = 10.0  # how long to wait for an external scheduler's handshake
NO_WORKERS_WARN_S = 60.0  # an external scheduler without workers this long is reported
WATCH_INTERVAL_S = 5.0  # how often the scheduler's workers are counted during a sweep


def workers_phrase(n: int) -> str:
    """'N single-threaded worker(s)', as the sweep says where it runs."""
    return f"{n} single-threaded worker{'s' if n != 1 else ''}"


def default_workers() -> int:
    """One worker per core this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


MAX_WORKERS = 4096
LOCAL_WORKERS_PER_CORE = 4
"""The most worker processes per core a local cluster may have.  A run is single-threaded and
CPU-bound, so workers beyond one per core only share the cores, and each holds its own
interpreter and compiled kernels: a LocalCluster worker's resident memory was about 260 MB as
its first run started and 350-400 MB through `paper-study --quick`'s runs (ps, 2026-11): 4096
workers would need some 1.5 TB."""


def check_workers(workers: int | None, what: str = "workers", *, local: bool = False) -> None:
    """InputError unless ``workers`` is None (one per core) or a count from 1 to MAX_WORKERS;
    for a ``local`` cluster from 1 to LOCAL_WORKERS_PER_CORE per core this process may use."""
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                or not 1 <= workers <= MAX_WORKERS):
        raise InputError(f"{what} must be an integer from 1 to {MAX_WORKERS}, got "
                         f"{short_repr(workers)}")
    cores = default_workers() if local and workers is not None else 0
    if cores and workers > LOCAL_WORKERS_PER_CORE * cores:
        raise InputError(
            f"{what} {workers}: a local cluster takes at most {LOCAL_WORKERS_PER_CORE * cores} "
            f"workers here ({LOCAL_WORKERS_PER_CORE} per core, {cores} core(s)); more would only "
            "share the cores, each with its own process of ~350 MB. For more, start a Dask "
            "scheduler and workers on other machines and pass its address as the scheduler")


class NoWorkersWatch:
    """Says when a scheduler has had no worker for ``after_s`` seconds, and when workers are
    back: a sweep on an external scheduler whose workers all died waits for new ones, and
    without a word its progress bar just stood still.  ``check(workers, now)`` is given the
    count of workers and the time [s] (monotonic); it calls ``say`` once per spell."""

    def __init__(self, address: str, say: Callable[[str], None], after_s: float) -> None:
        self.address, self.say, self.after_s = address, say, after_s
        self.none_since: float | None = None
        self.said = False

    def check(self, workers: int, now: float) -> None:
        if workers > 0:
            if self.said:
                self.say(f"{workers} worker(s) at {self.address} again: the sweep goes on")
            self.none_since, self.said = None, False
            return
        if self.none_since is None:
            self.none_since = now
        if not self.said and now - self.none_since >= self.after_s:
            self.said = True
            self.say(f"no worker at the Dask scheduler {self.address} for "
                     f"{now - self.none_since:.0f} s: the sweep waits for one (start workers "
                     f"with 'dask worker {self.address} --nthreads 1'; Ctrl-C stops the "
                     "sweep, and its finished runs are kept)")


@contextlib.contextmanager
def watching_workers(client: Client, say: Callable[[str], None] | None) -> Iterator[None]:
    """While the block runs, count ``client``'s workers every WATCH_INTERVAL_S in a daemon
    thread and tell ``say`` when there has been none for NO_WORKERS_WARN_S
    (``NoWorkersWatch``).  Nothing is watched without ``say``."""
    import threading

    if say is None:
        yield
        return
    watch = NoWorkersWatch(client.scheduler.address, say, NO_WORKERS_WARN_S)
    stop = threading.Event()

    def count() -> None:
        while not stop.wait(WATCH_INTERVAL_S):
            try:
                workers = len(client.scheduler_info().get("workers", {}))
            except Exception:  # noqa: BLE001 - a lost scheduler is the sweep's to report
                return
            watch.check(workers, time.monotonic())

    thread = threading.Thread(target=count, name="silodem-worker-watch", daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join(timeout=WATCH_INTERVAL_S)


def local_cluster(workers: int) -> LocalCluster:
    """A LocalCluster of ``workers`` single-threaded worker processes (each under a nanny
    that restarts it if it dies), no dashboard, and only critical log records: a worker
    that loses the scheduler while a sweep is stopped logs a traceback at ERROR, and every
    failure of a run reaches the sweep through its future (and is reported there).

    Ctrl-C in a terminal goes to the whole process group; the workers ignore SIGINT
    (``study.worker_setup``, preloaded), and the sweep's own SIGINT and SIGTERM are held
    while the cluster starts and act once it has (``signals.noted_signals``)."""
    import logging

    from distributed import LocalCluster

    from silodem.signals import noted_signals

    cluster = None
    try:
        with noted_signals(hold=True):
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   dashboard_address=":0", silence_logs=logging.CRITICAL,
                                   preload=["silodem.study.worker_setup"])
    except BaseException:  # a signal held while it started: close it, not left to the exit
        if cluster is not None:
            close_cluster(None, cluster)
        raise
    return cluster


SHUTDOWN_PATIENCE = 1  # signals a shutdown notes and lets wait; the next one acts at once


@contextlib.contextmanager
def shutdown_shield(*, stopping: bool) -> Iterator[list[int]]:
    """While a sweep shuts its Dask side down (cancels its tasks, closes its client and local
    cluster: one to a few seconds, a worker in the middle of a run being killed after
    distributed's timeout), SIGINT and SIGTERM are noted in the list yielded and wait: a second
    Ctrl-C broke the shutdown off midway, its 'interrupted' line came at once, and the
    interpreter's exit then waited some 10 s on distributed's own clean-up of the cluster left
    half closed.  Beyond ``SHUTDOWN_PATIENCE`` signals, the next acts at once through the
    handler it had (a shutdown that hangs can still be stopped).

    ``stopping``: the block runs because the sweep is being stopped (an exception is on its
    way): the signals noted are dropped, the one that stopped it gives the exit code.  Else
    the first signal noted is raised again, once, under its handler after the block, so that a
    signal during an ordinary close at the end of a sweep stops it as at any other moment.

    Only signals that have a Python handler are noted (SIG_DFL and SIG_IGN keep what they
    do), and only in the main thread (elsewhere the block runs as it is)."""
    import signal
    import threading

    from silodem.signals import NOTED, handled_by

    noted: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield noted
        return
    before = {s: h for s in NOTED if callable(h := signal.getsignal(s))}

    def note(signum, frame):
        noted.append(signum)
        if len(noted) > SHUTDOWN_PATIENCE:
            before[signum](signum, frame)

    with handled_by(note, before):
        yield noted
    if noted and not stopping:
        signal.raise_signal(noted[0])


def close_cluster(client: Client | None, cluster: LocalCluster | None, *,
                  stopping: bool = True) -> None:
    """Close ``client``, then ``cluster`` (either may be None) under ``shutdown_shield``: a
    signal meanwhile waits for the close to end (``stopping``: the sweep is being stopped, and
    it is dropped)."""
    with shutdown_shield(stopping=stopping):
        try:
            if client is not None:
                client.close()
        finally:
            if cluster is not None:
                cluster.close()


def _probe(address: str) -> None:
    """Open one Dask connection to ``address`` (connect and handshake) and close it, all
    within CONNECT_TIMEOUT_S.  Client's own timeout covers the connect only: a server that
    accepts and never answers (not a Dask scheduler, or a stuck one) hung it for ever in the
    handshake, and one that answers something else (an HTTP server) raised whatever its
    reply decoded to."""
    import asyncio
    import threading

    from distributed.comm import connect as dask_connect

    async def once() -> None:
        comm = await dask_connect(address, timeout=CONNECT_TIMEOUT_S)
        await comm.close()

    outcome: list[BaseException | None] = []  # None: the handshake was made

    def probe() -> None:  # in a thread of its own: a notebook's thread runs an event loop
        try:
            asyncio.run(asyncio.wait_for(once(), CONNECT_TIMEOUT_S))
            outcome.append(None)
        except BaseException as exc:  # noqa: BLE001 - handed to the caller's thread
            outcome.append(exc)

    # a daemon thread, joined with a timeout: Ctrl-C ends the wait at once, and the exit
    # does not wait for the probe (a pool's thread was joined, up to CONNECT_TIMEOUT_S)
    thread = threading.Thread(target=probe, name="silodem-scheduler-probe", daemon=True)
    thread.start()
    thread.join(CONNECT_TIMEOUT_S + 1.0)
    if not outcome or isinstance(outcome[0], TimeoutError):
        raise TimeoutError(f"no Dask handshake within {CONNECT_TIMEOUT_S:g} s")
    if outcome[0] is not None:
        raise outcome[0]


def connect(scheduler: str | None, workers: int | None,
            say: Callable[[str], None] | None = None) -> tuple[Client, LocalCluster | None, str]:
    """(client, cluster or None, description): a LocalCluster by default, else a client of
    the running scheduler at ``scheduler`` (``--workers`` then waits for that many workers,
    telling ``say`` so when they have not all joined yet)."""
    from distributed import Client

    if scheduler is None:
        n = workers or default_workers()
        cluster = local_cluster(n)
        try:
            client = Client(cluster)
        except BaseException:
            close_cluster(None, cluster)
            raise
        return client, cluster, f"LocalCluster of {workers_phrase(n)}"
    try:
        _probe(scheduler)
        client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s")
    except Exception as exc:  # noqa: BLE001 - TypeError: tls://, ucx://; MemoryError: not Dask
        reason = one_line(exc) or type(exc).__name__
        raise InputError(f"cannot reach the Dask scheduler at {scheduler} ({reason}); "
                         "start one with 'dask scheduler' or leave out --scheduler for a "
                         "local cluster") from None
    need = workers or 1
    try:
        have = len(client.scheduler_info().get("workers", {}))
        if have < need and say is not None:
            say(f"waiting up to {WORKER_WAIT_S:.0f} s for {need} worker(s) at {scheduler} "
                f"({have} joined so far)")
        client.wait_for_workers(n_workers=need, timeout=WORKER_WAIT_S)
    except (OSError, TimeoutError):
        have = len(client.scheduler_info().get("workers", {}))
        client.close()
        raise InputError(f"the Dask scheduler at {scheduler} has {have} worker(s), fewer than "
                         f"{need} after {WORKER_WAIT_S:.0f} s; start workers with "
                         f"'dask worker {scheduler} --nthreads 1'") from None
    except BaseException:  # Ctrl-C while waiting: close it here, not left open (or to atexit)
        client.close()
        raise
    n = len(client.scheduler_info().get("workers", {}))
    return client, None, f"Dask scheduler {scheduler} ({n} workers)"
