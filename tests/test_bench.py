"""`silodem bench`: the benchmark silo matches the reference deck, and the command's JSON."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import pytest

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


def test_bench_json_smoke():
    out = _bench("--n", "400", "--steps", "40", "--settle", "60", "--json")
    nx, ny = lattice_size(400)
    assert out["n"] == deck_lattice(nx, ny)[0].size
    assert out["threads"] == 1 and out["steps"] == 40
    assert out["particle_steps_per_s"] > 0 and out["peak_memory_bytes"] > 0
    assert 0 <= out["list_builds"] <= out["steps"]  # at most one build per step
    assert 0 <= out["build_seconds"] <= out["seconds"]  # a part of the timed steps


@pytest.mark.skipif(shutil.which("lmp") is None, reason="LAMMPS (Debian package lammps) absent")
def test_bench_runs_lammps_on_the_same_silo():
    out = _bench("--n", "400", "--steps", "40", "--settle", "60", "--json", "--lammps")
    assert out["lammps"]["n"] == out["n"]  # the same lattice, grain for grain
    assert out["ratio_vs_lammps"] > 0
    assert 0 <= out["lammps"]["list_builds"] <= out["steps"]  # read from LAMMPS's own log
    assert 0 <= out["lammps"]["build_seconds"] <= out["lammps"]["seconds"]
