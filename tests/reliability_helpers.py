"""Helpers for the reliability tests: a small quick case, the command line in a subprocess,
and comparing two results files bit for bit; the benchmark scripts imported as modules."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
import pytest

import silodem
from silodem.config import Config
from silodem.scenario_files import load_config, quick_variant

# paper-case2 --quick with about 90 grains (~25000 steps): a few seconds; a checkpoint every
# ~8 chunks (0.4 s of simulated time)
SETS = ("fill.n_particles=250", "checkpoint.every_steps=2000", "output.png=false",
        "measure.report=false")


def quick_config(*extra: str) -> Config:
    """The Config that ``silodem run paper-case2 --quick --set SETS...`` runs."""
    return quick_variant(load_config("paper-case2", [*SETS, *extra]))


def run_args(out: Path, *extra: str) -> list[str]:
    sets = [arg for item in (*SETS, *extra) for arg in ("--set", item)]
    return ["run", "paper-case2", "--quick", *sets, "--out", str(out)]


def env() -> dict[str, str]:
    """The environment for a subprocess that imports the same silodem as these tests."""
    out = dict(os.environ)
    package_parent = str(Path(next(iter(silodem.__path__))).parent)
    out["PYTHONPATH"] = os.pathsep.join(p for p in (package_parent, out.get("PYTHONPATH")) if p)
    out.setdefault("NUMBA_NUM_THREADS", "2")
    return out


def benchmark_module(name: str):
    """A script of the top-level ``benchmarks/`` folder, imported as a module."""
    import importlib.util

    path = Path(__file__).parents[1] / "benchmarks" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def command(*args: str) -> list[str]:
    return [sys.executable, "-m", "silodem", *args]


def cli(*args: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    return subprocess.run(command(*args), check=False, capture_output=True, text=True,
                          env=env(), timeout=timeout)


def start(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(command(*args), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env())


def wait_for_file(path: Path, proc: subprocess.Popen[str], timeout: float = 60) -> None:
    """Wait until ``path`` exists (the process must still be running)."""
    t0 = time.monotonic()
    while not path.exists():
        assert proc.poll() is None, f"process ended ({proc.returncode}) before {path} appeared"
        assert time.monotonic() - t0 < timeout, f"{path} did not appear in {timeout} s"
        time.sleep(0.01)


def signal_when(proc: subprocess.Popen[str], sig: int, ready: Callable[[], object]) -> str:
    """Wait with ``ready()``, send ``sig`` to ``proc`` and return its stderr once it ended;
    the process is killed if anything on the way fails."""
    try:
        ready()
        proc.send_signal(sig)
        _, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    return stderr


def signal_dropped_by_a_callback(sig: int) -> None:
    """Send ``sig`` to this process and drop the KeyboardInterrupt its handler raises (for
    SIGTERM, ``errors.Terminated``), as Python drops one raised inside a weakref callback
    while matplotlib draws: the code that was interrupted goes on."""
    try:
        os.kill(os.getpid(), sig)
        time.sleep(0.05)  # the handler runs between bytecodes
    except KeyboardInterrupt:
        pass  # as a weakref callback does: printed and dropped


def assert_one_line_error(result: subprocess.CompletedProcess[str], code: int,
                          *needles: str) -> str:
    assert result.returncode == code, (result.returncode, result.stdout, result.stderr)
    assert "Traceback" not in result.stderr + result.stdout
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].strip(), result.stderr
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


def datasets(path: Path, group: str = "/") -> dict[str, np.ndarray]:
    """Every dataset under ``group`` of an HDF5 file, by path."""
    out: dict[str, np.ndarray] = {}
    with h5py.File(path, "r") as h5:
        def visit(name: str, node) -> None:
            if isinstance(node, h5py.Dataset):
                out[name] = node[()]

        h5[group].visititems(visit)
    return out


def assert_bit_identical(a: Path, b: Path, group: str) -> None:
    """The datasets under ``group`` of two results files are equal bit for bit."""
    da, db = datasets(a, group), datasets(b, group)
    assert da.keys() == db.keys()
    assert da, f"no datasets under {group}"
    for key in da:
        x, y = da[key], db[key]
        assert x.dtype == y.dtype and x.shape == y.shape, key
        if x.dtype.kind in "biuf":  # bit for bit: -0.0 != 0.0, NaN == same NaN
            assert x.tobytes() == y.tobytes(), f"{group}/{key} differs"
        else:
            assert np.array_equal(x, y), f"{group}/{key} differs"


class _Stop(Exception):
    pass


def stop_and_restore(cfg: Config, phase: str, path: Path):
    """Run ``cfg`` until the third chunk of ``phase``, save a checkpoint to ``path`` there and
    stop; return (the stopped run, a new run restored from the checkpoint, not yet run on)."""
    from silodem.checkpoint import read_checkpoint, save_checkpoint
    from silodem.scenario_files import config_to_toml
    from silodem.silo.procedure import SiloRun

    first, seen = SiloRun(cfg), []

    def save_on_third_chunk(run: SiloRun) -> None:
        seen.append(run.state.phase)
        if seen.count(phase) == 3:
            save_checkpoint(run, path, config_toml=config_to_toml(cfg), reason="test")
            raise _Stop

    first.chunk_hooks.append(save_on_third_chunk)
    try:
        first.run()
    except _Stop:
        pass
    else:
        raise AssertionError(f"the run ended before a third chunk of {phase}")
    loaded = read_checkpoint(path)
    assert loaded.config == cfg
    second = SiloRun(loaded.config)
    loaded.restore(second)
    return first, second


def hertz_config() -> Config:
    """The quick hopper of the embedded scenario paper-case2-hertz (the Hertz-Mindlin law:
    grains of E = 1 GPa, nu = 0.3, steel walls of 200 GPa) with 120 grains and a 4 s
    discharge."""
    data = quick_variant(load_config("paper-case2-hertz")).model_dump()
    data["fill"]["n_particles"] = 120
    data["discharge"]["max_time"] = 4.0
    return Config.model_validate(data)


def exit_and_last_line(args: list[str], capsys) -> tuple[int, str]:
    """Run the command line in this process: its exit code and the last line on stderr (no
    traceback before it)."""
    from silodem.cli import main

    with pytest.raises(SystemExit) as exc:
        main(args)
    err = capsys.readouterr().err
    assert "Traceback" not in err, err
    return exc.value.code, err.strip().splitlines()[-1]


def saved_at(path: Path, step_key: str) -> str:
    """'at t = T s (step N, phase)' as a stopped run's line reads it from the file it kept."""
    with h5py.File(path) as h5:
        return (f"at t = {float(h5.attrs['time']):.4g} s (step {int(h5.attrs[step_key])}, "
                f"{h5.attrs['phase']})")


def results_written_line(out: Path) -> str:
    """The line of a run stopped by a signal after its complete results.h5 was written."""
    return (f"interrupted: after the run's results were written to {out / 'results.h5'}; "
            f"'silodem plot {out}' draws its pictures and report.html")
