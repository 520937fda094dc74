"""The reference of every config key (docs/config.md), made from the schema itself.

``reference_markdown()`` lists, section by section, each key of :class:`silodem.config.Config`
with its default, the values it may take (bounds and choices as the schema checks them) and
its description (which carries the unit).  docs/config.md is its output and a test keeps it
so; after a change to the schema, write it again with::

    python -m silodem.config_reference > docs/config.md
"""

from __future__ import annotations

import typing

from pydantic import BaseModel
from pydantic.fields import FieldInfo

from silodem.config import Config
from silodem.errors import one_line, submodel

# the bounds of pydantic's Field(gt=..., ...), read from its metadata by their names
_BOUNDS = (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<="))

HEAD = """# Configuration reference

Every key of a silodem config, section by section, as the schema
(`src/silodem/config.py`) defines and checks it: its default ("required" when a config must
give it; "unset" when it is off or worked out unless given), the values it may take, and its
meaning with its unit. `silodem show SCENARIO` prints a scenario's own values in the same
order, and `--set section.key=VALUE` changes one of them (docs/scenarios.md). Values that
are valid one by one but give no usable run together are refused before a run starts
(docs/reliability.md).

This page is written by `python -m silodem.config_reference > docs/config.md`; a test
checks that it matches the schema.
"""


def _number(value: float) -> str:
    return f"{value:,}" if isinstance(value, int) else f"{value:g}"


def _default(field: FieldInfo) -> str:
    if field.is_required():
        return "required"
    if field.default is None:
        return "unset"
    value = field.default
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"' if value else '""'
    return _number(value) if isinstance(value, int | float) else str(value)


def _allowed(field: FieldInfo) -> str:
    """The choices of a Literal, or the bounds the schema checks, or the kind of value."""
    annotation = field.annotation
    args = [annotation] if typing.get_origin(annotation) is typing.Literal else (
        [a for a in typing.get_args(annotation) if a is not type(None)] or [annotation])
    literal = [a for a in args if typing.get_origin(a) is typing.Literal]
    if literal:
        return ", ".join(f'"{v}"' for v in typing.get_args(literal[0]))
    kinds = {bool: "true / false", int: "integer", float: "number", str: "text"}
    kind = next((kinds[a] for a in args if a in kinds), None)
    if kind is None:  # a list
        inner = [typing.get_args(a) for a in args if typing.get_origin(a) is list]
        kind = f"list of {kinds.get(inner[0][0], 'values')}" if inner else "value"
        kind = kind.replace("number", "numbers").replace("text", "texts")
    bounds = [f"{sign} {_number(getattr(m, name))}" for m in field.metadata
              for name, sign in _BOUNDS if getattr(m, name, None) is not None]
    length = [m.min_length for m in field.metadata if getattr(m, "min_length", None)]
    if length:
        bounds.append(f"at least {length[0]} character")
    return kind + (f", {' and '.join(bounds)}" if bounds else "")


def _cell(text: str) -> str:
    return one_line(text).replace("|", "\\|")


def _table(model: type[BaseModel], prefix: str) -> list[str]:
    rows = ["| key | default | values | meaning |", "|---|---|---|---|"]
    for name, field in model.model_fields.items():
        if submodel(field.annotation) is not None:
            continue
        rows.append(f"| `{prefix}{name}` | {_cell(_default(field))} | {_cell(_allowed(field))} "
                    f"| {_cell(field.description or '')} |")
    return rows


def reference_markdown() -> str:
    """docs/config.md: the top-level keys, then each section's table."""
    out = [HEAD, "## Top level", "", *_table(Config, ""), ""]
    for name, field in Config.model_fields.items():
        section = submodel(field.annotation)
        if section is None:
            continue
        doc = one_line((section.__doc__ or "").strip().split("\n\n")[0]).replace("``", "`")
        need = ("A config must have this section." if field.is_required()
                else "The section may be left out: each of its keys has a default.")
        out += [f"## [{name}]", "", f"{doc} {need}", "", *_table(section, f"{name}."), ""]
    return "\n".join(out).rstrip() + "\n"


def main() -> None:
    print(reference_markdown(), end="")


if __name__ == "__main__":
    main()

