"""The results folder of a run: config.toml, results.h5 and PNG pictures (docs/output.md).

Every file is written to a temporary name in the same folder and renamed into place, so a
reader never sees a half-written file.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from silodem import __version__
from silodem.atomic import atomic_file, atomic_hdf5, write_atomic
from silodem.provenance import source_digest
from silodem.silo.procedure import SiloRun
from silodem.silo.recorders import write_snapshot

if TYPE_CHECKING:
    from silodem.report.load import Results


def write_text(path: Path, text: str) -> None:
    write_atomic(path, text)


def write_results(run: SiloRun, path: Path, config_toml: str, *, status: str = "complete") -> None:
    """results.h5: attributes, one group per recorder (/timeseries ...), /walls, /events,
    /warnings, and the /settled and /final snapshots (those taken so far).

    ``status``: "complete" at the end of a run; "running", "interrupted" or "unstable" when
    written before the end (checkpoints, docs/reliability.md); attributes ``phase``, ``time``
    and ``steps`` say how far the run had come."""
    with atomic_hdf5(path) as h5:
        h5.attrs["status"] = status
        h5.attrs["phase"] = run.state.phase
        h5.attrs["time"] = run.sim.time
        h5.attrs["steps"] = run.sim.steps
        h5.attrs["silodem_version"] = __version__
        h5.attrs["silodem_source"] = source_digest()  # the code itself (provenance.py)
        if run.started_by is not None:  # resumed with other code than started it
            h5.attrs["silodem_source_started"] = run.started_by
        h5.attrs["scenario"] = run.cfg.name
        h5.attrs["seed"] = run.cfg.seed
        h5.attrs["dt"] = run.dt
        h5.attrs["dt_crit"] = run.dt_crit
        h5.attrs["config_toml"] = config_toml
        for rec in run.recorders:
            rec.write(h5.create_group(rec.name))
        w = run.walls
        wg = h5.create_group("walls")
        wg.create_dataset("name", data=np.array(w.names, dtype=h5py.string_dtype()))
        stiffness = "Pa" if run.law.hertz else "N/m"  # Hertz-Mindlin: 2 E* and 8 G*
        for key, unit in (("ax", "m"), ("ay", "m"), ("bx", "m"), ("by", "m"), ("kn", stiffness),
                          ("ks", stiffness), ("mu", "-"), ("active", "-")):
            data = run.walls_built[key] if key in run.walls_built else getattr(w, key)
            wg.create_dataset(key, data=data).attrs["unit"] = unit
        ev = h5.create_group("events")
        for key, val in run.events.items():
            ev.attrs[key] = val
        h5.create_dataset("warnings", data=np.array(run.warnings, dtype=h5py.string_dtype()))
        for name, snap in run.snapshots.items():
            write_snapshot(h5.create_group(name), snap)


PICTURES = {"settled": "end of filling (settled)", "final": "end of run"}  # stem: caption


def write_views(folder: Path | str) -> list[Path]:
    """What a run's folder shows besides results.h5, all derived from it, by ``silodem run``
    and again by ``silodem plot``: settled.png and final.png (``draw_pictures``) and, where the
    run wrote VTK files (its config's ``output.vtk_interval``), the fields'
    ``vtk/fields_*.vtu``."""
    from silodem.report.load import load_results
    from silodem.viz.vtk import write_fields

    folder = Path(folder)
    res = load_results(folder, only=("walls", "events", *PICTURES))  # not frames, series
    out = draw_pictures(res)
    if res.cfg.output.vtk_interval:
        out += write_fields(folder / "results.h5", folder / "vtk")
    return out


def draw_pictures(res: Results) -> list[Path]:
    """settled.png and final.png of the run ``res`` (if its config's ``output.png``), drawn
    from the snapshots /settled and /final of its results.h5: by ``silodem run``, and again
    by ``silodem plot``."""
    if not res.cfg.output.png:
        return []
    walls = res.group("walls")
    out = []
    for name, caption in PICTURES.items():
        snap = res.snapshot(name)
        if snap is None or walls is None:
            continue
        path = res.folder / f"{name}.png"
        draw_state(snap, walls, path,
                   f"{res.cfg.name}: {caption}, t = {snap['@attrs']['time']:.2f} s", res.events)
        out.append(path)
    return out


def draw_state(snap: dict, walls: dict, path: Path, title: str,
               events: dict | None = None) -> None:
    """A PNG of a snapshot: grains to scale, the force network (every touching contact, line
    width and colour ~ normal force; ``report.draw.draw_force_network``, as the report's
    Fig. 5, with its colour bar) and the walls (``walls``: ax, ay, bx, by [m]; dotted where
    withdrawn; a sliding gate where it stood, from the run's ``events``)."""
    from silodem.report.draw import draw_force_network, save_png, tight_layout
    from silodem.viz.title import TITLE_MARGIN, TITLE_SIZES, fit_title, title_lines, title_tokens

    p = snap["particles"]
    wall_x = np.concatenate([walls["ax"], walls["bx"]])
    wall_y = np.concatenate([walls["ay"], walls["by"]])
    # margins scaled to the silo, as the animation's (viz.draw.FrameArtist): fixed ones of
    # 0.3-0.5 m left a silo 0.2 m wide in a seventh of the picture
    r_max = float(np.max(p["radius"], initial=0.0))
    margin = max(0.05 * float(np.ptp(wall_y)), 3 * r_max)
    low = min(float(wall_y.min()) - 5.5 * r_max,
              float(np.min(p["y"] - p["radius"], initial=np.inf)))
    xlim = (float(wall_x.min()) - margin, float(wall_x.max()) + margin)
    ylim = (low, float(wall_y.max()) + margin)
    # a tall silo in a portrait figure, a wide one in a landscape figure (9 in on the long side)
    aspect = (xlim[1] - xlim[0]) / (ylim[1] - ylim[0])
    size = (max(3.5, 9 * aspect) + 1.6, 9) if aspect <= 1 else (12 + 1.6, max(3, 12 / aspect) + 1)
    fig, ax = plt.subplots(figsize=size, dpi=110)
    lines, _ = draw_force_network(ax, snap, walls, events=events)
    ax.set_aspect("equal")
    ax.set_xlim(*xlim)
    ax.set_ylim(*ylim)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    # over the figure, fitted to its width (viz.title): a long scenario name, as a study's
    # runs have, ran off the picture's left edge
    tokens = title_tokens(title)
    size_pt, breaks = fit_title(tokens, 100 * size[0] - 2 * TITLE_MARGIN, 2) \
        or (TITLE_SIZES[-1], [])
    fig.suptitle("\n".join(title_lines(tokens, breaks)), fontsize=size_pt)
    if lines is not None:  # the colours of the chains mean forces: say which
        fig.colorbar(lines, ax=ax, shrink=0.5, pad=0.02, label="normal contact force F_n [N]")
    tight_layout(fig)
    try:
        with atomic_file(path) as tmp:
            save_png(fig, tmp)
    finally:
        plt.close(fig)
