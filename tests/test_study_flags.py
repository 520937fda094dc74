"""A study's flags on physically suspicious numbers: results.csv's columns
``janssen_K_fill_above_1`` and ``wall_friction_negative_fill`` (docs/sweeps.md), set by the
run report's own predicates (``report.flags``), and the heat maps' hatched cells.

The summaries come from test_report_numbers.py's synthetic run with its fits set by hand
(K = 1.3 +- 0.05: 0.25 over 1, flagged; 1.02 +- 0.05: within its error of 1, not; a
mobilised friction of -0.0312: below 0, flagged); the heat maps from a hand-made 2 x 2 grid
of two seeds whose flagged runs are chosen here.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import types

import pytest
from study_helpers import fake_plan, heat_map
from test_report_numbers import write_synthetic

from silodem.report import analysis
from silodem.report.load import load_results
from silodem.study.report import HEATMAPS, fig_heatmaps, layout_of
from silodem.study.table import (
    COLUMNS,
    read_table,
    summarise_run,
    table_columns,
    table_csv,
    table_rows,
)

NAN = float("nan")
FLAG_COLUMNS = ("janssen_K_fill_above_1", "wall_friction_negative_fill")


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return write_synthetic(tmp_path_factory.mktemp("study_flags") / "run")


def _summary(folder, monkeypatch, K: float, err: float, mu: float) -> dict:
    """summarise_run of the synthetic run with its filling fit's (K, K_err) and mobilised
    friction set by hand (the analysis it reads, edited)."""
    a = analysis.analyse(load_results(folder))
    b = copy.copy(a)
    b.janssen = {**a.janssen, "fill": dataclasses.replace(a.janssen["fill"], K=K, K_err=err)}
    b.mu_mobilised = {**a.mu_mobilised, "fill": mu}
    monkeypatch.setattr(analysis, "analyse", lambda res: b)
    return summarise_run(folder)


def test_flag_columns_of_results_csv(folder, monkeypatch, tmp_path):
    """The flags are true exactly where the run report flags the value (K above 1 by more
    than its error; a mobilised friction below 0), false elsewhere and without a value, and
    results.csv writes them 'true' / 'false' in their documented places: each after the
    value it judges."""
    names = [c for c, _, _ in COLUMNS]
    assert names.index("janssen_K_fill_above_1") == names.index("janssen_K_fill_err") + 1
    assert (names.index("wall_friction_negative_fill")
            == names.index("wall_friction_mobilised_fill") + 1)
    cases = {"flagged": (1.3, 0.05, -0.0312), "within": (1.02, 0.05, 0.1),
             "boundary": (1.06, 0.05, 0.0), "no error": (1.3, NAN, NAN)}
    expected = {"flagged": (True, True), "within": (False, False),
                "boundary": (True, False),  # 1.06 - 0.05 = 1.01 > 1; a friction of 0 is not < 0
                "no error": (False, False)}  # not judged
    summaries = {}
    for name, (K, err, mu) in cases.items():
        s = _summary(folder, monkeypatch, K, err, mu)
        assert (s["janssen_K_fill_above_1"], s["wall_friction_negative_fill"]) \
            == expected[name], name
        assert all(type(s[c]) is bool for c in FLAG_COLUMNS)  # JSON true / false
        summaries[name] = s
    s = summaries["flagged"]
    assert s["janssen_K_fill"] == 1.3 and s["wall_friction_mobilised_fill"] == -0.0312
    plan = types.SimpleNamespace(runs=[types.SimpleNamespace(id=name, slug=name, seed=1,
                                                             point={}) for name in cases])
    rows = table_rows(plan, summaries)
    path = tmp_path / "results.csv"
    path.write_text(table_csv(table_columns([], rows), rows), encoding="utf-8")
    back = {row["id"]: row for row in read_table(path)}
    for name, flags in expected.items():
        assert tuple(back[name][c] for c in FLAG_COLUMNS) == tuple(
            "true" if f else "false" for f in flags), name


def test_flag_columns_are_documented():
    """docs/sweeps.md lists both columns, with their meaning."""
    from pathlib import Path

    doc = (Path(__file__).parents[1] / "docs" / "sweeps.md").read_text(encoding="utf-8")
    for column in FLAG_COLUMNS:
        assert f"| `{column}` | - | `true` where" in doc, column




def _rows(plan, k_flagged: set[str], friction_flagged: set[str]) -> dict[str, dict]:
    """Every heat map's column 1.0 (K = 0.8 +- 0.05: not poorly determined), the flags set
    for the runs named; the friction flags as results.csv's text 'true' / 'false'."""
    rows = {}
    for run in plan.runs:
        row = {column: 1.0 for column, *_ in HEATMAPS}
        row.update(id=run.id, janssen_K_fill=0.8, janssen_K_fill_err=0.05,
                   janssen_K_fill_above_1=run.id in k_flagged,
                   wall_friction_negative_fill="true" if run.id in friction_flagged
                   else "false")
        rows[run.id] = row
    return rows


def _hatched_cells(ax) -> set[tuple[float, float]]:
    """Centres (x, y) of the hatched patches: column j, row i of the map at (j, i)."""
    return {(p.get_x() + p.get_width() / 2, p.get_y() + p.get_height() / 2)
            for p in ax.patches if p.get_hatch()}


def _cell_text_at(ax, xy: tuple[float, float]) -> str:
    return next(t.get_text() for t in ax.texts if tuple(t.get_position()) == xy)


def test_heatmaps_hatch_the_cells_where_a_seed_is_flagged():
    """The K map hatches the cell (theta = 60, phi_P = 10): one of its two seeds has K above 1;
    the friction map the cell (theta = 45, phi_P = 30), one seed's friction negative (a
    results.csv 'true').  Each says so under its title; no other map, and no other cell, is
    hatched; the cell keeps its value.  Without any flag no map is hatched or captioned."""
    plan = fake_plan()
    lay = layout_of(plan)
    assert lay.rows == [45.0, 60.0] and lay.cols == [{"walls.friction_deg": 10.0},
                                                     {"walls.friction_deg": 30.0}]
    fig = fig_heatmaps(plan, _rows(plan, {"t60_p10_s2"}, {"t45_p30_s1"}), lay)
    k_map = heat_map(fig, "Janssen K after filling")
    friction = heat_map(fig, "mobilised wall friction after filling")
    assert _hatched_cells(k_map) == {(0.0, 1.0)}  # column phi_P = 10, row theta = 60
    assert _cell_text_at(k_map, (0.0, 1.0)) == "0.8"
    assert k_map.get_title().endswith(
        "\nhatched: a run's K is above 1 by more than its error (no fill at rest)")
    assert _hatched_cells(friction) == {(1.0, 0.0)}  # column phi_P = 30, row theta = 45
    assert friction.get_title().endswith(
        "\nhatched: a run's friction is below 0: the walls carry none of the weight")
    others = [ax for ax in fig.axes if ax.images and ax not in (k_map, friction)]
    assert not any(_hatched_cells(ax) for ax in others)
    assert not any("hatched" in ax.get_title() for ax in others)
    plain = fig_heatmaps(plan, _rows(plan, set(), set()), lay)
    assert not any(_hatched_cells(ax) or "hatched" in ax.get_title() for ax in plain.axes)
    assert all(math.isclose(heat_map(plain, "Janssen K after filling").images[0].get_array()[i, j],
                            0.8) for i in range(2) for j in range(2))
