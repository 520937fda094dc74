"""The fast kernels (Verlet list, spatial sorting, history carried by uid slots, serial and
parallel variants) against a brute-force reference DEM on random configurations."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from reference_dem import ReferenceDEM

import silodem.jit
from silodem.engine.contact import GrainLaw
from silodem.engine.particles import Particles
from silodem.engine.simulation import Simulation
from silodem.engine.walls import Walls

K, KS, MU, ZETA, DT, G = 1e5, 8e4, 0.4, 0.15, 1e-4, 9.81
# Hertz-Mindlin: 2 E* and 8 G* [Pa] that give tangent stiffnesses near K, KS at the overlaps
# of the random states below (about 5 mm)
HERTZ_K, HERTZ_KS = 7e6, 5.6e6
BOX = 2.0
CORNERS = [(0.0, 0.0), (BOX, 0.0), (BOX, BOX), (0.0, BOX)]


def _random_state(seed, n=150):
    rng = np.random.default_rng(seed)
    # a loose lattice pushed together: many overlaps, random motion
    side = int(np.ceil(np.sqrt(n)))
    gx, gy = np.meshgrid(np.linspace(0.12, BOX - 0.12, side), np.linspace(0.12, BOX - 0.12, side))
    x = gx.ravel()[:n] + rng.uniform(-0.02, 0.02, n)
    y = gy.ravel()[:n] + rng.uniform(-0.02, 0.02, n)
    r = rng.uniform(0.06, 0.09, n)
    v = rng.uniform(-1.0, 1.0, (3, n))
    return x, y, r, v


def _engine(x, y, r, v, density=1000.0, hertz=False):
    k, ks = (HERTZ_K, HERTZ_KS) if hertz else (K, KS)
    p = Particles(8)
    p.add(x, y, r, density, vx=v[0], vy=v[1], omega=v[2] * 5)
    w = Walls()
    for a, b, name in zip(CORNERS, CORNERS[1:] + CORNERS[:1], "abcd"):
        w.add(name, a, b, k, ks, MU)
    law = GrainLaw(kn=k, ks=ks, mu=MU, zeta=ZETA, hertz=hertz)
    return Simulation(p, w, law, dt=DT, gravity=G, skin=0.01)


def _reference(x, y, r, v, density=1000.0, hertz=False):
    k, ks = (HERTZ_K, HERTZ_KS) if hertz else (K, KS)
    m = density * np.pi * r**2
    walls = [(*a, *b, k, ks, MU) for a, b in zip(CORNERS, CORNERS[1:] + CORNERS[:1])]
    return ReferenceDEM(x, y, v[0], v[1], v[2] * 5, r, m, range(len(x)), walls, k, ks, MU,
                        ZETA, DT, G, hertz=hertz)


@pytest.mark.parametrize("seed, hertz", [(0, False), (1, False), (2, True)])
@pytest.mark.parametrize("parallel", [False, True])
def test_forces_torques_and_history_equal_brute_force(seed, hertz, parallel, monkeypatch):
    """Either contact law (``hertz``: Hertz-Mindlin)."""
    if parallel:
        monkeypatch.setattr(silodem.jit, "PARALLEL_MIN_GRAINS", 1)
    x, y, r, v = _random_state(seed)
    sim, ref = _engine(x, y, r, v, hertz=hertz), _reference(x, y, r, v, hertz=hertz)
    p = sim.particles
    most = 0  # the largest number of contacts carrying shear history at once
    for _ in range(300):
        sim.step()
        fx, fy, tq = ref.step()
        most = max(most, sum(1 for k, val in ref.hist.items() if k[0] != "wall" and val != 0.0))
        order = p.view("uid")  # engine index -> uid (the reference keeps uid order)
        scale = np.abs(fx).max() + 1e-300
        np.testing.assert_allclose(p.view("fx"), fx[order], rtol=0, atol=1e-9 * scale)
        np.testing.assert_allclose(p.view("fy"), fy[order], rtol=0, atol=1e-9 * scale)
        np.testing.assert_allclose(p.view("torque"), tq[order], rtol=0,
                                   atol=1e-9 * scale * r.max())
    # the shear history of every touching contact equals the reference's
    nb, uid = sim.neighbors, p.view("uid")
    touching = (nb.pair_fn != 0) | (nb.pair_fs != 0)
    engine_hist = {(min(uid[i], uid[j]), max(uid[i], uid[j])): fs for i, j, fs in
                   zip(nb.pair_i[touching], nb.pair_j[touching], nb.pair_fs[touching])}
    ref_pairs = {k: val for k, val in ref.hist.items() if k[0] != "wall"}
    assert engine_hist.keys() == ref_pairs.keys()
    for key, fs in ref_pairs.items():
        assert engine_hist[key] == pytest.approx(fs, abs=1e-9 * scale)
    assert sim.neighbors.rebuilds > 5
    assert most > 50


def test_contact_table_forces_add_up_to_each_grains_total():
    """``quantities.grain_contacts`` rebuilds each force vector from F_n, F_s and the normal at
    the current positions.  With Newton's third law and the wall contacts, the vectors must add
    up to the total force the step applied to every grain, up to the turn of each normal during
    the step: |n(t + dt) - n(t)| <= 2 |v_j - v_i| dt / distance (v: the half-step velocity that
    moved the grains), a bound worked out per contact and summed per grain."""
    from silodem.engine import quantities as q

    x, y, r, v = _random_state(5)
    sim = _engine(x, y, r, v)
    p = sim.particles
    for _ in range(40):
        sim.step()
    checked = 0
    for _ in range(5):
        sim.step()
        n = p.n
        gc, wc = q.grain_contacts(sim), q.wall_contacts(sim)
        sx, sy, bound = np.zeros(n), np.zeros(n), np.zeros(n)
        np.add.at(sx, gc.j, gc.fx)
        np.add.at(sy, gc.j, gc.fy)
        np.add.at(sx, gc.i, -gc.fx)
        np.add.at(sy, gc.i, -gc.fy)
        np.add.at(sx, wc.grain, wc.fx)
        np.add.at(sy, wc.grain, wc.fy)
        dist = np.hypot(p.x[gc.j] - p.x[gc.i], p.y[gc.j] - p.y[gc.i])
        turn = 2.0 * np.hypot(p.vx[gc.j] - p.vx[gc.i], p.vy[gc.j] - p.vy[gc.i]) * DT / dist
        per_contact = np.hypot(gc.fn, gc.fs) * turn
        np.add.at(bound, gc.i, per_contact)
        np.add.at(bound, gc.j, per_contact)
        scale = np.abs(p.view("fx")).max()
        slack = bound + 1e-9 * scale
        assert np.all(np.abs(sx - p.view("fx")) <= slack)
        assert np.all(np.abs(sy - p.view("fy")) <= slack)
        assert bound.max() < 0.05 * scale  # the bound is tight enough to mean something
        checked += gc.i.size
    assert checked > 500


def test_an_edited_kernel_source_clears_every_cached_kernel(tmp_path):
    """numba checks a cached kernel only against its own file; the compiled step loop of
    simulation.py inlines contact.py's law, so an edited contact.py left the old law in the
    cache (a validation mutation went unseen).  The caches of all kernel files go as soon as
    any kernel source differs from the hash stored with them, and only then."""
    from silodem.jit import CACHE_STAMP, clear_stale_caches

    root = tmp_path / "silodem"
    sources = {"engine/contact.py": "law = 1\n", "engine/simulation.py": "loop = 1\n",
               "jit.py": "flags = 1\n", "measure/gaussian.py": "g = 1\n"}
    for name, text in sources.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)

    def cache_files(*names: str) -> list:
        made = []
        for name in names:
            made.append(root / name)
            made[-1].parent.mkdir(parents=True, exist_ok=True)
            made[-1].write_bytes(b"compiled")
        return made

    other = root / "report" / "__pycache__" / "unrelated.nbi"  # no kernel file there
    cached = cache_files("engine/__pycache__/simulation._steps-1.py311.nbi",
                         "engine/__pycache__/simulation._steps-1.py311.1.nbc",
                         "measure/__pycache__/gaussian.g-1.py311.nbi",
                         "__pycache__/jit.f-1.py311.nbi", "report/__pycache__/unrelated.nbi")
    assert clear_stale_caches(root)  # no stamp yet: nothing cached can be trusted
    assert [f.exists() for f in cached] == [False, False, False, False, True] and other.exists()
    stamp = (root / CACHE_STAMP).read_text()
    cached = cache_files("engine/__pycache__/simulation._steps-1.py311.nbi")
    assert not clear_stale_caches(root) and cached[0].exists()  # unchanged: kept
    (root / "engine/contact.py").write_text("law = 2\n")  # only the callee's file changes
    assert clear_stale_caches(root) and not cached[0].exists()
    assert (root / CACHE_STAMP).read_text() != stamp


def test_kernel_caches_under_numba_cache_dir_are_cleared_too(tmp_path, monkeypatch):
    """With NUMBA_CACHE_DIR set numba keeps the kernels there, not in __pycache__: an edited
    callee must clear those (before, the hash was stored and the stale step loop kept)."""
    import numba

    from silodem.jit import STAMP_NAME, _cache_dir, clear_stale_caches

    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path / "numba-cache"))
    root = tmp_path / "silodem"
    for name in ("engine/contact.py", "engine/simulation.py", "jit.py", "measure/gaussian.py"):
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text("x = 1\n")
    engine_cache = _cache_dir(root / "engine/simulation.py")
    assert engine_cache.is_relative_to(tmp_path / "numba-cache")
    assert clear_stale_caches(root) and (engine_cache / STAMP_NAME).exists()
    assert not (root / "engine/__pycache__").exists()  # nothing written beside the sources
    cached = engine_cache / "simulation._steps-1.py311.nbi"
    cached.write_bytes(b"compiled")
    assert not clear_stale_caches(root) and cached.exists()
    (root / "engine/contact.py").write_text("x = 2\n")
    assert clear_stale_caches(root) and not cached.exists()


# --- where the arrays lie: every stream of the step in an L1 cache set of its own ----------

def _l1_sets(arrays) -> list[int]:
    """The L1 set of each array's first byte on a 32 KB, 8-way cache of 64 B lines: address
    bits 6-11 (32768 / (8 x 64) = 64 sets), worked out here from the address alone."""
    return [(a.__array_interface__["data"][0] >> 6) & 63 for a in arrays]


@pytest.mark.parametrize("n", [1_000, 300_000])  # on the heap, and mmap'd by glibc
def test_lanes_start_in_64_different_l1_sets_and_hold_the_values(n):
    from silodem.engine import lanes

    made = [lanes.empty(n, lane) for lane in range(64)]
    assert len(set(_l1_sets(made))) == 64
    assert all(a.shape == (n,) and a.dtype == np.float64 and a.flags.c_contiguous
               and a.flags.writeable for a in made)
    values = np.random.default_rng(0).random(n)
    for lane in (0, 13):
        copied = lanes.copy(values, lane)
        assert copied.tobytes() == values.tobytes() and not np.shares_memory(copied, values)
    ints = lanes.zeros(n, 5, np.int64)
    assert ints.dtype == np.int64 and not ints.any()
    # no two arrays overlap
    spans = sorted((a.ctypes.data, a.ctypes.data + a.nbytes) for a in made)
    assert all(end <= start for (_, end), (start, _) in itertools.pairwise(spans))


def test_grain_and_list_arrays_lie_in_different_l1_sets_as_built_and_as_grown():
    """glibc gives every array of 128 KB or more a fresh page and numpy starts it 16 bytes in:
    element i of every such array then falls in one L1 set, and the step's dozen streams
    evicted each other (1e5-1e6 grains ran at 1.6-1.7x the cost per particle-step of 1e4;
    engine/lanes.py).  The grains' 14 fields and the list's float arrays streamed beside them
    must lie in different sets, in a new store, after it grew, and after a list build."""
    from silodem.engine.particles import FIELDS

    n = 40_000
    x, y = np.meshgrid(np.arange(200) * 0.2, np.arange(n // 200) * 0.2)
    p = Particles(16)  # grows to hold them
    p.add(x.ravel(), y.ravel(), 0.099, 1000.0)
    streams = [getattr(p, name) for name in FIELDS]
    assert min(a.nbytes for a in streams) >= 128 * 1024
    assert len(set(_l1_sets(streams))) == len(FIELDS)
    sim = Simulation(p, Walls(), GrainLaw(kn=K, ks=KS, mu=MU, zeta=ZETA), dt=DT, gravity=G,
                     skin=0.01)
    sim.run(2)
    nb = sim.neighbors
    streams = [getattr(p, name) for name in FIELDS] + [nb.wall_gap, nb.pair_fs, nb.pair_fn]
    assert len(set(_l1_sets(streams))) == len(streams)


def test_a_run_gives_the_same_bits_wherever_its_arrays_lie(monkeypatch):
    """The lanes move where the arrays start, never a value: a run with every array in lane 0
    (as plain numpy arrays lie) ends with the same bits as one with the lanes."""
    from silodem.engine import lanes

    def end_state():
        x, y, r, v = _random_state(4, n=300)
        sim = _engine(x, y, r, v)
        sim.run(400)
        p = sim.particles
        return b"".join(p.view(f).tobytes() for f in ("uid", "x", "y", "vx", "vy", "omega"))

    spread = end_state()
    monkeypatch.setattr(lanes, "LANE_BYTES", 0)
    assert end_state() == spread
