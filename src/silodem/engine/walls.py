"""Walls: straight segments A-B in 2D, each with its own contact stiffness and friction.

A grain touches a wall at the point of the segment closest to its centre.  An end point of a
segment acts as a contact point (a "cap") only when it is free; where two active segments
share an end point, the end is not capped, so that a grain sitting on the joint of two
collinear segments (a flat floor and its gate) is not counted twice.  For the convex
containers of a silo the faces of the two segments cover every grain near such a joint.

Walls are never deleted, only deactivated (the gate under the outlet is withdrawn that way),
so a wall's index is permanent and contact history can be keyed on it.  A wall may translate
with a constant velocity ``(vx, vy)`` [m/s].

A one-sided wall has an inside: the left of the direction A -> B.  Its face pushes grains
towards the inside even when a grain's centre has been pressed past the line (soft contacts,
fast impacts), instead of letting it tunnel through; silo walls are one-sided.
"""

from __future__ import annotations

import numpy as np

_JOIN_TOL = 1e-9  # [m] end points closer than this are the same point


class Walls:
    def __init__(self) -> None:
        self.names: list[str] = []
        self.ax = np.zeros(0)
        self.ay = np.zeros(0)
        self.bx = np.zeros(0)
        self.by = np.zeros(0)
        self.vx = np.zeros(0)
        self.vy = np.zeros(0)
        self.kn = np.zeros(0)  # contact normal stiffness with a grain [N/m]
        self.ks = np.zeros(0)  # contact shear stiffness with a grain [N/m]
        self.mu = np.zeros(0)  # grain-wall friction coefficient tan(phi_P) [-]
        self.active = np.zeros(0, dtype=np.bool_)
        self.cap_a = np.zeros(0, dtype=np.bool_)
        self.cap_b = np.zeros(0, dtype=np.bool_)
        self.one_sided = np.zeros(0, dtype=np.bool_)

    def __len__(self) -> int:
        return len(self.names)

    def add(
        self,
        name: str,
        a: tuple[float, float],
        b: tuple[float, float],
        kn: float,
        ks: float,
        mu: float,
        velocity: tuple[float, float] = (0.0, 0.0),
        one_sided: bool = False,
    ) -> int:
        """Add a segment from ``a`` to ``b`` [m] with contact stiffnesses [N/m] and friction [-];
        ``one_sided``: the inside is the left of a -> b."""
        if len(self.names) >= 1024:
            raise ValueError("at most 1024 walls (contact keys reserve 10 bits for the wall)")
        if name in self.names:
            raise ValueError(f"duplicate wall name {name!r}")
        if np.hypot(b[0] - a[0], b[1] - a[1]) <= 0.0:
            raise ValueError(f"wall {name!r} has zero length")
        self.names.append(name)
        for attr, val in (
            ("ax", a[0]), ("ay", a[1]), ("bx", b[0]), ("by", b[1]),
            ("vx", velocity[0]), ("vy", velocity[1]), ("kn", kn), ("ks", ks), ("mu", mu),
        ):
            setattr(self, attr, np.append(getattr(self, attr), float(val)))
        self.active = np.append(self.active, True)
        self.cap_a = np.append(self.cap_a, True)
        self.cap_b = np.append(self.cap_b, True)
        self.one_sided = np.append(self.one_sided, bool(one_sided))
        self.update_caps()
        return len(self.names) - 1

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no wall named {name!r}; walls: {', '.join(self.names)}") from None

    def set_active(self, name: str, active: bool) -> None:
        self.active[self.index(name)] = active
        self.update_caps()

    def update_caps(self) -> None:
        """An end point is a contact point only if no other active wall ends there."""
        ends = [(self.ax, self.ay), (self.bx, self.by)]
        for w in range(len(self)):
            for which, (ex, ey) in enumerate(ends):
                shared = False
                for v in range(len(self)):
                    if v == w or not self.active[v]:
                        continue
                    for ox, oy in ends:
                        if abs(ox[v] - ex[w]) < _JOIN_TOL and abs(oy[v] - ey[w]) < _JOIN_TOL:
                            shared = True
                (self.cap_a if which == 0 else self.cap_b)[w] = not shared

    def arrays(self) -> tuple:
        """The per-wall arrays in the order the contact kernels unpack them
        (``contact.wall_contact``)."""
        return (self.ax, self.ay, self.bx, self.by, self.vx, self.vy, self.kn, self.ks,
                self.mu, self.active, self.cap_a, self.cap_b, self.one_sided)

    def moving(self) -> bool:
        """Whether a wall has a velocity."""
        return bool(np.any(self.vx) or np.any(self.vy))

    def advance(self, dt: float) -> float:
        """Move the walls by velocity*dt; return the largest displacement [m]."""
        if not self.moving():
            return 0.0
        dx, dy = self.vx * dt, self.vy * dt
        self.ax += dx
        self.bx += dx
        self.ay += dy
        self.by += dy
        return float(np.max(np.hypot(dx, dy)))

    @property
    def length(self) -> np.ndarray:
        return np.hypot(self.bx - self.ax, self.by - self.ay)
