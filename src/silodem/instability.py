"""What makes a run unstable, and the grain to blame (docs/reliability.md, "Unstable runs").

Between two chunks, :func:`find_problem` finds a run unstable (exit code 3) when

* a grain has a non-finite position, velocity or spin;
* a grain is outside the domain: the silo's bounding box grown by one silo size
  L = max(cell width, wall height) on every side (grains that slip just through a wall are
  removed by the procedure and reported as lost; a grain that far away was thrown); of a
  grain under the removal level, discharged and removed at the next chunk, only x is tested;
* every grain has gone out through the walls, after pouring and with none discharged;
* the kinetic energy exceeds ``ENERGY_FACTOR`` times the energy the grains in the silo could gain
  by falling from the wall top to the removal level under the outlet, plus their pouring energy:
  E_max = 100 * M * (max(g, 9.81 m/s^2) * (z_top - z_remove) + v0^2 / 2).

The engine raises :class:`~silodem.errors.UnstableRunError` inside a step (non-finite
position, grains spread over a huge area); :func:`blame` then finds the grain from the arrays
(lowest uid among the non-finite ones, else the farthest out, else the most energetic /
fastest).  :func:`write_json` writes the diagnosis (diagnostic.json) that
``safety.RunGuard.fail`` puts together."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from silodem.atomic import atomic_file

if TYPE_CHECKING:
    from silodem.silo.procedure import SiloRun

ENERGY_FACTOR = 100.0
_STATE_FIELDS = ("x", "y", "vx", "vy", "omega")


@dataclass(frozen=True)
class Domain:
    """The box a grain must stay in [m]."""

    xmin: float
    xmax: float
    ymin: float
    ymax: float

    def distance_outside(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        dx = np.maximum(np.maximum(self.xmin - x, x - self.xmax), 0.0)
        dy = np.maximum(np.maximum(self.ymin - y, y - self.ymax), 0.0)
        return np.hypot(dx, dy)

    def text(self) -> str:
        return (f"x in [{self.xmin:.3g}, {self.xmax:.3g}] m, "
                f"y in [{self.ymin:.3g}, {self.ymax:.3g}] m")


def domain_of(run: SiloRun) -> Domain:
    shape = run.shape
    size = max(shape.width, shape.wall_top)
    return Domain(-size, shape.width + size, run.z_remove - size, shape.wall_top + size)


def energy_bound(run: SiloRun) -> float:
    """The largest kinetic energy a stable run may have now [J] (module docstring)."""
    g = max(run.cfg.gravity, 9.81)
    height = run.shape.wall_top - run.z_remove
    v0 = run.cfg.fill.initial_speed
    return ENERGY_FACTOR * run.sim.particles.total_mass() * (g * height + 0.5 * v0 * v0)


def grain_record(run: SiloRun, index: int) -> dict[str, Any]:
    """Everything about the live grain ``index``: uid, position, velocity, spin, size, force."""
    p = run.sim.particles
    rec: dict[str, Any] = {"uid": int(p.uid[index]), "index": int(index)}
    for key in ("x", "y", "vx", "vy", "omega", "radius", "mass", "fx", "fy"):
        rec[key] = float(getattr(p, key)[index])
    rec["speed"] = float(math.hypot(rec["vx"], rec["vy"]))
    return rec


@dataclass
class Problem:
    """What is wrong, with the grain to blame (``index`` into the live grains, or None)."""

    kind: str  # non_finite | outside_domain | energy | engine | all_lost
    message: str
    index: int | None
    details: dict[str, Any] = field(default_factory=dict)


def grain_text(rec: dict[str, Any]) -> str:
    """The grain of a :func:`grain_record` in words: its uid, position and velocity."""
    return (f"grain uid {rec['uid']} at (x, y) = ({rec['x']:.4g}, {rec['y']:.4g}) m, velocity "
            f"({rec['vx']:.3g}, {rec['vy']:.3g}) m/s")


def find_problem(run: SiloRun) -> Problem | None:
    """The first unphysical thing in the state of ``run`` (module docstring), or None."""
    p = run.sim.particles
    n = p.n
    when = f"at t = {run.sim.time:.6g} s (step {run.sim.steps}, {run.state.phase})"
    if n == 0:
        lost = int(run.events.get("lost_count", 0))
        # poured (a pour may lose its first batch and go on) and none left by the outlet
        if lost > 0 and run.state.phase != "fill" and run.state.discharged_mass == 0.0:
            return Problem("all_lost", f"no grain is left in the silo: all {lost} have gone "
                           f"out through its walls, {when}; the contacts are far too soft for "
                           "the silo's weight (the soft-contact warning, if any, gives the "
                           "stiffness to use) or the time step is too large", None,
                           {"lost_count": lost})
        return None
    uid = p.view("uid")
    bad = np.zeros(n, dtype=bool)
    for key in _STATE_FIELDS:
        bad |= ~np.isfinite(p.view(key))
    if np.any(bad):
        idx = np.flatnonzero(bad)
        i = int(idx[np.argmin(uid[idx])])
        rec = grain_record(run, i)
        fields = [k for k in _STATE_FIELDS if not math.isfinite(rec[k])]
        return Problem("non_finite", f"non-finite {', '.join(fields)} of {grain_text(rec)}, "
                       f"{when} ({idx.size} grain(s) with non-finite values)", i,
                       {"n_non_finite": int(idx.size),
                        "non_finite_uids": sorted(int(u) for u in uid[idx])[:20]})
    domain = domain_of(run)
    # a grain under the removal level has been discharged: it is removed at the start of the
    # next chunk however far it fell in this one (at 100 m/s under gravity = 1000 m/s^2, past
    # the domain's floor), so only its x is tested
    out = domain.distance_outside(p.view("x"), np.maximum(p.view("y"), run.z_remove))
    if np.any(out > 0):
        i = int(np.argmax(out))
        rec = grain_record(run, i)
        return Problem("outside_domain", f"{grain_text(rec)} has left the domain "
                       f"({domain.text()}), {when}", i,
                       {"n_outside": int(np.count_nonzero(out > 0))})
    ke = p.kinetic_energy()
    bound = energy_bound(run)
    if not ke <= bound:
        i = int(np.argmax(p.kinetic_energies()))
        rec = grain_record(run, i)
        return Problem("energy", f"kinetic energy {ke:.3g} J exceeds {ENERGY_FACTOR:g} x the "
                       f"energy the grains can gain by falling and being poured ({bound:.3g} J) "
                       f"{when}; most energetic: {grain_text(rec)}", i)
    return None


def blame(run: SiloRun, message: str) -> Problem:
    """A Problem for an error the engine raised: the grain found by :func:`find_problem`, else
    the fastest grain."""
    found = find_problem(run)
    if found is not None:
        return Problem("engine", message, found.index,
                       {"found": found.kind, "found_message": found.message, **found.details})
    p = run.sim.particles
    if p.n == 0:
        return Problem("engine", message, None)
    speed = np.hypot(p.view("vx"), p.view("vy"))
    return Problem("engine", message, int(np.argmax(speed)), {"found": "fastest grain"})


def _json_safe(value: Any) -> Any:
    """JSON without NaN/Infinity tokens: non-finite floats become the strings 'nan', 'inf'."""
    if isinstance(value, dict):
        return {str(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")
    return value


def write_json(path: Path, data: dict[str, Any]) -> None:
    """``data`` as strict JSON (:func:`_json_safe`), written whole or not at all."""
    with atomic_file(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        json.dump(_json_safe(data), fh, indent=2, allow_nan=False)
        fh.write("\n")
        fh.flush()
