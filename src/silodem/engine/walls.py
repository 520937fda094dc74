"""Walls: straight segments A-B in 2D, each with its own contact stiffness and friction.

A grain touches a wall at the point of the segment closest to its centre.  An end point of a
segment acts as a contact point (a "cap") where it is free.  Where two active segments share
an end point P, the faces of the two cover every grain near a straight joint (a flat floor and
its gate) or a concave one (the corners of a convex container), and P is not capped, so that
no grain is counted twice; P itself, the foot of a centre exactly on the normal there, belongs
to the face of the segment added first only (``END_FACE``; on neither, such a grain fell
through the joint).  A convex corner (the edge of a thick floor at an outlet, as in the
benchmark's silo) leaves a wedge that neither face covers: the grains whose closest point is P
on both segments.  There the segment added first is capped at P with a *guard*, the unit
direction of the other segment from P, and its cap counts only for grains with
(centre - P) . guard <= 0, i.e. in that wedge: one contact at P, as the nearest point of a
polygon gives (LAMMPS's wall/gran/region on a block; docs/validation.md, sections 5-6).
Contact history is kept per grain and segment: a grain that rolls round such a corner from
the cap onto the other segment's face starts a new contact there, with no shear force carried
over (a LAMMPS region keeps one contact per region).

Walls are never deleted, only deactivated (the gate under the outlet is withdrawn that way),
so a wall's index is permanent and contact history can be keyed on it.  A wall may translate
with a constant velocity ``(vx, vy)`` [m/s]; the joints, and so the caps, follow it.

A one-sided wall has an inside: the left of the direction A -> B.  Its face pushes grains
towards the inside even when a grain's centre has been pressed past the line (soft contacts,
fast impacts), instead of letting it tunnel through; silo walls are one-sided.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

_JOIN_TOL = 1e-9  # [m] end points closer than this are the same point

# what an end of a segment is (``Walls.cap_a``, ``cap_b``): not a contact point, a contact
# point (a cap, with its guard), or the closing point of the face
END_NONE, END_CAP, END_FACE = 0, 1, 2


class Walls:
    def __init__(self) -> None:
        self.names: list[str] = []
        self.ax = np.zeros(0)
        self.ay = np.zeros(0)
        self.bx = np.zeros(0)
        self.by = np.zeros(0)
        self.vx = np.zeros(0)
        self.vy = np.zeros(0)
        # contact normal and shear stiffness with a grain [N/m] (linear law; the moduli
        # 2 E*, 8 G* [Pa] under the Hertz-Mindlin law)
        self.kn = np.zeros(0)
        self.ks = np.zeros(0)
        self.mu = np.zeros(0)  # grain-wall friction coefficient tan(phi_P) [-]
        self.active = np.zeros(0, dtype=np.bool_)
        self.cap_a = np.zeros(0, dtype=np.int8)  # END_NONE, END_CAP or END_FACE
        self.cap_b = np.zeros(0, dtype=np.int8)
        # per wall: the guards of ends a (columns 0, 1) and b (2, 3); zero for a free end
        self.guard = np.zeros((0, 4))
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
        """Add a segment from ``a`` to ``b`` [m] with contact stiffnesses [N/m] (moduli [Pa]
        under the Hertz-Mindlin law) and friction [-];
        ``one_sided``: the inside is the left of a -> b."""
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
        self.cap_a = np.append(self.cap_a, np.int8(END_CAP))
        self.cap_b = np.append(self.cap_b, np.int8(END_CAP))
        self.guard = np.vstack([self.guard, np.zeros((1, 4))])
        self.one_sided = np.append(self.one_sided, bool(one_sided))
        # the new wall, and the walls that end where it does, are the only ones that change
        w = len(self.names) - 1
        ends = self._ends()
        touched = {w} | {int(v) for e in (0, 1) for v, _ in self._joined(ends[w, e], ends, w)}
        self.update_caps(sorted(touched), ends)
        return w

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no wall named {name!r}; walls: {', '.join(self.names)}") from None

    def set_active(self, name: str, active: bool) -> None:
        self.active[self.index(name)] = active
        self.update_caps()

    def update_caps(self, walls: Iterable[int] | None = None,
                    ends: np.ndarray | None = None) -> None:
        """Cap the free ends and, at a convex corner of two segments, the first one's end with
        a guard (module docstring); at a straight or concave joint close the first one's face
        with the shared point and leave both uncapped.  ``walls``:
        the indices to update (default all); ``ends``: ``_ends()`` if the caller has it."""
        ends = self._ends() if ends is None else ends
        for w in range(len(self)) if walls is None else walls:
            for which in (0, 1):
                cap, guard = self._cap(w, which, ends)
                (self.cap_a if which == 0 else self.cap_b)[w] = cap
                self.guard[w, 2 * which:2 * which + 2] = guard

    def joint_map(self) -> np.ndarray:
        """Which end points of active walls coincide (within ``_JOIN_TOL``), shape
        (2 W, 2 W) over the ends (a of wall 0, b of wall 0, a of wall 1, ...)."""
        ends = self._ends().reshape(-1, 2)
        on = np.repeat(self.active, 2)
        near = np.abs(ends[:, None, :] - ends[None, :, :]).max(axis=2) < _JOIN_TOL
        return near & on[:, None] & on[None, :]

    def _ends(self) -> np.ndarray:
        """The end points, shape (wall, end a / b, x / y) [m]."""
        return np.stack([np.column_stack([self.ax, self.ay]),
                         np.column_stack([self.bx, self.by])], axis=1)

    def _joined(self, point: np.ndarray, ends: np.ndarray, but: int) -> np.ndarray:
        """(wall, end) of the active walls other than ``but`` that end at ``point``."""
        near = np.abs(ends - point).max(axis=2) < _JOIN_TOL
        near[but] = False
        near[~self.active] = False
        return np.argwhere(near)

    def _cap(self, w: int, which: int, ends: np.ndarray) -> tuple[int, np.ndarray]:
        """What end ``which`` of wall w is (``END_*``), and its guard."""
        none = np.zeros(2)
        if not self.active[w]:
            return END_NONE, none
        joined = self._joined(ends[w, which], ends, w)
        if len(joined) == 0:
            return END_CAP, none
        v, end_v = joined[0]
        if len(joined) > 1 or v < w:
            return END_NONE, none
        into_w = ends[w, 1 - which] - ends[w, which]
        into_v = ends[v, 1 - end_v] - ends[v, end_v]
        into_w = into_w / np.hypot(*into_w)
        into_v = into_v / np.hypot(*into_v)
        if self._convex(w, into_w, into_v) and self._convex(v, into_v, into_w):
            return END_CAP, into_v
        return END_FACE, none

    def _convex(self, w: int, into_w: np.ndarray, into_v: np.ndarray) -> bool:
        """Whether the wedge beyond both segments at their joint lies on wall w's grain side:
        not a straight joint, and for a one-sided wall its centre direction -(into_w + into_v)
        points to the inside (the left of a -> b)."""
        mid = -(into_w + into_v)
        if np.hypot(*mid) < 1e-9:  # straight joint
            return False
        if not self.one_sided[w]:
            return True
        ux, uy = self.bx[w] - self.ax[w], self.by[w] - self.ay[w]
        return float(mid[0] * -uy + mid[1] * ux) > 0.0

    def arrays(self) -> tuple:
        """The per-wall arrays in the order the contact kernels unpack them
        (``contact.wall_contact``)."""
        return (self.ax, self.ay, self.bx, self.by, self.vx, self.vy, self.kn, self.ks,
                self.mu, self.active, self.cap_a, self.cap_b, self.guard, self.one_sided)

    def moving(self) -> bool:
        """Whether a wall has a velocity."""
        return bool(np.any(self.vx) or np.any(self.vy))

    def advance(self, dt: float) -> float:
        """Move the walls by velocity*dt; return the largest displacement [m].  A wall that
        leaves a joint frees its neighbour's end (capped again), and an end that comes within
        ``_JOIN_TOL`` of another's joins it: the caps are set again whenever the joints
        change (a gate sliding in its slot under the floor never changes them)."""
        if not self.moving():
            return 0.0
        joints = self.joint_map()
        dx, dy = self.vx * dt, self.vy * dt
        self.ax += dx
        self.bx += dx
        self.ay += dy
        self.by += dy
        if not np.array_equal(self.joint_map(), joints):
            self.update_caps()
        return float(np.max(np.hypot(dx, dy)))

    @property
    def length(self) -> np.ndarray:
        """Length of each wall [m]."""
        return np.hypot(self.bx - self.ax, self.by - self.ay)
