"""A gate that slides open (``discharge.gate_speed``): its motion against kinematics, no grain
out before the opening is as wide as a grain or through the part still closed, the gate gone
once the outlet is clear, a checkpoint mid-slide that resumes bit-identical, and the
refusals of a gate that cannot work."""

from __future__ import annotations

import math

import numpy as np
import pytest
from reliability_helpers import quick_config, stop_and_restore
from test_input_errors import assert_names, refused

from silodem.silo.checks import check_numbers, estimate_overlap
from silodem.silo.geometry import GATE, GATE_CLEARANCE, GATE_GAP
from silodem.silo.procedure import SiloRun
from silodem.silo.recorders import take_snapshot

SPEED = 0.3  # [m/s]: paper-case2's outlet D = 1 m clears in 3.33 s


@pytest.fixture(scope="module")
def sliding():
    """paper-case2 --quick with the sliding gate, watched between chunks: the time, the
    gate's trailing end, and where each grain under the floor crossed z = 0 (free fall traced
    back, as a ballistic grain does)."""
    run = SiloRun(quick_config(f"discharge.gate_speed={SPEED}"))
    seen: list[tuple[float, bool, float, float, int]] = []
    g = run.cfg.gravity

    def watch(r: SiloRun) -> None:
        if r.state.phase != "discharge":
            return
        w = r.walls.index(GATE)
        p = r.sim.particles
        x, y, vx, vy = (p.view(k) for k in ("x", "y", "vx", "vy"))
        under = y < -r.cfg.material.radius_max
        s = (vy[under] + np.sqrt(vy[under] ** 2 + 2.0 * g * -y[under])) / g  # since z = 0
        crossed = x[under] + vx[under] * s  # x - vx (-s) back along the fall
        seen.append((r.sim.time, bool(r.walls.active[w]), float(r.walls.ax[w]),
                     float(crossed.max()) if crossed.size else -math.inf,
                     r.discharged_count))

    run.chunk_hooks.append(watch)
    run.run()
    return run, seen


def test_the_gate_slides_at_its_speed_and_is_gone_once_the_outlet_is_clear(sliding):
    run, seen = sliding
    shape, t0 = run.shape, run.events["discharge_start_time"]
    D = shape.outlet_right - shape.outlet_left
    assert run.events["gate_opening_time"] == pytest.approx(D / SPEED, rel=1e-12)
    sliding_rows = [(t, ax) for t, active, ax, _, _ in seen if active]
    assert sliding_rows, "the gate was removed at once"
    for t, ax in sliding_rows:  # x = x_left + v (t - t0), the one-step clock of each move
        assert ax == pytest.approx(shape.outlet_left + SPEED * (t - t0), abs=1e-9)
        assert ax < shape.outlet_right + SPEED * 0.06  # at most one check late
    gone = [t for t, active, *_ in seen if not active]
    assert gone and gone[0] - t0 == pytest.approx(D / SPEED, abs=0.06)
    w = run.walls.index(GATE)
    assert run.walls.ay[w] == -GATE_GAP * run.cfg.material.radius_min  # under the floor
    assert run.events["discharge_end_reason"] == "fraction"


def test_no_grain_leaves_before_the_opening_is_a_grain_wide_nor_where_the_gate_is(sliding):
    """The opening is v (t - t0) wide: a disk of diameter 2 r_min cannot pass before it is
    that wide (less the overlaps, under 1 % of r here). Every grain under the silo crossed
    z = 0 left of the gate's trailing end at that moment, which is left of it now (the room
    of a largest diameter for collisions in the falling stream)."""
    run, seen = sliding
    t0, m = run.events["discharge_start_time"], run.cfg.material
    first_out = min(t for t, *_, count in seen if count > 0)
    assert first_out - t0 >= 0.99 * 2.0 * m.radius_min / SPEED
    for _, active, ax, crossed, _ in seen:
        if active:
            assert crossed <= ax + 2.0 * m.radius_max


def test_mass_is_conserved_with_a_sliding_gate(sliding):
    run, _ = sliding
    m = run.cfg.material
    poured = run.radii[: run.events["n_poured"]]
    mass0 = m.density * math.pi * m.thickness * float(np.sum(poured**2))
    assert run.sim.particles.total_mass() + run.discharged_mass + run.state.lost_mass == \
        pytest.approx(mass0, rel=1e-12)


def test_a_checkpoint_while_the_gate_slides_resumes_bit_identical(sliding, tmp_path):
    ref, _ = sliding
    first, second = stop_and_restore(ref.cfg, "discharge", tmp_path / "checkpoint.h5")
    assert first.gate_sliding() and second.gate_sliding()
    w = first.walls.index(GATE)
    assert second.walls.ax[w] == first.walls.ax[w] and second.walls.vx[w] == SPEED
    second.run()
    assert np.array(second.series.rows).tobytes() == np.array(ref.series.rows).tobytes()
    assert second.events == ref.events
    for key, arr in ref.snapshots["final"].particles.items():
        assert arr.tobytes() == second.snapshots["final"].particles[key].tobytes(), key


@pytest.mark.parametrize(("sets", "needles"), [
    (["discharge.gate_speed=1e6"], ("discharge.gate_speed", "more than material.radius_min")),
    (["discharge.gate_speed=0.01", "discharge.max_time=50"],
     ("discharge.max_time = 50 s", "100 s")),
    (["discharge.gate_speed=0.5", 'silo.kind="flat"', "material.kn=1e5", "walls.kn=1e5"],
     ("sliding gate", "expected overlaps", "0.5 material.radius_min")),
    (["discharge.gate_speed=0"], ("discharge.gate_speed",)),
])
def test_a_gate_that_cannot_work_is_refused_in_one_line(capsys, tmp_path, sets, needles):
    args = ["run", "paper-case2", "--out", str(tmp_path / "out")]
    for s in sets:
        args += ["--set", s]
    assert_names(refused(capsys, *args, silent=True), *needles)
    assert not (tmp_path / "out").exists()


def test_results_keep_the_gate_where_it_closed_the_outlet(sliding, tmp_path):
    """results.h5 /walls is the silo as built (frames draw the closed gate from it), not the
    slid gate at the end of the run."""
    import h5py

    from silodem.output import write_results

    run, _ = sliding
    write_results(run, tmp_path / "results.h5", "")
    with h5py.File(tmp_path / "results.h5", "r") as h5:
        names = [n.decode() for n in h5["walls/name"][()]]
        w = names.index(GATE)
        depth = -GATE_GAP * run.cfg.material.radius_min
        assert (h5["walls/ax"][w], h5["walls/bx"][w]) == (run.shape.outlet_left,
                                                          run.shape.outlet_right)
        assert h5["walls/ay"][w] == h5["walls/by"][w] == depth
        assert not h5["walls/active"][w]
    assert run.walls.ax[run.walls.index(GATE)] >= run.shape.outlet_right  # it did slide


def test_the_animation_draws_the_gate_where_it_has_slid(tmp_path):
    """A whole run's frames: while the gate slides, its line lies v (t - t0) right of the
    closed gate (v the config's gate_speed); before the discharge, over the outlet."""
    from silodem.run import run_simulation
    from silodem.silo.frames import read_frames
    from silodem.viz.draw import FrameArtist

    cfg = quick_config(f"discharge.gate_speed={SPEED}", "output.png=false",
                       "output.vtk_interval=0.5")
    run_simulation(cfg, tmp_path / "run", progress=False)
    frames = read_frames(tmp_path / "run" / "results.h5")
    k = frames.walls.names.index(GATE)
    left, right = float(frames.walls.ax[k]), float(frames.walls.bx[k])
    t0 = frames.events["discharge_start_time"]
    artist = FrameArtist(frames, "none")
    checked = {"settle": 0, "discharge": 0}
    for frame in frames:
        if frame.phase not in checked or not frame.walls_active[k]:
            continue
        artist.draw(frame)
        dx = SPEED * (frame.time - t0) if frame.phase == "discharge" else 0.0
        np.testing.assert_allclose(artist.wall_lines[k].get_xdata(), [left + dx, right + dx],
                                   rtol=0, atol=1e-9)
        # force lines end on the gate where it is: under the grain, within the slid segment
        on_gate = frame.wall_contacts["wall"] == k
        g = frame.wall_contacts["grain"][on_gate]
        x = frame.particles["x"][g].astype(float)
        y = frame.particles["y"][g].astype(float)
        wx, wy = frames.walls.closest_points(np.full(g.size, k), x, y,
                                             frames.wall_shift(frame.time))
        np.testing.assert_allclose(wx, np.clip(x, left + dx, right + dx), rtol=0, atol=1e-9)
        np.testing.assert_allclose(wy, frames.walls.ay[k], rtol=0, atol=1e-12)
        checked[frame.phase] += 1
    assert checked["settle"] and checked["discharge"] >= 10  # 3.3 s of slide, 0.1 s frames
    # the VTK walls likewise (their points: a, b of each segment in turn)
    import xml.etree.ElementTree as ET

    import meshio

    vtk = tmp_path / "run" / "vtk"
    sliding_files = 0
    for entry in ET.parse(vtk / "walls.pvd").getroot().iter("DataSet"):
        t = float(entry.get("timestep"))
        mesh = meshio.read(vtk / entry.get("file"))
        if t <= t0 or not mesh.cell_data["active"][0][k]:
            continue
        dx = SPEED * (t - t0)
        np.testing.assert_allclose(mesh.points[2 * k: 2 * k + 2, 0], [left + dx, right + dx],
                                   rtol=0, atol=1e-9)
        sliding_files += 1
    assert sliding_files >= 3
    # the report's pictures of the discharge window (Figs. 4, 5, the fields): the snapshot in
    # its middle, 0.5 + 0.5 s after the opening, has the gate in place, 0.3 m along
    from silodem.report.draw import walls_at
    from silodem.report.load import load_results

    res = load_results(tmp_path / "run")
    snap = res.snapshot("discharge")
    t, active = float(snap["@attrs"]["time"]), np.asarray(snap["walls_active"], dtype=bool)
    assert active[k] and t - t0 == pytest.approx(1.0, abs=0.05)
    moved = walls_at(res.group("walls"), res.events, t, active)
    assert moved["ax"][k] == pytest.approx(left + SPEED * (t - t0), abs=1e-9)
    assert moved["bx"][k] == pytest.approx(right + SPEED * (t - t0), abs=1e-9)
    others = np.arange(len(moved["ax"])) != k
    np.testing.assert_array_equal(moved["ax"][others], res.group("walls")["ax"][others])
    settled = res.snapshot("settled")
    assert walls_at(res.group("walls"), res.events, float(settled["@attrs"]["time"]),
                    settled["walls_active"]) is res.group("walls")  # closed: as built


@pytest.mark.parametrize("stiffness", [None, 1.1e6], ids=["stiff", "soft"])
def test_under_a_flat_floor_the_gate_never_touches_a_grain_resting_on_the_floor(stiffness):
    """A flat silo: the gate runs under the right-hand floor. At every check of the slide no
    grain centred over the floor (more than a largest radius beyond the outlet's edge)
    touches it. With soft contacts (k = 1.1e6 N/m: the largest floor overlap is some 0.014 m
    against an estimate of 0.0036 m) the gate runs GATE_CLEARANCE estimates deep, not
    GATE_GAP r_min = 0.009 m, which such grains reached."""
    sets = [f"discharge.gate_speed={SPEED}", 'silo.kind="flat"']
    if stiffness is not None:
        sets += [f"{s}.{k}={stiffness}" for s in ("material", "walls") for k in ("kn", "ks")]
    cfg = quick_config(*sets)
    check_numbers(cfg)  # accepted
    run = SiloRun(cfg)
    m = cfg.material
    depth = max(GATE_GAP * m.radius_min, GATE_CLEARANCE * estimate_overlap(cfg).overlap)
    w = run.walls.index(GATE)
    assert run.walls.ay[w] == pytest.approx(-depth, rel=1e-12)
    floor = [run.walls.index("left_floor"), run.walls.index("right_floor")]
    deepest, checks = 0.0, 0

    def watch(r: SiloRun) -> None:
        nonlocal deepest, checks
        if not r.gate_sliding():
            return
        snap = take_snapshot(r)
        wc, x = snap.wall_contacts, snap.particles["x"]
        over_floor = (x > r.shape.outlet_right + m.radius_max) | (
            x < r.shape.outlet_left - m.radius_max)
        on_gate = (wc["wall"] == w) & (wc["fn"] > 0)
        assert not np.any(over_floor[wc["grain"][on_gate]])
        on_floor = np.isin(wc["wall"], floor)
        y, rad = snap.particles["y"], snap.particles["radius"]
        g = wc["grain"][on_floor]
        g = g[over_floor[g]]  # (the overlap r - y of a face contact, not an edge's)
        deepest = max(deepest, float(np.max(rad[g] - y[g], initial=0.0)))
        checks += 1

    run.chunk_hooks.append(watch)
    run.run()
    assert checks >= 50  # 3.3 s of slide, 0.05 s apart
    assert 0.0 < deepest < depth  # grains press into the floor, not down to the gate


def test_a_window_that_begins_mid_slide_warns_and_a_gate_without_discharge_stays_put():
    """The discharge window begins measure.discharge_delay = 0.5 s after the gate begins to
    slide, before the outlet is clear (1 m / 0.3 m/s = 3.33 s): a warning; from 3.4 s on, none.
    Without a discharge the gate never slides and stays at z = 0, as the paper's."""
    early = SiloRun(quick_config(f"discharge.gate_speed={SPEED}")).warnings
    assert any("before the outlet is clear at 3.33 s" in w and ">= 3.34 s" in w for w in early)
    late = SiloRun(quick_config(f"discharge.gate_speed={SPEED}",
                                "measure.discharge_delay=3.4")).warnings
    assert not any("outlet is clear" in w for w in late)
    idle = SiloRun(quick_config(f"discharge.gate_speed={SPEED}", "discharge.enabled=false"))
    w = idle.walls.index(GATE)
    assert idle.walls.ay[w] == idle.walls.by[w] == 0.0


def test_pictures_of_a_snapshot_draw_the_gate_and_its_force_lines_where_it_stood():
    """settled.png, final.png and Figs. 4-5 (``draw_force_network``): a snapshot 2 s into a
    slide of a 1 m gate over 4 s has the gate 0.5 m along, and a grain at x = 1.7 over it is
    joined to it straight below; once the gate is out (inactive) it is drawn where it was
    (as built, [0.5, 1.5]: the nearest point is its end)."""
    from matplotlib.figure import Figure

    from silodem.report.draw import draw_force_network

    walls = {"name": np.array([b"left_floor", b"gate"]), "ax": np.array([0.0, 0.5]),
             "ay": np.array([0.0, -0.01]), "bx": np.array([0.5, 1.5]),
             "by": np.array([0.0, -0.01]), "active": np.array([True, False])}
    events = {"discharge_start_time": 10.0, "gate_opening_time": 4.0}
    grain = {"x": np.array([1.7]), "y": np.array([0.08]), "radius": np.array([0.1])}
    empty = {"i": np.zeros(0, int), "j": np.zeros(0, int), "fn": np.zeros(0)}
    for active, gate_x, end_x in ((True, [1.0, 2.0], 1.7), (False, [0.5, 1.5], 1.5)):
        snap = {"particles": grain, "contacts": empty, "@attrs": {"time": 12.0},
                "walls_active": np.array([True, active]),
                "wall_contacts": {"grain": np.array([0]), "wall": np.array([1]),
                                  "fn": np.array([50.0])}}
        ax = Figure().subplots()
        lines, _ = draw_force_network(ax, snap, walls, events=events)
        gate = [ln for ln in ax.get_lines() if list(ln.get_ydata()) == [-0.01, -0.01]]
        assert [list(ln.get_xdata()) for ln in gate] == [gate_x]
        np.testing.assert_allclose(lines.get_segments()[0][1], (end_x, -0.01), atol=1e-12)


@pytest.mark.parametrize("clear", [0.0, 10.0 / 3.0])
def test_the_discharge_rate_figure_marks_when_a_sliding_gate_cleared_the_outlet(clear):
    """A gate sliding at 0.3 m/s across a 1 m outlet clears it 3.33 s after it began to move
    (event gate_opening_time): the figure's two panels mark that moment, and its time axis
    counts from the beginning of the slide. A gate withdrawn at once has no mark."""
    from types import SimpleNamespace

    from silodem.measure.discharge import flow_rate_series, steady_rate
    from silodem.report.figures_flow import fig_discharge_rate

    t = np.linspace(0.0, 8.0, 161)
    mass = np.clip(t - clear, 0.0, None) * 100.0  # 100 kg/s once the outlet is clear
    events = {"gate_opening_time": clear} if clear else {}
    a = SimpleNamespace(res=SimpleNamespace(events=events),
                        flow={"t": t, "mass": mass, "rate": steady_rate(t, mass),
                              "series": flow_rate_series(t, mass)})
    ax1, ax2 = fig_discharge_rate(a).axes
    for ax in (ax1, ax2):
        marks = [line.get_xdata()[0] for line in ax.get_lines() if line.get_linestyle() == "--"]
        assert marks == ([pytest.approx(clear, rel=1e-12)] if clear else [])
    labels = [text.get_text() for text in ax2.get_legend().get_texts()]
    assert ("outlet clear: the sliding gate open" in labels) == bool(clear)
    assert ax2.get_xlabel() == ("time since the gate began to open [s]" if clear else
                                "time since the gate opened [s]")


def test_the_steady_rate_line_is_the_least_squares_line_of_the_mass_it_fitted():
    """The discharge-rate figure's red line had the fit's slope but went through the mass at
    the interval's middle: with a discharge that speeds up and slows down it ran under the
    curve (up to 142 kg, 5 grains, in paper-case2 --quick).  It is numpy's least-squares line
    of the samples in the steady interval: its residuals there sum to zero."""
    from types import SimpleNamespace

    from silodem.measure.discharge import flow_rate_series, steady_rate
    from silodem.report.figures_flow import fig_discharge_rate

    t = np.linspace(0.0, 4.0, 201)
    mass = 100.0 * t + 40.0 * np.sin(3.0 * t) ** 2  # a rate that pulses about 100 kg/s
    rate = steady_rate(t, mass)
    a = SimpleNamespace(res=SimpleNamespace(events={}),
                        flow={"t": t, "mass": mass, "rate": rate,
                              "series": flow_rate_series(t, mass)})
    ax1 = fig_discharge_rate(a).axes[0]
    red = next(line for line in ax1.get_lines() if line.get_label().startswith("steady rate"))
    inside = (t >= rate.t0) & (t <= rate.t1)
    slope, intercept = np.polyfit(t[inside], mass[inside], 1)
    np.testing.assert_allclose(red.get_xdata(), [rate.t0, rate.t1], rtol=1e-12)
    np.testing.assert_allclose(red.get_ydata(), intercept + slope * red.get_xdata(),
                               rtol=1e-9)
