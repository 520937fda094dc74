"""Neighbour search against brute force, and contact history across list rebuilds."""

from __future__ import annotations

import numpy as np
import pytest
from physics_helpers import law

from silodem.engine.particles import Particles
from silodem.engine.simulation import Simulation
from silodem.engine.walls import Walls


def _random_grains(rng, n, box, rmin=0.05, rmax=0.12):
    p = Particles(8)
    p.add(rng.uniform(0, box, n), rng.uniform(0, box, n), rng.uniform(rmin, rmax, n), 1000.0)
    return p


def _box(size, k=1e5, mu=0.4):
    w = Walls()
    corners = [(0, 0), (size, 0), (size, size), (0, size)]
    for a, b, name in zip(corners, corners[1:] + corners[:1], ["floor", "right", "top", "left"]):
        w.add(name, a, b, k, k, mu)
    return w


def _brute_pairs(x, y, r, uid, extra):
    d2 = (x[:, None] - x[None, :]) ** 2 + (y[:, None] - y[None, :]) ** 2
    cut = r[:, None] + r[None, :] + extra
    i, j = np.nonzero(np.triu(d2 < cut**2, k=1))
    return {(min(a, b), max(a, b)) for a, b in zip(uid[i], uid[j])}


def _list_pairs(sim, mask=None):
    nb, uid = sim.neighbors, sim.particles.view("uid")
    i, j = nb.pair_i, nb.pair_j
    if mask is not None:
        i, j = i[mask], j[mask]
    return {(min(a, b), max(a, b)) for a, b in zip(uid[i], uid[j])}


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_verlet_list_equals_brute_force_on_random_polydisperse_grains(seed):
    rng = np.random.default_rng(seed)
    p = _random_grains(rng, 400, 4.0)
    sim = Simulation(p, Walls(), law(), dt=1e-4, gravity=0.0, skin=0.03)
    sim.neighbors.rebuild(p, sim.walls)
    brute = _brute_pairs(p.view("x"), p.view("y"), p.view("radius"), p.view("uid"), 0.03)
    assert _list_pairs(sim) == brute
    assert np.all(sim.neighbors.pair_i < sim.neighbors.pair_j)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_candidates_that_touch_at_the_build_come_first_and_give_the_branchs_bits(seed):
    """The pair loop evaluates each grain's first candidates (up to ``i_apart``) without a
    branch on the touch test, selecting zeros for one that does not touch.  Those must be
    exactly the grain's candidates that touch at the build (brute force), each group in index
    order; and evaluating them without the branch must give the same bits as with it (forces,
    torques, history), also for candidates that have come apart since the build."""
    from silodem.engine.contact import pair_forces

    rng = np.random.default_rng(seed)
    p = _random_grains(rng, 400, 4.0)  # area fraction ~0.57: many overlaps
    sim = Simulation(p, Walls(), law(1e5, mu=0.3, zeta=0.2), dt=1e-4, gravity=0.0, skin=0.03)
    nb = sim.neighbors
    nb.rebuild(p, sim.walls)
    x, y, r = p.view("x"), p.view("y"), p.view("radius")
    touching = 0
    for i in range(p.n):
        a, m, b = nb.i_start[i], nb.i_apart[i], nb.i_start[i + 1]
        assert a <= m <= b
        js = nb.pair_j[a:b]
        touch = np.hypot(x[js] - x[i], y[js] - y[i]) < r[i] + r[js]
        assert np.all(touch[: m - a]) and not np.any(touch[m - a:])
        assert np.all(np.diff(js[: m - a]) > 0) and np.all(np.diff(js[m - a:]) > 0)
        touching += m - a
    assert touching > 200
    # shake the grains so that some contacts open and others form since the build, and give
    # every candidate a shear history and every grain a velocity and spin
    for name, scale in (("x", 0.01), ("y", 0.01), ("vx", 0.5), ("vy", 0.5), ("omega", 5.0)):
        p.view(name)[:] += rng.normal(0.0, scale, p.n)
    history = rng.normal(0.0, 1.0, nb.pair_j.size)
    blocks = np.array([0, nb.strip_start.size - 1], dtype=np.int32)

    def forces(i_apart):
        fs, fn = history.copy(), np.zeros(history.size)
        pair_forces.serial(nb.strip_start, blocks, nb.i_start, i_apart, nb.pair_j, fs, fn,
                           p.x, p.y, p.vx, p.vy, p.omega, p.radius, p.inv_mass, p.fx, p.fy,
                           p.torque, sim.law.kn, sim.law.ks, sim.law.mu, sim.law.zeta,
                           sim.law.allow_tension, sim.dt)
        return [a.copy() for a in (p.fx, p.fy, p.torque)] + [fs, fn]

    without_branch = forces(nb.i_apart)
    with_branch = forces(nb.i_start[:-1].copy())  # every candidate behind the branch
    for a, b in zip(without_branch, with_branch):
        assert np.array_equal(a, b)
    fn = without_branch[-1]
    first = np.zeros(fn.size, dtype=bool)
    for i in range(p.n):
        first[nb.i_start[i]:nb.i_apart[i]] = True
    assert np.count_nonzero(first & (fn == 0)) > 10  # came apart: zeros selected
    assert np.count_nonzero(~first & (fn != 0)) > 10  # formed since the build


@pytest.mark.parametrize("seed", [0, 1])
def test_strips_make_the_pair_loop_race_free(seed):
    """The pair loop runs strips of one parity at once; that is race-free only if every pair
    has its second grain in the first grain's strip or the next one (so strip s writes to s and
    s + 1 only).  Checked on every pair of a random packing with many strips; the strips must
    also tile the grains, cut at cell-row boundaries, and hold similar numbers of grains."""
    from silodem.engine.cells import STRIPS

    rng = np.random.default_rng(seed)
    p = _random_grains(rng, 6000, 20.0)
    sim = Simulation(p, Walls(), law(), dt=1e-4, gravity=0.0, skin=0.03)
    nb = sim.neighbors
    nb.rebuild(p, sim.walls)
    starts = nb.strip_start
    assert starts[0] == 0 and starts[-1] == p.n and np.all(np.diff(starts) >= 0)
    assert 2 * STRIPS // 3 < starts.size - 1 <= STRIPS
    sizes = np.diff(starts)
    assert sizes.max() < 2.5 * p.n / STRIPS  # about equal: rows hold ~p.n / 170 grains here
    strip = np.searchsorted(starts, np.arange(p.n), side="right") - 1
    step = strip[nb.pair_j] - strip[nb.pair_i]
    assert set(np.unique(step)) <= {0, 1}
    assert np.count_nonzero(step) > 100  # pairs across strip boundaries were tested
    # cut at row boundaries: no two grains of one cell row in different strips
    y = p.view("y")
    row = np.floor((y - y.min()) / (2.0 * p.view("radius").max() + nb.skin)).astype(int)
    assert np.all(np.diff(row) >= 0)  # sorted row-major
    assert np.all(row[starts[1:-1] - 1] < row[starts[1:-1]])


@pytest.mark.parametrize("threads", [1, 2, 3, 7])
def test_thread_blocks_cut_the_strips_nearest_to_equal_work(threads):
    """Each thread gets a run of consecutive strips; the cut between runs k - 1 and k must be
    a strip boundary whose work so far (grains + PAIR_WORK x candidates) is nearest to
    k / threads of the total, found here by trying every boundary."""
    from silodem.engine.cells import PAIR_WORK, thread_blocks

    rng = np.random.default_rng(threads)
    n_strips = 40
    grains = rng.integers(0, 30, n_strips)
    grains[5:9] = 0  # empty strips: cuts may coincide, runs may be empty
    strip_start = np.concatenate(([0], np.cumsum(grains))).astype(np.int32)
    candidates = rng.integers(0, 4, strip_start[-1])
    candidates[: strip_start[20]] *= 3  # a packed lower half
    i_start = np.concatenate(([0], np.cumsum(candidates))).astype(np.int32)
    blocks = thread_blocks(strip_start, i_start, threads)
    work = strip_start + PAIR_WORK * i_start[strip_start]
    assert blocks[0] == 0 and blocks[-1] == n_strips and blocks.size == threads + 1
    assert np.all(np.diff(blocks) >= 0)
    for k in range(1, threads):
        target = work[-1] * k / threads
        best = min(abs(work[b] - target) for b in range(1, n_strips + 1))
        assert abs(work[blocks[k]] - target) == best


def test_pair_loop_and_leapfrog_give_the_same_bits_for_any_runs_of_strips():
    """The strips may be cut into runs (one per thread) anywhere, runs starting at odd strips
    included: every grain must still get its force terms in the same order, so the forces,
    the history and the moved grains are the same bits as with one run."""
    from silodem.engine.contact import pair_forces
    from silodem.engine.integrate import walls_and_leapfrog

    rng = np.random.default_rng(5)
    p = _random_grains(rng, 3000, 12.0, rmin=0.08, rmax=0.14)
    sim = Simulation(p, _box(12.0), law(1e5, mu=0.4, zeta=0.2), dt=1e-4, skin=0.03)
    sim.run(20)  # contacts with shear history
    nb, w = sim.neighbors, sim.walls
    n_strips = nb.strip_start.size - 1
    assert n_strips > 30 and np.count_nonzero(nb.pair_fs) > 500
    names = ("x", "y", "vx", "vy", "omega", "fx", "fy", "torque")
    start = {name: p.view(name).copy() for name in names}
    start_fs = nb.pair_fs.copy()

    def one_step(blocks):
        for name in names:
            p.view(name)[:] = start[name]
        nb.pair_fs[:] = start_fs
        pair_forces.serial(nb.strip_start, blocks, nb.i_start, nb.i_apart, nb.pair_j,
                           nb.pair_fs, nb.pair_fn, p.x, p.y, p.vx, p.vy, p.omega, p.radius,
                           p.inv_mass, p.fx, p.fy, p.torque, sim.law.kn, sim.law.ks, sim.law.mu,
                           sim.law.zeta, sim.law.allow_tension, sim.dt)
        moved = walls_and_leapfrog.serial(
            nb.strip_start, blocks, nb.w_start, nb.wc_w, nb.wc_fs.copy(), nb.wc_fn.copy(),
            nb.wc_fx, nb.wc_fy, w.arrays(), p.x, p.y, p.vx, p.vy, p.omega, p.fx, p.fy,
            p.torque, p.radius, p.mass, p.x_ref, p.y_ref, sim.gravity, sim.law.zeta,
            sim.law.allow_tension, sim.law.local_damping, sim.dt, np.empty((blocks.size, 8)),
            True, nb.wall_gap, 0.0, 0.25 * nb.skin**2, nb.fast)
        return [p.view(name).copy() for name in names] + [nb.pair_fs.copy(), moved]

    one = one_step(np.array([0, n_strips], dtype=np.int32))
    for cuts in ([1, 2, 3], [5, 6, 17, 28], [2, 9, 9, 21]):
        assert any(c % 2 for c in cuts) and any(c % 2 == 0 for c in cuts)
        blocks = np.array([0, *cuts, n_strips], dtype=np.int32)
        got = one_step(blocks)
        for a, b in zip(one[:-1], got[:-1]):
            assert np.array_equal(a, b)
        assert one[-1] == got[-1]


def test_touching_contacts_equal_brute_force_over_many_steps():
    """Grains falling and colliding in a closed box: at every check, the contacts the kernels
    found (non-zero force; tension on, so every overlap has one) are exactly the overlapping
    pairs, and the grain-wall contacts are exactly the grains overlapping a wall."""
    rng = np.random.default_rng(7)
    size = 3.0
    xs, ys = np.meshgrid(np.linspace(0.2, 2.8, 12), np.linspace(0.2, 2.8, 12))
    p = Particles(8)
    p.add(xs.ravel() + rng.uniform(-0.02, 0.02, xs.size), ys.ravel(),
          rng.uniform(0.06, 0.1, xs.size), 1000.0,
          vx=rng.uniform(-2, 2, xs.size), vy=rng.uniform(-2, 2, xs.size))
    sim = Simulation(p, _box(size), law(1e5, zeta=0.1, tension=True), dt=2e-4, gravity=9.81,
                     skin=0.02)
    checked = 0
    for _ in range(120):
        sim.run(25)  # in one call: the compiled loop must stop for every rebuild
        nb = sim.neighbors
        # forces of this step were computed at the positions before the integration: undo it
        x = p.view("x") - p.view("vx") * sim.dt
        y = p.view("y") - p.view("vy") * sim.dt
        r, uid = p.view("radius"), p.view("uid")
        assert _list_pairs(sim, nb.pair_fn != 0.0) == _brute_pairs(x, y, r, uid, 0.0)
        gap = np.minimum.reduce([y, size - y, x, size - x]) - r
        assert set(uid[nb.wc_i[nb.wc_fn != 0.0]]) == set(uid[gap < 0.0])
        checked += 1
    assert sim.neighbors.rebuilds > 10 and checked == 120


@pytest.mark.parametrize("threaded", [False, True])
def test_many_steps_in_one_call_equal_the_steps_one_by_one(threaded, monkeypatch):
    """``run(n)`` repeats the force and integration kernels in a compiled loop until the list
    expires; ``step()`` returns to Python after each step, which decides on the rebuild.  Both
    must rebuild at the same steps and end with the same bits, also when ``run(n)`` uses the
    threaded kernels (forced here at 144 grains) and the steps one by one the serial ones."""
    def make():
        rng = np.random.default_rng(11)
        xs, ys = np.meshgrid(np.linspace(0.2, 2.8, 12), np.linspace(0.2, 2.8, 12))
        p = Particles(8)
        p.add(xs.ravel(), ys.ravel(), rng.uniform(0.06, 0.1, xs.size), 1000.0,
              vx=rng.uniform(-2, 2, xs.size), vy=rng.uniform(-2, 2, xs.size))
        return Simulation(p, _box(3.0), law(1e5, mu=0.5, zeta=0.2), dt=2e-4, skin=0.02)

    a, b = make(), make()
    if threaded:
        import numba

        import silodem.jit

        monkeypatch.setattr(silodem.jit, "PARALLEL_MIN_GRAINS", 1)
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
    a.run(2000)
    monkeypatch.undo()
    for _ in range(2000):
        b.step()
    assert a.steps == b.steps == 2000 and a.time == b.time
    assert a.neighbors.rebuilds == b.neighbors.rebuilds > 20
    for name in ("x", "y", "vx", "vy", "omega"):
        assert np.array_equal(a.particles.view(name), b.particles.view(name))


def test_contact_history_survives_rebuilds():
    """The same settled pile run with a rebuild every step and with the usual rebuilds: shear
    forces carried over by key give the same motion (to round-off from summation order)."""
    size = 2.0

    def make():
        rng = np.random.default_rng(3)
        p = Particles(8)
        xs, ys = np.meshgrid(np.linspace(0.15, 1.85, 9), np.linspace(0.12, 1.5, 7))
        p.add(xs.ravel() + rng.uniform(-0.03, 0.03, xs.size), ys.ravel(),
              rng.uniform(0.07, 0.1, xs.size), 1000.0)
        return p

    a = Simulation(make(), _box(size), law(1e5, mu=0.5, zeta=0.3), dt=2e-4, skin=0.02)
    a.run(3000)  # settle: many sticking contacts with shear history
    b = Simulation(make(), _box(size), law(1e5, mu=0.5, zeta=0.3), dt=2e-4, skin=0.02)
    b.run(3000)
    assert np.array_equal(a.particles.view("x"), b.particles.view("x"))
    assert np.count_nonzero(a.neighbors.pair_fs) > 20
    for _ in range(1500):
        a.invalidate()  # force a rebuild (and re-sort) at every step
        a.step()
        b.step()
    assert a.neighbors.rebuilds > b.neighbors.rebuilds + 1000
    ua, ub = np.argsort(a.particles.view("uid")), np.argsort(b.particles.view("uid"))
    # round-off apart (measured 1.8e-15 m and 4e-13 rad/s); with the history dropped at each
    # rebuild the two runs differ by 0.15 m and 8.2 rad/s
    np.testing.assert_allclose(a.particles.view("x")[ua], b.particles.view("x")[ub], atol=1e-12)
    np.testing.assert_allclose(a.particles.view("omega")[ua], b.particles.view("omega")[ub],
                               atol=1e-10)


def test_history_of_candidates_apart_at_the_build_is_never_read():
    """The build carries the shear history over only for the candidates that touch at the
    build and gives the others 0: the next force evaluation, on the same positions, finds
    them apart and writes 0 without reading it.  Checked: grains falling into a pile, rebuilt
    at every step, once as built and once with random history put in those candidates after
    each build, gives the same bits; and the build's own values there are 0 while many of
    the candidates that touch carry a history."""
    import copy

    from silodem.engine.neighbors import NeighborList

    rng = np.random.default_rng(7)
    p = _random_grains(rng, 600, 6.0, rmin=0.08, rmax=0.14)
    a = Simulation(p, _box(6.0), law(1e5, mu=0.4, zeta=0.2), dt=1e-4, skin=0.03)
    a.run(1500)  # falling into a pile: contacts open and form
    b = copy.deepcopy(a)
    noise = np.random.default_rng(8)
    apart_total = carried = 0

    def rebuild_with_noise(particles, walls):
        nonlocal apart_total, carried
        NeighborList.rebuild(b.neighbors, particles, walls)
        nb = b.neighbors
        apart = np.ones(nb.pair_j.size, dtype=bool)
        for i in range(particles.n):
            apart[nb.i_start[i]:nb.i_apart[i]] = False
        assert np.all(nb.pair_fs[apart] == 0.0)
        apart_total += np.count_nonzero(apart)
        carried += np.count_nonzero(nb.pair_fs[~apart])
        nb.pair_fs[apart] = noise.normal(0.0, 1.0, np.count_nonzero(apart))

    b.neighbors.rebuild = rebuild_with_noise
    for _ in range(200):
        a.invalidate()
        b.invalidate()
        a.step()
        b.step()
    assert apart_total > 10_000 and carried > 10_000
    for name in ("x", "y", "vx", "vy", "omega", "fx", "fy", "torque"):
        assert np.array_equal(a.particles.view(name), b.particles.view(name))
    assert np.array_equal(a.neighbors.pair_fs, b.neighbors.pair_fs)
    assert np.array_equal(a.neighbors.pair_fn, b.neighbors.pair_fn)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_wall_candidates_equal_brute_force_with_many_walls(seed):
    """The wall search looks only at the walls binned to a grain's cell; on 500 random grains
    and 60 random segments (some one-sided, some switched off, some far outside the grains)
    its candidates must be exactly the (grain, wall) pairs within r + skin (3 r + skin for a
    one-sided wall) of the segment, found by testing every pair, in ascending wall order."""
    rng = np.random.default_rng(seed)
    p = _random_grains(rng, 500, 4.0)
    w = Walls()
    for k in range(60):
        a = rng.uniform(-1.0, 5.0, 2)
        b = a + rng.normal(0.0, 1.5, 2)
        if k % 10 == 9:  # far from every grain
            a, b = a + 40.0, b + 40.0
        w.add(f"w{k}", tuple(a), tuple(b), 1e5, 1e5, 0.3, one_sided=bool(k % 3 == 0))
        if k % 7 == 3:
            w.set_active(f"w{k}", False)
    skin = 0.03
    sim = Simulation(p, w, law(), dt=1e-4, gravity=0.0, skin=skin)
    sim.neighbors.rebuild(p, w)
    x, y, r, uid = (p.view(name) for name in ("x", "y", "radius", "uid"))
    expected = []
    for g in np.argsort(uid):  # brute force: every grain against every wall
        for k in range(w.ax.size):
            if not w.active[k]:
                continue
            ux, uy = w.bx[k] - w.ax[k], w.by[k] - w.ay[k]
            s = np.clip(((x[g] - w.ax[k]) * ux + (y[g] - w.ay[k]) * uy) / (ux * ux + uy * uy),
                        0.0, 1.0)
            dist = np.hypot(x[g] - w.ax[k] - s * ux, y[g] - w.ay[k] - s * uy)
            if dist < r[g] * (3.0 if w.one_sided[k] else 1.0) + skin:
                expected.append((int(uid[g]), k))
    nb = sim.neighbors
    found = sorted((int(uid[g]), int(k)) for g, k in zip(nb.wc_i, nb.wc_w))
    assert found == sorted(expected) and len(expected) > 100
    assert np.all(np.diff(nb.wc_w)[np.diff(nb.wc_i) == 0] > 0)  # ascending per grain


def _missed_contacts(sim):
    """Overlapping grain pairs and grain-wall overlaps at the current positions that the list
    does not hold (brute force with a k-d tree, and every wall for every grain)."""
    from scipy.spatial import cKDTree

    p, nb, w = sim.particles, sim.neighbors, sim.walls
    x, y, r = p.view("x"), p.view("y"), p.view("radius")
    listed = set(zip(nb.pair_i.tolist(), nb.pair_j.tolist()))
    missed = 0
    for i, j in cKDTree(np.c_[x, y]).query_pairs(2 * r.max()):
        if np.hypot(x[i] - x[j], y[i] - y[j]) < r[i] + r[j]:
            missed += (min(i, j), max(i, j)) not in listed
    wall_listed = set(zip(nb.wc_i.tolist(), nb.wc_w.tolist()))
    for k in np.flatnonzero(w.active):
        ux, uy = w.bx[k] - w.ax[k], w.by[k] - w.ay[k]
        s = np.clip(((x - w.ax[k]) * ux + (y - w.ay[k]) * uy) / (ux * ux + uy * uy), 0, 1)
        near = np.hypot(x - w.ax[k] - s * ux, y - w.ay[k] - s * uy) < r
        missed += sum((g, k) not in wall_listed for g in np.flatnonzero(near).tolist())
    return missed


def test_cell_test_keeps_every_contact_and_saves_list_builds():
    """The benchmark silo (grains re-entering at the top fall freely onto the packing): after
    every step at which the global test says rebuild and the test by cells keeps the list,
    every overlapping pair and grain-wall overlap is in it (brute force); and the list is
    rebuilt less often than by the global test alone."""
    from silodem.bench import advance, build

    builds = {}
    for cell_test in (False, True):
        sim, _, top = build(16, 60)
        sim.cell_test = cell_test
        advance(sim, top, 6000)  # packed at the bottom, re-entered grains falling
        start, kept = sim.neighbors.rebuilds, 0
        for _ in range(600):
            advance(sim, top, 1)
            if cell_test and sim._past_global_test() and not sim._list_expired():
                assert _missed_contacts(sim) == 0  # this list makes the next forces
                kept += 1
        builds[cell_test] = sim.neighbors.rebuilds - start
    assert kept > 150
    assert builds[True] < builds[False]


@pytest.mark.parametrize("x0", [-1.6, -1.575, -1.55, -1.525, -1.5, -1.475])
@pytest.mark.parametrize("y0", [2.5, 2.42, 2.375])
def test_cell_test_misses_no_contact_of_a_grain_shot_into_a_resting_block(x0, y0):
    """One fast grain (50 m/s) shot at 401 grains at rest (no gravity, no walls), head-on at
    a grain, off-centre, or between two, from six starts (so the list is built at six phases
    of the approach): the global test expires every few steps, the test
    by cells keeps the list while the fast grain is away from the others; after every step,
    every overlapping pair is in the list (brute force), through the approach and the
    impact.  A test by cells that took a touching pair for a candidate without looking, or
    looked at the cells 1 away only, fails here."""
    xs, ys = np.meshgrid(np.arange(20) * 0.25, np.arange(20) * 0.25)
    p = Particles(8)
    p.add(xs.ravel(), ys.ravel(), 0.1, 1000.0)
    p.add([-3.0], [0.0], 0.1, 1000.0)  # far away: the cell grid does not start at the shot
    p.add([x0], [y0], 0.1, 1000.0, vx=50.0)
    sim = Simulation(p, Walls(), law(1e6, zeta=0.1), dt=1e-4, gravity=0.0, skin=0.05)
    kept = touched = 0
    for _ in range(400):
        sim.step()
        past_global = sim._past_global_test()
        if not sim._list_expired():  # this list makes the next forces
            kept += past_global
            assert _missed_contacts(sim) == 0
        touched += np.count_nonzero(sim.neighbors.pair_fn) > 0
    assert kept > 50
    assert touched > 10  # the shot grain hit the block
