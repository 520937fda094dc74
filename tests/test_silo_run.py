"""A whole fill -> settle -> discharge run on a small silo: conservation, reproducibility,
output."""

from __future__ import annotations

import math

import h5py
import numpy as np
import pytest
from measure_helpers import tiny_hopper_config

import silodem.jit
from silodem.config import Config
from silodem.engine.walls import END_CAP
from silodem.errors import InputError
from silodem.run import run_simulation
from silodem.scenario_files import load_config, quick_variant
from silodem.silo.checks import estimate_overlap
from silodem.silo.geometry import build_walls, outlet_room, silo_shape
from silodem.silo.procedure import CHECK_INTERVAL, SiloRun


def small(kind: str = "hopper", **sets) -> Config:
    cfg = quick_variant(load_config("paper-case2" if kind == "hopper" else "paper-case1"))
    data = cfg.model_dump()
    data["fill"]["n_particles"] = 120
    data["discharge"]["max_time"] = 4.0
    for key, value in sets.items():
        section, name = key.split("__")
        data[section][name] = value
    return Config.model_validate(data)


@pytest.fixture(scope="module")
def hopper_run():
    run = SiloRun(small())
    run.run()
    return run


def test_mass_is_conserved_through_the_run(hopper_run):
    run = hopper_run
    poured = run.radii[: run.events["n_poured"]]
    m = run.cfg.material
    mass0 = float(np.sum(m.density * math.pi * poured**2 * m.thickness))
    remaining = run.sim.particles.total_mass()
    assert remaining + run.discharged_mass == pytest.approx(mass0, rel=1e-12)
    assert run.events["n_poured"] == 120
    assert run.discharged_count + run.sim.particles.n == 120


def test_grains_stay_inside_the_silo_until_the_gate_opens(hopper_run):
    """The settled fill: every centre inside the silo's outline, and no grain deeper in a wall
    than the linear law allows, F_n / k_n for the largest wall force (the deepest grain is the
    one pressed hardest; the dashpot's share of F_n at rest, 1e-5 of it here, is the only
    difference). The walls carry the weight: the wall forces are the grains' contact
    resultants summed (Newton's third law: the grain-grain forces cancel), and these differ
    from the weight by at most the grains' leftover resultants, sum |F_i - m_i g|."""
    snap = hopper_run.snapshots["settled"]
    shape, walls = hopper_run.shape, hopper_run.walls
    x, y, r = snap.particles["x"], snap.particles["y"], snap.particles["radius"]
    assert np.all(y + r > 0.0)  # nothing has passed the gate
    for xi, yi in zip(x, y):
        lo, hi = shape.inner_x_range(min(yi, shape.wall_top))
        assert lo < xi < hi
    distance = np.full(x.size, np.inf)  # from each centre to the nearest wall segment
    for ax, ay, bx, by in zip(walls.ax, walls.ay, walls.bx, walls.by):
        ux, uy = bx - ax, by - ay
        t = np.clip(((x - ax) * ux + (y - ay) * uy) / (ux * ux + uy * uy), 0.0, 1.0)
        distance = np.minimum(distance, np.hypot(x - ax - t * ux, y - ay - t * uy))
    assert np.all(walls.kn == walls.kn[0])
    deepest = np.max(r - distance)
    assert deepest == pytest.approx(snap.wall_contacts["fn"].max() / walls.kn[0], rel=1e-4)
    # the settled fill is at rest by the configured criterion, and the walls carry its weight
    assert hopper_run.events["settle_criterion_value"] < hopper_run.cfg.settle.threshold
    m = hopper_run.cfg.material
    mass = m.density * np.pi * r**2 * m.thickness
    g = hopper_run.cfg.gravity
    fy = snap.particles["fy"]
    assert np.sum(snap.wall_contacts["fy"]) == pytest.approx(np.sum(fy), rel=1e-12)
    leftover = np.sum(np.hypot(snap.particles["fx"], fy - mass * g))
    assert abs(np.sum(fy) - np.sum(mass) * g) <= leftover
    assert leftover < 0.01 * np.sum(mass) * g  # the bound is a sharp one (6e-3 here)


def test_discharge_ends_for_a_stated_reason(hopper_run):
    """The reason given matches the state: the fraction that left, counted from the grains'
    masses, reached ``stop_fraction``, or else the time limit was reached (within one check
    interval, ``CHECK_INTERVAL``) with less gone; this small silo does not clog."""
    run, d = hopper_run, hopper_run.cfg.discharge
    ev = run.events
    m = run.cfg.material
    poured = run.radii[: ev["n_poured"]]
    mass0 = float(np.sum(m.density * math.pi * poured**2 * m.thickness))
    left = mass0 - run.sim.particles.total_mass()
    assert ev["discharged_fraction"] == pytest.approx(left / mass0, rel=1e-12)
    if ev["discharge_end_reason"] == "fraction":
        assert left / mass0 >= d.stop_fraction
        assert ev["discharge_time"] < d.max_time + CHECK_INTERVAL
    else:
        assert ev["discharge_end_reason"] == "time"
        assert left / mass0 < d.stop_fraction
        assert d.max_time <= ev["discharge_time"] < d.max_time + CHECK_INTERVAL + run.sim.dt


def test_same_seed_gives_bit_identical_results():
    a, b = SiloRun(small(discharge__max_time=1.0)), SiloRun(small(discharge__max_time=1.0))
    a.run()
    b.run()
    for key in ("x", "y", "vx", "vy", "omega", "radius"):
        first, second = a.snapshots["final"].particles, b.snapshots["final"].particles
        assert np.array_equal(first[key], second[key])
    c = SiloRun(small(discharge__max_time=1.0).model_copy(update={"seed": 99}))
    c.run()
    assert not np.array_equal(a.snapshots["settled"].particles["x"],
                              c.snapshots["settled"].particles["x"])


def test_parallel_kernels_give_the_same_bits_as_serial(monkeypatch):
    import numba

    cfg = small(discharge__enabled=False, fill__n_particles=80)
    serial = SiloRun(cfg)
    serial.run()
    monkeypatch.setattr(silodem.jit, "PARALLEL_MIN_GRAINS", 1)
    numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
    parallel = SiloRun(cfg)
    parallel.run()
    for key in ("x", "y", "omega"):
        assert np.array_equal(serial.snapshots["final"].particles[key],
                              parallel.snapshots["final"].particles[key])


def test_clog_is_detected_and_reported_not_hung(tmp_path):
    """An outlet barely wider than two grains arches at once: the run must stop and say so,
    and its flow is 'clogged', not classified from the velocities of grains at rest (it read
    'funnel flow', with an MFI of noise)."""
    from silodem.study.table import summarise_run

    cfg = small(silo__outlet_width=0.3, discharge__clog_time=0.5,
                discharge__max_time=20.0, material__friction_deg=40.0)
    run_simulation(cfg, tmp_path, progress=False)
    with h5py.File(tmp_path / "results.h5", "r") as h5:
        events = dict(h5["events"].attrs)
        warnings = [w.decode() for w in h5["warnings"][()]]
    assert events["discharge_end_reason"] == "clog"
    assert any("clogged" in w for w in warnings)
    assert events["discharge_time"] < 20.0
    row = summarise_run(tmp_path)
    assert row["discharged_fraction"] == 0.0 and math.isnan(row["discharge_rate"])
    assert row["flow_pattern"] == "clogged" and math.isnan(row["mass_flow_index"])


def test_results_folder_layout(tmp_path):
    summary = run_simulation(small(discharge__max_time=1.0), tmp_path, progress=False)
    assert (tmp_path / "config.toml").is_file()
    assert (tmp_path / "final.png").stat().st_size > 10_000
    with h5py.File(tmp_path / "results.h5") as h5:
        ts = h5["timeseries"]
        for key in ("time", "kinetic_energy", "n_particles", "discharged_mass"):
            assert ts[key].shape == ts["time"].shape and ts[key].shape[0] > 10
        assert np.all(np.diff(ts["time"][:]) > 0)
        cfg = small(discharge__max_time=1.0)  # every recorder's configured interval [s]
        assert ts.attrs["interval"] == cfg.output.sample_interval
        assert h5["measure"].attrs["interval"] == cfg.measure.interval
        final = h5["final/particles"]
        n = final["x"].shape[0]
        for key in ("x", "y", "vx", "vy", "omega", "radius"):
            assert final[key].shape == (n,)
        c = h5["final/contacts"]
        assert c["i"].shape == c["fn"].shape and np.all(c["i"][:] < n) and np.all(c["j"][:] < n)
        assert load_config(str(tmp_path / "config.toml")) == small(discharge__max_time=1.0)
        from silodem.provenance import source_digest  # the code that made it (a study's check)

        assert h5.attrs["silodem_source"] == source_digest()
    assert any("results" in line for line in summary.lines())


@pytest.mark.parametrize("ks", [5e6, 5e5])
def test_time_step_above_the_stability_limit_is_refused(ks):
    """docs/physics.md, "Time step": dt_crit = min sqrt(m_eff / k) over the contact kinds,
    m_eff = m_min/2 and m_min/6 between grains (normal, shear), m_min and m_min/3 at a wall,
    k the series stiffnesses, the normal kinds' times f = sqrt(1 + 4 zeta^2) - 2 zeta for the
    dashpot's damping ratio zeta = -ln e / sqrt(pi^2 + ln^2 e); computed here for paper-case2's
    lightest grain, whose k_s = k_n leaves the limit to the shear spring, and with a softer
    k_s = k_n / 10, which leaves it to the damped normal one.  A dt just above it is refused,
    one just below runs, and unset dt is time.safety x dt_crit."""
    cfg = small(material__ks=ks, walls__ks=ks)
    m, w = cfg.material, cfg.walls
    assert (m.kn, m.ks, w.kn, w.ks, m.restitution) == (5e6, ks, 5e6, ks, 0.5)
    m_min = m.density * math.pi * m.radius_min**2 * m.thickness
    kn, ks_s = 5e6 / 2, ks / 2  # grains and walls alike, in series
    zeta = -math.log(0.5) / math.sqrt(math.pi**2 + math.log(0.5) ** 2)
    f2 = (math.sqrt(1 + 4 * zeta**2) - 2 * zeta) ** 2
    ratios = [m_min / 2 / kn * f2, m_min / 6 / ks_s, m_min / kn * f2, m_min / 3 / ks_s]
    assert min(ratios) == (ratios[1] if ks == 5e6 else ratios[0])
    dt_crit = math.sqrt(min(ratios))
    with pytest.raises(InputError, match="exceeds the stability limit"):
        SiloRun(small(material__ks=ks, walls__ks=ks, time__dt=dt_crit * (1 + 1e-9)))
    run = SiloRun(small(material__ks=ks, walls__ks=ks, time__dt=dt_crit * (1 - 1e-9)))
    assert run.dt == dt_crit * (1 - 1e-9)
    default = SiloRun(cfg)
    assert default.dt_crit == pytest.approx(dt_crit, rel=1e-12)
    assert default.dt == pytest.approx(cfg.time.safety * dt_crit, rel=1e-12)


def test_paper_case1_stiffness_warns_with_the_numbers():
    """Table 1: k_n = 5e4 N/m under ~5 m of 1607 kg/m^3 grains.  Hand check of the estimate:
    Janssen with K = 0.4, mu_w = tan 26.5 deg, B = 3.4 m, rho_b = 0.82*1607."""
    cfg = load_config("paper-case1")
    est = estimate_overlap(cfg)
    rho_b, mu_w, B, K = 0.82 * 1607.0, math.tan(math.radians(26.5)), 3.4, 0.4
    # the flat silo's fill: the grains' area (uniform radii: <r^2> = (b^3 - a^3) / (3 (b - a)))
    # at packing fraction 0.82 over the cell width
    m = cfg.material
    mean_r2 = (m.radius_max**3 - m.radius_min**3) / (3 * (m.radius_max - m.radius_min))
    assert est.fill_height == pytest.approx(
        cfg.fill.n_particles * math.pi * mean_r2 / (0.82 * B), rel=1e-12)
    a = 2 * K * mu_w / B
    sigma = rho_b * 9.81 / a * (1 - math.exp(-a * est.fill_height))
    assert est.sigma_v == pytest.approx(sigma, rel=1e-12)
    assert est.overlap == pytest.approx(sigma * 0.2 / 2.5e4, rel=1e-12)
    assert est.overlap_fraction > 1.0  # overlaps of the order of the radius, and more
    assert est.recommended == pytest.approx(2 * sigma * 0.2 / (0.01 * 0.1), rel=1e-12)
    run = SiloRun(cfg)
    assert any("soft contacts" in w and "a grain stiffness material.kn and a wall stiffness "
               "walls.kn >=" in w for w in run.warnings)  # Table 1: both are soft
    assert not SiloRun(load_config("paper-case2")).warnings


def test_a_hopper_lower_than_one_grain_is_warned():
    """A hopper angle of 0.0001 deg (a hopper micrometres high) ran without a word, its report
    quoting hopper theory for a floor the grains could not tell from flat.  The hopper is
    (B - D)/2 tan(theta) high; the warning comes exactly when that is under 2 r_max."""
    base = load_config("paper-case2")
    B, D, d = base.silo.cell_width, base.silo.outlet_width, 2 * base.material.radius_max
    edge = math.degrees(math.atan(d / (0.5 * (B - D))))  # a hopper one grain high
    for angle, warned in ((0.0001, True), (0.99 * edge, True), (1.01 * edge, False)):
        cfg = load_config("paper-case2", [f"silo.hopper_angle_from_horizontal_deg={angle}"])
        said = [w for w in SiloRun(cfg).warnings if "lower than one grain" in w]
        assert len(said) == warned, (angle, said)
    assert said == [] and "lower than one grain" not in " ".join(SiloRun(base).warnings)
    flat = load_config("paper-case1", ["silo.hopper_angle_from_horizontal_deg=0.0001"])
    assert not any("lower than one grain" in w for w in SiloRun(flat).warnings)


def test_local_damping_in_a_run_with_a_discharge_is_warned():
    """material.local_damping = 0.7 tripled paper-case2 --quick's discharge time (3.1 s to
    9.8 s) and its report gave the damped rate and a Beverloo C without a word (an audit).
    PFC's local damping takes alpha |F| off a moving grain's unbalanced force: a grain falling
    freely (F = m g) accelerates at (1 - alpha) g, which the warning states; none without a
    discharge, or without the damping."""
    said = [w for w in SiloRun(load_config("paper-case2", ["material.local_damping=0.7"])).warnings
            if "material.local_damping" in w]
    assert len(said) == 1 and "a falling grain accelerates at 0.3 g" in said[0]
    for sets in ([], ["material.local_damping=0.7", "discharge.enabled=false"]):
        cfg = load_config("paper-case2", sets)
        assert not any("local_damping" in w for w in SiloRun(cfg).warnings), sets


def test_tangential_springs_too_soft_to_mobilise_friction_are_warned():
    """Table 1's k_s = 1e3 N/m with k_n raised to 2e7 N/m (the overlap advice alone): a
    grain-grain contact of k_s/2 = 500 N/m reaches mu F = tan(45 deg) F only after F / 500 N/m
    of elastic sliding, about 20 m.  The warning says so and names the k_s, mu times the k_n
    recommended, that brings it under 1 % of the radius; with it there is no warning."""
    sets = ["material.kn=2e7", "walls.kn=2e7"]
    est = estimate_overlap(load_config("paper-case1", sets))
    assert not est.too_soft and est.soft_shear
    mu_g, mu_w = 1.0, math.tan(math.radians(26.5))
    assert est.slip == pytest.approx(max(mu_g * est.contact_force / 500.0,
                                         mu_w * est.contact_force / 500.0), rel=1e-12)
    assert est.slip == pytest.approx(20.1, abs=0.05)
    need = 2 * est.contact_force / (0.01 * 0.1)  # k_n for 1 % of r = 0.1 m, times mu_g = 1
    assert est.shear_keys == (("material.ks", pytest.approx(need)),
                              ("walls.ks", pytest.approx(need)))
    run = SiloRun(load_config("paper-case1", sets))
    assert any(w.startswith("soft tangential contacts: ") and "material.ks >= 2e+07 and "
               "walls.ks >= 2e+07 N/m" in w for w in run.warnings), run.warnings
    stiff = estimate_overlap(load_config("paper-case1", [*sets, "material.ks=2e7",
                                                          "walls.ks=2e7"]))
    assert not stiff.soft_shear and stiff.slip_fraction == pytest.approx(0.01, rel=0.02)
    assert "material.ks >= 2e+07" in estimate_overlap(load_config("paper-case1")).warning()
    assert not estimate_overlap(load_config("paper-case2")).soft_shear  # k_s = k_n = 5e6 N/m
    assert estimate_overlap(load_config("paper-case2-hertz")).slip == 0.0  # Mindlin: not judged


@pytest.mark.parametrize(("scenario", "sets", "named", "not_named"), [
    ("paper-case2", ["material.kn=1e8", "walls.kn=1e3"], "a wall stiffness walls.kn >=",
     "material.kn"),
    ("paper-case2", ["material.kn=2e4", "walls.kn=1e8"], "a grain stiffness material.kn >=",
     "walls.kn"),
    ("paper-case2", ["material.kn=2e4", "walls.kn=2e4"],
     "a grain stiffness material.kn and a wall stiffness walls.kn >=", None),
    ("paper-case2-hertz", ["material.young_modulus=1e9", "walls.young_modulus=1e5"],
     "a wall Young's modulus walls.young_modulus >=", "material.young_modulus"),
])
def test_the_soft_contact_advice_names_the_soft_side(scenario, sets, named, not_named):
    """The advice named material.kn even when the grains were stiff (1e8 N/m) and the walls
    soft (1e3 N/m): raising the stiff side changes nothing.  It names the keys below the
    stiffness (modulus) it recommends, each the overlap of 1 % needs on its own."""
    est = estimate_overlap(load_config(scenario, sets))
    assert est.too_soft
    text = est.warning()
    assert named in text, text
    if not_named is not None:
        assert not_named not in text, text


def test_grains_lost_through_soft_walls_are_all_counted():
    """Table 1's soft contacts squeeze grains out at the floor's corners.  Every grain poured is
    either still in the silo, discharged, or lost, and the warnings carry the same total as
    events/lost_count (the first loss alone named 2 of 65 grains before)."""
    run = SiloRun(small("flat", discharge__max_time=0.2))
    run.run()
    lost = run.events.get("lost_count", 0)
    assert lost > 1  # the case this test is about: several losses over the run
    assert run.sim.particles.n + run.discharged_count + lost == run.events["n_poured"]
    m = run.cfg.material
    poured = run.radii[: run.events["n_poured"]]
    mass0 = float(np.sum(m.density * math.pi * poured**2 * m.thickness))
    left = run.sim.particles.total_mass() + run.discharged_mass + run.state.lost_mass
    assert left == pytest.approx(mass0, rel=1e-12)
    totals = [w for w in run.warnings if w.startswith("grains lost in all: ")]
    assert len(totals) == 1
    assert totals[0].startswith(f"grains lost in all: {lost} grain(s) (")


def test_a_hopper_lined_otherwise_than_the_cell_has_its_own_wall_friction():
    """walls.hopper_friction_deg = 10 under a cell of 30 deg: the two hopper walls carry
    mu = tan 10 deg, the cell walls and the gate tan 30 deg; unset, every wall has the cell's.
    The report's hopper theory (Walker, EN 1991-4's hopper loads) reads the hopper's."""
    sets = ["walls.friction_deg=30"]
    lined = build_walls(load_config("paper-case2", [*sets, "walls.hopper_friction_deg=10"]))
    mu = dict(zip(lined.names, lined.mu))
    assert mu["left_hopper"] == mu["right_hopper"] == pytest.approx(math.tan(math.radians(10)))
    for name in ("left_wall", "right_wall", "gate"):
        assert mu[name] == pytest.approx(math.tan(math.radians(30)))
    same = build_walls(load_config("paper-case2", sets))
    assert set(np.round(same.mu, 12)) == {round(math.tan(math.radians(30)), 12)}
    flat = load_config("paper-case1", ["walls.hopper_friction_deg=10"])  # no hopper: no effect
    assert set(np.round(build_walls(flat).mu, 12)) == {round(math.tan(math.radians(26.5)), 12)}


def test_the_hopper_theory_reads_the_hopper_walls_friction(tmp_path):
    from silodem.report.analysis import analyse
    from silodem.report.load import load_results

    cfg = tiny_hopper_config()
    cfg = cfg.model_copy(update={"walls": cfg.walls.model_copy(
        update={"hopper_friction_deg": 12.0})})
    run_simulation(cfg, tmp_path, progress=False)
    a = analyse(load_results(tmp_path))
    assert a.geom["mu_wall"] == pytest.approx(math.tan(math.radians(24.0)))
    assert a.hopper["fill"]["mu"] == pytest.approx(math.tan(math.radians(12.0)))
    from silodem.report.figures_stress import fig_wall_shear

    e = a.edge["fill"]  # the fully mobilised line: each bin's own wall's friction
    line = next(ln for ln in fig_wall_shear(a).axes[0].get_lines()
                if ln.get_label().startswith("tan(phi_P) sigma_n") and "after" in
                ln.get_label())
    mu = np.where(e.on_vertical, math.tan(math.radians(24.0)), math.tan(math.radians(12.0)))
    np.testing.assert_allclose(line.get_xdata(), mu * e.sigma_n, rtol=1e-12)


def test_geometry_places_the_junction_where_the_paper_has_it():
    cfg = load_config("paper-case2")
    shape = silo_shape(cfg)
    assert shape.junction == pytest.approx(1.2, rel=1e-12)  # (3.4 - 1.0)/2 * tan 45
    walls = build_walls(cfg)
    assert walls.names == ["left_wall", "right_wall", "left_hopper", "right_hopper", "gate"]
    # the gate's ends are shared with the hopper walls, so they are not contact points
    g = walls.index("gate")
    assert walls.cap_a[g] != END_CAP and walls.cap_b[g] != END_CAP
    h = walls.index("left_hopper")
    assert (walls.bx[h], walls.by[h]) == (shape.outlet_left, 0.0)
    assert walls.cap_b[h] != END_CAP
    walls.set_active("gate", False)
    assert walls.cap_b[h] == END_CAP  # the outlet edge becomes a free end
    assert walls.cap_a[h] != END_CAP  # the junction stays shared with the vertical wall


def test_reinsertion_keeps_every_grain_and_its_radius_until_the_time_limit():
    """discharge.reinsert: each grain that leaves through the outlet comes back at the top with
    its radius (DESIGN section 2, steady-flow studies). Between every two chunks the grains in
    the silo and those waiting for a free spot are the poured grains: the same count and, as
    a multiset, the same radii (so the same mass, rho pi r^2 t each). The discharged mass
    counts every passage, so stop_fraction = 2 ends the run once twice the silo's initial
    mass has passed the outlet (above 1 only with re-insertion), and the silo still holds all
    its grains."""
    cfg = small(discharge__reinsert=True, discharge__stop_fraction=2.0,
                discharge__max_time=40.0)
    run = SiloRun(cfg)
    checked = []

    def conserved(r: SiloRun) -> None:
        if r.phase != "discharge":
            return
        inside = r.sim.particles.view("radius")
        radii = np.sort(np.concatenate([inside, r.state.pending_radii]))
        np.testing.assert_array_equal(radii, np.sort(r.radii))
        checked.append(r.sim.time)

    run.chunk_hooks.append(conserved)
    run.run()
    assert len(checked) > 20
    assert run.events["discharge_end_reason"] == "fraction"
    assert run.discharged_mass >= 2.0 * run.state.mass0
    m = cfg.material
    mass0 = float(np.sum(m.density * math.pi * run.radii**2 * m.thickness))
    pending = np.asarray(run.state.pending_radii)
    pending_mass = float(np.sum(m.density * math.pi * pending**2 * m.thickness))
    assert run.sim.particles.total_mass() + pending_mass == pytest.approx(mass0, rel=1e-12)


def test_kinetic_energy_criterion_ends_settling_below_its_threshold():
    """settle.criterion = "kinetic_energy": settling ends once the mean kinetic energy per
    grain, (1/N) sum (m v^2 / 2 + I omega^2 / 2) with m = rho pi r^2 t and I = m r^2 / 2,
    is below the threshold. The value recorded is that of the settled snapshot, recomputed
    here from its velocities, spins and radii."""
    threshold = 1e-4  # [J]
    cfg = small(settle__criterion="kinetic_energy", settle__threshold=threshold,
                discharge__enabled=False)
    run = SiloRun(cfg)
    run.run()
    snap = run.snapshots["settled"].particles
    m = cfg.material
    mass = m.density * math.pi * snap["radius"] ** 2 * m.thickness
    energy = 0.5 * mass * (snap["vx"] ** 2 + snap["vy"] ** 2) \
        + 0.25 * mass * snap["radius"] ** 2 * snap["omega"] ** 2
    value = run.events["settle_criterion_value"]
    assert value == pytest.approx(energy.mean(), rel=1e-12)
    assert 0 < value < threshold


def test_a_pour_cut_short_by_its_rate_says_so_not_that_there_was_no_room():
    """fill.rate = 20 grains/s for fill.max_time = 2 s pours about 40 of 155 grains: the
    warning blamed 'no room in the pouring band'; it now names the rate and what it pours."""
    cfg = quick_variant(load_config("paper-case2", ["fill.rate=20", "fill.max_time=2"]))
    run = SiloRun(cfg)
    while run.state.phase == "fill":
        run.advance_chunk()
    placed = run.events["n_poured"]
    assert 35 <= placed <= 45 < cfg.fill.n_particles  # 20 / s for 2 s, in batches
    expected = (f"pouring stopped after fill.max_time = 2.0 s with {placed} of "
                f"{cfg.fill.n_particles} grains placed: fill.rate = 20 grains/s pours only "
                "about 40 in that time")
    assert [w for w in run.warnings if w.startswith("pouring stopped")] == [expected]


def test_a_pour_cut_short_by_a_full_silo_says_so_not_that_the_rate_was_low():
    """1800 grains asked of the quick silo (0.36 x 5000) at 250 grains/s for 4 s: the rate
    lets in 1000, but fewer than half of those find room once the silo is full to the pouring
    band (an audit: the warning blamed the rate, 'pours only about 3.75e+03 in that time',
    with 176 grains placed)."""
    cfg = quick_variant(load_config("paper-case2", ["fill.n_particles=5000", "fill.max_time=4"]))
    run = SiloRun(cfg)
    while run.state.phase == "fill":
        run.advance_chunk()
    placed = run.events["n_poured"]
    assert placed < 0.5 * 250 * 4
    assert [w for w in run.warnings if w.startswith("pouring stopped")] == [
        (f"pouring stopped after fill.max_time = 4.0 s with {placed} of 1800 grains placed: no "
        "room in the pouring band: the silo is full up to it")]


def test_a_pour_slower_than_its_rate_with_the_silo_not_full_says_the_rate_reached():
    """paper-case2 with fill.max_time = 2 s: 250 grains/s asked, about 85/s placed (a batch
    places only the grains that find room in the band), 174 of 430 grains, which fill the
    silo to about 2.4 m at rest (their area at a packing of 0.82), far under the band at
    5.4 m: not 'the silo is full' (a review of the first wording), nor the rate's 500."""
    run = SiloRun(load_config("paper-case2", ["fill.max_time=2"]))
    while run.state.phase == "fill":
        run.advance_chunk()
    placed, took = run.events["n_poured"], run.events["fill_time"]
    assert placed < 0.5 * 250 * 2
    [warning] = [w for w in run.warnings if w.startswith("pouring stopped")]
    assert warning == (
        f"pouring stopped after fill.max_time = 2.0 s with {placed} of 430 grains placed: no "
        f"room in the pouring band for more: {placed / took:.3g} grains/s placed against "
        "fill.rate = 250 (a batch places only the grains that find room); give a longer "
        "fill.max_time")


def test_the_key_numbers_give_the_pouring_rate_reached():
    """fill.rate is an upper bound: paper-case2 asks 250 grains/s and its 430 grains took
    5.15 s, 430 / 5.15 = 83.5 grains/s.  A loose fill (placed at once) has no such row."""
    from types import SimpleNamespace

    from silodem.report.key_numbers import _pour_row

    cfg = load_config("paper-case2")
    a = SimpleNamespace(res=SimpleNamespace(cfg=cfg, events={"n_poured": 430,
                                                             "fill_time": 5.15}), numbers=[])
    _pour_row(a)
    assert a.numbers == [(("grains poured, time the filling took, mean rate (fill.rate = 250 "
                          "grains/s is an upper bound)"), "430 in 5.15 s: 83.5 grains/s", "-")]
    loose = SimpleNamespace(res=SimpleNamespace(cfg=load_config("paper-case2",
                                                                ["fill.method=loose"]),
                                                events=a.res.events), numbers=[])
    _pour_row(loose)
    assert loose.numbers == []


def test_progress_rate_leaves_out_the_time_before_the_first_report(monkeypatch):
    """The first progress line's rate counted the kernels' compilation (600 steps/s in a run
    that went at 40,000): it is NaN there, and after it the steps since the first report over
    the wall seconds since it, on a clock that ticks 1 s per reading."""
    from silodem.silo import procedure

    ticks = iter(range(1, 10**9))
    monkeypatch.setattr(procedure, "wallclock",
                        type("Clock", (), {"perf_counter": staticmethod(lambda: next(ticks))}))
    seen: list = []
    run = SiloRun(small(discharge__max_time=0.5), on_progress=seen.append)
    run.run()
    assert len(seen) > 3 and math.isnan(seen[0].steps_per_s)
    for k, pr in enumerate(seen[1:], start=1):
        assert pr.steps_per_s == (pr.steps - seen[0].steps) / k


def test_every_phase_is_reported_however_short(monkeypatch):
    """Reports come at most every 0.2 wall seconds: a settling shorter than that had no
    progress line in a log (fill, then discharge).  A new phase is reported at once: on a
    clock that never moves, the reports are the four phases, in order, once each."""
    from silodem.silo import procedure

    monkeypatch.setattr(procedure, "wallclock",
                        type("Clock", (), {"perf_counter": staticmethod(lambda: 5.0)}))
    seen: list = []
    run = SiloRun(small(discharge__max_time=0.5), on_progress=seen.append)
    run.run()
    assert [pr.phase for pr in seen] == ["fill", "settle", "discharge", "done"]


def test_a_grain_pushed_under_the_floor_after_the_gate_opens_is_lost_not_discharged():
    """At the gate's opening (stiff grains: none lost on their own), one grain is moved under
    the left hopper wall, halfway from the silo's edge to the outlet, and one under the
    outlet's middle, both below the removal height.  At the next chunk the first is lost
    (lost count, lost mass, the warning, the flow measurement's flag), not discharged, and
    the second discharged, with an exit time.  The discharged fraction is the discharged mass
    over the mass at the opening; the share held against stop_fraction leaves the lost grain's
    mass out (a lost grain can never leave through the outlet, so it must not keep the run
    from stopping)."""
    from silodem.measure.recorders import MeasureRecorder, recorders_for

    cfg = small()
    run = SiloRun(cfg, recorders=recorders_for(cfg))
    while run.phase != "discharge":
        run.advance_chunk()
    shape, p = run.shape, run.sim.particles
    room = outlet_room(cfg)
    x_beside = 0.5 * shape.outlet_left
    assert x_beside < shape.outlet_left - room  # the premise: clearly not under the outlet
    assert run.events.get("lost_count", 0) == 0 and run.discharged_count == 0
    x, y, uid, mass = p.view("x"), p.view("y"), p.view("uid"), p.view("mass")
    x[0], y[0] = x_beside, run.z_remove - 0.1
    x[1], y[1] = 0.5 * (shape.outlet_left + shape.outlet_right), run.z_remove - 0.1
    for name in ("vx", "vy", "omega"):
        p.view(name)[:2] = 0.0
    run.sim.invalidate()
    lost_uid, left_uid = int(uid[0]), int(uid[1])
    m_lost, m_left, mass0 = float(mass[0]), float(mass[1]), run.state.mass0
    run.advance_chunk()
    assert run.events["lost_count"] == 1 and run.state.lost_mass == m_lost
    assert run.discharged_count == 1 and run.discharged_mass == m_left
    assert run.discharged_fraction() == pytest.approx(m_left / mass0, rel=1e-12)
    assert run.stop_fraction_of() == pytest.approx(m_left / (mass0 - m_lost), rel=1e-12)
    assert any("through a wall during discharge" in w for w in run.warnings)
    flow = next(r for r in run.recorders if isinstance(r, MeasureRecorder)).flow
    at = {int(u): k for k, u in enumerate(flow.uid0)}
    assert flow.lost_later[at[lost_uid]] and not flow.lost_later[at[left_uid]]
    assert np.isnan(flow.exit_time[at[lost_uid]]) and np.isnan(flow.max_disp[at[lost_uid]])
    assert flow.exit_time[at[left_uid]] > 0
    assert flow.lost_later.sum() == 1


def test_a_grain_outside_the_silo_when_the_gate_opens_is_lost_wherever_it_falls(monkeypatch,
                                                                                tmp_path):
    """A grain pushed under the floor while filling (here: put under the left hopper wall,
    beside the outlet's span and its room, as the gate opens) may slide under the floor into
    the outlet's span and fall out there (here: put below the removal height under the
    outlet's middle). It was counted as discharged mass, while the flow measurement flagged
    it lost before the discharge, so the two disagreed (paper-case1 --quick: 3 such grains,
    164 kg). It is lost: the lost count and mass, not the discharged ones; every grain poured
    is in the silo, discharged or lost."""
    from silodem.measure.recorders import MeasureRecorder, recorders_for

    cfg = small()
    run = SiloRun(cfg, recorders=recorders_for(cfg))
    shape, p, room = run.shape, run.sim.particles, outlet_room(cfg)
    from silodem.silo import procedure

    snapshot = procedure.take_snapshot
    moved = {}

    def push_one_out_then_snapshot(silo_run):  # (the settled snapshot is taken at the opening)
        if not moved:
            k = 0
            moved["uid"], moved["mass"] = int(p.view("uid")[k]), float(p.view("mass")[k])
            p.view("x")[k] = shape.outlet_left - room - cfg.material.radius_max
            p.view("y")[k] = -cfg.material.radius_max
            for name in ("vx", "vy", "omega"):
                p.view(name)[k] = 0.0
            run.sim.invalidate()
        return snapshot(silo_run)

    monkeypatch.setattr(procedure, "take_snapshot", push_one_out_then_snapshot)
    while run.phase != "discharge":
        run.advance_chunk()
    assert run.state.pushed_out == [moved["uid"]]
    assert run.events.get("lost_count", 0) == 0 and run.discharged_count == 0
    # a checkpoint keeps the list; one written before it was kept gets it back from the
    # settled snapshot, taken at the opening (an empty list counted the grain discharged)
    import h5py

    from silodem.checkpoint import read_checkpoint, save_checkpoint
    from silodem.scenario_files import config_to_toml

    path = tmp_path / "checkpoint.h5"
    save_checkpoint(run, path, config_toml=config_to_toml(cfg), reason="test")
    resumed = SiloRun(cfg, recorders=recorders_for(cfg))
    read_checkpoint(path).restore(resumed)
    assert resumed.state.pushed_out == [moved["uid"]]
    with h5py.File(path, "r+") as h5:  # as an older silodem wrote it: no list, no digest
        del h5["run/state/pushed_out"]
        del h5.attrs["sha256"]
    older = SiloRun(cfg, recorders=recorders_for(cfg))
    read_checkpoint(path).restore(older)
    assert older.state.pushed_out == [moved["uid"]]
    k = int(np.flatnonzero(p.view("uid") == moved["uid"])[0])
    p.view("x")[k] = 0.5 * (shape.outlet_left + shape.outlet_right)  # slid under the outlet
    p.view("y")[k] = run.z_remove - 0.1  # and fell below the removal height
    run.sim.invalidate()
    assert shape.came_through_outlet(p.view("x")[k:k + 1], p.view("y")[k:k + 1], np.zeros(1),
                                     np.zeros(1), cfg.gravity, room)[0]  # (the premise)
    run.advance_chunk()
    assert run.events["lost_count"] == 1 and run.state.lost_mass == moved["mass"]
    assert moved["uid"] not in p.view("uid")
    assert run.sim.particles.n + run.discharged_count + 1 == run.events["n_poured"]
    flow = next(r for r in run.recorders if isinstance(r, MeasureRecorder)).flow
    at = int(np.flatnonzero(flow.uid0 == moved["uid"])[0])
    assert flow.lost[at] and not flow.lost_later[at] and np.isnan(flow.exit_time[at])


def test_came_through_outlet_traces_the_fall_back_to_the_outlet():
    """The tiny hopper's outlet spans x = 0.4-0.8 m; with 0.1 m of room a grain that crossed
    z = 0 at 0.31-0.89 m came through it, one at 0.29 or 0.91 m (under a hopper wall) did
    not.  Grains at rest under the outlet line are judged where they are.  A grain at
    z = -0.2 m falling at vz = -3 m/s under g = 10 crossed z = 0 s before, z = vz s + g s^2/2:
    s = (3 - sqrt(9 - 4)) / 10 = 0.0764 s; at vx = -2 m/s it was 0.153 m further right: seen
    at x = 0.70 m it crossed at 0.853 m (in), at x = 0.76 m at 0.913 m (out).  Without gravity
    a grain at vz = -2 m/s went straight, s = 0.1 s."""
    from measure_helpers import tiny_hopper_config

    shape = silo_shape(tiny_hopper_config())
    assert (shape.outlet_left, shape.outlet_right) == pytest.approx((0.4, 0.8))
    x = np.array([0.29, 0.31, 0.6, 0.89, 0.91, -0.5, 1.5])
    zero = np.zeros(x.size)
    got = shape.came_through_outlet(x, zero - 0.01, zero, zero, 9.81, 0.1)
    np.testing.assert_array_equal(got, [False, True, True, True, False, False, False])
    s = (3.0 - math.sqrt(9.0 - 4.0)) / 10.0
    assert 0.70 + 2.0 * s == pytest.approx(0.853, abs=1e-3)  # the premise of the numbers
    got = shape.came_through_outlet([0.70, 0.76], [-0.2, -0.2], [-2.0, -2.0], [-3.0, -3.0],
                                    10.0, 0.1)
    np.testing.assert_array_equal(got, [True, False])
    got = shape.came_through_outlet([0.78, 0.62], [-0.2, -0.2], [-1.5, 1.2], [-2.0, -2.0],
                                    0.0, 0.1)  # crossed at 0.93 (out) and 0.50 (in)
    np.testing.assert_array_equal(got, [False, True])
    assert outlet_room(tiny_hopper_config()) == pytest.approx(2 * 0.055)
