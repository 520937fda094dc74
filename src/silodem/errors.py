"""User-input errors, and one-line messages for configuration validation errors.

An :class:`InputError` is a problem with what the user gave (a file, a scenario name, a
``--set`` override, a command-line value).  Its ``str()`` is one line that names what is wrong
and what is allowed; the command line prints it as is and exits with code 2, no traceback.
"""

from __future__ import annotations

import datetime
import difflib
import json
import re
import sys
import types
import typing
from collections.abc import Iterable, Sequence
from typing import Any

from pydantic import BaseModel, ValidationError


class InputError(Exception):
    """A user-input problem; ``str()`` is one line naming what is wrong and what is allowed."""

    def __init__(self, message: str) -> None:
        super().__init__(one_line(message))


def short_repr(value: Any, limit: int = 60) -> str:
    """``value`` for an error's ``got ...``: its repr on one line if that is short, else a
    string's cut to ``limit`` characters, an integer's count of digits, or the type's name (a
    Config's repr is 1,500 characters).

    Never raises: Python refuses to write an integer of more than 4300 digits
    (``sys.get_int_max_str_digits``) in decimal, and an error's message must still be made
    (``threads=10**5000`` ended in that ValueError)."""
    try:
        text: str | None = one_line(repr(value))
    except ValueError:  # "Exceeds the limit (4300 digits) for integer string conversion"
        text = None
    if text is not None and len(text) <= limit:
        return text
    if isinstance(value, str | bytes) and text is not None:
        return shorten(text, limit)
    if isinstance(value, int) and not isinstance(value, bool):
        digits = (str(len(text.lstrip("-"))) if text is not None
                  else f"more than {sys.get_int_max_str_digits()}")
        return f"an integer of {digits} digits"
    name = type(value).__name__
    return f"{'an' if name[:1].lower() in 'aeiou' else 'a'} {name}"


def shorten(text: str, limit: int = 60) -> str:
    """``text`` on one line, cut to ``limit`` characters (its end written ``...``) when longer:
    a name or key the user gave, quoted in an error (a 5,000-character unknown key made a
    5,000-character message)."""
    text = one_line(text)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def check_flag(value: Any, name: str) -> None:
    """InputError unless ``value`` is True or False, Python's or numpy's (a string such as 'no'
    is truthy: it would switch the option on)."""
    import numpy as np

    if not isinstance(value, bool | np.bool_):
        raise InputError(f"{name} must be True or False; got {short_repr(value)}")


def parse_toml(text: str, where: str) -> dict[str, Any]:
    """The dict of TOML ``text``; an InputError naming ``where`` if it is not TOML.

    Besides malformed TOML, ``tomllib`` raises ValueError for an integer of more than 4300
    digits and RecursionError for arrays nested thousands deep: each is the file's fault."""
    import tomllib

    try:
        return tomllib.loads(text.removeprefix("\ufeff"))  # a byte-order mark is not TOML's
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{where}: malformed TOML: {exc}") from None
    except ValueError as exc:  # e.g. "Exceeds the limit (4300 digits) for integer string ..."
        raise InputError(f"{where}: a value TOML cannot read: {str(exc).split(':')[0]}") from None
    except RecursionError:
        raise InputError(f"{where}: malformed TOML: nested too deeply") from None


_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f]")


def one_line(text: str) -> str:
    """Collapse ``text`` to a single line (newlines and runs of blanks become one space); a
    control character left (a terminal's escape, ESC, from a --set value) is written as an
    escape, ``\\x1b``, that the terminal shows and does not act on."""
    line = " ".join(str(text).split())
    return _CONTROL.sub(lambda m: f"\\x{ord(m.group()):02x}", line)


# --- walking the schema --------------------------------------------------------------------


def submodel(annotation: Any) -> type[BaseModel] | None:
    """The pydantic model class inside a field annotation (``Material``, ``X | None``).

    None when the annotation holds no model.
    """
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    origin = typing.get_origin(annotation)
    if origin is typing.Union or origin is types.UnionType:
        for arg in typing.get_args(annotation):
            found = submodel(arg)
            if found is not None:
                return found
    return None


def model_at(root: type[BaseModel], parts: Sequence[Any]) -> type[BaseModel] | None:
    """The model class reached by following the field names ``parts`` from ``root``.

    Returns None when a part is not a field or does not lead to a sub-model.
    """
    model: type[BaseModel] | None = root
    for part in parts:
        if model is None or not isinstance(part, str) or part not in model.model_fields:
            return None
        model = submodel(model.model_fields[part].annotation)
    return model


def schema_keys(root: type[BaseModel], prefix: str = "") -> list[str]:
    """Every dotted key of the schema, sections included (``material``, ``material.kn``, ...)."""
    keys: list[str] = []
    for name, field in root.model_fields.items():
        dotted = f"{prefix}{name}"
        keys.append(dotted)
        sub = submodel(field.annotation)
        if sub is not None:
            keys.extend(schema_keys(sub, dotted + "."))
    return keys


def did_you_mean(word: str, choices: Iterable[str]) -> str | None:
    """The closest of ``choices`` to ``word`` (difflib, ignoring case), or None.

    Case is ignored because difflib alone finds nothing for ``PAPER-CASE2`` against
    ``paper-case2`` (every letter differs); a choice equal but for case wins outright.
    """
    by_lower: dict[str, str] = {}
    for choice in choices:
        by_lower.setdefault(choice.lower(), choice)
    matches = difflib.get_close_matches(word.lower(), list(by_lower), n=1, cutoff=0.6)
    return by_lower[matches[0]] if matches else None


def suggest_key(root: type[BaseModel], parts: Sequence[str]) -> str | None:
    """A dotted key of the schema that the unknown key ``parts`` was probably meant to be.

    First among the fields at the same level (``material.knn`` -> ``material.kn``), then
    anywhere in the schema by last component (``kn`` -> ``material.kn``).
    """
    if not parts:
        return None
    *head, last = parts
    parent = model_at(root, head)
    if parent is not None:
        hit = did_you_mean(last, parent.model_fields)
        if hit is not None:
            return ".".join([*head, hit])
    leaves = {k.rsplit(".", 1)[-1]: k for k in reversed(schema_keys(root))}
    hit = did_you_mean(last, leaves)
    return leaves[hit] if hit is not None else None


def _toml_key(parts: Sequence[str]) -> str:
    """The key path with a part that holds a dot or a space (``"settle.threshold"`` quoted in
    a TOML file is one name) or nothing in double quotes, as TOML writes it."""
    return ".".join(json.dumps(p) if not p or re.search(r"[.\s]", p) else p for p in parts)


def unknown_key_message(root: type[BaseModel], parts: Sequence[str]) -> str:
    """``unknown key 'a.b' (did you mean 'a.c'?)``, or the keys allowed at that level; a key
    longer than 60 characters cut short (:func:`shorten`)."""
    dotted = shorten(_toml_key(parts))
    hint = suggest_key(root, parts)
    if hint is not None and hint == ".".join(parts):  # '"settle.threshold" = 1' at the top
        return f"unknown key '{dotted}': a quoted key is one name; write {hint} without quotes"
    if hint is not None:
        return f"unknown key '{dotted}' (did you mean '{hint}'?)"
    parent = model_at(root, parts[:-1])
    if parent is not None:
        where = f"in [{'.'.join(parts[:-1])}]" if len(parts) > 1 else "at the top level"
        return f"unknown key '{dotted}' (allowed {where}: {', '.join(parent.model_fields)})"
    return f"unknown key '{dotted}'"


# --- formatting validation errors ----------------------------------------------------------


def format_value(value: Any, limit: int = 60) -> str:
    """A short TOML-like rendering of a scalar value or a list of them, for ``(got ...)``."""
    if isinstance(value, list | tuple):
        return shorten("[" + ", ".join(format_value(v, limit) for v in value) + "]", limit)
    if isinstance(value, bool):
        text = "true" if value else "false"
    elif isinstance(value, str):
        text = '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    elif isinstance(value, int):  # a long one by its digits (not its first 57: another number)
        return short_repr(value, limit)
    elif isinstance(value, datetime.date | datetime.time):  # a TOML date or time, as written
        kind = ("date and time" if isinstance(value, datetime.datetime) else
                "date" if isinstance(value, datetime.date) else "time")
        text = f"the {kind} {value.isoformat()}"
    else:
        text = repr(value)
    return shorten(text, limit)


def _lookup(data: Any, loc: Sequence[Any]) -> tuple[bool, Any]:
    for part in loc:
        in_dict = isinstance(data, dict) and part in data
        in_list = (
            isinstance(data, list) and isinstance(part, int) and -len(data) <= part < len(data)
        )
        if in_dict or in_list:
            data = data[part]
        else:
            return False, None
    return True, data


def _root_model(err: ValidationError) -> type[BaseModel] | None:
    from silodem import config

    found = getattr(config, err.title, None)
    return found if isinstance(found, type) and issubclass(found, BaseModel) else None


def first_error(err: ValidationError) -> dict[str, Any]:
    """The error reported: the first unknown key if any, else pydantic's first error."""
    return dict(min(err.errors(), key=lambda e: e["type"] != "extra_forbidden"))


OTHERS_NAMED = 6  # the other errors' keys named after the first error, at most


def _others(errors: list[Any], first: dict[str, Any]) -> str:
    """`` (+N more: a.b missing, c unknown, d, ...)``: where the errors after the first are
    (each key once, unknown keys first, at most OTHERS_NAMED of them, each cut to 60
    characters), or "" when there is one error."""
    rest = sorted((e for e in errors if dict(e) != first),  # unknown keys first, as the
                  key=lambda e: e["type"] != "extra_forbidden")  # first error is chosen
    if not rest:
        return ""
    names: list[str] = []
    for e in rest:
        dotted = shorten(_toml_key([str(p) for p in e["loc"]])) if e["loc"] else \
            "(the whole config)"
        kind = {"missing": " missing", "extra_forbidden": " unknown"}.get(e["type"], "")
        if dotted + kind not in names:  # (two long keys cut to the same text: named once)
            names.append(dotted + kind)
    shown = ", ".join(names[:OTHERS_NAMED])
    if len(names) > OTHERS_NAMED:
        shown += f", and {len(names) - OTHERS_NAMED} more key(s)"
    return f" (+{len(rest)} more: {shown})"


def format_validation_error(
    err: ValidationError, data: dict, *, model: type[BaseModel] | None = None
) -> str:
    """One line describing the first error of ``err``, then the keys of the others
    (``(+N more: key missing, key unknown, key, ...)``: a file with several mistakes is not
    mended one rerun at a time without knowing how many and where).

    ``data`` is the raw dict that was validated; ``model`` the validated model class (found
    by the error's title in :mod:`silodem.config` when omitted).  Unknown keys are reported
    first, with a did-you-mean; then the other errors in pydantic's order.
    """
    root = model if model is not None else _root_model(err)
    errors = err.errors()
    if not errors:
        return "config error: invalid configuration"
    first = first_error(err)
    loc = list(first["loc"])
    dotted = ".".join(str(p) for p in loc)
    more = _others(errors, first)

    if first["type"] == "extra_forbidden":
        parts = [str(p) for p in loc]
        text = (unknown_key_message(root, parts) if root is not None
                else f"unknown key '{shorten(dotted)}'")
        return one_line(f"config error: {text}{more}")

    if first["type"] == "missing":
        desc = ""
        parent = model_at(root, loc[:-1]) if root is not None else None
        if parent is not None and loc and loc[-1] in parent.model_fields:
            field_desc = parent.model_fields[loc[-1]].description
            desc = f" ({field_desc})" if field_desc else ""
        return one_line(f"config error: missing required key '{dotted}'{desc}{more}")

    msg = str(first["msg"])
    if first["type"] == "model_type":  # pydantic: "Input should be a valid dictionary or
        msg = (f"a section, not a value: write it as a table [{dotted}] of keys"  # instance
               if dotted else "a table of keys")                                   # of X"
    for prefix in ("Value error, ", "Assertion failed, "):
        msg = msg.removeprefix(prefix)
    if "input" in first:
        has_value, value = True, first["input"]
    else:
        has_value, value = _lookup(data, loc)
    got = ""
    if has_value and not isinstance(value, dict | set):
        got = f" (got {format_value(value)})"
    if not dotted or msg.startswith(dotted):
        text = f"config error: {msg}"
        got = ""
    else:
        text = f"config error: {dotted}: {msg}"
    return one_line(f"{text}{got}{more}")


class UnstableRunError(RuntimeError):
    """The simulation became unphysical (non-finite values, a grain thrown out of the domain).
    The CLI reports it as one line with exit code 3."""


class Terminated(KeyboardInterrupt):
    """SIGTERM outside a run's own handlers (``cli.main``): stops the command like Ctrl-C,
    with exit code 143."""


class RunInterrupted(Exception):
    """A run stopped cleanly on a signal (SIGINT, SIGTERM) after saving a checkpoint.

    ``signum`` is the signal; the CLI exits with code ``128 + signum`` (130, 143)."""

    def __init__(self, message: str, signum: int) -> None:
        super().__init__(one_line(message))
        self.signum = int(signum)

    @property
    def exit_code(self) -> int:
        return 128 + self.signum
