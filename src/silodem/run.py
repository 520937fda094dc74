"""Run one configured silo end to end and write its results folder.

Data path: Config -> SiloRun (walls, grains, Simulation) -> fill -> settle -> discharge
-> results folder (config.toml, results.h5, settled.png, final.png, report.html).
"""

from __future__ import annotations

import contextlib
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

from silodem.checkpoint import LoadedCheckpoint, read_checkpoint
from silodem.config import Config
from silodem.errors import InputError, RunInterrupted, short_repr
from silodem.measure.recorders import recorders_for
from silodem.output import write_results, write_text, write_views
from silodem.run_folder import (
    clear_previous_run,
    ended_unstable,
    folder_lock,
    remove_pictures,
    run_config_text,
)
from silodem.safety import RunGuard
from silodem.signals import noted_signals, signal_of
from silodem.silo.checks import check_numbers
from silodem.silo.frame_store import FramesRecorder
from silodem.silo.procedure import LOST_TOTAL, NOT_SETTLED, PHASES, Progress, SiloRun


@dataclass
class RunSummary:
    name: str
    out_dir: Path
    wall_seconds: float
    steps: int
    dt: float
    events: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    # the warnings' texts printed on stderr as they came; one rewritten since (the running
    # total of lost grains) has a new text, which the summary then gives
    warnings_shown: frozenset[str] = frozenset()
    resumed_at: int = 0  # the step a resumed run went on from (0: not resumed)

    def lines(self, *, shown_above: bool = False) -> list[str]:
        """The summary's lines.  ``shown_above``: stdout and stderr are one stream (a
        terminal, or ``2>&1``), where the warnings printed as they came are counted, not
        printed twice."""
        e = self.events
        leg = (f", {self.steps - self.resumed_at} of them after the resume from step "
               f"{self.resumed_at}," if self.resumed_at else "")  # (the wall time is theirs)
        poured = e.get("n_poured", 0)
        settled = "not settled after" if any(w.startswith(NOT_SETTLED) for w in self.warnings) \
            else "settled in"  # (settle.max_time passed: the warning says how far it was)
        out = [
            (f"scenario {self.name}: {self.steps} steps of dt = {self.dt:.3g} s{leg} in "
             f"{self.wall_seconds:.1f} s wall time"),
            (f"fill: {poured} grain{'' if poured == 1 else 's'} in "
             f"{e.get('fill_time', 0):.2f} s; {settled} {e.get('settle_time', 0):.2f} s, at a "
             f"fill level of {e.get('fill_level', 0):.2f} m"),
        ]
        if "discharge_end_reason" in e:
            out.append(
                f"discharge: {100 * e['discharged_fraction']:.1f}% of the mass left through the "
                f"outlet in "
                f"{e['discharge_time']:.2f} s (ended by: {e['discharge_end_reason']})"
            )
        shown = self.warnings_shown if shown_above else frozenset()
        above = sum(w in shown for w in self.warnings) + (LOST_TOTAL in shown)
        if above:
            total = (" (with the running total of grains lost, whose end follows)"
                     if LOST_TOTAL in shown else "")
            out.append(f"warnings: {above} printed above as they came{total}")
        out += [f"warning: {w}" for w in self.warnings if w not in shown]
        out.append(f"results: {self.out_dir}")
        return out


def check_out(out: Path, flag: str = "out", *, make: bool = True) -> None:
    """Refuse (InputError) an output folder that is a file, lies under a file, cannot be
    created or written, or holds an unfinished run (a checkpoint.h5, unless the run was stopped
    as unstable: a new run replaces that one, ``run_folder.ended_unstable``); create it (with
    ``make`` False, only try: the folders made are removed again).  ``flag`` names it in the
    message (``--out`` on the command line)."""
    try:
        _check_out_folder(Path(out), flag, make)
    except OSError as exc:  # a name too long, a system folder (/proc, /sys), ...
        raise InputError(f"{flag} {out}: cannot write a folder there ({exc.strerror})") from None
    except ValueError as exc:  # a NUL character in the path
        raise InputError(f"{flag} {out!r}: not a usable path ({exc})") from None


def _check_out_folder(out: Path, flag: str, make: bool) -> None:
    if out.exists() and not out.is_dir():
        raise InputError(f"{flag} {out} is a file, not a folder; give a folder for the results "
                         "(created if missing)")
    for folder in (out, *out.parents):
        if folder.is_symlink() and not folder.exists():  # (mkdir said only "File exists")
            raise InputError(f"{flag} {out}: {folder} is a symbolic link to "
                             f"{os.readlink(folder)}, which does not exist (or is a loop)")
        if folder.exists():
            if not folder.is_dir():
                raise InputError(f"{flag} {out}: {folder} is a file, not a folder")
            if not os.access(folder, os.W_OK | os.X_OK):
                raise InputError(f"{flag} {out}: no permission to write in {folder}")
            _check_path_room(out, folder, flag)
            break
    if (out / "checkpoint.h5").exists() and not ended_unstable(out):  # (an unstable run's is
        # replaced: a resume is bit-identical, it only comes to the same failure again)
        raise InputError(f"{flag} {out} holds an unfinished run (checkpoint.h5); continue it with "
                         f"'silodem run --resume {out}', or delete {out / 'checkpoint.h5'} to "
                         "start afresh there")
    made: list[Path] = []  # the folders made here, removed again if a deeper one fails
    try:
        for folder in reversed([f for f in (out, *out.parents) if not f.exists()]):
            folder.mkdir()
            made.append(folder)
    except OSError:  # (a name too long: an empty runs/ was left behind)
        _remove(made)
        raise
    if not make:
        _remove(made)


# bytes a run's own names add to its folder's path: the longest, the temporary file of
# figures/fig7_switch_zone_evolution.png (43 bytes), and room for longer frame counters
PATH_ROOM = 48


def _check_path_room(out: Path, existing: Path, flag: str) -> None:
    """InputError when ``out``'s absolute path leaves no room under the system's limit
    (PATH_MAX of ``existing``, the deepest folder of it there is) for the files a run writes
    in it (:data:`PATH_ROOM`): a path of 4077 bytes made its 20 folders, then failed on its
    first file (an audit); this refuses it before any folder is made."""
    try:
        limit = os.pathconf(existing, "PC_PATH_MAX")
    except (OSError, ValueError):  # (no such limit here)
        return
    size = len(os.fsencode(out.absolute()))
    if size + 1 + PATH_ROOM >= limit:
        raise InputError(f"{flag} {out}: a path of {size} bytes leaves no room for the files "
                         f"a run writes in it (up to {PATH_ROOM} bytes more) under the system's "
                         f"limit of {limit} bytes; give a shorter path")


def _remove(made: list[Path]) -> None:
    """Remove the empty folders ``made`` (parents first in the list), deepest first."""
    for folder in reversed(made):
        with contextlib.suppress(OSError):
            folder.rmdir()


def check_threads(threads: int | None, what: str = "threads") -> None:
    """InputError unless ``threads`` is None or a thread count numba may use here."""
    if threads is None:
        return
    import numba

    top = int(numba.config.NUMBA_NUM_THREADS)
    if isinstance(threads, bool) or not isinstance(threads, int) or not 1 <= threads <= top:
        raise InputError(f"{what} must be an integer from 1 to {top} (the number of threads "
                         f"numba may use here, NUMBA_NUM_THREADS); got {short_repr(threads)}")


def _set_threads(threads: int | None) -> None:
    if threads is not None:
        import numba

        numba.set_num_threads(int(threads))


def run_simulation(cfg: Config, out_dir: Path | str, *, threads: int | None = None,
                   progress: bool = True,
                   resume_from: LoadedCheckpoint | None = None) -> RunSummary:
    """Run ``cfg`` and write its results folder ``out_dir``; return a summary.

    Checkpoints, SIGINT/SIGTERM and unstable runs: see ``silodem.safety`` and
    docs/reliability.md.  ``resume_from``: continue from this checkpoint (resume_simulation).
    The folder is locked while the run writes there (``run_folder.folder_lock``): a second
    run, or resume, of it is refused."""
    check_numbers(cfg)
    _set_threads(threads)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    with folder_lock(out):  # (before anything in the folder is touched)
        return _run_in(cfg, out, progress, resume_from)


def _run_in(cfg: Config, out: Path, progress: bool,
            resume_from: LoadedCheckpoint | None) -> RunSummary:
    """run_simulation's body, in the folder ``out`` it holds the lock of."""
    from silodem.scenario_files import config_to_toml

    toml_text = config_to_toml(cfg)
    guard = RunGuard(out, toml_text, cfg, resume_from)
    if resume_from is None:
        clear_previous_run(out)
        write_text(out / "config.toml", run_config_text(toml_text))
    else:  # once the checkpoint is restored: a resume it refuses leaves the folder as it was
        guard.after_restore.append(
            lambda run: _resumed_in(out, cfg, toml_text, run, resume_from.attrs))
    recorders = [FramesRecorder.from_config(cfg, out), *recorders_for(cfg)]
    t0 = time.perf_counter()
    live: dict = {"run": None, "warned": 0, "printed": set(), "phase": "", "logged": 0.0}
    written = False  # the ended run's complete results.h5
    try:
        # the run's handlers (``RunGuard.running``), from its start until its final results.h5
        # is written: a signal meanwhile is the run's, never a bare KeyboardInterrupt
        with contextlib.ExitStack() as handled:
            if progress:
                run = _run_with_bar(cfg, guard, recorders, live, handled)
            else:
                run = SiloRun(cfg, recorders=recorders)
                handled.enter_context(guard.running())
                guard.drive(run)
            _write_final(guard, run, toml_text)
            written = True
    except KeyboardInterrupt as exc:
        if not written:  # before the run started: the command's own 'interrupted'
            raise
        # just after the run's handlers were put back: the run is done, as with a signal in
        # its last chunk (it stops once its checkpoint is removed)
        guard.stop_signal = guard.stop_signal or signal_of(exc)
    except RunInterrupted as exc:
        if not written:
            raise
        # a second signal's stop in the moment after the final write, before the handlers
        # were put back: the results are complete all the same
        guard.stop_signal = exc.signum
    resumed_at = resume_from.step if resume_from is not None else 0
    return _finish(cfg, guard, run, toml_text, t0, frozenset(live["printed"]), resumed_at)


def _resumed_in(out: Path, cfg: Config, toml_text: str, run: SiloRun,
                checkpoint_attrs: dict) -> None:
    """Ready the folder of a resumed run, its checkpoint restored: remove the pictures of the
    run so far (they would stay beside the finished run's results), and write config.toml as
    the checkpoint's config, with a warning when it was edited since (the edit was dropped
    without a word, an audit): the run goes on with the config of its checkpoint.  A
    checkpoint written by other code (its ``silodem_source``, provenance.py) is warned about
    and recorded (results.h5 ``silodem_source_started``)."""
    from silodem.provenance import other_code, source_digest
    from silodem.scenario_files import config_from_text

    started = other_code(checkpoint_attrs.get("silodem_source"))
    if started is not None:
        run.started_by = started
        said = (f"the run was started by other silodem code (source {started}) than the code "
                f"it goes on with (source {source_digest()}): its results mix the two "
                "(results.h5 records both)")
        if said not in run.warnings:  # (a second resume restores the first one's warning)
            run.warnings.append(said)
    remove_pictures(out)
    path = out / "config.toml"
    try:
        edited = config_from_text(path.read_text(encoding="utf-8"), str(path)) != cfg
    except (OSError, UnicodeDecodeError, InputError):  # removed, or no config any more
        edited = path.exists()
    if edited:
        run.warnings.append(
            f"config.toml in {out} was changed after the run stopped: a resume goes on with "
            "the config its checkpoint holds, written to config.toml again (to run the "
            "edited config, start a new run with a copy of it)")
    write_text(path, run_config_text(toml_text))


def _write_final(guard: RunGuard, run: SiloRun, toml_text: str) -> None:
    """Write the ended run's complete results.h5, under the run's handlers: a first signal
    meanwhile is noted and the write goes on (the run then stops as after a signal in its last
    chunk, ``_finish``); a second one stops it at once (the atomic write leaves results.h5 as
    the last save's, and ``RunGuard.running`` names the checkpoint kept).  A failed write (a
    full disk) says what is kept (``_kept``)."""
    guard.final_write = True
    try:
        write_results(run, guard.results_path, toml_text)
    except KeyboardInterrupt as exc:  # not through the run's handlers: a hard stop all the same
        raise guard.final_write_stopped(signal_of(exc)) from None
    except OSError as exc:
        if guard.hard_stop is not None:  # (a second signal's stop, seen as a failed write)
            raise guard.final_write_stopped(guard.hard_stop) from None
        where = f" ({exc.filename})" if exc.filename else ""  # a full disk: say what is kept
        raise OSError(exc.errno, f"{exc.strerror or exc}{where} while the run's final results "
                      f"were written to {guard.results_path}; {_kept(guard)}") from None


def _run_with_bar(cfg: Config, guard: RunGuard, recorders: list, live: dict,
                  handled: contextlib.ExitStack) -> SiloRun:
    """Make the run and drive it to its end under a progress bar on stderr; the run's signal
    handlers (``RunGuard.running``) go on ``handled``, the caller's, which holds them until the
    final results are written: the bar is closed while they answer (a signal then is the
    run's, noted: its results are written, then it stops), not a bare KeyboardInterrupt."""
    from rich.console import Console
    from rich.progress import BarColumn, TextColumn, TimeElapsedColumn
    from rich.progress import Progress as Bar

    console = Console(stderr=True, soft_wrap=True)
    with contextlib.ExitStack() as closing:
        bar = closing.enter_context(
            Bar(TextColumn("[bold]{task.fields[phase]:<9}"), BarColumn(),
                TextColumn("{task.description}"), TimeElapsedColumn(), console=console,
                transient=False, disable=not console.is_terminal))
        # (a log file gets the lines of show() and no bar: rich drew its last state
        # at the end, bar characters and an elapsed time that was not the run's)
        task = bar.add_task("compiling kernels...", total=3, phase="start")

        def show(pr: Progress) -> None:
            rate = (f"{pr.steps_per_s:8.0f} steps/s" if math.isfinite(pr.steps_per_s)
                    else "kernels compiled")
            text = f"t = {pr.time:7.3f} s  grains {pr.particles:6d}  {rate}  {pr.detail}"
            bar.update(task, completed=PHASES.index(pr.phase), phase=pr.phase,
                       description=text)
            now = time.perf_counter()
            if not console.is_terminal and (pr.phase != live["phase"]
                                            or now - live["logged"] >= LOG_EVERY_S):
                # a log file gets no bar until the end: a line now and then instead
                console.print(f"{pr.phase:<9} {text}".rstrip(), markup=False, highlight=False)
                live["phase"], live["logged"] = pr.phase, now
            _warn_new(console, live)

        try:
            run = SiloRun(cfg, on_progress=show, recorders=recorders)
            live["run"] = run
            _warn_new(console, live)
            handled.enter_context(guard.running())
            guard.drive(run)
            bar.update(task, completed=3)
            closing.close()  # the bar's last state (its with block then closes nothing)
        except BaseException:  # the error's one line is the last word, not a stale bar
            if not console.is_terminal:  # (a terminal shows the bar as it was drawn)
                console.quiet = True
            raise
    return run


def _finish(cfg: Config, guard: RunGuard, run: SiloRun, toml_text: str, t0: float,
            shown: frozenset[str], resumed_at: int = 0) -> RunSummary:
    """Remove the checkpoint of the ended run, whose complete results.h5 is written
    (``_write_final``), draw its pictures and report; a signal on the way, or one that came in
    its last chunk or during the final write, ends it with a line that says where its results
    are."""
    out = guard.out
    noted: list[int] = []  # signals while the pictures were drawn
    try:
        with noted_signals(hold=True):  # (a checkpoint left beside complete results would
            guard.completed(run)        # block a new run there, and resume an ended one)
        if guard.stop_signal is not None:  # it came in the last chunk: the run is complete
            raise RunInterrupted(f"as the run ended; its complete results are in "
                                 f"{out / 'results.h5'} ('silodem plot {out}' draws its "
                                 "pictures and report.html)", guard.stop_signal)
        with noted_signals(hold=False) as noted:
            write_views(out)
            if cfg.measure.report:
                _write_report(out, run.warnings)
        if noted:  # its KeyboardInterrupt was raised in a callback that dropped it (a weakref's)
            raise KeyboardInterrupt
        return RunSummary(cfg.name, out, time.perf_counter() - t0, run.sim.steps, run.dt,
                          dict(run.events), list(run.warnings), shown, resumed_at)
    except KeyboardInterrupt as exc:
        signum = noted[0] if noted else signal_of(exc)
        raise RunInterrupted(f"after the run's results were written to {out / 'results.h5'}; "
                             f"'silodem plot {out}' draws its pictures and report.html",
                             signum) from None


def _kept(guard: RunGuard) -> str:
    """What an ended run whose final results.h5 was not written keeps."""
    if guard.checkpoint_path.exists() and guard.last_checkpoint is not None:
        step, at = guard.last_checkpoint
        return (f"the last checkpoint, at t = {at:.4g} s (step {step}), is kept: once the cause "
                f"is mended, 'silodem run --resume {guard.out}' goes on from there")
    return f"{guard.out / 'results.h5'} holds the run up to its last save"


LOG_EVERY_S = 30.0  # wall seconds between progress lines when stderr is not a terminal


def _warn_new(console, live: dict) -> None:
    """Print the run's warnings not printed yet, as they come (a periodic save that failed
    on a full disk was said only in the summary, which a failed final write never printed)."""
    from rich.markup import escape

    run = live["run"]
    if run is None:
        return
    for w in run.warnings[live["warned"]:]:  # (a total rewritten in place is not repeated)
        if w.startswith(LOST_TOTAL):  # a running total: said as such, the summary gives the end
            console.print("[yellow]warning:[/] grains lost so far: "
                          + escape(w.removeprefix(LOST_TOTAL)))
            live["printed"].add(LOST_TOTAL)  # (counted in the summary; no warning is this)
            continue
        console.print(f"[yellow]warning:[/] {escape(w)}")  # (a '[...]' in it is no markup)
        live["printed"].add(w)
    live["warned"] = len(run.warnings)


def _write_report(out: Path, warnings: list[str]) -> None:
    """report.html with every figure (silodem.report); results.h5 is already safe, so a
    failure here is reported as a warning with the command that retries it."""
    from silodem.report import write_report

    try:
        write_report(out)
    except Exception as exc:  # noqa: BLE001 - the run's results are written; say so, go on
        warnings.append(f"report.html not written ({type(exc).__name__}: {exc}); retry with "
                        f"'silodem plot {out}'")


def resume_simulation(out_dir: Path | str, *, threads: int | None = None,
                      progress: bool = True,
                      checkpoint: LoadedCheckpoint | None = None) -> RunSummary:
    """Continue the interrupted run whose results folder is ``out_dir`` from its
    checkpoint.h5, with the config saved in it; it ends bit-identical to an uninterrupted run
    (docs/reliability.md).  A missing or unreadable checkpoint raises CheckpointError.
    ``checkpoint``: that file already read with :func:`read_checkpoint` (the CLI reads it
    first, so that it announces only a run it can resume)."""
    if checkpoint is None:
        checkpoint = read_checkpoint(out_dir)
    return run_simulation(checkpoint.config, out_dir, threads=threads, progress=progress,
                          resume_from=checkpoint)
