"""``silodem validate``: run the case families, collect their records, draw their figures.

Families (one module each; a family returns its records and the data of its figure):

* impacts    linear normal impacts against the analytic spring-dashpot solution
              (Chung & Ooi tests 1-3; Schwager & Poeschel 2007), with the order of convergence;
* chung_ooi  Chung & Ooi (2011) tests 4-8 adapted to disks, against rigid-body theory;
* hertz_mindlin  the Hertz-Mindlin law against Hertz's impact and static overlap, Mindlin's
              shear stiffness, and the restitution of Tsuji's dashpot at three speeds;
* statics    a settled column: floor + walls carry the weight;
* lammps     grain-by-grain trajectories against LAMMPS on the benchmark's outlet (when ``lmp``
              is installed);
* janssen    a tall flat-bottomed slot silo against the 2D Janssen solution   (full mode only);
* beverloo   steady discharge rates against the 2D Beverloo law                (full mode only).

``--quick`` runs the first five (the particle-impact level, one small packing, LAMMPS), the subset
CI runs; the full mode adds the silo-scale cases; ``--case NAME`` (repeatable) runs only the
named families, e.g. the Janssen silo alone.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from importlib import import_module
from pathlib import Path
from typing import TYPE_CHECKING

from silodem.validate.records import Record

if TYPE_CHECKING:
    from rich.console import Console


@dataclass(frozen=True)
class Family:
    name: str
    title: str
    quick: bool  # part of --quick
    run: Callable[[bool], tuple[list[Record], object]]
    figure: Callable[[object, Path], Path]


# (name, title, part of --quick): each name is a module of this package with ``run(quick)``
# and a function of ``figures`` that draws its figure
FAMILIES = (
    ("impacts", "linear normal impacts", True),
    ("chung_ooi", "Chung & Ooi tests 4-8 (disks)", True),
    ("hertz_mindlin", "Hertz-Mindlin law", True),
    ("statics", "settled column", True),
    ("lammps", "trajectories against LAMMPS", True),
    ("janssen", "Janssen slot silo", False),
    ("beverloo", "Beverloo discharge", False),
)
NAMES = tuple(name for name, _title, _quick in FAMILIES)


def check_cases(names: Iterable[str]) -> None:
    """Raise ValueError naming the names that are not families (of ``NAMES``)."""
    unknown = sorted(set(names) - set(NAMES))
    if unknown:
        raise ValueError(f"unknown validation case {', '.join(map(repr, unknown))}; "
                         f"the cases are {', '.join(NAMES)}")


def families() -> list[Family]:
    """The families in the order they run (their modules are imported here: numba)."""
    from silodem.validate import figures

    return [Family(name, title, quick, import_module(f"silodem.validate.{name}").run,
                   getattr(figures, name)) for name, title, quick in FAMILIES]


@dataclass
class Validation:
    records: list[Record] = field(default_factory=list)
    figures: list[Path] = field(default_factory=list)
    seconds: dict[str, float] = field(default_factory=dict)
    figure_errors: dict[str, str] = field(default_factory=dict)  # family -> why not drawn

    @property
    def passed(self) -> bool:
        return all(r.passed for r in self.records)

    @property
    def failures(self) -> list[Record]:
        return [r for r in self.records if not r.passed]

    def to_json(self) -> str:
        return json.dumps([r.to_dict() for r in self.records], indent=1)


def run_validation(quick: bool = False, out: Path | None = None,
                   progress: Callable[[str], None] | None = None,
                   only: list[str] | None = None) -> Validation:
    """Run the families (``quick``: those marked quick; ``only``: these names, of ``NAMES``),
    write their figures into ``out`` (none if None) and return every record."""
    check_cases(only or ())
    say = progress or (lambda _msg: None)
    result = Validation()
    for fam in families():
        if (quick and not fam.quick) or (only is not None and fam.name not in only):
            continue
        say(f"validate: {fam.title} ...")
        t0 = time.perf_counter()
        records, data = fam.run(quick)
        result.records.extend(records)
        if out is not None:  # the records stand without their picture: a figure that cannot
            try:             # be written (full disk, a folder in its place) is said, not fatal
                result.figures.append(fam.figure(data, Path(out) / f"{fam.name}.png"))
            except Exception as exc:  # noqa: BLE001 - reported with the records kept
                why = f"{type(exc).__name__}: {exc}"
                result.figure_errors[fam.name] = why
                say(f"validate: warning: {fam.name}.png not written ({why})")
        result.seconds[fam.name] = time.perf_counter() - t0
        checked = sum(r.kind != "info" for r in records)
        bad = sum(not r.passed for r in records)
        say(f"validate: {fam.title}: {checked} checks ({len(records) - checked} reported "
            f"values), {bad} failed, {result.seconds[fam.name]:.1f} s")
    return result


def _fmt(v) -> str:
    if v is None:
        return "-"
    v = float(v)
    if math.isnan(v):
        return "nan"
    if v == 0.0:
        return "0"
    return f"{v:.6g}" if 1e-3 <= abs(v) < 1e6 else f"{v:.4e}"


def _tol(r: Record) -> str:
    if r.kind == "info":
        return "reported"
    if r.kind == "rel":
        return f"{100 * r.tolerance:g} %"
    return f"+- {r.tolerance:g}"


def print_table(result: Validation, console: Console) -> None:
    """The records as a rich table, then a one-line verdict."""
    from rich.table import Table
    from rich.text import Text

    table = Table(title="silodem validate", show_lines=False)
    for col, kw in (("case", {"overflow": "fold", "max_width": 60}),
                    ("quantity", {"overflow": "fold", "max_width": 42}),
                    ("expected", {"justify": "right"}), ("got", {"justify": "right"}),
                    ("tolerance", {"justify": "right"}), ("pass", {"justify": "center"})):
        table.add_column(col, **kw)
    for r in result.records:
        verdict = "info" if r.kind == "info" else ("yes" if r.passed else "NO")
        style = None if r.passed else "bold red"
        unit = f" [{r.unit}]" if r.unit not in ("-", "") else ""
        # (Text, not markup: rich read ' [s]', ' [m/s]' as tags and printed no unit)
        table.add_row(Text(r.case), Text(r.quantity + unit), _fmt(r.expected), _fmt(r.got),
                      _tol(r), verdict, style=style)
    console.print(table)
    n = len(result.records)
    checked = sum(r.kind != "info" for r in result.records)
    bad = len(result.failures)
    times = ", ".join(f"{k} {v:.0f} s" for k, v in result.seconds.items())
    console.print(f"{checked} checks ({n - checked} reported values): "
                  f"{checked - bad} passed, {bad} failed  [{times}]", markup=False,
                  highlight=False)
    for r in result.failures:
        console.print(failure_line(r), markup=False, highlight=False, soft_wrap=True,
                      style="bold red")
    for path in result.figures:
        console.print(f"figure: {path}", markup=False, highlight=False, soft_wrap=True)


def failure_line(r: Record) -> str:
    """One line for a failed check: what, expected, got, the relative or absolute miss
    against the tolerance, and the record's note (where the case says why)."""
    unit = f" {r.unit}" if r.unit not in ("-", "") else ""
    if r.kind == "rel" and r.expected:
        miss = f"{100 * (r.got - r.expected) / abs(r.expected):+.1f} % against {_tol(r)}"
    else:
        miss = f"{r.got - r.expected:+.3g}{unit} against {_tol(r)}"
    note = f"; {r.note}" if r.note else ""
    return (f"FAILED {r.case}: {r.quantity}: expected {_fmt(r.expected)}{unit}, "
            f"got {_fmt(r.got)}{unit} ({miss}){note}")
