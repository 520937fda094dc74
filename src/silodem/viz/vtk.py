"""ParaView files of a run: VTK XML unstructured grids written with meshio, and .pvd series.

Per output time k (``DIR/vtk/``):

* ``particles_k.vtu``: one vertex per grain at its centre (z = 0), point data ``radius`` [m],
  ``velocity`` [m/s] (3-vector, z = 0), ``spin`` [rad/s], ``force`` [N] (magnitude of the
  resultant contact force, gravity excluded), ``force_vector`` [N], ``normal_force_sum`` [N]
  (sum of the normal forces of the grain's contacts), ``coordination`` [-] (touching contacts,
  grains and walls) and ``uid`` (the grain's permanent id);
* ``contacts_k.vtu``: one line per touching contact, grain centre to grain centre, or grain
  centre to the contact point on a wall, cell data ``normal_force`` [N], ``shear_force`` [N] and
  ``kind`` (0 grain-grain, 1 grain-wall);
* ``walls_k.vtu``: one line per wall segment, cell data ``wall_id`` (index into results.h5
  ``/walls/name``) and ``active`` (1 while the wall is in place; the gate is 0 once open).

``particles.pvd``, ``contacts.pvd`` and ``walls.pvd`` list the files with their times, so
ParaView plays them as time series (docs/visualisation.md).

At the end of the run, ``fields_settled.vtu`` and ``fields_discharge.vtu``: the density and
stress fields of results.h5 ``/measure/fields`` (``silodem.measure.fields``), one quad per
cell, cell data ``density`` [kg/m^3], ``stress_xx``, ``stress_zz``, ``stress_xz`` [Pa]
(compression positive; NaN outside the silo).
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import meshio
import numpy as np

from silodem.atomic import atomic_file
from silodem.silo.frames import Frame, WallGeometry

KINDS = ("particles", "contacts", "walls")
_STALE = re.compile(r"^(particles|contacts|walls)(_\d+\.vtu|\.pvd)$"
                    r"|^fields_(settled|discharge)\.vtu$")


def remove_written(directory: Path) -> None:
    """Remove from ``directory`` the files this module writes (grains, contacts, walls, their
    .pvd collections, the fields); other files are not touched."""
    if not directory.is_dir():
        return
    for entry in directory.iterdir():
        if _STALE.match(entry.name) and entry.is_file():
            entry.unlink()


def file_name(kind: str, k: int) -> str:
    return f"{kind}_{k:06d}.vtu"


def _points(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    return np.column_stack([x, y, np.zeros_like(x)])


def particles_mesh(frame: Frame) -> meshio.Mesh:
    p = frame.particles
    n = frame.n
    zero = np.zeros(n, dtype=p["vx"].dtype)
    point_data = {
        "radius": p["radius"],
        "velocity": np.column_stack([p["vx"], p["vy"], zero]),
        "spin": p["omega"],
        "force": frame.force().astype(p["fx"].dtype),
        "force_vector": np.column_stack([p["fx"], p["fy"], zero]),
        "normal_force_sum": frame.normal_force_sum(),
        "coordination": frame.coordination(),
        "uid": p["uid"],
    }
    cells = [("vertex", np.arange(n, dtype=np.int32).reshape(-1, 1))]
    return meshio.Mesh(_points(p["x"], p["y"]), cells, point_data=point_data)


def contacts_mesh(frame: Frame, walls: WallGeometry) -> meshio.Mesh:
    p, c, w = frame.particles, frame.contacts, frame.wall_contacts
    n, m = frame.n, w["grain"].size
    gx, gy = p["x"][w["grain"]].astype(float), p["y"][w["grain"]].astype(float)
    cx, cy = walls.closest_points(w["wall"], gx, gy)
    points = _points(np.concatenate([p["x"], cx.astype(p["x"].dtype)]),
                     np.concatenate([p["y"], cy.astype(p["y"].dtype)]))
    lines = np.concatenate([np.column_stack([c["i"], c["j"]]),
                            np.column_stack([w["grain"], n + np.arange(m)])]).astype(np.int32)
    kind = np.concatenate([np.zeros(c["i"].size, np.int32), np.ones(m, np.int32)])
    cell_data = {"normal_force": [np.concatenate([c["fn"], w["fn"]])],
                 "shear_force": [np.concatenate([c["fs"], w["fs"]])],
                 "kind": [kind]}
    return meshio.Mesh(points, [("line", lines.reshape(-1, 2))], cell_data=cell_data)


def walls_mesh(walls: WallGeometry, active: np.ndarray) -> meshio.Mesh:
    nw = len(walls)
    x = np.column_stack([walls.ax, walls.bx]).ravel()
    y = np.column_stack([walls.ay, walls.by]).ravel()
    lines = np.arange(2 * nw, dtype=np.int32).reshape(-1, 2)
    cell_data = {"wall_id": [np.arange(nw, dtype=np.int32)],
                 "active": [np.asarray(active, dtype=np.int32)]}
    return meshio.Mesh(_points(x, y), [("line", lines)], cell_data=cell_data)


def fields_mesh(x_edges: np.ndarray, z_edges: np.ndarray, density: np.ndarray,
                stress: np.ndarray) -> meshio.Mesh:
    """The grid of a density and stress field as quads (cell (i, k) spans x_edges[i:i+2] x
    z_edges[k:k+2]), its values as cell data, in the order i * nz + k."""
    nx, nz = x_edges.size - 1, z_edges.size - 1
    gx, gz = np.meshgrid(x_edges, z_edges, indexing="ij")
    node = np.arange((nx + 1) * (nz + 1), dtype=np.int32).reshape(nx + 1, nz + 1)
    quads = np.stack([node[:-1, :-1], node[1:, :-1], node[1:, 1:], node[:-1, 1:]],
                     axis=-1).reshape(-1, 4)
    cell_data = {"density": [np.asarray(density, float).ravel()]}
    for c, name in enumerate(("stress_xx", "stress_zz", "stress_xz")):
        cell_data[name] = [np.asarray(stress, float)[..., c].ravel()]
    return meshio.Mesh(_points(gx.ravel(), gz.ravel()), [("quad", quads)], cell_data=cell_data)


def write_fields(results: Path | str, directory: Path | str) -> list[Path]:
    """``fields_<window>.vtu`` in ``directory`` for each field of ``results`` (a results.h5)
    that has samples; returns the files written."""
    import h5py

    out = []
    with h5py.File(results, "r") as h5:
        f = h5.get("measure/fields")
        if f is None:
            return out
        xe, ze = f["x_edges"][()], f["z_edges"][()]
        for window in ("settled", "discharge"):
            g = f.get(window)
            if g is None or g.attrs.get("samples", 0) == 0:
                continue
            path = Path(directory) / f"fields_{window}.vtu"
            path.parent.mkdir(parents=True, exist_ok=True)  # none yet: a run shorter than
            # its output.vtk_interval wrote no grains' files
            _write_mesh(path, fields_mesh(xe, ze, g["density"][()], g["stress"][()]))
            out.append(path)
    return out


def _write_mesh(path: Path, mesh: meshio.Mesh) -> None:
    """Write ``mesh`` to ``path`` whole or not at all (``atomic.atomic_file``)."""
    with atomic_file(path) as tmp:
        meshio.write(tmp, mesh, file_format="vtu")


def write_pvd(path: Path, entries: list[tuple[float, str]]) -> None:
    """A ParaView collection: ``entries`` = (time [s], file relative to ``path``'s folder)."""
    root = ET.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
    coll = ET.SubElement(root, "Collection")
    for time, name in entries:
        ET.SubElement(coll, "DataSet", timestep=repr(float(time)), group="", part="0",
                      file=name)
    ET.indent(root)
    with atomic_file(path) as tmp:
        ET.ElementTree(root).write(tmp, encoding="utf-8", xml_declaration=True)


class VtkSeries:
    """Writes the three files of each output time into ``directory`` and keeps the .pvd
    collections current (rewritten after every output, so ParaView can open a running job).

    ``fresh``: remove files of an earlier run (only names this writer makes) first."""

    def __init__(self, directory: Path | str, walls: WallGeometry, fresh: bool = True) -> None:
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self.walls = walls
        if fresh:
            remove_written(self.directory)

    def write(self, k: int, frame: Frame) -> None:
        d = self.directory
        _write_mesh(d / file_name("particles", k), particles_mesh(frame))
        _write_mesh(d / file_name("contacts", k), contacts_mesh(frame, self.walls))
        _write_mesh(d / file_name("walls", k), walls_mesh(self.walls, frame.walls_active))

    def write_collections(self, times: list[float]) -> None:
        for kind in KINDS:
            write_pvd(self.directory / f"{kind}.pvd",
                      [(t, file_name(kind, k)) for k, t in enumerate(times)])
