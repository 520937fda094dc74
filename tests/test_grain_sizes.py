"""Grain size distributions (silo/sizes.py): the draws against their densities, the moments
against numerical integrals of those densities, exact counts of discrete mixtures, a run with
a binary mixture, and the refusals of inconsistent size keys."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy import integrate
from test_input_errors import assert_names, refused

from silodem.config import Config, Material
from silodem.scenario_files import load_config, quick_variant
from silodem.silo import sizes
from silodem.silo.checks import PACKING_FRACTION, estimate_overlap
from silodem.silo.geometry import silo_shape
from silodem.silo.procedure import SiloRun, neighbour_skin
from silodem.study.plan import config_hash

A, B = 0.1, 0.3  # radius range of the continuous distributions [m]


def material(**keys) -> Material:
    base = {"density": 2000.0, "radius_min": A, "radius_max": B, "kn": 1e6, "ks": 1e6,
            "friction_deg": 20.0}
    return Material.model_validate({**base, **keys})


def density(m: Material):
    """The probability density of r that docs/physics.md gives for ``m``'s distribution."""
    if m.radius_distribution == "uniform_mass":
        return lambda r: A * B / ((B - A) * r * r)
    return lambda r: 1.0 / (B - A)


@pytest.mark.parametrize("kind", ["uniform", "uniform_mass"])
def test_moments_are_the_integrals_of_the_density(kind):
    m = material(radius_distribution=kind)
    p = density(m)
    assert integrate.quad(p, A, B)[0] == pytest.approx(1.0, rel=1e-12)
    assert sizes.mean_radius(m) == pytest.approx(integrate.quad(lambda r: r * p(r), A, B)[0],
                                                 rel=1e-12)
    assert sizes.mean_square_radius(m) == pytest.approx(
        integrate.quad(lambda r: r * r * p(r), A, B)[0], rel=1e-12)


def test_uniform_mass_draws_equal_mass_in_equal_radius_intervals():
    """Four equal radius intervals each hold a quarter of the drawn grains' mass (r^2), and
    the numbers in them follow the density's integrals. With 4e5 draws a share's standard
    deviation is below 1e-3; the bound is five of them."""
    m = material(radius_distribution="uniform_mass")
    r = sizes.draw_radii(m, 400_000, np.random.default_rng(7))
    assert r.min() >= A and r.max() <= B
    edges = np.linspace(A, B, 5)
    index = np.digitize(r, edges[1:-1])
    mass_share = np.bincount(index, weights=r * r) / np.sum(r * r)
    np.testing.assert_allclose(mass_share, 0.25, atol=5e-3)
    number_share = np.bincount(index) / r.size
    expected = [integrate.quad(density(m), lo, hi)[0] for lo, hi in itertools.pairwise(edges)]
    np.testing.assert_allclose(number_share, expected, atol=5e-3)
    assert r.mean() == pytest.approx(sizes.mean_radius(m), rel=2e-3)


def test_uniform_draws_are_numpys_single_uniform_call():
    """A config without the new keys draws the grains every earlier run drew (one
    ``Generator.uniform`` call on the seed), and keeps its study hash."""
    cfg = quick_variant(load_config("paper-case2"))
    run = SiloRun(cfg)
    m = cfg.material
    expected = np.random.default_rng(cfg.seed).uniform(m.radius_min, m.radius_max,
                                                       cfg.fill.n_particles)
    np.testing.assert_array_equal(run.radii, expected)
    assert neighbour_skin(cfg) == 0.4 * 0.5 * (m.radius_min + m.radius_max)
    data = cfg.model_dump()
    data["material"]["radius_distribution"] = "uniform_mass"
    assert config_hash(Config.model_validate(data)) != config_hash(cfg)


@pytest.mark.parametrize(("share", "n", "counts"), [
    ([0.3, 0.7], 1001, [300, 701]),  # 300.3 and 700.7: the larger remainder gets the grain
    ([1 / 3, 1 / 3, 1 / 3], 100, [34, 33, 33]),  # ties: the first size
    ([0.5, 0.5], 10, [5, 5]),
])
def test_discrete_counts_are_exact_by_largest_remainder(share, n, counts):
    assert sizes.discrete_counts(np.array(share), n).tolist() == counts


def small_mixture(**keys) -> Config:
    cfg = quick_variant(load_config("paper-case2"))
    data = cfg.model_dump()
    data["fill"]["n_particles"] = 120
    data["discharge"]["max_time"] = 4.0
    data["material"] = {**data["material"], "radius_distribution": "discrete",
                        "radii": [0.08, 0.12], "radius_shares": [0.25, 0.75], **keys}
    del data["material"]["radius_min"], data["material"]["radius_max"]
    return Config.model_validate(data)


def test_binary_mixture_runs_with_its_exact_composition():
    """30 grains of 0.08 m and 90 of 0.12 m (shares 0.25 and 0.75 of 120), shuffled; radius_min
    and radius_max come from the radii; the overlap check's fill height is the area of those
    grains at the packing fraction; the whole run conserves their mass."""
    cfg = small_mixture()
    m = cfg.material
    assert (m.radius_min, m.radius_max) == (0.08, 0.12)
    run = SiloRun(cfg)
    values, counts = np.unique(run.radii, return_counts=True)
    assert values.tolist() == [0.08, 0.12] and counts.tolist() == [30, 90]
    assert not np.all(np.diff(run.radii) >= 0)  # shuffled, not sorted
    solid = (30 * 0.08**2 + 90 * 0.12**2) * math.pi
    assert estimate_overlap(cfg).fill_height == pytest.approx(
        silo_shape(cfg).height_of_area(solid / PACKING_FRACTION), rel=1e-12)
    assert neighbour_skin(cfg) == pytest.approx(0.4 * (0.25 * 0.08 + 0.75 * 0.12), rel=1e-15)
    run.run()
    mass0 = m.density * math.pi * m.thickness * np.sum(run.radii[: run.events["n_poured"]] ** 2)
    assert run.sim.particles.total_mass() + run.discharged_mass + run.state.lost_mass == \
        pytest.approx(mass0, rel=1e-12)
    assert set(np.unique(run.sim.particles.view("radius"))) <= {0.08, 0.12}


def test_same_seed_same_mixture_other_seed_other_order():
    a, b = SiloRun(small_mixture()).radii, SiloRun(small_mixture()).radii
    np.testing.assert_array_equal(a, b)
    data = small_mixture().model_dump()
    data["seed"] += 1
    c = SiloRun(Config.model_validate(data)).radii
    assert np.sort(c).tolist() == np.sort(a).tolist() and not np.array_equal(a, c)


@pytest.mark.parametrize(("sets", "needles"), [
    (["material.radii=[0.1, 0.2]"], ("material.radii", "radius_distribution = 'discrete'")),
    (["material.radius_distribution=\"discrete\""], ("material.radii",)),
    (["material.radius_distribution=\"discrete\"", "material.radii=[0.09, 0.11]",
      "material.radius_shares=[1.0]"], ("radius_shares", "1 values for 2 radii")),
    (["material.radius_distribution=\"discrete\"", "material.radii=[0.09, 0.11]",
      "material.radius_shares=[0.5, 0.6]"], ("radius_shares", "sum to 1.1")),
    (["material.radius_distribution=\"discrete\"", "material.radii=[0.09, 0.1]"],
     ("material.radius_max (0.11)", "largest", "material.radius_max = 0.1")),
    (["material.radius_distribution=\"discrete\"", "material.radii=[0.09, -0.11]"],
     ("material.radii", "positive")),
    (["material.radius_distribution=\"discrete\"", "material.radii=[0.09, 0.09, 0.11]"],
     ("material.radii", "repeat")),
    (["material.radius_distribution=\"lognormal\""], ("material.radius_distribution",)),
])
def test_inconsistent_size_keys_are_refused_in_one_line(capsys, sets, needles):
    args = ["show", "paper-case2"]
    for s in sets:
        args += ["--set", s]
    assert_names(refused(capsys, *args), *needles)


def test_uniform_mass_of_one_size_is_that_size_and_keeps_the_random_stream():
    """r_min = r_max: every radius is exactly r_min (1 / (1 / a) need not be a), and the draw
    takes the n numbers the general case takes, so what the seed draws next is the same."""
    m = material(radius_min=0.013, radius_max=0.013, radius_distribution="uniform_mass")
    rng, ref = np.random.default_rng(5), np.random.default_rng(5)
    r = sizes.draw_radii(m, 1000, rng)
    assert np.all(r == 0.013)
    ref.uniform(0.0, 1.0, 1000)
    assert rng.bit_generator.state == ref.bit_generator.state
    assert sizes.mean_radius(m) == 0.013 and sizes.mean_square_radius(m) == 0.013**2


def test_the_sizes_in_words():
    assert sizes.describe(material()) == "uniform in [0.1, 0.3]"
    assert sizes.describe(material(radius_distribution="uniform_mass")) == (
        "equal mass per radius interval in [0.1, 0.3]")
    binary = material(radius_distribution="discrete", radii=[0.08, 0.12],
                      radius_shares=[0.25, 0.75], radius_min=0.08, radius_max=0.12)
    assert sizes.describe(binary) == "0.08 (25 %), 0.12 (75 %)"
    equal = material(radius_distribution="discrete", radii=[0.08, 0.1, 0.12],
                     radius_min=0.08, radius_max=0.12)
    assert sizes.describe(equal) == "0.08 (33.3 %), 0.1 (33.3 %), 0.12 (33.3 %)"


def test_the_composition_figure_of_a_mixture_draws_each_sizes_share():
    """fig_composition: the diameter ratio, and for two sizes each one's share of every tenth
    of the discharged mass (hand values: the small grains, a fifth of the mass, leave first)."""
    import types

    from silodem.measure.discharge import discharge_composition
    from silodem.report.figures_flow import fig_composition

    c = discharge_composition(np.arange(20.0), np.array([1.0] * 10 + [2.0] * 10))
    fig = fig_composition(types.SimpleNamespace(flow={"composition": c}))
    top, shares = fig.axes[:2]
    ratio = [line for line in top.get_lines() if line.get_label().startswith("each tenth")]
    np.testing.assert_allclose(ratio[0].get_ydata(), [5 / 9] * 2 + [10 / 9] * 8, rtol=1e-14)
    drawn = {line.get_label(): line.get_ydata() for line in shares.get_lines()
             if line.get_label().startswith("r = ")}
    np.testing.assert_allclose(drawn["r = 1 m"], [100, 100] + [0] * 8)
    np.testing.assert_allclose(drawn["r = 2 m"], [0, 0] + [100] * 8)
    band = [p for p in top.collections if p.get_label().startswith("chance")]
    outline = band[0].get_paths()[0].vertices[:, 1]  # (the band's lows and highs)
    assert outline.min() == pytest.approx(np.nanmin(c.chance_lo), rel=1e-12)
    assert outline.max() == pytest.approx(np.nanmax(c.chance_hi), rel=1e-12)
    for j, label in enumerate(("chance, r = 1 m", "chance, r = 2 m")):  # each size's band
        size_band = [p for p in shares.collections if p.get_label() == label]
        outline = size_band[0].get_paths()[0].vertices[:, 1]
        assert outline.min() == pytest.approx(100 * np.nanmin(c.share_lo[:, j]), abs=1e-9)
        assert outline.max() == pytest.approx(100 * np.nanmax(c.share_hi[:, j]), abs=1e-9)
    # grains of one size: a flat line at 1 in a band of no width, so no figure (the key
    # numbers say there are no sizes to segregate)
    one_size = discharge_composition(np.arange(20.0), np.ones(20))
    assert one_size.diameter_ratio == pytest.approx(np.ones(10), rel=1e-14)
    assert fig_composition(types.SimpleNamespace(flow={"composition": one_size})) is None
