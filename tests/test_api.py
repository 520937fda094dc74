"""The Python API for notebooks (silodem.api, docs/api.md): build a scenario, run it, read its
results as DataFrames.  The tables are checked against results.h5 read with h5py, against
mass conservation, and against each grain's force balance."""

from __future__ import annotations

import dataclasses
import shutil
import subprocess
import sys

import h5py
import numpy as np
import pandas as pd
import pytest
from measure_helpers import tiny_hopper_config
from reliability_helpers import env

from silodem import api, study
from silodem.api import SilodemWarning
from silodem.errors import InputError
from silodem.silo.checks import estimate_overlap


@pytest.fixture(scope="module")
def res(tmp_path_factory):
    return api.run(tiny_hopper_config(), tmp_path_factory.mktemp("api") / "run")


def test_timeseries_phase_and_counts_are_integers(res):
    """/timeseries wrote the phase code and the counts as float64 where the other groups hold
    integers; its phase_codes said fill=0,settle=1,discharge=2 by hand (docs/output.md)."""
    with h5py.File(res.folder / "results.h5", "r") as h5:
        ts = h5["timeseries"]
        assert ts["phase"].dtype == np.int8 and h5["measure/phase"].dtype == np.int8
        for key in ("n_particles", "n_contacts", "n_wall_contacts"):
            assert ts[key].dtype == np.int64, key
        for key in ("time", "kinetic_energy", "discharged_mass", "force_ratio"):
            assert ts[key].dtype == np.float64, key
        codes = "fill=0,settle=1,discharge=2"  # docs/output.md
        assert ts.attrs["phase_codes"] == h5["frames"].attrs["phase_codes"] == codes
        assert h5["measure/phase"].attrs["codes"] == codes
        phase = ts["phase"][()]
        assert set(phase) == {0, 1, 2} and np.all(np.diff(phase) >= 0)
        # every grain poured is counted while the silo fills (none has left yet)
        poured = ts["n_particles"][phase == 0]
        assert poured.max() == h5["events"].attrs["n_poured"] == 150
        # the last sample of the settling holds the grains of the settled snapshot
        assert ts["n_particles"][phase == 1][-1] == h5["settled/particles/x"].shape[0]


def _write_as_float(folder, keys=("phase", "n_particles", "n_contacts", "n_wall_contacts")):
    """Rewrite ``keys`` of folder/results.h5's /timeseries as float64, as silodem did before."""
    with h5py.File(folder / "results.h5", "r+") as h5:
        ts = h5["timeseries"]
        for key in keys:
            data, unit = ts[key][()].astype(np.float64), ts[key].attrs["unit"]
            del ts[key]
            ts.create_dataset(key, data=data).attrs["unit"] = unit


def test_an_older_results_file_with_float_columns_reads_the_same(res, tmp_path):
    """A results.h5 of an earlier version (phase and counts float64) gives the same tables,
    phase names, report numbers and flow as the integer columns."""
    old = tmp_path / "old"
    shutil.copytree(res.folder, old)
    _write_as_float(old)
    with h5py.File(old / "results.h5", "r") as h5:
        assert h5["timeseries/phase"].dtype == np.float64
    before = api.open_results(old)
    now = res.timeseries()
    then = before.timeseries()
    pd.testing.assert_frame_equal(then, now, check_dtype=False)
    assert list(then["phase_name"]) == list(now["phase_name"])
    assert set(then["phase_name"]) == {"fill", "settle", "discharge"}
    pd.testing.assert_frame_equal(before.numbers(), res.numbers())
    flow_then, flow_now = before.analysis().flow, res.analysis().flow
    for key in ("t", "mass"):  # the discharge samples, chosen by phase == 2
        np.testing.assert_array_equal(flow_then[key], flow_now[key])
    assert flow_now["t"].size > 10
    np.testing.assert_array_equal(dataclasses.astuple(flow_then["rate"]),
                                  dataclasses.astuple(flow_now["rate"]))


def test_scenario_takes_dotted_keys_and_quick():
    cfg = api.scenario("paper-case2", set={"material.friction_deg": 25.0, "silo.cell_width": 4})
    assert cfg.material.friction_deg == 25.0 and cfg.silo.cell_width == 4.0
    quick = api.scenario("paper-case2", quick=True)
    assert quick.name == "paper-case2-quick" and quick.silo.cell_width == pytest.approx(3.4 * 0.6)
    with pytest.raises(InputError, match="did you mean 'material.friction_deg'"):
        api.scenario("paper-case2", set={"material.friction": 25.0})
    with pytest.raises(InputError, match="not a TOML value"):
        api.scenario("paper-case2", set={"material.kn": object()})
    # the messages name the API's argument, not the command line's --set
    with pytest.raises(InputError, match=r"\(from set material.kn=-1\)$") as bad:
        api.scenario("paper-case2", set={"material.kn": -1})
    assert "--set" not in str(bad.value)
    with pytest.raises(InputError, match=r"^set material.kn.x=1: 'material.kn' is a value"):
        api.scenario("paper-case2", set={"material.kn.x": 1})
    # a Config already built: one short line, not its 1,600-character repr
    with pytest.raises(InputError) as built:
        api.scenario(cfg)
    text = str(built.value)
    assert text == ("source is a Config already built ('paper-case2'): pass it to api.run "
                    "directly; api.scenario takes a scenario name or a TOML file")
    assert "\n" not in text and len(text) < 200
    # quick shrinks what set gave too, and says so (300 grains became 108 without a word)
    with pytest.warns(api.SilodemWarning, match=r"^quick changed what set gave: "
                      r"fill.n_particles 300 -> 108 \(it shrinks the silo after set\)$"):
        small = api.scenario("paper-case2", quick=True, set={"fill.n_particles": 300})
    assert small.fill.n_particles == round(300 * 0.36)  # docs/scenarios.md: 0.36 x the grains
    # a quick run's config name is not a scenario's: the error says which one it shrank
    with pytest.raises(InputError, match=r"quick variant of 'paper-case2'; give 'paper-case2' "
                       r"with --quick \(quick=True"):
        api.scenario(small.name)
    assert api.scenario("paper-case2", quick=np.True_) == quick  # numpy's True is True


@pytest.mark.parametrize("call", [
    lambda cfg, r: api.scenario(set={"material.kn": 1e7}, quick=cfg),
    lambda cfg, r: api.scenario(set=[cfg]),
    lambda cfg, r: api.scenario(set={("material", "kn") * 50: 1e7}),
    lambda cfg, r: api.scenario(set={"material.kn": [cfg]}),
    lambda cfg, r: api.run(cfg, out=cfg),
    lambda cfg, r: api.run(cfg, r.folder / "n", threads=cfg),
    lambda cfg, r: api.run(cfg, r.folder / "n", threads="8" * 500),
    lambda cfg, r: api.run(cfg, r.folder / "n", threads=10**5000),
    lambda cfg, r: api.run(cfg, r.folder / "n", progress=cfg),
    lambda cfg, r: api.run(vars(cfg)),
    lambda cfg, r: api.open_results(cfg),
    lambda cfg, r: r.particles(list(range(500))),
    lambda cfg, r: r.wall_profile("x" * 500),
])
def test_a_wrong_value_is_named_briefly(res, call):
    """A wrong value is quoted in at most 60 characters (a string cut short, a long repr
    replaced by its type's name): given a Config, the messages held its whole repr."""
    with pytest.raises(InputError) as bad:
        call(api.scenario("paper-case2"), res)
    text = str(bad.value)
    assert "\n" not in text and len(text) < 200 and "description=" not in text, text


def test_tables_are_the_datasets_of_results_h5(res):
    """Each DataFrame column is the dataset of the same name, read here with h5py."""
    with h5py.File(res.folder / "results.h5", "r") as h5:
        ts = res.timeseries()
        for key, dset in h5["timeseries"].items():
            assert np.array_equal(ts[key].to_numpy(), dset[()], equal_nan=True), key
        assert set(ts["phase_name"]) <= {"fill", "settle", "discharge"}
        for snap in ("settled", "final"):
            for table, group in ((res.particles(snap), "particles"),
                                 (res.contacts(snap), "contacts"),
                                 (res.wall_contacts(snap), "wall_contacts")):
                for key, dset in h5[f"{snap}/{group}"].items():
                    same = np.array_equal(table[key].to_numpy(), dset[()], equal_nan=True)
                    assert same, (snap, key)
        m = res.measurements()
        assert np.array_equal(m["band_coordination"].to_numpy(),
                              h5["measure/band/coordination"][()], equal_nan=True)
        # every stress column: component k of the stress datasets is xx, zz, xz (docs/output.md)
        band, circles = h5["measure/band/stress"][()], h5["measure/circles/stress"][()]
        for n, raw in enumerate(h5["measure/circles/name"][()]):
            name = raw.decode()
            assert np.array_equal(m[f"{name}_coordination"].to_numpy(),
                                  h5["measure/circles/coordination"][:, n], equal_nan=True)
            assert np.array_equal(m[f"{name}_porosity"].to_numpy(),
                                  h5["measure/circles/porosity"][:, n], equal_nan=True)
            for k, comp in enumerate(("xx", "zz", "xz")):
                assert np.array_equal(m[f"{name}_sigma_{comp}"].to_numpy(), circles[:, n, k],
                                      equal_nan=True), (name, comp)
        for k, comp in enumerate(("xx", "zz", "xz")):
            assert np.array_equal(m[f"band_sigma_{comp}"].to_numpy(), band[:, k],
                                  equal_nan=True), comp
    assert isinstance(ts, pd.DataFrame) and len(ts) > 10


def test_tables_start_with_the_documented_columns_and_carry_the_files_units(res):
    """docs/api.md's column lists lead each table (results.h5 keeps datasets alphabetically:
    a table began with discharged_mass, or with fn, fs before i, j), and ``attrs["units"]`` is
    each dataset's ``unit`` attribute as h5py reads it (docs/output.md's units)."""
    expected_first = {"timeseries": ["time", "phase", "phase_name"],
                      "particles": ["x", "y", "vx", "vy", "omega", "radius", "uid", "fx", "fy"],
                      "contacts": ["i", "j", "fn", "fs", "fx", "fy"],
                      "wall_contacts": ["grain", "wall", "fn", "fs", "fx", "fy"]}
    tables = {"timeseries": (res.timeseries(), "timeseries"),
              "particles": (res.particles("settled"), "settled/particles"),
              "contacts": (res.contacts("settled"), "settled/contacts"),
              "wall_contacts": (res.wall_contacts("settled"), "settled/wall_contacts")}
    with h5py.File(res.folder / "results.h5", "r") as h5:
        for name, (df, path) in tables.items():
            first = expected_first[name]
            assert list(df.columns[:len(first)]) == first, name
            for key, dset in h5[path].items():
                assert df.attrs["units"][key] == dset.attrs["unit"], (name, key)
    assert res.timeseries().attrs["units"]["time"] == "s"
    assert res.particles("settled").attrs["units"]["mass"] == "kg"
    m = res.measurements()
    assert list(m.columns[:5]) == ["time", "step", "phase", "phase_name", "band_coordination"]
    assert m.attrs["units"]["band_sigma_zz"] == "Pa" and m.attrs["units"]["time"] == "s"
    assert res.wall_profile("fill").attrs["units"] == {"z": "m", "sigma_n": "Pa",
                                                       "tau_down": "Pa", "on_vertical": "-"}


def test_the_grains_left_in_the_silo_hold_the_mass_not_discharged(res):
    """Mass conservation: the final grains' mass (rho pi r^2 t) is the mass at the gate's
    opening less the discharged fraction (the tiny silo does not re-insert grains)."""
    ev = res.events
    left = res.particles("final")["mass"].sum()
    assert left == pytest.approx(ev["initial_mass"] * (1 - ev["discharged_fraction"]), rel=1e-12)


def test_contact_tables_balance_each_grains_resultant_force(res):
    """Per grain of the settled packing: the forces of its grain-grain contacts (+F on j, -F
    on i) and of its wall contacts add up to its resultant contact force (fx, fy).  The
    contact vectors are rebuilt at the snapshot's positions, one step after the forces were
    computed: the normal has turned by at most |v_j - v_i| dt / |x_j - x_i|, which bounds the
    difference by that angle times |F| summed over the grain's contacts."""
    p, c, w = res.particles("settled"), res.contacts("settled"), res.wall_contacts("settled")
    dt = res.dt
    i, j = c["i"].to_numpy(), c["j"].to_numpy()
    Fc = c[["fx", "fy"]].to_numpy()
    total = np.zeros((len(p), 2))
    np.add.at(total, j, Fc)
    np.add.at(total, i, -Fc)
    np.add.at(total, w["grain"].to_numpy(), w[["fx", "fy"]].to_numpy())
    x, v = p[["x", "y"]].to_numpy(), p[["vx", "vy"]].to_numpy()
    turn = np.linalg.norm(v[j] - v[i], axis=1) * dt / np.linalg.norm(x[j] - x[i], axis=1)
    bound = np.zeros(len(p))
    np.add.at(bound, i, np.linalg.norm(Fc, axis=1) * turn)
    np.add.at(bound, j, np.linalg.norm(Fc, axis=1) * turn)
    resultant = p[["fx", "fy"]].to_numpy()
    miss = np.linalg.norm(total - resultant, axis=1)
    assert np.all(miss <= bound * (1 + 1e-6) + 1e-9 * np.abs(resultant).max())
    assert len(c) > len(p)  # a packing: more contacts than grains


def _wall_profile_from_h5(h5, window):
    """The wall profile recomputed from results.h5's raw wall bins (docs/measurements.md):
    the window's samples ('fill': settling samples in (t_open - window, t_open]; 'discharge':
    discharge samples in (t_open + delay, t_open + delay + window)), their mean per bin,
    both sides' bins sorted by z and averaged; the downward shear is minus the shear along
    A -> B times the sign of the tangent's z component."""
    m, cfg = h5["measure"], tiny_hopper_config().measure
    t, phase = m["time"][()], m["phase"][()]
    t_open = float(h5["events"].attrs["discharge_start_time"])
    if window == "fill":
        sel = (phase == 1) & (t > t_open - cfg.window) & (t <= t_open)
    else:
        lo = t_open + cfg.discharge_delay
        sel = (phase == 2) & (t > lo) & (t < lo + cfg.window)
    assert sel.sum() >= 3
    names = [n.decode() for n in h5["walls/name"][()]]
    wall, z = m["wall_bins/wall"][()], m["wall_bins/z"][()]
    ty = m["wall_bins/tangent"][()][wall, 1]
    normal = m["wall_bins/normal"][()][sel].mean(axis=0)
    down = -m["wall_bins/shear"][()][sel].mean(axis=0) * np.sign(ty)
    sides = []
    for side in ("left", "right"):
        b = np.isin(wall, [names.index(f"{side}_wall"), names.index(f"{side}_hopper")])
        order = np.argsort(z[b])
        sides.append((z[b][order], normal[b][order], down[b][order]))
    (zl, nl, dl), (_, nr, dr) = sides
    return zl, 0.5 * (nl + nr), 0.5 * (dl + dr)


def test_report_views_and_summary(res):
    prof = res.wall_profile("fill")
    assert list(prof.columns) == ["z", "sigma_n", "tau_down", "on_vertical"]
    assert np.all(np.diff(prof["z"]) > 0) and (prof["sigma_n"] >= 0).all()
    with h5py.File(res.folder / "results.h5", "r") as h5:
        for window in ("fill", "discharge"):
            z, sigma_n, tau_down = _wall_profile_from_h5(h5, window)
            got = res.wall_profile(window)
            np.testing.assert_allclose(got["z"], z, rtol=1e-12)
            np.testing.assert_allclose(got["sigma_n"], sigma_n, rtol=1e-12, atol=1e-9)
            np.testing.assert_allclose(got["tau_down"], tau_down, rtol=1e-12, atol=1e-9)
    numbers = res.numbers()
    assert numbers["quantity"].str.contains("Janssen").any()
    assert res.summary()["n_poured"] == res.events["n_poured"] == 150
    assert len(res.frames()) > 0 and res.status == "complete"
    assert "frames" not in res._raw.data  # the frames stay on disk until asked for
    with h5py.File(res.folder / "results.h5", "r") as h5:
        assert res.frames()[-1].time == h5["frames/time"][-1]
        assert res.dt == h5.attrs["dt"]


def test_numpy_scalars_are_values_too():
    cfg = api.scenario("paper-case2", set={"fill.n_particles": np.int64(200),
                                           "output.png": np.bool_(False),
                                           "material.kn": np.float64(6e6)})
    assert (cfg.fill.n_particles, cfg.output.png, cfg.material.kn) == (200, False, 6e6)


def _plan():
    return study.expand(study.load_study("paper-study"), quick=True)


def _unfinished(parent):
    folder = parent / "unfinished"
    folder.mkdir(exist_ok=True)
    (folder / "checkpoint.h5").write_bytes(b"a run's state")
    return folder


@pytest.mark.parametrize("call, needle", [
    (lambda r: r.particles("middle"), "snapshot must be one of"),
    (lambda r: r.wall_profile("later"), "window must be"),
    (lambda r: api.open_results(r.folder / "nothing"), "not a results folder"),
    (lambda r: api.open_results(r.folder / "results.h5"), "give the results folder"),
    (lambda r: api.open_results(None), "folder must be"),
    (lambda r: api.scenario(set=[("material.kn", 1.0)]), "set must map dotted keys"),
    (lambda r: api.scenario(set={"silo": {"outlet_width": 0.8}}), "dotted key, not a table"),
    (lambda r: api.scenario(quick="no"), "quick must be True or False"),
    (lambda r: api.run({"name": "x"}), "cfg must be a Config"),
    (lambda r: api.run(r.config, r.folder / "results.h5"), "is a file, not a folder"),
    (lambda r: api.run(r.config, r.folder / "again", threads=0), "threads must be"),
    (lambda r: api.run(r.config, _unfinished(r.folder.parent)), "holds an unfinished run"),
    # model_copy(update=...) skips pydantic's checks: a numpy or TypeError traceback before
    (lambda r: api.run(r.config.model_copy(update={"seed": -5}), r.folder / "n"), "seed"),
    (lambda r: api.run(r.config.model_copy(update={"fill": r.config.fill.model_copy(
        update={"n_particles": 2.5})}), r.folder / "n"), "fill.n_particles"),
    (lambda r: api.run(r.config, out=3), "out must be a results folder's path"),
    (lambda r: api.open_results(""), "folder must be"),  # was the current folder
    (lambda r: api.run(r.config, r.folder.parent / "a\0b"), "not a usable path"),
    (lambda r: api.scenario(set={"material.kn=3": 1e7}), "a key is a dotted name"),
    (lambda r: api.scenario(set={" ": 1e7}), "a key is a dotted name"),
    (lambda r: study.load_study(None), "source must be a study's name"),
    # a key model_copy(update=...) does not know was dropped without a word before
    (lambda r: api.run(r.config.model_copy(update={"sed": 7}), r.folder / "n"),
     r"unknown key 'sed' \(did you mean 'seed'\?\)"),
    (lambda r: api.run(r.config.model_copy(update={"material": r.config.material.model_copy(
        update={"friction": 5.0})}), r.folder / "n"), r"unknown key 'material.friction' "),
    # a set key given to model_copy: the hint was a TOML file's ('write it without quotes')
    (lambda r: api.run(r.config.model_copy(update={"material.friction_deg": 30.0}),
                       r.folder / "n"),
     (r"^unknown key 'material.friction_deg': model_copy\(update=...\) takes the names of one "
      r"section's fields, not dotted keys; give it as set={'material.friction_deg': ...} to "
      r"api.scenario, or update={'material': cfg.material.model_copy\(update={...}\)}$")),
    # flags: the string 'no' is truthy, it switched the option on
    (lambda r: api.run(r.config, r.folder / "n", progress="no"), "progress must be True or"),
    (lambda r: study.expand(study.load_study("paper-study"), quick="no"), "quick must be True"),
    (lambda r: study.run_study(_plan(), r.folder / "s", serial="no"), "serial must be True"),
    (lambda r: study.run_study(_plan(), r.folder / "s", client="tcp://127.0.0.1:1"),
     "client must be a dask.distributed Client.*scheduler="),
    (lambda r: study.expand("paper-study"), "expand takes a study from load_study"),
    (lambda r: study.run_study("paper-study", r.folder / "s"), "run_study takes a plan"),
    (lambda r: study.run_study(_plan(), None), "out_dir must be"),
    (lambda r: study.run_study(_plan(), r.folder / "s", workers=0), "workers must be"),
    (lambda r: study.run_study(_plan(), r.folder / "s", workers=4096),
     "a local cluster takes at most"),
])
def test_bad_requests_are_one_line_input_errors(res, call, needle):
    with pytest.raises(InputError, match=needle):
        call(res)


HUGE = 10**5000  # more digits than Python writes in decimal (sys.get_int_max_str_digits)


@pytest.mark.parametrize("call, needle", [
    (lambda r: api.run(r.config, r.folder / "n", threads=HUGE), "threads must be"),
    (lambda r: api.run(r.config, r.folder / "n", threads=-HUGE), "threads must be"),
    (lambda r: api.run(r.config.model_copy(update={"seed": HUGE}), r.folder / "n"), "seed:"),
    (lambda r: api.run(r.config.model_copy(update={"fill": r.config.fill.model_copy(
        update={"n_particles": HUGE})}), r.folder / "n"), "fill.n_particles:"),
    (lambda r: api.scenario(set={"seed": HUGE}), "set 'seed': .* is not a TOML value"),
    (lambda r: api.scenario(set={HUGE: 1}), "a key is a dotted name"),
    (lambda r: api.run(r.config, out=HUGE), "out must be"),
    (lambda r: api.run(r.config, r.folder / "n", progress=HUGE), "progress must be"),
    (lambda r: study.load_study(HUGE), "source must be a study's name"),
    (lambda r: study.run_study(_plan(), r.folder / "s", workers=HUGE), "workers must be"),
])
def test_an_integer_too_long_to_print_is_named_by_its_digits(res, call, needle):
    """threads=10**5000 (and seed, n_particles, workers...) ended in Python's ValueError
    "Exceeds the limit (4300 digits) for integer string conversion" while the error message
    was being made: now the one-line InputError says how long the integer is."""
    with pytest.raises(InputError, match=needle) as bad:
        call(res)
    text = str(bad.value)
    limit = sys.get_int_max_str_digits()
    assert f"an integer of more than {limit} digits" in text, text
    assert "\n" not in text and len(text) < 200, text


def test_an_integer_of_many_digits_is_named_by_their_count(res):
    """One Python can write but too long to quote: its count of digits, not its first 57
    (another number)."""
    with pytest.raises(InputError, match="got an integer of 100 digits") as bad:
        api.run(res.config, res.folder / "n", threads=int("9" * 100))
    assert "999" not in str(bad.value)


def test_a_run_refused_for_its_numbers_makes_no_folder_and_numpy_threads_run(res, tmp_path):
    """A time step over the stability limit is refused before the results folder is made
    (as on the command line); a thread count that is a numpy integer runs, to the same
    grains as the fixture's run (the kernels' sums do not depend on the thread count)."""
    cfg = tiny_hopper_config()
    with pytest.raises(InputError, match="exceeds the stability limit"):
        api.run(cfg.model_copy(update={"time": cfg.time.model_copy(update={"dt": 1.0})}),
                tmp_path / "refused")
    assert not (tmp_path / "refused").exists()
    again = api.run(cfg, tmp_path / "again", threads=np.int64(1))
    assert again.particles("final").equals(res.particles("final"))


def test_a_runs_warnings_are_python_warnings(tmp_path, capsys):
    """A run whose contacts are too soft (estimate_overlap: overlaps of the grains' radius)
    says so, loses grains and does not settle: api.run issues each of its warnings as a
    SilodemWarning from the caller's line, where a notebook shows it (only the command line
    printed them).  Run again over it with progress: the note that the earlier results are
    replaced comes first, and the warnings printed as they came are not issued twice."""
    cfg = tiny_hopper_config()
    soft = {"kn": 2e4, "ks": 2e4}
    cfg = cfg.model_copy(update={
        "material": cfg.material.model_copy(update=soft),
        "walls": cfg.walls.model_copy(update=soft),
        "settle": cfg.settle.model_copy(update={"max_time": 0.5, "min_time": 0.2}),
        "discharge": cfg.discharge.model_copy(update={"max_time": 0.5})})
    assert estimate_overlap(cfg).overlap_fraction > 0.5
    folder = tmp_path / "soft"
    with pytest.warns(SilodemWarning) as record:
        first = api.run(cfg, folder)
    issued = [w for w in record if w.category is SilodemWarning]  # (not another library's)
    assert [str(w.message) for w in issued] == first.warnings
    assert first.warnings[0].startswith("soft contacts: ")
    assert any(w.startswith("grains lost in all: ") for w in first.warnings)
    assert first.warnings[-1].startswith("not settled: ")
    assert {w.filename for w in issued} == {__file__}  # stacklevel: the caller's line

    with pytest.warns(SilodemWarning) as record:
        again = api.run(cfg, str(folder), progress=True)
    said = [str(w.message) for w in record if w.category is SilodemWarning]
    assert said[0] == f"replacing the earlier run's results in {folder}"
    assert again.warnings == first.warnings  # the same run
    live = capsys.readouterr().err
    shown = [w for w in again.warnings if f"warning: {w}" in live]
    assert shown and "soft contacts: " in shown[0]
    assert said[1:] == [w for w in again.warnings if w not in shown]
    # the running total of lost grains is printed as it grows, and issued at its end
    assert "warning: grains lost so far: " in live
    assert any(w.startswith("grains lost in all: ") for w in said)


def test_a_silodem_warning_is_shown_each_time_unless_filtered():
    """Python shows a warning once per text and calling line: a notebook cell run again, or a
    loop of runs, would hide each run's warnings after the first.  A SilodemWarning is shown
    each time; a filter of the user's still comes first."""
    code = ("import warnings; from silodem.api import SilodemWarning\n"
            "for _ in range(2): warnings.warn('soft contacts', SilodemWarning)\n"
            "warnings.filterwarnings('ignore', 'replacing', SilodemWarning)\n"
            "warnings.warn('replacing the earlier run', SilodemWarning)\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=env(), check=True, timeout=120)
    assert done.stderr.count("SilodemWarning: soft contacts") == 2, done.stderr
    assert "replacing" not in done.stderr
