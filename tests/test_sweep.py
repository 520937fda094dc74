"""Parametric studies on Dask (docs/sweeps.md): a cluster reproduces a serial run bit for bit,
a killed worker loses no grid point, a second invocation recomputes nothing, bad study files
end in one line with exit code 2."""

from __future__ import annotations

import csv
import json
import math
import os
import random
import re
import shutil
import signal
import socket
import threading
import time
import tomllib
import warnings
from pathlib import Path

import h5py
import numpy as np
import pytest

from silodem.cli import main
from silodem.errors import InputError
from silodem.study import expand, load_study, run_study
from silodem.study.cluster import local_cluster
from silodem.study.spec import _first_repeat, _same_value

# A tiny study: the paper's hopper case shrunk by --quick (about 50 grains, a 1 s discharge),
# two grain-grain friction angles, one seed; no per-run pictures or report.
TINY = """\
base = "paper-case2"
seeds = [3]
[set]
"fill.n_particles" = 60
"discharge.max_time" = 1.0
"measure.report" = false
"output.png" = false
[grid]
"material.friction_deg" = [20.0, 30.0]
"""

SNAPSHOT_FIELDS = ("x", "y", "vx", "vy", "omega", "radius", "uid")


def _plan(folder: Path):
    path = folder / "tiny.toml"
    path.write_text(TINY, encoding="utf-8")
    return expand(load_study(str(path)), quick=True)


def _arrays(run_dir: Path) -> dict[str, np.ndarray]:
    out = {}
    with h5py.File(run_dir / "results.h5", "r") as h5:
        assert h5.attrs["status"] == "complete"
        for snap in ("settled", "final"):
            for key in SNAPSHOT_FIELDS:
                out[f"{snap}/{key}"] = h5[f"{snap}/particles/{key}"][()]
    return out


def _assert_same_runs(plan, dir_a: Path, dir_b: Path) -> None:
    """Every planned run is finished in both folders with bit-identical grain arrays, and the
    two results tables are the same text."""
    for run in plan.runs:
        a, b = _arrays(dir_a / "runs" / run.id), _arrays(dir_b / "runs" / run.id)
        assert a.keys() == b.keys()
        for key in a:
            assert a[key].dtype == b[key].dtype and a[key].tobytes() == b[key].tobytes(), \
                f"{run.id}: {key} differs"
    text_a = (dir_a / "results.csv").read_text(encoding="utf-8")
    text_b = (dir_b / "results.csv").read_text(encoding="utf-8")
    assert text_a == text_b
    assert len(text_a.splitlines()) == 1 + len(plan.runs)


def _run_folders(study_dir: Path) -> list[str]:
    return sorted(p.name for p in (study_dir / "runs").iterdir())


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    """The tiny study run in this process, one run after the other: the reference."""
    root = tmp_path_factory.mktemp("serial")
    plan = _plan(root)
    outcome = run_study(plan, root / "study", serial=True)
    assert outcome.computed == len(plan.runs) == 2 and not outcome.failed
    return plan, root / "study"


@pytest.fixture(scope="module")
def client():
    from distributed import Client

    cluster = local_cluster(2)
    c = Client(cluster)
    yield c
    c.close()
    cluster.close()


def test_local_cluster_equals_serial_and_second_invocation_recomputes_nothing(
        serial, client, tmp_path, capsys):
    plan_ref, ref_dir = serial
    plan = _plan(tmp_path)
    assert [r.id for r in plan.runs] == [r.id for r in plan_ref.runs]
    study_dir = tmp_path / "study"
    outcome = run_study(plan, study_dir, client=client)
    assert outcome.computed == 2 and outcome.skipped == 0 and not outcome.failed
    # the runs ran in the cluster's worker processes, not in this one
    worker_pids = set(client.run(os.getpid).values())
    assert {r["pid"] for r in outcome.results.values()} <= worker_pids
    assert os.getpid() not in worker_pids
    assert _run_folders(study_dir) == sorted(r.id for r in plan.runs)
    _assert_same_runs(plan, ref_dir, study_dir)

    # the same command again, from the command line: nothing is recomputed
    stamps = {p: p.stat().st_mtime_ns for p in (study_dir / "runs").rglob("*")}
    stamps[study_dir / "runs"] = (study_dir / "runs").stat().st_mtime_ns
    again = run_study(_plan(tmp_path), study_dir, client=client)
    assert again.computed == 0 and again.skipped == 2 and not again.results
    # the report still says where the runs were computed (it said only "finished before")
    assert again.where == f"every run finished before this invocation, on {socket.gethostname()}"
    with pytest.raises(SystemExit) as exc:
        main(["sweep", str(tmp_path / "tiny.toml"), "--quick", "--out", str(study_dir)])
    assert exc.value.code == 0
    # it says so first (it said the runs not finished yet would run on a cluster)
    first = capsys.readouterr().out.splitlines()[0]
    assert first.endswith(f"2 runs -> {study_dir}; all finished already: nothing to run")
    after = {p: p.stat().st_mtime_ns for p in (study_dir / "runs").rglob("*")}
    after[study_dir / "runs"] = (study_dir / "runs").stat().st_mtime_ns
    assert after == stamps
    _assert_same_runs(plan, ref_dir, study_dir)


def test_a_worker_killed_mid_run_loses_no_grid_point(serial, tmp_path):
    """kill -9 the worker process that is running a run; the study still ends with every grid
    point, each equal to the serial run, and no half folder."""
    from distributed import Client

    _, ref_dir = serial
    plan = _plan(tmp_path)
    study_dir = tmp_path / "study"
    runs = study_dir / "runs"
    cluster = local_cluster(2)  # fresh workers: a run starts with imports, a wide window
    c = Client(cluster)
    try:
        worker_pids = set(c.run(os.getpid).values())
        result: dict = {}
        thread = threading.Thread(
            target=lambda: result.update(outcome=run_study(plan, study_dir, client=c)))
        thread.start()
        victim = None
        deadline = time.monotonic() + 120
        while victim is None and time.monotonic() < deadline:
            for attempt in runs.glob(".*.tmp-*/attempt.json") if runs.is_dir() else []:
                try:
                    info = json.loads(attempt.read_text(encoding="utf-8"))
                except (OSError, ValueError):
                    continue  # being written
                victim = (info["pid"], info["id"], attempt.parent)
                break
            time.sleep(0.01)
        assert victim is not None, "no run started"
        pid, run_id, tmp = victim
        assert pid in worker_pids  # the process running the run is a Dask worker
        os.kill(pid, signal.SIGKILL)
        time.sleep(0.2)
        # killed mid-run: its temporary folder is left, the run is not finished
        assert tmp.is_dir() and not (runs / run_id).exists()
        thread.join(timeout=300)
        assert not thread.is_alive()
    finally:
        c.close()
        cluster.close()
    outcome = result["outcome"]
    assert not outcome.failed
    assert outcome.computed == 2
    # every grid point has its result, nothing else is left in runs/
    assert _run_folders(study_dir) == sorted(r.id for r in plan.runs)
    _assert_same_runs(plan, ref_dir, study_dir)


def test_ctrl_c_in_a_terminal_stops_the_sweep_without_worker_tracebacks(tmp_path):
    """Ctrl-C goes to the terminal's whole process group: the sweep and its Dask workers.
    The sweep stopped cleanly, but each worker that took the signal printed tracebacks
    (CancelledError, KeyboardInterrupt); workers now start with SIGINT ignored."""
    import subprocess

    from reliability_helpers import command, env

    study = tmp_path / "tiny.toml"
    study.write_text(TINY, encoding="utf-8")
    runs = tmp_path / "study" / "runs"
    # as from a terminal: SIGINT at its default, which Python turns into KeyboardInterrupt.
    # A test run started in the background by a non-interactive shell inherits SIGINT
    # ignored, and a Python started so keeps ignoring it (the sweep then ran to its end)
    proc = subprocess.Popen(command("sweep", str(study), "--workers", "2", "--out",
                                    str(tmp_path / "study")),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env(), start_new_session=True,
                            # one signal() call in the child before exec: safe with threads
                            preexec_fn=lambda: signal.signal(  # noqa: PLW1509
                                signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 120
        while not (runs.is_dir() and any(runs.glob(".*.tmp-*/attempt.json"))):
            assert proc.poll() is None and time.monotonic() < deadline, "no run started"
            time.sleep(0.01)
        os.killpg(proc.pid, signal.SIGINT)
        _, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    assert proc.returncode == 130, stderr[-3000:]
    assert "Traceback" not in stderr, stderr[-3000:]
    # (without --quick: the runs of the full-size tiny case)
    _assert_the_stop_line(stderr, expand(load_study(str(study))), tmp_path / "study")


def _assert_the_stop_line(stderr: str, plan, study_dir: Path, prefix: str = "") -> int:
    """stderr of a stopped sweep is its one line, after nothing but the lines of the runs
    that finished (progress); the line's counts are those of the finished run folders on
    disk.  Returns how many are finished."""
    from silodem.study.execute import is_finished

    *before, line = stderr.strip().splitlines()
    assert all(re.match(r"(computed|existing) \S+ \(\d+\.\d s on ", b) for b in before), stderr
    runs = study_dir / "runs"
    done = sum(is_finished(runs / r.id) for r in plan.runs)
    total, left = len(plan.runs), len(plan.runs) - done
    if done == 0:
        text = f"none of the {total} runs is finished yet; repeat the command to run them"
    elif left == 0:
        text = (f"all {total} runs are finished and kept in {runs}; repeat the command to "
                f"write {study_dir / 'results.csv'} and the report")
    else:
        text = (f"{done} of {total} runs {'is' if done == 1 else 'are'} finished and kept in "
                f"{runs}; repeat the command to run the other "
                f"{'one' if left == 1 else left}")
    assert line == f"interrupted: {prefix}{text}", (line, stderr[-3000:])
    return done


def _live_processes_of_session(sid: int) -> list[str]:
    """The processes of session ``sid`` still running (zombies not counted): a sweep's
    local cluster left behind."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rpartition(")")[2].split()
        except OSError:
            continue
        if int(fields[3]) == sid and fields[0] != "Z":
            found.append(stat.parent.name)
    return found


SIX = TINY.replace('[20.0, 30.0]', '[15.0, 20.0, 25.0, 30.0, 35.0, 40.0]')


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_stopped_sweep_says_how_many_runs_are_kept_and_how_to_go_on(tmp_path, sig):
    """Ctrl-C or SIGTERM stopped a sweep with a bare 'interrupted'.  Its one line now says how
    many runs are finished and kept and that the command goes on: counted on disk after the
    cluster is closed.  A second Ctrl-C while the cluster closes waits for the close (it broke
    it off: the line came at once, then the exit waited ~10 s on distributed's clean-up; the
    shield is tested in-process below, here that the count is right and nothing is left).
    Ctrl-C goes to the terminal's whole process group; SIGTERM here to the sweep alone."""
    import subprocess

    from reliability_helpers import cli, command, env

    from silodem.study.execute import is_finished

    study = tmp_path / "six.toml"
    study.write_text(SIX, encoding="utf-8")
    plan = expand(load_study(str(study)), quick=True)
    study_dir = tmp_path / "study"
    runs = study_dir / "runs"
    args = ("sweep", str(study), "--quick", "--workers", "2", "--out", str(study_dir))
    proc = subprocess.Popen(command(*args), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env(), start_new_session=True,
                            preexec_fn=lambda: signal.signal(  # noqa: PLW1509 - as a terminal
                                signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 180
        while not any(is_finished(runs / r.id) for r in plan.runs):  # one kept, at least
            assert proc.poll() is None and time.monotonic() < deadline, "no run finished"
            time.sleep(0.01)
        if sig == signal.SIGINT:
            os.killpg(proc.pid, sig)
            time.sleep(0.3)  # the cluster is being closed: a second Ctrl-C
            if proc.poll() is None:
                os.killpg(proc.pid, sig)
        else:
            proc.send_signal(sig)
        _, stderr = proc.communicate(timeout=120)
        # a worker may still be exiting as the sweep ends; one left behind never does
        gone_by = time.monotonic() + 30.0
        while (left_behind := _live_processes_of_session(proc.pid)) and \
                time.monotonic() < gone_by:
            time.sleep(0.1)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    assert proc.returncode == 128 + sig, stderr[-3000:]
    assert "Traceback" not in stderr, stderr[-3000:]
    name = "" if sig == signal.SIGINT else "SIGTERM: "
    done = _assert_the_stop_line(stderr, plan, study_dir, name)
    assert not left_behind  # the cluster's nannies and workers are closed
    if sig == signal.SIGINT and done < len(plan.runs):  # what the line says to do: the rest
        again = cli(*args, timeout=300)
        assert again.returncode == 0, again.stderr[-3000:]
        assert (f"{len(plan.runs) - done} computed, {done} already finished, 0 failed"
                in again.stdout), again.stdout


OUTLET_STUDY = """\
base = "paper-case2"
seeds = [1, 2]
[grid]
"material.friction_deg" = [20.0, 30.0]
"silo.outlet_width" = [0.6, 0.8, 1.0, 1.2, 1.4]
"""


def test_the_beverloo_fit_of_a_mixture_takes_the_mean_diameter_by_number(tmp_path):
    """Radii 0.05 m (80 % by number) and 0.15 m: d = 2 (0.8 x 0.05 + 0.2 x 0.15) = 0.14 m,
    not r_min + r_max = 0.2 m. Rates made with k = 1.4 at d = 0.14 m give k = 1.4 back, and
    the fit and beverloo.csv name d = 0.14 m."""
    import csv as csv_module

    from silodem import theory as th
    from silodem.study.beverloo import outlet_fits
    from silodem.study.report import write_study_report

    path = tmp_path / "outlets.toml"
    path.write_text(OUTLET_STUDY.replace("[grid]", """[set]
"material.radius_distribution" = "discrete"
"material.radii" = [0.05, 0.15]
"material.radius_shares" = [0.8, 0.2]
"material.radius_min" = 0.05
"material.radius_max" = 0.15
[grid]"""), encoding="utf-8")
    plan = expand(load_study(str(path)), quick=True)
    rows = [{"id": run.id, "bulk_density": 700.0, "discharge_rate_err": 0.0,
             "discharge_rate": th.beverloo_2d(run.cfg.silo.outlet_width, 0.14, 700.0, 9.81,
                                              0.5, 1.4, 1.0)} for run in plan.runs]
    fits, _ = outlet_fits(plan, {r["id"]: r for r in rows})
    assert [f.d for f in fits] == pytest.approx([0.14, 0.14], rel=1e-12)
    assert [f.fixed.k for f in fits] == pytest.approx([1.4, 1.4], rel=1e-9)
    write_study_report(plan, tmp_path / "study", rows)
    with open(tmp_path / "study" / "beverloo.csv", encoding="utf-8") as fh:
        table = list(csv_module.DictReader(fh))
    assert [float(r["grain_diameter"]) for r in table] == pytest.approx([0.14, 0.14])


@pytest.mark.parametrize("k", [0.0, -0.5])
def test_a_beverloo_fit_with_k_at_or_below_zero_is_drawn(tmp_path, k):
    """Rates exactly ~ D^(3/2) (k = 0; the fit's k is 0 only to round-off) or with k < 0 (a
    fit may give one): the study report was not written at all, because the figure's line
    started at D = 0, which the law's function refuses. The line drawn is the law's W^(2/3)
    at the widths, and the report is written."""
    from silodem import theory as th
    from silodem.study.beverloo import fig_beverloo, outlet_fits
    from silodem.study.report import write_study_report

    path = tmp_path / "outlets.toml"
    path.write_text(OUTLET_STUDY, encoding="utf-8")
    plan = expand(load_study(str(path)), quick=True)
    rho_b, d = 700.0, 0.2
    rows = [{"id": run.id, "discharge_rate": th.beverloo_2d(
                run.cfg.silo.outlet_width, d, rho_b, 9.81, 0.5, k, 1.0),
             "discharge_rate_err": 0.0, "bulk_density": rho_b} for run in plan.runs]
    fits, _ = outlet_fits(plan, {r["id"]: r for r in rows})
    assert [f.fixed.k for f in fits] == pytest.approx([k, k], abs=1e-9)
    line = fig_beverloo(fits).axes[0].get_lines()[-1]
    x, y = line.get_data()
    W = th.beverloo_2d(x[-1], d, rho_b, 9.81, 0.5, k, 1.0)
    assert y[-1] == pytest.approx(W ** (2 / 3), rel=1e-9)
    write_study_report(plan, tmp_path / "study", rows)
    assert "id='beverloo'" in (tmp_path / "study" / "report.html").read_text(encoding="utf-8")


def test_a_figure_that_cannot_be_drawn_leaves_the_rest_of_the_study_report(tmp_path,
                                                                          monkeypatch):
    """One figure's error (as the Beverloo figure's with k <= 0 was) ended the report: no
    report.html for the whole study. The figure is now left out, the page says which and
    why, ``undrawn`` carries it for the command's warning, and the other figures stand."""
    import silodem.study.report as study_report
    from silodem import theory as th

    def broken(*args, **kwargs):
        raise ValueError("no numbers")

    monkeypatch.setattr(study_report, "fig_heatmaps", broken)
    path = tmp_path / "outlets.toml"
    path.write_text(OUTLET_STUDY, encoding="utf-8")
    plan = expand(load_study(str(path)), quick=True)
    rows = [{"id": run.id, "discharge_rate": th.beverloo_2d(
                run.cfg.silo.outlet_width, 0.2, 700.0, 9.81, 0.5, 1.4, 1.0),
             "discharge_rate_err": 0.0, "bulk_density": 700.0} for run in plan.runs]
    undrawn: dict[str, str] = {}
    page = study_report.write_study_report(plan, tmp_path / "study", rows, undrawn=undrawn)
    html = page.read_text(encoding="utf-8")
    assert undrawn == {"heatmaps": "ValueError: no numbers"}
    assert "heatmaps could not be drawn (ValueError: no numbers)" in html
    assert "id='heatmaps'" not in html and "id='beverloo'" in html
    assert not (tmp_path / "study" / "figures" / "heatmaps.png").exists()


def test_a_grid_over_outlet_widths_gets_the_beverloo_constants(tmp_path):
    """Rates drawn from the 2D Beverloo law (docs/theory.md), one C per friction angle, k = 1.4,
    the two seeds 3 % above and below it: the study's fit gives C and k back (the seed means
    are the law), b = 3/2 when free, and the report and beverloo.csv carry them.

    The errors of the fixed-b fit, from the seeds' spread: W_err = 3 % of W, so y = W^(2/3)
    = a (D - k d), a = (C rho_b sqrt(g) t)^(2/3), has sigma_y = (2/3) 0.03 y = 0.02 a u with
    u = D - k d.  Weighted least squares for the line y = a D + c (weights 1/sigma_y^2, the
    given errors taken as absolute), with S, Sx, Sxx the sums of w, w D, w D^2 and Delta =
    S Sxx - Sx^2: Var(a) = S / Delta, Var(c) = Sxx / Delta, Cov = -Sx / Delta.  Propagated
    to first order: C ~ a^(3/2) gives C_err = 1.5 C sqrt(S / Delta) (a / a scaled out), and
    k = -c / (a d) gives k_err^2 = k^2 S/Delta - 2 k Sx / (d Delta) + Sxx / (d^2 Delta)."""
    import csv as csv_module

    from silodem import theory as th
    from silodem.study.beverloo import outlet_fits
    from silodem.study.report import write_study_report

    path = tmp_path / "outlets.toml"
    path.write_text(OUTLET_STUDY, encoding="utf-8")
    plan = expand(load_study(str(path)), quick=True)
    C_of = {20.0: 0.55, 30.0: 0.45}
    rho_b, d = 700.0, 0.2  # d: the mean diameter, r_min + r_max of paper-case2
    rows = []
    for run in plan.runs:
        W = th.beverloo_2d(run.cfg.silo.outlet_width, d, rho_b, 9.81,
                           C_of[run.cfg.material.friction_deg], 1.4, 1.0)
        rows.append({"id": run.id, "discharge_rate": W * (1.03 if run.seed == 1 else 0.97),
                     "discharge_rate_err": 0.01 * W, "bulk_density": rho_b})
    fits, notes = outlet_fits(plan, {r["id"]: r for r in rows})
    assert [f.label for f in fits] == ["phiG=20 deg", "phiG=30 deg"] and notes == []
    for f, C in zip(fits, (0.55, 0.45)):
        assert f.D.tolist() == [0.6, 0.8, 1.0, 1.2, 1.4] and f.n_runs == 10
        assert (f.fixed.C, f.fixed.k) == pytest.approx((C, 1.4), rel=1e-9)
        assert (f.free.C, f.free.k, f.free.b) == pytest.approx((C, 1.4, 1.5), rel=1e-6)
        # error of a mean: the seeds' spread (3 % of W, sample std / sqrt 2) beats 1 % / sqrt 2
        assert f.W_err == pytest.approx(0.03 * f.W, rel=1e-9)
        u = f.D - 1.4 * d
        w = 1.0 / (0.02 * u) ** 2  # in units of 1/a^2: a scales out of the relative errors
        S, Sx, Sxx = w.sum(), (w * f.D).sum(), (w * f.D**2).sum()
        delta = S * Sxx - Sx**2
        assert f.fixed.C_err == pytest.approx(1.5 * C * math.sqrt(S / delta), rel=1e-6)
        k_var = (1.4**2 * S - 2 * 1.4 * Sx / d + Sxx / d**2) / delta
        assert f.fixed.k_err == pytest.approx(math.sqrt(k_var), rel=1e-6)
    write_study_report(plan, tmp_path / "study", rows)
    with open(tmp_path / "study" / "beverloo.csv", encoding="utf-8") as fh:
        table = list(csv_module.DictReader(fh))
    assert [float(r["C"]) for r in table] == pytest.approx([0.55, 0.45], rel=1e-9)
    assert [float(r["b_free"]) for r in table] == pytest.approx([1.5, 1.5], rel=1e-6)
    html = (tmp_path / "study" / "report.html").read_text(encoding="utf-8")
    assert "Beverloo fit" in html and "id='beverloo'" in html
    # every column of results.csv is explained, the per-circle ones too (docs/sweeps.md)
    from silodem.study.table import CIRCLE_QUANTITIES, COLUMNS
    for column, _, _ in COLUMNS:
        assert f"<td>{column}</td>" in html
    for column, _, _ in CIRCLE_QUANTITIES:
        assert f"<td>circle_&lt;name&gt;_{column}</td>" in html
    # a study without a description writes no empty paragraph, a figure without the paper's
    # number no empty bold label, and an image's alt text is what it shows, not its file name
    # (an audit: alt='beverloo' was read out to a screen reader)
    assert "<p></p>" not in html and "<b></b>" not in html
    assert "alt='beverloo'" not in html and "alt='Discharge rate against outlet width" in html

    # a clog at the narrowest outlet of phiG = 30: that width leaves the fit and the note says
    # so; its settled packing still counts in rho_b.  With one more width clogged, no fit.
    for row, run in zip(rows, plan.runs):
        if run.cfg.material.friction_deg == 30.0 and run.cfg.silo.outlet_width == 0.6:
            row["discharge_rate"] = row["discharge_rate_err"] = float("nan")
            row["bulk_density"] = 2 * rho_b
    fits, notes = outlet_fits(plan, {r["id"]: r for r in rows})
    assert fits[1].left_out == [0.6] and fits[1].D.tolist() == [0.8, 1.0, 1.2, 1.4]
    assert fits[1].rho_b == pytest.approx(rho_b * 12 / 10)  # 2 of its 10 packings at 2 rho_b
    C_rho = fits[1].fixed.C * fits[1].rho_b  # the rates fix C rho_b, whatever rho_b is
    assert (C_rho, fits[1].fixed.k) == pytest.approx((0.45 * rho_b, 1.4))
    assert notes == [("phiG=30 deg: no steady rate at D = 0.6 m (clogged, too short, or not "
                      "finished)")]
    for row, run in zip(rows, plan.runs):
        if run.cfg.material.friction_deg == 30.0 and run.cfg.silo.outlet_width in (0.8, 1.0):
            row["discharge_rate"] = float("nan")
    fits, notes = outlet_fits(plan, {r["id"]: r for r in rows})
    assert [f.label for f in fits] == ["phiG=20 deg"]
    assert notes == [("phiG=30 deg: no fit, 2 outlet width(s) with a steady rate, 3 needed; no "
                      "steady rate at D = 0.6, 0.8, 1 m (clogged, too short, or not finished)")]
    write_study_report(plan, tmp_path / "study", rows)
    html = (tmp_path / "study" / "report.html").read_text(encoding="utf-8")
    assert "phiG=30 deg: no fit" in html

    # rates that fall as the outlet widens follow no Beverloo law: a note, not a fit
    for row, run in zip(rows, plan.runs):
        if run.cfg.material.friction_deg == 20.0:
            row["discharge_rate"] = 10.0 - run.cfg.silo.outlet_width
    fits, notes = outlet_fits(plan, {r["id"]: r for r in rows})
    assert fits == [] and notes[0].startswith("phiG=20 deg: no fit, the rates do not grow with "
                                              "the outlet width")


@pytest.mark.parametrize(("text", "needles"), [
    (TINY.replace('seeds = [3]', 'seeds = [3]\ngird = 1'), ["unknown key 'gird'", "'grid'"]),
    (TINY.replace('"material.friction_deg"', '"material.frction_deg"'),
     ["material.frction_deg", "did you mean 'material.friction_deg'"]),
    (TINY.replace('"material.friction_deg"', '"silo"'), ["'silo' is a section"]),
    (TINY.replace('"material.friction_deg" = [20.0, 30.0]', 'material.friction_deg = []'),
     ["material.friction_deg", "no values"]),
    (TINY.replace('"material.friction_deg" = [20.0, 30.0]', '"silo.outlet_width" = [1.0, 9.0]'),
     ["silo.outlet_width", "9", ", run outlet_width=9 m, seed 3: "]),
    # a [set] value that no run can have is put on [set], not on the first grid point; a
    # list there is one the grid should have had
    (TINY.replace('[set]\n', '[set]\n"silo.wall_height" = 1.0\n'),
     [("bad.toml, [set] (it fails with the base alone): silo.wall_height (1.0) must exceed "
       "the hopper height")]),
    (TINY.replace('[set]\n', '[set]\n"walls.friction_deg" = [20.0, 30.0]\n'),
     [("[set] (it fails with the base alone): walls.friction_deg: Input should be a valid "
       "number (got [20.0, 30.0]); a list of values to run goes in [grid], not [set] "
       "(walls.friction_deg)")]),
    # a list field's bad list gets no such hint
    (TINY.replace('[set]\n', '[set]\n"material.radius_distribution" = "discrete"\n'
                  '"material.radii" = [0.08, -0.12]\n'),
     ["[set] (it fails with the base alone): material.radii"]),
    # a list inside a grid's list is quoted, in its label too ('phiG=30 deg' looked valid)
    (TINY.replace("[20.0, 30.0]", "[20.0, [30.0]]"),
     [("run phiG=[30] deg, seed 3: material.friction_deg: Input should be a valid number (got "
      "[30.0])")]),
    (TINY.replace('"material.friction_deg" = [20.0, 30.0]', '"seed" = [1, 2]'), ["seeds"]),
    # keys that change what a run writes, not what it computes: the same simulation twice
    (TINY.replace('"material.friction_deg" = [20.0, 30.0]', '"output.png" = [true, false]'),
     ["'output.png' changes what a run writes, not what it computes", "put it in [set]"]),
    (TINY.replace('"material.friction_deg" = [20.0, 30.0]', '"checkpoint.every_steps" = [1, 2]'),
     ["'checkpoint.every_steps' changes what a run writes"]),
    (TINY.replace('"material.friction_deg" = [20.0, 30.0]', '"measure.report" = [true, false]')
     .replace('"measure.report" = false\n', ''),
     ["'measure.report' changes what a run writes"]),
    (TINY.replace('seeds = [3]\n', ''), ["missing required key 'seeds'"]),
    # pydantic's words before: "List should have at least 1 item after validation, not 0"
    (TINY.replace('seeds = [3]', 'seeds = []'), ["seeds is empty: give one or more"]),
    ('base = "paper-case2"\nseeds = [1]\n[grid]\n', ["[grid] is empty: give one or more"]),
    (TINY.replace('base = "paper-case2"', 'base = "paper-case9"'),
     ["paper-case9", "did you mean 'paper-case2'"]),
    (TINY + "[grid\n", ["malformed TOML"]),
    # 20 and 20.0 are one value (they made the same run: a message about --quick before)
    (TINY.replace("[20.0, 30.0]", "[20, 20.0]"), ["'material.friction_deg' lists 20.0 twice"]),
    # a repeat found among many values (looked up by value, not compared pairwise)
    (TINY.replace("[20.0, 30.0]", str([*range(5000), 2500.0])),
     ["'material.friction_deg' lists 2500.0 twice"]),
    # a long repeated value quoted cut short (it was echoed whole: 10,000 characters)
    (TINY.replace('"material.friction_deg" = [20.0, 30.0]',
                  f'"material.contact_model" = ["{"x" * 5000}", "{"x" * 5000}"]'),
     ["'material.contact_model' lists 'xxxxxxxx", "xxx... twice"]),
    # more runs than a study takes: refused before any is planned
    (TINY.replace('"material.friction_deg" = [20.0, 30.0]',
                  f'"material.friction_deg" = {list(range(400))}\n'
                  f'"silo.outlet_width" = {[1 + k / 1000 for k in range(300)]}'),
     ["the study has 120000 runs (1 seed x grid 400 x 300); at most 100000"]),
    (TINY.replace("[20.0, 30.0]", str(list(range(100_001)))),
     ["'material.friction_deg' lists 100001 values; a study runs at most 100000"]),
    # a key checked stripped, then set with its spaces (an 'unknown key' in the expansion)
    (TINY.replace('"material.friction_deg"', '" material.friction_deg "'),
     ["has spaces around its parts", "write 'material.friction_deg'"]),
    # a grid over base scenarios
    ('base = "paper-case2"\nseeds = [1]\n[grid]\nbase = ["paper-case1"]\n',
     ["'base' is both at the top and in [grid]"]),
    ('seeds = [1]\n[grid]\n"material.friction_deg" = [20.0]\n', ["missing required key 'base'"]),
    ('seeds = [1]\n[grid]\nbase = [3]\n', ["[grid] 'base' lists base scenarios"]),
    ('seeds = [1]\n[grid]\nbase = ["paper-case9"]\n', ["base 'paper-case9'", "paper-case2"]),
])
def test_bad_study_files_give_one_line_and_exit_2(tmp_path, capsys, text, needles):
    path = tmp_path / "bad.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(SystemExit) as exc:
        main(["sweep", str(path), "--out", str(tmp_path / "out")])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    for needle in needles:
        assert needle in err
    assert not (tmp_path / "out").exists()  # refused before anything was written


def test_grid_repeats_are_found_as_a_pairwise_comparison_finds_them():
    """``_first_repeat`` (a set lookup) against the brute-force pairwise ``_same_value`` on
    random lists of ints, floats equal to them, bools, strings and lists."""
    rng = random.Random(7)
    pool = [0, 1, 2, 0.0, 1.0, 2.5, True, False, "0", "a", [1], [1.0], [2]]
    for _ in range(2000):
        values = [rng.choice(pool) for _ in range(rng.randint(1, 6))]
        brute = next((k for k in range(len(values))
                      if any(_same_value(values[k], v) for v in values[:k])), None)
        assert _first_repeat(values) == brute, values


def test_grid_values_that_quick_makes_one_run_are_refused(tmp_path):
    """--quick keeps 0.36 of the grains, rounded (at least 50): 200 and 201 grains both become
    72, one simulation that results.csv would list under two particle counts."""
    path = tmp_path / "counts.toml"
    path.write_text('name = "counts"\nbase = "paper-case2"\nseeds = [1]\n[grid]\n'
                    '"fill.n_particles" = [200, 201]\n', encoding="utf-8")
    full = expand(load_study(str(path)))
    assert [run.cfg.fill.n_particles for run in full.runs] == [200, 201]
    with pytest.raises(InputError, match=r"n_particles=200.* and .*n_particles=201.*"
                                         r"same config once --quick has shrunk them"):
        expand(load_study(str(path)), quick=True)


def test_missing_study_and_bad_options_give_one_line_and_exit_2(tmp_path, capsys):
    for argv in (["sweep", str(tmp_path / "nope.toml")], ["sweep", "paper-stdy"],
                 ["sweep", "paper-study", "--workers", "0"]):
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err


def test_a_local_cluster_takes_at_most_four_workers_per_core(tmp_path, capsys):
    """--workers 4096 started 4096 worker processes of about 180 MB each (some 740 GB) on
    whatever machine it was given; a local cluster now takes at most 4 per core this process
    may use (os.sched_getaffinity), and refuses more before anything is written.  An external
    scheduler's count is not bounded by this machine's cores."""
    from silodem.study.cluster import check_workers

    cores = len(os.sched_getaffinity(0))
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exc:
        main(["sweep", "paper-study", "--quick", "--workers", str(4 * cores + 1), "--out",
              str(out)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert f"--workers {4 * cores + 1}: a local cluster takes at most {4 * cores} workers" in err
    assert not out.exists()
    check_workers(4 * cores, local=True)  # the bound itself is allowed
    check_workers(4096, local=False)      # e.g. --scheduler with --workers 4096
    with pytest.raises(InputError, match="from 1 to 4096"):
        check_workers(4097, local=False)


def test_paper_study_is_the_papers_grid_and_every_case_is_valid(capsys):
    """Section 5 of the paper: hopper slope 35, 45, 55, 75 deg x phi_G 20, 30 deg x phi_P 10,
    45 deg on case 2; every combination gives a valid run, full size and --quick."""
    with pytest.raises(SystemExit) as exc:
        main(["show", "paper-study"])
    assert exc.value.code == 0
    data = tomllib.loads(capsys.readouterr().out)
    assert data["base"] == "paper-case2"
    grid = data["grid"]
    assert sorted(grid["silo.hopper_angle_from_horizontal_deg"]) == [35, 45, 55, 75]
    assert sorted(grid["material.friction_deg"]) == [20, 30]
    assert sorted(grid["walls.friction_deg"]) == [10, 45]
    for quick in (False, True):
        plan = expand(load_study("paper-study"), quick=quick)
        assert len({r.id for r in plan.runs}) == 16
        points = {(r.cfg.silo.hopper_angle_from_horizontal_deg, r.cfg.material.friction_deg,
                   r.cfg.walls.friction_deg) for r in plan.runs}
        assert points == {(t, g, p) for t in (35, 45, 55, 75) for g in (20, 30) for p in (10, 45)}
        # the paper keeps the silo height and the outlet constant over the study
        assert len({(r.cfg.silo.wall_height, r.cfg.silo.outlet_width, r.cfg.silo.cell_width,
                     r.cfg.fill.n_particles) for r in plan.runs}) == 1


def test_bare_dotted_keys_mean_the_same_as_quoted_ones(tmp_path):
    quoted = _plan(tmp_path)
    bare = tmp_path / "bare.toml"
    bare.write_text(TINY.replace('"fill.n_particles"', "fill.n_particles")
                    .replace('"material.friction_deg"', "material.friction_deg"),
                    encoding="utf-8")
    plan = expand(load_study(str(bare)), quick=True)
    assert [r.id for r in plan.runs] == [r.id for r in quoted.runs]


def test_a_half_written_run_folder_is_never_taken_as_finished(serial, tmp_path):
    """A run folder without its summary (as a copy cut short would leave) is run again, and
    its files are set aside, not mixed with the new result."""
    _, ref_dir = serial
    plan = _plan(tmp_path)
    study_dir = tmp_path / "study"
    half = study_dir / "runs" / plan.runs[0].id
    half.mkdir(parents=True)
    (half / "results.h5").write_bytes(b"not a finished run")
    outcome = run_study(plan, study_dir, serial=True)
    assert outcome.computed == 2 and outcome.skipped == 0
    _assert_same_runs(plan, ref_dir, study_dir)
    aside = list((study_dir / "runs").glob(f".{plan.runs[0].id}.incomplete-*/results.h5"))
    assert len(aside) == 1 and aside[0].read_bytes() == b"not a finished run"


def test_a_failing_run_is_reported_kept_aside_and_retried(tmp_path, monkeypatch):
    """A run that stops as unstable is not retried within the sweep, is not in runs/ nor in
    the table, keeps its folder in failed/, and is run again by the next invocation."""
    from silodem.errors import UnstableRunError
    from silodem.study import execute

    plan = _plan(tmp_path)
    bad = plan.runs[1]
    real = execute._run_simulation
    calls = []

    def flaky(cfg, out):
        calls.append(cfg.material.friction_deg)
        if cfg.material.friction_deg == bad.cfg.material.friction_deg:
            raise UnstableRunError("grain 7 left the domain (test)")
        real(cfg, out)

    monkeypatch.setattr(execute, "_run_simulation", flaky)
    study_dir = tmp_path / "study"
    outcome = run_study(plan, study_dir, serial=True)
    assert list(outcome.failed) == [bad.id] and outcome.computed == 1
    assert outcome.failed[bad.id] == "unstable: grain 7 left the domain (test)"
    assert calls.count(bad.cfg.material.friction_deg) == 1
    assert _run_folders(study_dir) == [plan.runs[0].id]
    assert (study_dir / "failed" / bad.id / "attempt.json").is_file()
    rows = (study_dir / "results.csv").read_text(encoding="utf-8").splitlines()
    assert len(rows) == 2 and bad.id not in "\n".join(rows)
    assert bad.id in (study_dir / "report.html").read_text(encoding="utf-8")

    monkeypatch.setattr(execute, "_run_simulation", real)
    again = run_study(plan, study_dir, serial=True)
    assert again.computed == 1 and again.skipped == 1 and not again.failed
    assert _run_folders(study_dir) == sorted(r.id for r in plan.runs)
    assert not (study_dir / "failed" / bad.id).exists()

    # from Python, another study's file replaced comes as a SilodemWarning (the command line
    # prints the note); here the same runs under another description: nothing is re-run
    from silodem.api import SilodemWarning

    renamed = tmp_path / "renamed.toml"
    renamed.write_text('description = "the same grid"\n' + TINY, encoding="utf-8")
    with pytest.warns(SilodemWarning, match="^replacing .*study.toml, another study file's"):
        other = run_study(expand(load_study(str(renamed)), quick=True), study_dir, serial=True)
    assert other.skipped == 2 and other.computed == 0
    with warnings.catch_warnings():
        warnings.simplefilter("error", SilodemWarning)  # its own file again: no word
        run_study(expand(load_study(str(renamed)), quick=True), study_dir, serial=True)


def test_the_failed_sweeps_line_says_which_failures_a_new_attempt_repeats():
    """Runs stopped as unstable or refused (run_task's 'unstable: ', 'bad input: ') are
    deterministic: the line said 'run the command again to retry them', which repeats the
    failure. It says so for those, and offers the retry for the others (a worker's death)."""
    from silodem.study.execute import failed_runs_text

    out = Path("studies/s")
    head = ("error: 2 of 5 runs failed (first: a: unstable: grain 3 left); see "
            "studies/s/report.html; ")
    lost = {"a": "unstable: grain 3 left", "b": "KilledWorker: worker died"}
    assert failed_runs_text(lost, 5, out) == head + (
        "run the command again to retry the 1 that failed otherwise; the 1 stopped as "
        "unstable or refused will fail the same way again until its config changes (folders "
        "in studies/s/failed)")
    both = {"a": "unstable: grain 3 left", "b": "bad input: outlet narrower than a grain"}
    assert failed_runs_text(both, 5, out) == head + (
        "they will fail the same way again until their configs change (folders in "
        "studies/s/failed)")
    assert failed_runs_text({"b": "OSError: disk full"}, 5, out).endswith(
        "; run the command again to retry them")


def test_a_sweep_says_when_it_replaces_another_study_file(tmp_path, capsys, monkeypatch):
    """A study run into the folder of another replaced its study.toml without a word; its
    runs stay (reused by any study that plans them again). The same study says nothing."""
    from silodem.study.execute import other_study_note, prepare

    plan = _plan(tmp_path)
    study_dir = tmp_path / "study"
    assert other_study_note(plan, study_dir) is None  # no folder yet
    prepare(plan, study_dir)
    assert other_study_note(plan, study_dir) is None
    edited = tmp_path / "edited.toml"
    edited.write_text(TINY.replace("[20.0, 30.0]", "[20.0, 30.0, 40.0]"), encoding="utf-8")
    note = other_study_note(expand(load_study(str(edited)), quick=True), study_dir)
    assert note == (f"silodem: replacing {study_dir / 'study.toml'}, another study file's "
                    f"text; the finished runs in {study_dir / 'runs'} are kept (a study that "
                    "plans one again reuses it), and results.csv and report.html become this "
                    "study's")
    # the command line says it once the file is replaced: a scheduler that cannot be reached
    # leaves the file as it was, and its error is the one line on stderr
    from test_input_errors import refused

    from silodem.study import cluster as study_cluster
    from silodem.study.execute import replaced_study_file

    monkeypatch.setattr(study_cluster, "CONNECT_TIMEOUT_S", 2.0)
    old = (study_dir / "study.toml").read_text(encoding="utf-8")
    line = refused(capsys, "sweep", str(edited), "--quick", "--out", str(study_dir),
                   "--scheduler", "tcp://127.0.0.1:1")
    assert line.startswith("error: cannot reach the Dask scheduler at tcp://127.0.0.1:1")
    assert (study_dir / "study.toml").read_text(encoding="utf-8") == old
    assert not replaced_study_file(expand(load_study(str(edited)), quick=True), study_dir)


@pytest.fixture
def stand_in_cluster(capsys, monkeypatch):
    """A sweep's cluster and runs stood in for: its first hand-out of runs records what
    stderr held by then (``seen["err"]``) and computes nothing."""
    from silodem.study import api as study_api
    from silodem.study.execute import StudyOutcome

    seen = {}

    def first_run(plan, out_dir, client, on_done, say):
        seen["err"] = capsys.readouterr().err
        return StudyOutcome(plan, out_dir)

    monkeypatch.setattr(study_api, "connect", lambda *args: (object(), None, "here"))
    monkeypatch.setattr(study_api, "close_cluster", lambda *args, **kwargs: None)
    monkeypatch.setattr(study_api, "run_on_client", first_run)
    return seen


def test_the_sweep_says_it_replaced_the_study_file_before_any_run(tmp_path, capsys,
                                                                   stand_in_cluster):
    """The note came in a `finally` at the end of the sweep, hours after the file was
    replaced; it is now on stderr by the time the first run is handed out. The cluster and
    the runs are stood in for: this checks when the line is said, not the runs."""
    from silodem.cli import main
    from silodem.study.execute import prepare

    plan = _plan(tmp_path)
    study_dir = tmp_path / "study"
    prepare(plan, study_dir)
    edited = tmp_path / "edited.toml"
    edited.write_text(TINY.replace("[20.0, 30.0]", "[20.0, 30.0, 40.0]"), encoding="utf-8")
    seen = stand_in_cluster
    with pytest.raises(SystemExit) as stop:
        main(["sweep", str(edited), "--quick", "--out", str(study_dir), "--workers", "1"])
    assert stop.value.code == 0
    note = f"silodem: replacing {study_dir / 'study.toml'}, another study file's text"
    assert [line for line in seen["err"].splitlines() if line.startswith(note)], seen["err"]
    assert note not in capsys.readouterr().err  # said once


def test_a_resumed_sweep_says_which_finished_runs_other_code_computed(tmp_path,
                                                                      stand_in_cluster):
    """A study resumed after an update tabled runs of two engines side by side without a
    word (__version__ stays 0.1.0; they differed in signed zeros): results.h5 records a
    digest of the code's files, and a sweep names the finished runs whose digest is not its
    own. A run that recorded none (written before the digest) is not judged."""
    import h5py

    from silodem.cli import main
    from silodem.provenance import source_digest
    from silodem.study import api as study_api
    from silodem.study.execute import prepare

    plan = _plan(tmp_path)
    study_dir = tmp_path / "study"
    prepare(plan, study_dir)
    for run, digest in zip(plan.runs, ("0123456789abcdef", None)):
        folder = study_dir / "runs" / run.id
        folder.mkdir(parents=True)
        with h5py.File(folder / "results.h5", "w") as h5:
            if digest is not None:
                h5.attrs["silodem_source"] = digest
        (folder / "summary.json").write_text("{}", encoding="utf-8")
    ours = source_digest()
    assert len(ours) == 16 and ours != "0123456789abcdef"
    note = (f"1 of the 2 finished runs in {study_dir / 'runs'} were computed by other silodem "
            f"code (source 0123456789abcdef, this is {ours}; first: {plan.runs[0].id})")
    assert study_api.other_code_note(plan, study_dir).startswith(note)
    with h5py.File(study_dir / "runs" / plan.runs[0].id / "results.h5", "a") as h5:
        h5.attrs["silodem_source"] = ours
    assert study_api.other_code_note(plan, study_dir) is None  # this code's, and unrecorded
    with h5py.File(study_dir / "runs" / plan.runs[0].id / "results.h5", "a") as h5:
        h5.attrs["silodem_source_started"] = "aaaaaaaaaaaaaaaa"  # resumed by this code
    assert "(source aaaaaaaaaaaaaaaa, this is" in study_api.other_code_note(plan, study_dir)
    with h5py.File(study_dir / "runs" / plan.runs[0].id / "results.h5", "a") as h5:
        del h5.attrs["silodem_source_started"]
    with h5py.File(study_dir / "runs" / plan.runs[1].id / "results.h5", "a") as h5:
        h5.attrs["silodem_source"] = "fedcba9876543210"
    seen = stand_in_cluster
    (study_dir / "runs" / plan.runs[0].id / "summary.json").unlink()  # one run still to do
    with pytest.raises(SystemExit):
        main(["sweep", str(tmp_path / "tiny.toml"), "--quick", "--out", str(study_dir)])
    assert (f"silodem: warning: 1 of the 1 finished runs in {study_dir / 'runs'} were "
            f"computed by other silodem code (source fedcba9876543210, this is {ours}; first: "
            f"{plan.runs[1].id}): they are kept") in seen["err"], seen["err"]


def test_the_source_digest_follows_the_computing_files_only(tmp_path, monkeypatch):
    """SHA-256 over the files that compute a run (paths and bytes, sorted): a copy of the
    package (new modification times, no bytecode caches), CRLF line ends, an editor's
    hidden lock file (a broken link, which made the digest raise) and an edit of the report
    give the same digest; one more byte in the contact law gives another."""
    import shutil

    from silodem import provenance

    copy_dir = tmp_path / "silodem"
    shutil.copytree(provenance.PACKAGE, copy_dir,
                    ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(provenance, "PACKAGE", copy_dir)
    provenance.source_digest.cache_clear()

    def digest_after(edit) -> str:
        edit()
        provenance.source_digest.cache_clear()
        return provenance.source_digest()

    def append(name: str, text: str):
        path = copy_dir / name
        return lambda: path.write_bytes(path.read_bytes() + text.encode())

    try:
        same = provenance.source_digest()
        law = copy_dir / "engine" / "contact.py"
        crlf = lambda: law.write_bytes(law.read_bytes().replace(b"\n", b"\r\n"))
        assert digest_after(crlf) == same
        assert digest_after(lambda: (copy_dir / "engine" / ".#contact.py").symlink_to(
            copy_dir / "gone")) == same
        assert digest_after(append("report/html.py", "\n# a comment\n")) == same
        assert digest_after(append("engine/contact.py", "\n")) != same
    finally:
        monkeypatch.undo()
        provenance.source_digest.cache_clear()
    assert same == provenance.source_digest()


def test_each_finished_run_line_says_how_far_the_study_is(tmp_path, capsys, monkeypatch):
    """A sweep's log (stderr to a file: no bar drawn) said which run finished, not how many
    of how many nor how long the rest would take. The time left is the mean time between
    finished runs times the runs to come: 1 of 5 after 20 s -> 4 x 20 s = 80 s; 2 of 5 after
    120 s -> 3 x 60 s = 3 min."""
    from silodem.study import api as study_api

    plan = _plan(tmp_path)
    clock = iter([0.0, 20.0, 120.0])
    monkeypatch.setattr(study_api, "_clock", lambda: next(clock))
    result = {"status": "computed", "wall_s": 9.5, "host": "h", "pid": 7}
    with study_api._progress_bar(5, True) as done:
        for run in plan.runs[:2]:
            done(run, result)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if "computed" in line]
    assert lines[0].startswith(f"computed {plan.runs[0].id} (9.5 s on h:7; 1/5, about 80 s "
                               "left)")
    assert lines[1].startswith(f"computed {plan.runs[1].id} (9.5 s on h:7; 2/5, about 3 min "
                               "left)")
    # (the bar's last state is not written to a log: 'runs ━━━━ 16/16 0:01:05 left 0:00:00')
    assert "\u2501" not in err
    assert study_api._time_left(100000.0, 5, 5) == "all done"
    assert study_api._time_left(3600.0, 1, 3) == "about 2.0 h left"
    # with 4 runs under way at once, the first finishes when all 4 nearly have: after 100 s,
    # 1 of 12 done would say 11 x 100 s; it waits for 4 (400 s / 4 x 8 = 800 s = 13 min)
    assert study_api._time_left(100.0, 1, 12, 4) == "time left said once 4 runs have finished"
    assert study_api._time_left(400.0, 4, 12, 4) == "about 13 min left"


def test_a_log_gets_a_line_while_no_run_finishes(tmp_path, capsys, monkeypatch):
    """A sweep's log (stderr to a file: no bar drawn) said nothing between finished runs: a
    study of hour-long runs looked hung.  A line comes each HEARTBEAT_S without one (here
    0.05 s, 0.5 s without a run: several lines), and a finished run's line starts the wait
    again; none after the sweep has ended."""
    from silodem.study import api as study_api

    plan = _plan(tmp_path)
    monkeypatch.setattr(study_api, "HEARTBEAT_S", 0.05)
    result = {"status": "computed", "wall_s": 9.5, "host": "h", "pid": 7}
    with study_api._progress_bar(3, True) as done:
        t0 = time.monotonic()
        time.sleep(0.5)
        waited = time.monotonic() - t0
        done(plan.runs[0], result)
        time.sleep(0.5)
    assert not any(t.name == "silodem-heartbeat" for t in threading.enumerate())
    lines = capsys.readouterr().err.splitlines()
    first = lines.index(next(line for line in lines if line.startswith("computed")))
    before, after = lines[:first], lines[first + 1:]
    beats = [line for line in before if line.startswith("still running: 0/3 runs finished")]
    assert 3 <= len(beats) <= waited / 0.05 + 1, lines  # not more often than each 0.05 s
    assert all(line.endswith("the others are under way or waiting for a worker")
               for line in beats)
    assert 3 <= sum(line.startswith("still running: 1/3 runs finished") for line in after)


def test_run_ids_of_configs_planned_before_the_hertz_law_are_unchanged():
    """The Hertz-Mindlin law added keys to the schema (``plan.LATER_KEYS``); a study planned
    before keeps its run ids, so that its finished runs are found and not run again.  The
    hashes are those the commit before the law (4e5e4d3) gave."""
    from silodem.config import Config
    from silodem.scenario_files import load_config
    from silodem.study.plan import config_hash

    assert config_hash(load_config("paper-case1")) == "3460381cd7"
    assert config_hash(load_config("paper-case2")) == "e62e6c9ea6"
    hertz = load_config("paper-case2").model_dump()
    for section in ("material", "walls"):
        hertz[section].update(kn=None, ks=None, young_modulus=1e9, poisson_ratio=0.3)
    hertz["material"]["contact_model"] = "hertz_mindlin"
    assert config_hash(Config.model_validate(hertz)) != "e62e6c9ea6"
    # measure.angle_of_repose_deg (EN 1991-4 §5.3 in the report) came later still: unset, it
    # leaves the id alone; set, it makes another run
    repose = load_config("paper-case2").model_dump()
    repose["measure"]["angle_of_repose_deg"] = 30.0
    assert config_hash(Config.model_validate(repose)) != "e62e6c9ea6"


def test_a_grid_over_base_scenarios_compares_the_two_contact_laws(tmp_path):
    """[grid] base = [...] runs each grid point from its own base scenario: here the paper's
    linear case and a Hertz-Mindlin file, which differ in keys a value grid could not switch
    (the other law's keys are refused).  Each run has its base's law, the table names the base
    of each row, and a run's config is the one its base file gives."""
    from reliability_helpers import hertz_config

    from silodem.scenario_files import config_to_toml, quick_variant

    (tmp_path / "hertz.toml").write_text(config_to_toml(hertz_config()), encoding="utf-8")
    study = tmp_path / "laws.toml"
    study.write_text('seeds = [3]\n[set]\n"fill.n_particles" = 60\n"discharge.max_time" = 1.0\n'
                     '"measure.report" = false\n"output.png" = false\n'
                     '[grid]\nbase = ["paper-case2", "hertz.toml"]\n', encoding="utf-8")
    plan = expand(load_study(str(study)), quick=True)
    laws = {run.point["base"]: run.cfg.material.contact_model for run in plan.runs}
    assert laws == {"paper-case2": "linear", "hertz.toml": "hertz_mindlin"}
    hertz_run = next(r for r in plan.runs if r.point["base"] == "hertz.toml")
    expected = quick_variant(hertz_config().model_copy(update={"seed": 3}))
    assert hertz_run.cfg.material == expected.material and hertz_run.cfg.walls == expected.walls
    outcome = run_study(plan, tmp_path / "out", serial=True)
    assert outcome.computed == 2 and not outcome.failed
    with open(outcome.table_path, encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert sorted(r["base"] for r in rows) == ["hertz.toml", "paper-case2"]


def test_a_scheduler_lost_mid_study_names_the_cause_and_a_second_invocation_completes(
        serial, tmp_path):
    """kill -9 the external scheduler while a run goes: Dask cancels every future, and each
    run was reported failed with 'NoneType: None' (a cancelled future has no exception()).
    The error now says the connection to the scheduler was lost; the same study on a new
    scheduler then finishes what is missing, equal to the serial reference."""
    import subprocess
    import sys

    from reliability_helpers import env

    _, ref_dir = serial
    plan = _plan(tmp_path)
    study_dir = tmp_path / "study"
    runs = study_dir / "runs"
    procs = []

    def cluster(name: str) -> str:
        sched_file = tmp_path / f"{name}.json"
        for module, args in (("dask_scheduler", ["--host", "127.0.0.1", "--port", "0"]),
                             ("dask_worker", ["--nthreads", "1", "--nworkers", "1"])):
            procs.append(subprocess.Popen(
                [sys.executable, "-m", f"distributed.cli.{module}", *args,
                 "--scheduler-file", str(sched_file), "--dashboard-address", ":0"],
                env=env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
            deadline = time.monotonic() + 60
            while not sched_file.is_file():
                assert time.monotonic() < deadline, "no scheduler"
                time.sleep(0.1)
        return json.loads(sched_file.read_text(encoding="utf-8"))["address"]

    try:
        address = cluster("first")
        result: dict = {}
        thread = threading.Thread(target=lambda: result.update(
            outcome=run_study(plan, study_dir, scheduler=address, report=False)))
        thread.start()
        deadline = time.monotonic() + 120
        while not (runs.is_dir() and any(runs.glob(".*.tmp-*/attempt.json"))):
            assert time.monotonic() < deadline, "no run started"
            time.sleep(0.01)
        procs[0].kill()
        thread.join(timeout=120)
        assert not thread.is_alive()
        outcome = result["outcome"]
        assert outcome.failed
        for error in outcome.failed.values():
            assert "NoneType" not in error and "lost the connection to the scheduler" in error
        procs[1].kill()
        again = run_study(plan, study_dir, scheduler=cluster("second"))
    finally:
        for proc in procs:
            proc.kill()
            proc.wait()
    assert not again.failed and again.computed + again.skipped == len(plan.runs)
    _assert_same_runs(plan, ref_dir, study_dir)


def test_ctrl_c_while_waiting_for_workers_closes_the_client(monkeypatch):
    """Ctrl-C while `--workers N` waited for an external scheduler's workers left the client
    connected (and the default client of the process): closed only by distributed's atexit
    hook, where a second Ctrl-C printed a traceback."""
    import distributed

    from silodem.study import cluster as study_cluster

    closed = []

    class FakeClient:
        def __init__(self, address, timeout=None):
            self.address = address

        def scheduler_info(self):
            return {"workers": {}}

        def wait_for_workers(self, n_workers, timeout):
            raise KeyboardInterrupt

        def close(self):
            closed.append(self.address)

    monkeypatch.setattr(study_cluster, "_probe", lambda address: None)
    monkeypatch.setattr(distributed, "Client", FakeClient)
    with pytest.raises(KeyboardInterrupt):
        study_cluster.connect("tcp://127.0.0.1:1", 3)
    assert closed == ["tcp://127.0.0.1:1"]


def test_runs_finished_by_another_attempt_meanwhile_are_counted(serial, tmp_path, monkeypatch):
    """A task that finds its run finished after the sweep planned it (another sweep, or the
    attempt of a sweep stopped with Ctrl-C that its worker still finished) returns 'existing':
    it was counted nowhere, and a re-run after Ctrl-C said '0 computed, 0 already finished,
    0 failed' for a complete study of two runs."""

    from silodem.study import execute

    _, ref_dir = serial
    plan = _plan(tmp_path)
    study_dir = tmp_path / "study"
    shutil.copytree(ref_dir / "runs", study_dir / "runs")
    real_prepare = execute.prepare
    monkeypatch.setattr(execute, "prepare",  # planned before the other attempt finished
                        lambda p, out: (real_prepare(p, out), list(p.runs))[1])
    outcome = execute.run_serial(plan, study_dir)
    assert {r["status"] for r in outcome.results.values()} == {"existing"}
    assert outcome.computed == 0 and outcome.skipped == 2 and not outcome.failed


def test_a_spell_without_workers_is_said_once_and_its_end_too():
    """NoWorkersWatch, on a made-up clock: nothing before NO_WORKERS_WARN_S of no worker,
    one line when it has passed, one when workers are back, and a new spell starts over."""
    from silodem.study.cluster import NoWorkersWatch

    said: list[str] = []
    watch = NoWorkersWatch("tcp://10.0.0.1:8786", said.append, after_s=60.0)
    for workers, now in ((2, 0.0), (0, 10.0), (0, 40.0), (0, 69.0)):
        watch.check(workers, now)
    assert said == []  # 59 s without a worker
    watch.check(0, 71.0)
    watch.check(0, 500.0)
    first = ("no worker at the Dask scheduler tcp://10.0.0.1:8786 for 61 s: the sweep waits "
             "for one (start workers with 'dask worker tcp://10.0.0.1:8786 --nthreads 1'; "
             "Ctrl-C stops the sweep, and its finished runs are kept)")
    assert said == [first]
    watch.check(3, 510.0)
    assert said[1:] == ["3 worker(s) at tcp://10.0.0.1:8786 again: the sweep goes on"]
    watch.check(0, 600.0)
    watch.check(0, 659.0)
    assert len(said) == 2
    watch.check(0, 660.0)
    assert said[2:] == [first.replace(" for 61 s", " for 60 s")]


def test_a_sweep_on_a_scheduler_without_workers_says_so_and_finishes_when_one_joins(
        serial, tmp_path, monkeypatch):
    """A scheduler whose workers are all gone: the sweep waited in silence.  It now says so
    after NO_WORKERS_WARN_S (shortened here), and when a worker joins it says that too and
    finishes every run, equal to the serial reference."""
    from distributed import Client, LocalCluster

    from silodem.study import cluster as study_cluster
    from silodem.study import execute
    from silodem.study.api import finish_study

    monkeypatch.setattr(study_cluster, "NO_WORKERS_WARN_S", 0.5)
    monkeypatch.setattr(study_cluster, "WATCH_INTERVAL_S", 0.1)
    _, ref_dir = serial
    plan = _plan(tmp_path)
    study_dir = tmp_path / "study"
    said: list[str] = []
    result: dict = {}
    cluster = LocalCluster(n_workers=0, threads_per_worker=1, processes=True,
                           dashboard_address=":0")
    client = Client(cluster)
    try:
        address = client.scheduler.address
        thread = threading.Thread(target=lambda: result.update(outcome=execute.run_on_client(
            plan, study_dir, client, say=said.append)))
        thread.start()
        deadline = time.monotonic() + 30
        while not said:
            assert time.monotonic() < deadline, "nothing said"
            time.sleep(0.05)
        assert said[0].startswith(f"no worker at the Dask scheduler {address} for ")
        cluster.scale(1)
        thread.join(timeout=300)
        assert not thread.is_alive()
    finally:
        client.close()
        cluster.close()
    assert said[1:] == [f"1 worker(s) at {address} again: the sweep goes on"]
    outcome = result["outcome"]
    assert outcome.computed == len(plan.runs) and not outcome.failed
    finish_study(plan, study_dir, outcome, report=False)  # results.csv, as run_study
    _assert_same_runs(plan, ref_dir, study_dir)


@pytest.mark.parametrize("status, error", [
    ("finished", ("its result was lost with the connection to the scheduler "
                 "(ConnectionResetError: [Errno 104] Connection reset by peer)")),
    ("cancelled", "CancelledError: cancelled for reason: scheduler-connection-lost"),
])
def test_a_run_whose_result_is_lost_with_the_scheduler_is_read_from_its_folder(
        serial, tmp_path, monkeypatch, status, error):
    """The scheduler killed just after a task finished: fetching its result raised
    ConnectionResetError out of the sweep ('error: in <TCP (closed) ConnectionPool.gather
    ...>', exit 2, no results.csv; seen with the command line).  A lost scheduler also
    cancels the futures of runs that their worker then finishes.  Either way a run whose
    folder is finished is now counted from it, with the summary its task wrote; one that
    is not is a failure naming the cause, run again by the next invocation."""
    from concurrent.futures import CancelledError

    import distributed

    from silodem.study import execute

    plan = _plan(tmp_path)
    _, ref_dir = serial
    study_dir = tmp_path / "study"
    done, lost = plan.runs
    shutil.copytree(ref_dir / "runs" / done.id, study_dir / "runs" / done.id)

    class LostFuture:
        def __init__(self, key):
            self.key, self.status = key, status

        def result(self):
            if status == "finished":
                raise ConnectionResetError(104, "Connection reset by peer")
            raise CancelledError("cancelled for reason: scheduler-connection-lost")

    futures = [LostFuture(f"silodem-{r.id}") for r in plan.runs]
    monkeypatch.setattr(distributed, "as_completed", iter)
    outcome = execute.StudyOutcome(plan, study_dir)
    execute._gather(futures, {f.key: r for f, r in zip(futures, plan.runs)}, outcome, None)
    summary = json.loads((ref_dir / "runs" / done.id / "summary.json").read_text())
    del summary[execute.VERSION_KEY]  # (which analysis made it: not a result)
    assert outcome.results[done.id]["status"] == "computed" and outcome.computed == 1
    assert outcome.results[done.id]["summary"] == summary
    assert outcome.results[done.id]["wall_s"] >= 0.0
    assert outcome.failed == {lost.id: error}


def test_a_summary_made_by_another_analysis_version_is_made_again(serial, tmp_path):
    """A finished run's summary.json from an older analysis (say, before the switch zone was
    kept in the hopper's upper half) is not taken as it is: the run is summarised again from
    its results.h5, to the numbers a fresh run gets, and the new summary saved."""
    from silodem.study.execute import VERSION_KEY, read_summary

    plan, study_dir = serial
    run_dir = tmp_path / "run"
    shutil.copytree(study_dir / "runs" / plan.runs[0].id, run_dir)
    fresh = json.loads((run_dir / "summary.json").read_text())
    stale = {**fresh, VERSION_KEY: fresh[VERSION_KEY] - 1, "wall_peak_fill": -1.0}
    (run_dir / "summary.json").write_text(json.dumps(stale))
    again = read_summary(run_dir)
    same = lambda a, b: json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)  # NaN
    assert same(again, {k: v for k, v in fresh.items() if k != VERSION_KEY})
    assert same(json.loads((run_dir / "summary.json").read_text()), fresh)  # saved in place
    # the same version: read as it is, even a number no analysis would give
    (run_dir / "summary.json").write_text(json.dumps({**fresh, "wall_peak_fill": -1.0}))
    assert read_summary(run_dir)["wall_peak_fill"] == -1.0


def test_a_quick_study_report_says_which_silo_ran(serial):
    """The study table listed 'set silo.wall_height 8.5' and 'set fill.n_particles 480' while
    --quick ran walls of 0.6 x 8.5 = 5.1 m, round(0.36 x 480) = 173 grains and a cell 0.6 x
    3.4 = 2.04 m wide (docs/scenarios.md, --quick): the report now names what ran."""
    from silodem.study.report import _quick_silo

    text = _quick_silo(expand(load_study("paper-study"), quick=True))
    assert text.startswith("yes: cell width B = 2.04 m, wall height 5.1 m, outlet D = 1 m, "
                           "173 grains")
    # and what such a silo is for (the tiny study here is a --quick one)
    import html

    from silodem.report.html import quick_caveat

    assert serial[0].quick
    report = (serial[1] / "report.html").read_text(encoding="utf-8")
    assert html.escape(quick_caveat(hopper=True)) in report  # (paper-case2's hopper)


def test_signals_while_the_local_cluster_starts_are_held_not_lost():
    """While the LocalCluster starts, SIGINT was ignored (SIG_IGN): a Ctrl-C in that second
    was lost and the whole study ran on; a SIGTERM there ended in distributed's tracebacks.
    ``noted_signals(hold=True)`` notes both and raises them again after the block, under the
    handlers they had before: nothing is raised inside, KeyboardInterrupt after, and SIGTERM reaches
    its previous handler once."""
    from silodem.signals import noted_signals

    reached: list[int] = []
    before = signal.signal(signal.SIGTERM, lambda signum, frame: reached.append(signum))
    try:
        inside = False
        with pytest.raises(KeyboardInterrupt), noted_signals(hold=True):
            os.kill(os.getpid(), signal.SIGINT)
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(0.05)  # the handlers run between bytecodes: let them
            inside = True
        assert inside and reached == [signal.SIGTERM]
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        signal.signal(signal.SIGTERM, before)


def test_signals_while_a_sweep_shuts_down_wait_for_the_shutdown():
    """A second Ctrl-C while a stopped sweep closed its cluster broke the close off midway.
    ``shutdown_shield`` notes it and lets the close go on; the one after acts at once.  A
    sweep being stopped drops the signals noted (the first one gives the exit code); an
    ordinary close raises the first one again after the block, so that it still stops the
    command."""
    from silodem.study.cluster import shutdown_shield

    def kill(sig: int = signal.SIGINT) -> None:
        os.kill(os.getpid(), sig)
        time.sleep(0.05)  # the handlers run between bytecodes: let them

    with shutdown_shield(stopping=True) as noted:
        kill()
        closed = True
    assert closed and noted == [signal.SIGINT]  # noted and dropped
    with pytest.raises(KeyboardInterrupt), shutdown_shield(stopping=True):
        kill()
        kill()  # the third of the stop: at once
        raise AssertionError("not reached")
    closed = False
    with pytest.raises(KeyboardInterrupt), shutdown_shield(stopping=False):
        kill()
        closed = True
    assert closed  # raised after the block, not inside
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_the_line_of_a_stopped_sweep_counts_the_finished_runs(serial, tmp_path):
    """The one line of a stopped sweep counts the runs finished on disk; a run cut off
    mid-way (its temporary folder, or a folder without summary.json) is not finished."""
    from silodem.study.execute import stopped_sweep_text

    plan, ref_dir = serial
    study_dir = tmp_path / "study"
    runs = study_dir / "runs"
    a, b = (r.id for r in plan.runs)
    assert stopped_sweep_text(plan, study_dir, signal.SIGINT) == (
        "none of the 2 runs is finished yet; repeat the command to run them")
    shutil.copytree(ref_dir / "runs" / a, runs / a)
    shutil.copytree(ref_dir / "runs" / b, runs / f".{b}.tmp-0123456789ab")  # mid-way
    assert stopped_sweep_text(plan, study_dir, signal.SIGINT) == (
        f"1 of 2 runs is finished and kept in {runs}; repeat the command to run the other one")
    shutil.copytree(ref_dir / "runs" / b, runs / b)
    (runs / b / "summary.json").unlink()  # not finished
    assert stopped_sweep_text(plan, study_dir, signal.SIGTERM).startswith("SIGTERM: 1 of 2 ")
    shutil.copy(ref_dir / "runs" / b / "summary.json", runs / b)
    assert stopped_sweep_text(plan, study_dir, signal.SIGINT) == (
        f"all 2 runs are finished and kept in {runs}; repeat the command to write "
        f"{study_dir / 'results.csv'} and the report")


def test_a_damaged_summary_is_made_again_and_a_damaged_run_is_named(serial, tmp_path, capsys):
    """summary.json is derived from results.h5 alone: a damaged one (not JSON, or JSON but not
    an object) ended the sweep in a traceback; it is now summarised again from results.h5, to
    the same bytes.  A damaged results.h5 ended the report in a one-line h5py error that named
    no file; the run now keeps its row with the documented summary_error, the report is
    written, and the command warns with the run and its file, exit 0."""
    plan, ref_dir = serial
    study_dir = tmp_path / "study"
    shutil.copytree(ref_dir, study_dir)
    first, second = (study_dir / "runs" / r.id for r in plan.runs)
    good = (first / "summary.json").read_bytes()
    (tmp_path / "tiny.toml").write_text(TINY, encoding="utf-8")
    sweep = ["sweep", str(tmp_path / "tiny.toml"), "--quick", "--out", str(study_dir)]
    for damage in ("{bad", "[1, 2]", ""):
        (first / "summary.json").write_text(damage, encoding="utf-8")
        with pytest.raises(SystemExit) as exc:
            main(sweep)
        assert exc.value.code == 0
        assert (first / "summary.json").read_bytes() == good
    capsys.readouterr()
    (second / "results.h5").write_bytes(b"junk")
    (second / "summary.json").write_text("{bad", encoding="utf-8")
    with pytest.raises(SystemExit) as exc:
        main(sweep)
    assert exc.value.code == 0
    warning = capsys.readouterr().out.splitlines()[-1]
    assert warning.startswith("warning: 1 finished run(s) could not be summarised")
    assert second.name in warning and str(second / "results.h5") in warning
    rows = list(csv.DictReader((study_dir / "results.csv").open(encoding="utf-8")))
    assert [bool(r["summary_error"]) for r in rows] == [False, True]
    assert (study_dir / "report.html").is_file()


def test_the_sweep_warns_of_a_report_figure_left_out(serial, tmp_path, capsys, monkeypatch):
    """A figure that could not be drawn is left out of report.html; the command says so in
    a warning line naming it and its error, and ends with 0 (every run finished)."""
    import silodem.study.report as study_report

    def broken(*args, **kwargs):
        raise ValueError("no numbers")

    monkeypatch.setattr(study_report, "fig_change", broken)
    _, ref_dir = serial
    study_dir = tmp_path / "study"
    shutil.copytree(ref_dir, study_dir)
    (tmp_path / "tiny.toml").write_text(TINY, encoding="utf-8")
    with pytest.raises(SystemExit) as exc:
        main(["sweep", str(tmp_path / "tiny.toml"), "--quick", "--out", str(study_dir)])
    assert exc.value.code == 0
    assert capsys.readouterr().out.splitlines()[-1] == (
        "warning: 1 figure(s) of the report could not be drawn and are left out (first: "
        "fig8_change: ValueError: no numbers)")


def test_a_scheduler_that_cannot_be_reached_makes_no_study_folder(tmp_path, capsys):
    """The study folder (study.toml, runs/) was made before the scheduler was tried: a refused
    command left it behind.  Now the connection comes first."""
    (tmp_path / "tiny.toml").write_text(TINY, encoding="utf-8")
    out = tmp_path / "study"
    with pytest.raises(SystemExit) as exc:
        main(["sweep", str(tmp_path / "tiny.toml"), "--quick", "--scheduler", "garbage",
              "--out", str(out)])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: cannot reach the Dask scheduler")
    assert not out.exists()


def test_a_sweep_into_a_folder_that_is_not_a_studys_is_refused(tmp_path, capsys):
    """`sweep --out` into a single run's folder replaced its report.html and put the study's
    figures among the run's (an audit). A folder holding what a study writes (report.html,
    results.csv, figures/) without a study.toml is refused in one line, exit code 2, and
    left as it was; an empty folder, or a study's own, is taken."""
    run = tmp_path / "a-run"
    (run / "figures").mkdir(parents=True)
    (run / "report.html").write_text("the run's report")
    (run / "config.toml").write_text("# the run's\n")
    with pytest.raises(SystemExit) as exc:
        main(["sweep", "paper-study", "--quick", "--out", str(run)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"error: --out {run} holds report.html (+2 more), which a study")
    assert sorted(p.name for p in run.iterdir()) == ["config.toml", "figures", "report.html"]
    assert (run / "report.html").read_text() == "the run's report"
    from silodem.study.execute import check_study_folder

    check_study_folder(tmp_path / "empty")  # (missing: made later)
    quiet = tmp_path / "quiet-run"  # a run that drew nothing: its results.h5 alone
    quiet.mkdir()
    (quiet / "results.h5").write_bytes(b"a run's")
    with pytest.raises(InputError, match="holds results.h5, which a study there"):
        check_study_folder(quiet)
    (run / "study.toml").write_text("# a study's folder\n")
    check_study_folder(run)
