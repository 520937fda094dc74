"""Loading run configurations: embedded scenarios, TOML files and ``--set`` overrides.

The embedded scenarios are the TOML files in the package folder ``silodem/scenarios/``
(package data; the folder has no ``__init__.py``).  A scenario is named by its file name
without ``.toml``.
"""

from __future__ import annotations

import copy
import tomllib
from collections.abc import Callable, Iterable
from importlib import resources
from pathlib import Path
from typing import Any

import tomli_w
from pydantic import BaseModel, ValidationError

from silodem.config import Config
from silodem.errors import (
    InputError,
    did_you_mean,
    first_error,
    format_validation_error,
    format_value,
    one_line,
    parse_toml,
    shorten,
    submodel,
    unknown_key_message,
)

DEFAULT_SCENARIO = "paper-case2"

QUICK_SUFFIX = "-quick"


# --- embedded scenarios --------------------------------------------------------------------


def _scenario_dir() -> Any:
    return resources.files("silodem") / "scenarios"


def _scenario_files() -> dict[str, Any]:
    folder = _scenario_dir()
    files = {}
    for entry in folder.iterdir():
        if entry.is_file() and entry.name.endswith(".toml"):
            files[entry.name[: -len(".toml")]] = entry
    return dict(sorted(files.items()))


def scenario_names() -> list[str]:
    """Names of the embedded scenarios, sorted."""
    return list(_scenario_files())


def list_scenarios() -> list[tuple[str, str]]:
    """``(name, description)`` of every embedded scenario, sorted by name."""
    out = []
    for name, entry in _scenario_files().items():
        try:
            description = str(
                tomllib.loads(entry.read_text(encoding="utf-8")).get("description", "")
            )
        except tomllib.TOMLDecodeError:
            description = "(unreadable scenario file)"
        out.append((name, one_line(description)))
    return out


# --- reading -------------------------------------------------------------------------------


def _path_kind(path: Path) -> str:
    """'file', 'other' (exists, not a regular file) or 'missing' (also for impossible names)."""
    try:
        if path.is_file():
            return "file"
        return "other" if path.exists() else "missing"
    except (OSError, ValueError):  # name too long, embedded NUL...
        return "missing"


def _read_source(source: str) -> dict[str, Any]:
    """The raw dict of an embedded scenario or of a TOML file."""
    files = _scenario_files()
    names = ", ".join(files)
    if not source.strip():
        raise InputError(f"empty scenario name: give an embedded scenario ({names}) or the "
                         "path of a .toml file")
    path = Path(source)
    kind = _path_kind(path)
    if kind == "file":
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise InputError(f"cannot read {source}: {exc}") from None
        return parse_toml(text, str(source))
    # a folder is never a config: one named like a scenario (`silodem run` makes
    # runs/paper-case2, and `cd runs` puts it in the way) leaves the name to the scenario
    if kind == "other" and source not in files:
        raise InputError(f"{source} is not a file (give a .toml file or one of: {names})")
    if source in files:
        return parse_toml(files[source].read_text(encoding="utf-8"), f"scenario {source}")
    if source.endswith(".toml") or "/" in source or "\\" in source:
        raise InputError(
            f"file not found: {shorten(source, 200)} (give an existing .toml file, or an "
            f"embedded scenario: {names})"
        )
    if source.strip() in files:  # ' paper-case2': the message showed the name without them
        raise InputError(f"unknown scenario {source!r}: it has spaces around the name; did you "
                         f"mean '{source.strip()}'?")
    from silodem.study.spec import study_names

    if source in study_names():  # (a study's base, or 'silodem run paper-study')
        raise InputError(f"'{source}' is a study (a grid of runs), not a scenario: run it with "
                         f"'silodem sweep {source}'; a study's base is a scenario or a config "
                         f"file ({names})")
    base = source.removesuffix(QUICK_SUFFIX)
    if base != source and base in files:  # a quick run's config name, as in its folder
        raise InputError(f"unknown scenario {source!r}: it is the quick variant of '{base}'; "
                         f"give '{base}' with --quick (quick=True in the Python API)")
    if Path(source).suffix:  # 'my.yaml': a file name, not a scenario's
        raise InputError(
            f"file not found: {shorten(source, 200)} (a config is a .toml file; or give an "
            f"embedded scenario: {names})"
        )
    hint = did_you_mean(source, files)
    hint_text = f" (did you mean '{hint}'?)" if hint else ""
    raise InputError(
        f"unknown scenario '{shorten(source)}'{hint_text}; embedded scenarios: {names}; "
        f"or give a path to a .toml file"
    )


# --- overrides -----------------------------------------------------------------------------


def parse_value(text: str) -> Any:
    """A ``--set`` value: a TOML value (``3``, ``2.5``, ``true``, ``"x"``).

    Text that is not one TOML value is taken as the plain string (``1e7\nseed = 3`` parsed
    as TOML is two keys: the second was dropped without a word before).
    """
    try:
        table = tomllib.loads(f"v = {text}")
    except (ValueError, RecursionError):  # whatever tomllib rejects is taken literally
        return text
    return table["v"] if table.keys() == {"v"} else text


def _split_set(item: str, flag: str = "--set") -> tuple[list[str], str]:
    key, sep, value = item.partition("=")
    key = key.strip()
    if not sep or not key:
        raise InputError(
            f"{flag} '{shorten(item)}': expected dotted.key=value, e.g. {flag} material.kn=2e7"
        )
    parts = [p.strip() for p in key.split(".")]
    if not all(parts):  # '.kn', 'material..kn': the message quoted the key '""'
        raise InputError(f"{flag} '{shorten(item)}': the key '{shorten(key)}' has an empty part "
                         f"(write dotted.key=value, e.g. {flag} material.kn=2e7)")
    return parts, value.strip()


def _check_key(parts: list[str], item: str, flag: str = "--set") -> type[BaseModel] | None:
    """Raise InputError when ``parts`` is not a key path of the schema; return the section
    it names (None for a value)."""
    model: type[BaseModel] | None = Config
    for i, part in enumerate(parts):
        if model is None:
            section = ".".join(parts[:i])
            raise InputError(
                f"{flag} {shorten(item)}: '{section}' is a value, not a section, so "
                f"'{shorten('.'.join(parts))}' does not exist"
            )
        if part not in model.model_fields:
            raise InputError(
                f"{flag} {shorten(item)}: {unknown_key_message(Config, parts[: i + 1])}"
            )
        model = submodel(model.model_fields[part].annotation)
    return model


def apply_sets(data: dict[str, Any], sets: Iterable[str],
               flag: str = "--set") -> dict[str, Any]:
    """Apply ``dotted.key=value`` overrides to the raw dict ``data`` (in place; returned);
    ``flag`` names where they came from in error messages (``--set``, or ``set`` for the
    Python API)."""
    for item in sets:
        parts, text = _split_set(item, flag)
        section = _check_key(parts, item, flag)
        value = parse_value(text)
        if section is not None and not isinstance(value, dict):  # pydantic would say "Input
            keys = ", ".join(section.model_fields)  # should be a valid dictionary or instance"
            raise InputError(f"{flag} {shorten(item)}: '{'.'.join(parts)}' is a section, not a "
                             f"value; set one of its keys ({keys}), e.g. {flag} "
                             f"{'.'.join(parts)}.{next(iter(section.model_fields))}=...")
        node = data
        for i, part in enumerate(parts[:-1]):
            child = node.setdefault(part, {})
            if not isinstance(child, dict):
                raise InputError(
                    f"{flag} {shorten(item)}: '{'.'.join(parts[: i + 1])}' holds a value, "
                    "not a section"
                )
            node = child
        node[parts[-1]] = value
    return data


def config_from_text(text: str, where: str, error: type[InputError] = InputError) -> Config:
    """The validated Config of a saved TOML text (a results folder's or a checkpoint's);
    ``error`` (an InputError, one line) naming ``where`` when it is not TOML or not a valid
    config for this silodem."""
    try:
        data = parse_toml(text, where)
    except InputError as exc:
        raise error(str(exc)) from None
    try:
        return Config.model_validate(data)
    except ValidationError as exc:
        detail = format_validation_error(exc, data, model=Config)
        raise error(f"{where} does not load: {detail}") from None


def _validate(data: dict[str, Any], sets: Iterable[str] = (), flag: str = "--set") -> Config:
    try:
        return Config.model_validate(data)
    except ValidationError as exc:
        message = format_validation_error(exc, data, model=Config)
        first = first_error(exc)
        dotted = ".".join(str(p) for p in first["loc"])
        for item in reversed(list(sets)):  # the last --set of a key is the one in force
            key = item.partition("=")[0].strip()
            inside = key.startswith(dotted + ".") if dotted else True  # a section's check
            if (dotted and (key == dotted or dotted.startswith(key + "."))) or \
                    (inside and key in message):  # naming the key, e.g. radius_max >= min
                message += f" (from {flag} {shorten(item)})"
                break
        raise InputError(message) from None


def _breaking(given: dict[str, Any], sets: list[str], flag: str) -> list[str]:
    """The ``sets`` that make the valid raw config ``given`` invalid (:func:`breaking_sets`)."""
    return breaking_sets(sets, lambda items: _valid(apply_sets(copy.deepcopy(given), items,
                                                               flag)))


def breaking_sets(sets: list[str], valid_with: Callable[[list[str]], bool]) -> list[str]:
    """The ``sets`` that break a config valid without them (``valid_with(items)``: is it
    valid with these alone?): those that do it alone, where any does; else those without
    which the rest pass (only together do they: a wider cell and a steeper hopper); else all
    of them."""
    alone = [item for item in sets if not valid_with([item])]
    if alone:
        return alone
    needed = [item for k, item in enumerate(sets) if valid_with(sets[:k] + sets[k + 1:])]
    return needed or sets


def _valid(data: dict[str, Any]) -> bool:
    try:
        Config.model_validate(data)
    except ValidationError:
        return False
    return True


def revalidated(cfg: Config) -> Config:
    """``cfg`` validated again (pydantic's ``model_copy(update=...)`` and attribute
    assignment skip the checks): InputError, one line, naming the key that is out of range,
    or unknown (``model_copy(update={"sed": 7})`` keeps 'sed' beside the fields, which
    ``model_dump`` would drop without a word)."""
    data = cfg.model_dump(warnings=False)
    _put_strays(cfg, data)
    return _validate(data)


def _put_strays(model: BaseModel, data: dict[str, Any], where: str = "") -> None:
    """Copy into ``data`` (``model``'s dump) the attributes of ``model`` and of its sections
    that are no fields of theirs, so that validation names them; a dotted one (``update=
    {"material.kn": ...}``, a ``set`` key given to ``model_copy``) is refused saying how a
    section's value is changed."""
    fields = type(model).model_fields
    for key, value in vars(model).items():
        if key not in fields and isinstance(key, str) and "." in key:
            head = key.split(".", 1)[0]
            raise InputError(
                f"unknown key '{where}{shorten(key)}': model_copy(update=...) takes the names "
                f"of one section's fields, not dotted keys; give it as set={{'{where}"
                f"{shorten(key)}': ...}} to api.scenario, or update={{'{head}': "
                f"cfg.{where}{head}.model_copy(update={{...}})}}")
        if key not in fields:
            data[key] = value
        elif isinstance(value, BaseModel) and isinstance(data.get(key), dict):
            _put_strays(value, data[key], f"{where}{key}.")


def load_config(source: str, sets: Iterable[str] = (), flag: str = "--set") -> Config:
    """The validated :class:`Config` of an embedded scenario name or a ``.toml`` path.

    ``sets`` are ``dotted.key=value`` overrides applied before validation (``flag`` names
    them in messages: ``--set`` on the command line, ``set`` in the Python API).  Every problem
    (missing file, malformed TOML, unknown scenario or key, bad value) raises
    :class:`InputError` with a one-line message.
    """
    sets = list(sets)
    data = _read_source(str(source))
    empty = not data
    given = copy.deepcopy(data) if sets else None
    apply_sets(data, sets, flag)
    try:
        return _validate(data, sets, flag)
    except InputError as exc:
        message = str(exc)
        if f"(from {flag} " not in message and given is not None and _valid(given):
            # a check across keys that the --set values broke (outlet_width against a
            # radius_max set): the error names another key, so name them
            raise InputError(f"{message} (after {flag} "
                             f"{', '.join(map(shorten, _breaking(given, sets, flag)))})") \
                from None
        if f"(from {flag} " in message or _path_kind(Path(source)) != "file":
            raise  # a --set's value, or an embedded scenario (whose values are valid)
        raise InputError(f"{message} (in {source}{', an empty file' if empty else ''})") \
            from None


# --- writing -------------------------------------------------------------------------------


def _toml_value(value: Any) -> str:
    return tomli_w.dumps({"v": value}).strip()[len("v = ") :]


def _field_lines(model: BaseModel, width: int) -> list[str]:
    lines = []
    for name, field in type(model).model_fields.items():
        if submodel(field.annotation) is not None:
            continue
        value = getattr(model, name)
        desc = one_line(field.description or "")
        if value is None:
            default = " (the default)" if field.default is None else ""
            lines.append(f"# {name} is unset{default}" + (f"; {desc}" if desc else ""))
            continue
        text = f"{name} = {_toml_value(value)}"
        lines.append(f"{text:<{width}}  # {desc}" if desc else text)
    return lines


CONFIG_HEADER = "# silodem configuration:"  # the first line of config_to_toml's text


def config_to_toml(cfg: Config) -> str:
    """The complete TOML of ``cfg``: every key, defaults included (unset ones as comments).

    :func:`load_config` reads the text back to a Config equal to ``cfg``.
    """
    out = [
        f"{CONFIG_HEADER} {one_line(cfg.name)}",
        *([f"# {one_line(cfg.description)}"] if cfg.description else []),
        "# Every key is listed, defaults included; units are SI (see docs/scenarios.md).",
        "",
    ]
    out += _field_lines(cfg, 30)
    for name, field in Config.model_fields.items():
        sub = getattr(cfg, name)
        if submodel(field.annotation) is None or sub is None:
            continue
        doc = one_line((type(sub).__doc__ or "").strip().split("\n\n")[0])
        out += ["", f"[{name}]"] + ([f"# {doc}"] if doc else []) + _field_lines(sub, 34)
    return "\n".join(out) + "\n"


# --- quick variant -------------------------------------------------------------------------


def quick_variant(cfg: Config) -> Config:
    """The same procedure on a small silo (0.36 of the grains, well under a minute).

    Cell width x 0.6, wall height x 0.6 (at least hopper height + 1 m), same outlet,
    grains x 0.36 (at least 50), phase time limits capped; name suffixed ``-quick``.
    """
    data = cfg.model_dump()
    silo = data["silo"]
    silo["cell_width"] = round(cfg.silo.cell_width * 0.6, 9)
    hopper = cfg.silo.model_copy(update={"cell_width": silo["cell_width"]}).hopper_height
    silo["wall_height"] = round(max(cfg.silo.wall_height * 0.6, hopper + 1.0), 9)
    data["fill"]["n_particles"] = max(50, round(cfg.fill.n_particles * 0.36))
    data["fill"]["max_time"] = min(cfg.fill.max_time, 15.0)
    data["settle"]["max_time"] = min(cfg.settle.max_time, 3.0)
    data["discharge"]["max_time"] = min(cfg.discharge.max_time, 10.0)
    data["name"] = cfg.name + QUICK_SUFFIX
    try:
        return Config.model_validate(data)
    except ValidationError as exc:
        detail = format_validation_error(exc, data, model=Config).removeprefix("config error: ")
        raise InputError(f"--quick cannot shrink '{cfg.name}': {detail}") from None


def quick_overrides(cfg: Config, small: Config, sets: Iterable[str]) -> str:
    """'key a -> b, ...' for each key of ``sets`` whose value ``quick_variant`` changed from
    ``cfg`` to ``small``, or ''."""
    said = []
    for item in sets:
        key = item.partition("=")[0].strip()
        before, after = cfg, small
        for part in key.split("."):
            before, after = getattr(before, part, None), getattr(after, part, None)
        entry = f"{key} {format_value(before)} -> {format_value(after)}"
        if before != after and entry not in said:
            said.append(entry)
    return ", ".join(said)


def flat_table(table: dict[str, Any], where: str) -> dict[str, Any]:
    """``{"a": {"b": 1}}`` -> ``{"a.b": 1}``, in the table's order (TOML's bare dotted keys
    are nested tables; a config's dump has its sections).  ValueError naming ``where`` for an
    empty table, and for a key given twice (quoted ``"a.b"`` beside ``[a] b``)."""
    out: dict[str, Any] = {}

    def walk(node: dict, prefix: str) -> None:
        for key, value in node.items():
            dotted = f"{prefix}{key}"
            if isinstance(value, dict):
                if not value:
                    raise ValueError(f"[{where}] '{shorten(dotted)}' is an empty table")
                walk(value, dotted + ".")
            else:
                if dotted in out:
                    raise ValueError(f"[{where}] gives '{shorten(dotted)}' twice")
                out[dotted] = value

    walk(table, "")
    return out


def changes_from_scenario(cfg: Config) -> tuple[str, list[str]] | None:
    """(scenario, ['key = value', ...]) for a config named as an embedded scenario, or as its
    --quick variant, with the keys (dotted, in the schema's order) whose values differ from
    that scenario's (or its --quick variant's): what ``--set`` or an edited copy changed, which
    the scenario's description, shown with the config, does not say.  None for a config of
    another name."""
    base_name = cfg.name.removesuffix(QUICK_SUFFIX)
    files = _scenario_files()
    if base_name not in files:
        return None
    # the embedded file itself: load_config would take a file of that name in the working
    # folder first (a report then compared the run with it, or failed on a non-TOML one)
    text = files[base_name].read_text(encoding="utf-8")
    base = _validate(parse_toml(text, f"scenario {base_name}"))
    if cfg.name != base_name:
        base = quick_variant(base)
    ours = flat_table(cfg.model_dump(), "config")
    theirs = flat_table(base.model_dump(), "config")
    # errors.format_value: TOML on one line (tomli_w spreads a list over several lines, with
    # a trailing comma, which in a sentence read 'material.radii = [ 0.08, 0.12, ]')
    return base_name, [f"{key} = {'unset' if value is None else format_value(value, 10**6)}"
                       for key, value in ours.items() if theirs.get(key) != value]
