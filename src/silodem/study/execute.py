"""Running a study on dask.distributed: one task per run, atomic run folders, resumption.

Layout of a study folder DIR (docs/sweeps.md)::

    DIR/study.toml              the study file as given
    DIR/runs/<id>/              a finished run: config.toml, results.h5, summary.json, ...
    DIR/runs/.<id>.tmp-<uuid>/  a run in progress (or left by a worker that died)
    DIR/failed/<id>/            the folder of a run that raised (unstable, bad numbers)
    DIR/results.csv             one row per finished run
    DIR/report.html             the study report (figures in DIR/figures/)

A run is done in its own temporary folder and renamed to ``runs/<id>`` only once complete (the
rename is atomic on one file system), so ``runs/<id>`` is either complete or absent; it is
finished when it holds results.h5 and summary.json (written last, before the rename).  A task
is idempotent: it returns the finished folder's summary if there is one, and two attempts of the
same run (a worker thought dead that still works) never mix their files.  A worker that dies
mid-run leaves only its temporary folder; the scheduler gives the task to another worker.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import socket
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from silodem.errors import InputError, one_line, short_repr
from silodem.output import write_text
from silodem.run_folder import foreign_files
from silodem.study.plan import PlannedRun, StudyPlan

if TYPE_CHECKING:
    from distributed import Client, LocalCluster

SUMMARY_NAME = "summary.json"
ATTEMPT_NAME = "attempt.json"
RESULTS_NAME = "results.h5"
TASK_RETRIES = 2  # re-runs of a task that raised an unexpected error (a full disk, a lost file)
WORKER_WAIT_S = 120.0  # how long to wait for the first worker of an external scheduler
CONNECT_TIMEOUT_S = 10.0  # how long to wait for an external scheduler's handshake
NO_WORKERS_WARN_S = 60.0  # an external scheduler without workers this long is reported
WATCH_INTERVAL_S = 5.0  # how often the scheduler's workers are counted during a sweep


# --- one run, in a worker --------------------------------------------------------------------


def is_finished(run_dir: Path) -> bool:
    """True when ``run_dir`` is a finished run folder (results.h5 and summary.json)."""
    return (run_dir / RESULTS_NAME).is_file() and (run_dir / SUMMARY_NAME).is_file()


VERSION_KEY = "analysis_version"  # summary.json: study.table.ANALYSIS_VERSION it was made by


def read_summary(run_dir: Path) -> dict[str, Any]:
    """The per-run quantities of the finished run ``run_dir``: its summary.json, or, when that
    was written by another version of the analysis (``study.table.ANALYSIS_VERSION``) or
    cannot be read as one (damaged, not a JSON object), a new summary from its results.h5,
    saved in its place: the summary is derived from results.h5 alone."""
    from silodem.study.table import ANALYSIS_VERSION

    try:
        summary = json.loads((run_dir / SUMMARY_NAME).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):  # (JSONDecodeError is a ValueError)
        summary = None
    if isinstance(summary, dict) and summary.pop(VERSION_KEY, None) == ANALYSIS_VERSION:
        return summary
    summary = summarise(run_dir)
    write_summary(run_dir, summary)
    return summary


def summarise(run_dir: Path) -> dict[str, Any]:
    """``study.table.summarise_run`` of a complete run, or, if it fails, the reason (the run
    is kept: its results.h5 is whole)."""
    from silodem.study.table import summarise_run

    try:
        return summarise_run(run_dir)
    except Exception as exc:  # noqa: BLE001 - the run is complete: keep it, say why not
        return {"summary_error": f"{type(exc).__name__}: {one_line(exc)}"}


def write_summary(run_dir: Path, summary: dict[str, Any]) -> None:
    """summary.json (atomic), marked with the analysis version that made it."""
    from silodem.study.table import ANALYSIS_VERSION

    write_text(run_dir / SUMMARY_NAME,
               json.dumps({VERSION_KEY: ANALYSIS_VERSION, **summary}, indent=1) + "\n")


def _fsync_dir(path: Path) -> None:
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def tmp_prefix(run_id: str) -> str:
    return f".{run_id}.tmp-"


def run_task(cfg_data: dict[str, Any], study_dir: str, run_id: str) -> dict[str, Any]:
    """The Dask task of one run: run it in ``runs/.<id>.tmp-<uuid>`` and rename that folder to
    ``runs/<id>`` when complete.  Returns a small dict: id, status ('computed', 'existing' or
    'failed'), summary (the per-run results), error, wall_s, host, pid.

    Errors of the run itself (an unstable run, values refused) are deterministic: they are
    returned as status 'failed' (no retry) and the run's folder is kept as ``failed/<id>``.
    Any other error propagates, so that Dask retries the task."""
    from silodem.config import Config
    from silodem.errors import UnstableRunError

    root = Path(study_dir)
    runs = root / "runs"
    final = runs / run_id
    info = {"id": run_id, "host": socket.gethostname(), "pid": os.getpid()}
    if is_finished(final):
        return {**info, "status": "existing", "summary": read_summary(final), "wall_s": 0.0}
    runs.mkdir(parents=True, exist_ok=True)
    tmp = runs / f"{tmp_prefix(run_id)}{uuid.uuid4().hex[:12]}"
    tmp.mkdir()
    t0 = time.perf_counter()
    try:
        write_text(tmp / ATTEMPT_NAME, json.dumps({**info, "started": time.time()}) + "\n")
        cfg = Config.model_validate(cfg_data)
        _run_simulation(cfg, tmp)
        summary = summarise(tmp)
        write_summary(tmp, summary)
        _fsync_dir(tmp)
    except (UnstableRunError, InputError) as exc:
        failed = root / "failed" / run_id
        failed.parent.mkdir(parents=True, exist_ok=True)
        shutil.rmtree(failed, ignore_errors=True)
        try:
            os.rename(tmp, failed)
            where = str(failed)
        except OSError:
            shutil.rmtree(tmp, ignore_errors=True)
            where = "(folder not kept)"
        kind = "unstable" if isinstance(exc, UnstableRunError) else "bad input"
        error = one_line(exc).replace(str(tmp), where)  # its files are in failed/ now
        return {**info, "status": "failed", "error": f"{kind}: {error}",
                "wall_s": time.perf_counter() - t0}
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if final.exists() and not is_finished(final):  # not ours: set aside, never taken as done
        with contextlib.suppress(OSError):
            os.rename(final, runs / f".{run_id}.incomplete-{uuid.uuid4().hex[:12]}")
    try:
        os.rename(tmp, final)  # atomic; fails if another attempt finished first
    except OSError:
        if not is_finished(final):
            raise
        shutil.rmtree(tmp, ignore_errors=True)
        return {**info, "status": "existing", "summary": read_summary(final),
                "wall_s": time.perf_counter() - t0}
    _fsync_dir(runs)
    shutil.rmtree(root / "failed" / run_id, ignore_errors=True)
    return {**info, "status": "computed", "summary": summary, "wall_s": time.perf_counter() - t0}


def _run_simulation(cfg, out: Path) -> None:
    """run_simulation on one thread, without progress bars; numba's thread count restored."""
    import numba

    from silodem.run import run_simulation

    before = numba.get_num_threads()
    try:
        run_simulation(cfg, out, threads=1, progress=False)
    finally:
        numba.set_num_threads(before)


# --- the study -------------------------------------------------------------------------------


@dataclass
class StudyOutcome:
    plan: StudyPlan
    out_dir: Path
    computed: int = 0  # runs computed by this invocation
    skipped: int = 0  # runs found finished (before it started, or by another attempt)
    failed: dict[str, str] = field(default_factory=dict)  # run id -> error
    # finished runs whose results.h5 could not be summarised: run id -> summary_error
    unsummarised: dict[str, str] = field(default_factory=dict)
    undrawn: dict[str, str] = field(default_factory=dict)  # report figure -> its error
    results: dict[str, dict[str, Any]] = field(default_factory=dict)  # run id -> task result
    wall_s: float = 0.0
    table_path: Path | None = None
    report_path: Path | None = None
    where: str = ""  # the cluster used


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
interpreter (about 180 MB once silodem's engine is imported, measured with a LocalCluster
worker) besides its run: 4096 workers would need some 740 GB before a run starts."""


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
            "share the cores, each with its own ~180 MB process. For more, start a Dask "
            "scheduler and workers on other machines and pass its address as the scheduler")


# what a study writes beside its study.toml, and what a single run's folder holds: a folder
# with any of them but no study.toml is not a study's
NOT_A_STUDY = ("report.html", "results.csv", "figures", "results.h5", "config.toml",
               "checkpoint.h5")


def check_study_folder(out_dir: Path) -> None:
    """InputError if ``out_dir`` holds files a study writes (report.html, results.csv,
    figures/) or a run's (results.h5, config.toml, checkpoint.h5) but is no study's folder
    (no study.toml, which every study writes first): a sweep there replaced a single run's
    report.html and put its figures among the run's."""
    if (out_dir / "study.toml").is_file():
        return
    found = [name for name in NOT_A_STUDY if (out_dir / name).exists()]
    if found:
        raise foreign_files(out_dir, found, "study",
                            "it is not a study's folder (no study.toml)", "--out")


def prepare(plan: StudyPlan, out_dir: Path) -> list[PlannedRun]:
    """Create the study folder, save the study file, return the runs still to do."""
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(f"--out {out_dir} is a file, not a folder")
    check_study_folder(out_dir)
    try:
        (out_dir / "runs").mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"--out {out_dir}: cannot create the study folder ({exc})") from None
    write_text(out_dir / "study.toml", plan.study.text)
    return [r for r in plan.runs if not is_finished(out_dir / "runs" / r.id)]


def clean_stale(plan: StudyPlan, out_dir: Path) -> int:
    """Remove the temporary folders of this study's finished runs (left by dead workers or by
    a redundant attempt); the temporary folders of unfinished runs are left alone (another
    sweep may be working on them).  Returns how many were removed."""
    runs = out_dir / "runs"
    removed = 0
    for run in plan.runs:
        if not is_finished(runs / run.id):
            continue
        for tmp in runs.glob(f"{tmp_prefix(run.id)}*"):
            shutil.rmtree(tmp, ignore_errors=True)
            removed += 1
    return removed


Callback = Callable[[PlannedRun, dict[str, Any]], None]


def _record(outcome: StudyOutcome, run: PlannedRun, result: dict[str, Any]) -> None:
    outcome.results[run.id] = result
    if result["status"] == "failed":
        outcome.failed[run.id] = result.get("error", "failed")
    elif result["status"] == "computed":
        outcome.computed += 1
    elif result["status"] == "existing":  # finished meanwhile (another sweep, a stale attempt)
        outcome.skipped += 1


def run_serial(plan: StudyPlan, out_dir: Path, on_done: Callback | None = None) -> StudyOutcome:
    """Run the study in this process, one run after the other (no Dask): the reference that a
    cluster must reproduce."""
    t0 = time.perf_counter()
    out_dir = Path(out_dir).resolve()
    todo = prepare(plan, out_dir)
    outcome = StudyOutcome(plan, out_dir, skipped=len(plan.runs) - len(todo), where="serial")
    for run in todo:
        result = run_task(run.cfg.model_dump(), str(out_dir), run.id)
        _record(outcome, run, result)
        if on_done is not None:
            on_done(run, result)
    clean_stale(plan, out_dir)
    outcome.wall_s = time.perf_counter() - t0
    return outcome


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


def run_on_client(plan: StudyPlan, out_dir: Path, client: Client,
                  on_done: Callback | None = None,
                  say: Callable[[str], None] | None = None) -> StudyOutcome:
    """Submit the runs still to do to a dask.distributed ``client`` and wait for them.

    Task keys are ``silodem-<run id>`` (a resubmitted study reuses them); each task may be
    retried ``TASK_RETRIES`` times after an unexpected error, and the scheduler re-runs the
    task of a worker that dies (up to ``distributed.scheduler.allowed-failures`` times, then
    the run is reported failed with KilledWorker).  With ``say``, a spell without workers is
    reported there (``watching_workers``)."""
    t0 = time.perf_counter()
    out_dir = Path(out_dir).resolve()
    todo = prepare(plan, out_dir)
    outcome = StudyOutcome(plan, out_dir, skipped=len(plan.runs) - len(todo))
    by_key = {}
    futures = []
    for run in todo:
        fut = client.submit(run_task, run.cfg.model_dump(), str(out_dir), run.id,
                            key=f"silodem-{run.id}", pure=False, retries=TASK_RETRIES)
        by_key[fut.key] = run
        futures.append(fut)
    try:
        with watching_workers(client, say):
            _gather(futures, by_key, outcome, on_done)
    except BaseException:
        with shutdown_shield(stopping=True):
            client.cancel(futures)
        raise
    clean_stale(plan, out_dir)
    outcome.wall_s = time.perf_counter() - t0
    return outcome


def result_from_folder(out_dir: Path, run_id: str, error: str) -> dict[str, Any]:
    """The result of a run whose task's result did not come back: read from the run's
    folder when that is finished (the task got there before the scheduler was lost), else
    a failure with ``error`` (the next invocation runs it again)."""
    final = Path(out_dir) / "runs" / run_id
    if not is_finished(final):
        return {"id": run_id, "status": "failed", "error": error}
    attempt = {}
    with contextlib.suppress(OSError, ValueError):
        attempt = json.loads((final / ATTEMPT_NAME).read_text(encoding="utf-8"))
    wall_s = (final / SUMMARY_NAME).stat().st_mtime - attempt.get("started", math.nan)
    return {"id": run_id, "host": attempt.get("host", "?"), "pid": attempt.get("pid", "?"),
            "status": "computed", "summary": read_summary(final), "wall_s": wall_s}


def _gather(futures: list, by_key: dict[str, PlannedRun], outcome: StudyOutcome,
            on_done: Callback | None) -> None:
    """Record each run's result (or its failure) as its future completes."""
    from distributed import as_completed

    for fut in as_completed(futures):
        run = by_key[fut.key]
        try:
            if fut.status != "finished":
                # raises the task's error, or for a cancelled future (a lost scheduler
                # cancels them all) the reason; exception() gives None for the latter
                fut.result()
                raise RuntimeError(f"the task ended as '{fut.status}'")
            result = fut.result()
        except Exception as exc:  # noqa: BLE001 - any error is this run's failure, unless
            # its folder is finished: the task got there before the scheduler was lost.  (A
            # finished task whose result could not be fetched raised ConnectionResetError
            # out of the sweep.)
            error = f"{type(exc).__name__}: {one_line(exc)}"
            if fut.status == "finished" and isinstance(exc, OSError):  # CommClosedError too
                error = f"its result was lost with the connection to the scheduler ({error})"
            result = result_from_folder(outcome.out_dir, run.id, error)
        _record(outcome, run, result)
        if on_done is not None:
            on_done(run, result)


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


def stopped_sweep_text(plan: StudyPlan, out_dir: Path, signum: int) -> str:
    """The line of a sweep stopped by the signal ``signum`` (after its cluster was closed):
    how many of the planned runs are finished (``is_finished``; a run cut off mid-way is not)
    and kept in ``out_dir/runs``, and that repeating the command goes on."""
    import signal

    runs = Path(out_dir) / "runs"
    total = len(plan.runs)
    done = sum(is_finished(runs / r.id) for r in plan.runs)
    left = total - done
    if done == 0:
        text = (f"none of the {total} runs is finished yet; repeat the command to run them"
                if total > 1 else "the run is not finished; repeat the command to run it")
    elif left == 0:
        every = f"all {total} runs are" if total > 1 else "the run is"
        text = (f"{every} finished and kept in {runs}; repeat the command to write "
                f"{Path(out_dir) / 'results.csv'} and the report")
    else:
        verb = "is" if done == 1 else "are"
        other = "the other one" if left == 1 else f"the other {left}"
        text = (f"{done} of {total} runs {verb} finished and kept in {runs}; repeat the "
                f"command to run {other}")
    return text if signum == signal.SIGINT else f"{signal.Signals(signum).name}: {text}"


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
