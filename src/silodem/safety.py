"""Run safety (docs/reliability.md): a run that becomes unphysical is stopped with a
diagnosis; checkpoints are written every ``checkpoint.every_steps`` steps and when SIGINT or
SIGTERM asks the run to stop. (Numbers that give no usable run are refused before it starts
by ``silo.checks.check_numbers``.)

:class:`RunGuard` drives a ``SiloRun`` and is its chunk hook: between two chunks it checks the
state, then saves results.h5 and checkpoint.h5 when they are due or when a signal came.

A run is stopped as unstable (exit code 3) when, between two chunks,

* a grain has a non-finite position, velocity or spin;
* a grain is outside the domain: the silo's bounding box grown by one silo size
  L = max(cell width, wall height) on every side (grains that slip just through a wall are
  removed by the procedure and reported as lost; a grain that far away was thrown); of a
  grain under the removal level, discharged and removed at the next chunk, only x is tested;
* every grain has gone out through the walls, after pouring and with none discharged;
* the kinetic energy exceeds ``ENERGY_FACTOR`` times the energy the grains in the silo could gain
  by falling from the wall top to the removal level under the outlet, plus their pouring energy:
  E_max = 100 * M * (max(g, 9.81 m/s^2) * (z_top - z_remove) + v0^2 / 2);

or when the engine raises :class:`UnstableRunError` inside a step (non-finite position, grains
spread over a huge area).  The grain to blame is found from the arrays (lowest uid among the
non-finite ones, else the farthest out, else the most energetic / fastest).
"""

from __future__ import annotations

import json
import math
import signal
import sys
import threading
import time as wallclock
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from silodem import __version__
from silodem.atomic import atomic_file
from silodem.checkpoint import (
    CHECKPOINT_NAME,
    FAILURE_NAME,
    LoadedCheckpoint,
    save_checkpoint,
)
from silodem.config import Config
from silodem.errors import InputError, RunInterrupted, UnstableRunError, one_line
from silodem.silo import frame_store
from silodem.silo.checks import law_key_names
from silodem.silo.frames import FOLDER

if TYPE_CHECKING:
    from silodem.silo.procedure import SiloRun

ENERGY_FACTOR = 100.0
DIAGNOSTIC_NAME = "diagnostic.json"
RESULTS_NAME = "results.h5"
_STATE_FIELDS = ("x", "y", "vx", "vy", "omega")


# what a run and its pictures write into the folder (the VTK writer clears its own files)
ANIMATIONS = ("animation.mp4", "animation.gif")  # silodem animate's default names
_RUN_FILES = (RESULTS_NAME, "report.html", "settled.png", "final.png", DIAGNOSTIC_NAME,
              FAILURE_NAME, *ANIMATIONS)


def _replaced_files(out: Path) -> list[Path]:
    """The files of ``out`` that ``clear_previous_run`` removes by name (not the frames' and
    VTK writers' own files, which they recognise); an unstable run's checkpoint.h5 among them
    (``ended_unstable``)."""
    found = [out / name for name in _RUN_FILES if (out / name).exists()]
    figures = out / "figures"
    if figures.is_dir():
        found += sorted(figures.glob("*.png"))
    if (out / CHECKPOINT_NAME).exists() and ended_unstable(out):
        found.append(out / CHECKPOINT_NAME)
    return found


def ended_unstable(out: Path) -> bool:
    """Whether the last run in ``out`` was stopped as unstable: its results.h5, written by
    silodem, has ``status = "unstable"`` (a resume of it, or a new run, rewrites that file at
    its first save).  The checkpoint.h5 such a run leaves is the last good state before the
    failure, with the failing config: a resume is bit-identical and comes to the same failure,
    so a new run there (the config mended) replaces it with the run's other files, instead of
    being refused as over an unfinished run."""
    attrs = _silodem_attrs(out / RESULTS_NAME)
    status = attrs.get("status") if attrs is not None else None
    if isinstance(status, bytes):
        status = status.decode(errors="replace")
    return status == "unstable"


def _silodem_attrs(results: Path) -> dict[str, Any] | None:
    """The root attributes of ``results`` when silodem wrote it (it has ``silodem_version``);
    None for another file, or one that cannot be read."""
    import h5py

    try:
        with h5py.File(results, "r") as h5:
            return dict(h5.attrs) if "silodem_version" in h5.attrs else None
    except (OSError, ValueError):
        return None


def _written_by_silodem(results: Path) -> bool:
    return _silodem_attrs(results) is not None


def check_replaceable(out: Path, flag: str = "out") -> bool:
    """Whether ``out`` holds an earlier run's files, which a new run there replaces; InputError
    if it holds files of those names that no silodem run wrote (no config.toml beside them, or
    a results.h5 without silodem's attributes): a user's own results.h5 or figures/*.png in a
    folder given as ``--out`` were deleted without a word."""
    found = _replaced_files(out)
    if not found:
        return False
    results = out / RESULTS_NAME
    foreign = not (out / "config.toml").is_file() or (
        results.exists() and not _written_by_silodem(results))
    if foreign:
        more = f" (+{len(found) - 1} more)" if len(found) > 1 else ""
        raise InputError(f"{flag} {out} holds {found[0].relative_to(out)}{more}, which a run "
                         "there would replace, but no silodem run wrote it (no config.toml "
                         "and silodem results.h5 there); give a new or empty folder, or move "
                         "those files")
    return True


def replacing_note(out: Path, flag: str = "out") -> str | None:
    """What a new run in ``out`` replaces, in the words of the command line's note (printed on
    stderr) and of the API's warning; None when there is nothing to replace.  InputError as
    :func:`check_replaceable` for files no silodem run wrote."""
    unstable = ended_unstable(out)  # (read before anything is replaced)
    if not check_replaceable(out, flag):
        return None
    if unstable:
        return (f"replacing the earlier unstable run in {out}, its checkpoint.h5 included (a "
                "resume of it only comes to the same failure)")
    return f"replacing the earlier run's results in {out}"


def clear_previous_run(out: Path) -> None:
    """Remove from ``out`` the files an earlier run wrote there (results.h5, its pictures and
    report, a failed run's diagnosis and failure state, an unstable run's checkpoint.h5
    (``ended_unstable``); only these names, ``figures/*.png``, the frames'
    segment files in ``frames/`` and the VTK writer's own files in ``vtk/``), so that a
    fresh run's folder never shows the old run's results beside the new config, even if the
    new run is stopped before its first save or writes no VTK files.  InputError, removing
    nothing, where those files are not a silodem run's (``check_replaceable``)."""
    from silodem.viz.vtk import remove_written

    check_replaceable(out)
    for path in _replaced_files(out):
        path.unlink(missing_ok=True)
    remove_partial_saves(out)
    frame_store.clear(out / FOLDER)
    remove_written(out / "vtk")


def remove_partial_saves(out: Path) -> None:
    """Remove the temporary files (``atomic.atomic_file``'s ``.NAME.tmp``) of results.h5,
    checkpoint.h5, config.toml and the run's other files (``_RUN_FILES``: pictures, report,
    an unstable run's failure.h5 and diagnostic.json) that a SIGKILL in the middle of a save
    left in ``out``: the next save of the same file replaced them, but a run that saved no
    more (it ended, or checkpoints are off) kept a stale copy of a checkpoint beside its
    results, and a failure save cut short left its partial failure.h5."""
    for name in (*_RUN_FILES, CHECKPOINT_NAME, "config.toml"):
        (out / f".{name}.tmp").unlink(missing_ok=True)


# --- finding what went wrong ---------------------------------------------------------------


@dataclass(frozen=True)
class Domain:
    """The box a grain must stay in [m]."""

    xmin: float
    xmax: float
    ymin: float
    ymax: float

    def distance_outside(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        dx = np.maximum(np.maximum(self.xmin - x, x - self.xmax), 0.0)
        dy = np.maximum(np.maximum(self.ymin - y, y - self.ymax), 0.0)
        return np.hypot(dx, dy)

    def text(self) -> str:
        return (f"x in [{self.xmin:.3g}, {self.xmax:.3g}] m, "
                f"y in [{self.ymin:.3g}, {self.ymax:.3g}] m")


def domain_of(run: SiloRun) -> Domain:
    shape = run.shape
    size = max(shape.width, shape.wall_top)
    return Domain(-size, shape.width + size, run.z_remove - size, shape.wall_top + size)


def energy_bound(run: SiloRun) -> float:
    """The largest kinetic energy a stable run may have now [J] (module docstring)."""
    g = max(run.cfg.gravity, 9.81)
    height = run.shape.wall_top - run.z_remove
    v0 = run.cfg.fill.initial_speed
    return ENERGY_FACTOR * run.sim.particles.total_mass() * (g * height + 0.5 * v0 * v0)


def grain_record(run: SiloRun, index: int) -> dict[str, Any]:
    """Everything about the live grain ``index``: uid, position, velocity, spin, size, force."""
    p = run.sim.particles
    rec: dict[str, Any] = {"uid": int(p.uid[index]), "index": int(index)}
    for key in ("x", "y", "vx", "vy", "omega", "radius", "mass", "fx", "fy"):
        rec[key] = float(getattr(p, key)[index])
    rec["speed"] = float(math.hypot(rec["vx"], rec["vy"]))
    return rec


@dataclass
class Problem:
    """What is wrong, with the grain to blame (``index`` into the live grains, or None)."""

    kind: str  # non_finite | outside_domain | energy | engine | all_lost
    message: str
    index: int | None
    details: dict[str, Any] = field(default_factory=dict)


def _where(rec: dict[str, Any]) -> str:
    return (f"grain uid {rec['uid']} at (x, y) = ({rec['x']:.4g}, {rec['y']:.4g}) m, velocity "
            f"({rec['vx']:.3g}, {rec['vy']:.3g}) m/s")


def find_problem(run: SiloRun) -> Problem | None:
    """The first unphysical thing in the state of ``run`` (module docstring), or None."""
    p = run.sim.particles
    n = p.n
    when = f"at t = {run.sim.time:.6g} s (step {run.sim.steps}, {run.state.phase})"
    if n == 0:
        lost = int(run.events.get("lost_count", 0))
        # poured (a pour may lose its first batch and go on) and none left by the outlet
        if lost > 0 and run.state.phase != "fill" and run.state.discharged_mass == 0.0:
            return Problem("all_lost", f"no grain is left in the silo: all {lost} have gone "
                           f"out through its walls, {when}; the contacts are far too soft for "
                           "the silo's weight (the soft-contact warning, if any, gives the "
                           "stiffness to use) or the time step is too large", None,
                           {"lost_count": lost})
        return None
    uid = p.view("uid")
    bad = np.zeros(n, dtype=bool)
    for key in _STATE_FIELDS:
        bad |= ~np.isfinite(p.view(key))
    if np.any(bad):
        idx = np.flatnonzero(bad)
        i = int(idx[np.argmin(uid[idx])])
        rec = grain_record(run, i)
        fields = [k for k in _STATE_FIELDS if not math.isfinite(rec[k])]
        return Problem("non_finite", f"non-finite {', '.join(fields)} of {_where(rec)}, {when} "
                       f"({idx.size} grain(s) with non-finite values)", i,
                       {"n_non_finite": int(idx.size),
                        "non_finite_uids": sorted(int(u) for u in uid[idx])[:20]})
    domain = domain_of(run)
    # a grain under the removal level has been discharged: it is removed at the start of the
    # next chunk however far it fell in this one (at 100 m/s under gravity = 1000 m/s^2, past
    # the domain's floor), so only its x is tested
    out = domain.distance_outside(p.view("x"), np.maximum(p.view("y"), run.z_remove))
    if np.any(out > 0):
        i = int(np.argmax(out))
        rec = grain_record(run, i)
        return Problem("outside_domain", f"{_where(rec)} has left the domain "
                       f"({domain.text()}), {when}", i,
                       {"n_outside": int(np.count_nonzero(out > 0))})
    ke = p.kinetic_energy()
    bound = energy_bound(run)
    if not ke <= bound:
        i = int(np.argmax(p.kinetic_energies()))
        rec = grain_record(run, i)
        return Problem("energy", f"kinetic energy {ke:.3g} J exceeds {ENERGY_FACTOR:g} x the "
                       f"energy the grains can gain by falling and being poured ({bound:.3g} J) "
                       f"{when}; most energetic: {_where(rec)}", i)
    return None


def blame(run: SiloRun, message: str) -> Problem:
    """A Problem for an error the engine raised: the grain found by :func:`find_problem`, else
    the fastest grain."""
    found = find_problem(run)
    if found is not None:
        return Problem("engine", message, found.index,
                       {"found": found.kind, "found_message": found.message, **found.details})
    p = run.sim.particles
    if p.n == 0:
        return Problem("engine", message, None)
    speed = np.hypot(p.view("vx"), p.view("vy"))
    return Problem("engine", message, int(np.argmax(speed)), {"found": "fastest grain"})


def _json_safe(value: Any) -> Any:
    """JSON without NaN/Infinity tokens: non-finite floats become the strings 'nan', 'inf'."""
    if isinstance(value, dict):
        return {str(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")
    return value


def write_json(path: Path, data: dict[str, Any]) -> None:
    with atomic_file(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        json.dump(_json_safe(data), fh, indent=2, allow_nan=False)
        fh.write("\n")
        fh.flush()


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


# --- the guard -----------------------------------------------------------------------------


class _Stopped(UnstableRunError):
    """An instability already diagnosed and saved (not to be handled twice)."""


class _HardStop(RunInterrupted):
    """A second signal's stop, without saving; ``RunGuard.drive`` adds what is kept."""


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
            self.failure = one_line(f"{problem.message}; {_where(grain)}")
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
            "hints": [
                f"reduce time.safety (now {cfg.time.safety:g}) or set a smaller time.dt",
                (f"check the contact law's values ({law_key_names(cfg)}) and the grain sizes "
                 "and density against each other"),
                "look at the grain named here in failure.h5 (same layout as checkpoint.h5)",
            ],
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
