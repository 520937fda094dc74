"""Exit times and the grains lost before the discharge (``measure.recorders``' flow part), on
a hand-made sequence of readings whose answers are worked out here: which grain leaves at
which sample, which were never in the silo when the gate opened, and that state()/restore()
carries it all; and the dead-zone figure that draws them."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from measure_helpers import tiny_hopper_config

from silodem.measure.discharge import dead_zone
from silodem.measure.reading import Reading
from silodem.measure.recorders import _FlowPart
from silodem.silo.geometry import silo_shape

T_OPEN = 3.0  # [s]
R = 0.05  # [m]


def _reading(time, uid, x, z):
    """A reading of grains ``uid`` at (x, z) [m], at rest, without contacts."""
    n = len(uid)
    x, z = np.asarray(x, float), np.asarray(z, float)
    zeros, none = np.zeros(n), np.zeros(0)
    return Reading(float(time), 0, x, z, np.full(n, R), zeros, zeros, np.ones(n),
                   np.asarray(uid, np.int64), none.astype(np.int64), none.astype(np.int64),
                   none, none, none.astype(np.int64), none.astype(np.int64), none, none,
                   none, none, np.zeros((n, 2, 2)), zeros, none, none)


def _tiny():
    """The tiny hopper: B = 1.2 m, outlet 0.4 m wide at z = 0 (x from 0.4 to 0.8), hopper walls
    at 50 degrees from the horizontal up to z_j = 0.4 tan 50 = 0.477 m."""
    cfg = tiny_hopper_config()
    return cfg, silo_shape(cfg)


# uid: place at the gate opening (x, z) [m], and what happens to it
GRAINS = {
    10: (0.60, 0.50),   # stays, moves 0.03 m down then 0.04 m (its largest) and back
    11: (0.60, 0.10),   # above the outlet: below z = 0 at the 2nd sample -> leaves there
    12: (0.15, -0.04),  # pushed through the left hopper wall near its foot, under it: lost
    13: (-0.02, 1.50),  # pushed through the left wall while filling: lost
    14: (0.50, 0.20),   # gone (removed) at the 1st sample -> leaves there
    15: (0.10, 0.15),   # z = 0.15 m but x = 0.1 m: beyond the left hopper wall (which is at
                        # x = 0.4 (1 - 0.15 / 0.477) = 0.274 m there): lost
}


def _begin(flow):
    uid = np.array(list(GRAINS))
    x, z = np.array(list(GRAINS.values())).T
    flow.begin(T_OPEN, uid, x, z, np.full(uid.size, R), fill_level=1.2)


def _samples():
    """Three samples after the opening, at +0.02, +0.04, +0.06 s (before the discharge window
    of the tiny config, delay 0.2 s): the lost grains 12 and 13 are gone at once (the run
    removes them), or still there below the outlet; 14 is gone at the first."""
    return [
        _reading(T_OPEN + 0.02, [10, 11, 12, 15], [0.60, 0.60, 0.15, 0.10],
                 [0.47, 0.05, -0.06, 0.15]),
        _reading(T_OPEN + 0.04, [10, 11, 15], [0.60, 0.60, 0.10], [0.46, -0.01, 0.15]),
        _reading(T_OPEN + 0.06, [15, 10], [0.10, 0.60], [0.14, 0.49]),
    ]


def test_a_grain_pushed_out_is_a_centre_outside_the_silo():
    _, shape = _tiny()
    z_j = 0.4 * math.tan(math.radians(50.0))
    x_wall = 0.4 * (1 - 0.15 / z_j)  # the left hopper wall at z = 0.15 m
    # under the silo: over the outlet (0.4-0.8 m, 0.1 m of room) sunk into the gate, not
    # lost; under the hopper wall, lost
    got = shape.pushed_out([0.6, 0.6, 0.35, 0.2, 0.95, -0.02, 1.22, x_wall + 1e-6,
                            x_wall - 1e-6],
                           [0.0, -1e-9, -0.03, -1e-9, -0.03, 1.5, 1.5, 0.15, 0.15], 0.1)
    np.testing.assert_array_equal(got, [False, False, False, True, True, True, True, False,
                                        True])


def test_exit_times_skip_the_grains_lost_before_the_discharge():
    """Grains 11 and 14 leave (at +0.04 and +0.02 s); 10 stays and moved at most
    hypot(0, 0.04) = 0.04 m; 12, 13, 15 were outside the silo when the gate opened: flagged,
    with no exit time (not the first to leave at +0.02 s) and no displacement (NaN), so that
    the dead zone does not count them either."""
    cfg, shape = _tiny()
    flow = _FlowPart(cfg, shape)
    _begin(flow)
    for rd in _samples():
        flow.record(None, rd)
    order = list(GRAINS)
    np.testing.assert_array_equal(flow.uid0, order)
    np.testing.assert_array_equal(flow.lost, [False, False, True, True, False, True])
    expected_exit = {10: np.nan, 11: 0.04, 12: np.nan, 13: np.nan, 14: 0.02, 15: np.nan}
    np.testing.assert_allclose(flow.exit_time, [expected_exit[u] for u in order],
                               rtol=0, atol=1e-12)
    expected_disp = {10: 0.04, 11: 0.05, 12: np.nan, 13: np.nan, 14: 0.0, 15: np.nan}
    np.testing.assert_allclose(flow.max_disp, [expected_disp[u] for u in order],
                               rtol=0, atol=1e-12)
    # the dead zone: grain 10 (never left, moved 0.04 m) is dead for a radius over 0.04 m,
    # and no lost grain is, whatever the radius
    np.testing.assert_array_equal(dead_zone(flow.exit_time, flow.max_disp, 0.045),
                                  [True, False, False, False, False, False])


def test_state_and_restore_carry_the_lost_grains_through_a_checkpoint():
    """A copy restored from state() after the first sample goes on exactly as the original;
    a checkpoint written before the flag existed (which gave the lost grains still there or
    below the outlet the first sample's time, +0.02 s, and a displacement of 0) gets the flag
    back from the places at the opening, and those grains' records undone."""
    cfg, shape = _tiny()
    a = _FlowPart(cfg, shape)
    _begin(a)
    first, *rest = _samples()
    a.record(None, first)
    state = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in a.state().items()}
    assert state["flow.lost"].dtype == bool
    b, c = _FlowPart(cfg, shape), _FlowPart(cfg, shape)
    b.restore(state)
    old = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in state.items()
           if k != "flow.lost"}
    old["flow.exit_time"][state["flow.lost"]] = 0.02
    old["flow.max_disp"][state["flow.lost"]] = 0.0
    c.restore(old)
    for rd in rest:
        for part in (a, b, c):
            part.record(None, rd)
    for part in (b, c):
        np.testing.assert_array_equal(part.lost, a.lost)
        np.testing.assert_array_equal(part.exit_time, a.exit_time)
        np.testing.assert_array_equal(part.max_disp, a.max_disp)


def test_results_file_holds_the_flag(tmp_path):
    import h5py

    cfg, shape = _tiny()
    flow = _FlowPart(cfg, shape)
    _begin(flow)
    for rd in _samples():
        flow.record(None, rd)
    with h5py.File(tmp_path / "m.h5", "w") as h5:
        flow.write(h5.create_group("measure"))
    with h5py.File(tmp_path / "m.h5") as h5:
        f = h5["measure/flow"]
        np.testing.assert_array_equal(f["lost_before_discharge"][()],
                                      [False, False, True, True, False, True])
        assert np.isnan(f["exit_time"][2]) and np.isnan(f["max_displacement"][2])
        assert f["exit_time"].attrs["unit"] == "s"


def _analysis(exit_time, max_disp, z0, lost=None, lost_later=None, poured=None):
    """The parts of an Analysis that fig_dead_zones reads, for grains on a row at z0 [m]
    (``poured``: /events n_poured; None: the grains on the row)."""
    n = len(exit_time)
    flow = {"uid": np.arange(n), "x0": np.linspace(0.2, 1.0, n), "z0": np.asarray(z0, float),
            "r0": np.full(n, R), "exit_time": np.asarray(exit_time, float),
            "max_displacement": np.asarray(max_disp, float)}
    if lost is not None:
        flow["lost_before_discharge"] = np.asarray(lost, bool)
    if lost_later is not None:
        flow["lost_during_discharge"] = np.asarray(lost_later, bool)
    walls = {"ax": np.zeros(1), "ay": np.zeros(1), "bx": np.zeros(1), "by": np.ones(1),
             "name": np.array(["left_wall"])}
    groups = {("measure", "flow"): flow, ("walls",): walls}
    res = SimpleNamespace(group=lambda *path: groups.get(path),
                          events={"n_poured": n if poured is None else poured})
    dead = dead_zone(flow["exit_time"], flow["max_displacement"], R)
    return SimpleNamespace(res=res, flow={"dead": dead, "dead_fraction": dead.mean()},
                           geom={"B": 1.2, "top": 2.4})


@pytest.mark.parametrize("with_flag", [True, False])
def test_dead_zone_figure_leaves_the_lost_grains_out_of_the_exit_times(with_flag):
    """Five grains: two left (0.2 and 0.3 s), one dead, two lost before the discharge.  The
    exit-time colours hold 0.2 and 0.3 s only; the lost grains are drawn as outlines and
    counted in the title.  A file written before the flag (its lost grains below the outlet
    then got the first sample's time, 0.019 s, and a displacement of 0) is read the same
    way, by z0 < 0."""
    from silodem.report.figures_flow import fig_dead_zones

    z0 = [0.5, 0.6, 0.7, -0.04, -0.03]
    if with_flag:
        a = _analysis([0.2, 0.3, np.nan, np.nan, np.nan], [0.5, 0.5, 0.0, np.nan, np.nan], z0,
                      lost=[False, False, False, True, True])
    else:
        a = _analysis([0.2, 0.3, np.nan, 0.019, 0.019], [0.5, 0.5, 0.0, 0.0, 0.0], z0)
    fig = fig_dead_zones(a)
    ax = fig.axes[0]
    coloured = [c for c in ax.collections if c.get_array() is not None]
    assert len(coloured) == 1
    np.testing.assert_array_equal(np.sort(coloured[0].get_array()), [0.2, 0.3])
    assert "dashed: 2 grains lost through a wall before the gate opened" in ax.get_title()
    # one collection of the lost grains, unfilled, with their centres
    outlines = [c for c in ax.collections if c.get_array() is None
                and len(c.get_facecolors()) == 0]
    assert len(outlines) == 1
    np.testing.assert_allclose(outlines[0].get_offsets()[:, 1], [-0.04, -0.03])


def test_the_dead_fraction_counts_only_the_grains_there_as_the_gate_opened():
    """Ten grains, two in the dead zone, three lost through a wall before the gate opened:
    2 of the 7 that were there (2/10 before, the lost ones counted as not dead)."""
    from silodem.measure.discharge import dead_fraction

    dead = np.array([1, 1, 0, 0, 0, 0, 0, 0, 0, 0], bool)
    lost = np.array([0, 0, 0, 0, 0, 0, 0, 1, 1, 1], bool)
    assert dead_fraction(dead, lost) == pytest.approx(2 / 7)
    assert dead_fraction(dead) == pytest.approx(2 / 10)  # a file without the flag
    assert np.isnan(dead_fraction(dead[:0], lost[:0]))
    assert np.isnan(dead_fraction(dead[7:], lost[7:]))  # every grain lost


def test_a_grain_under_the_floor_beside_the_outlet_has_not_left_and_is_lost_when_told():
    """After the opening, grain 10 is seen under the silo at x = 0.15 m (under the left
    hopper wall: the outlet spans 0.4-0.8 m, and 2 largest radii of room, 0.11 m, reach only
    0.29 m): pushed through the wall, not discharged, so it has no exit time although its
    centre is below z = 0; grain 11 under the outlet's edge (x = 0.35 m, within the room) has
    left.  When the run removes grain 10 as lost (``lose``), it is flagged, its displacement
    is undone (NaN) and it is followed no more, absent or not; a grain that had left keeps
    its exit time even if told (14), as do the grains never told."""
    cfg, shape = _tiny()
    flow = _FlowPart(cfg, shape)
    _begin(flow)
    flow.record(None, _reading(T_OPEN + 0.02, [10, 11, 15], [0.15, 0.35, 0.10],
                               [-0.01, -0.01, 0.15]))
    order = list(GRAINS)
    i10, i11, i14 = order.index(10), order.index(11), order.index(14)
    assert np.isnan(flow.exit_time[i10])
    assert flow.exit_time[i11] == pytest.approx(0.02)
    assert flow.max_disp[i10] == pytest.approx(math.hypot(0.60 - 0.15, 0.51))
    flow.lose(np.array([10]))
    assert flow.lost_later.tolist() == [u == 10 for u in order]
    assert np.isnan(flow.exit_time[i10]) and np.isnan(flow.max_disp[i10])
    flow.record(None, _reading(T_OPEN + 0.04, [15], [0.10], [0.15]))  # 10 is gone now
    assert np.isnan(flow.exit_time[i10])
    assert flow.exit_time[i14] == pytest.approx(0.02)  # absent from the first sample
    state = flow.state()
    again = _FlowPart(cfg, shape)
    again.restore(state)
    np.testing.assert_array_equal(again.lost_later, flow.lost_later)
    del state["flow.lost_later"]  # a checkpoint written before the flag: none lost later
    again.restore(state)
    assert not again.lost_later.any() and again.lost_later.size == len(order)


def test_told_of_losses_before_the_gate_opens_the_flow_part_keeps_nothing():
    """Grains lost while filling are gone before the opening: the flow part follows none yet,
    so being told of them changes nothing (it has no grains)."""
    cfg, shape = _tiny()
    flow = _FlowPart(cfg, shape)
    flow.lose(np.array([1, 2]))
    assert flow.lost_later.size == 0 and flow.uid0.size == 0


def test_the_dead_zone_map_names_the_grains_lost_before_and_after_the_gate_opened():
    """Five grains: one left (0.2 s), one dead, one lost before the opening (below the floor)
    and two lost through a wall after it (never given an exit time): all three outlined,
    none coloured, the title counts each kind."""
    from silodem.report.figures_flow import fig_dead_zones, lost_note

    a = _analysis([0.2, np.nan, np.nan, np.nan, np.nan], [0.5, 0.0, np.nan, np.nan, np.nan],
                  [0.5, 0.6, -0.04, 0.3, 0.4], lost=[False, False, True, False, False],
                  lost_later=[False, False, False, True, True])
    ax = fig_dead_zones(a).axes[0]
    assert ("dashed: 3 grains lost through a wall: 1 before the gate opened, 2 after"
            in ax.get_title())
    outlines = [c for c in ax.collections if c.get_array() is None
                and len(c.get_facecolors()) == 0]
    np.testing.assert_allclose(outlines[0].get_offsets()[:, 1], [-0.04, 0.3, 0.4])
    assert lost_note(0, 1) == "1 grain lost through a wall after the gate opened"


@pytest.mark.parametrize("lost_here", [True, False])
def test_the_dead_zone_map_counts_the_grains_gone_before_the_gate_opened(lost_here):
    """paper-case1 --quick lost 71 of its 166 grains, 65 of them before the gate opened (101
    in the silo then), yet its map said "8 grains lost through a wall": only those still in
    the silo at the opening are drawn.  The grains poured but no longer there (the closed
    gate lets none out) are counted apart: 9 poured, 5 on the map -> 4."""
    from silodem.report.figures_flow import fig_dead_zones

    lost = [False, False, True, False, False] if lost_here else None
    a = _analysis([0.2, np.nan, np.nan, 0.3, 0.4], [0.5, 0.0, np.nan, 0.5, 0.5],
                  [0.5, 0.6, 0.5, 0.3, 0.4], lost=lost, poured=9)
    title = fig_dead_zones(a).axes[0].get_title()
    if lost_here:
        assert title.endswith("\ndashed: 1 grain lost through a wall before the gate opened"
                              "\nmore: 4 grains fell out through a wall before the gate opened"
                              " (not drawn)"), title
    else:
        assert title.endswith("\n4 grains fell out through a wall before the gate opened "
                              "(not drawn)"), title
    none_gone = fig_dead_zones(_analysis([0.2, 0.3], [0.5, 0.5], [0.5, 0.6])).axes[0]
    assert "fell out" not in none_gone.get_title()


def test_lost_grains_reads_both_flags_and_older_files():
    """A file with both flags gives them as written; one without the later flag (written
    before it) has none lost later; one without either takes the grains below the outlet at
    the opening (z0 < 0) as lost before.  The dead fraction leaves both kinds out: one dead
    grain of the 2 that neither kind took."""
    from silodem.measure.discharge import dead_fraction, lost_grains

    z0 = np.array([0.5, -0.02, 0.4, 0.3])
    both = {"z0": z0, "lost_before_discharge": np.array([0, 0, 1, 0], bool),
            "lost_during_discharge": np.array([0, 0, 0, 1], bool)}
    before, during = lost_grains(both)
    assert before.tolist() == [False, False, True, False]
    assert during.tolist() == [False, False, False, True]
    before, during = lost_grains({"z0": z0, "lost_before_discharge": both[
        "lost_before_discharge"]})
    assert not during.any() and during.size == 4
    before, during = lost_grains({"z0": z0})
    assert before.tolist() == [False, True, False, False] and not during.any()
    dead = np.array([True, False, True, True])
    assert dead_fraction(dead, np.logical_or(*lost_grains(both))) == pytest.approx(1 / 2)


def test_a_grain_sunk_into_the_gate_falls_through_the_outlet_and_a_lost_one_is_lost_once():
    """A grain whose centre is under z = 0 over the outlet when the gate opens (sunk into the
    gate by soft contacts) is not lost: it leaves at the first sample, as the run counts it
    discharged.  A grain lost before the opening (12, under the hopper wall) that the run
    later removes as lost through a wall is not flagged a second time: one grain, one loss."""
    cfg, shape = _tiny()
    flow = _FlowPart(cfg, shape)
    uid = np.array([1, 2, 12])
    flow.begin(T_OPEN, uid, np.array([0.6, 0.6, 0.15]), np.array([0.5, -0.03, -0.04]),
               np.full(3, R), fill_level=1.2)
    assert flow.lost.tolist() == [False, False, True]
    flow.record(None, _reading(T_OPEN + 0.02, [1, 2, 12], [0.6, 0.6, 0.15],
                               [0.5, -0.08, -0.06]))
    assert flow.exit_time[1] == pytest.approx(0.02) and np.isnan(flow.exit_time[2])
    flow.lose(np.array([12]))
    assert flow.lost_later.tolist() == [False, False, False]
    from silodem.measure.discharge import lost_grains

    twice = {"z0": np.zeros(2), "lost_before_discharge": np.array([True, False]),
             "lost_during_discharge": np.array([True, True])}  # (a file written before)
    before, during = lost_grains(twice)
    assert before.tolist() == [True, False] and during.tolist() == [False, True]


def test_the_dead_zone_is_read_up_to_the_discharge_windows_end():
    """The tiny config's discharge window ends 0.2 + 0.3 = 0.5 s after the opening.  Grain 20
    creeps 0.03 m by then and is drawn 0.4 m down after it; 21 moves 0.06 m (more than
    R = 0.05 m) within the window; 22 stays within 0.01 m and leaves at +0.8 s.  Up to the
    window's end 20 and 22 are dead; over the whole discharge none is (the old reading, kept
    for a results.h5 without the window's record).  A checkpoint's copy goes on the same."""
    from silodem.report.analysis import _dead_zone

    cfg, shape = _tiny()
    places = {20: (0.60, 1.00), 21: (0.60, 1.20), 22: (0.60, 0.80)}
    uid = np.array(list(places))
    x, z = np.array(list(places.values())).T
    samples = [_reading(T_OPEN + 0.3, [20, 21, 22], [0.6, 0.6, 0.6], [0.98, 1.14, 0.79]),
               _reading(T_OPEN + 0.5, [20, 21, 22], [0.6, 0.6, 0.6], [0.97, 1.10, 0.80]),
               _reading(T_OPEN + 0.8, [20, 21], [0.6, 0.6], [0.60, 0.90])]
    flow, copy, old = (_FlowPart(cfg, shape) for _ in range(3))
    flow.begin(T_OPEN, uid, x, z, np.full(3, R), fill_level=1.3)
    flow.record(None, samples[0])  # (+0.3 s: before the snapshot in the window's middle)
    state = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in flow.state().items()}
    copy.restore(state)
    old.restore({k: v for k, v in state.items() if k != "flow.window_disp"})
    for part in (flow, copy, old):
        part.snapshot = "taken"  # (there is no run to take the snapshot of)
    for rd in samples[1:]:
        for part in (flow, copy, old):
            part.record(None, rd)
    np.testing.assert_allclose(flow.window_disp, [0.03, 0.10, 0.01], rtol=0, atol=1e-12)
    np.testing.assert_allclose(flow.max_disp, [0.40, 0.30, 0.01], rtol=0, atol=1e-12)
    np.testing.assert_allclose(flow.exit_time, [np.nan, np.nan, 0.8], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(copy.window_disp, flow.window_disp)
    np.testing.assert_array_equal(old.window_disp, flow.window_disp)  # = max_disp in the window
    np.testing.assert_array_equal(dead_zone(flow.exit_time, flow.window_disp, R, 0.5),
                                  [True, False, True])
    np.testing.assert_array_equal(dead_zone(flow.exit_time, flow.max_disp, R),
                                  [False, False, False])
    f = {"exit_time": flow.exit_time, "max_displacement": flow.max_disp,
         "max_displacement_window": flow.window_disp,
         "@attrs": {"window_start": 0.2, "window": 0.3}}
    dead, to = _dead_zone(f, R)
    assert dead.tolist() == [True, False, True] and to == "the discharge window's end"
    del f["max_displacement_window"]
    dead, to = _dead_zone(f, R)
    assert dead.tolist() == [False, False, False] and to == "the run's end"


def test_in_a_slow_mass_flow_a_grain_that_descends_less_than_a_radius_is_not_dead():
    """A column that has descended 0.15 m by the window's end: 150 kg through the outlet by
    t = 1.5 s (100 kg/s) over rho_b B t = 1000 x 2 x 0.5 kg per metre.  A wall grain of a
    mass flow moved 0.05 m, under a radius (0.1 m) but over a quarter of the descent
    (0.0375 m): not dead; one that moved 0.01 m is.  Without a bulk density the radius
    alone decides (a review: slow mass flows read as funnel flow)."""
    from types import SimpleNamespace

    from silodem.report.analysis import _dead_zone, mean_descent

    a = SimpleNamespace(rho_b=1000.0, geom={"B": 2.0, "t": 0.5})
    t, mass = np.array([0.0, 1.0, 2.0]), np.array([0.0, 100.0, 200.0])
    descent = mean_descent(t, mass, 1.5, a)
    assert descent == pytest.approx(0.15, rel=1e-12)
    f = {"exit_time": np.full(3, np.nan), "max_displacement": np.zeros(3),
         "max_displacement_window": np.array([0.05, 0.01, 0.2]),
         "@attrs": {"window_start": 0.5, "window": 1.0}}
    assert _dead_zone(f, 0.1, descent)[0].tolist() == [False, True, False]
    assert _dead_zone(f, 0.1)[0].tolist() == [True, True, False]
    assert mean_descent(t, mass, 1.5, SimpleNamespace(rho_b=np.nan, geom=a.geom)) == np.inf


def test_the_earliest_exit_colour_stands_apart_from_the_dead_zones_black():
    """The dead-zone map's black beside its exit-time colours: plasma began at a navy with a
    contrast of 1.4:1 against black.  Each colour of the map's scale has 3:1 or more, WCAG
    2.1's least for graphical objects (SC 1.4.11; contrast (L1 + 0.05) / (L2 + 0.05) of the
    relative luminances L of sRGB)."""
    from silodem.report.figures_flow import EXIT_CMAP

    def luminance(rgb):
        lin = [c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4 for c in rgb]
        return 0.2126 * lin[0] + 0.7152 * lin[1] + 0.0722 * lin[2]

    contrast = [(luminance(EXIT_CMAP(t)[:3]) + 0.05) / 0.05 for t in np.linspace(0, 1, 101)]
    assert min(contrast) >= 3.0
