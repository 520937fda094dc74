"""`silodem bench`: the benchmark silo matches the reference deck, and the command's JSON."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest
from reliability_helpers import benchmark_module

from silodem.bench import deck_lattice, deck_path, lattice_size


def test_lattice_matches_the_reference_deck():
    """The issue quotes N = 31,700 for the deck at NX = 100, NY = 200."""
    x, _y, width, top = deck_lattice(100, 200)
    assert x.size == 31_700
    assert width == pytest.approx(22.0) and top == pytest.approx(70.4)
    assert lattice_size(31_700) == (100, 200)
    deck = deck_path().read_text()
    assert "gran/hooke/history 5.0e6 5.0e6" in deck and "timestep        2.0e-4" in deck


def _bench(*args):
    proc = subprocess.run([sys.executable, "-m", "silodem", "bench", *args], check=False,
                          capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def test_bench_json_reports_the_deck_lattice_and_its_throughput():
    """The issue's smoke test: at tiny N, the JSON holds the deck's grains (its lattice at the
    NX, NY chosen for N), the steps asked for, and throughput = N x steps / seconds."""
    out = _bench("--n", "400", "--steps", "40", "--settle", "60", "--json")
    nx, ny = lattice_size(400)
    assert out["n"] == deck_lattice(nx, ny)[0].size
    assert (out["nx"], out["ny"]) == (nx, ny)
    assert out["threads"] == 1 and out["steps"] == 40
    assert out["particle_steps_per_s"] == pytest.approx(
        out["n"] * out["steps"] / out["seconds"], rel=1e-9)
    assert out["peak_memory_bytes"] > 0
    assert 0 <= out["list_builds"] <= out["steps"]  # at most one build per step
    assert 0 <= out["build_seconds"] <= out["seconds"]  # a part of the timed steps
    # the machine the figures belong to: the CPUs this process may use, as the OS says
    assert out["machine"]["cpus"] == len(os.sched_getaffinity(0))
    assert isinstance(out["machine"]["cpu"], str) and out["machine"]["cpu"]


def test_bench_says_each_stage_on_stderr_and_keeps_stdout_for_the_json():
    """A bench of 2e5 grains printed nothing for its minute of settling (an audit): each
    stage is now said on stderr as it begins, with the grains and steps, while stdout holds
    the JSON alone."""
    proc = subprocess.run([sys.executable, "-m", "silodem", "bench", "--n", "400", "--steps",
                           "40", "--settle", "60", "--json"], check=False, capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    nx, ny = lattice_size(400)
    said = [line for line in proc.stderr.splitlines() if line.startswith("silodem bench: ")]
    assert said == [  # (in this order; anything else on stderr, a library's warning, aside)
        f"silodem bench: building the silo ({nx} x {ny} lattice)...",
        f"silodem bench: {out['n']} grains: 60 untimed steps (the kernels compile here)...",
        "silodem bench: 40 timed steps..."]


def test_bench_rows_widens_the_deck_silo_to_n_grains():
    """--rows NY keeps the deck's column height and widens the silo: the deck's fill region
    0.2 <= y <= 0.352 NY - 0.4 holds the lattice rows y = 0.22 (k + 1/2), 29 of them at
    NY = 20, so NX columns hold 29 NX grains, NX the nearest to N / 29."""
    out = _bench("--n", "2000", "--rows", "20", "--steps", "20", "--settle", "30", "--json")
    per_column = sum(1 for k in range(100) if 0.2 <= 0.22 * (k + 0.5) <= 0.352 * 20 - 0.4)
    assert per_column == 29
    assert (out["nx"], out["ny"]) == (round(2000 / 29), 20)
    assert out["n"] == out["nx"] * per_column


def test_bench_refuses_rows_that_leave_no_silo(capsys):
    from silodem.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["bench", "--n", "2000", "--rows", "600"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--rows must be from 4 to --n / 4 = 500" in err


def test_bench_text_keeps_one_record_per_line_when_piped():
    """Piped (not a terminal), rich wrapped its lines at 80 columns: the result row was split
    after its throughput's number.  Each figure's row is one line, with its unit."""
    proc = subprocess.run([sys.executable, "-m", "silodem", "bench", "--n", "400", "--steps",
                           "40", "--settle", "60"], check=False, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr
    rows = [line for line in proc.stdout.splitlines() if line.startswith("silodem  n =")]
    assert len(rows) == 1 and "M particle-steps/s" in rows[0] and rows[0].endswith("builds")
    # the whole process's peak, not divided by n as "bytes per grain" (400 grains: ~580 KB
    # each, and 7.7 KB at 31,700; a grain's state is 300-400 B, docs/performance.md)
    peak = [line for line in proc.stdout.splitlines() if line.startswith("peak memory")]
    assert len(peak) == 1 and "bytes per grain" not in peak[0] and "whole process" in peak[0]


@pytest.mark.skipif(shutil.which("lmp") is None, reason="LAMMPS (Debian package lammps) absent")
def test_bench_runs_lammps_on_the_same_silo():
    out = _bench("--n", "400", "--steps", "40", "--settle", "60", "--json", "--lammps")
    assert out["lammps"]["n"] == out["n"]  # the same lattice, grain for grain
    assert out["ratio_vs_lammps"] > 0
    assert 0 <= out["lammps"]["list_builds"] <= out["steps"]  # read from LAMMPS's own log
    assert 0 <= out["lammps"]["build_seconds"] <= out["lammps"]["seconds"]
    assert out["lammps"]["peak_memory_bytes"] is None  # not measured, not a made-up 0


def _fake_lmp(tmp_path, script: str) -> dict:
    """An environment whose PATH finds a fake ``lmp`` (a shell script) first."""
    fake = tmp_path / "bin" / "lmp"
    fake.parent.mkdir()
    fake.write_text("#!/bin/sh\n" + script)
    fake.chmod(0o755)
    return {**os.environ, "PATH": f"{fake.parent}{os.pathsep}{os.environ['PATH']}"}


def test_a_lammps_that_fails_is_one_line_not_a_traceback(tmp_path):
    """A LAMMPS that exits with an error ended the bench in a 38-line RuntimeError traceback:
    its last ERROR line now, exit code 1 (the bench ran; the reference did not)."""
    env = _fake_lmp(tmp_path, 'echo "LAMMPS (fake)"\necho "ERROR: Lost atoms: original 400 '
                              'current 399 (fake)"\nexit 1\n')
    proc = subprocess.run([sys.executable, "-m", "silodem", "bench", "--n", "100", "--steps",
                           "5", "--settle", "5", "--lammps"], check=False, capture_output=True,
                          text=True, timeout=600, env=env)
    assert proc.returncode == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    # one line, after the stages the bench went through ("silodem bench: ...")
    said = [line for line in proc.stderr.splitlines() if not line.startswith("silodem bench: ")]
    assert said == [("error: LAMMPS failed (exit 1): ERROR: Lost atoms: original 400 current "
                    "399 (fake)")]


def test_a_missing_lammps_is_said_before_silodems_run(tmp_path, monkeypatch):
    """--lammps without LAMMPS installed was found only after silodem's whole run."""
    from silodem import bench

    monkeypatch.setattr(bench, "lammps_executable", lambda: None)
    monkeypatch.setattr(bench, "run_silodem", lambda *a: pytest.fail("silodem ran first"))
    with pytest.raises(FileNotFoundError, match="LAMMPS not found"):
        bench.bench(100, 1, 5, 5, lammps=True)


def test_side_by_side_copies_are_alike_not_identical():
    """``--scaling`` puts copies of one silo side by side: each copy holds grains on the same
    lattice (shifted by the silo width and a gap) behind its own six walls, and no grain is a
    contact candidate of another copy's grains or walls (without the gap, the walls of two
    neighbouring copies lay on one line and the grains pressed against them were candidates
    of the other silo's wall and grains: the 1e6-grain row did more work per grain).  The
    first copy is the deck's silo, bit for bit; the others draw their own radii from the
    deck's distribution, so that their states are not one state repeated (identical copies
    stayed equal to 1e-16 m for 3000 steps, and the branch predictor learned the repetition)."""
    from silodem.bench import COPY_GAP, advance, build

    one, width, top = build(12, 24)
    three, _, _ = build(12, 24, copies=3)
    pitch = width + COPY_GAP
    n = one.particles.n
    assert three.particles.n == 3 * n and three.walls.ax.size == 3 * one.walls.ax.size
    x3 = three.particles.view("x").reshape(3, n)
    r3 = three.particles.view("radius").reshape(3, n)
    for c in range(3):
        assert x3[c] == pytest.approx(one.particles.view("x") + c * pitch, abs=1e-12)
        assert r3[c].min() >= 0.09 and r3[c].max() <= 0.11  # diameters in [0.18, 0.22] m
    assert np.array_equal(r3[0], one.particles.view("radius"))
    assert not np.array_equal(r3[1], r3[0]) and not np.array_equal(r3[2], r3[1])
    advance(one, top, 400)
    advance(three, top, 400)
    copy_of = (three.particles.view("x") // pitch).astype(int)
    for c in range(3):
        assert np.count_nonzero(copy_of == c) == n  # no grain crossed into another silo
    nb = three.neighbors
    assert np.array_equal(copy_of[nb.pair_i], copy_of[nb.pair_j])
    wall_copy = (np.minimum(three.walls.ax, three.walls.bx) // pitch).astype(int)
    assert nb.wc_w.size > 0 and np.array_equal(copy_of[nb.wc_i], wall_copy[nb.wc_w])


def test_lattice_deck_runs_the_cache_probe_law():
    """``benchmarks/lammps-lattice2d.in`` runs the law of ``cache_probe.lattice``: kn = kt =
    1e5 N/m, friction 0.5, dt = 1e-5 s, and LAMMPS's gamma_n = c_n / m_eff = 2 zeta
    sqrt(kn / m_eff) for zeta = 0.1 and two disks of the mean radius 0.0975 m at 1000 kg/m^2."""
    from pathlib import Path

    deck = (Path(__file__).parents[1] / "benchmarks" / "lammps-lattice2d.in").read_text()
    words = next(line for line in deck.splitlines() if line.startswith("pair_style")).split()
    kn, kt, gamma_n, mu = float(words[2]), float(words[3]), float(words[4]), float(words[6])
    m_eff = 1000.0 * np.pi * 0.0975**2 / 2
    assert (kn, kt, mu) == (1e5, 1e5, 0.5) and "timestep        1.0e-5" in deck
    # given to three figures (16.37 -> 16.4): within half a unit of the last
    assert abs(gamma_n - 2 * 0.1 * np.sqrt(kn / m_eff)) <= 0.05


@pytest.mark.skipif(shutil.which("lmp") is None, reason="LAMMPS (Debian package lammps) absent")
def test_lattice_vs_lammps_runs_both_codes_on_the_same_grains():
    """A smoke test of the script: both codes run and report the 20 x 20 lattice's 400 grains.
    Each builds its own lattice (``cache_probe.lattice``; ``lammps-lattice2d.in``): the same
    0.2 m spacing and kind of grains, their radii and jitter drawn by each code's own random
    numbers, so alike, not identical; the count is what this test checks."""
    from pathlib import Path

    script = Path(__file__).parents[1] / "benchmarks" / "lattice_vs_lammps.py"
    proc = subprocess.run([sys.executable, str(script), "--sizes", "20", "--work", "8000",
                           "--repeat", "1"], capture_output=True, text=True, timeout=600,
                          check=False)
    assert proc.returncode == 0, proc.stderr
    assert "N =      400 (     400 in LAMMPS)" in proc.stdout  # 20 x 20 in both codes


def test_matrix_keeps_each_codes_best_pass():
    """``performance_matrix.py --passes``: the row of several passes holds silodem's fastest
    pass and LAMMPS's fastest pass, even when they come from different passes, and their
    ratio; every pass's pair of figures is kept."""
    best_of = benchmark_module("performance_matrix").best_of
    runs = [{"n": 990, "threads": 2, "particle_steps_per_s": ps,
             "lammps": {"particle_steps_per_s": lam}, "ratio_vs_lammps": ps / lam}
            for ps, lam in ((30e6, 16e6), (20e6, 18e6), (36e6, 15e6))]
    row = best_of(runs)
    assert row["particle_steps_per_s"] == 36e6
    assert row["lammps"]["particle_steps_per_s"] == 18e6
    assert row["ratio_vs_lammps"] == 2.0
    assert row["passes"] == [{"silodem": 30e6, "lammps": 16e6}, {"silodem": 20e6,
                             "lammps": 18e6}, {"silodem": 36e6, "lammps": 15e6}]
    assert runs[2]["lammps"]["particle_steps_per_s"] == 15e6  # the passes are not changed
    alone = best_of([{"n": 1, "threads": 1, "particle_steps_per_s": 5.0}])
    assert "lammps" not in alone and alone["passes"] == [{"silodem": 5.0, "lammps": None}]


def test_profile_step_times_a_run_without_changing_it():
    """``benchmarks/profile_step.py``: a run with its build timers gives the same bits as one
    without, the kernels it times inside a build add up to no more than the builds' own time,
    and its timers are gone afterwards; its step-by-step run (``stepped``, each part timed)
    gives the same bits, list builds and clock as ``Simulation.run`` over the same steps, and
    leaves the simulation where ``run`` goes on from it as it would have."""
    import collections

    import silodem.engine.neighbors as nbm
    from silodem.bench import advance, build

    prof = benchmark_module("profile_step")
    original = nbm._pairs_of
    plain, _, top = build(12, 24)
    timed, _, _ = build(12, 24)
    acc = collections.defaultdict(float)
    with prof.builds_timed(timed, acc):
        advance(timed, top, 3000)
    advance(plain, top, 3000)
    assert timed.neighbors.rebuilds == plain.neighbors.rebuilds > 1
    for name in ("x", "y", "vx", "vy", "omega"):
        assert np.array_equal(timed.particles.view(name), plain.particles.view(name))
    parts = sum(v for k, v in acc.items() if k != "build")
    assert 0.0 < parts <= acc["build"]
    assert {"_pairs_of", "_carry_pairs", "permute", "cell_list"} <= acc.keys()
    assert nbm._pairs_of is original and "rebuild" not in vars(timed.neighbors)

    builds = plain.neighbors.rebuilds
    parts = collections.defaultdict(float)
    listed, tested = prof.stepped(timed, 700, parts)
    advance(plain, top, 700)
    # the stretch saw builds, steps listing fast grains, and tests by cells
    assert plain.neighbors.rebuilds - builds > 5 and listed > tested > 5
    assert {"pair_loop", "walls_and_leapfrog", "test_by_cells", "build"} <= parts.keys()
    for more in (0, 300):  # and run() goes on from where each left off
        for sim in (timed, plain):
            advance(sim, top, more)
        assert timed.neighbors.rebuilds == plain.neighbors.rebuilds
        assert (timed.steps, timed.time) == (plain.steps, plain.time)
        for name in ("x", "y", "vx", "vy", "omega", "fx", "fy", "torque"):
            assert np.array_equal(timed.particles.view(name), plain.particles.view(name))
        assert np.array_equal(timed.neighbors.pair_fs, plain.neighbors.pair_fs)


def test_interleaved_scaling_runs_every_size_the_same_steps(monkeypatch):
    """``benchmarks/interleaved_scaling.py``: every size settles, then runs ``turn`` steps in
    turn with the others until each has run ``steps`` (so all stay in the same flow state);
    its silo is ``performance_matrix --scaling``'s (10,144 grains a copy)."""
    from pathlib import Path

    monkeypatch.syspath_prepend(str(Path(__file__).parents[1] / "benchmarks"))
    measure = benchmark_module("interleaved_scaling").measure
    sims, seconds = measure([1, 2], steps=20, turn=10, settle=5, log=lambda line: None)
    assert [sim.particles.n for sim in sims] == [10_144, 20_288]
    assert [sim.steps for sim in sims] == [25, 25]
    assert seconds.shape == (2, 2) and np.all(seconds > 0)
