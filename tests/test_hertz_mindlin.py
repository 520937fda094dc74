"""The Hertz-Mindlin contact law against Hertz's and Mindlin's analytic solutions, and its
dimensionless impact integrated by scipy (``validate.hertz_mindlin.dimensionless_rebound``;
engine/hertz.py, docs/physics.md)."""

from __future__ import annotations

import math

import h5py
import numpy as np
import pytest
from physics_helpers import MASS, RHO, R, pair_impact, run_until_separated
from pydantic import ValidationError
from reliability_helpers import hertz_config, stop_and_restore

from silodem.cli import main
from silodem.config import Config
from silodem.engine import hertz
from silodem.engine.contact import GrainLaw
from silodem.engine.particles import Particles
from silodem.engine.simulation import Simulation
from silodem.engine.walls import Walls
from silodem.output import write_results
from silodem.scenario_files import config_to_toml
from silodem.silo.checks import estimate_overlap
from silodem.silo.materials import design_overlaps
from silodem.silo.procedure import SiloRun
from silodem.validate.hertz_mindlin import dimensionless_rebound, hertz_impact, rocking_period

E, NU = 1e8, 0.3  # grain Young's modulus [Pa] and Poisson's ratio [-]
E_WALL, NU_WALL = 2e11, 0.25


def textbook_moduli(e_a, nu_a, e_b, nu_b):
    """E* and G* of two bodies (Johnson, Contact Mechanics, 1985, ch. 4 and 7), written
    here from the book, not taken from silodem."""
    e_star = 1.0 / ((1 - nu_a**2) / e_a + (1 - nu_b**2) / e_b)
    g_star = 1.0 / ((2 - nu_a) * (1 + nu_a) * 2 / e_a + (2 - nu_b) * (1 + nu_b) * 2 / e_b)
    return e_star, g_star


def hertz_law(zeta=0.0, tension=False, mu=0.5):
    e_star, g_star = textbook_moduli(E, NU, E, NU)
    return GrainLaw(kn=2 * e_star, ks=8 * g_star, mu=mu, zeta=zeta, allow_tension=tension,
                    hertz=True)


def hertz_floor(mu=0.5):
    e_star, g_star = textbook_moduli(E, NU, E_WALL, NU_WALL)
    w = Walls()
    w.add("floor", (-10.0, 0.0), (10.0, 0.0), 2 * e_star, 8 * g_star, mu, one_sided=True)
    return w, e_star, g_star


@pytest.mark.parametrize("e", [0.001, 0.1, 0.5, 0.9, 0.99])
def test_damping_ratio_gives_the_integrated_restitution(e):
    """zeta_H(e) = sqrt(5/6) (-ln e)/sqrt(pi^2 + ln^2 e) against the impact integrated here
    (scipy's DOP853 at rtol 1e-11: the two agree within 1e-10)."""
    zeta = hertz.damping_ratio_from_restitution(e)
    assert dimensionless_rebound(zeta, tension=True) == pytest.approx(e, rel=1e-9, abs=1e-12)


def test_elastic_pair_impact_matches_hertz():
    """Two equal disks (R* = R/2, m* = m/2) meeting head-on: the largest overlap, the contact
    duration and the rebound speed of Hertz's solution."""
    v = 1.0  # each grain; relative speed 2v
    e_star, _ = textbook_moduli(E, NU, E, NU)
    d_max, t_c = hertz_impact(2 * v, MASS / 2, e_star, R / 2)
    sim = pair_impact(hertz_law(), v=v, dt=t_c / 2000)
    p = sim.particles
    deepest = [0.0]

    def touching():
        deepest[0] = max(deepest[0], 2 * R - abs(p.x[1] - p.x[0]))
        return sim.neighbors.pair_fn[0] != 0.0

    t0, t1 = run_until_separated(sim, touching)
    # sampled at the steps, the deepest overlap is short of d_max by up to about
    # (pi dt / t_c)^2 / 8 = 3e-7 of it (measured 1.1e-7)
    assert deepest[0] == pytest.approx(d_max, rel=1e-6)
    assert t1 - t0 == pytest.approx(t_c, rel=1e-3)  # measured to one step, t_c / 2000
    # the leap-frog's energy error is of order (dt / t_c)^2 = 2.5e-7 (measured 1.7e-9)
    assert (p.vx[1] - p.vx[0]) / (2 * v) == pytest.approx(1.0, abs=2.5e-7)


@pytest.mark.parametrize("v", [0.02, 0.2, 2.0])
@pytest.mark.parametrize("tension", [True, False])
def test_restitution_is_the_same_at_every_speed(v, tension):
    """Tsuji's dashpot (delta^(1/4)) gives one restitution at every speed: the requested e with
    tension allowed, and without tension the e* of the integrated impact whose force must
    stay >= 0, over two decades of impact speed."""
    e = 0.5
    zeta = hertz.damping_ratio_from_restitution(e)
    expected = e if tension else dimensionless_rebound(zeta, tension=False)
    e_star, _ = textbook_moduli(E, NU, E, NU)
    _, t_c = hertz_impact(2 * v, MASS / 2, e_star, R / 2)
    sim = pair_impact(hertz_law(zeta=zeta, tension=tension), v=v, dt=t_c / 2000)
    run_until_separated(sim, lambda: sim.neighbors.pair_fn[0] != 0.0)
    p = sim.particles
    # the central-difference scheme's error in e is of order dt / t_c = 5e-4: within two
    assert (p.vx[1] - p.vx[0]) / (2 * v) == pytest.approx(expected, rel=1e-3)
    if not tension:
        assert expected > e + 0.02  # the no-tension contact loses less, as for the linear law


def _resting_grain(mu=0.5):
    walls, e_star, g_star = hertz_floor(mu)
    p = Particles()
    p.add(np.array([0.0]), np.array([R]), R, RHO)
    law = hertz_law(zeta=hertz.damping_ratio_from_restitution(0.3), mu=mu)
    sim = Simulation(p, walls, law, dt=2e-5, gravity=9.81, skin=0.02)
    sim.run(50_000)  # 1 s: the dashpot's decay time is about 5 ms
    return sim, e_star, g_star


def test_grain_at_rest_on_a_floor_has_hertz_overlap():
    """m g = 4/3 E* sqrt(R) delta^(3/2) (grain on a flat wall, R* = R): the static overlap, and
    the wall force equal to the weight."""
    sim, e_star, _ = _resting_grain()
    delta = (3 * MASS * 9.81 / (4 * e_star * math.sqrt(R))) ** (2 / 3)
    assert R - sim.particles.y[0] == pytest.approx(delta, rel=1e-9)
    assert sim.neighbors.wc_fn[0] == pytest.approx(MASS * 9.81, rel=1e-9)


def test_mindlin_shear_stiffness_sets_the_rocking_frequency():
    """A grain at rest on the floor, nudged sideways, rocks on its contact without slipping:
    the contact point's displacement u obeys u'' = -(1/m + R^2/I) S_s u = -3 S_s u / m, with
    Mindlin's S_s = 8 G* sqrt(R delta) at the static overlap.  The period is read from the
    zero crossings of the shear force over ten cycles.  The leap-frog oscillates with
    sin(omega_h dt / 2) = omega dt / 2, a period shorter by (omega dt)^2 / 24 = 1.7e-6: the
    period is compared with that one (they agree within 3e-12)."""
    sim, _, g_star = _resting_grain(mu=0.9)
    delta = R - sim.particles.y[0]
    omega_t = math.sqrt(3 * 8 * g_star * math.sqrt(R * delta) / MASS)
    period, mobilised = rocking_period(sim, omega_t)
    leap_frog = math.pi * sim.dt / math.asin(omega_t * sim.dt / 2)
    assert period == pytest.approx(leap_frog, rel=1e-9)
    assert period == pytest.approx(2 * math.pi / omega_t, rel=1e-5)
    assert mobilised < 1e-2  # far from Coulomb's limit


def test_mindlin_over_hertz_stiffness_ratio_is_2_1_nu_over_2_nu():
    """For a grain on a rigid wall S_s / S_n = 4 G*/E* = 2 (1 - nu)/(2 - nu) (Mindlin 1949; the
    wall here is 2000 times stiffer than the grain, so the ratio holds to 1e-3)."""
    _, e_star, g_star = hertz_floor()
    assert 4 * g_star / e_star == pytest.approx(2 * (1 - NU) / (2 - NU), rel=1e-3)
    kn, ks = hertz.kernel_constants(E, NU, E_WALL, NU_WALL)
    assert (kn, ks) == pytest.approx((2 * e_star, 8 * g_star), rel=1e-14)


# --- configuration and a whole run ----------------------------------------------------------


@pytest.fixture(scope="module")
def hertz_run():
    run = SiloRun(hertz_config())
    run.run()
    return run


def test_the_walls_carry_the_settled_hertz_fill(hertz_run):
    """At the end of settling the walls carry the weight of the grains: the wall forces are
    the grains' contact resultants summed (Newton's third law: the grain-grain forces
    cancel), and these differ from the weight by at most the grains' leftover resultants,
    sum |F_i - m_i g| (as tests/test_silo_run.py checks for the linear law); the run then
    discharges."""
    snap = hertz_run.snapshots["settled"]
    m = hertz_run.cfg.material
    r = snap.particles["radius"]
    mass = m.density * np.pi * r**2 * m.thickness
    g = hertz_run.cfg.gravity
    fy = snap.particles["fy"]
    assert np.sum(snap.wall_contacts["fy"]) == pytest.approx(np.sum(fy), rel=1e-12)
    leftover = np.sum(np.hypot(snap.particles["fx"], fy - mass * g))
    assert abs(np.sum(fy) - np.sum(mass) * g) <= leftover < 0.01 * np.sum(mass) * g
    assert hertz_run.discharged_count > 0


def test_hertz_overlaps_stay_within_those_the_time_step_was_set_for(hertz_run):
    """dt comes from the tangent stiffness at the design overlaps (``materials.linearised``):
    every overlap of the settled packing must be smaller, or the stiffest contact would be
    stiffer than dt allows for."""
    cfg = hertz_run.cfg
    d_grain, d_wall = design_overlaps(cfg, estimate_overlap(cfg).contact_force)
    snap = hertz_run.snapshots["settled"]
    p, c, wc = snap.particles, snap.contacts, snap.wall_contacts
    grain = (cfg.material.young_modulus, cfg.material.poisson_ratio)
    e_star, _ = textbook_moduli(*grain, *grain)
    r_eff = p["radius"][c["i"]] * p["radius"][c["j"]] / (p["radius"][c["i"]] + p["radius"][c["j"]])
    # overlaps from the contact forces by Hertz's law (static packing: F_n is elastic)
    overlap = (3 * c["fn"] / (4 * e_star * np.sqrt(r_eff))) ** (2 / 3)
    assert 0 < overlap.max() < d_grain
    e_wall, _ = textbook_moduli(*grain, cfg.walls.young_modulus, cfg.walls.poisson_ratio)
    wall_overlap = (3 * wc["fn"] / (4 * e_wall * np.sqrt(p["radius"][wc["grain"]]))) ** (2 / 3)
    assert 0 < wall_overlap.max() < d_wall
    # and the time step is the stated fraction of the limit at those overlaps
    m_min = cfg.material.density * math.pi * cfg.material.radius_min**2
    r = cfg.material.radius_max
    s_n = 2 * e_star * math.sqrt(r / 2 * d_grain)
    assert hertz_run.dt <= cfg.time.safety * math.sqrt(m_min / 2 / s_n) * (1 + 1e-12)


@pytest.mark.parametrize("sets, needles", [
    (["material.contact_model=hertz_mindlin"], ["material.young_modulus", "required"]),
    (["material.contact_model=hertz_mindlin", "material.young_modulus=1e9",
      "material.poisson_ratio=0.3"], ["material.kn", "remove it"]),
    (["material.young_modulus=1e9"], ["material.young_modulus", "'linear'"]),
    (["material.poisson_ratio=0.7"], ["material.poisson_ratio", "0.5"]),
])
def test_law_keys_that_do_not_fit_the_model_are_refused_in_one_line(capsys, sets, needles):
    args = ["show", "paper-case2"]
    for item in sets:
        args += ["--set", item]
    with pytest.raises(SystemExit) as exc:
        main(args)
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.count("\n") == 1 and "Traceback" not in err
    for needle in needles:
        assert needle in err, err


def test_walls_need_the_hertz_keys_too():
    data = hertz_config().model_dump()
    data["walls"]["poisson_ratio"] = None
    with pytest.raises(ValidationError, match="walls.poisson_ratio is required"):
        Config.model_validate(data)
    data["walls"].update(poisson_ratio=0.3, kn=1e6)
    with pytest.raises(ValidationError, match="walls.kn belongs to the 'linear' law"):
        Config.model_validate(data)


def test_results_give_the_hertz_walls_moduli_in_pascals(hertz_run, tmp_path):
    """results.h5 /walls holds, under the Hertz-Mindlin law, 2 E* and 8 G* of grain and wall
    (Johnson's formulas, above), and says so in each dataset's unit: Pa, not the linear
    law's N/m (docs/output.md)."""
    write_results(hertz_run, tmp_path / "results.h5", "")
    c = hertz_run.cfg
    e_star, g_star = textbook_moduli(c.material.young_modulus, c.material.poisson_ratio,
                                     c.walls.young_modulus, c.walls.poisson_ratio)
    with h5py.File(tmp_path / "results.h5") as h5:
        walls = h5["walls"]
        np.testing.assert_allclose(walls["kn"][()], 2 * e_star, rtol=1e-12)
        np.testing.assert_allclose(walls["ks"][()], 8 * g_star, rtol=1e-12)
        assert walls["kn"].attrs["unit"] == walls["ks"].attrs["unit"] == "Pa"
        assert walls["ax"].attrs["unit"] == "m"


def test_a_hertz_run_resumes_from_a_checkpoint_bit_identical(hertz_run, tmp_path):
    """The Hertz-Mindlin law is rebuilt from the checkpoint's config: a run saved in the middle
    of its discharge and continued ends with the bits of the uninterrupted run."""
    _, second = stop_and_restore(hertz_config(), "discharge", tmp_path / "checkpoint.h5")
    assert second.law == hertz_run.law and second.law.hertz
    second.run()
    assert np.array(second.series.rows).tobytes() == np.array(hertz_run.series.rows).tobytes()
    for key, arr in hertz_run.snapshots["final"].particles.items():
        assert arr.tobytes() == second.snapshots["final"].particles[key].tobytes(), key


def test_hertz_parallel_kernels_give_the_same_bits_as_serial(hertz_run, monkeypatch):
    """The Hertz-Mindlin copies of the threaded kernels sum in the serial order too: the run on
    two threads ends with the serial run's bits."""
    import numba

    import silodem.jit

    monkeypatch.setattr(silodem.jit, "PARALLEL_MIN_GRAINS", 1)
    numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
    parallel = SiloRun(hertz_config())
    parallel.run()
    for key, arr in hertz_run.snapshots["final"].particles.items():
        assert arr.tobytes() == parallel.snapshots["final"].particles[key].tobytes(), key


def test_soft_hertz_grains_warn_and_the_advised_modulus_gives_one_percent():
    """E = 1 MPa under the quick hopper's fill: the overlap check warns naming
    material.young_modulus, and the modulus it advises, put back into Hertz's law with the
    same force, gives a grain-grain overlap of 1 % of the mean radius (E* = E / (2 (1 - nu^2))
    between equal grains, R* = r/2; Johnson 1985)."""
    data = hertz_config().model_dump()
    data["material"]["young_modulus"] = 1e6
    cfg = Config.model_validate(data)
    est = estimate_overlap(cfg)
    assert est.too_soft
    assert any("material.young_modulus >=" in w for w in SiloRun(cfg).warnings)
    m = cfg.material
    r = 0.5 * (m.radius_min + m.radius_max)
    e_star = est.recommended / (2 * (1 - m.poisson_ratio**2))
    overlap = (3 * est.contact_force / (4 * e_star * math.sqrt(r / 2))) ** (2 / 3)
    assert overlap == pytest.approx(0.01 * r, rel=1e-12)
    assert not estimate_overlap(hertz_config()).too_soft


def test_a_hertz_time_step_above_its_limit_is_refused_saying_why(capsys, tmp_path):
    path = tmp_path / "hertz.toml"
    path.write_text(config_to_toml(hertz_config()), encoding="utf-8")
    with pytest.raises(SystemExit) as exc:
        main(["run", str(path), "--set", "time.dt=0.01", "--out", str(tmp_path / "r")])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.count("\n") == 1
    assert "time.dt" in err and "Hertz stiffness" in err
