"""The study report's heat maps read as they should: a quantity that can be below 0 on a
two-sided colour map centred on 0, a poorly determined (starred) value kept out of the colour
range, the grid values' units on the tick labels; and the Runs table one line per run.

The heat maps are drawn from a hand-made 2 x 2 grid (theta 45, 60 deg x phi_P 10, 30 deg) of
two seeds with the same values, so that each cell's seed mean is the value set here.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from study_helpers import GRID, fake_plan, heat_map

from silodem.study.plan import key_unit, label_of
from silodem.study.report import (
    HEATMAPS,
    SIGNED_CMAP,
    colour_range,
    fig_heatmaps,
    layout_of,
    shared_colour_range,
)

NAN = float("nan")
CELLS = list(itertools.product(range(2), range(2)))  # (row i: theta, column j: phi_P)


def _rows(plan, values: dict[str, dict[tuple[int, int], float]],
          errors: dict[tuple[int, int], float] | None = None) -> dict[str, dict]:
    """Every heat map's column 1.0 but those of ``values`` (cell (i, j) -> value, both seeds);
    ``errors``: K's standard error per cell (0.05, well determined, elsewhere)."""
    rows = {}
    for run in plan.runs:
        t, p = run.point.values()
        cell = (GRID["silo.hopper_angle_from_horizontal_deg"].index(t),
                GRID["walls.friction_deg"].index(p))
        row = {column: 1.0 for column, *_ in HEATMAPS}
        for column, by_cell in values.items():
            row[column] = by_cell[cell]
        row.update(id=run.id, janssen_K_fill_err=(errors or {}).get(cell, 0.05))
        rows[run.id] = row
    return rows


def test_the_signed_quantities_are_the_changes_and_the_friction():
    """By their definitions (docs/sweeps.md): the sign of a change in % and of the mobilised
    wall friction sum(tau) / sum(sigma_n) is their meaning; stresses, their ratio, a CV, K
    (fitted above 0), a mass rate, the mass flow index (0 to about 1) and a contact count
    have none."""
    signed = {hm.column for hm in HEATMAPS if hm.signed}
    assert signed == {"switch_sigma_h_change_pct", "switch_sigma_v_change_pct",
                      "wall_friction_mobilised_fill"}


def test_the_friction_map_is_centred_on_zero_even_when_every_value_is_positive():
    """Mobilised frictions 0.02, 0.05, 0.01, 0.04 (all above 0): the map is two-sided, its
    colour range -0.05..0.05 (+- the largest magnitude), so 0 is its middle (white) and every
    cell is on the red side; the colour bar is not extended.  A one-way quantity, the
    coordination number 1.5, 2.0, 1.8, 1.6, keeps its own range 1.5..2.0."""
    plan = fake_plan()
    mu = dict(zip(CELLS, (0.02, 0.05, 0.01, 0.04)))
    z = dict(zip(CELLS, (1.5, 2.0, 1.8, 1.6)))
    fig = fig_heatmaps(plan, _rows(plan, {"wall_friction_mobilised_fill": mu,
                                          "coordination_discharge": z}), layout_of(plan))
    im = heat_map(fig, "mobilised wall friction after filling").images[0]
    assert im.get_clim() == pytest.approx((-0.05, 0.05), rel=1e-12)
    assert im.get_cmap().name == SIGNED_CMAP
    assert im.colorbar.extend == "neither"
    assert im.norm(0.0) == pytest.approx(0.5)
    assert all(im.norm(v) > 0.5 for v in mu.values())
    coordination = heat_map(fig, "coordination number at the junction").images[0]
    assert coordination.get_clim() == pytest.approx((1.5, 2.0), rel=1e-12)
    assert coordination.get_cmap().name == "viridis"


def test_a_poorly_determined_K_is_left_out_of_the_colour_range():
    """K = 3.0 +- 2.0 (error over half of it: starred) among well-determined 0.7, 1.4 and
    1.0 (+- 0.05): the colour range is 0.7..1.4, that of the three, and the starred cell is
    drawn in the colour of its top (as 1.4), the colour bar extended at the top; the cell
    still reads '3*'.  A starred 0.2 +- 0.15 instead extends the bar at the bottom, and both
    at once at both ends."""
    plan = fake_plan()
    lay = layout_of(plan)
    well = {(0, 0): 0.7, (1, 0): 1.4, (1, 1): 1.0}
    fig = fig_heatmaps(plan, _rows(plan, {"janssen_K_fill": {**well, (0, 1): 3.0}},
                                   {(0, 1): 2.0}), lay)
    ax = heat_map(fig, "Janssen K after filling")
    im = ax.images[0]
    assert im.get_clim() == pytest.approx((0.7, 1.4), rel=1e-12)
    assert im.colorbar.extend == "max"
    assert im.get_array()[0, 1] == pytest.approx(3.0)  # the value itself is kept
    rgba = im.to_rgba(im.get_array())
    assert np.array_equal(rgba[0, 1], rgba[1, 0])  # 3.0 drawn as the range's top, 1.4
    texts = {tuple(t.get_position()): t.get_text() for t in ax.texts}
    assert texts[(1.0, 0.0)] == "3*" and texts[(0.0, 0.0)] == "0.7"
    assert "its colour is left out of the range" in ax.get_title()

    low = fig_heatmaps(plan, _rows(plan, {"janssen_K_fill": {**well, (0, 1): 0.2}},
                                   {(0, 1): 0.15}), lay)
    im = heat_map(low, "Janssen K after filling").images[0]
    assert im.get_clim() == pytest.approx((0.7, 1.4), rel=1e-12)
    assert im.colorbar.extend == "min"

    both = fig_heatmaps(plan, _rows(plan, {"janssen_K_fill": {
        (0, 0): 0.7, (0, 1): 3.0, (1, 0): 1.4, (1, 1): 0.2}}, {(0, 1): 2.0, (1, 1): 0.15}), lay)
    im = heat_map(both, "Janssen K after filling").images[0]
    assert im.get_clim() == pytest.approx((0.7, 1.4), rel=1e-12)
    assert im.colorbar.extend == "both"


def test_the_same_quantity_after_filling_and_in_discharge_shares_one_colour_scale():
    """The wall peak after filling (8,300-37,000 Pa) beside the same peak in discharge
    (5,300-25,000 Pa), each on its own range, drew 22,735 Pa teal and 23,774 Pa yellow.  Both
    maps now span 5,300..37,000 Pa, so equal colours are equal stresses; the changes of
    sigma_h (+-56 %) and sigma_v (+-77 %) share +-77 %.  A map on its own (the discharge
    rate) keeps its range, and each shared map's bar is extended only for its own values."""
    plan = fake_plan()
    fill = dict(zip(CELLS, (8300.0, 22735.0, 37000.0, 15000.0)))
    flow = dict(zip(CELLS, (5300.0, 23774.0, 25000.0, 9000.0)))
    dh = dict(zip(CELLS, (-56.0, 10.0, 20.0, -5.0)))
    dv = dict(zip(CELLS, (-77.0, 40.0, 30.0, 5.0)))
    rate = dict(zip(CELLS, (900.0, 1100.0, 1000.0, 1200.0)))
    fig = fig_heatmaps(plan, _rows(plan, {"wall_peak_fill": fill, "wall_peak_discharge": flow,
                                          "switch_sigma_h_change_pct": dh,
                                          "switch_sigma_v_change_pct": dv,
                                          "discharge_rate": rate}), layout_of(plan))
    for title in ("wall peak in the switch zone, after filling",
                  "wall peak in the switch zone, discharge"):
        ax = heat_map(fig, title)
        assert ax.images[0].get_clim() == pytest.approx((5300.0, 37000.0), rel=1e-12)
        assert ax.images[0].colorbar.extend == "neither"
        assert "one colour scale with the map beside it" in ax.get_title()
    for title in ("change of sigma_h", "change of sigma_v"):
        assert heat_map(fig, title).images[0].get_clim() == pytest.approx((-77.0, 77.0))
    own = heat_map(fig, "discharge rate").images[0]
    assert own.get_clim() == pytest.approx((900.0, 1200.0), rel=1e-12)
    # the maps that share a scale stand side by side: one row of the two-column grid
    for key in {hm.shares for hm in HEATMAPS} - {""}:
        where = [k for k, hm in enumerate(HEATMAPS) if hm.shares == key]
        assert len(where) == 2 and where[0] % 2 == 0 and where[1] == where[0] + 1, key


def test_a_shared_colour_scale_extends_a_bar_only_for_its_own_values():
    """shared_colour_range on hand-worked grids: the union of both maps, 1..9, sets both
    ranges; a starred 30 in the first map is left out of the range and extends only the
    first map's bar; a map without a finite value gets none."""
    a = np.array([[1.0, 30.0], [4.0, 5.0]])
    b = np.array([[2.0, 9.0], [NAN, 3.0]])
    star_a = np.array([[False, True], [False, False]])
    no = np.zeros((2, 2), dtype=bool)
    maps = [(a, star_a), (b, no)]
    assert shared_colour_range(maps, False, a) == (1.0, 9.0, "max")
    assert shared_colour_range(maps, False, b) == (1.0, 9.0, "neither")
    assert shared_colour_range(maps, True, b) == (-9.0, 9.0, "neither")
    assert shared_colour_range([(a, star_a), (np.full((2, 2), NAN), no)], False,
                               np.full((2, 2), NAN)) is None


def test_colour_range_of_hand_worked_grids():
    """colour_range's (vmin, vmax, extend) on small grids worked by hand."""
    no = np.zeros((2, 2), dtype=bool)
    star_01 = np.array([[False, True], [False, False]])
    k = np.array([[0.7, 3.0], [1.4, NAN]])
    assert colour_range(k, False, star_01) == (0.7, 1.4, "max")
    assert colour_range(k, False, no) == (0.7, 3.0, "neither")  # nothing starred: all count
    # every finite value starred: their own range, nothing to set it else
    assert colour_range(k, False, np.array([[True, True], [True, False]])) == (0.7, 3.0,
                                                                                "neither")
    mu = np.array([[-0.02, 0.3], [0.05, 0.01]])
    assert colour_range(mu, True, no) == (-0.3, 0.3, "neither")
    assert colour_range(mu, True, star_01) == (-0.05, 0.05, "max")
    assert colour_range(-mu, True, star_01) == (-0.05, 0.05, "min")
    assert colour_range(np.zeros((1, 2)), True, no[:1]) == (-1.0, 1.0, "neither")
    assert colour_range(np.full((2, 2), NAN), False, no) is None


def test_tick_labels_carry_the_grid_keys_units():
    """The Config's angles are in degrees: theta=45 deg, phiP=10 deg on the heat maps' ticks;
    an outlet width in m, a density in kg/m^3; a dimensionless key, a choice and the grid key
    'base' (a scenario) carry none."""
    plan = fake_plan()
    fig = fig_heatmaps(plan, _rows(plan, {}), layout_of(plan))
    for ax in (ax for ax in fig.axes if ax.images):
        assert [t.get_text() for t in ax.get_yticklabels()] == ["theta=45 deg", "theta=60 deg"]
        assert [t.get_text() for t in ax.get_xticklabels()] == ["phiP=10 deg", "phiP=30 deg"]
    assert key_unit("silo.outlet_width") == "m"
    assert key_unit("material.density") == "kg/m^3"
    assert key_unit("measure.circle_x") == "m"  # a list of numbers
    assert key_unit("fill.n_particles") == ""  # [-]
    assert key_unit("settle.criterion") == ""  # a choice (its description names [J])
    assert key_unit("discharge.enabled") == ""  # a bool
    assert key_unit("base") == ""


def test_a_runs_name_carries_the_units_of_its_grid_values():
    """The runs table and each run's description name a run by its grid values with the
    units of the Config's descriptions ([deg], [m]); a choice and the seed have none."""
    point = {"silo.hopper_angle_from_horizontal_deg": 45.0, "silo.outlet_width": 0.4,
             "material.contact_model": "hertz_mindlin"}
    assert label_of(point, 3) == ("theta=45 deg, outlet_width=0.4 m, "
                                  "contact_model=hertz_mindlin, seed 3")
    assert label_of(point) == "theta=45 deg, outlet_width=0.4 m, contact_model=hertz_mindlin"
    # an error's label shows a list as one, and a list of lengths keeps its unit [m]
    circles = {"measure.circle_x": [0.1, 0.25]}
    assert label_of(circles, 1, brackets=True) == "circle_x=[0.1, 0.25] m, seed 1"


def test_the_runs_table_keeps_one_line_per_run(tmp_path):
    """The study page's Runs table is in a box that scrolls sideways and its cells do not
    wrap (a run's name took five lines), but for a failed run's reason, which does."""
    from silodem.study import expand, load_study
    from silodem.study.report import write_study_report

    path = tmp_path / "small.toml"
    path.write_text('name = "small"\nbase = "paper-case2"\nseeds = [1]\n[grid]\n'
                    '"walls.friction_deg" = [10.0, 45.0]\n', encoding="utf-8")
    plan = expand(load_study(str(path)), quick=True)
    rows = [{"id": plan.runs[0].id, "discharge_rate": 1500.0}]
    page = write_study_report(plan, tmp_path / "study", rows,
                              failed={plan.runs[1].id: "unstable: a grain left"})
    html = page.read_text(encoding="utf-8")
    assert "<div class='wide'><table class='runs'>" in html
    style = html[html.index("<style>"):html.index("</style>")]
    assert ".wide{overflow-x:auto" in style
    assert "table.runs td{white-space:nowrap}" in style
    assert "table.runs td.warn{\nwhite-space:normal}" in style
    assert "class='warn'>unstable: a grain left</td>" in html
