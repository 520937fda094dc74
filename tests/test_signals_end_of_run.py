"""Signals at the edges of a run: as it ends (its progress bar closing, its final results.h5
written, its checkpoint removed, its summary printed) and while an unstable run's failure state
is saved.

Each signal is sent in this process from a hook at the moment it is about (a patched step of
the run calls ``signal.raise_signal``, whose handler runs before it returns), never by timing.
"""

from __future__ import annotations

import math
import signal

import h5py
import pytest
from reliability_helpers import (
    exit_and_last_line,
    quick_config,
    results_written_line,
    run_args,
    saved_at,
)

from silodem.checkpoint import read_checkpoint
from silodem.cli import main
from silodem.errors import RunInterrupted
from silodem.silo.procedure import SiloRun

SIGNALS = pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM],
                                  ids=["SIGINT", "SIGTERM"])


def _status(out) -> str:
    with h5py.File(out / "results.h5") as h5:
        return str(h5.attrs["status"])


def _complete(out) -> str:
    """The line of a run that a signal stopped as it ended, its complete results written."""
    return (f"interrupted: as the run ended; its complete results are in {out / 'results.h5'} "
            f"('silodem plot {out}' draws its pictures and report.html)")


def _assert_stopped_complete(out, capsys, sig: int, sent: list[int]):
    """Run the command line into ``out``, whose ``sent`` signal (``sig``) comes as the run
    ends: the run stops with complete results, no checkpoint left, 130 or 143.  ``out``."""
    code, last = exit_and_last_line(run_args(out), capsys)
    assert sent == [sig]
    assert (code, last) == (128 + sig, _complete(out))
    assert _status(out) == "complete"
    assert not (out / "checkpoint.h5").exists()  # complete: nothing left to resume
    return out


# --- as the run ends --------------------------------------------------------------------------


@SIGNALS
def test_a_signal_as_the_progress_bar_closes_is_the_runs_and_loses_nothing(
        sig, tmp_path, monkeypatch, capsys):
    """The bar was closed after the run's handlers had been put back: a signal then gave a
    bare 'interrupted' (exit 130, or 143 and 'interrupted (SIGTERM)') and the finished run's
    final results were never written.  The handlers now last until the bar is closed: the
    signal is the run's, which writes its complete results and says so."""
    from rich.progress import Progress

    stop = Progress.stop
    sent: list[int] = []

    def stop_with_a_signal(self) -> None:
        if not sent:
            sent.append(sig)
            signal.raise_signal(sig)
        stop(self)

    monkeypatch.setattr(Progress, "stop", stop_with_a_signal)
    _assert_stopped_complete(tmp_path / "run", capsys, sig, sent)


def test_a_second_signal_as_the_progress_bar_closes_stops_at_once_and_names_the_checkpoint(
        tmp_path, monkeypatch, capsys):
    """A second SIGINT there is the run's hard stop: no final results, the last checkpoint
    named with the command that finishes the run, which then ends complete."""
    from rich.progress import Progress

    stop = Progress.stop
    sent: list[int] = []

    def stop_with_two_signals(self) -> None:
        if not sent:
            sent.append(signal.SIGINT)
            signal.raise_signal(signal.SIGINT)  # noted: the run's results are written next
            signal.raise_signal(signal.SIGINT)  # again: stop at once, here
        stop(self)

    monkeypatch.setattr(Progress, "stop", stop_with_two_signals)
    out = tmp_path / "run"
    code, last = exit_and_last_line(run_args(out), capsys)
    checkpoint = out / "checkpoint.h5"
    assert code == 130
    assert last == (f"interrupted: SIGINT again: stopped at once, without saving; the last "
                    f"checkpoint, {checkpoint} {saved_at(checkpoint, 'step')}, is kept; "
                    f"continue with: silodem run --resume {out}")
    assert _status(out) == "running"  # the last periodic save's
    monkeypatch.setattr(Progress, "stop", stop)
    with pytest.raises(SystemExit) as exc:
        main(["run", "--resume", str(out)])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip().splitlines()[-1] == f"results: {out}"
    assert _status(out) == "complete" and not checkpoint.exists()


@pytest.mark.parametrize("when", ["after the last chunk", "after the final write"])
def test_a_signal_as_the_run_ends_without_a_progress_bar_still_writes_its_results(
        when, tmp_path, monkeypatch):
    """Without a progress bar (the API, a sweep's run) nothing is left to close: a signal
    just after the handlers were put back, before the final results were written, raised a
    bare KeyboardInterrupt.  The run's handlers now last until its final results.h5 is
    written: a signal after its last chunk is the run's; one in the moment after the write,
    once they are put back (Python's handler again: a KeyboardInterrupt), finds the results
    complete.  Either ends as a signal in the run's last chunk."""
    from contextlib import contextmanager

    import silodem.run

    if when == "after the last chunk":
        drive = silodem.run.RunGuard.drive

        def drive_then_signal(self, run) -> None:
            drive(self, run)
            signal.raise_signal(signal.SIGINT)

        monkeypatch.setattr(silodem.run.RunGuard, "drive", drive_then_signal)
    else:
        handlers = silodem.run.RunGuard.signals

        @contextmanager
        def handlers_then_signal(self):
            with handlers(self):
                yield
            if self.final_write:  # put back once the final results are written
                signal.raise_signal(signal.SIGINT)

        monkeypatch.setattr(silodem.run.RunGuard, "signals", handlers_then_signal)
    out = tmp_path / "run"
    with pytest.raises(RunInterrupted) as info:
        try:
            silodem.run.run_simulation(quick_config(), out, progress=False)
        except KeyboardInterrupt:  # (not let through: it would end the whole test session)
            pytest.fail("a bare KeyboardInterrupt came out of the run")
    assert info.value.exit_code == 130
    assert f"interrupted: {info.value}" == _complete(out)
    assert _status(out) == "complete" and not (out / "checkpoint.h5").exists()


def test_a_signal_while_the_checkpoint_is_removed_keeps_the_folder_whole(
        tmp_path, monkeypatch, capsys):
    """Once the complete results.h5 is written, the run removes its checkpoint: a signal in
    the middle left it beside the complete results (a new run there was refused, a resume ran
    the end again) and said a bare 'interrupted'.  The removal now finishes first, and the
    line says where the results are."""
    import silodem.run

    completed = silodem.run.RunGuard.completed

    def completed_with_a_signal(self, run) -> None:
        signal.raise_signal(signal.SIGINT)
        completed(self, run)

    monkeypatch.setattr(silodem.run.RunGuard, "completed", completed_with_a_signal)
    out = tmp_path / "run"
    code, last = exit_and_last_line(run_args(out), capsys)
    assert code == 130
    assert last == results_written_line(out)
    assert _status(out) == "complete"
    assert not (out / "checkpoint.h5").exists()
    assert not [p.name for p in out.iterdir() if p.name.endswith(".tmp")]


def _signals_in_the_final_write(monkeypatch, signals: list[int]) -> list[int]:
    """Send ``signals`` from inside the ended run's final write of results.h5, in the middle
    of it (as its /final snapshot goes into the file being built); the list of those sent."""
    import silodem.output
    import silodem.run

    sent: list[int] = []
    final = {"inside": False}
    write_results, write_snapshot = silodem.run.write_results, silodem.output.write_snapshot

    def final_write(*args, **kwargs):
        final["inside"] = True
        try:
            return write_results(*args, **kwargs)
        finally:
            final["inside"] = False

    def snapshot_with_signals(group, snap):
        if final["inside"] and not sent:
            for sig in signals:
                sent.append(sig)
                signal.raise_signal(sig)  # (its handler runs before this returns)
        return write_snapshot(group, snap)

    monkeypatch.setattr(silodem.run, "write_results", final_write)
    monkeypatch.setattr(silodem.output, "write_snapshot", snapshot_with_signals)
    return sent


def _no_partial_save(out) -> None:
    assert not [p.name for p in out.iterdir() if p.name.endswith(".tmp")]


@SIGNALS
def test_a_signal_while_the_final_results_are_written_lets_the_write_finish(
        sig, tmp_path, monkeypatch, capsys):
    """A first signal while the ended run's final results.h5 was written aborted the write:
    results.h5 stayed the last periodic save's and the line sent the user to resume a run that
    had ended.  The run has ended: the signal is noted, the write finishes and the run ends as
    after a signal in its last chunk (complete results, no checkpoint left, 130 or 143)."""
    sent = _signals_in_the_final_write(monkeypatch, [sig])
    _no_partial_save(_assert_stopped_complete(tmp_path / "run", capsys, sig, sent))


@pytest.mark.parametrize("first", ["in the final write", "after the last chunk"])
def test_a_second_signal_while_the_final_results_are_written_stops_at_once(
        first, tmp_path, monkeypatch, capsys):
    """A second signal there (the first in the same write, or after the run's last chunk)
    stops the write at once: results.h5 stays the last save's (the write is atomic), and the
    line names the checkpoint kept and the resume that finishes the run, which then ends
    complete."""
    import silodem.run

    if first == "after the last chunk":
        drive = silodem.run.RunGuard.drive

        def drive_then_signal(self, run) -> None:
            drive(self, run)
            signal.raise_signal(signal.SIGINT)  # noted: the final results are written next

        monkeypatch.setattr(silodem.run.RunGuard, "drive", drive_then_signal)
    sent = _signals_in_the_final_write(
        monkeypatch, [signal.SIGINT] * (2 if first == "in the final write" else 1))
    out = tmp_path / "run"
    code, last = exit_and_last_line(run_args(out), capsys)
    checkpoint = out / "checkpoint.h5"
    assert sent and code == 130
    assert last == (f"interrupted: SIGINT again: stopped at once, without writing its final "
                    f"results; the last checkpoint, {checkpoint} {saved_at(checkpoint, 'step')}"
                    f", is kept; continue with: silodem run --resume {out}")
    assert _status(out) == "running"  # the last periodic save's
    _no_partial_save(out)
    monkeypatch.undo()
    with pytest.raises(SystemExit) as exc:
        main(["run", "--resume", str(out)])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip().splitlines()[-1] == f"results: {out}"
    assert _status(out) == "complete" and not checkpoint.exists()


def test_a_full_disk_during_the_final_write_names_the_checkpoint_kept(
        tmp_path, monkeypatch, capsys):
    """A final write that finds no room (an OSError, not a signal) ends the run with one line
    (exit 1: a full disk is no bad input, which is 2) naming what failed, the checkpoint kept
    and the resume that goes on once the cause is mended; results.h5 stays the last save's."""
    import errno

    import silodem.run

    def no_room(run, path, config_toml, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(silodem.run, "write_results", no_room)
    out = tmp_path / "run"
    code, last = exit_and_last_line(run_args(out), capsys)
    kept = read_checkpoint(out)
    assert code == 1
    assert last == (f"error: No space left on device ({out / 'results.h5'}) while the run's "
                    f"final results were written to {out / 'results.h5'}; the last "
                    f"checkpoint, at t = {kept.time:.4g} s (step {kept.step}), is kept: once "
                    f"the cause is mended, 'silodem run --resume {out}' goes on from there")
    assert _status(out) == "running"


@SIGNALS
def test_a_signal_while_the_summary_is_printed_says_the_run_is_complete(
        sig, tmp_path, monkeypatch, capsys):
    """The summary is printed after everything is written: a signal then ended the command
    with a bare 'interrupted' (or 'interrupted (SIGTERM)'), as if the run had been cut."""
    from silodem.cli import commands_run

    def print_with_a_signal(console, summary) -> None:
        signal.raise_signal(sig)

    monkeypatch.setattr(commands_run, "_print_summary", print_with_a_signal)
    out = tmp_path / "run"
    code, last = exit_and_last_line(run_args(out), capsys)
    assert code == 128 + sig
    assert last == (f"interrupted: after the run had ended, while its summary was printed; "
                    f"nothing is lost: its results are complete in {out}")
    assert _status(out) == "complete" and not (out / "checkpoint.h5").exists()


# --- an unstable run's failure save -----------------------------------------------------------

NAN_AT_CHUNK = 14  # settling: checkpoints are behind


def _nan_after_chunk(monkeypatch) -> dict:
    """A NaN velocity put into one grain after chunk NAN_AT_CHUNK; its uid, once put."""
    advance = SiloRun.advance_chunk
    done: dict = {}
    count = [0]

    def patched(self: SiloRun) -> None:
        advance(self)
        count[0] += 1
        if count[0] == NAN_AT_CHUNK:
            k = self.sim.particles.n // 2
            self.sim.particles.vx[k] = math.nan
            done["uid"] = int(self.sim.particles.uid[k])

    monkeypatch.setattr(SiloRun, "advance_chunk", patched)
    return done


def _signals_in_the_failure_save(monkeypatch, where: str, count: int) -> list[int]:
    """Send ``count`` SIGINTs as the failure state's ``where`` (failure.h5 or results.h5)
    is about to be written."""
    import silodem.safety

    sent: list[int] = []

    def send() -> None:
        for _ in range(count - len(sent)):
            sent.append(signal.SIGINT)
            signal.raise_signal(signal.SIGINT)

    if where == "failure.h5":
        save_checkpoint = silodem.safety.save_checkpoint

        def save(run, path, **kwargs):
            if kwargs.get("reason") == "unstable":
                send()
            return save_checkpoint(run, path, **kwargs)

        monkeypatch.setattr(silodem.safety, "save_checkpoint", save)
    else:
        write = silodem.safety.RunGuard._write_results

        def write_results(self, run, status):
            if status == "unstable":
                send()
            return write(self, run, status)

        monkeypatch.setattr(silodem.safety.RunGuard, "_write_results", write_results)
    return sent


@pytest.mark.parametrize("where", ["failure.h5", "results.h5"])
def test_a_second_signal_while_an_unstable_runs_state_is_saved_stops_it_and_says_so(
        where, tmp_path, monkeypatch, capsys):
    """A second Ctrl-C while the diverged run's state was saved was swallowed (taken for a
    failed write of failure.h5, or let through as a plain 'SIGINT again' that hid the
    instability): the run ended with exit 3 as if nothing had come.  It now stops the save at
    once, as it stops any save of a run; the run still ends as unstable (exit 3), in one line
    that gives the diagnosis, says the signal cut the save short and what was written, and
    names the checkpoint kept."""
    done = _nan_after_chunk(monkeypatch)
    sent = _signals_in_the_failure_save(monkeypatch, where, 2)
    out = tmp_path / "run"
    code, last = exit_and_last_line(run_args(out), capsys)
    assert sent == [signal.SIGINT, signal.SIGINT]
    assert code == 3
    checkpoint = out / "checkpoint.h5"
    assert last.startswith(f"run stopped: non-finite vx of grain uid {done['uid']} "), last
    if where == "failure.h5":
        written = "before any of it was written"
        assert not (out / "failure.h5").exists() and _status(out) == "running"
    else:
        written = (f"after writing {out / 'failure.h5'} (not results.h5 and "
                   "diagnostic.json)")
        with h5py.File(out / "failure.h5") as h5:
            assert h5.attrs["reason"] == "unstable"
        assert _status(out) == "running"  # the last periodic save's
    assert not (out / "diagnostic.json").exists()
    assert last.endswith(
        f"; SIGINT again: stopped at once while saving the failure state, {written}; the last "
        f"checkpoint, {checkpoint} {saved_at(checkpoint, 'step')}, is kept; 'silodem run "
        f"--resume {out}' repeats the run from it to the same failure, and saves its state"), last
    read_checkpoint(out)  # whole, as named


def test_a_first_signal_while_an_unstable_runs_state_is_saved_lets_the_save_finish(
        tmp_path, monkeypatch, capsys):
    """One signal while the failure state is saved changes nothing of it (the run is stopping
    anyway): every file is written, exit 3, and the line says the signal came."""
    _nan_after_chunk(monkeypatch)
    sent = _signals_in_the_failure_save(monkeypatch, "failure.h5", 1)
    out = tmp_path / "run"
    code, last = exit_and_last_line(run_args(out), capsys)
    assert sent == [signal.SIGINT] and code == 3
    assert last.startswith("run stopped: non-finite vx")
    assert last.endswith(f"; diagnosis in {out / 'diagnostic.json'}, state in "
                         f"{out / 'failure.h5'}; SIGINT received: the run stopped here, once "
                         "its failure state was saved"), last
    assert _status(out) == "unstable"
    with h5py.File(out / "failure.h5") as h5:
        assert h5.attrs["reason"] == "unstable"


def test_the_checkpoint_named_after_a_cut_short_failure_save_repeats_the_failure(
        tmp_path, monkeypatch, capsys):
    """What the line of a cut-short failure save promises: a real blow-up (a time step 8 x
    the stability limit, its refusal bypassed), stopped by a second signal while its state
    was saved; the resume named comes to the same failure, and saves its state this time."""
    from silodem.silo import procedure

    stable = procedure.choose_time_step

    def too_large(*args):
        _, dt_crit = stable(*args)
        return 8.0 * dt_crit, dt_crit

    monkeypatch.setattr(procedure, "choose_time_step", too_large)
    sent = _signals_in_the_failure_save(monkeypatch, "results.h5", 2)
    out = tmp_path / "run"
    code, cut = exit_and_last_line(run_args(out), capsys)
    assert code == 3 and len(sent) == 2 and "SIGINT again" in cut, cut
    assert not (out / "diagnostic.json").exists()
    sent.clear()
    monkeypatch.undo()
    monkeypatch.setattr(procedure, "choose_time_step", too_large)  # (the checkpoint has dt)
    code, last = exit_and_last_line(["run", "--resume", str(out)], capsys)
    assert code == 3
    diagnosis = cut.split("; SIGINT again")[0]
    assert last.startswith(diagnosis), (cut, last)
    assert (out / "diagnostic.json").is_file() and (out / "failure.h5").is_file()
    assert _status(out) == "unstable"


def test_an_interrupt_dropped_in_a_callback_while_drawing_prints_no_traceback(monkeypatch):
    """Drawing runs under ``noted_signals(hold=False)``: a SIGTERM's ``Terminated`` raised
    inside a weakref callback (matplotlib's) cannot propagate, and Python reported it as
    "Exception ignored ..." with a traceback before the command's one line (3 of 22 SIGTERMs
    in an audit).  Inside the block such a KeyboardInterrupt is dropped quietly (the note
    still has the signal); any other exception in a callback is still reported."""
    import sys
    import weakref

    from silodem.errors import Terminated
    from silodem.signals import noted_signals

    reported = []
    monkeypatch.setattr(sys, "unraisablehook", lambda u: reported.append(type(u.exc_value)))

    class Thing:
        pass

    def dies_raising(exc):
        thing = Thing()
        ref = weakref.ref(thing, lambda _: (_ for _ in ()).throw(exc))
        del thing
        return ref

    with noted_signals(hold=False):
        dies_raising(Terminated())
        dies_raising(KeyboardInterrupt())
        dies_raising(ValueError("a real fault"))
    assert reported == [ValueError]
    dies_raising(KeyboardInterrupt())  # outside the block: reported as before
    assert reported == [ValueError, KeyboardInterrupt]
