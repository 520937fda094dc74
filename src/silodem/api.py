"""The Python API for notebooks: build a scenario, run it, read its results as pandas
DataFrames and NumPy arrays (docs/api.md).

    from silodem import api

    cfg = api.scenario("paper-case2", quick=True, set={"material.friction_deg": 25.0})
    res = api.run(cfg, "runs/nb1")          # or api.open_results("runs/paper-case2")
    res.timeseries()                        # one row per sample: time, phase, energy, ...
    res.particles("settled")                # one row per grain of a snapshot
    res.wall_profile("fill")                # the wall stresses the report draws as Fig. 3a
    res.numbers()                           # the report's key numbers

Everything here reads; nothing changes a results folder except :func:`run`, which writes one.
Bad input raises :class:`silodem.errors.InputError` with the same one-line message the
command line prints.  What a run has to say (soft contacts, grains lost, not settled, an
earlier run's results replaced) comes as a :class:`SilodemWarning` through Python's
``warnings`` module, which shows it in a notebook and filters it as any other warning.
"""

from __future__ import annotations

import warnings as _warnings
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from silodem.config import Config
from silodem.errors import InputError, check_flag
from silodem.errors import short_repr as _got
from silodem.report.load import Results as _Raw
from silodem.report.load import load_results
from silodem.silo.recorders import PHASE_CODES

if TYPE_CHECKING:
    from silodem.report.analysis import Analysis
    from silodem.silo.frames import Frames

SNAPSHOTS = ("settled", "discharge", "final")  # "discharge": mid-window of the discharge
PHASE_NAMES = {code: name for name, code in PHASE_CODES.items()}  # of the phase columns


class SilodemWarning(UserWarning):
    """What a run has to say that does not stop it: each of its warnings (``RunResults.warnings``:
    soft contacts, grains lost through a wall, not settled, ...), and the earlier run's results
    that :func:`run` replaces in its folder.  Filter them as any warning, e.g.
    ``warnings.filterwarnings("ignore", "replacing the earlier run", SilodemWarning)``."""


# Shown every time, not once per calling line as Python's default does: a notebook cell run
# again, or a loop of runs, repeats the same texts, and each run's must be seen.  Appended, so
# that any filter of the user's (warnings.filterwarnings, -W, PYTHONWARNINGS) comes first.
_warnings.filterwarnings("always", category=SilodemWarning, append=True)


def scenario(source: str = "paper-case2", *, quick: bool = False,
             set: dict[str, Any] | None = None) -> Config:
    """The validated config of an embedded scenario or a TOML file, with ``set``'s dotted keys
    given new values (as ``--set``: ``{"material.kn": 2e7}``) and, with ``quick``, shrunk as
    ``--quick`` does.

    A ``Config`` as ``source`` is refused (InputError), not returned as it is: it is already
    what this returns, ready for :func:`run`, and ``quick`` and ``set`` would be silently left
    out (or, applied, shrink an already quick config twice).  To change a built config, call
    this again with the scenario it came from and ``set`` (a quick config's name ends in
    ``-quick``: give the scenario's own name with ``quick=True``), or with a run's
    ``config.toml``, or use ``cfg.model_copy(update=...)``, which :func:`run` checks again
    (its keys are one section's field names, not dotted keys)."""
    from silodem.scenario_files import (
        _toml_value,
        load_config,
        quick_overrides,
        quick_variant,
    )

    if isinstance(source, Config):
        raise InputError(f"source is a Config already built ({_got(source.name)}): pass it to "
                         "api.run directly; api.scenario takes a scenario name or a TOML file")
    if not isinstance(source, str | Path):
        raise InputError("source must be a scenario name or a TOML file's path; got "
                         f"{_got(source)}")
    check_flag(quick, "quick")
    if set is not None and not isinstance(set, Mapping):
        raise InputError("set must map dotted keys to values, e.g. {'material.kn': 2e7}; got "
                         f"{_got(set)}")
    sets = []
    for key, value in (set or {}).items():
        if isinstance(value, np.generic):  # numpy's scalars, as notebooks make them
            value = value.item()
        if isinstance(value, Mapping):
            raise InputError(f"set {_got(key)}: give each value by its dotted key, not a table")
        if not isinstance(key, str) or "=" in key or not key.strip():
            raise InputError(f"set {_got(key)}: a key is a dotted name such as 'material.kn' "
                             "(its value goes on the right of the colon)")
        try:
            sets.append(f"{key}={_toml_value(value)}")
        except (TypeError, ValueError):  # ValueError: an int of more than 4300 digits
            raise InputError(f"set {_got(key)}: {_got(value)} is not a TOML value") from None
    cfg = load_config(str(source), sets, flag="set")
    if not quick:
        return cfg
    small = quick_variant(cfg)
    changed = quick_overrides(cfg, small, sets)
    if changed:  # as the command line says it: a value given, changed
        _warnings.warn(f"quick changed what set gave: {changed} (it shrinks the silo after "
                       "set)", SilodemWarning, stacklevel=2)
    return small


def run(cfg: Config, out: Path | str | None = None, *, threads: int | None = None,
        progress: bool = False) -> RunResults:
    """Run ``cfg`` into the folder ``out`` (default ``runs/<name>``), as ``silodem run`` does,
    and open its results.

    Each of the run's warnings (``RunResults.warnings``, and a report.html that could not be
    written) is issued as a :class:`SilodemWarning` once the run has ended, from the line
    that called this; with ``progress`` those the progress display printed as they came are
    not issued again (the final count of grains lost is).  A finished run's results already
    in ``out`` are replaced, which a SilodemWarning says before the run starts."""
    from silodem.run import check_out, check_threads, run_simulation
    from silodem.run_folder import check_config_kept, replacing_note
    from silodem.scenario_files import revalidated
    from silodem.silo.checks import check_numbers

    if not isinstance(cfg, Config):
        raise InputError(f"cfg must be a Config (from api.scenario); got {_got(cfg)}")
    cfg = revalidated(cfg)  # a model_copy(update=...) of it skipped the schema's checks
    if out is not None and (not isinstance(out, str | Path) or not str(out).strip()):
        raise InputError(f"out must be a results folder's path; got {_got(out)}")
    if isinstance(threads, np.integer):  # numpy's integers, as notebooks make them
        threads = int(threads)
    check_threads(threads)
    check_flag(progress, "progress")
    check_numbers(cfg)  # values that make no run together: refused before any folder is made
    folder = Path(out) if out is not None else Path("runs") / cfg.name
    check_out(folder)  # as the command line: never a file, never over an unfinished run
    replacing = replacing_note(folder)  # nor over files no silodem run wrote
    check_config_kept(None, folder, cfg, "out")  # nor over a config.toml of the user's
    if replacing is not None:  # (the command line prints it on stderr: cli/commands_run.py)
        _warnings.warn(replacing, SilodemWarning, stacklevel=2)
    summary = run_simulation(cfg, folder, threads=threads, progress=progress)
    for text in summary.warnings:
        if text not in summary.warnings_shown:  # (empty without progress)
            _warnings.warn(text, SilodemWarning, stacklevel=2)
    return open_results(folder)


def open_results(folder: Path | str) -> RunResults:
    """The results of the run in ``folder`` (its results.h5, read once)."""
    if not isinstance(folder, str | Path) or not str(folder).strip():
        raise InputError(f"folder must be a results folder's path; got {_got(folder)}")
    return RunResults(load_results(folder))


# the columns a table starts with, in this order (results.h5 keeps a group's datasets in
# alphabetical order); the others follow in the file's order
_FIRST = ("time", "step", "phase", "phase_name", "grain", "wall", "i", "j", "x", "y", "vx", "vy",
          "omega", "radius", "uid", "fn", "fs", "fx", "fy")


def _frame(group: dict[str, Any] | None, what: str) -> pd.DataFrame:
    """The group's 1-D datasets as a DataFrame, ``attrs["units"]`` their units (docs/output.md;
    datasets' ``unit`` attributes)."""
    if group is None:
        raise InputError(f"this results file has no {what}")
    columns = {k: v for k, v in group.items()
               if not k.startswith("@") and isinstance(v, np.ndarray) and v.ndim == 1}
    return _table(columns, dict(group.get("@units", {})))


def _table(columns: Mapping[str, Any], units: dict[str, str]) -> pd.DataFrame:
    """A DataFrame of ``columns``, those named in ``_FIRST`` first, with ``units`` of its
    columns in ``attrs["units"]``."""
    first = [k for k in _FIRST if k in columns]
    df = pd.DataFrame({k: columns[k] for k in [*first, *(k for k in columns if k not in first)]})
    df.attrs["units"] = {k: u for k, u in units.items() if k in df.columns}
    return df


def _add(df: pd.DataFrame, name: str, values: Any, unit: str, after: str | None = None) -> None:
    """Put column ``name`` of ``unit`` into ``df`` (after column ``after``, else last)."""
    at = df.columns.get_loc(after) + 1 if after is not None else len(df.columns)
    df.insert(at, name, values)
    df.attrs["units"][name] = unit


class RunResults:
    """One run's results (``open_results``): the config, events and warnings, and its data
    as DataFrames (SI units, compressive stresses positive; masses, forces and energies of
    the slab of thickness t, not per metre of it)."""

    def __init__(self, raw: _Raw) -> None:
        self._raw = raw
        self._analysis = None

    def __repr__(self) -> str:
        return f"RunResults({str(self.folder)!r}, scenario={self.config.name!r})"

    folder = property(lambda self: self._raw.folder, doc="the results folder")
    config = property(lambda self: self._raw.cfg, doc="the run's complete Config")
    events = property(lambda self: dict(self._raw.events),
                      doc="fill time, settling, discharge end... (docs/output.md)")
    warnings = property(lambda self: list(self._raw.warnings),
                        doc="the run's warnings, as results.h5 holds them (api.run issued each "
                            "as a SilodemWarning; the command line printed them)")
    status = property(lambda self: str(self._raw.attrs.get("status", "complete")),
                      doc="'complete', or how far an unfinished run's file goes")
    dt = property(lambda self: float(self._raw.attrs["dt"]), doc="the time step [s]")

    def timeseries(self) -> pd.DataFrame:
        """/timeseries: one row per sample (every output.sample_interval), with the phase's
        name in ``phase_name``."""
        df = _frame(self._raw.group("timeseries"), "/timeseries")
        _add(df, "phase_name", df["phase"].map(PHASE_NAMES), "-", after="phase")
        return df

    def _snapshot(self, name: str) -> dict[str, Any]:
        if name not in SNAPSHOTS:
            raise InputError(f"snapshot must be one of {', '.join(SNAPSHOTS)}; got {_got(name)}")
        snap = self._raw.snapshot(name)
        if snap is None:
            raise InputError(f"the run has no '{name}' snapshot (not reached, or not recorded)")
        return snap

    def particles(self, snapshot: str = "final") -> pd.DataFrame:
        """The grains of a snapshot: x, y [m], vx, vy [m/s], omega [rad/s], radius [m], uid,
        fx, fy [N] (resultant contact force), and mass [kg] from the config."""
        df = _frame(self._snapshot(snapshot).get("particles"), f"{snapshot}/particles")
        m = self.config.material
        _add(df, "mass", m.density * np.pi * df["radius"] ** 2 * m.thickness, "kg")
        return df

    def contacts(self, snapshot: str = "final") -> pd.DataFrame:
        """The touching grain pairs of a snapshot: i, j (rows of ``particles``), fn, fs [N],
        fx, fy [N] (the force on j)."""
        return _frame(self._snapshot(snapshot).get("contacts"), f"{snapshot}/contacts")

    def wall_contacts(self, snapshot: str = "final") -> pd.DataFrame:
        """The touching grain-wall contacts of a snapshot: grain, wall, fn, fs, fx, fy [N]."""
        return _frame(self._snapshot(snapshot).get("wall_contacts"),
                      f"{snapshot}/wall_contacts")

    def measurements(self) -> pd.DataFrame:
        """The measurement samples (every measure.interval): time, step, phase, the junction
        band's coordination number and stress, and each circle's coordination number, porosity
        and stress (``<circle>_coordination``, ``<circle>_porosity`` [-], ``<circle>_sigma_xx``
        / ``_zz`` / ``_xz`` [Pa])."""
        m = self._raw.group("measure")
        if m is None:
            raise InputError("this run recorded no measurements (measure recorder absent, or "
                             "no sample)")
        cols = {"time": m["time"], "step": m["step"], "phase": m["phase"],
                "phase_name": pd.Series(m["phase"]).map(PHASE_NAMES).to_numpy()}
        units = {"time": "s", "step": "-", "phase": "-", "phase_name": "-"}

        def put(name: str, values: np.ndarray, unit: str) -> None:
            cols[name], units[name] = values, unit

        put("band_coordination", m["band"]["coordination"], "-")
        for k, comp in enumerate(("xx", "zz", "xz")):
            put(f"band_sigma_{comp}", m["band"]["stress"][:, k], "Pa")
        c = m["circles"]
        for n, name in enumerate(str(x) for x in c["name"]):
            put(f"{name}_coordination", c["coordination"][:, n], "-")
            if "porosity" in c:
                put(f"{name}_porosity", c["porosity"][:, n], "-")
            for k, comp in enumerate(("xx", "zz", "xz")):
                put(f"{name}_sigma_{comp}", c["stress"][:, n, k], "Pa")
        return _table(cols, units)

    def analysis(self) -> Analysis:
        """The report's analysis (``silodem.report.analysis.Analysis``), made once."""
        if self._analysis is None:
            from silodem.report.analysis import analyse

            self._analysis = analyse(self._raw)
        return self._analysis

    def wall_profile(self, window: str = "fill") -> pd.DataFrame:
        """Wall stresses along the silo's edges, time-averaged over the ``'fill'`` window (the
        end of settling) or the ``'discharge'`` window: z [m] (bin centre), sigma_n [Pa] (both
        sides averaged), tau_down [Pa] (downward shear traction), on_vertical (bin on a vertical
        wall).  What Figs. 3a and 6 of the report draw."""
        if window not in ("fill", "discharge"):
            raise InputError(f"window must be 'fill' or 'discharge'; got {_got(window)}")
        edge = self.analysis().edge.get(window)
        if edge is None:
            raise InputError(f"no wall profile for the {window} window (not reached, or no "
                             "measurement sample in it)")
        return _table({"z": edge.z, "sigma_n": edge.sigma_n, "tau_down": edge.tau_down,
                       "on_vertical": edge.on_vertical},
                      {"z": "m", "sigma_n": "Pa", "tau_down": "Pa", "on_vertical": "-"})

    def numbers(self) -> pd.DataFrame:
        """The report's key numbers: quantity, value (text, as the report prints it: '26,045
        at z = 0.751 m (hopper wall)'), unit.  To compute with them, take the numbers behind
        them: :meth:`summary` (``wall_peak_fill``, ``discharge_rate``, ...: docs/sweeps.md)
        or :meth:`analysis` (``peaks``, ``janssen``, ...: docs/measurements.md)."""
        return pd.DataFrame(self.analysis().numbers, columns=["quantity", "value", "unit"])

    def summary(self) -> dict[str, Any]:
        """The per-run quantities of a study's results.csv (docs/sweeps.md), as a dict."""
        from silodem.study.table import summarise_run

        return summarise_run(self.folder)

    def frames(self) -> Frames:
        """The saved frames (``silodem.silo.frames.Frames``) for pictures and animations."""
        from silodem.silo.frames import NoFramesError, read_frames

        try:
            return read_frames(self.folder / "results.h5")
        except NoFramesError as exc:
            raise InputError(str(exc)) from None
