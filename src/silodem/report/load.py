"""Read a results folder (results.h5 + config) into memory for the figures and the report."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from silodem.checkpoint import CHECKPOINT_NAME as CHECKPOINT
from silodem.config import Config
from silodem.errors import InputError
from silodem.scenario_files import config_from_text


def _tree(group, only: tuple[str, ...] | None = None,
          skip: tuple[str, ...] = ()) -> dict[str, Any]:
    """A nested dict of an HDF5 group: datasets as NumPy arrays, attributes under '@attrs',
    the datasets' ``unit`` attributes under '@units' (of the members named ``only``, if
    given; never of those named ``skip``)."""
    import h5py

    out: dict[str, Any] = {"@attrs": {k: _plain(v) for k, v in group.attrs.items()}}
    units: dict[str, str] = {}
    for key, item in group.items():
        if key in skip or (only is not None and key not in only):
            continue
        if isinstance(item, h5py.Group):
            out[key] = _tree(item)
        else:
            if "unit" in item.attrs:
                units[key] = str(_plain(item.attrs["unit"]))
            data = item[()]
            if item.dtype.kind in "OS":
                data = np.array([d.decode() if isinstance(d, bytes) else str(d)
                                 for d in np.atleast_1d(data)])
            out[key] = data
    if units:
        out["@units"] = units
    return out


def _plain(value):
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, np.generic):
        return value.item()
    return value


@dataclass
class Results:
    """A run's results: config, attributes, events, warnings and every group of results.h5."""

    folder: Path
    cfg: Config
    config_toml: str
    attrs: dict[str, Any]
    events: dict[str, Any]
    warnings: list[str]
    data: dict[str, Any] = field(repr=False)

    def group(self, *path: str) -> dict[str, Any] | None:
        node: Any = self.data
        for p in path:
            if not isinstance(node, dict) or p not in node:
                return None
            node = node[p]
        return node

    def snapshot(self, name: str) -> dict[str, Any] | None:
        """'settled', 'final' or 'discharge' (taken by the measurement recorder)."""
        if name == "discharge":
            return self.group("measure", "discharge_snapshot")
        return self.group(name)


SAMPLED = ("step", "phase", "circles/stress", "circles/porosity", "circles/coordination",
           "circles/count", "band/coordination", "band/count", "band/stress", "wall_bins/normal",
           "wall_bins/shear", "profiles/left", "profiles/right", "profiles/slices")
"""The datasets of /measure with one row per sample (docs/output.md: shape (S, ...))."""


WALL_KEYS = ("name", "ax", "ay", "bx", "by")  # /walls: every run writes these


def _check_parts(res: Results, only: tuple[str, ...] | None) -> None:
    """InputError when a part every run writes is missing (the time step, the walls of the
    loaded groups) or when the columns of /timeseries, or the per-sample datasets of /measure
    and /measure/time, have different numbers of rows (a damaged or hand-edited file), before
    a reader or a figure trips over it."""
    where = res.folder / "results.h5"
    if "dt" not in res.attrs:
        raise InputError(f"{where} has no attribute dt (damaged, or not written by silodem)")
    walls = res.group("walls")
    if (only is None or "walls" in only) and not (
            isinstance(walls, dict) and all(k in walls for k in WALL_KEYS)):
        raise InputError(f"{where} has no /walls with {', '.join(WALL_KEYS)} (damaged?)")
    series = res.group("timeseries") or {}
    lengths = {k: np.shape(v)[0] for k, v in series.items()
               if isinstance(v, np.ndarray) and v.ndim == 1}
    if len(set(lengths.values())) > 1:
        (a, n_a), (b, n_b) = min(lengths.items(), key=lambda kv: kv[1]), max(
            lengths.items(), key=lambda kv: kv[1])
        raise InputError(f"{where}: /timeseries/{a} has {n_a} rows where /timeseries/{b} has "
                         f"{n_b} (damaged?)")
    samples = np.size(res.group("measure", "time"))
    for name in SAMPLED:
        node = res.group("measure", *name.split("/"))
        if node is None:
            continue
        rows = np.shape(node)[0] if np.ndim(node) else 0
        if rows != samples:
            raise InputError(f"{where}: /measure/{name} has {rows} rows where /measure/time "
                             f"has {samples} (damaged?)")


def load_results(folder: Path | str, only: tuple[str, ...] | None = None) -> Results:
    """Load ``folder``/results.h5 (its attributes and config, and of its groups only those
    named ``only``, if given); InputError (one line) when it is missing or unreadable.  The
    saved frames (``/frames``, the bulk of a run's data) are left on the disk:
    ``silodem.silo.frames.read_frames`` reads them a block at a time."""
    import h5py

    folder = Path(folder)
    path = folder / "results.h5"
    if folder.is_file():
        raise InputError(f"{folder} is a file; give the results folder that holds it")
    if not folder.is_dir():
        what = "not a folder" if folder.exists() else "no such folder"  # (/dev/null: exists)
        raise InputError(f"{folder} is not a results folder ({what})")
    if path.exists() and not path.is_file():
        raise InputError(f"{path} is not a file")
    if not path.is_file():
        if (folder / CHECKPOINT).is_file():  # ('silodem run --out' refuses its folder)
            raise InputError(f"{folder} holds no results.h5 but the {CHECKPOINT} of an "
                             f"unfinished run: continue it with 'silodem run --resume "
                             f"{folder}' (it writes results.h5 as it goes)")
        if (folder / "study.toml").is_file():  # ('silodem sweep --out' made it)
            raise InputError(f"{folder} is a study's folder: its report is "
                             f"{folder / 'report.html'}, and each run's folder is under "
                             f"{folder / 'runs'}")
        raise InputError(f"{folder} holds no results.h5 (run 'silodem run --out {folder}' first)")
    try:
        with h5py.File(path, "r") as h5:
            data = _tree(h5, only, skip=("frames",))
    except Exception as exc:  # noqa: BLE001 - a damaged file fails in h5py in many ways
        raise InputError(f"cannot read {path} (damaged?): {type(exc).__name__}: {exc}") from None
    measure = data.get("measure")
    if isinstance(measure, dict) and np.size(measure.get("time", ())) == 0:
        del data["measure"]  # not one sample (measure.interval longer than the run): none
    attrs = data.get("@attrs", {})
    toml_text = attrs.get("config_toml")
    config_file = folder / "config.toml"
    if toml_text is None and config_file.is_file():
        try:
            toml_text = config_file.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise InputError(f"cannot read {config_file}: {exc}") from None
    if toml_text is None:
        raise InputError(f"{path} holds no config (attribute config_toml)")
    if not isinstance(toml_text, str):
        raise InputError(f"{path}: its attribute config_toml is a {type(toml_text).__name__}, "
                         "not the config's TOML text (damaged?)")
    cfg = config_from_text(toml_text, f"the config saved in {path}")
    events = dict(data.get("events", {}).get("@attrs", {}))
    warnings = [str(w) for w in np.atleast_1d(data.get("warnings", np.zeros(0)))]
    res = Results(folder, cfg, toml_text, attrs, events, warnings, data)
    _check_parts(res, only)
    return res
