"""Checkpoints: the whole state of a silo run in one HDF5 file, written atomically, read back
exactly (docs/reliability.md).

A checkpoint is taken between two chunks of the procedure (never inside a time step) and holds
everything the run needs to go on as if it had never stopped:

* ``/particles``, ``/walls``, ``/neighbors``, ``/simulation``: every array and number of the
  engine's objects (the grain arrays up to their capacity, the whole Verlet list with its
  contact history, the walls with their active flags, the clock and the rebuild trigger),
  less what the list remakes itself (``NeighborList.NOT_STATE``);
* ``/run``: the procedure state, the random generator's bit-generator state, the grain radii
  drawn at the start, events, warnings and the snapshots taken so far;
* ``/recorders/<name>``: what each recorder's ``state()`` returned;
* the attributes of ``/``: format, silodem version, config (TOML), reason, step, time, phase.

The engine objects are saved attribute by attribute (``vars``), so an array added to them later
is saved too; an attribute of a kind this module cannot store is an error at the first
checkpoint, never a silently incomplete file.

Values are stored as HDF5 datasets: arrays as they are, numbers and booleans as scalar
datasets, dicts as groups, other values (strings, lists, None) as JSON text in a string dataset
(Python's JSON writes floats with the shortest repr that reads back to the same double).  The
attribute ``silodem_kind`` tells how to read a node back; every value comes back exact.
HDF5's Fletcher-32 checksum guards each numeric array as it is read; a SHA-256 over the names
and bytes of every dataset, the root attribute ``sha256``, guards them all, with the scalars
and texts Fletcher-32 cannot (the time step, the clock, the config, the random generator's
state), and the arrays edited through HDF5, which writes their Fletcher-32 anew.  So bytes
changed on disk or by hand in any dataset are refused when the checkpoint is read, not resumed
from (the attributes, which say how far the run went and how a node is read, are not in it).
Checkpoints of earlier versions carry ``plain_sha256``, over the datasets without Fletcher-32
only, and are checked by it.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import hashlib
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import h5py
import numpy as np

from silodem import __version__
from silodem.atomic import atomic_hdf5
from silodem.config import Config
from silodem.errors import InputError, one_line
from silodem.provenance import source_digest
from silodem.scenario_files import config_from_text

if TYPE_CHECKING:
    from silodem.silo.procedure import SiloRun

CHECKPOINT_NAME = "checkpoint.h5"
FAILURE_NAME = "failure.h5"
FORMAT = "silodem-checkpoint"
FORMAT_VERSION = 1

_KIND = "silodem_kind"  # attribute naming how a dataset or group is decoded
_DIGEST = "sha256"  # root attribute: _digest of every dataset of the file
_PLAIN_DIGEST = "plain_sha256"  # earlier files': _digest of those without Fletcher-32 (or none)
_SCALARS = {"bool": bool, "int": int, "float": float}  # scalar datasets -> Python values
# attributes of the engine objects that are other objects (saved on their own) or derived from
# the config (rebuilt identically by SiloRun(cfg))
_SIM_OBJECTS = ("particles", "walls", "neighbors", "law")


class CheckpointError(InputError):
    """A checkpoint that is missing, unreadable or of another format (exit code 2)."""


# --- encoding values -----------------------------------------------------------------------


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f"cannot store a {type(obj).__name__} in a checkpoint")


def _is_tree(value: Any) -> bool:
    """True for values stored as a group: dicts, and lists holding arrays or dicts."""
    if isinstance(value, dict):
        return True
    if isinstance(value, list | tuple):
        return any(isinstance(v, np.ndarray) or _is_tree(v) for v in value)
    return False


def put(group: h5py.Group, name: str, value: Any) -> None:
    """Store ``value`` under ``name`` (see the module docstring for the encoding)."""
    if "/" in name or not name:
        raise TypeError(f"checkpoint: bad name {name!r}")
    if isinstance(value, np.ndarray):
        if value.dtype.kind == "U":
            ds = group.create_dataset(name, data=value.astype(object),
                                      dtype=h5py.string_dtype())
            ds.attrs[_KIND] = "str_array"
        elif value.dtype.kind in "biufc":  # with a checksum (HDF5's Fletcher-32), so that
            # bytes changed on disk are refused on reading, not resumed from; one chunk (with
            # the 1.10 format, save_checkpoint: no chunk index, no larger than without)
            group.create_dataset(name, data=value, fletcher32=value.size > 0,
                                 chunks=value.shape if value.size > 0 else None)
        else:
            raise TypeError(f"checkpoint: cannot store an array of dtype {value.dtype} ({name})")
    elif isinstance(value, dict):
        sub = group.create_group(name, track_order=True)
        sub.attrs[_KIND] = "dict"
        for key, item in value.items():
            if not isinstance(key, str):
                raise TypeError(f"checkpoint: dict keys must be strings ({name}: {key!r})")
            put(sub, key, item)
    elif isinstance(value, list | tuple) and _is_tree(value):
        sub = group.create_group(name, track_order=True)
        sub.attrs[_KIND] = "list"
        for k, item in enumerate(value):
            put(sub, str(k), item)
    elif isinstance(value, bool | np.bool_):
        group.create_dataset(name, data=np.bool_(value)).attrs[_KIND] = "bool"
    elif isinstance(value, int | np.integer) and -(2**63) <= int(value) < 2**63:
        group.create_dataset(name, data=np.int64(value)).attrs[_KIND] = "int"
    elif isinstance(value, float | np.floating):
        group.create_dataset(name, data=np.float64(value)).attrs[_KIND] = "float"
    else:
        text = json.dumps(value, default=_json_default)
        ds = group.create_dataset(name, data=text, dtype=h5py.string_dtype())
        ds.attrs[_KIND] = "json"


def _digest(h5: h5py.File, every: bool = True) -> str:
    """SHA-256 of the names and bytes of the datasets of ``h5``, in the order of their names:
    every one, or (``every=False``, the ``plain_sha256`` of earlier files) those Fletcher-32
    does not guard (scalars, texts, empty arrays)."""
    names: list[str] = []

    def counted(name: str, node: h5py.Group | h5py.Dataset) -> None:
        if isinstance(node, h5py.Dataset) and (every or not node.fletcher32):
            names.append(name)

    h5.visititems(counted)
    digest = hashlib.sha256()
    for name in sorted(names):
        value = h5[name][()]
        if isinstance(value, np.ndarray) and value.dtype.kind == "O":  # a str_array
            value = b"\0".join(v if isinstance(v, bytes) else str(v).encode() for v in value)
        elif isinstance(value, str):
            value = value.encode()
        elif not isinstance(value, bytes):
            value = np.asarray(value).tobytes()
        digest.update(f"{name}\0{len(value)}\0".encode())
        digest.update(value)
    return digest.hexdigest()


def get(node: h5py.Group | h5py.Dataset) -> Any:
    """Inverse of :func:`put`."""
    kind = node.attrs.get(_KIND, "")
    if isinstance(node, h5py.Dataset):
        if kind == "json":
            return json.loads(node.asstr()[()])
        if kind in _SCALARS:
            return _SCALARS[kind](node[()])
        if kind == "str_array":
            return np.array(node.asstr()[()], dtype=str)
        return node[()]
    if kind == "list":
        return [get(node[str(k)]) for k in range(len(node))]
    return {key: get(child) for key, child in node.items()}


def _plain(value: Any) -> bool:
    """Values an engine object's attribute may hold to be saved."""
    if isinstance(value, np.ndarray | np.generic | bool | int | float | str | type(None)):
        return True
    if isinstance(value, list | tuple):
        return all(_plain(v) for v in value)
    return False


def object_state(obj: Any, skip: tuple[str, ...] = ()) -> dict[str, Any]:
    """Every attribute of ``obj`` (arrays and plain values), except ``skip``."""
    out: dict[str, Any] = {}
    for name, value in vars(obj).items():
        if name in skip:
            continue
        if not _plain(value):
            raise TypeError(
                f"checkpoint: {type(obj).__name__}.{name} holds a {type(value).__name__}, "
                "which silodem.checkpoint cannot save; teach object_state about it"
            )
        out[name] = value
    return out


def _kind_error(where: str, fresh: Any, value: Any, same_shape: bool) -> str | None:
    """Why ``value`` cannot replace ``fresh`` (the attribute of a run built from the config),
    or None: an array must stay an array of the same kind and rank (and shape for
    ``same_shape``), a number a number, a list a list, a text a text."""
    if isinstance(fresh, np.ndarray):
        if not isinstance(value, np.ndarray) or value.dtype.kind != fresh.dtype.kind \
                or value.ndim != fresh.ndim or (same_shape and value.shape != fresh.shape):
            shape = f"shape {fresh.shape}" if same_shape else f"{fresh.ndim}-D"
            got = (f"{value.dtype} {value.shape}" if isinstance(value, np.ndarray)
                   else type(value).__name__)
            return f"{where} is {got}, not a {shape} array of {fresh.dtype}"
        return None
    if isinstance(fresh, bool | np.bool_):
        ok = isinstance(value, bool | np.bool_)
    elif isinstance(fresh, int | np.integer):
        ok = isinstance(value, int | np.integer) and not isinstance(value, bool | np.bool_)
    elif isinstance(fresh, float | np.floating):
        ok = isinstance(value, int | float | np.integer | np.floating) \
            and not isinstance(value, bool | np.bool_)
    elif isinstance(fresh, list | tuple):
        ok = isinstance(value, list | tuple)
    elif isinstance(fresh, str):
        ok = isinstance(value, str)
    else:
        return None
    return None if ok else f"{where} is a {type(value).__name__}, not a {type(fresh).__name__}"


def check_kinds(obj: Any, state: dict[str, Any], where: str, same_shape: bool = False) -> None:
    """TypeError for the first saved value in ``state`` that is not of the kind the same
    attribute of ``obj`` (built from the config) holds (``_kind_error``): a hand-edited file
    failed in the middle of the run, or in numba's compiler, with a traceback."""
    for name, value in state.items():
        problem = _kind_error(f"{where}.{name}", getattr(obj, name, None), value, same_shape)
        if problem is not None:
            raise TypeError(problem)


def restore_object(obj: Any, state: dict[str, Any], same_shape: bool = False) -> None:
    """Set the attributes saved by :func:`object_state` (arrays are fresh copies), after
    :func:`check_kinds`."""
    check_kinds(obj, state, type(obj).__name__, same_shape)
    for name, value in state.items():
        if isinstance(value, np.ndarray):
            value = np.ascontiguousarray(value)
        setattr(obj, name, value)


# --- saving --------------------------------------------------------------------------------


def _dataclass_state(obj: Any) -> dict[str, Any]:
    return {f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)}


def _recorder_keys(run: SiloRun) -> list[str]:
    names = [rec.name for rec in run.recorders]
    return [name if names.count(name) == 1 else f"{name}.{k}" for k, name in enumerate(names)]


def save_checkpoint(run: SiloRun, path: Path | str, *, config_toml: str, reason: str,
                    attrs: dict[str, Any] | None = None) -> None:
    """Write the whole state of ``run`` to ``path`` atomically (temporary file, fsync, rename).

    Call it between two chunks of the procedure (a chunk hook), never inside a step."""
    sim = run.sim
    with atomic_hdf5(path, track_order=True, libver=("v110", "latest")) as h5:
        h5.attrs["format"] = FORMAT
        h5.attrs["format_version"] = FORMAT_VERSION
        h5.attrs["silodem_version"] = __version__
        h5.attrs["silodem_source"] = run.started_by or source_digest()  # (the code it began
        # with: a second resume still knows, provenance.py)
        h5.attrs["created"] = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
        h5.attrs["reason"] = reason
        h5.attrs["scenario"] = run.cfg.name
        h5.attrs["step"] = int(sim.steps)
        h5.attrs["time"] = float(sim.time)
        h5.attrs["phase"] = run.state.phase
        h5.attrs["n_particles"] = int(sim.particles.n)
        for key, val in (attrs or {}).items():
            h5.attrs[key] = val
        put(h5, "config_toml", config_toml)
        put(h5, "particles", object_state(sim.particles))
        put(h5, "walls", object_state(sim.walls))
        put(h5, "neighbors", object_state(sim.neighbors, skip=sim.neighbors.NOT_STATE))
        put(h5, "simulation", object_state(sim, skip=_SIM_OBJECTS))
        put(h5, "run", {
            "state": _dataclass_state(run.state),
            "rng": json.dumps(run.rng.bit_generator.state),
            "radii": np.asarray(run.radii),
            "events": json.dumps(run.events, default=_json_default),
            "warnings": list(run.warnings),
            "snapshots": {name: _dataclass_state(s) for name, s in run.snapshots.items()},
        })
        recorders = h5.create_group("recorders", track_order=True)
        for key, rec in zip(_recorder_keys(run), run.recorders):
            put(recorders, key, rec.state())
        h5.attrs[_DIGEST] = _digest(h5)
        h5.flush()


# --- loading -------------------------------------------------------------------------------


@dataclasses.dataclass
class LoadedCheckpoint:
    """A checkpoint read into memory: its config and everything to restore a SiloRun."""

    path: Path
    config: Config
    config_toml: str
    attrs: dict[str, Any]
    data: dict[str, Any]

    @property
    def step(self) -> int:
        return int(self.attrs["step"])

    @property
    def time(self) -> float:
        return float(self.attrs["time"])

    def restore(self, run: SiloRun) -> None:
        """Put the saved state into ``run``, a fresh ``SiloRun`` built from ``self.config``
        (with the same recorders): afterwards it continues exactly as the saved run would."""
        if run.cfg != self.config:
            raise ValueError("restore: the run was built from another config than the "
                             "checkpoint's")
        try:
            self._restore(run)
        except CheckpointError:
            raise
        except (KeyError, IndexError, ValueError, TypeError, AttributeError) as exc:  # what
            # _check_parts missed
            raise CheckpointError(f"{self.path} holds a state this run cannot take "
                                  f"({type(exc).__name__}: {one_line(exc)}); it cannot be "
                                  "resumed") from None

    def _restore(self, run: SiloRun) -> None:
        from silodem.silo.recorders import Snapshot

        d, sim = self.data, run.sim
        restore_object(sim.particles, d["particles"])
        sim.particles.to_lanes()  # placed as a fresh run places them (engine/lanes.py)
        restore_object(sim.walls, d["walls"], same_shape=True)  # the config's walls
        restore_object(sim.neighbors, d["neighbors"])
        sim.neighbors.to_lanes()
        sim.neighbors.forget_derived()
        restore_object(sim, d["simulation"])
        r = d["run"]
        check_kinds(run.state, r["state"], "run.state")
        run.state = type(run.state)(**r["state"])
        rng_state = json.loads(r["rng"])
        if not isinstance(rng_state, dict) or not isinstance(json.loads(r["events"]), dict):
            raise CheckpointError(f"{self.path}: its random generator state or events are "
                                  "not tables: it cannot be resumed")
        if rng_state.get("bit_generator") != type(run.rng.bit_generator).__name__:
            raise CheckpointError(f"{self.path}: random generator {rng_state.get('bit_generator')}"
                                  f" is not this silodem's {type(run.rng.bit_generator).__name__}")
        run.rng.bit_generator.state = rng_state
        run.radii = np.ascontiguousarray(r["radii"])
        run.events = json.loads(r["events"])
        run.warnings = list(r["warnings"])
        run.snapshots = {name: Snapshot(**snap) for name, snap in r["snapshots"].items()}
        settled = run.snapshots.get("settled")
        if "pushed_out" not in r["state"] and run.state.phase == "discharge" \
                and settled is not None:  # a checkpoint from before the list was kept: the
            # grains outside at the opening, from the snapshot taken then (an empty list
            # counted them as discharged once more)
            g = settled.particles
            run.state.pushed_out = run.pushed_out_uids(g["x"], g["y"], g["uid"])
        saved = d.get("recorders", {})
        for key, rec in zip(_recorder_keys(run), run.recorders):
            if key in saved:
                rec.restore(saved[key])
            else:
                run.warnings.append(f"resume: recorder '{key}' was not in the checkpoint; it "
                                    "holds only what it recorded after the resume")
        for key in saved.keys() - set(_recorder_keys(run)):
            run.warnings.append(f"resume: the checkpoint's recorder '{key}' is not part of this "
                                "run; its data is dropped")


def _results_status(folder: Path) -> str | None:
    """The ``status`` of the results.h5 in ``folder`` ("complete" when it has none; None: no
    such file, or not HDF5)."""
    try:
        with h5py.File(folder / "results.h5", "r") as h5:
            status = h5.attrs.get("status", "complete")
    except OSError:
        return None
    return status.decode(errors="replace") if isinstance(status, bytes) else str(status)


def read_checkpoint(where: Path | str) -> LoadedCheckpoint:
    """Read ``where`` (a results folder, or a checkpoint file).  Every problem (missing folder
    or file, unreadable or foreign file, other format version, invalid config) raises
    :class:`CheckpointError` with a one-line message."""
    where = Path(where)
    if where.is_dir():
        path = where / CHECKPOINT_NAME
        if not path.exists():
            status = _results_status(where)
            if status == "complete":
                raise CheckpointError(f"the run in {where} has finished (results.h5 is complete);"
                                      " there is nothing to resume")
            if status == "running":  # (a run killed before it could say it stopped, too)
                raise CheckpointError(f"the run in {where} has written no {CHECKPOINT_NAME} "
                                      "yet: it is still running, or was killed before its "
                                      "first checkpoint; nothing to resume")
            if status is not None:  # a run's results.h5, stopped, with no checkpoint kept
                raise CheckpointError(f"the run in {where} stopped ({status}) with no "
                                      f"{CHECKPOINT_NAME} to go on from (checkpoint.enabled "
                                      "false, none written yet, or the file removed): it "
                                      "cannot be resumed; start it again")
            raise CheckpointError(f"no {CHECKPOINT_NAME} in {where}: nothing to resume (give the "
                                  "results folder of an interrupted run)")
    elif where.exists():
        path = where
    else:
        raise CheckpointError(f"{where} does not exist (give the results folder of an "
                              "interrupted run)")
    try:
        with h5py.File(path, "r") as h5:
            attrs = {k: (v.item() if isinstance(v, np.generic) else v)
                     for k, v in h5.attrs.items()}
            if attrs.get("format") != FORMAT:
                raise CheckpointError(f"{path} is not a silodem checkpoint")
            if attrs.get("format_version") != FORMAT_VERSION:
                raise CheckpointError(
                    f"{path} has checkpoint format {attrs.get('format_version')} (written by "
                    f"silodem {attrs.get('silodem_version')}); this silodem {__version__} reads "
                    f"format {FORMAT_VERSION}")
            data = {key: get(node) for key, node in h5.items()}
            if _DIGEST in attrs:
                changed = attrs[_DIGEST] != _digest(h5)
            else:
                changed = _PLAIN_DIGEST in attrs and attrs[_PLAIN_DIGEST] != _digest(h5, False)
            if changed:
                raise CheckpointError(
                    f"{path} has changed on disk since it was written (the checksum of its "
                    "numbers and texts does not match): the file is damaged; no run can go on "
                    "from it (remove it to start the run again)")
    except CheckpointError:
        raise
    except Exception as exc:  # noqa: BLE001 - a damaged file fails in h5py in many ways
        raise CheckpointError(f"{path} cannot be read as a checkpoint "
                              f"({type(exc).__name__}: {one_line(exc)}): the file is damaged; "
                              "no run can go on from it (remove it to start the run "
                              "again)") from None
    toml_text = data.pop("config_toml", None)
    if not isinstance(toml_text, str):
        raise CheckpointError(f"{path} holds no config (its config_toml is "
                              f"{type(toml_text).__name__}, not TOML text)")
    _check_parts(data, path)
    cfg = config_from_text(toml_text, f"{path}: the config it holds", CheckpointError)
    return LoadedCheckpoint(path, cfg, toml_text, attrs, data)


REQUIRED = {"particles": ("n", "x", "y", "vx", "vy", "omega", "radius", "mass", "uid"),
            "walls": ("ax", "ay", "bx", "by"), "neighbors": (), "simulation": ("time", "steps"),
            "run": ("state", "rng", "radii", "events", "warnings", "snapshots")}
"""The parts of a checkpoint that :meth:`LoadedCheckpoint.restore` reads, and some members."""


def _check_parts(data: dict[str, Any], path: Path) -> None:
    """CheckpointError when a part that a resume needs is missing, or the grains' arrays and
    count or the phase disagree (a hand-edited or foreign file read as a checkpoint): found
    here, in one line, not as a KeyError or a broadcast error in the middle of a run."""
    from silodem.silo.procedure import PHASES

    for part, members in REQUIRED.items():
        node = data.get(part)
        if not isinstance(node, dict):
            raise CheckpointError(f"{path} lacks /{part}: it cannot be resumed")
        for member in members:
            if member not in node:
                raise CheckpointError(f"{path} lacks /{part}/{member}: it cannot be resumed")
    grains = data["particles"]
    arrays = {k: v for k, v in grains.items() if isinstance(v, np.ndarray) and v.ndim == 1}
    lengths = {v.size for v in arrays.values()}
    n = grains["n"]
    if len(lengths) != 1 or not isinstance(n, int | np.integer) or not 0 <= n <= min(lengths):
        raise CheckpointError(f"{path}: its {n} grains and their arrays of lengths "
                              f"{sorted(lengths)} disagree: it cannot be resumed")
    phase = data["run"]["state"].get("phase") if isinstance(data["run"]["state"], dict) else None
    if phase not in PHASES:
        raise CheckpointError(f"{path}: its phase {phase!r} is not one of {', '.join(PHASES)}: "
                              "it cannot be resumed")
    taken = data["run"]["snapshots"]
    needed = {"discharge": ("settled",), "done": ("settled", "final")}.get(phase, ())
    lacking = [name for name in needed if not (isinstance(taken, dict) and name in taken)]
    if lacking:  # (a phase edited by hand: 'done' gave a complete results.h5 without them)
        raise CheckpointError(f"{path}: its phase {phase!r} comes after the {lacking[0]} "
                              "snapshot, which it lacks: it cannot be resumed")
    _check_neighbors(data["neighbors"], int(n), path)


def _check_neighbors(nb: dict[str, Any], n: int, path: Path) -> None:
    """CheckpointError when the neighbour list's offsets and indices do not fit its arrays
    and the ``n`` grains: the kernels index with them unchecked, and a shortened pair_j or
    i_start (a hand-edited file) ended the resume in a segmentation fault."""
    def arr(key: str) -> np.ndarray:
        value = nb.get(key)
        return np.asarray(value) if isinstance(value, np.ndarray) else np.zeros(0, np.int64)

    problems = []
    for start, owned in (("i_start", ("pair_j", "pair_fs", "pair_fn")),
                         ("w_start", ("wc_w", "wc_fs", "wc_fn", "wc_fx", "wc_fy"))):
        offsets = arr(start)
        sizes = {arr(k).size for k in owned}
        if (offsets.size != n + 1 or len(sizes) != 1 or offsets[0] != 0
                or np.any(np.diff(offsets) < 0) or offsets[-1] > min(sizes)):
            problems.append(f"{start} and {', '.join(owned)}")
    j = arr("pair_j")[: arr("i_start")[-1] if arr("i_start").size else 0]
    if j.size and not (0 <= j.min() and j.max() < n):
        problems.append("pair_j's grains")
    for key in ("i_apart", "wall_gap"):
        if arr(key).size != n:
            problems.append(key)
    for key in ("strip_start", "cell_start", "slot_of_uid"):
        v = arr(key)
        if v.size and not (-1 <= v.min() and v.max() <= n):
            problems.append(key)
    if problems:
        raise CheckpointError(f"{path}: its neighbour list does not fit its {n} grains "
                              f"({'; '.join(problems)}): it cannot be resumed")
