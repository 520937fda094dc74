"""A hand-made study for the tests of the study report's heat maps: a 2 x 2 grid (theta 45,
60 deg x phi_P 10, 30 deg) of two seeds, as plain namespaces with what ``fig_heatmaps`` and
``layout_of`` read of a StudyPlan (its runs' ids and grid points, the grid and seeds)."""

from __future__ import annotations

import itertools
import types

GRID = {"silo.hopper_angle_from_horizontal_deg": [45.0, 60.0], "walls.friction_deg": [10.0, 30.0]}
SEEDS = (1, 2)


def fake_plan() -> types.SimpleNamespace:
    runs = [types.SimpleNamespace(id=f"t{t:g}_p{p:g}_s{s}", point={
        "silo.hopper_angle_from_horizontal_deg": t, "walls.friction_deg": p})
        for s, t, p in itertools.product(SEEDS, *GRID.values())]
    spec = types.SimpleNamespace(grid=GRID, seeds=list(SEEDS))
    return types.SimpleNamespace(runs=runs, study=types.SimpleNamespace(spec=spec))


def heat_map(fig, title: str):
    """The one heat map axis of ``fig`` whose title starts with ``title``."""
    axes = [ax for ax in fig.axes if ax.images and ax.get_title().startswith(title)]
    assert len(axes) == 1, title
    return axes[0]
