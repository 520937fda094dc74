"""The measurement recorder: it never changes the run, and its data survive state()/restore()
(what a checkpoint carries) unchanged."""

from __future__ import annotations

import h5py
import numpy as np
import pytest
from measure_helpers import tiny_hopper_config

from silodem.measure.recorders import MeasureRecorder, recorders_for
from silodem.silo.procedure import SiloRun


@pytest.fixture(scope="module")
def runs():
    cfg = tiny_hopper_config()
    plain = SiloRun(cfg)
    plain.run()
    measured = SiloRun(cfg, recorders=recorders_for(cfg))
    measured.run()
    return cfg, plain, measured


def test_measuring_does_not_change_the_run(runs):
    _, plain, measured = runs
    a, b = plain.sim.particles, measured.sim.particles
    assert plain.sim.steps == measured.sim.steps
    for key in ("x", "y", "vx", "vy", "omega"):
        np.testing.assert_array_equal(a.view(key), b.view(key))


def _flatten(group, prefix=""):
    out = {}
    for key, item in group.items():
        if isinstance(item, h5py.Group):
            out.update(_flatten(item, prefix + key + "/"))
        else:
            out[prefix + key] = item[()]
    return out


def test_state_and_restore_carry_everything(runs, tmp_path):
    cfg, _, measured = runs
    rec = next(r for r in measured.recorders if isinstance(r, MeasureRecorder))
    assert len(rec.rows) > 50 and rec.flow.snapshot is not None
    state = rec.state()
    for key, val in state.items():  # what a checkpoint can store: numeric arrays and scalars
        assert isinstance(key, str) and "/" not in key
        assert isinstance(val, int | float | np.generic) or (
            isinstance(val, np.ndarray) and val.dtype.kind in "biuf"), key
    copy = MeasureRecorder(cfg)
    copy.restore({k: v.copy() if isinstance(v, np.ndarray) else v for k, v in state.items()})
    files = []
    for r, name in ((rec, "a.h5"), (copy, "b.h5")):
        with h5py.File(tmp_path / name, "w") as h5:
            r.write(h5.create_group("measure"))
        with h5py.File(tmp_path / name) as h5:
            files.append(_flatten(h5["measure"]))
    assert files[0].keys() == files[1].keys()
    for key in files[0]:
        np.testing.assert_array_equal(files[0][key], files[1][key], err_msg=key)


def test_recorded_quantities_are_physical(runs):
    measured_run = runs[2]
    rec = next(r for r in measured_run.recorders if isinstance(r, MeasureRecorder))
    rows = np.array(rec.rows)
    settle = rows[:, 2] == 1
    c = rec.circles.arrays()
    # settled grains: porosity of a 2D disk packing, compression, 3-5 contacts per grain
    por = c["porosity"][settle]
    assert np.all((por > 0.08) & (por < 0.35))
    assert np.all(c["stress"][settle][:, :, :2] > 0)
    band = c["band"][settle, 0]
    assert np.all((band > 2.5) & (band < 5.5))
    # every grain present when the gate opened either left or is still there
    f = rec.flow
    assert f.uid0.size > 0 and np.isfinite(f.exit_time).sum() > 0.5 * f.uid0.size
