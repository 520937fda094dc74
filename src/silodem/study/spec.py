"""Study files: a base scenario, seeds, fixed overrides and a grid of values (docs/sweeps.md).

```toml
name = "my-study"                 # optional; default: the file name
description = "..."               # optional
base = "paper-case2"              # an embedded scenario, or a .toml file (relative to this file)
seeds = [1, 2]                    # every grid point is run once per seed
[set]                             # optional: values every run gets
"fill.n_particles" = 480
[grid]                            # dotted config keys -> lists of values; the full product is run
"silo.hopper_angle_from_horizontal_deg" = [35, 45]
"material.friction_deg" = [20, 30]
```

The grid key ``base`` (``GRID_BASE``), instead of the top-level ``base``, lists base scenarios:
each grid point then starts from its own.

Dotted keys may be written quoted (one key) or bare (TOML then nests them as tables: ``[grid]
material.friction_deg = [20, 30]`` is the same as the quoted form).  The embedded studies are
the TOML files of the package folder ``silodem/studies/``.  Every problem is an
:class:`InputError` with one line.
"""

from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    StrictInt,
    ValidationError,
    field_validator,
    model_validator,
)

from silodem.config import Config, folder_name
from silodem.errors import (
    InputError,
    did_you_mean,
    format_validation_error,
    model_at,
    one_line,
    parse_toml,
    short_repr,
    shorten,
    submodel,
    unknown_key_message,
)
from silodem.scenario_files import flat_table

GRID_BASE = "base"  # a [grid] key whose values are base scenarios, not a config key
RESERVED_KEYS = {"seed": "give the seeds in the study's 'seeds' list",
                 "name": "the runs are named by the study",
                 "description": "the runs are described by the study"}


def _flatten(table: Any, where: str) -> Any:
    """A study's ``[set]`` or ``[grid]`` table with dotted keys (``scenario_files.flat_table``;
    anything else as it is, for the schema to refuse)."""
    return flat_table(table, where) if isinstance(table, dict) else table


def _same_value(a: Any, b: Any) -> bool:
    """Whether two grid values are one: equal numbers whatever their kind (20 and 20.0 gave
    the same runs), else equal values of one type (True is not 1)."""
    numbers = (int, float)
    if (isinstance(a, numbers) and isinstance(b, numbers)
            and not isinstance(a, bool) and not isinstance(b, bool)):
        return a == b
    return type(a) is type(b) and a == b


def _first_repeat(values: list[Any]) -> int | None:
    """Index of the first value that is one with an earlier one (``_same_value``), or None.
    Hashable values are looked up in a set (a number's key is its value: 20 and 20.0 have
    one hash and are equal); only unhashable ones (lists, tables) are compared pairwise."""
    seen: set[Any] = set()
    unhashable: list[Any] = []
    for k, v in enumerate(values):
        number = isinstance(v, (int, float)) and not isinstance(v, bool)
        key = ("number", v) if number else (type(v), v)
        try:
            if key in seen:
                return k
            seen.add(key)
        except TypeError:
            if any(_same_value(v, u) for u in unhashable):
                return k
            unhashable.append(v)
    return None


# keys that change what a run writes or when it saves its state, not what it computes: a grid
# over them runs one simulation once per value (output.sample_interval is not among them: the
# time series it samples are what the discharge rate is fitted to)
NOT_SWEPT = ("output.png", "output.frame_interval", "output.vtk_interval", "measure.report")
NOT_SWEPT_SECTION = "checkpoint."  # every key of it


def check_grid_key(dotted: str) -> None:
    """ValueError unless ``dotted`` is a value key that changes what a run computes
    (:func:`check_config_key`, and not one of ``NOT_SWEPT`` or ``NOT_SWEPT_SECTION``)."""
    check_config_key(dotted)
    if dotted in NOT_SWEPT or dotted.startswith(NOT_SWEPT_SECTION):
        raise ValueError(f"'{dotted}' changes what a run writes, not what it computes: each "
                         "of its values would give the same results; put it in [set]")


def check_config_key(dotted: str) -> None:
    """ValueError unless ``dotted`` is a value key (not a section) of the run Config schema."""
    parts = [p.strip() for p in dotted.split(".")]
    if ".".join(parts) != dotted:  # (checked stripped, then set unstripped: unknown key)
        raise ValueError(f"'{shorten(dotted)}' has spaces around its parts: write "
                         f"'{shorten('.'.join(parts))}'")
    if parts[0] in RESERVED_KEYS and len(parts) == 1:
        raise ValueError(f"'{dotted}' cannot be set by a study: {RESERVED_KEYS[parts[0]]}")
    parent = model_at(Config, parts[:-1])
    if parent is None or parts[-1] not in parent.model_fields:
        raise ValueError(unknown_key_message(Config, parts))
    sub = submodel(parent.model_fields[parts[-1]].annotation)
    if sub is not None:
        example = next(iter(sub.model_fields))
        raise ValueError(f"'{dotted}' is a section, not a value; give a key inside "
                         f"it, e.g. '{dotted}.{example}'")


# runs in one study at most: 1e5 runs of the quickest scenario are days of one core, and
# planning them (each run's config validated and checked) already takes about a minute
MAX_RUNS = 100_000


class StudySpec(BaseModel):
    """A parametric study: ``base`` x ``set`` x the product of ``grid`` x ``seeds``."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    name: str = Field("", description="study name (default: the study file's name)")
    description: str = Field("", description="free text")
    base: str | None = Field(None, min_length=1, description="embedded scenario name or .toml "
                             "file of the base configuration (a relative path is taken from the "
                             "study file's folder); or a list of them as the [grid] key 'base'")
    seeds: list[StrictInt] = Field(description="seeds; every grid point runs once per seed")
    set: dict[str, Any] = Field(default_factory=dict,
                                description="dotted config keys -> values every run gets")
    grid: dict[str, list[Any]] = Field(description="dotted config keys -> lists of values; "
                                       "the full product is run")

    @model_validator(mode="before")
    @classmethod
    def _flatten_tables(cls, data: Any) -> Any:
        if isinstance(data, dict):
            data = dict(data)
            if "set" in data:
                data["set"] = _flatten(data["set"], "set")
            if "grid" in data:
                data["grid"] = _flatten(data["grid"], "grid")
        return data

    @field_validator("name")
    @classmethod
    def _name(cls, name: str) -> str:
        return folder_name(name, "name") if name else name

    @field_validator("seeds")
    @classmethod
    def _seeds(cls, seeds: list[int]) -> list[int]:
        if not seeds:  # (pydantic's words were "List should have at least 1 item ...")
            raise ValueError("seeds is empty: give one or more, e.g. seeds = [1, 2]")
        if any(s < 0 for s in seeds):
            raise ValueError("seeds must be integers >= 0")
        if len(set(seeds)) != len(seeds):
            raise ValueError("seeds must not repeat")
        return seeds

    @field_validator("set")
    @classmethod
    def _set_keys(cls, table: dict[str, Any]) -> dict[str, Any]:
        for key in table:
            check_config_key(key)
        return table

    @field_validator("grid")
    @classmethod
    def _grid_keys(cls, table: dict[str, list[Any]]) -> dict[str, list[Any]]:
        if not table:
            raise ValueError("[grid] is empty: give one or more keys, each with a list of "
                             'values, e.g. "material.friction_deg" = [20, 30]')
        for key, values in table.items():
            if key == GRID_BASE:  # base scenarios: compare cases that differ in many keys
                if not all(isinstance(v, str) and v.strip() for v in values):
                    raise ValueError("[grid] 'base' lists base scenarios: embedded scenario "
                                     "names or .toml files, as strings")
            else:
                check_grid_key(key)
            if not values:
                raise ValueError(f"'{key}' has no values; give a list of one or more")
            if len(values) > MAX_RUNS:
                raise ValueError(f"'{key}' lists {len(values)} values; a study runs at most "
                                 f"{MAX_RUNS}")
            repeat = _first_repeat(values)
            if repeat is not None:
                raise ValueError(f"'{key}' lists {short_repr(values[repeat])} twice")
        return table

    @model_validator(mode="after")
    def _no_overlap(self) -> StudySpec:
        both = sorted(set(self.set) & set(self.grid))
        if both:
            raise ValueError(f"'{both[0]}' is both in [set] and in [grid]; keep it in one")
        if self.base is None and GRID_BASE not in self.grid:
            raise ValueError("missing required key 'base' (the base scenario; or a list of them "
                             "as [grid] base = [...])")
        if self.base is not None and GRID_BASE in self.grid:
            raise ValueError("'base' is both at the top and in [grid]; keep it in one")
        if self.n_runs > MAX_RUNS:
            sizes = " x ".join(str(len(v)) for v in self.grid.values())
            seeds = f"{len(self.seeds)} seed{'s' if len(self.seeds) > 1 else ''}"
            raise ValueError(f"the study has {self.n_runs} runs ({seeds} x grid {sizes}); at "
                             f"most {MAX_RUNS}: split it into several studies")
        return self

    @property
    def n_runs(self) -> int:
        n = len(self.seeds)
        for values in self.grid.values():
            n *= len(values)
        return n


# --- embedded studies ------------------------------------------------------------------------


def _study_files() -> dict[str, Any]:
    folder = resources.files("silodem") / "studies"
    files = {}
    if folder.is_dir():
        for entry in folder.iterdir():
            if entry.is_file() and entry.name.endswith(".toml"):
                files[entry.name[: -len(".toml")]] = entry
    return dict(sorted(files.items()))


def study_names() -> list[str]:
    """Names of the embedded studies, sorted."""
    return list(_study_files())


def list_studies() -> list[tuple[str, str]]:
    """``(name, description)`` of every embedded study."""
    out = []
    for name, entry in _study_files().items():
        try:
            desc = str(tomllib.loads(entry.read_text(encoding="utf-8")).get("description", ""))
        except tomllib.TOMLDecodeError:
            desc = "(unreadable study file)"
        out.append((name, one_line(desc)))
    return out


# --- loading ---------------------------------------------------------------------------------


def _read(source: str) -> tuple[str, str, Path | None]:
    """(TOML text, default name, folder for relative paths) of a study name or file."""
    files = _study_files()
    names = ", ".join(files) or "none"
    if not str(source).strip():
        raise InputError(f"empty study name: give an embedded study ({names}) or a .toml file")
    path = Path(source)
    try:
        is_file, exists = path.is_file(), path.exists()
    except (OSError, ValueError):
        is_file = exists = False
    if is_file:
        try:
            return path.read_text(encoding="utf-8"), path.stem, path.resolve().parent
        except (OSError, UnicodeDecodeError) as exc:
            raise InputError(f"cannot read study file {source}: {exc}") from None
    if exists and source not in files:  # a folder named like a study leaves the name to it
        raise InputError(f"{source} is not a file (give a study .toml file or one of: {names})")
    if source in files:
        return files[source].read_text(encoding="utf-8"), source, None
    if str(source).endswith(".toml") or "/" in str(source) or "\\" in str(source):
        raise InputError(f"study file not found: {source} (give an existing .toml file, or an "
                         f"embedded study: {names})")
    from silodem.scenario_files import scenario_names

    if source in scenario_names():
        raise InputError(f"'{source}' is a scenario, not a study; a study names it as its base "
                         f"(see 'silodem show paper-study'); embedded studies: {names}")
    if path.suffix:  # 'my.yaml': a file name, not a study's
        raise InputError(f"study file not found: {source} (a study is a .toml file; or give "
                         f"an embedded study: {names})")
    hint = did_you_mean(str(source), files)
    hint_text = f" (did you mean '{hint}'?)" if hint else ""
    raise InputError(f"unknown study '{one_line(source)[:60]}'{hint_text}; embedded studies: "
                     f"{names}; or give the path of a study .toml file")


def study_text(source: str) -> str | None:
    """The TOML text of an embedded study name or of a study file (a TOML file with top-level
    ``grid`` or ``seeds``), for ``silodem show``; None when ``source`` is not a study."""
    if source in _study_files():
        return _study_files()[source].read_text(encoding="utf-8")
    path = Path(source)
    try:
        if not path.is_file():
            return None
        text = path.read_text(encoding="utf-8")
        data = parse_toml(text, source)
    except (OSError, UnicodeDecodeError, InputError):
        return None
    return text if isinstance(data, dict) and ("grid" in data or "seeds" in data) else None


class LoadedStudy(BaseModel):
    """A validated study with where it came from."""

    model_config = ConfigDict(arbitrary_types_allowed=True)

    spec: StudySpec
    source: str
    text: str
    folder: Path | None  # folder of the study file (None: embedded)

    @property
    def name(self) -> str:
        return self.spec.name


def load_study(source: str) -> LoadedStudy:
    """Read and validate an embedded study or a study file; InputError (one line) if bad."""
    if not isinstance(source, str | Path):
        raise InputError(f"source must be a study's name or a TOML file's path; got "
                         f"{short_repr(source)}")
    text, default_name, folder = _read(str(source))
    where = f"study {source}"
    data = parse_toml(text, where)
    if "grid" not in data and "seeds" not in data and {"material", "silo"} & set(data):
        raise InputError(f"{source} is a scenario (one run), not a study: run it with "
                         f"'silodem run {source}', or name it as a study's base "
                         "(see 'silodem show paper-study')")
    try:
        spec = StudySpec.model_validate(data)
    except ValidationError as exc:
        message = format_validation_error(exc, data, model=StudySpec)
        raise InputError(f"{where}: {message.removeprefix('config error: ')}") from None
    if not spec.name:  # model_copy skips the validator of 'name': check it here
        try:
            folder_name(default_name, "name")
        except ValueError as exc:
            raise InputError(f"{where}: the study is named by its file name, but {exc}; give "
                             "the study a name = \"...\" in the file") from None
        spec = spec.model_copy(update={"name": default_name})
    return LoadedStudy(spec=spec, source=str(source), text=text, folder=folder)
