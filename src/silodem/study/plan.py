"""From a study to its runs: the grid product, the resolved config of each run and its id.

A run's config is built as: the base scenario (the study's ``base``, or the grid point's value of
the grid key ``base``) -> the study's ``[set]`` values -> the values of its grid point -> its
seed -> validation -> ``quick_variant`` (with ``--quick``).  Its id is
``<slug>-<hash>``: the slug names the grid point for people (``theta35_phiG20_phiP10_seed2``),
the hash is the first 10 hex digits of the SHA-256 of the resolved config (every value except
``name`` and ``description``, as canonical JSON), so the same physics always has the same id
and any change of a value, a default or ``--quick`` gives another.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import re
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from silodem.config import Config
from silodem.errors import InputError, check_flag, format_validation_error, submodel
from silodem.scenario_files import QUICK_SUFFIX, load_config, quick_variant
from silodem.study.spec import GRID_BASE, LoadedStudy

HASH_DIGITS = 10
# short names of the paper's parameters, for run slugs and report labels
NICKNAMES = {
    "silo.hopper_angle_from_horizontal_deg": "theta",
    "material.friction_deg": "phiG",
    "walls.friction_deg": "phiP",
}


@dataclass(frozen=True)
class PlannedRun:
    """One run of a study: its grid point, seed, resolved config and id."""

    id: str
    slug: str
    seed: int
    point: dict[str, Any]  # grid key -> value, in the grid's order
    cfg: Config = field(repr=False)

    @property
    def label(self) -> str:
        return label_of(self.point, self.seed)


@dataclass(frozen=True)
class StudyPlan:
    study: LoadedStudy
    quick: bool
    runs: list[PlannedRun]

    @property
    def name(self) -> str:
        return self.study.name

    @property
    def grid_keys(self) -> list[str]:
        return list(self.study.spec.grid)


def _numeric(annotation: Any) -> bool:
    """Whether a Config field's annotation holds a number or a list of numbers (float,
    ``float | None``, ``list[float] | None``), not a choice, a text or a bool."""
    for arg in typing.get_args(annotation) or (annotation,):
        if arg in (int, float) or (typing.get_origin(arg) is list
                                   and {int, float} & set(typing.get_args(arg))):
            return True
    return False


def key_unit(key: str) -> str:
    """The unit of a config key's numbers, as the first ``[unit]`` of its description in
    :class:`silodem.config.Config`: "deg" for ``silo.hopper_angle_from_horizontal_deg``, "m"
    for ``silo.outlet_width``.  "" for a dimensionless key ("[-]"), one that is not a number
    (a choice, a bool) and a key that is not the Config's (a study's grid key ``base``),
    unless its name ends in ``_deg`` (an angle in degrees, as every such key of the Config)."""
    model, found = Config, None
    for part in key.split("."):
        found = model.model_fields.get(part) if model is not None else None
        if found is None:
            return "deg" if key.endswith("_deg") else ""
        model = submodel(found.annotation)
    if model is not None or not _numeric(found.annotation):  # a section; not a number
        return ""
    unit = re.search(r"\[([^\]]+)\]", found.description or "")
    return unit.group(1) if unit and unit.group(1) != "-" else ""


def value_label(name: str, unit: str, value: Any, brackets: bool = False) -> str:
    """'theta=35 deg': a grid key's short ``name``, its ``value`` (``format_value``) and the
    key's ``unit`` (:func:`key_unit`; a number's only, not a choice's or a bool's).
    ``brackets``: a list shown as one, 'x=[0.1, 0.2] m', not 'x=0.1+0.2 m'."""
    number = isinstance(value, int | float | list | tuple) and not isinstance(value, bool)
    text = "[" + ", ".join(format_value(x) for x in value) + "]" \
        if brackets and isinstance(value, list | tuple) else format_value(value)
    return f"{name}={text}" + (f" {unit}" if unit and number else "")


def nicknames(keys: list[str]) -> dict[str, str]:
    """A short, unique name per dotted key: the paper's symbol if it has one, else its last
    part, else (when two keys share a last part) section_last."""
    lasts = [k.rsplit(".", 1)[-1] for k in keys]
    out = {}
    for key, last in zip(keys, lasts):
        if key in NICKNAMES:
            out[key] = NICKNAMES[key]
        elif lasts.count(last) == 1:
            out[key] = last
        else:
            out[key] = key.replace(".", "_")
    return out


def format_value(value: Any) -> str:
    """A short text of a grid value: 35.0 -> '35', 0.5 -> '0.5', True -> 'true'."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float) and math.isfinite(value) and value == int(value) \
            and abs(value) < 1e15:
        return str(int(value))
    if isinstance(value, list | tuple):
        return "+".join(format_value(v) for v in value)
    return str(value)


def _safe(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9.+-]+", "_", text).strip("_.") or "x"


def slug_of(point: dict[str, Any], seed: int) -> str:
    names = nicknames(list(point))
    parts = [f"{names[k]}{_safe(format_value(v))}" for k, v in point.items()]
    slug = "_".join([*parts, f"seed{seed}"])
    return slug if len(slug) <= 120 else slug[:120].rstrip("_")


def label_of(point: dict[str, Any], seed: int | None = None, *, brackets: bool = False) -> str:
    """A run's name for people: 'theta=45 deg, phiP=10 deg, seed 1' (each grid value with its
    unit, as the heat maps' labels; :func:`value_label`).  ``brackets``: a list value shown as
    one, '[20]', not '20' (an error's label: a list where a number belongs looked like that
    number)."""
    names = nicknames(list(point))
    text = ", ".join(value_label(names[k], key_unit(k), v, brackets) for k, v in point.items())
    return text + (f", seed {seed}" if seed is not None else "")


# keys added to the schema after studies were first planned, left out of the hash while they
# hold these values (the behaviour from before they existed): a study planned earlier keeps
# its run ids, so that its finished runs are not run again
LATER_KEYS = {("material", "contact_model"): "linear", ("material", "young_modulus"): None,
              ("material", "poisson_ratio"): None, ("walls", "young_modulus"): None,
              ("walls", "poisson_ratio"): None, ("measure", "field_kernel"): "box",
              ("measure", "field_width"): None, ("measure", "angle_of_repose_deg"): None,
              ("walls", "hopper_friction_deg"): None,
              ("material", "radius_distribution"): "uniform", ("material", "radii"): None,
              ("material", "radius_shares"): None, ("discharge", "gate_speed"): None}


def config_hash(cfg: Config) -> str:
    """First ``HASH_DIGITS`` hex digits of the SHA-256 of the canonical JSON of ``cfg``
    without ``name`` and ``description``, nor the ``LATER_KEYS`` at their old values."""
    data = cfg.model_dump(mode="json", exclude={"name", "description"})
    for (section, key), old in LATER_KEYS.items():
        if data[section][key] == old:
            del data[section][key]
    text = json.dumps(data, sort_keys=True, separators=(",", ":"), allow_nan=True)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:HASH_DIGITS]


def _put(data: dict[str, Any], dotted: str, value: Any) -> None:
    parts = dotted.split(".")
    node = data
    for part in parts[:-1]:
        node = node.setdefault(part, {})
        if node is None:  # an optional section left unset
            raise InputError(f"'{dotted}': its section is not set in the base config")
    node[parts[-1]] = value


def _base_config(study: LoadedStudy, name: str) -> Config:
    """The base scenario ``name`` (a relative path: from the study file's folder first)."""
    base = name
    if study.folder is not None and not Path(base).is_absolute():
        candidate = study.folder / base
        if candidate.is_file():
            base = str(candidate)
    try:
        return load_config(base)
    except InputError as exc:
        raise InputError(f"study {study.source}: base '{name}': {exc}") from None


def _run_config(bases: dict[str, dict], spec, point: dict[str, Any], seed: int, quick: bool,
                check: bool) -> Config:
    """The config of the run at grid ``point`` with ``seed``: its base, then [set], then the
    point's values (``--quick``'s variant); InputError (without the run's name) where it is
    not valid or, with ``check``, gives no usable run (``silo.checks.check_numbers``)."""
    data = json.loads(json.dumps(bases[point.get(GRID_BASE, spec.base)]))  # a deep copy
    for key, value in {**spec.set, **point}.items():
        if key != GRID_BASE:
            _put(data, key, value)
    data["seed"] = seed
    try:
        cfg = Config.model_validate(data)
    except ValidationError as exc:
        msg = format_validation_error(exc, data, model=Config)
        raise InputError(msg.removeprefix("config error: ")) from None
    if quick:
        cfg = quick_variant(cfg)
    if check:
        from silodem.silo.checks import check_numbers

        check_numbers(cfg)
    return cfg


def _run_error(study: LoadedStudy, bases: dict[str, dict], point: dict[str, Any], seed: int,
               quick: bool, check: bool, message: str) -> str:
    """The line for the run at ``point`` whose config failed with ``message``: put on [set]
    where the base with [set] alone fails the same way (naming the first grid point sent the
    user through the grid), with a hint where a scalar key got a list there, else on the
    grid point."""
    alone = {GRID_BASE: point[GRID_BASE]} if GRID_BASE in point else {}
    if study.spec.set and alone != point:
        try:
            _run_config(bases, study.spec, alone, seed, quick, check)
        except InputError as exc:
            if str(exc) == message:
                listed = [k for k, v in study.spec.set.items() if isinstance(v, list)
                          and f"{k}: Input should be a valid" in message]  # (not radii)
                hint = (f"; a list of values to run goes in [grid], not [set] ({listed[0]})"
                        if listed else "")
                return (f"study {study.source}, [set] (it fails with the base alone): "
                        f"{message}{hint}")
    return f"study {study.source}, run {label_of(point, seed, brackets=True)}: {message}"


def expand(study: LoadedStudy, quick: bool = False, check: bool = True) -> StudyPlan:
    """Every run of ``study`` (seeds outermost, then the grid product in the order of its
    keys, the first key slowest).  ``check``: also refuse values that validate one by one but
    give no usable run together (``silodem.silo.checks.check_numbers``).  InputError, one line,
    naming the grid point, for a run that is not valid."""
    if not isinstance(study, LoadedStudy):
        raise InputError(f"expand takes a study from load_study(...); got a {type(study).__name__}")
    check_flag(quick, "quick")
    check_flag(check, "check")
    spec = study.spec
    names = spec.grid.get(GRID_BASE, [spec.base])
    bases = {name: _base_config(study, name).model_dump() for name in names}
    keys = list(spec.grid)
    runs: list[PlannedRun] = []
    seen: dict[str, str] = {}
    for seed in spec.seeds:
        for values in itertools.product(*(spec.grid[k] for k in keys)):
            point = dict(zip(keys, values))
            try:
                cfg = _run_config(bases, spec, point, seed, quick, check)
            except InputError as exc:
                raise InputError(_run_error(study, bases, point, seed, quick, check,
                                            str(exc))) from None
            slug, digest = slug_of(point, seed), config_hash(cfg)
            run_id = f"{slug}-{digest}"
            if digest in seen:  # one simulation under two labels, e.g. two particle counts
                # that --quick (x 0.36, at least 50) rounds to one
                how = " once --quick has shrunk them" if quick else ""
                raise InputError(f"study {study.source}: runs {seen[digest]} and "
                                 f"{label_of(point, seed)} have the same config{how}; remove "
                                 "the repeated grid value")
            seen[digest] = label_of(point, seed)
            name = f"{spec.name}-{slug}" + (QUICK_SUFFIX if quick else "")
            cfg = cfg.model_copy(update={"name": name,
                                         "description": f"{spec.name}: {label_of(point, seed)}"})
            runs.append(PlannedRun(run_id, slug, seed, point, cfg))
    return StudyPlan(study, quick, runs)
