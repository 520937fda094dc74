"""The measurement recorder: it never changes the run, its data survive state()/restore()
(what a checkpoint carries) unchanged, and what it records equals a recount from the raw contact
forces written in this file."""

from __future__ import annotations

import math

import h5py
import numpy as np
import pytest
from measure_helpers import tiny_hopper_config
from scipy.integrate import quad

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


def test_every_number_under_measure_carries_its_unit(runs, tmp_path):
    """docs/output.md: datasets of numbers and flags under /measure carry a ``unit``
    attribute (the discharge snapshot's columns had none; its walls-in-place flags and the
    lost-grain flags had none, where /walls/active had '-'); names do not."""
    _, _, measured = runs
    rec = next(r for r in measured.recorders if isinstance(r, MeasureRecorder))
    with h5py.File(tmp_path / "m.h5", "w") as h5:
        rec.write(h5.create_group("measure"))
    with h5py.File(tmp_path / "m.h5") as h5:
        missing = []
        h5["measure"].visititems(lambda name, item: missing.append(name) if (
            isinstance(item, h5py.Dataset) and item.dtype.kind in "iufb"
            and "unit" not in item.attrs) else None)
        assert missing == []
        assert h5["measure/flow/lost_during_discharge"].attrs["unit"] == "-"
        snap = h5["measure/discharge_snapshot"]
        assert snap["particles/vx"].attrs["unit"] == "m/s"
        assert snap["contacts/fn"].attrs["unit"] == "N"


def _half_chord(radius, dx):
    """Half the length of the vertical chord of a disk at horizontal offset dx from its centre."""
    return math.sqrt(max(radius * radius - dx * dx, 0.0))


def _area_by_chords(x_lo, x_hi, span, kinks):
    """Area [m^2] between x_lo and x_hi of a region whose vertical section at x is the interval
    ``span(x)`` (empty when reversed): the integral of the chord length, by adaptive quadrature
    (scipy quad, with the section's kinks given as break points)."""
    points = [k for k in kinks if x_lo < k < x_hi]
    value, _ = quad(lambda x: max(0.0, span(x)[1] - span(x)[0]), x_lo, x_hi,
                        points=points or None, epsabs=1e-12, epsrel=1e-10, limit=200)
    return value


def _circle_area_in_hopper(cfg, cx, cz, radius):
    """Area of a circle inside the tiny hopper, from the config alone: above the floor line
    z = max(0, (|x - B/2| - b/2) tan(theta)) (the hopper walls, flat in the cell) and under
    the wall top, for 0 <= x <= B."""
    s = cfg.silo
    slope = math.tan(math.radians(s.hopper_angle_from_horizontal_deg))
    half_b, mid = 0.5 * s.outlet_width, 0.5 * s.cell_width

    def span(x):
        h = _half_chord(radius, x - cx)
        floor = max(0.0, (abs(x - mid) - half_b) * slope)
        return max(cz - h, floor), min(cz + h, s.wall_height)

    return _area_by_chords(max(cx - radius, 0.0), min(cx + radius, s.cell_width), span,
                           [mid - half_b, mid + half_b, mid])


def _lens(cx, cz, radius, x, z, r):
    """Area of disk (x, z, r) inside the circle (cx, cz, radius), by chords; the sections'
    kinks are where the two boundaries cross and where the circle's edge is."""
    def span(u):
        a, b = _half_chord(radius, u - cx), _half_chord(r, u - x)
        return max(cz - a, z - b), min(cz + a, z + b)

    d = math.hypot(x - cx, z - cz)
    kinks = [cx - radius, cx + radius]
    if abs(radius - r) < d < radius + r:  # the crossings of the two circles
        along = (d * d + radius * radius - r * r) / (2.0 * d)
        across = math.sqrt(radius * radius - along * along)
        ux, uz = (x - cx) / d, (z - cz) / d
        kinks += [cx + along * ux - across * uz, cx + along * ux + across * uz]
    return _area_by_chords(max(cx - radius, x - r), min(cx + radius, x + r), span, kinks)


def _love_weber_moments(snap, walls):
    """M_p = sum over grain p's contacts of f (x) (x_c - x_p), written from the definitions of
    docs/measurements.md: the force on j is F_n n + F_s t (n from i to j, t = (-n_y, n_x)),
    the contact point of a pair is x_i + (r_i - overlap/2) n, that of a wall contact the
    closest point of the wall segment; built from the engine's raw contact state (F_n, F_s)
    one contact at a time."""
    g, c, w = snap.particles, snap.contacts, snap.wall_contacts
    x, z, r = g["x"], g["y"], g["radius"]
    moments = np.zeros((x.size, 2, 2))
    for i, j, fn, fs in zip(c["i"], c["j"], c["fn"], c["fs"]):
        branch = np.array([x[j] - x[i], z[j] - z[i]])
        d = math.hypot(*branch)
        n = branch / d
        f_on_j = fn * n + fs * np.array([-n[1], n[0]])
        point = np.array([x[i], z[i]]) + (r[i] - 0.5 * (r[i] + r[j] - d)) * n
        moments[j] += np.outer(f_on_j, point - (x[j], z[j]))
        moments[i] += np.outer(-f_on_j, point - (x[i], z[i]))
    for p, k, fx, fz in zip(w["grain"], w["wall"], w["fx"], w["fy"]):
        a, b = np.array([walls.ax[k], walls.ay[k]]), np.array([walls.bx[k], walls.by[k]])
        centre = np.array([x[p], z[p]])
        s = np.clip(np.dot(centre - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
        moments[p] += np.outer((fx, fz), a + s * (b - a) - centre)
    return moments


def _sym(m):
    return -np.array([m[0, 0], m[1, 1], 0.5 * (m[0, 1] + m[1, 0])])


def test_recorded_circles_and_band_equal_a_recount_from_the_raw_contacts(runs):
    """At the sample where the flow snapshot was taken (the recorder's row of that time), every
    circle's count, coordination number, porosity and stress and the junction band's numbers
    equal a recount written here from the definitions (docs/measurements.md) over the
    snapshot's grains and the engine's raw contact forces: centres inside counted one by one,
    contacts per grain tallied from the contact lists, the grains' area inside each circle and
    the circle's area inside the silo as integrals of chord lengths (adaptive quadrature, error
    ~1e-10; the recorder's area inside the silo is a grid quadrature documented to 1e-4), the
    Love-Weber moments one contact at a time. The recorder takes all of this through
    ``read_simulation``, ``circle_measure`` and ``region_stress``."""
    cfg, _, measured = runs
    rec = next(r for r in measured.recorders if isinstance(r, MeasureRecorder))
    snap = rec.flow.snapshot
    row = int(np.flatnonzero(np.array(rec.rows)[:, 0] == snap.time)[0])
    got = {k: v[row] for k, v in rec.circles.arrays().items()}
    g = snap.particles
    x, z, r = g["x"], g["y"], g["radius"]
    counts = np.zeros(x.size, int)
    np.add.at(counts, snap.contacts["i"], 1)
    np.add.at(counts, snap.contacts["j"], 1)
    np.add.at(counts, snap.wall_contacts["grain"], 1)
    moments = _love_weber_moments(snap, measured.walls)
    for k, circle in enumerate(rec.circles.circles):
        inside = np.hypot(x - circle.x, z - circle.z) < circle.radius
        assert got["count"][k] == inside.sum() > 10
        assert got["coordination"][k] == pytest.approx(counts[inside].mean(), rel=1e-12)
        near = np.flatnonzero(np.hypot(x - circle.x, z - circle.z) < circle.radius + r)
        solid = sum(_lens(circle.x, circle.z, circle.radius, x[p], z[p], r[p]) for p in near)
        # the circle's area inside the silo is a grid quadrature, documented to 1e-4
        exact_area = _circle_area_in_hopper(cfg, circle.x, circle.z, circle.radius)
        assert circle.area_inside == pytest.approx(exact_area, rel=1e-4)
        assert (1.0 - got["porosity"][k]) * circle.area_inside == pytest.approx(solid, rel=1e-9)
        # stress / (1 - n): the sum of the moments over the grains' area, without quadrature
        solid_area = np.sum(np.pi * r[inside] ** 2) * cfg.material.thickness
        np.testing.assert_allclose(got["stress"][k] / (1.0 - got["porosity"][k]),
                                   _sym(moments[inside].sum(axis=0)) / solid_area,
                                   rtol=1e-9, atol=1e-9 * np.abs(got["stress"][k]).max())
    lo, hi = rec.circles.band
    s = cfg.silo
    slope = math.tan(math.radians(s.hopper_angle_from_horizontal_deg))
    junction = 0.5 * (s.cell_width - s.outlet_width) * slope

    def area_below(height):  # trapezoid of the hopper, then the rectangle of the cell
        zh = min(max(height, 0.0), junction)
        return ((s.outlet_width + zh / slope) * zh
                + s.cell_width * max(height - junction, 0.0))

    band = (z >= lo) & (z < hi)
    assert got["band"][1] == band.sum() > 10
    assert got["band"][0] == pytest.approx(counts[band].mean(), rel=1e-12)
    band_area = (area_below(hi) - area_below(lo)) * cfg.material.thickness
    np.testing.assert_allclose(got["band"][2:], _sym(moments[band].sum(axis=0)) / band_area,
                               rtol=1e-9, atol=1e-9 * np.abs(got["band"][2:]).max())


def test_recorded_mean_stress_is_compressive(runs):
    """Contacts carry no tension (F_n >= 0), the shear force is perpendicular to the branch
    vector, so each contact adds F_n |l| >= 0 to the trace of the Love-Weber sum: the mean
    stress of every circle and of the band, at every sample, is >= 0 (exactly, not on
    average)."""
    rec = next(r for r in runs[2].recorders if isinstance(r, MeasureRecorder))
    a = rec.circles.arrays()
    trace = a["stress"][:, :, 0] + a["stress"][:, :, 1]
    assert np.all(trace[np.isfinite(trace)] >= 0) and np.isfinite(trace).sum() > 100
    band_trace = a["band"][:, 2] + a["band"][:, 3]
    assert np.all(band_trace[np.isfinite(band_trace)] >= 0)


def test_every_grain_that_left_has_an_exit_time_and_no_other(runs):
    """Book-keeping of the discharge: of the grains present when the gate opened, the ones
    still in the silo (above the outlet, z >= 0) at the end of the run have no exit time, and
    every grain the run removed (below z = -4 r_max) has one: it crossed z = 0 at least one
    sample before, as falling 4 r_max from rest takes sqrt(8 r_max / g), longer than a
    sample interval. So the grains with an exit time hold at least the discharged fraction of
    the mass (the run's particle arrays and its events are the reference)."""
    cfg, _, measured = runs
    rec = next(r for r in measured.recorders if isinstance(r, MeasureRecorder))
    f = rec.flow
    left = np.isfinite(f.exit_time)
    p = measured.sim.particles
    in_silo = p.view("uid")[p.view("y") >= 0.0]  # below the outlet counts as gone
    at_end = np.isin(f.uid0, in_silo)
    assert not np.any(left & at_end)
    interval = np.diff([row[0] for row in rec.rows]).max()
    assert interval < math.sqrt(8 * cfg.material.radius_max / cfg.gravity)
    mass_left = np.sum(f.r0[left] ** 2) / np.sum(f.r0**2)  # same rho, t for every grain
    assert mass_left >= measured.events["discharged_fraction"] >= cfg.discharge.stop_fraction
    # the ones that left after the last sample are the only ones without a time
    last = rec.rows[-1][0]
    assert f.exit_time[left].max() <= last - f.t_open + 1e-12


def test_a_sampling_interval_under_the_time_step_is_warned_of_before_the_run():
    """`--set measure.interval=1e-300` measured at every step of a quick case, 25 times slower
    and with a results.h5 38 times larger, without a word.  An interval under the time step
    is warned of with the most samples the phase time limits allow (68 s / dt for
    paper-case2); the shipped scenarios draw no such warning."""
    from types import SimpleNamespace

    from silodem.scenario_files import load_config, scenario_names
    from silodem.silo.checks import check_numbers
    from silodem.silo.recorders import TimeSeries

    def warnings(cfg):
        run = SimpleNamespace(cfg=cfg, dt=check_numbers(cfg)[0])
        recorders = (MeasureRecorder(cfg), TimeSeries(cfg.output.sample_interval))
        return [w for rec in recorders if (w := rec.volume_warning(run))]

    for name in scenario_names():
        assert warnings(load_config(name)) == [], name
    cfg = load_config("paper-case2", ["measure.interval=1e-300", "output.sample_interval=1e-9"])
    dt = check_numbers(cfg)[0]
    said = warnings(cfg)
    assert [w.split(" = ")[0] for w in said] == ["measure.interval", "output.sample_interval"]
    assert said[0].startswith(f"measure.interval = 1e-300 s is shorter than the time step "
                              f"{dt:.3g} s: sampled at every step, up to {68.0 / dt:.3g} "
                              "samples in 68 s of simulated time")
    at_dt = load_config("paper-case2", [f"measure.interval={dt!r}"])
    assert warnings(at_dt) == []  # one sample a step, as asked
