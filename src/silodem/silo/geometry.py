"""Silo walls from a few parameters.

Coordinates: x across the silo, x = 0 at the left wall of the cell; z (the simulation's y)
upwards, z = 0 at the outlet.  The outlet of width D is centred: x in [(B-D)/2, (B+D)/2].

* flat:   left/right vertical walls from z = 0 to the wall top, floor pieces on each side of the
          outlet, and the gate across it.
* hopper: left/right vertical walls from the junction z_j = (B-D)/2 * tan(theta) to the wall top,
          planar hopper walls from the outlet edges to the junction, and the gate.

theta is the hopper wall's angle FROM THE HORIZONTAL (the paper's "slope"); hopper theory
(Walker, Jenike) uses the complement 90 deg - theta, measured from the vertical.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from silodem.config import Config
from silodem.engine.walls import Walls
from silodem.silo.materials import contact_constants

GATE = "gate"
GATE_GAP = 0.1  # a sliding gate's least depth under the outlet's edges [smallest radii]
GATE_CLEARANCE = 10.0  # ... and under a flat floor, this many expected overlaps at least
GATE_DEEPEST = 0.5  # the deepest a sliding gate may lie [smallest radii] (checks.check_gate)


def gate_depth(cfg: Config, expected_overlap: float = 0.0) -> float:
    """How far under z = 0 the gate lies [m]: 0 for a gate removed at once (the paper's, and
    without a discharge); for one that slides open (``discharge.gate_speed``) GATE_GAP
    smallest radii, and under a flat floor at least GATE_CLEARANCE times the fill's
    ``expected_overlap`` [m] (``checks.estimate_overlap``): a slide gate runs in a slot under
    the floor, clear of the grains that rest on it, whose overlaps under the force chains
    reach about five times the estimate's mean (measured in a flat paper-case2 --quick).
    Beside a hopper's outlet only grains over the outlet, which rest on the gate anyway, can
    reach it."""
    d = cfg.discharge
    if d.gate_speed is None or not d.enabled:
        return 0.0
    least = GATE_GAP * cfg.material.radius_min
    return max(least, GATE_CLEARANCE * expected_overlap) if cfg.silo.kind == "flat" else least


def gate_opening_time(cfg: Config) -> float | None:
    """How long a sliding gate takes to clear the outlet, D / ``discharge.gate_speed`` [s];
    None for a gate removed at once, and without a discharge."""
    d = cfg.discharge
    if d.gate_speed is None or not d.enabled:
        return None
    return cfg.silo.outlet_width / d.gate_speed


def gate_overlap(cfg: Config) -> float:
    """The expected overlap [m] that sets a sliding gate's depth under a flat floor
    (``gate_depth``): ``checks.estimate_overlap``'s; 0 where it plays no part."""
    if cfg.discharge.gate_speed is None or cfg.silo.kind != "flat":
        return 0.0
    from silodem.silo.checks import estimate_overlap  # (checks reads this module)

    return estimate_overlap(cfg).overlap


def gate_shift(events: Mapping[str, Any], names: Sequence[str], ax: npt.ArrayLike,
               bx: npt.ArrayLike, time: float) -> np.ndarray:
    """Each wall's x displacement [m] at ``time`` [s] from its place as built (results.h5
    /walls): a gate that slides open (the event ``gate_opening_time``) has moved its length
    over that time for each second since the discharge started (``discharge_start_time``),
    0 before; every other wall, and a gate removed at once, 0. Pure kinematics: a drawing
    applies it while the gate stands (walls_active). 0 at an unknown (NaN) time."""
    shift = np.zeros(len(names))
    t0, span = events.get("discharge_start_time"), events.get("gate_opening_time")
    if t0 is None or span is None or GATE not in names or not math.isfinite(float(time)):
        return shift
    k = list(names).index(GATE)
    length = float(np.asarray(bx)[k] - np.asarray(ax)[k])
    shift[k] = max(float(time) - float(t0), 0.0) * length / float(span)
    return shift


def outlet_room(cfg: Config) -> float:
    """Room [m] each side of the outlet's span where a grain under the silo still counts as
    come through it (``SiloShape.came_through_outlet``): 2 largest radii, for the grains
    knocked sideways by others in the falling stream."""
    return 2.0 * cfg.material.radius_max


@dataclass(frozen=True)
class SiloShape:
    """The silo's outline, for placing grains and for measurements."""

    kind: str
    width: float  # B [m]
    wall_top: float  # [m]
    outlet_left: float  # [m]
    outlet_right: float  # [m]
    junction: float  # z of the cell-hopper junction [m] (0 for flat)

    def inner_x_range(self, z: float) -> tuple[float, float]:
        """Horizontal extent of the silo's inside at height z [m] (0 <= z <= wall_top)."""
        lo, hi = self.inner_x_bounds(z)
        return float(lo), float(hi)

    def inner_x_bounds(self, z: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """(left, right) edges [m] of the silo's inside at the heights ``z`` [m]: the hopper
        walls below the junction (those of the outlet under it), the cell's walls above."""
        z = np.asarray(z, dtype=float)
        if self.kind == "flat" or self.junction <= 0.0:
            return np.zeros_like(z), np.full_like(z, self.width)
        f = np.clip(z / self.junction, 0.0, 1.0)
        return (self.outlet_left * (1.0 - f),
                self.outlet_right + (self.width - self.outlet_right) * f)

    def pushed_out(self, x: npt.ArrayLike, z: npt.ArrayLike, room: float) -> np.ndarray:
        """True where a grain centre (x, z) [m] lies outside the silo, pushed through a wall
        by too soft contacts: under the floor away from the outlet (not within its span
        widened by ``room`` [m], :meth:`over_outlet`, the rule of :meth:`came_through_outlet`
        for a grain at rest) or, above it, beyond a wall at its height.  A grain sunk into
        the closed gate (z < 0 over the outlet) falls through the outlet when it opens: it is
        not pushed out."""
        x, z = np.asarray(x, dtype=float), np.asarray(z, dtype=float)
        lo, hi = self.inner_x_bounds(z)
        return np.where(z < 0.0, ~self.over_outlet(x, room), (x < lo) | (x > hi))

    def came_through_outlet(self, x: np.ndarray, z: np.ndarray, vx: np.ndarray,
                            vz: np.ndarray, g: float, room: float) -> np.ndarray:
        """True where a grain under the silo (z < 0) at (x, z) [m] moving at (vx, vz) [m/s] can
        have come through the outlet: its free fall under gravity ``g`` [m/s^2] traced back to
        z = 0 (the time s since then from z = vz s + g s^2 / 2) crossed it within the outlet's
        span widened by ``room`` [m] each side.  A grain under the floor elsewhere, or beside
        the walls, was pushed through a wall.  (Tracing back takes out the sideways drift of a
        grain that left the outlet slanting; collisions in the falling stream are what the
        room is for.)"""
        x, z, vx, vz = (np.asarray(v, dtype=float) for v in (x, z, vx, vz))
        below = np.minimum(z, 0.0)
        if g > 0.0:
            s = (-vz - np.sqrt(np.maximum(vz * vz + 2.0 * g * below, 0.0))) / g  # (the root
            # with the grain going down at z = 0)
        else:  # no gravity: a straight line back
            s = np.where(vz < 0.0, below / np.where(vz < 0.0, vz, -1.0), 0.0)
        return self.over_outlet(x - vx * np.maximum(s, 0.0), room)

    def over_outlet(self, x: np.ndarray, room: float) -> np.ndarray:
        """True where x [m] lies within the outlet's span widened by ``room`` [m] each side."""
        x = np.asarray(x, dtype=float)
        return (x >= self.outlet_left - room) & (x <= self.outlet_right + room)

    def outline(self) -> list[tuple[float, float]]:
        """Corners of the silo's inside [m], anticlockwise from the outlet's left edge (the
        outlet and the cell's open top are edges of the polygon)."""
        B, top = self.width, self.wall_top
        if self.kind == "flat":
            return [(0.0, 0.0), (B, 0.0), (B, top), (0.0, top)]
        return [(self.outlet_left, 0.0), (self.outlet_right, 0.0), (B, self.junction), (B, top),
                (0.0, top), (0.0, self.junction)]

    def area_below(self, z: float) -> float:
        """Area of the silo's inside under height z [m^2]."""
        z = min(max(z, 0.0), self.wall_top)
        if self.kind == "flat":
            return self.width * z
        zh = min(z, self.junction)
        lo, hi = self.inner_x_range(zh)
        hopper = 0.5 * ((self.outlet_right - self.outlet_left) + (hi - lo)) * zh
        return hopper + self.width * max(z - self.junction, 0.0)

    def height_of_area(self, area: float) -> float:
        """Inverse of ``area_below`` (bisection) [m]."""
        lo, hi = 0.0, self.wall_top
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            if self.area_below(mid) < area:
                lo = mid
            else:
                hi = mid
        return 0.5 * (lo + hi)


def silo_shape(cfg: Config) -> SiloShape:
    """The outline of ``cfg``'s silo: a centred outlet of ``silo.outlet_width`` in a cell of
    ``silo.cell_width`` [m]."""
    s = cfg.silo
    left = 0.5 * (s.cell_width - s.outlet_width)
    return SiloShape(s.kind, s.cell_width, s.wall_height, left, left + s.outlet_width,
                     s.hopper_height)


def build_walls(cfg: Config) -> Walls:
    """The silo's wall segments with their contact parameters (with the grains', combined by
    ``materials.contact_constants``)."""
    shape = silo_shape(cfg)
    c = contact_constants(cfg)
    kn, ks = c.wall_kn, c.wall_ks
    mu = math.tan(math.radians(cfg.walls.friction_deg))
    walls = Walls()
    B, top, zj = shape.width, shape.wall_top, shape.junction
    xl, xr = shape.outlet_left, shape.outlet_right
    # one-sided walls, each directed so that the inside of the silo is on its left
    walls.add("left_wall", (0.0, top), (0.0, zj), kn, ks, mu, one_sided=True)
    walls.add("right_wall", (B, zj), (B, top), kn, ks, mu, one_sided=True)
    if shape.kind == "hopper":
        mu_h = cfg.walls.hopper_mu()  # (walls.hopper_friction_deg, else the cell's)
        walls.add("left_hopper", (0.0, zj), (xl, 0.0), kn, ks, mu_h, one_sided=True)
        walls.add("right_hopper", (xr, 0.0), (B, zj), kn, ks, mu_h, one_sided=True)
    else:
        walls.add("left_floor", (0.0, 0.0), (xl, 0.0), kn, ks, mu, one_sided=True)
        walls.add("right_floor", (xr, 0.0), (B, 0.0), kn, ks, mu, one_sided=True)
    h = gate_depth(cfg, gate_overlap(cfg))
    walls.add(GATE, (xl, -h), (xr, -h), kn, ks, mu, one_sided=True)
    return walls
