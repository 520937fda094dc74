"""``silodem plot`` and ``silodem animate`` on the folders a run can leave behind besides a
finished one: a run stopped in its settling (results.h5 status "interrupted", a
checkpoint.h5), a frames segment file cut short or overwritten, a checkpoint.h5 without
results.h5.

Two small quick runs (module fixtures): one stopped at its 30th settling check, as a
SIGINT stops a run (the guard's recorded signal, no process and no timing), and one
finished.  Every name, phase, time and frame number the tests expect is read from the
files the runs wrote (h5py), not from the code under test.
"""

from __future__ import annotations

import html
import re
import shutil
import signal
from pathlib import Path

import h5py
import numpy as np
import pytest

from silodem.cli import main
from silodem.errors import RunInterrupted
from silodem.run import run_simulation
from silodem.safety import RunGuard
from silodem.scenario_files import load_config, quick_variant
from silodem.silo.frames import read_frames

SETS = ("fill.n_particles=80", "output.png=false", "measure.report=false")
STOP_AT = 30  # the settling check at which the run is stopped (0.05 s each: 1.5 s of settling)


def _config(*extra: str):
    return quick_variant(load_config("paper-case2", [*SETS, *extra]))


@pytest.fixture(scope="module")
def stopped(tmp_path_factory) -> Path:
    """A run stopped in its settling, as a Ctrl-C stops it: the guard's chunk hook finds a
    recorded SIGINT, writes results.h5 (status "interrupted") and checkpoint.h5, and the
    run ends with RunInterrupted.  settle.threshold = 1e-9: it does not settle first."""
    out = tmp_path_factory.mktemp("unfinished") / "run"
    hook = RunGuard.__call__
    seen: list[str] = []

    def sigint_in_settling(self, run):
        seen.append(run.state.phase)
        if seen.count("settle") == STOP_AT:
            self.stop_signal = signal.SIGINT  # as the signal handler records it
        hook(self, run)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(RunGuard, "__call__", sigint_in_settling)
        with pytest.raises(RunInterrupted):
            run_simulation(_config("settle.threshold=1e-9"), out, progress=False)
    return out


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> Path:
    """A finished quick run, saved every 2000 steps: several frames segment files, each of
    over 1024 grain rows (a frame every 0.02 s), so gzip-compressed (docs/output.md)."""
    out = tmp_path_factory.mktemp("finished") / "run"
    run_simulation(_config("checkpoint.every_steps=2000", "output.frame_interval=0.02"), out,
                   progress=False)
    return out


def _attrs(folder: Path) -> dict:
    with h5py.File(folder / "results.h5", "r") as h5:
        return {**{k: h5.attrs[k] for k in ("status", "phase", "time", "steps")},
                "groups": set(h5), "events": dict(h5["events"].attrs),
                "measure_t": h5["measure/time"][()], "measure_phase": h5["measure/phase"][()],
                "segments": [str(s) for s in h5["frames"].attrs.get("segments", [])],
                "frames": int(h5["frames/time"].size)}


def _plot(folder: Path, capsys) -> tuple[int, str, str]:
    with pytest.raises(SystemExit) as exc:
        main(["plot", str(folder)])
    out, err = capsys.readouterr()
    return exc.value.code, out, err


def _key_numbers(page: str) -> dict[str, str]:
    rows = re.findall(r"<tr><td>(.*?)</td><td>(.*?)</td><td>.*?</td></tr>", page)
    return {html.unescape(q): html.unescape(v) for q, v in rows}


def _text(page: str) -> str:
    return html.unescape(re.sub(r"<[^>]+>", "", page))


# --- finding 1: an unfinished run's report says so ---------------------------------------------
def test_plot_of_an_interrupted_run_says_it_is_unfinished_and_how_to_go_on(stopped, capsys):
    """The stopped run's report gets a box at its top with the status, phase, time and step of
    results.h5 and the resume command (checkpoint.h5 is there); `silodem plot` exits 0 and
    says the same in one line on stderr."""
    f = _attrs(stopped)
    assert (f["status"], f["phase"]) == ("interrupted", "settle")
    assert (stopped / "checkpoint.h5").is_file()
    code, out, err = _plot(stopped, capsys)
    assert code == 0
    assert out.strip() == f"report: {stopped / 'report.html'}"
    assert err.splitlines() == [
        (f"silodem: {stopped} holds an unfinished run (interrupted in settle at "
         f"t = {f['time']:.4g} s): its report covers what was reached; continue it with "
         f"'silodem run --resume {stopped}'")]
    page = (stopped / "report.html").read_text(encoding="utf-8")
    banner = re.search(r"<p class='unfinished' id='unfinished'>(.*?)</p>", page)
    assert banner is not None
    assert page.index("id='unfinished'") < page.index("<h2>Key numbers</h2>")  # at the top
    text = html.unescape(banner[1])
    assert text.startswith(
        "Unfinished run: this results.h5 was written before the run ended: it was interrupted "
        f"(SIGINT or SIGTERM) in settle at t = {f['time']:.4g} s (step {f['steps']}). "
        "Measurements labelled after filling or during discharge cover only what the run "
        "reached. Settling had not ended:")
    assert text.endswith(f"Continue it with: silodem run --resume {stopped.resolve()}")
    # the end-of-filling network picture is titled as the last frame saved, not as settled
    frames = read_frames(stopped / "results.h5")
    assert (frames.status, frames.settled) == ("interrupted", False)


def test_an_unsettled_runs_numbers_say_what_is_missing_and_which_window(stopped, capsys):
    """No /settled snapshot in the file: the free surface and bulk density rows say why they
    are n/a; the fill window's numbers are labelled as the last window of the unfinished
    settling, not 'after filling', and that window (measure.window = 1 s) ends at the last
    settling sample of /measure."""
    f = _attrs(stopped)
    assert "settled" not in f["groups"] and "settle_time" not in f["events"]
    _plot(stopped, capsys)
    rows = _key_numbers((stopped / "report.html").read_text(encoding="utf-8"))
    why = (f"n/a (no settled snapshot: the run stopped in settle at t = {f['time']:.4g} s, "
           "before settling ended)")
    surface = [v for q, v in rows.items() if q.startswith("free surface after filling")]
    density = [v for q, v in rows.items() if q.startswith("bulk density rho_b")]
    assert surface == density == [why]
    assert not [q for q in rows if "after filling" in q and not q.startswith("free surface")]
    assert "switch-zone peak of the wall normal stress, late in the unfinished settling" in rows
    end = float(f["measure_t"][f["measure_phase"] == 1].max())
    window = ("averaging window late in the unfinished settling: the last measure.window = "
              "1 s of the settling reached (the run stopped before settling ended)")
    assert rows[window] == f"{end - 1.0:.3f} - {end:.3f} (1 s)"
    assert rows["change fill -> discharge"] == (
        "n/a (no measurement sample in the discharge window: the run stopped in settle at "
        f"t = {f['time']:.4g} s)")


def _captions(page: str) -> dict[str, str]:
    """figure id -> its caption's text."""
    found = re.findall(r"<figure id='(\w+)'>.*?<figcaption>(.*?)</figcaption>", page)
    return {name: _text(caption) for name, caption in found}


def test_an_unsettled_runs_figure_captions_name_its_window_as_the_titles_do(stopped, capsys):
    """The captions of Figs. 3a and 3b name the fill window as the key numbers, the banner and
    the figures' own titles do: the last window of the unfinished settling, not "after
    filling" (the run stopped before settling ended: there is no settled fill)."""
    _plot(stopped, capsys)
    captions = _captions((stopped / "report.html").read_text(encoding="utf-8"))
    assert captions["fig3a_horizontal_filling"].startswith(
        "Fig. 3a equivalent. Horizontal stress along the silo wall late in the unfinished "
        "settling (time average over the last window of the settling reached: the run "
        "stopped before settling ended):")
    assert captions["fig3b_vertical_filling"].startswith(
        "Fig. 3b equivalent. Vertical stress along the silo wall late in the unfinished "
        "settling:")
    assert not [name for name, text in captions.items() if "after filling" in text]


def test_a_finished_runs_report_has_no_banner_and_plot_no_note(finished, tmp_path, capsys):
    copy = tmp_path / "run"
    shutil.copytree(finished, copy)
    assert _attrs(copy)["status"] == "complete"
    code, _, err = _plot(copy, capsys)
    assert (code, err) == (0, "")
    page = (copy / "report.html").read_text(encoding="utf-8")
    assert "id='unfinished'" not in page and "unfinished settling" not in page
    assert "switch-zone peak of the wall normal stress, after filling" in _key_numbers(page)
    assert _captions(page)["fig3a_horizontal_filling"].startswith(
        "Fig. 3a equivalent. Horizontal stress along the silo wall after filling (time average "
        "over the last window of settling):")
    frames = read_frames(copy / "results.h5")
    assert (frames.status, frames.settled) == ("complete", True)


# --- finding 2: a damaged frames segment is named ----------------------------------------------
def _segment_range(name: str) -> tuple[int, int]:
    first, last = re.fullmatch(r"frames/frames-(\d+)-(\d+)\.h5", name).groups()
    return int(first), int(last)


def _damaged_tail(name: str) -> str:
    first, last = _segment_range(name)
    return f"): frames {first} to {last} of the run cannot be read (the rest of its results.h5 can)"


@pytest.fixture
def cut_short(finished, tmp_path) -> tuple[Path, str]:
    """A copy of the finished run whose second frames segment is cut to 5000 bytes."""
    copy = tmp_path / "run"
    shutil.copytree(finished, copy)
    segments = _attrs(copy)["segments"]
    assert len(segments) >= 3
    (copy / segments[1]).write_bytes((copy / segments[1]).read_bytes()[:5000])
    return copy, segments[1]


def test_animate_names_a_frames_segment_cut_short(cut_short, capsys):
    copy, name = cut_short
    with pytest.raises(SystemExit) as exc:
        main(["animate", str(copy)])
    err = capsys.readouterr().err.strip().splitlines()
    assert exc.value.code == 2 and len(err) == 1, err
    assert err[0].startswith(f"error: '{copy / name}' is damaged (OSError: ")
    assert err[0].endswith(_damaged_tail(name))
    assert not list(copy.glob("*.mp4"))


def test_plot_says_why_the_network_snapshots_are_left_out(cut_short, capsys):
    copy, name = cut_short
    code, _, err = _plot(copy, capsys)
    assert (code, err) == (0, "")
    text = _text((copy / "report.html").read_text(encoding="utf-8"))
    said = re.search(r"Left out: network_end_of_filling, network_early_discharge, "
                     r"network_late_discharge; they are drawn from the frames saved beside "
                     r"results\.h5 \(frames/\), which cannot be read: (.*?\))\.", text)
    assert said is not None, text
    assert said[1].startswith(f"'{copy / name}' is damaged (OSError: ")
    assert said[1].endswith(_damaged_tail(name))
    assert "missing or hold no frame" not in text


def test_a_segment_whose_data_is_overwritten_is_named_when_its_frames_are_read(finished,
                                                                             tmp_path, capsys):
    """A segment that opens but whose compressed column cannot be decompressed: read_frames
    reads only the index, so the error comes when the frames are read (a frame, the animation),
    and names the segment and its frames."""
    from silodem.silo.frames import DamagedFramesError

    copy = tmp_path / "run"
    shutil.copytree(finished, copy)
    name = _attrs(copy)["segments"][1]
    with h5py.File(copy / name, "r") as h5:  # where the gzip chunk of particles/x lies
        column = h5["frames/particles/x"]
        assert column.compression == "gzip"
        chunk = column.id.get_chunk_info(0)
    with open(copy / name, "r+b") as fh:
        fh.seek(chunk.byte_offset)
        fh.write(b"\xff" * chunk.size)
    frames = read_frames(copy / "results.h5")
    last = _segment_range(name)[1]
    with pytest.raises(DamagedFramesError) as exc:
        frames[last]
    assert str(exc.value).startswith(f"'{copy / name}' is damaged (OSError: ")
    assert str(exc.value).endswith(_damaged_tail(name))
    with pytest.raises(SystemExit) as code:
        main(["animate", str(copy), "--format", "gif"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code.value.code == 2 and err[-1] == f"error: {exc.value}"
    assert "Traceback" not in "".join(err) and not list(copy.glob("*.gif"))


# --- finding 3: a checkpoint without results.h5 ------------------------------------------------
def test_a_folder_with_only_a_checkpoint_is_pointed_to_resume(stopped, tmp_path, capsys):
    """The advice of `plot` and `animate` for such a folder is the command that works:
    `silodem run --out DIR` refuses it, `silodem run --resume DIR` finishes the run."""
    copy = tmp_path / "run"
    shutil.copytree(stopped, copy)
    (copy / "results.h5").unlink()  # (the checkpoint's frames/ and config.toml stay)
    code, _, err = _plot(copy, capsys)
    assert code == 2
    assert err.splitlines() == [
        (f"error: {copy} holds no results.h5 but the checkpoint.h5 of an unfinished run: "
         f"continue it with 'silodem run --resume {copy}' (it writes results.h5 as it goes)")]
    with pytest.raises(SystemExit) as exc:
        main(["animate", str(copy)])
    assert exc.value.code == 2
    assert capsys.readouterr().err.splitlines() == [
        (f"error: '{copy}' has no results.h5 but the checkpoint.h5 of an unfinished run: "
         f"continue it with 'silodem run --resume {copy}' (it writes results.h5 as it goes)")]
    with pytest.raises(SystemExit) as exc:  # what the old advice said to do
        main(["run", "paper-case2", "--quick", "--out", str(copy)])
    assert exc.value.code == 2 and "--resume" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["run", "--resume", str(copy)])
    capsys.readouterr()
    assert exc.value.code == 0
    with h5py.File(copy / "results.h5", "r") as h5:
        assert h5.attrs["status"] == "complete" and "settled" in h5
        assert np.isfinite(h5["settled"].attrs["time"])


# --- the fill window ends where settling ended -------------------------------------------------
def test_the_fill_window_ends_at_the_settled_snapshot_else_the_settle_events(tmp_path):
    """A run without discharge has no gate opening: its fill window ends at the /settled
    snapshot's time, else at fill_time + settle_time of /events, and only without either (a
    settling that had not ended) at the last settling sample.  The synthetic file of
    test_report_numbers (settle samples 2.65625 .. 2.96875 s, every 1/16 s) with those
    attributes set by hand."""
    from test_report_numbers import write_synthetic

    from silodem.report.analysis import analyse
    from silodem.report.load import load_results

    folder = write_synthetic(tmp_path / "nodis", discharge=False)
    with h5py.File(folder / "results.h5", "r+") as h5:
        t, phase = h5["measure/time"][()], h5["measure/phase"][()]
        first, last = float(t[phase == 1].min()), float(t[phase == 1].max())
        assert "discharge_start_time" not in h5["events"].attrs
        h5["settled"].attrs["time"] = 2.99
    assert analyse(load_results(folder)).windows["fill"] == (first, 2.99)
    with h5py.File(folder / "results.h5", "r+") as h5:
        del h5["settled"]
        h5["events"].attrs["settle_time"] = 0.36
        fill_time = float(h5["events"].attrs["fill_time"])
    assert analyse(load_results(folder)).windows["fill"] == (first, fill_time + 0.36)
    with h5py.File(folder / "results.h5", "r+") as h5:
        del h5["events"].attrs["settle_time"]
    assert analyse(load_results(folder)).windows["fill"] == (first, last)


def test_the_advice_for_an_unstable_a_checkpointless_and_a_study_folder_is_what_works(
        stopped, tmp_path, capsys):
    """An audit's misleading hints.  For an unstable run `plot` said 'continue it with silodem
    run --resume', which only repeats the failure (the checkpoint keeps the failing config);
    a stopped run with no checkpoint was 'nothing to resume (give the results folder of an
    interrupted run)', though it is one; `plot` of a study's folder advised `silodem run
    --out` into it, which is refused."""
    unstable = tmp_path / "unstable"
    shutil.copytree(stopped, unstable)
    with h5py.File(unstable / "results.h5", "r+") as h5:
        h5.attrs["status"] = "unstable"
    code, _, err = _plot(unstable, capsys)
    assert code == 0
    assert err.strip().endswith(f"'silodem run --resume {unstable}' only repeats it to the same "
                                "failure; mend the config and start it again")
    page = _text((unstable / "report.html").read_text(encoding="utf-8"))
    assert (f"silodem run --resume {unstable.resolve()} only repeats it to the same failure "
            "(the checkpoint keeps the run's config): mend the config and start the run "
            "again.") in page
    assert "Continue it with" not in page

    bare = tmp_path / "bare"
    shutil.copytree(stopped, bare)
    (bare / "checkpoint.h5").unlink()
    with pytest.raises(SystemExit) as exc:
        main(["run", "--resume", str(bare)])
    err = capsys.readouterr().err.strip().splitlines()
    assert exc.value.code == 2 and len(err) == 1
    assert err[0].endswith(f"the run in {bare} stopped (interrupted) with no checkpoint.h5 to "
                           "go on from (checkpoint.enabled false, none written yet, or the "
                           "file removed): it cannot be resumed; start it again")

    with h5py.File(bare / "results.h5", "r+") as h5:  # a run still going, or killed
        h5.attrs["status"] = "running"
    with pytest.raises(SystemExit) as exc:
        main(["run", "--resume", str(bare)])
    err = capsys.readouterr().err.strip().splitlines()
    assert exc.value.code == 2 and err[-1].endswith(
        f"the run in {bare} has written no checkpoint.h5 yet: it is still running, or was "
        "killed before its first checkpoint; nothing to resume")

    study = tmp_path / "study"
    (study / "runs").mkdir(parents=True)
    (study / "study.toml").write_text("# a study\n")
    code, _, err = _plot(study, capsys)
    assert code == 2
    assert err.splitlines() == [(f"error: {study} is a study's folder: its report is "
                                f"{study / 'report.html'}, and each run's folder is under "
                                f"{study / 'runs'}")]


def test_a_changed_byte_in_an_uncompressed_frames_column_is_an_error(tmp_path):
    """A byte flipped in a segment's small (uncompressed) column was read back as another
    number, and `animate` and a resume went on with it: every column carries a Fletcher-32
    checksum, and reading it fails."""
    from silodem.silo.frames import _write_arrays

    path = tmp_path / "frames.h5"
    with h5py.File(path, "w") as h5:
        _write_arrays(h5, {"time": np.linspace(0.0, 0.9, 10)})
    with h5py.File(path, "r") as h5:
        ds = h5["time"]
        offset = ds.id.get_offset() if ds.chunks is None else ds.id.get_chunk_info(0).byte_offset
    data = bytearray(path.read_bytes())
    data[offset + 3] ^= 0x10
    path.write_bytes(bytes(data))
    with h5py.File(path, "r") as h5, pytest.raises(OSError):
        h5["time"][()]
