"""``run_study``: plan -> run what is missing (Dask or serial) -> results.csv -> report.html."""

from __future__ import annotations

import contextlib
import sys
import threading
import time
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, Self

from silodem.errors import InputError, check_flag, short_repr
from silodem.output import write_text
from silodem.study.cluster import check_workers, close_cluster, connect
from silodem.study.execute import (
    StudyOutcome,
    is_finished,
    other_study_note,
    prepare,
    read_summary,
    replaced_study_file,
    run_on_client,
    run_serial,
)
from silodem.study.plan import PlannedRun, StudyPlan

if TYPE_CHECKING:
    from distributed import Client

TABLE_NAME = "results.csv"
REPLACING = "replacing "  # how the warning of another study's study.toml replaced begins


def _warn(text: str) -> None:
    """``text`` as a :class:`silodem.api.SilodemWarning` from the caller of run_study."""
    from silodem.api import SilodemWarning

    warnings.warn(text, SilodemWarning, stacklevel=3)


def collect_rows(plan: StudyPlan, out_dir: Path) -> list[dict[str, Any]]:
    """Table rows of the planned runs whose folders are finished (read from their
    summary.json), in plan order."""
    from silodem.study.table import table_rows

    runs = Path(out_dir) / "runs"
    summaries = {r.id: read_summary(runs / r.id) for r in plan.runs if is_finished(runs / r.id)}
    return table_rows(plan, summaries)


def _earlier_hosts(plan: StudyPlan, out_dir: Path) -> str:
    """Where the finished runs were computed, from their attempt.json (host names)."""
    import json

    from silodem.study.execute import ATTEMPT_NAME

    hosts = set()
    for run in plan.runs:
        try:
            info = json.loads((out_dir / "runs" / run.id / ATTEMPT_NAME).read_text("utf-8"))
            hosts.add(str(info["host"]))
        except (OSError, ValueError, KeyError, TypeError):
            continue
    return ("every run finished before this invocation, on " + (", ".join(sorted(hosts))
            or "hosts not recorded"))


def finish_study(plan: StudyPlan, out_dir: Path, outcome: StudyOutcome | None = None,
                 report: bool = True) -> StudyOutcome:
    """Write DIR/results.csv (from the run folders that exist) and DIR/report.html."""
    from silodem.study.table import table_columns, table_csv

    out_dir = Path(out_dir).resolve()
    if outcome is None:
        outcome = StudyOutcome(plan, out_dir)
    rows = collect_rows(plan, out_dir)
    outcome.unsummarised = {r["id"]: r["summary_error"] for r in rows if "summary_error" in r}
    columns = table_columns(plan.grid_keys, rows)
    outcome.table_path = out_dir / TABLE_NAME
    write_text(outcome.table_path, table_csv(columns, rows))
    if report:
        from silodem.study.report import write_study_report

        outcome.report_path = write_study_report(plan, out_dir, rows, outcome.failed,
                                                 outcome.where, outcome.undrawn)
    return outcome


@contextlib.contextmanager
def _progress_bar(total: int, enabled: bool,
                  slots: int = 1) -> Iterator[Callable[[PlannedRun, dict], None]]:
    """The sweep's bar, and its line per finished run with k/N and the time left
    (:func:`_time_left`, once ``slots`` runs, the runs under way at once, have finished)."""
    if not enabled:
        yield lambda run, result: None
        return
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )
    from rich.progress import Progress as Bar

    console = Console(stderr=True, soft_wrap=True)
    start = _clock()
    count = [0]
    beat = _Heartbeat(console, start, total) if not console.is_terminal else None
    with beat or contextlib.nullcontext(), \
            Bar(TextColumn("[bold]runs"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                TextColumn("left"), TimeRemainingColumn(), TextColumn("{task.description}"),
                console=console, transient=False, disable=not console.is_terminal) as bar:
        # (a log gets the runs' lines, not the bar's last state, 'runs ━━━━ 16/16 ...')
        task = bar.add_task("", total=total)

        def done(run: PlannedRun, result: dict) -> None:
            count[0] += 1  # (each line says how far: a log, where the bar is not drawn, too)
            status = result.get("status", "?")
            where = f"{result.get('host', '?')}:{result.get('pid', '?')}"
            k = f"{count[0]}/{total}, {_time_left(_clock() - start, count[0], total, slots)}"
            if status == "failed":
                text = f"[red]failed[/] {run.id} ({k}): {result.get('error', '')}"
            else:
                text = (f"{status} {run.id} ({result.get('wall_s', 0.0):.1f} s on {where}; "
                        f"{k})")
            bar.console.print(text, highlight=False)
            bar.update(task, advance=1, description=run.slug)
            if beat is not None:
                beat.finished(count[0])

        try:
            yield done
        except BaseException:  # the stop's one line is the last word, not a stale bar ('runs
            if not console.is_terminal:  # 0/16' after a Ctrl-C); a terminal keeps it as drawn
                console.quiet = True
            raise


_clock = time.perf_counter  # the progress lines' clock [s] (a test sets its own)
HEARTBEAT_S = 600.0  # [s] a log's line after this long without a finished run's line


class _Heartbeat:
    """A line on ``console`` each ``HEARTBEAT_S`` seconds in which no run has finished, from
    a daemon thread, while the context is open: a log (stderr to a file, where no bar is
    drawn) of a study whose runs take hours showed nothing between their lines, as if the
    sweep had hung.  A terminal has the bar's elapsed time instead."""

    def __init__(self, console: Any, start: float, total: int) -> None:
        self.console, self.start, self.total = console, start, total
        self.done = 0
        self.last = time.monotonic()  # (real time: the thread waits on it)
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, name="silodem-heartbeat", daemon=True)

    def __enter__(self) -> Self:
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        self.thread.join()

    def finished(self, done: int) -> None:
        """A run's line was just printed: the next heartbeat is HEARTBEAT_S from now."""
        self.done, self.last = done, time.monotonic()

    def _run(self) -> None:
        while not self.stop.wait(max(self.last + HEARTBEAT_S - time.monotonic(), 0.0)):
            if time.monotonic() - self.last >= HEARTBEAT_S:
                self.console.print(
                    f"still running: {self.done}/{self.total} runs finished after "
                    f"{_duration(_clock() - self.start)}; the others are under way or "
                    "waiting for a worker", highlight=False, markup=False)
                self.last = time.monotonic()


def _duration(seconds: float) -> str:
    """'80 s', '13 min' or '2.0 h'."""
    if seconds < 90.0:
        return f"{seconds:.0f} s"
    if seconds < 5400.0:
        return f"{seconds / 60.0:.0f} min"
    return f"{seconds / 3600.0:.1f} h"


def _time_left(elapsed: float, done: int, total: int, slots: int = 1) -> str:
    """'about 12 min left' after ``done`` of ``total`` runs in ``elapsed`` seconds: the mean
    time between finished runs so far, times the runs still to come; 'all done' at the end.
    Not before ``slots`` runs have finished, ``slots`` being the runs under way at once: the
    first of 16 runs on 16 workers finishes when all 16 are nearly done, and the mean time
    between finished runs is then 16 times too long."""
    if done >= total:
        return "all done"
    if done < slots:
        return f"time left said once {slots} runs have finished"
    return f"about {_duration(elapsed / done * (total - done))} left"


def other_code_note(plan: StudyPlan, out_dir: Path) -> str | None:
    """The warning that finished runs in ``out_dir/runs`` were computed, wholly or in part,
    by other silodem code than this (their results.h5's ``silodem_source`` or
    ``silodem_source_started``, provenance.py, differs): a study resumed after an update
    mixes two engines' results.  Runs that recorded none (written before the digest existed)
    or ``UNKNOWN`` are not judged.  None when every recorded one is this code's."""
    import h5py

    from silodem.provenance import other_code, source_digest
    from silodem.study.execute import RESULTS_NAME

    theirs, finished = {}, 0
    for run in plan.runs:
        folder = out_dir / "runs" / run.id
        if not is_finished(folder):
            continue
        finished += 1
        try:
            with h5py.File(folder / RESULTS_NAME, "r") as h5:
                made = [h5.attrs.get(key) for key in ("silodem_source_started",
                                                      "silodem_source")]
        except (OSError, ValueError):  # (an unreadable file is the summary's to report)
            continue
        other = next((d for d in map(other_code, made) if d is not None), None)
        if other is not None:
            theirs[run.id] = other
    if not theirs:
        return None
    first, digest = next(iter(theirs.items()))
    return (f"{len(theirs)} of the {finished} finished runs in {out_dir / 'runs'} were computed "
            f"by other silodem code (source {digest}, this is {source_digest()}; first: "
            f"{first}): they are kept and tabled beside this code's; delete their folders to "
            "compute them again with this code")


def _slots(client: Any) -> int:
    """How many runs ``client``'s workers take at once (their threads), at least 1; 1 where
    it cannot say."""
    try:
        return max(1, int(sum(client.nthreads().values())))
    except Exception:  # noqa: BLE001 - a client that cannot say: the time left comes sooner
        return 1


def _stderr_line(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def run_study(plan: StudyPlan, out_dir: Path | str, *, scheduler: str | None = None,
              workers: int | None = None, client: Client | None = None, serial: bool = False,
              progress: bool = False, report: bool = True) -> StudyOutcome:
    """Run every planned run that has no finished folder in ``out_dir/runs``, then write
    ``out_dir/results.csv`` and ``out_dir/report.html``.

    Where: ``serial`` in this process; else on ``client`` (a dask.distributed Client) if
    given; else on the scheduler at ``scheduler``; else on a new LocalCluster of ``workers``
    single-threaded processes (default one per core), closed at the end.  Nothing is started
    when every run is finished already.  A study.toml of another study in ``out_dir`` is
    replaced with a :class:`silodem.api.SilodemWarning` (its finished runs are kept), and
    finished runs computed by other silodem code are named in another (:func:`other_code_note`)."""
    if not isinstance(plan, StudyPlan):
        raise InputError(f"run_study takes a plan from expand(load_study(...)); got a "
                         f"{type(plan).__name__}")
    if not isinstance(out_dir, str | Path) or not str(out_dir).strip():
        raise InputError(f"out_dir must be the study's folder path; got {short_repr(out_dir)}")
    for flag, name in ((serial, "serial"), (progress, "progress"), (report, "report")):
        check_flag(flag, name)
    if client is not None and not callable(getattr(client, "submit", None)):
        raise InputError(f"client must be a dask.distributed Client; got {short_repr(client)} (an "
                         "address goes in scheduler=...)")
    check_workers(workers, local=scheduler is None and client is None and not serial)
    say = _stderr_line if progress else None
    t0 = time.perf_counter()
    out_dir = Path(out_dir).resolve()
    own = cluster = None  # a client (and local cluster) connected here, closed here
    if not serial and client is None and not all(is_finished(out_dir / "runs" / r.id)
                                                  for r in plan.runs):
        # before the folder is made: a scheduler that cannot be reached leaves none
        own, cluster, where = connect(scheduler, workers, say)
    replacing = other_study_note(plan, out_dir)
    try:
        todo = prepare(plan, out_dir)
        if replacing is not None and replaced_study_file(plan, out_dir):
            _warn(replacing.removeprefix("silodem: "))  # (the command line says it its way)
        other_code = other_code_note(plan, out_dir)
        if other_code is not None:
            _warn(other_code)
        if not todo:
            outcome = StudyOutcome(plan, out_dir, skipped=len(plan.runs),
                                   where=_earlier_hosts(plan, out_dir))
        elif serial:
            with _progress_bar(len(todo), progress) as on_done:
                outcome = run_serial(plan, out_dir, on_done)
        elif own is None:
            with _progress_bar(len(todo), progress, _slots(client)) as on_done:
                outcome = run_on_client(plan, out_dir, client, on_done, say)
            outcome.where = f"Dask client of {client.scheduler.address}"
        else:
            with _progress_bar(len(todo), progress, _slots(own)) as on_done:
                # (a local cluster's nannies restart its workers: only an external
                # scheduler's are watched)
                outcome = run_on_client(plan, out_dir, own, on_done,
                                        say if cluster is None else None)
            outcome.where = where
    except BaseException:  # a signal (or an error): the shutdown is finished before it goes on
        close_cluster(own, cluster, stopping=True)
        raise
    close_cluster(own, cluster, stopping=False)
    outcome = finish_study(plan, out_dir, outcome, report=report)
    outcome.wall_s = time.perf_counter() - t0
    return outcome
