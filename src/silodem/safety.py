"""Run safety (docs/reliability.md): a run that becomes unphysical is stopped with a
diagnosis; checkpoints are written every ``checkpoint.every_steps`` steps and when SIGINT or
SIGTERM asks the run to stop. (Numbers that give no usable run are refused before it starts
by ``silo.checks.check_numbers``.)

:class:`RunGuard` drives a ``SiloRun`` and is its chunk hook: between two chunks it checks the
state, then saves results.h5 and checkpoint.h5 when they are due or when a signal came.  What
makes a run unstable, and the grain to blame, is :mod:`silodem.instability`'s; the names of
the files in the run's folder are :mod:`silodem.run_folder`'s.
"""

from __future__ import annotations

import signal
import sys
import threading
import time as wallclock
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from silodem import __version__
from silodem.checkpoint import (
    CHECKPOINT_NAME,
    FAILURE_NAME,
    LoadedCheckpoint,
    save_checkpoint,
)
from silodem.config import Config
from silodem.errors import RunInterrupted, UnstableRunError, one_line
from silodem.instability import (
    Problem,
    blame,
    domain_of,
    energy_bound,
    find_problem,
    grain_record,
    grain_text,
    write_json,
)
from silodem.run_folder import DIAGNOSTIC_NAME, RESULTS_NAME, remove_partial_saves
from silodem.silo.checks import law_key_names

if TYPE_CHECKING:
    from silodem.silo.procedure import SiloRun


def _saved_at(path: Path, step_key: str) -> str:
    """' at t = T s (step N, PHASE)' of a checkpoint.h5 (``step_key`` 'step') or results.h5
    ('steps'), from the file's attributes; '' if they cannot be read."""
    import h5py

    try:
        with h5py.File(path, "r") as h5:
            at, step = float(h5.attrs["time"]), int(h5.attrs[step_key])
            phase = h5.attrs.get("phase")
    except (OSError, KeyError, TypeError, ValueError):
        return ""
    phase = f", {phase.decode() if isinstance(phase, bytes) else phase}" if phase else ""
    return f" at t = {at:.4g} s (step {step}{phase})"


class _Stopped(UnstableRunError):
    """An instability already diagnosed and saved (not to be handled twice)."""


class _HardStop(RunInterrupted):
    """A second signal's stop, without saving; ``RunGuard.drive`` adds what is kept."""


def hints(run: SiloRun, problem: Problem, grain: dict[str, Any] | None) -> list[str]:
    """What to change, most likely first, for diagnostic.json: a smaller time step, other
    contact values, the grain to look at; first of all, for a grain that flew up out of the
    open top while the grains' kinetic energy is within ``energy_bound``, the speed and
    elasticity of the grains (a smaller time step does not help there: an audit's elastic
    grains poured at 15 m/s left the same way at a quarter of the step)."""
    cfg = run.cfg
    out = [f"reduce time.safety (now {cfg.time.safety:g}) or set a smaller time.dt",
           (f"check the contact law's values ({law_key_names(cfg)}) and the grain sizes and "
            "density against each other"),
           "look at the grain named here in failure.h5 (same layout as checkpoint.h5)"]
    p = run.sim.particles
    if (problem.kind == "outside_domain" and grain is not None and grain["vy"] > 0.0
            and grain["y"] > run.shape.wall_top and p.kinetic_energy() <= energy_bound(run)):
        m = cfg.material
        damping = (f"material.restitution = {m.restitution:g}" if m.restitution is not None
                   else f"material.damping_ratio = {m.damping_ratio:g}")
        speed = (f"lower fill.initial_speed (now {cfg.fill.initial_speed:g} m/s) or "
                 if cfg.fill.method == "pour" else "")
        out.insert(0, "the grain flew up out of the silo's open top, the grains' energy within "
                      "bounds, as fast and elastic grains do in a stable run: "
                      f"{speed}make the contacts less elastic (now {damping})")
    return out


class RunGuard:
    """Drives a SiloRun with checkpoints, signal handling and instability checks.

    ``out_dir`` is the results folder, ``config_toml`` the run's config as written to it,
    ``resume_from`` a checkpoint to continue from (None: a fresh run)."""

    def __init__(self, out_dir: Path | str, config_toml: str, cfg: Config,
                 resume_from: LoadedCheckpoint | None = None) -> None:
        self.out = Path(out_dir)
        self.config_toml = config_toml
        self.settings = cfg.checkpoint
        self.resume_from = resume_from
        # called with the run once its checkpoint is restored (``drive``): what a resume
        # changes in the folder waits until the checkpoint is known to be usable
        self.after_restore: list[Callable[[SiloRun], None]] = []
        self.stop_signal: int | None = None
        self.hard_stop: int | None = None  # a second signal: stop without saving
        self.stopping = False  # the hard stop is on its way out: further signals wait
        self.ended = False  # the run has come to its end (its final results are written next)
        self.final_write = False  # its final results.h5 is being (or was) written (run.py)
        self.failure: str | None = None  # the instability found, while its state is saved
        self.failure_saved: list[Path] = []  # what of that state is written so far
        self._running = False  # inside ``running``
        self.save_failed = False
        self.last_step = 0
        self.last_wall = wallclock.perf_counter()
        self.last_checkpoint: tuple[int, float] | None = (
            (resume_from.step, resume_from.time) if resume_from is not None else None)

    @property
    def checkpoint_path(self) -> Path:
        return self.out / CHECKPOINT_NAME

    @property
    def results_path(self) -> Path:
        return self.out / RESULTS_NAME

    # --- driving -----------------------------------------------------------------------------
    def drive(self, run: SiloRun) -> None:
        """Restore (when resuming), then run to the end; save on the way (module docstring)."""
        if self.resume_from is not None:
            self.resume_from.restore(run)
            for hook in self.after_restore:
                hook(run)
        run.chunk_hooks.append(self)
        self.last_step = run.sim.steps
        self.last_wall = wallclock.perf_counter()
        with self.running():
            if self.resume_from is None:
                self.save(run, "start")
            try:
                run.run()
            except _Stopped:
                raise
            except UnstableRunError as exc:
                self.failure = one_line(exc)  # (a second signal from here on: ``running``)
                self.fail(run, blame(run, str(exc)), during_step=True)
            self.ended = True

    @contextmanager
    def running(self) -> Iterator[None]:
        """``signals``, and the one line of a second signal's stop (a RunInterrupted naming
        what is kept, ``kept``; of an unstable run whose failure state was being saved, an
        UnstableRunError, ``_cut_short``).  ``drive`` runs in one; a caller may put ``drive``
        in one of its own, and the run's handlers then last until that one ends
        (``run.run_simulation`` closes the progress bar and writes the ended run's final
        results.h5 in it: a signal then is the run's, noted, the write going on to the end, or
        its hard stop, never a bare KeyboardInterrupt)."""
        if self._running:  # the outer one answers
            yield
            return
        self._running = True
        try:
            with self.signals():
                try:
                    yield
                    self._stop_if_hard()  # (one dropped as the bar closed, say)
                except _HardStop as exc:  # (not the first signal's stop, which saved,
                    # although a second signal came: its raise was dropped, in a weakref
                    # callback)
                    self.stopping = True  # a third signal now waits: this line is said first
                    if self.failure is not None:
                        raise _Stopped(self._cut_short(exc)) from None
                    raise RunInterrupted(f"{exc}; {self.kept()}", exc.signum) from None
        finally:
            self._running = False

    def __call__(self, run: SiloRun) -> None:
        """The chunk hook: check the state, then save if a signal came or a save is due."""
        self._stop_if_hard()
        problem = find_problem(run)
        if problem is not None:
            self.fail(run, problem, during_step=False)
        if run.state.phase == "done":
            return
        if self.stop_signal is not None:
            self.interrupt(run, self.stop_signal)
        s = self.settings
        if (run.sim.steps - self.last_step >= s.every_steps
                or wallclock.perf_counter() - self.last_wall >= s.every_wall_seconds):
            try:
                self.save(run, "periodic")
            except OSError as exc:  # a full disk should not end a run that may still finish
                self.last_step = run.sim.steps
                self.last_wall = wallclock.perf_counter()
                if not self.save_failed:
                    run.warnings.append(
                        f"saving results.h5/checkpoint.h5 failed at t = {run.sim.time:.4g} s "
                        f"({one_line(exc)}); the run goes on and tries again later")
                self.save_failed = True

    def completed(self, run: SiloRun) -> None:
        """The run finished and its results are written: the checkpoint is no longer needed."""
        self.checkpoint_path.unlink(missing_ok=True)
        remove_partial_saves(self.out)
        for rec in run.recorders:
            rec.saved_everywhere()

    # --- saving ------------------------------------------------------------------------------
    def _write_results(self, run: SiloRun, status: str) -> None:
        from silodem.output import write_results

        write_results(run, self.results_path, self.config_toml, status=status)

    def save(self, run: SiloRun, reason: str, status: str = "running") -> None:
        """results.h5 (what the run holds so far), then checkpoint.h5 (if enabled)."""
        self._write_results(run, status)
        if self.settings.enabled:
            save_checkpoint(run, self.checkpoint_path, config_toml=self.config_toml,
                            reason=reason)
            self.last_checkpoint = (run.sim.steps, run.sim.time)
        for rec in run.recorders:
            rec.saved_everywhere()
        self.last_step = run.sim.steps
        self.last_wall = wallclock.perf_counter()

    def interrupt(self, run: SiloRun, signum: int) -> None:
        name = signal.Signals(signum).name
        where = (f"at t = {run.sim.time:.4g} s (step {run.sim.steps}, {run.state.phase})")
        try:
            self.save(run, name, status="interrupted")
        except OSError as exc:
            raise RunInterrupted(f"{name} {where}: saving failed ({one_line(exc)}); the last "
                                 f"checkpoint, if any, is in {self.checkpoint_path}",
                                 signum) from None
        if self.settings.enabled:
            text = (f"{name} {where}: checkpoint saved to {self.checkpoint_path}; continue with: "
                    f"silodem run --resume {self.out}")
        else:
            text = (f"{name} {where}: partial results in {self.results_path} (checkpoint.enabled "
                    "is false: the run cannot be resumed)")
        raise RunInterrupted(text, signum)

    def kept(self, *, unstable: bool = False) -> str:
        """What a run stopped without saving (a second signal) leaves, read from its folder:
        the checkpoint on disk, with its time and step, and the command that continues from
        it; or that there is none, and what results.h5 holds.  (The second signal may have cut
        the first one's save short: the checkpoint is then the one before, whole.)
        ``unstable``: the run had become unstable, and a resume comes to the same failure."""
        checkpoint = self.checkpoint_path
        if checkpoint.is_file():
            go_on = (f"'silodem run --resume {self.out}' repeats the run from it to the same "
                     "failure, and saves its state" if unstable else
                     f"continue with: silodem run --resume {self.out}")
            return (f"the last checkpoint, {checkpoint}{_saved_at(checkpoint, 'step')}, is "
                    f"kept; {go_on}")
        if self.settings.enabled:
            none = "no checkpoint was written yet: the run cannot be resumed (start it again)"
        else:
            none = "no checkpoint (checkpoint.enabled is false): the run cannot be resumed"
        results = self.results_path
        if results.is_file():
            return (f"{none}; {results} holds the run up to its last save"
                    f"{_saved_at(results, 'steps')}")
        return f"{none}; nothing was saved"

    def _cut_short(self, exc: RunInterrupted) -> str:
        """The line of an unstable run whose failure state's save a second signal stopped:
        the instability, what of its state was written, what is kept."""
        saving = [self.out / FAILURE_NAME] if self.settings.enabled else []
        saving += [self.results_path, self.out / DIAGNOSTIC_NAME]
        missing = [p.name for p in saving if p not in self.failure_saved]
        if not self.failure_saved:
            written = "before any of it was written"
        else:
            written = f"after writing {', '.join(str(p) for p in self.failure_saved)}"
            if missing:
                written += f" (not {' and '.join(missing)})"
        name = signal.Signals(exc.signum).name
        return (f"{self.failure}; {name} again: stopped at once while saving the failure "
                f"state, {written}; {self.kept(unstable=True)}")

    def fail(self, run: SiloRun, problem: Problem, *, during_step: bool) -> None:
        """Save the state and a diagnosis of an unstable run; raise UnstableRunError (one line).

        A first signal meanwhile lets the saves finish (the line then says it came); a second
        one stops them at once, as it stops a run's save (``running`` then gives the
        instability, what of its state was written and what is kept, ``_cut_short``)."""
        self.failure = one_line(problem.message)
        grain = grain_record(run, problem.index) if problem.index is not None else None
        if grain is not None and problem.kind == "engine":
            self.failure = one_line(f"{problem.message}; {grain_text(grain)}")
        notes: list[str] = []
        failure = self.out / FAILURE_NAME
        failure_written = False
        if self.settings.enabled:
            try:
                save_checkpoint(run, failure, config_toml=self.config_toml, reason="unstable",
                                attrs={"during_step": during_step})
                failure_written = True
                self.failure_saved.append(failure)
            except RunInterrupted:  # a second signal: not a failed save (``running``)
                raise
            except Exception as exc:  # noqa: BLE001 - the diagnosis matters more
                notes.append(f"{FAILURE_NAME} not written: {one_line(exc)}")
            self._stop_if_hard()
        try:
            self._write_results(run, "unstable")
            self.failure_saved.append(self.results_path)
        except RunInterrupted:
            raise
        except Exception as exc:  # noqa: BLE001
            notes.append(f"{RESULTS_NAME} not updated: {one_line(exc)}")
        self._stop_if_hard()
        p = run.sim.particles
        cfg = run.cfg
        diag = {
            "silodem_version": __version__,
            "scenario": cfg.name,
            "kind": problem.kind,
            "message": problem.message,
            "time": run.sim.time,
            "step": run.sim.steps,
            "during_step": during_step,
            "phase": run.state.phase,
            "grain": grain,
            "n_grains": p.n,
            "kinetic_energy": p.kinetic_energy() if p.n else 0.0,
            "energy_bound": energy_bound(run),
            "domain": vars(domain_of(run)),
            "dt": run.dt,
            "dt_crit": run.dt_crit,
            "details": problem.details,
            "failure_state": FAILURE_NAME if failure_written else None,
            "last_checkpoint": (None if self.last_checkpoint is None else
                                {"file": CHECKPOINT_NAME, "step": self.last_checkpoint[0],
                                 "time": self.last_checkpoint[1]}),
            "notes": notes,
            "hints": hints(run, problem, grain),
        }
        path = self.out / DIAGNOSTIC_NAME
        text = self.failure
        try:
            write_json(path, diag)
            self.failure_saved.append(path)
            text += f"; diagnosis in {path}"
        except RunInterrupted:
            raise
        except Exception as exc:  # noqa: BLE001
            text += f"; {DIAGNOSTIC_NAME} not written: {exc}"
        self.stopping = True  # saved: a signal from now on waits for this line
        if failure_written:
            text += f", state in {failure}"
        came = self.hard_stop or self.stop_signal  # (a hard stop dropped in the last save)
        if came is not None:
            text += (f"; {signal.Signals(came).name} received: the run stopped here, once its "
                     "failure state was saved")
        raise _Stopped(one_line(text)) from None

    def _stop_if_hard(self) -> None:
        """Raise the hard stop of a second signal whose raise was dropped (``signals``)."""
        if self.hard_stop is not None:
            raise self._hard_stop_error()

    # --- signals -----------------------------------------------------------------------------
    @contextmanager
    def signals(self) -> Iterator[None]:
        """While inside: SIGINT/SIGTERM ask the run to stop at the end of the current chunk
        (after saving; an unstable run's failure state is saved all the same, and a run that
        has ended writes its results); a second one stops it at once, without saving
        (``running`` then says what is kept, ``kept``); a further one, while that is said,
        waits."""
        if threading.current_thread() is not threading.main_thread():
            yield
            return

        def handler(signum: int, frame: Any) -> None:
            if self.stopping:  # the hard stop is saying what is kept: its line comes
                return
            if self.stop_signal is not None:
                self.hard_stop = signum  # (for the chunk hook, should the raise be dropped)
                raise self._hard_stop_error()
            self.stop_signal = signum
            if sys.stderr.isatty():
                doing = ("saving the unstable run's failure state" if self.failure is not None
                         else "the run has ended: writing its results" if self.ended
                         else "saving at the end of the current chunk")
                sys.stderr.write(f"\nsilodem: {signal.Signals(signum).name}: {doing}; send it "
                                 "again to stop at once\n")

        def unraisable(info: Any) -> None:
            """Python drops an exception raised inside a weakref callback or __del__ (a second
            signal's, now and then) and prints its traceback: this one is kept quiet, and the
            chunk hook raises it again."""
            if not isinstance(info.exc_value, RunInterrupted):
                before_hook(info)

        wanted = (signal.SIGINT, signal.SIGTERM)
        # a signal ignored where silodem was started (SIGINT of 'silodem run ... &' in a
        # script) stays ignored, as Python leaves it: it stopped the run only once this was set
        previous = {s: h for s in wanted if (h := signal.getsignal(s)) is not signal.SIG_IGN}
        for s in previous:
            signal.signal(s, handler)
        before_hook, sys.unraisablehook = sys.unraisablehook, unraisable
        try:
            yield
        finally:
            sys.unraisablehook = before_hook
            for s, old in previous.items():
                signal.signal(s, old if old is not None else signal.SIG_DFL)

    def _hard_stop_error(self) -> RunInterrupted:
        name = signal.Signals(self.hard_stop).name
        what = "without writing its final results" if self.final_write else "without saving"
        return _HardStop(f"{name} again: stopped at once, {what}", self.hard_stop)

    def final_write_stopped(self, signum: int) -> RunInterrupted:
        """The hard stop of the ended run's final write, which ``running`` turns into its line
        (what is kept, ``kept``): a second signal's (whose stop the write may have taken for a
        failed write), or that of a KeyboardInterrupt that did not come through ``signals``
        (the code under the write raised one)."""
        if self.hard_stop is not None:
            return self._hard_stop_error()
        name = signal.Signals(signum).name
        return _HardStop(f"{name}: stopped at once, without writing its final results", signum)
