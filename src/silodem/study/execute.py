"""Running a study on dask.distributed: one task per run, atomic run folders, resumption
(the cluster itself: ``study.cluster``).

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
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from silodem.errors import InputError, one_line
from silodem.output import write_text
from silodem.run_folder import foreign_files
from silodem.study.cluster import shutdown_shield, watching_workers
from silodem.study.plan import PlannedRun, StudyPlan

if TYPE_CHECKING:
    from distributed import Client

SUMMARY_NAME = "summary.json"
ATTEMPT_NAME = "attempt.json"
RESULTS_NAME = "results.h5"
UNSTABLE, REFUSED = "unstable", "bad input"  # run_task's failures, which a new attempt repeats
TASK_RETRIES = 2  # re-runs of a task that raised an unexpected error (a full disk, a lost file)


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
        kind = UNSTABLE if isinstance(exc, UnstableRunError) else REFUSED
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


def other_study_note(plan: StudyPlan, out_dir: Path) -> str | None:
    """The note of a sweep into a folder whose study.toml is another text than ``plan``'s (an
    edited study, or another one), which the sweep replaces: nothing else is lost, since the
    finished runs stay in runs/ (any study that plans them again finds them), but results.csv
    and the report become this study's. None when the file is this study's, or absent."""
    path = Path(out_dir) / "study.toml"
    if _study_file_text(out_dir) in (None, plan.study.text):
        return None
    return (f"silodem: replacing {path}, another study file's text; the finished runs in "
            f"{Path(out_dir) / 'runs'} are kept (a study that plans one again reuses it), and "
            "results.csv and report.html become this study's")


def replaced_study_file(plan: StudyPlan, out_dir: Path) -> bool:
    """Whether ``out_dir``'s study.toml is ``plan``'s study file (``prepare`` wrote it)."""
    return _study_file_text(out_dir) == plan.study.text


def _study_file_text(out_dir: Path) -> str | None:
    """The text of ``out_dir``'s study.toml; None where there is none to read."""
    try:
        return (Path(out_dir) / "study.toml").read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return None


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




def failed_runs_text(failed: dict[str, str], total: int, out_dir: Path) -> str:
    """The line of a sweep some of whose ``total`` runs ``failed`` (run id -> run_task's
    error): how many, the first, and what running the command again does. A run stopped as
    unstable, or refused, is deterministic and fails the same way until its config changes
    (its folder is kept in ``out_dir/failed``); one lost to a worker's death or a full disk
    may finish when run again."""
    first_id, first_error = next(iter(failed.items()))
    lasting = sum(error.startswith((f"{UNSTABLE}: ", f"{REFUSED}: "))
                  for error in failed.values())
    text = (f"error: {len(failed)} of {total} runs failed (first: {first_id}: {first_error}); "
            f"see {Path(out_dir) / 'report.html'}; ")
    if lasting == 0:
        return text + "run the command again to retry them"
    until = "its config changes" if lasting == 1 else "their configs change"
    same = f"will fail the same way again until {until} (folders in {Path(out_dir) / 'failed'})"
    if lasting == len(failed):
        return text + f"{'it' if lasting == 1 else 'they'} {same}"
    return (text + f"run the command again to retry the {len(failed) - lasting} that failed "
            f"otherwise; the {lasting} stopped as unstable or refused {same}")


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
