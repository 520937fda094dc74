"""`silodem validate`: the quick suite passes, its records carry the tolerances the issue states,
and the pure functions of the suite agree with algebra and with numerical integration done here
independently."""

from __future__ import annotations

import itertools
import json
import math
import shutil
import subprocess
import sys

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from silodem.validate.chung_ooi import (
    rigid_pair_impact,
    rigid_wall_impact,
    sliding_limit,
    sticking_tangential_restitution,
)
from silodem.validate.hertz_mindlin import textbook_moduli
from silodem.validate.impacts import convergence_order, spring_dashpot
from silodem.validate.records import Record

FIELDS = {"case", "quantity", "expected", "got", "tolerance", "pass"}


def passes(r: dict) -> bool:
    """A JSON record that is a passed check, or an info record (reported, not judged: its
    ``pass`` is null)."""
    if r["tolerance_kind"] == "info":
        return r["pass"] is None
    return r["pass"] is True


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("validation")
    proc = subprocess.run([sys.executable, "-m", "silodem", "validate", "--quick", "--json",
                           "--out", str(out)], capture_output=True, text=True, timeout=600,
                          check=False)
    return proc, out


def test_quick_validation_exits_0_and_every_record_passes(quick_run):
    proc, out = quick_run
    assert proc.returncode == 0, proc.stderr[-2000:]
    records = json.loads(proc.stdout)  # nothing but the JSON list on stdout
    assert isinstance(records, list) and len(records) > 100
    for r in records:
        assert FIELDS <= set(r), r
        assert passes(r), r
    for name in ("impacts", "chung_ooi", "hertz_mindlin", "statics"):
        assert (out / f"{name}.png").stat().st_size > 1000


@pytest.mark.slow
def test_janssen_validation_passes_every_check(tmp_path):
    """The silo-scale Janssen family of the full suite (docs/validation.md, section 4: the
    settled column's wall stresses against Janssen's 2D slot solution, K and mu_w fitted, and
    against the fill's own Love-Weber ratio): every check within its stated tolerance.
    A few minutes, so marked slow (deselect with -m 'not slow'); CI runs it."""
    proc = subprocess.run([sys.executable, "-m", "silodem", "validate", "--case", "janssen",
                           "--json", "--out", str(tmp_path)], capture_output=True, text=True,
                          timeout=1800, check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    records = json.loads(proc.stdout)
    assert len(records) > 5
    for r in records:
        assert FIELDS <= set(r), r
        assert passes(r), r



@pytest.mark.slow
def test_beverloo_validation_exponent_and_rates(tmp_path):
    """The silo-scale Beverloo family of the full suite (docs/validation.md, section 5): five
    outlet widths D/d = 6..30 in one silo, two fills each. The exponent b of W = A (D - k d)^b
    fitted with A, k, b free is the 2D Beverloo law's 3/2 within 0.1 (Mankoc et al. 2007,
    Janda et al. 2012), and the rate grows with the outlet. The family's fill-height check is
    known to fail with this contact law (issue 6, blocked on the owner's choice; section 5):
    the test asserts every other check, and that one failing (exit code 1), as a strict
    expected failure: should it pass one day, this test says so. About 11 minutes, so
    marked slow; CI runs it."""
    proc = subprocess.run([sys.executable, "-m", "silodem", "validate", "--case", "beverloo",
                           "--json", "--out", str(tmp_path)], capture_output=True, text=True,
                          timeout=3600, check=False)
    assert proc.returncode == 1, proc.stderr[-2000:]  # the fill-height check, below
    records = json.loads(proc.stdout)
    for r in records:
        assert FIELDS <= set(r), r
    exponent = [r for r in records if r["quantity"].startswith("exponent b of W")]
    assert len(exponent) == 1
    assert exponent[0]["expected"] == 1.5 and exponent[0]["tolerance"] == 0.1
    assert abs(exponent[0]["got"] - 1.5) <= 0.1, exponent[0]
    assert exponent[0]["pass"] is True
    rates = [r["got"] for r in records if r["quantity"] == "steady discharge rate W"]
    assert len(rates) == 5
    assert all(b > a > 0 for a, b in itertools.pairwise(rates)), rates
    checked = [r for r in records if r["tolerance_kind"] != "info"]
    height = [r for r in checked if "fill height" in r["quantity"]]
    assert len(height) == 1 and height[0]["tolerance"] == 0.05
    assert height[0]["pass"] is False, "the fill-height check passes now: update issue 6"
    assert all(r["pass"] is True for r in checked if r not in height), checked


def _tolerances(records, quantity):
    found = {(r["tolerance_kind"], r["tolerance"]) for r in records if r["quantity"] == quantity}
    assert found, quantity
    return found


def test_quick_validation_uses_the_stated_tolerances(quick_run):
    records = json.loads(quick_run[0].stdout)
    # normal impacts: the scheme's own error, first order for a damped impact (1.5 |ln e|
    # dt/t_c on e, |ln e| dt/t_c + (dt/t_c)^2 on the duration), round-off on an undamped e
    for r in records:
        case = r["case"]
        if not case.startswith("normal impact, disk-") or "paper-case2" in case or ".." in case:
            continue  # the silo's time step (reported) and the convergence orders
        e = float(case.split("e=")[1].split(",")[0])
        n = int(case.split("dt=t_c/")[1].split()[0].rstrip(")"))
        if r["quantity"] == "restitution" and r["tolerance_kind"] == "rel":
            assert r["tolerance"] == pytest.approx(1.5 * abs(math.log(e)) / n + 1e-9), case
            if e == 1.0:
                assert r["tolerance"] < 2e-9
        elif r["quantity"] == "contact duration":
            assert r["tolerance"] == pytest.approx(abs(math.log(e)) / n + 1 / n**2), case
    # settled column: floor + walls = weight + rate of change of momentum, to round-off;
    # the column at rest within 1e-3 of its weight
    assert _tolerances(records, "vertical force of the grains on floor + walls") == {
        ("rel", 1e-9)}
    assert _tolerances(records, "Delta P_y / T / weight over the window (the column at "
                                "rest)") == {("abs", 1e-3)}
    # Chung & Ooi's gross sliding (test 4): e's first-order error at 500 steps, e = 0.98
    [(kind, tol)] = _tolerances(records, "friction's share 1 - v_t'/v_t")
    assert kind == "rel" and tol == pytest.approx(1.5 * abs(math.log(0.98)) / 500 + 1e-9)
    # around the change from sticking to sliding (tests 5-8): 0.5 %
    assert _tolerances(records, "normalised spin w'R/(mu(1+e)v_n)") == {("rel", 0.005)}
    cases = {r["case"] for r in records}
    for e in ("0.1", "0.3", "0.5", "0.7", "0.9", "1"):  # e spans [0.1, 1]
        for geometry in ("disk-disk", "disk-wall"):
            assert any(f"{geometry}, e={e}," in c for c in cases), (geometry, e)
    for n in range(4, 9):  # Chung & Ooi tests 4-8
        assert any(c.startswith(f"Chung-Ooi {n},") for c in cases), n
    # every sliding angle of test 4 from 30 to 85 deg is checked
    angles = {int(c.split("angle ")[1].split(" ")[0]) for c in cases if "angle " in c}
    assert set(range(30, 90, 5)) <= angles


def test_quick_validation_expects_nominal_e_and_series_stiffnesses(quick_run):
    """The expected values come from outside the engine: with tension, the nominal e asked
    for (not exp(-zeta pi/sqrt(1 - zeta^2)) of the engine's zeta), and the contact durations
    of paper-case2's constants from k_a k_b / (k_a + k_b) of its body stiffnesses."""
    records = json.loads(quick_run[0].stdout)
    tension = [r for r in records if r["case"].startswith("normal impact")
               and ", tension, dt=t_c/" in r["case"] and r["quantity"] == "restitution"]
    assert len(tension) == 2 * 6 * 3 + 1  # the checked impacts and paper-case2's dt
    for r in tension:
        assert r["expected"] == float(r["case"].split("e=")[1].split(",")[0]), r
    series = [r for r in records if "paper-case2's contact constants" in r["case"]]
    assert {r["case"].split(", ")[1] for r in series} == {"grain-grain", "grain-wall"}
    # walls four times as stiff as the grains (5e6 N/m): 4e6 N/m in series, by hand
    from silodem.validate.impacts import R1, disk_mass

    wall = next(r for r in series if ", grain-wall, " in r["case"])
    assert wall["expected"] == pytest.approx(math.pi * math.sqrt(disk_mass(R1) / 4e6),
                                             rel=1e-12)
    # undamped: second order in dt / t_c = 1 / 1000
    assert all(r["tolerance"] == pytest.approx(1e-6) and r["pass"] is True
               for r in series), series


def test_textbook_moduli_of_the_hertz_check():
    # nu = 0: E* = E/2 for two equal bodies; G = E/2, 1/G* = 2/G + 2/G  =>  G* = E/8
    assert textbook_moduli(1.0, 0.0, 1.0, 0.0) == pytest.approx((0.5, 0.125), rel=1e-15)
    # a rigid wall: E* = E/(1 - nu^2), G* = G/(2 - nu)
    e_star, g_star = textbook_moduli(2.0, 0.25, math.inf, 0.3)
    assert e_star == pytest.approx(2.0 / (1 - 0.25**2), rel=1e-15)
    assert g_star == pytest.approx(2.0 / 2.5 / 1.75, rel=1e-15)


@pytest.mark.skipif(shutil.which("lmp") is None, reason="LAMMPS (Debian package lammps) absent")
def test_quick_validation_follows_lammps_grain_by_grain(quick_run):
    records = [r for r in json.loads(quick_run[0].stdout)
               if r["case"].startswith("LAMMPS trajectories")]
    assert len(records) == 3  # two clouds of the linear law, one of the Hertz law
    assert {(r["tolerance_kind"], r["tolerance"]) for r in records} == {("abs", 1e-6)}
    assert all(r["pass"] for r in records)


@pytest.mark.skipif(shutil.which("lmp") is None, reason="LAMMPS (Debian package lammps) absent")
def test_lammps_comparison_sees_a_difference_of_law():
    """The check has teeth: with tension allowed LAMMPS keeps a Coulomb cap of mu |F_n| while
    the damped normal force pulls, silodem a cap of 0, and the colliding cloud parts by far
    more than the tolerance within the first collisions (500 steps)."""
    from silodem.validate.lammps import TOLERANCE, cloud, divergence

    dev = divergence(cloud(60, 0.3), 500, 500, tension=True)
    assert dev[-1] > 100 * TOLERANCE


@pytest.mark.skipif(shutil.which("lmp") is None, reason="LAMMPS (Debian package lammps) absent")
def test_lammps_hertz_comparison_sees_a_one_percent_stiffer_law(monkeypatch):
    """The Hertz check has teeth: a LAMMPS law 1 % stiffer than silodem's parts the cloud by
    far more than the tolerance within 1,000 steps (measured 8e-5 m), so the grains collide
    and the comparison sees their law."""
    import silodem.validate.lammps as lm

    state = lm.cloud(60, 0.3)
    ours = lm.run_silodem(state, 1000, 1000, hertz=True)
    monkeypatch.setattr(lm, "HERTZ_KN", 1.01 * lm.HERTZ_KN)
    theirs = lm.run_lammps(state, 1000, 1000, hertz=True)
    assert np.abs(ours[-1] - theirs[-1]).max() > 10 * lm.TOLERANCE


@pytest.mark.skipif(shutil.which("lmp") is None, reason="LAMMPS (Debian package lammps) absent")
def test_lammps_comparison_sees_a_shear_spring_of_the_normal_stiffness(monkeypatch):
    """With k_s = k_n in every check, a law that took k_n for the shear spring passed the
    whole suite. The comparison runs k_s = k_n / 2 in both codes: silodem given k_n for it
    parts the walls-only cloud from LAMMPS by far more than the tolerance (2.6e-2 m)."""
    import silodem.validate.lammps as lm

    state = lm.cloud(20, 0.42)
    theirs = lm.run_lammps(state, 1500, 1500)
    monkeypatch.setattr(lm, "KS", lm.K)
    ours = lm.run_silodem(state, 1500, 1500)
    assert np.abs(ours[-1] - theirs[-1]).max() > 1000 * lm.TOLERANCE


def test_validate_refuses_an_out_that_is_a_file(tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    proc = subprocess.run([sys.executable, "-m", "silodem", "validate", "--quick", "--out",
                           str(f)], capture_output=True, text=True, timeout=120,
                          check=False)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and len(proc.stderr.strip().splitlines()) == 1


def _statics(out) -> tuple[subprocess.CompletedProcess[str], list[dict]]:
    """``silodem validate --case statics --json --out OUT``: exit 0 and records that all pass."""
    proc = subprocess.run([sys.executable, "-m", "silodem", "validate", "--case", "statics",
                           "--json", "--out", str(out)], capture_output=True, text=True,
                          timeout=300, check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    records = json.loads(proc.stdout)
    assert records and all(passes(r) for r in records)
    return proc, records


def test_validate_case_runs_only_the_named_family(tmp_path):
    """``--case statics``: the settled column's records and figure, nothing of the others;
    its check is a conservation law (floor + walls carry the weight)."""
    _, records = _statics(tmp_path)
    assert {r["case"].split(",")[0] for r in records} == {"settled column"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["statics.png"]


def test_a_figure_that_cannot_be_written_keeps_the_records(tmp_path):
    """A folder where statics.png should go (or a full disk) made the whole validation end with
    exit code 2, the bad-input code, and nothing on stdout: every record lost.  The records are
    now printed and judged as ever (exit 0: they pass), with a warning naming the figure; the
    progress line counts checks apart from reported values, as the table does."""
    (tmp_path / "statics.png").mkdir()
    proc, records = _statics(tmp_path)
    checked = sum(r["tolerance_kind"] != "info" for r in records)
    lines = proc.stderr.strip().splitlines()
    assert any(line.startswith("validate: warning: statics.png not written (") for line in lines)
    assert any(f": {checked} checks ({len(records) - checked} reported values), 0 failed," in line
               for line in lines), lines
    assert "Traceback" not in proc.stderr


@pytest.mark.parametrize("args, words", [
    (["--case", "nosuch"], ["--case", "nosuch", "janssen"]),
    (["--case", "janssen", "--quick"], ["--quick", "--case"]),
])
def test_validate_case_refuses_bad_names_in_one_line(tmp_path, args, words):
    out = tmp_path / "figures"
    proc = subprocess.run([sys.executable, "-m", "silodem", "validate", *args, "--out",
                           str(out)], capture_output=True, text=True, timeout=120,
                          check=False)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert "Traceback" not in proc.stderr and len(lines) == 1
    assert lines[0].startswith("error: ")
    assert all(w in lines[0] for w in words), lines[0]
    assert not out.exists()  # refused before any work, even the folder


# --- pure functions ------------------------------------------------------------------------------


def test_sticking_limit_of_a_disk_is_two_thirds():
    # a disk (I = m R^2 / 2) leaving the wall rolling without slip: impulse P on the centre
    # gives v' = v - P/m, w' R = -P R^2 / I = -2 P/m, and v' + w' R = 0  =>  v' = 2 v / 3
    assert sticking_tangential_restitution(0.5) == pytest.approx(2.0 / 3.0, rel=1e-15)
    assert sticking_tangential_restitution(0.4) == pytest.approx(5.0 / 7.0, rel=1e-15)  # sphere
    assert sliding_limit(0.5) == pytest.approx(3.0)
    assert sliding_limit(0.4) == pytest.approx(3.5)


def test_rigid_wall_impact_sticks_below_psi_3_and_slides_above_continuously():
    r, e, mu, vn = 0.1, 0.8, 0.3, 1.0
    s = mu * (1 + e) * vn
    stick = rigid_wall_impact(vn, 2.0 * s, 0.0, r, e, mu)  # Psi_1 = 2 < 3: sticks
    assert not stick.sliding
    assert stick.vt + stick.omega * r == pytest.approx(0.0, abs=1e-14)  # rolls off
    assert stick.vt / (2.0 * s) == pytest.approx(2.0 / 3.0)
    slide = rigid_wall_impact(vn, 5.0 * s, 0.0, r, e, mu)  # Psi_1 = 5 > 3
    assert slide.sliding
    assert slide.vt == pytest.approx(5.0 * s - s)  # tangential impulse = mu x normal impulse
    assert slide.omega * r == pytest.approx(-2.0 * s)
    assert slide.vn == pytest.approx(e * vn)
    # continuous at the limit
    a = rigid_wall_impact(vn, 3.0 * s * (1 - 1e-9), 0.0, r, e, mu)
    b = rigid_wall_impact(vn, 3.0 * s * (1 + 1e-9), 0.0, r, e, mu)
    assert a.vt == pytest.approx(b.vt, rel=1e-8) and a.omega == pytest.approx(b.omega, rel=1e-8)


def test_rigid_pair_impact_conserves_momentum_and_angular_momentum():
    m1, m2, r1, r2 = 1.0, 3.0, 0.1, 0.2
    for w1, w2 in ((5.0, 5.0), (40.0, -3.0), (0.5, 0.2)):
        out = rigid_pair_impact(m1, m2, r1, r2, 1.0, 0.2, -0.1, w1, w2, 0.7, 0.4)
        assert m1 * out.vt1 + m2 * out.vt2 == pytest.approx(m1 * 0.2 + m2 * -0.1, abs=1e-14)
        # angular momentum about the contact point (x = r1, on the line of centres): the
        # impulse acts there, so it is conserved: -m1 r1 vt1 + I1 w1 + m2 r2 vt2 + I2 w2
        def L(vt1, vt2, a, b):
            return -m1 * r1 * vt1 + 0.5 * m1 * r1**2 * a + m2 * r2 * vt2 + 0.5 * m2 * r2**2 * b
        assert L(out.vt1, out.vt2, out.omega1, out.omega2) == pytest.approx(
            L(0.2, -0.1, w1, w2), abs=1e-12)


def _integrate_impact(k, m, zeta, tension):
    """Integrate m x'' = -F, F = k x + c x' (cut at zero without tension) from x = 0, x' = 1
    until the contact ends, with scipy (rtol 1e-11): duration and rebound speed."""
    c = 2.0 * zeta * math.sqrt(k * m)

    def rhs(t, y):
        f = k * y[0] + c * y[1]
        if not tension:
            f = max(f, 0.0)
        return [y[1], -f / m]

    def overlap_zero(t, y):
        return y[0] if t > 0 else 1.0

    def force_zero(t, y):
        return k * y[0] + c * y[1] if t > 1e-12 else 1.0

    overlap_zero.terminal = force_zero.terminal = True
    overlap_zero.direction = force_zero.direction = -1
    events = [overlap_zero] if tension else [overlap_zero, force_zero]
    sol = solve_ivp(rhs, (0.0, 10.0 * math.pi * math.sqrt(m / k)), [0.0, 1.0], rtol=1e-11,
                    atol=1e-14, events=events)
    t_end = min(ev[0] for ev in sol.t_events if len(ev))
    return t_end, -sol.y[1, -1]


@pytest.mark.parametrize("zeta", [0.0, 0.2, 0.5, 0.65])
@pytest.mark.parametrize("tension", [True, False])
def test_spring_dashpot_formulas_match_numerical_integration(zeta, tension):
    k, m = 2.0e5, 0.3
    ref = spring_dashpot(k, m, zeta)
    t_end, e = _integrate_impact(k, m, zeta, tension)
    assert ref.duration(tension) == pytest.approx(t_end, rel=1e-7)
    assert ref.restitution(tension) == pytest.approx(e, rel=1e-7)


def test_convergence_order_of_a_power_law():
    steps = np.array([50, 100, 200, 400])
    assert convergence_order(steps, 3.0 / steps) == pytest.approx(1.0)
    assert convergence_order(steps, -7.0 / steps**2) == pytest.approx(2.0)


def test_record_pass_rules():
    assert Record("c", "q", 1.0, 1.004, 5e-3).passed
    assert not Record("c", "q", 1.0, 1.006, 5e-3).passed
    assert Record("c", "q", 0.0, 0.09, 0.1, "abs").passed
    assert not Record("c", "q", 0.0, float("nan"), 0.1, "abs").passed
    assert Record("c", "q", None, 3.0, None, "info").passed
    assert Record("c", "q", 1.0, float("nan"), 0.1).to_dict()["got"] is None


def test_json_pass_is_null_only_for_a_record_not_judged():
    """An info record never fails the run, but its JSON says it was not checked; a check
    says whether it passed (1.004 within 0.5 % of 1, 1.006 not)."""
    assert Record("c", "q", None, 3.0, None, "info").to_dict()["pass"] is None
    assert Record("c", "q", 1.0, 1.004, 5e-3).to_dict()["pass"] is True
    assert Record("c", "q", 1.0, 1.006, 5e-3).to_dict()["pass"] is False


def test_beverloo_fits_recover_known_laws():
    from silodem.theory import fit_beverloo_free as fit_free
    from silodem.theory import fit_beverloo_three_halves as fit_three_halves

    d, rho, g, t = 0.01, 2000.0, 9.81, 0.01
    D = np.array([6.0, 9.0, 13.5, 20.0, 30.0]) * d
    for C, k, b in ((0.6, 1.4, 1.5), (0.9, 2.0, 1.5), (0.5, 1.0, 1.7)):
        W = C * rho * math.sqrt(g) * (D - k * d) ** b * t
        fit = fit_free(D, W, 0.01 * W, d, rho, g, t)
        assert (fit.C, fit.k, fit.b) == pytest.approx((C, k, b), rel=1e-4)
        if b == 1.5:
            lin = fit_three_halves(D, W, d, rho, g, t)
            assert (lin.C, lin.k) == pytest.approx((C, k), rel=1e-9)


def test_a_failed_check_is_named_with_its_miss_and_note():
    from silodem.validate.runner import failure_line

    line = failure_line(Record("Beverloo", "rate at 2 x H", 1.445, 1.548, 0.05, "rel", "kg/s",
                               "see section 5"))
    # (1.548 - 1.445) / 1.445 = +7.13 %, against the 5 % allowed
    assert "expected 1.445 kg/s, got 1.548 kg/s (+7.1 % against 5 %); see section 5" in line
    line = failure_line(Record("c", "offset", 0.0, -0.25, 0.1, "abs", "m"))
    assert "(-0.25 m against +- 0.1)" in line and line.startswith("FAILED c: offset:")


def test_run_validation_refuses_an_unknown_case_before_running_any():
    from silodem.validate.runner import run_validation

    said = []
    with pytest.raises(ValueError, match="unknown validation case 'nosuch'.*statics"):
        run_validation(only=["statics", "nosuch"], progress=said.append)
    assert said == []


def test_the_table_prints_every_unit_and_bracket_as_written():
    """rich read ' [s]', ' [m/s]', ' [deg]' after a quantity as markup tags and printed none
    of them: 164 of 331 records lost their unit.  Each row now shows its text as written."""
    from rich.console import Console

    from silodem.validate.runner import Validation, print_table

    units = ["s", "m", "m/s", "rad/s", "deg", "N", "kg/s", "Pa"]
    records = [Record("impact [bold]e = 0.5[/bold]", f"q{k}", 1.0, 1.0, 0.1, "rel", unit)
               for k, unit in enumerate(units)]
    console = Console(record=True, width=200, color_system=None)
    print_table(Validation(records=records), console)
    text = console.export_text()
    for k, unit in enumerate(units):
        assert f"q{k} [{unit}]" in text, text
    assert text.count("impact [bold]e = 0.5[/bold]") == len(units), text
