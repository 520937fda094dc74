"""Visualisation: saved frames, ParaView (VTK) files, animations and force-network pictures.

One small quick run (module fixture) through the command line, as a user would make it.  The
checks compare against data that other parts of the program write (the /settled and /final
snapshots, the time series, /walls, /events) and against what independent readers (meshio's VTK
reader, XML, FFmpeg through imageio, Pillow) find in the files.
"""

from __future__ import annotations

import io
import itertools
import math
import os
import shutil
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import meshio
import numpy as np
import pytest
from PIL import Image
from reliability_helpers import command, env, signal_dropped_by_a_callback

from silodem.silo.frame_store import FramesRecorder
from silodem.silo.frames import read_frames


def cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(command(*args), capture_output=True,
                          text=True, env=env(), timeout=300, check=False)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("viz") / "run"
    res = cli("run", "paper-case2", "--quick", "--set", "fill.n_particles=80",
              "--set", "output.vtk_interval=0.5", "--out", str(out))
    assert res.returncode == 0, res.stderr
    return out


@pytest.fixture(scope="module")
def h5(run_dir):
    with h5py.File(run_dir / "results.h5", "r") as f:
        data = {
            "dt": float(f.attrs["dt"]),
            "events": dict(f["events"].attrs),
            "walls": {k: f["walls"][k][()] for k in ("name", "ax", "ay", "bx", "by")},
            "ts": {k: f["timeseries"][k][()] for k in ("time", "n_particles", "n_contacts")},
            "frame_time": f["frames/time"][()],
        }
        for snap in ("settled", "final"):
            data[snap] = {"time": float(f[snap].attrs["time"]),
                          **{k: f[snap]["particles"][k][()] for k in ("x", "y", "uid")},
                          "fn": f[snap]["contacts"]["fn"][()]}
    return data


@pytest.fixture(scope="module")
def frames(run_dir):
    return read_frames(run_dir / "results.h5")


# --- frames -----------------------------------------------------------------------------------
def test_frames_are_regular_and_include_the_settled_and_final_states(frames, h5):
    t = frames.times
    assert len(frames) == h5["frame_time"].size >= 40  # about 4.8 s of run at 0.1 s
    assert np.all(np.diff(t) > 0)
    # regular every 0.1 s (to a time step), apart from the frames added at the phase ends
    regular = [f.time for f in frames if f.step % round(0.1 / h5["dt"]) == 0]
    assert len(regular) >= len(frames) - 3
    assert np.allclose(np.diff(regular), 0.1, atol=h5["dt"])
    for name, frame in (("settled", frames.end_of_filling()), ("final", frames[-1])):
        snap = h5[name]
        assert frame.time == pytest.approx(snap["time"], abs=1e-12)
        assert np.array_equal(frame.particles["uid"], snap["uid"])
        assert np.array_equal(frame.particles["x"], snap["x"].astype(np.float32))
        assert np.array_equal(frame.particles["y"], snap["y"].astype(np.float32))
        assert np.array_equal(frame.contacts["fn"], snap["fn"].astype(np.float32))
    t_open = h5["events"]["discharge_start_time"]
    for f in frames:
        assert (f.phase == "discharge") == (f.time > t_open + 1e-9)
        assert f.walls_active[list(h5["walls"]["name"]).index(b"gate")] == (f.time <= t_open)


def test_frames_agree_with_the_time_series(frames, h5):
    ts = h5["ts"]
    matched = 0
    for f in frames:
        k = np.flatnonzero(np.abs(ts["time"] - f.time) < 1e-9)
        if k.size:
            matched += 1
            assert f.n == ts["n_particles"][k[0]]
            assert f.contacts["fn"].size == ts["n_contacts"][k[0]]
    assert matched >= len(frames) - 3


def test_read_frames_reads_frames_a_block_at_a_time_when_asked_for(run_dir, monkeypatch):
    """read_frames holds the frames' index, not their tables: the arrays it allocates
    (tracemalloc, which counts NumPy's) are a small part of the tables' bytes, and reading a
    frame allocates no more than its block (``BLOCK_BYTES`` here a few frames' worth) and
    its own copy.
    Every frame read so equals its rows of the columns read whole with h5py, by the offsets
    of docs/output.md, the frames without a contact (a block of no rows) included."""
    import tracemalloc

    from silodem.silo import frames as frames_module
    from silodem.silo.frames import FIELDS, OFFSETS

    with h5py.File(run_dir / "results.h5") as f:
        g = f["frames"]
        whole = {f"{t}/{k}": g[f"{t}/{k}"][()] for t, keys in FIELDS.items() for k in keys}
        offsets = {t: g[OFFSETS[t]][()] for t in FIELDS}
    tables = sum(a.nbytes for a in whole.values())
    count = offsets["particles"].size - 1
    budget = 3 * tables / count
    monkeypatch.setattr(frames_module, "BLOCK_BYTES", budget)
    tracemalloc.start()
    try:
        frames = read_frames(run_dir / "results.h5")
        held = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        middle = frames[count // 2]
        peak = tracemalloc.get_traced_memory()[1] - held
    finally:
        tracemalloc.stop()
    assert count > 20 and held < 0.25 * tables, (held, tables)  # all read: more than tables
    largest = max(frame.nbytes for frame in frames)
    assert middle.nbytes <= peak < max(budget, largest) + largest + 20_000, (peak, budget)
    assert len(frames.frames.blocks) > count / 10  # (the blocks as asked)
    empty = 0
    for k, frame in enumerate(frames):
        empty += frame.contacts["fn"].size == 0
        for t, keys in FIELDS.items():
            rows = slice(offsets[t][k], offsets[t][k + 1])
            for key in keys:
                got = getattr(frame, t)[key]
                assert got.tobytes() == whole[f"{t}/{key}"][rows].tobytes(), (k, t, key)
                assert got.dtype == whole[f"{t}/{key}"].dtype
    assert empty > 0
    assert frames[-1].time == frames.times[-1] and frames[-count].time == frames.times[0]
    with pytest.raises(IndexError):
        frames[count]
    assert [f.step for f in frames[1:7:2]] == frames.frames.index["step"][1:7:2].tolist()
    radius = whole["particles/radius"]  # read column-wise in slices of BLOCK_BYTES
    assert budget < radius.nbytes and frames.largest_radius() == float(radius.max())


def test_recorder_state_restores_to_the_same_frames(frames):
    rec = FramesRecorder(0.1, 0.5, None)
    rec.frames = list(frames)
    rec.vtk_times = [0.5, 1.0]
    state = rec.state()
    assert all(isinstance(v, np.ndarray) for v in state.values())
    other = FramesRecorder(0.1)
    other.restore({k: v.copy() for k, v in state.items()})
    assert other.vtk_times == [0.5, 1.0]
    a, b = rec.arrays(), other.arrays()
    assert a.keys() == b.keys()
    for key in a:
        assert np.array_equal(a[key], b[key]), key


def _frames_group(rec: FramesRecorder, path: Path) -> None:
    """``rec`` writes results.h5 ``/frames`` at ``path`` (a save of the run)."""
    with h5py.File(path, "w") as h5:
        rec.write(h5.create_group("frames"))


def _datasets(path: Path) -> dict[str, np.ndarray]:
    out = {}
    with h5py.File(path) as h5:
        h5["frames"].visititems(lambda name, obj: out.__setitem__(name, obj[()])
                                if isinstance(obj, h5py.Dataset) else None)
    return out


def test_frames_written_out_read_back_as_taken_and_a_resume_drops_the_unsaved(
        frames, tmp_path, monkeypatch):
    """A recorder with a results folder holds at most ``PENDING_BYTES`` of frames and writes
    the rest to segment files; results.h5 ``/frames`` (the index, and virtual datasets over
    the segments) reads back bit for bit as the frames written whole into results.h5 by a
    recorder without a folder (every frame held: the old layout).  A run killed after its
    checkpoint had written one more segment and a results.h5 listing it; resumed from the
    checkpoint, it ends with the same /frames, and the killed process's segment is gone."""
    from silodem.silo import frame_store

    frames = list(frames)
    assert len(frames) >= 30
    whole = FramesRecorder(0.1)
    whole.frames = list(frames)
    _frames_group(whole, tmp_path / "whole.h5")
    reference = _datasets(tmp_path / "whole.h5")

    cap = 3 * frames[-1].nbytes
    monkeypatch.setattr(frame_store, "PENDING_BYTES", cap)
    run = tmp_path / "run"
    run.mkdir()
    store = run / "frames"
    rec = FramesRecorder(0.1, store_dir=store)
    for frame in frames[:20]:
        rec._keep(frame)
        assert sum(f.nbytes for f in rec.frames) <= cap
    _frames_group(rec, run / "results.h5")  # a save: results.h5, then the checkpoint's state
    checkpoint = rec.state()
    rec.saved_everywhere()
    assert rec.frames == [] and rec.count == 20
    for frame in frames[20:25]:  # then killed after one more save of results.h5 alone
        rec.frames.append(frame)
    _frames_group(rec, run / "results.h5")
    unsaved = rec.store.names[-1]
    assert unsaved == "frames-000020-000024.h5" and (store / unsaved).is_file()
    partial = store / ".frames-000025-000026.h5.tmp"  # a segment being written when killed
    partial.write_bytes(b"half")
    (store / "notes.txt").write_text("mine")

    resumed = FramesRecorder(0.1, store_dir=store)
    resumed.restore(checkpoint)
    assert resumed.count == 20
    for frame in frames[20:]:
        resumed._keep(frame)
    _frames_group(resumed, run / "results.h5")
    resumed.saved_everywhere()
    assert not (store / unsaved).exists() and not partial.exists()
    with h5py.File(run / "results.h5") as h5:
        listed = [str(s) for s in h5["frames"].attrs["segments"]]
        assert h5["frames/particles/x"].is_virtual
    assert sorted(f"frames/{p.name}" for p in store.iterdir()) == sorted([*listed,
                                                                          "frames/notes.txt"])
    assert len(listed) > 4  # several segments, the cap's and the saves'
    got = _datasets(run / "results.h5")
    assert got.keys() == reference.keys()
    for key, arr in reference.items():
        assert got[key].dtype == arr.dtype and got[key].tobytes() == arr.tobytes(), key
    moved = tmp_path / "moved"  # the folder moved whole reads the same
    shutil.move(run, moved)
    got = _datasets(moved / "results.h5")
    assert all(got[key].tobytes() == arr.tobytes() for key, arr in reference.items())


def test_a_checkpoint_whose_frames_file_is_gone_is_refused_naming_it(frames, tmp_path):
    """A checkpoint lists the segment files written before it; restoring it when one of them
    is gone (deleted by hand) is a ValueError naming the file (``silodem run --resume``
    then ends in one line: 'holds a state this run cannot take (...)', exit 2)."""
    rec = FramesRecorder(0.1, store_dir=tmp_path / "frames")
    for frame in list(frames)[:6]:
        rec.frames.append(frame)
        rec.write_out()
    state = rec.state()
    (tmp_path / "frames" / "frames-000003-000003.h5").unlink()
    with pytest.raises(ValueError, match=r"frames-000003-000003\.h5 is missing \(1 of 6 "
                       r"missing; the run can be resumed once they are back\)"):
        FramesRecorder(0.1, store_dir=tmp_path / "frames").restore(state)


def test_a_checkpoint_with_another_runs_frames_files_is_refused(frames, tmp_path):
    """A checkpoint copied into another run's folder found segment files of the same names
    holding other frames: the resume linked them, and reading /frames then failed in HDF5
    ('different number of elements selected').  The row counts saved with the checkpoint
    are checked against each file's tables."""
    frames_list = list(frames)
    rec = FramesRecorder(0.1, store_dir=tmp_path / "a" / "frames")
    for frame in frames_list[:3]:
        rec.frames.append(frame)
        rec.write_out()
    state = rec.state()
    other = FramesRecorder(0.1, store_dir=tmp_path / "b" / "frames")
    for frame in frames_list[-3:]:  # the same file names, other frames (other grains)
        other.frames.append(frame)
        other.write_out()
    assert other.store.names == rec.store.names
    with pytest.raises(ValueError, match=r"frames-00000\d-00000\d\.h5 is not the one this "
                                         r"checkpoint wrote: it holds \["):
        FramesRecorder(0.1, store_dir=tmp_path / "b" / "frames").restore(state)
    FramesRecorder(0.1, store_dir=tmp_path / "a" / "frames").restore(state)  # its own: taken


def test_frames_that_cannot_be_written_out_stay_held_for_the_next_save(frames, tmp_path,
                                                                      monkeypatch):
    """Writing out frames past the cap fails (a full disk): recording goes on with the
    frames held, and the next save writes every one of them."""
    from silodem.silo import frame_store

    frames = list(frames)[:12]
    monkeypatch.setattr(frame_store, "PENDING_BYTES", 1)  # write out after every frame
    rec = FramesRecorder(0.1, store_dir=tmp_path / "frames")
    full = OSError(28, "No space left on device")
    with monkeypatch.context() as mp:
        mp.setattr(frame_store.FrameStore, "append", lambda *a: (_ for _ in ()).throw(full))
        for frame in frames:
            rec._keep(frame)
    assert rec.frames == frames and rec.store.names == []
    _frames_group(rec, tmp_path / "results.h5")
    assert rec.store.names == ["frames-000000-000011.h5"] and rec.frames == []
    assert _datasets(tmp_path / "results.h5")["time"].tolist() == [f.time for f in frames]


# --- VTK --------------------------------------------------------------------------------------
def _piece_counts(path: Path) -> tuple[int, int]:
    piece = ET.parse(path).getroot().find(".//Piece")
    return int(piece.get("NumberOfPoints")), int(piece.get("NumberOfCells"))


def _pvd(path: Path) -> list[tuple[float, str]]:
    return [(float(d.get("timestep")), d.get("file"))
            for d in ET.parse(path).getroot().iter("DataSet")]


def test_pvd_collections_list_every_vtk_file_at_the_vtk_interval(run_dir, h5):
    vtk = run_dir / "vtk"
    listed = set()
    end = h5["final"]["time"]
    for kind in ("particles", "contacts", "walls"):
        entries = _pvd(vtk / f"{kind}.pvd")
        assert len(entries) == math.floor(end / (round(0.5 / h5["dt"]) * h5["dt"]))
        for k, (time, name) in enumerate(entries):
            assert abs(time - 0.5 * (k + 1)) <= (k + 1) * h5["dt"]
            assert (vtk / name).is_file()
            listed.add(name)
    # besides the time series, only the end-of-run fields (not a series)
    fields = {"fields_settled.vtu", "fields_discharge.vtu"}
    assert listed == {p.name for p in vtk.glob("*.vtu")} - fields
    assert {p.name for p in vtk.glob("fields_*.vtu")} <= fields


def test_the_pvd_collections_are_not_rewritten_after_every_vtk_output(tmp_path, monkeypatch):
    """Each rewrite of the .pvd collections lists every VTK file so far: rewritten after every
    output, a run with vtk_interval = 0.001 s slowed from 50,000 steps/s to 85 (an audit).
    Within PVD_EVERY_S of wall time they are not rewritten, yet they are written at each
    phase's end and every save of results.h5, so the finished run's collections list every
    file (a brute-force count: one per output time, at the interval)."""
    from measure_helpers import tiny_hopper_config

    from silodem.run import run_simulation
    from silodem.silo import frame_store
    from silodem.viz import vtk as vtk_module

    cfg = tiny_hopper_config()
    cfg = cfg.model_copy(update={
        "fill": cfg.fill.model_copy(update={"n_particles": 40}),
        "discharge": cfg.discharge.model_copy(update={"max_time": 0.5}),
        "output": cfg.output.model_copy(update={"vtk_interval": 0.02, "png": False})})
    rewrites = []
    real = vtk_module.VtkSeries.write_collections
    monkeypatch.setattr(vtk_module.VtkSeries, "write_collections",
                        lambda self, times: (rewrites.append(len(times)), real(self, times)))
    monkeypatch.setattr(frame_store, "PVD_EVERY_S", 1e9)
    out = tmp_path / "run"
    run_simulation(cfg.model_copy(update={"measure": cfg.measure.model_copy(
        update={"report": False})}), out, progress=False)
    entries = _pvd(out / "vtk" / "particles.pvd")
    with h5py.File(out / "results.h5", "r") as f:
        end, dt = float(f.attrs["time"]), float(f.attrs["dt"])
    step = round(0.02 / dt) * dt
    assert len(entries) == math.floor(end / step + 1e-9)
    assert [name for _, name in entries] == [f"particles_{k:06d}.vtu" for k in range(len(entries))]
    assert 1 <= len(rewrites) <= 6 < len(entries)  # the phases' ends and the saves, no more
    assert rewrites[-1] == len(entries)


def test_a_vtk_write_that_fails_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    """VTK files are written whole or not at all, as every other file of a run folder
    (atomic.atomic_file): a write that fails half-way (a full disk) leaves the file written
    before untouched and no temporary file beside it."""
    from silodem.viz import vtk as vtk_module

    pvd = tmp_path / "particles.pvd"
    vtk_module.write_pvd(pvd, [(0.5, "particles_000001.vtu")])
    before = pvd.read_bytes()
    mesh = meshio.Mesh(np.zeros((1, 3)), [("vertex", np.zeros((1, 1), dtype=int))])
    vtu = tmp_path / "particles_000001.vtu"
    vtk_module._write_mesh(vtu, mesh)
    vtu_before = vtu.read_bytes()

    def full_disk(target, *args, **kwargs):
        Path(target).write_bytes(b"half a file")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(vtk_module.meshio, "write", full_disk)
    with pytest.raises(OSError):
        vtk_module._write_mesh(vtu, mesh)
    monkeypatch.setattr(vtk_module.ET.ElementTree, "write",
                        lambda self, target, *args, **kwargs: full_disk(target))
    with pytest.raises(OSError):
        vtk_module.write_pvd(pvd, [(0.5, "a.vtu"), (1.0, "b.vtu")])
    assert (pvd.read_bytes(), vtu.read_bytes()) == (before, vtu_before)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["particles.pvd",
                                                          "particles_000001.vtu"]


def test_vtk_files_hold_the_frames(run_dir, frames, h5):
    vtk = run_dir / "vtk"
    walls = h5["walls"]
    n_walls = walls["name"].size
    gate = list(walls["name"]).index(b"gate")
    by_time = {f.time: f for f in frames}
    entries = _pvd(vtk / "particles.pvd")
    assert len(entries) >= 8
    for k, (time, name) in enumerate(entries):
        f = by_time[time]  # each VTK time is a saved frame
        n, p, c, w = f.n, f.particles, f.contacts, f.wall_contacts
        # particles: one point (and one vertex) per grain, fields equal to the frame
        assert _piece_counts(vtk / name) == (n, n)
        m = meshio.read(vtk / name)
        assert m.points.shape == (n, 3)
        assert np.array_equal(m.points[:, 0], p["x"]) and np.array_equal(m.points[:, 1], p["y"])
        assert not m.points[:, 2].any()
        pd = m.point_data
        assert {"radius", "velocity", "spin", "force", "coordination"} <= set(pd)
        assert np.array_equal(pd["radius"], p["radius"])
        assert pd["velocity"].shape == (n, 3)
        assert np.array_equal(pd["velocity"][:, 0], p["vx"])
        assert np.array_equal(pd["velocity"][:, 1], p["vy"])
        assert np.array_equal(pd["spin"], p["omega"])
        assert np.allclose(pd["force"], np.hypot(p["fx"].astype(float), p["fy"]), rtol=1e-6)
        touching = (np.bincount(c["i"], minlength=n) + np.bincount(c["j"], minlength=n)
                    + np.bincount(w["grain"], minlength=n))
        assert np.array_equal(pd["coordination"], touching)
        assert np.array_equal(pd["uid"], p["uid"])
        # contacts: one line per touching contact, carrying its normal force
        cname = vtk / f"contacts_{k:06d}.vtu"
        n_lines = c["fn"].size + w["fn"].size
        assert _piece_counts(cname) == (n + w["fn"].size, n_lines)
        if n_lines:
            m = meshio.read(cname)
            lines = m.cells_dict["line"]
            assert np.array_equal(m.cell_data["normal_force"][0],
                                  np.concatenate([c["fn"], w["fn"]]))
            gg = lines[: c["fn"].size]
            assert np.array_equal(m.points[gg[:, 0], 0], p["x"][c["i"]])
            assert np.array_equal(m.points[gg[:, 1], 1], p["y"][c["j"]])
        # walls: one line per wall, the gate active until it opens
        m = meshio.read(vtk / f"walls_{k:06d}.vtu")
        lines = m.cells_dict["line"]
        assert lines.shape == (n_walls, 2)
        assert np.allclose(m.points[lines[:, 0], 0], walls["ax"])
        assert np.allclose(m.points[lines[:, 1], 1], walls["by"])
        active = m.cell_data["active"][0]
        assert np.array_equal(active.astype(bool), f.walls_active)
        assert bool(active[gate]) == (time <= h5["events"]["discharge_start_time"])


def test_vtk_steps_follow_the_vtk_interval_when_frames_are_saved_every_step(tmp_path):
    """A frame interval below the time step saves a frame every step; the VTK files then
    still come every vtk_interval of simulated time (they came every 1e6 steps: the ratio of
    the intervals, 1e-3 / 1e-9, was taken as a count of frame steps)."""
    dt = 2.38e-4
    rec = FramesRecorder(1e-9, 1e-3, tmp_path)
    assert rec.every_steps(dt) == 1
    assert rec._vtk_steps(dt) == round(1e-3 / dt) == 4
    # a whole multiple of a frame interval above dt is still a whole multiple of its steps,
    # so that each VTK file is a saved frame
    rec = FramesRecorder(0.1, 0.5, tmp_path)
    assert rec._vtk_steps(dt) == 5 * round(0.1 / dt)


def test_a_run_shorter_than_its_vtk_interval_ends_well_and_writes_its_fields(tmp_path):
    """No grains' VTK file falls inside the run, so vtk/ did not exist when the fields'
    files were written at the end (the run ended 'error: No such file or directory')."""
    out = tmp_path / "run"
    res = cli("run", "paper-case2", "--quick", "--set", "fill.n_particles=80",
              "--set", "output.vtk_interval=100", "--set", "output.png=false",
              "--out", str(out))
    assert res.returncode == 0, res.stderr
    assert sorted(p.name for p in (out / "vtk").iterdir()) == ["fields_discharge.vtu",
                                                               "fields_settled.vtu"]


def test_the_output_size_estimates_hold_for_a_real_run(run_dir, frames):
    """The bytes per grain that the output warning (``volume_warning``) counts, against what
    the fixture's run saved as frames (uncompressed) and wrote as VTK files (both are about
    a grain's fields and its share of the contacts, so they agree within a factor 2)."""
    from silodem.silo import frame_store as frames_module

    rows = sum(f.n for f in frames)
    held = sum(a.nbytes for f in frames
               for table in (f.particles, f.contacts, f.wall_contacts) for a in table.values())
    assert held == sum(f.nbytes for f in frames)
    assert 0.5 <= held / rows / frames_module.FRAME_BYTES_PER_GRAIN <= 1.0
    vtk = run_dir / "vtk"
    grains = written = 0
    for particles in vtk.glob("particles_*.vtu"):
        grains += len(meshio.read(particles).points)
        written += sum((vtk / particles.name.replace("particles", kind)).stat().st_size
                       for kind in ("particles", "contacts", "walls"))
    assert 0.5 <= written / grains / frames_module.VTK_BYTES_PER_GRAIN <= 2.0


def test_output_that_would_not_fit_is_warned_of_before_the_run():
    """The shipped scenarios draw no warning; a frame every step of paper-case2 does, with
    the count of frames its phase time limits allow (68 s / dt), and VTK files every step
    do, with their count (3 files each)."""
    from types import SimpleNamespace

    from silodem.scenario_files import load_config, scenario_names
    from silodem.silo.checks import check_numbers

    def warning(cfg):
        run = SimpleNamespace(cfg=cfg, dt=check_numbers(cfg)[0])
        return FramesRecorder.from_config(cfg, Path("run")).volume_warning(run)

    for name in scenario_names():
        assert warning(load_config(name)) is None, name
    cfg = load_config("paper-case2", ["output.frame_interval=1e-9"])
    dt = check_numbers(cfg)[0]
    limits = cfg.fill.max_time + cfg.settle.max_time + cfg.discharge.max_time
    assert limits == 68.0
    said = warning(cfg)
    # an upper bound, said to be one: the default run took 14.2 s of the 68, and its frames
    # take about 40 % less in their gzip-compressed files (an audit read "8.84 GB on disk"
    # for a run that wrote 408 MB)
    assert said.startswith("output.frame_interval = 1e-09 s may save up to about "
                           f"{limits / dt:.3g} frames, ")
    assert "GB before compression" in said and "430 grains" in said
    assert "a bound that a run which settles and empties sooner stays under" in said
    cfg = load_config("paper-case2", ["output.vtk_interval=1e-9"])
    said = warning(cfg)
    assert said.startswith(f"output.vtk_interval = 1e-09 s may write up to about "
                           f"{3 * limits / dt:.3g} VTK files, ")


# --- animations and pictures ------------------------------------------------------------------
def _check_frames_differ_and_not_blank(images: list[np.ndarray]) -> None:
    spread = [float(img.std()) for img in images]
    inked = [float(np.mean(img.min(axis=2) < 200)) for img in images]
    assert min(spread) > 10  # not a blank picture
    assert min(inked) > 0.02  # something drawn besides white
    diffs = [float(np.abs(a.astype(int) - b.astype(int)).max())
             for a, b in itertools.pairwise(images)]
    assert min(diffs) > 30  # every frame is a new picture (the time in the title at least)
    changed = np.abs(images[0].astype(int) - images[-1].astype(int)).max(axis=2) > 30
    assert float(changed.mean()) > 0.005  # the grains moved between first and last


def test_animate_out_under_a_file_says_it_is_not_a_folder(run_dir, tmp_path):
    """`--out afile/x.gif` with afile a regular file said "folder 'afile' does not exist"."""
    (tmp_path / "afile").write_bytes(b"")
    res = cli("animate", str(run_dir), "--out", str(tmp_path / "afile" / "x.gif"))
    assert res.returncode == 2 and res.stderr.strip().splitlines() == [
        f"error: --out {tmp_path / 'afile' / 'x.gif'}: '{tmp_path / 'afile'}' is not a folder"]


def test_animate_out_a_pipe_or_device_is_refused(run_dir, tmp_path):
    """`--out /dev/null` wrote /dev/null.mp4 (a name without a suffix gets one): a new file
    among the devices.  A named pipe stands in for the device here."""
    pipe = tmp_path / "video"
    os.mkfifo(pipe)
    res = cli("animate", str(run_dir), "--out", str(pipe))
    assert res.returncode == 2 and res.stderr.strip().splitlines() == [
        (f"error: --out {pipe} is not a regular file (a device, a pipe or a socket); give the "
         "video's file name")]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["video"]


def test_animate_ends_with_143_when_a_callback_drops_the_sigterm(run_dir, tmp_path,
                                                                  monkeypatch, capsys):
    """A SIGTERM whose exception a callback drops while the frames are rendered (as a weakref
    callback drops a KeyboardInterrupt) still ends 'silodem animate' with one line and 143."""
    import signal

    import silodem.viz.animate
    from silodem.cli import main

    render = silodem.viz.animate.render_animation

    def render_that_drops_the_signal(plan, progress):
        signal_dropped_by_a_callback(signal.SIGTERM)
        return render(plan, progress)

    monkeypatch.setattr(silodem.viz.animate, "render_animation", render_that_drops_the_signal)
    with pytest.raises(SystemExit) as exc:
        main(["animate", str(run_dir), "--format", "gif", "--out", str(tmp_path / "a.gif")])
    assert exc.value.code == 143
    assert capsys.readouterr().err.strip().splitlines()[-1] == "interrupted (SIGTERM)"


def test_a_full_disk_names_the_file_that_could_not_be_written(run_dir, tmp_path,
                                                             monkeypatch, capsys):
    """A full disk during `plot` or `animate` said "error: No space left on device" and no
    file (the write's OSError names none): the line names the file asked for, exit code 1."""
    import silodem.viz.animate
    from silodem.atomic import write_atomic
    from silodem.cli import main

    target = tmp_path / "figure.png"

    def full(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Path, "write_bytes", full)
    with pytest.raises(OSError) as exc:
        write_atomic(target, b"png")
    assert exc.value.filename == str(target) and not list(tmp_path.iterdir())
    monkeypatch.undo()
    monkeypatch.setattr(silodem.viz.animate, "_write_gif", full)
    video = tmp_path / "a.gif"
    with pytest.raises(SystemExit) as code:
        main(["animate", str(run_dir), "--format", "gif", "--out", str(video)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code.value.code == 1 and err[-1] == f"error: No space left on device: {video}", err
    assert not list(tmp_path.iterdir())


def test_animate_mp4_has_one_video_frame_per_saved_frame(run_dir, h5):
    out = run_dir / "anim.mp4"
    res = cli("animate", str(run_dir), "--color", "force", "--out", str(out))
    assert res.returncode == 0, res.stderr
    import imageio.v2 as imageio

    reader = imageio.get_reader(out, format="FFMPEG")
    images = [np.asarray(img) for img in reader]
    reader.close()
    assert len(images) == h5["frame_time"].size
    _check_frames_differ_and_not_blank(images)
    # the summary gives the video's length (frames / fps) and calls the render time so
    n = h5["frame_time"].size
    assert f"{n} frames (" in res.stdout and f"{n / 10:.3g} s of video at 10 fps" in res.stdout
    assert "), drawn in " in res.stdout, res.stdout


def test_animate_gif_has_one_frame_per_saved_frame_at_the_fps(run_dir, h5):
    """GIF stores a frame's delay in whole hundredths of a second: --fps 15 is 100 / 7 =
    14.3 frames per second, and the summary says so (it said 15 while Pillow had rounded
    66.7 ms down to 60, 16.7 fps)."""
    res = cli("animate", str(run_dir), "--color", "coordination", "--format", "gif",
              "--fps", "15")
    assert res.returncode == 0, res.stderr
    assert "14.3 fps for --fps 15" in res.stdout
    assert "\u2501" not in res.stderr  # (no bar's last state in a log: 'rendering ━━━━ 143/143')
    images = []
    with Image.open(run_dir / "animation.gif") as gif:
        assert gif.n_frames == h5["frame_time"].size
        for k in range(gif.n_frames):
            gif.seek(k)
            assert gif.info["duration"] == 70
            images.append(np.asarray(gif.convert("RGB")))
    _check_frames_differ_and_not_blank(images)


def test_animate_out_without_a_suffix_gets_the_formats(run_dir, tmp_path):
    """`--out movie` wrote an MP4 named 'movie', which players and browsers do not
    recognise: a name without a suffix gets the format's (.mp4 by default, .gif with
    --format gif); a name with .mp4 or .gif is kept as given."""
    from silodem.viz.animate import plan_animation

    assert plan_animation(run_dir, tmp_path / "movie").out == tmp_path / "movie.mp4"
    assert plan_animation(run_dir, tmp_path / "movie", fmt="gif").out == tmp_path / "movie.gif"
    assert plan_animation(run_dir, tmp_path / "m.gif").out == tmp_path / "m.gif"
    # from Python: a format or a path of the wrong type is a one-line InputError
    from silodem.errors import InputError

    for call, needle in ((lambda: plan_animation(run_dir, fmt=3), "--format must be one of"),
                         (lambda: plan_animation(run_dir, 5), "--out must be a path"),
                         (lambda: plan_animation(None), "results folder must be a path")):
        with pytest.raises(InputError, match=needle):
            call()


@pytest.mark.parametrize("case", ["missing", "no_results", "no_frames", "bad_color",
                                  "out_in_proc", "out_a_folder", "walls_missing",
                                  "segments_missing"])
def test_animate_bad_input_is_one_line_exit_2(tmp_path, run_dir, case):
    target = tmp_path / "r"
    extra: list[str] = []
    if case != "missing":
        target.mkdir()
    if case == "no_frames":
        with h5py.File(target / "results.h5", "w") as f:
            f.attrs["scenario"] = "x"
    if case == "bad_color":
        target, extra = run_dir, ["--color", "rainbow"]
    if case == "out_in_proc":  # refused before rendering, not after (root may write nowhere)
        target, extra = run_dir, ["--out", "/proc/silodem.gif"]
    if case == "out_a_folder":  # '.' crashed (ValueError); a folder failed after rendering
        target, extra = run_dir, ["--out", str(tmp_path)]
    if case in ("walls_missing", "segments_missing"):
        shutil.copy(run_dir / "results.h5", target / "results.h5")
    if case == "walls_missing":  # was told it had no /frames, and to run it again
        shutil.copytree(run_dir / "frames", target / "frames")
        with h5py.File(target / "results.h5", "r+") as f:
            del f["walls"]
    res = cli("animate", str(target), *extra)
    assert res.returncode == 2
    assert len(res.stderr.strip().splitlines()) == 1 and "Traceback" not in res.stderr
    assert res.stderr.startswith("error:")
    if case == "out_in_proc":
        assert "rendering" not in res.stderr and "--out /proc/silodem.gif" in res.stderr
    if case == "out_a_folder":
        assert "rendering" not in res.stderr and "is a folder" in res.stderr
    if case == "walls_missing":
        assert "cannot be read" in res.stderr and "has no /frames" not in res.stderr
    if case == "segments_missing":  # results.h5 copied without frames/: its tables are there
        with h5py.File(run_dir / "results.h5") as f:  # as links to the segment files
            first = f["frames"].attrs["segments"][0].split("/")[-1]
        assert (f"keeps its frames in '{target / 'frames'}/', and {first} is not there"
                in res.stderr), res.stderr


def test_force_lines_have_a_key_that_reads_true(frames):
    """The force network's key: the run's force scale to one significant figure, half and
    twice that, each drawn as wide as the network draws a contact of that force: on the
    settled frame every unclipped line's width over its force is the key's width over its
    force.  A force whose line would be clipped is left out of the key."""
    from matplotlib.collections import LineCollection

    from silodem.viz.draw import FrameArtist, key_forces

    artist = FrameArtist(frames, "none")
    frame = frames.end_of_filling()
    artist.draw(frame)
    key = artist.force_key
    forces = [float(t.get_text().removesuffix(" N")) for t in key.get_texts()]
    # rounded to one significant figure: within half a unit of the leading digit
    unit = 10.0 ** math.floor(math.log10(artist.force_scale))
    assert abs(forces[1] - artist.force_scale) <= 0.5 * unit * (1 + 1e-12)
    assert len(f"{forces[1]:e}".split("e")[0].rstrip("0").rstrip(".")) == 1  # one figure
    assert forces == [0.5 * forces[1], forces[1], 2.0 * forces[1]]
    key_ratio = [line.get_linewidth() / f for line, f in zip(key.get_lines(), forces)]
    assert key_ratio == pytest.approx([key_ratio[0]] * len(key_ratio))
    # twice a scale rounded up past 1.2 x would be clipped: 1.5 N rounds to 2, 4 N is 6.7 pt
    assert key_forces(1.5) == [1.0, 2.0] and key_forces(1.2) == [0.5, 1.0, 2.0]
    chains = next(a for a in artist.ax.collections if isinstance(a, LineCollection))
    widths = np.asarray(chains.get_linewidths(), dtype=float)
    fn = np.concatenate([frame.contacts["fn"], frame.wall_contacts["fn"]]).astype(float)
    fn = fn[fn > 0]
    free = (widths > 0.15) & (widths < 6.0)  # not clipped
    assert free.sum() > 10
    assert widths[free] / fn[free] == pytest.approx(key_ratio[0], rel=1e-9)


@pytest.mark.parametrize(("color", "height"), [("none", 700), ("velocity", 560),
                                               ("velocity", 200), ("coordination", 320),
                                               ("force", 800)])
def test_the_keys_hide_no_grain_and_no_wall(frames, color, height):
    """The force key and the colour bar lie outside the silo's plot: their boxes on the canvas
    do not meet the plot's, nor each other, and stay inside the figure; and the plot's pixels
    are the same with the key drawn and without it (in the first frame, pouring at the top,
    and the settled one, whose force lines reach the right wall's top)."""
    from silodem.viz.draw import FrameArtist

    artist = FrameArtist(frames, color, height_px=height)
    renderer = artist.canvas.get_renderer()
    for frame in (frames[0], frames.end_of_filling()):
        artist.draw(frame)
        artist.force_key.set_visible(True)
        with_key = artist.rgb()
        plot = artist.ax.get_window_extent(renderer)
        boxes = {"key": artist.force_key.get_window_extent(renderer)}
        bars = [a for a in artist.fig.axes if a is not artist.ax]
        assert len(bars) == (0 if color == "none" else 1)
        if bars:
            boxes["colour bar"] = bars[0].get_window_extent(renderer)
        _check_bar_label(artist)
        for name, box in boxes.items():
            assert not box.overlaps(plot), name
            assert box.x0 >= 0 and box.y0 >= 0, name
            assert box.x1 <= artist.width_px and box.y1 <= artist.height_px, name
        if bars:
            assert not boxes["key"].overlaps(boxes["colour bar"])
        artist.force_key.set_visible(False)
        without = artist.rgb()
        h = artist.height_px  # the plot's pixels: rows counted from the top
        rows = slice(int(h - plot.y1) + 1, int(h - plot.y0) - 1)
        cols = slice(int(plot.x0) + 1, int(plot.x1) - 1)
        np.testing.assert_array_equal(with_key[rows, cols], without[rows, cols])
        assert not np.array_equal(with_key, without)  # (the key is drawn somewhere)


def _hand_silo(kind: str, width: float, height: float, outlet: float, slope_deg: float,
               name: str):
    """Frames (filling, settled, discharge) of a silo built as build_walls builds one (a
    ``kind`` "flat" or "hopper" cell ``width`` wide, walls ``height`` tall [m]), a block of
    grains in it with a chain of contacts; times and grain counts as wide as a long run's."""
    from silodem.silo.frames import Frame, Frames, WallGeometry

    xl, xr = 0.5 * (width - outlet), 0.5 * (width + outlet)
    zj = xl * math.tan(math.radians(slope_deg)) if kind == "hopper" else 0.0
    segs = [("left_wall", 0, height, 0, zj), ("right_wall", width, zj, width, height)]
    segs += ([("left_hopper", 0, zj, xl, 0), ("right_hopper", xr, 0, width, zj)]
             if kind == "hopper" else
             [("left_floor", 0, 0, xl, 0), ("right_floor", xr, 0, width, 0)])
    segs.append(("gate", xl, 0, xr, 0))
    walls = WallGeometry([s[0] for s in segs],
                         *(np.array([s[k] for s in segs], dtype=float) for k in range(1, 5)))
    r = 0.05 * min(width, height)
    xs, ys = np.meshgrid(np.arange(r, width - r, 2 * r), np.arange(zj + r, 0.8 * height, 2 * r))
    n = xs.size
    zeros = np.zeros(n, np.float32)
    particles = {"x": xs.ravel().astype(np.float32), "y": ys.ravel().astype(np.float32),
                 "vx": zeros, "vy": zeros - 1.0, "omega": zeros,
                 "radius": np.full(n, r, np.float32), "fx": zeros, "fy": zeros,
                 "uid": np.arange(n)}
    contacts = {"i": np.arange(n - 1, dtype=np.int32), "j": np.arange(1, n, dtype=np.int32),
                "fn": np.ones(n - 1, np.float32), "fs": np.zeros(n - 1, np.float32)}
    no_walls = {"grain": np.zeros(0, np.int32), "wall": np.zeros(0, np.int32),
                "fn": np.zeros(0, np.float32), "fs": np.zeros(0, np.float32)}
    frames = [Frame(t, round(t * 1000), phase, particles, contacts, no_walls,
                    np.array([True] * (len(segs) - 1) + [phase != "discharge"]))
              for t, phase in ((1.0, "fill"), (123.45, "settle"), (999.99, "discharge"))]
    return Frames(frames, walls, {"discharge_start_time": 123.45, "discharge_time": 876.54},
                  {}, name)


_LONG_NAME = "paper-case2-hertz-hopper-slope-55deg-grain-friction-30deg-walls-10deg"
ELLIPSIS = "\u2026"


def _check_title(artist, title: str, name: str = "") -> None:
    """The title as the renderer measures it: inside the figure, clear of the plot, the colour
    bar (with its ticks and label) and the force key; at most two lines of at least 7 pt;
    and it reads ``title`` (its line breaks where ``title`` has spaces or a comma's space, or
    after a - or _), or ``title`` with a middle part of the ``name`` it starts with left out
    (an ellipsis)."""
    renderer = artist.canvas.get_renderer()
    box = artist.text.get_window_extent(renderer)
    figure = artist.fig.bbox
    assert (figure.width, figure.height) == pytest.approx((artist.width_px, artist.height_px))
    assert figure.x0 <= box.x0 and box.x1 <= figure.x1, (box, figure)
    assert figure.y0 <= box.y0 and box.y1 <= figure.y1, (box, figure)
    others = {"plot": artist.ax.get_window_extent(renderer),
              "force key": artist.force_key.get_window_extent(renderer)}
    others.update({f"colour bar {k}": ax.get_tightbbox(renderer) for k, ax in
                   enumerate(a for a in artist.fig.axes if a is not artist.ax)})
    for what, other in others.items():
        assert not box.overlaps(other), (what, box, other)
    assert box.y0 >= others["plot"].y1 + 4  # over the plot, not beside it
    text = artist.text.get_text()
    assert text.count("\n") <= 1 and artist.text.get_fontsize() >= 7.0
    flat, want = "".join(text.split()), "".join(title.split())
    if ELLIPSIS in text:  # the name's middle left out: its ends and all the rest kept
        head, tail = flat.split(ELLIPSIS)
        assert want.startswith(head) and want.endswith(tail), (text, title)
        assert 10 <= len(head) and len(want) - len("".join(name.split())) + 4 <= len(tail)
        assert len(head) + len(tail) < len(want) and title.startswith(name)
    else:
        assert " ".join(text.split()) == " ".join(title.split()) or (  # broken in a word
            flat == want and text.split("\n")[0][-1] in "-_"), (text, title)


def _check_bar_label(artist) -> None:
    """The colour bar's label (rotated along the bar), as the renderer draws it: inside the
    figure, clear of the title, the plot, the force key and the bar's tick labels; its words
    all there, on at most two lines of at least 7 pt."""
    from silodem.viz.draw import _LABELS

    bars = [a for a in artist.fig.axes if a is not artist.ax]
    if not bars:  # (color "none": no colour bar)
        return
    artist.rgb()  # (the label is placed as the figure is drawn)
    renderer = artist.canvas.get_renderer()
    label = bars[0].yaxis.label
    box = label.get_window_extent(renderer)
    assert 0 <= box.x0 and box.x1 <= artist.width_px, (box, artist.width_px)
    assert 0 <= box.y0 and box.y1 <= artist.height_px, (box, artist.height_px)
    others = {"title": artist.text, "plot": artist.ax, "force key": artist.force_key}
    others.update({f"tick {t.get_text()}": t for t in bars[0].get_yticklabels()})
    for what, other in others.items():
        assert not box.overlaps(other.get_window_extent(renderer)), (what, box)
    assert " ".join(label.get_text().split()) == _LABELS[artist.color]
    assert label.get_text().count("\n") <= 1 and label.get_fontsize() >= 7.0


@pytest.mark.parametrize("height", [200, 240, 256, 300, 800])
@pytest.mark.parametrize("color", ["velocity", "force", "coordination"])
@pytest.mark.parametrize("name", ["paper-case2", _LONG_NAME])
def test_the_colour_bars_label_fits_at_every_height(color, height, name):
    """The colour bar's label runs along the bar, from the figure's bottom up to under the
    title at most: under about 290 px of height the force and coordination labels (250 px at
    8 pt) were longer than that and ran off the figure's bottom.  Measured by the renderer,
    it lies inside the figure, clear of the title (on two lines with a long name), the plot,
    the force key and the ticks, smaller (7 pt) or on two lines where one line of 8 pt is too
    long, the same in every frame; a figure with room for it keeps it on one line at 8 pt."""
    from silodem.viz import draw

    frames = _hand_silo("hopper", 3.4, 6.0, 1.0, 45.0, name)  # paper-case2's silo
    artist = draw.FrameArtist(frames, color, height_px=height)
    assert artist.width_px % 16 == 0 and artist.height_px % 16 == 0
    looks = set()
    for frame in frames:
        artist.draw(frame)
        _check_bar_label(artist)
        label = artist.fig.axes[1].yaxis.label
        box = label.get_window_extent(artist.canvas.get_renderer())
        looks.add((label.get_text(), label.get_fontsize(), tuple(box.bounds)))
        assert artist.rgb().shape == (artist.height_px, artist.width_px, 3)
    assert len(looks) == 1, looks
    if height >= 300 and name == "paper-case2":  # room enough: as it always was
        assert looks.pop()[:2] == (draw._LABELS[color], 8.0)


@pytest.mark.parametrize("height", [200, 240, 300, 800])
@pytest.mark.parametrize(("silo", "color"), [
    (("hopper", 3.4, 6.0, 1.0, 45.0), "velocity"),  # paper-case2's silo
    (("hopper", 1.0, 12.0, 0.3, 75.0), "force"),  # tall and narrow
    (("flat", 1.2, 15.0, 0.3, 0.0), "coordination"),
    (("flat", 3.4, 6.0, 1.0, 0.0), "none"),  # paper-case1's silo
    (("flat", 20.0, 3.0, 1.0, 0.0), "velocity"),  # wide
])
@pytest.mark.parametrize("name", ["paper-case2", _LONG_NAME])
def test_the_title_fits_over_the_plot_at_every_height(silo, color, height, name):
    """The title of an animation's frames (the scenario, time, phase, grains) and of the force
    network pictures: under about 300 px of height the figure (as wide as the silo's aspect
    makes it) was narrower than the title, which ran off its right edge.  Measured by the
    renderer, it lies inside the figure and clear of the plot and the keys, wrapped onto two
    lines and smaller where it must, and the same size and lines in every frame; the frames
    keep one size, a multiple of 16 px; the colour bar's label fits too (``_check_bar_label``).
    """
    from silodem.viz import draw, network

    frames = _hand_silo(*silo, name)
    artist = draw.FrameArtist(frames, color, height_px=height)
    assert artist.width_px % 16 == 0 and artist.height_px % 16 == 0
    looks = set()
    for frame in frames:
        artist.draw(frame)
        _check_title(artist, f"{name}   t = {frame.time:6.2f} s   {frame.phase:<9}   "
                     f"{frame.n} grains", name)
        _check_bar_label(artist)
        looks.add((artist.text.get_fontsize(), artist.text.get_text().count("\n")))
        assert artist.rgb().shape == (artist.height_px, artist.width_px, 3)
    assert len(looks) == 1, looks
    if height >= 560 and silo[1] / silo[2] > 0.5 and name == "paper-case2":  # not narrow
        assert looks == {(draw.TITLE_SIZES[0], 0)}  # room enough: one line at full size
    if name != "paper-case2":  # (the pictures' titles have no name)
        return

    drawn = []

    class Checked(draw.FrameArtist):  # each picture's title checked as it is drawn
        def draw(self, frame, title=None):
            super().draw(frame, title)
            _check_title(self, title)
            _check_bar_label(self)
            drawn.append(title)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(draw, "FrameArtist", Checked)
        network.force_network_pngs(frames)
        network.force_network_png(frames, "final", color=color, height_px=height)
        frames.status = "running"  # unfinished before settling ended: the longest label
        network.force_network_png(frames, "end-of-filling", color=color, height_px=height)
    # (the end of filling and the discharge's one frame, the last frame, the unsettled end)
    assert len(drawn) == 4 and "not settled" in drawn[-1]


@pytest.mark.parametrize("height", [200, 240, 300])
def test_the_titles_of_a_runs_pictures_and_frames_fit_at_small_heights(run_dir, frames,
                                                                       height, monkeypatch):
    """The quick paper-case2 run: its force network pictures ("end of filling (settled), t =
    4.45 s (155 grains)" ran off a figure 200 to 300 px tall) and every frame of its
    animation (the grains' count growing from none while it fills) keep their title inside
    the figure, over the plot, at one size and on the same lines in every frame."""
    from silodem.viz import draw, network

    drawn = []

    class Checked(draw.FrameArtist):
        def draw(self, frame, title=None):
            super().draw(frame, title)
            if title is not None:
                _check_title(self, title)
            else:
                _check_title(self, f"{frames.scenario}   t = {frame.time:6.2f} s   "
                             f"{frame.phase:<9}   {frame.n} grains", frames.scenario)
            drawn.append((self.text.get_fontsize(), self.text.get_text().count("\n")))

    monkeypatch.setattr(draw, "FrameArtist", Checked)
    for view in network.VIEWS:
        network.force_network_png(run_dir, view, height_px=height)
    drawn.clear()
    artist = Checked(frames, "velocity", height_px=height)
    for frame in frames:
        artist.draw(frame)
    assert len(drawn) == len(frames) and len(set(drawn)) == 1


def test_a_name_too_long_for_the_title_is_shortened_in_its_middle_not_the_times():
    """A scenario's name may be 200 characters long: at 200 px high the default title keeps
    its time, phase and grains, and the name's two ends (where a study's runs differ) with
    an ellipsis between them."""
    from silodem.viz.draw import FrameArtist

    name = "study-" + "x" * 180 + "-phiW-10"
    frames = _hand_silo("hopper", 1.0, 12.0, 0.3, 75.0, name)
    artist = FrameArtist(frames, "velocity", height_px=200)
    artist.draw(frames[2])
    text = artist.text.get_text()
    assert text.startswith("study-xxx") and ELLIPSIS in text and text.endswith(
        f"phiW-10   t = 999.99 s   discharge   {frames[2].n} grains"), text
    _check_title(artist, f"{name}   t = 999.99 s   discharge   {frames[2].n} grains", name)


def _relative_luminance(rgb) -> float:
    """WCAG 2 relative luminance of an sRGB colour (components 0 to 1)."""
    lin = [c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4 for c in rgb[:3]]
    return 0.2126 * lin[0] + 0.7152 * lin[1] + 0.0722 * lin[2]


@pytest.mark.parametrize("color", ["velocity", "force"])
def test_force_lines_stand_out_on_grains_at_rest(frames, color):
    """A grain at rest (speed 0; no force on it) is drawn in the low end of the colour map:
    against it the red force lines have a WCAG contrast ratio (L1 + 0.05) / (L2 + 0.05) of at
    least 4.5 (6.1 on YlGnBu's pale yellow; 2.5 on viridis' dark purple), so a settled
    packing's network reads."""
    from matplotlib.colors import to_rgb

    from silodem.viz.draw import CHAIN_COLOR, FrameArtist

    artist = FrameArtist(frames, color)
    rest = _relative_luminance(artist.cmap(artist.norm(0.0)))
    chain = _relative_luminance(to_rgb(CHAIN_COLOR))
    assert (max(rest, chain) + 0.05) / (min(rest, chain) + 0.05) >= 4.5


def test_force_network_of_a_file_without_frames_is_a_one_line_error(tmp_path):
    """A results.h5 with no /frames (written by an older silodem or another program) gives a
    ValueError (``NoFramesError``, from ``read_frames`` itself) naming the file and what it
    lacks, not a bare KeyError('frames'); the report (which catches ValueError) then leaves
    the snapshots out."""
    import h5py

    from silodem.silo.frames import NoFramesError
    from silodem.viz import force_network_png, force_network_pngs

    path = tmp_path / "results.h5"
    with h5py.File(path, "w") as f:
        f.attrs["scenario"] = "none"
    with pytest.raises(NoFramesError):
        read_frames(path)
    for draw in (lambda: read_frames(path), lambda: force_network_png(path),
                 lambda: force_network_pngs(path)):
        with pytest.raises(ValueError, match="has no /frames") as err:
            draw()
        assert str(path) in str(err.value) and "\n" not in str(err.value)


def test_force_network_pictures_of_filling_and_discharge(run_dir, frames, h5):
    from silodem.viz import force_network_png, force_network_pngs
    from silodem.viz.network import select_frame

    pictures = force_network_pngs(run_dir / "results.h5")
    assert list(pictures) == ["end-of-filling", "early-discharge", "late-discharge"]
    images = [np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))
              for png in pictures.values()]
    assert all(png.startswith(b"\x89PNG") for png in pictures.values())
    _check_frames_differ_and_not_blank(images)
    for view, png in pictures.items():  # one artist for the three: each as drawn on its own
        assert png == force_network_png(run_dir / "results.h5", view), view
    # the moments: settled packing, then inside the discharge, early before late
    t_open = h5["events"]["discharge_start_time"]
    assert select_frame(frames, "end-of-filling").time == pytest.approx(h5["settled"]["time"])
    early, late = (select_frame(frames, v) for v in ("early-discharge", "late-discharge"))
    assert t_open < early.time < late.time <= h5["final"]["time"]
    # ... at 15 % and 75 % of the discharge's duration, to the nearest frame (0.1 s apart)
    duration = h5["events"]["discharge_time"]
    for frame, share in ((early, 0.15), (late, 0.75)):
        assert frame.time == pytest.approx(t_open + share * duration, abs=0.05 + h5["dt"])
    # a time picks the nearest frame
    assert force_network_png(run_dir / "results.h5", 2.0).startswith(b"\x89PNG")
    assert select_frame(frames, 2.03).time == pytest.approx(2.0, abs=0.05 + h5["dt"])
    # the results folder is read as its results.h5
    assert force_network_png(run_dir, "final") == force_network_png(run_dir / "results.h5",
                                                                    "final")


def test_force_network_pictures_are_of_distinct_moments_and_need_frames(frames):
    """With one saved discharge frame the early and late discharge pictures were the same
    picture under two labels: the late one is left out.  Frames without any frame are a
    ValueError, as the docstring says (an empty dict before)."""
    from silodem.silo.frames import Frames
    from silodem.viz import force_network_pngs

    first_out = next(k for k, p in enumerate(frames.phases) if p == "discharge")
    one = Frames([frames[k] for k in range(first_out + 1)], frames.walls, {}, frames.attrs)
    assert list(force_network_pngs(one)) == ["end-of-filling", "early-discharge"]
    two = Frames([frames[k] for k in range(first_out + 2)], frames.walls, {}, frames.attrs)
    assert list(force_network_pngs(two)) == ["end-of-filling", "early-discharge",
                                             "late-discharge"]
    with pytest.raises(ValueError, match="has no frames"):
        force_network_pngs(Frames([], frames.walls, {}, frames.attrs))


@pytest.mark.parametrize("call, needle", [
    (lambda d: _network(d, float("inf")), "a time in seconds; got inf"),
    (lambda d: _network(d, float("nan")), "a time in seconds; got nan"),
    (lambda d: _network(d, True), "a time in seconds; got True"),
    (lambda d: _network(d, height_px=0), "height_px must be an integer from 200"),
    (lambda d: _network(d, height_px=10**6), "height_px must be an integer from 200"),
    (lambda d: _network(d, height_px=None), "height_px must be an integer from 200"),
    (lambda d: _network(d, color="red"), "color must be one of"),
    (lambda d: _network(d / "nothing.h5"), "does not exist"),
    (lambda d: _network(d / "config.toml"), "cannot read"),
    (lambda d: _network(d / "figures"), "has no results.h5|does not exist"),
    (lambda d: _network(None), "results_h5 must be a run's results.h5 or its results folder"),
    (lambda d: read_frames(d / "results.h5").nearest(float("nan")), "finite number of seconds"),
    (lambda d: read_frames(d / "results.h5")[1.5], "indexed by an integer"),
])
def test_bad_requests_for_pictures_are_one_line_errors(run_dir, call, needle):
    """ValueError (TypeError for an argument of the wrong type), one line.  Before: inf and
    nan drew the first frame, a folder or a missing file raised h5py's errors several lines
    deep, a height of 0 or 1e6 px matplotlib's or a bad_alloc."""
    with pytest.raises((ValueError, TypeError), match=needle) as err:
        call(run_dir)
    assert "\n" not in str(err.value)


def _network(path, which="final", **kwargs):
    from silodem.viz import force_network_png

    return force_network_png(path, which, **kwargs)


def test_every_number_under_frames_carries_its_unit(run_dir):
    """docs/output.md: datasets of numbers carry a ``unit`` attribute; the frames' index
    (step, phase, the offsets) had none (counts and codes: '-')."""
    missing = []
    with h5py.File(run_dir / "results.h5", "r") as f:
        f["frames"].visititems(lambda name, item: missing.append(name) if (
            isinstance(item, h5py.Dataset) and item.dtype.kind in "iuf"
            and "unit" not in item.attrs) else None)
        assert f["frames/step"].attrs["unit"] == "-" and f["frames/time"].attrs["unit"] == "s"
    assert missing == []


def test_every_number_and_flag_in_results_h5_carries_its_unit(run_dir):
    """docs/output.md: datasets of numbers carry a ``unit`` attribute, flags (bool) '-':
    /walls/active and /frames/walls_active had '-', /settled and /final walls_active none."""
    missing = []
    with h5py.File(run_dir / "results.h5", "r") as f:
        f.visititems(lambda name, item: missing.append(name) if (
            isinstance(item, h5py.Dataset) and item.dtype.kind in "iufb"
            and "unit" not in item.attrs) else None)
        assert f["settled/walls_active"].attrs["unit"] == f["walls/active"].attrs["unit"] == "-"
    assert missing == []
