"""Particle state: a struct of arrays with spare capacity (jax-md / LAMMPS style).

Only the first ``n`` entries of each array are live.  Arrays are compacted when grains are
removed (``keep``, at once) and reordered (spatial sort) by the neighbour list at each
rebuild, so code that must follow a grain across steps uses its permanent ``uid``, never its
index.

Units: positions [m], velocities [m/s], spin [rad/s], forces [N], torques [N m], mass [kg],
moment of inertia [kg m^2].  Disks: m = rho*pi*r^2*t and I = m*r^2/2.
"""

from __future__ import annotations

import numpy as np

from silodem.engine import lanes
from silodem.jit import kernel, prange

_FLOAT_FIELDS = (
    "x", "y", "vx", "vy", "omega", "radius", "mass", "inv_mass",
    "fx", "fy", "torque", "x_ref", "y_ref",
)
# every field in a lane of its own (``engine/lanes.py``): the step streams a dozen of them at
# the same index, which must not all fall in one L1 cache set
FIELDS = (*_FLOAT_FIELDS, "uid")
_LANE = {name: k for k, name in enumerate(FIELDS)}


class Particles:
    """Disks in 2D.  ``fx, fy, torque`` hold the contact forces of the last step (no gravity)."""

    def __init__(self, capacity: int = 1024) -> None:
        capacity = max(int(capacity), 16)
        for name in _FLOAT_FIELDS:
            setattr(self, name, lanes.zeros(capacity, _LANE[name]))
        self.uid = lanes.zeros(capacity, _LANE["uid"], np.int64)
        self.n = 0
        self.next_uid = 0

    @property
    def capacity(self) -> int:
        return self.x.shape[0]

    def _grow(self, needed: int) -> None:
        cap = self.capacity
        while cap < needed:
            cap *= 2
        if cap == self.capacity:
            return
        for name in FIELDS:
            old = getattr(self, name)
            new = lanes.zeros(cap, _LANE[name], old.dtype)
            new[: self.n] = old[: self.n]
            setattr(self, name, new)

    def to_lanes(self) -> None:
        """Copy every field into its own lane, after the arrays were replaced wholesale (a
        checkpoint's restore): the same values, placed as ``__init__`` places them."""
        for name in FIELDS:
            setattr(self, name, lanes.copy(getattr(self, name), _LANE[name]))

    def add(
        self,
        x: np.ndarray,
        y: np.ndarray,
        radius: np.ndarray,
        density: float,
        thickness: float = 1.0,
        vx: np.ndarray | float = 0.0,
        vy: np.ndarray | float = 0.0,
        omega: np.ndarray | float = 0.0,
    ) -> np.ndarray:
        """Append disks at (x, y) [m] of ``radius`` [m], ``density`` [kg/m^3] and ``thickness``
        [m] (mass density pi r^2 thickness), with velocity (vx, vy) [m/s] and spin ``omega``
        [rad/s]; return their uids.  The neighbour list must be rebuilt afterwards."""
        x = np.atleast_1d(np.asarray(x, dtype=float))
        k = x.shape[0]
        self._grow(self.n + k)
        s = slice(self.n, self.n + k)
        r = np.broadcast_to(np.asarray(radius, dtype=float), (k,))
        self.x[s] = x
        self.y[s] = np.broadcast_to(np.asarray(y, dtype=float), (k,))
        self.vx[s] = vx
        self.vy[s] = vy
        self.omega[s] = omega
        self.radius[s] = r
        mass = density * np.pi * r**2 * thickness
        self.mass[s] = mass
        self.inv_mass[s] = 1.0 / mass
        self.fx[s] = 0.0
        self.fy[s] = 0.0
        self.torque[s] = 0.0
        self.x_ref[s] = self.x[s]
        self.y_ref[s] = self.y[s]
        uids = np.arange(self.next_uid, self.next_uid + k, dtype=np.int64)
        self.uid[s] = uids
        self.next_uid += k
        self.n += k
        return uids

    def keep(self, mask: np.ndarray) -> None:
        """Keep the live particles where ``mask`` is True (compaction, order preserved)."""
        idx = np.flatnonzero(mask[: self.n])
        m = idx.shape[0]
        for name in FIELDS:
            arr = getattr(self, name)
            arr[:m] = arr[idx]
        self.n = m

    def permute(self, order: np.ndarray, skip: tuple[str, ...] = (),
                threads: int | None = None) -> None:
        """Reorder the live particles: new index k holds old index ``order[k]``.  Fields in
        ``skip`` are left as they are (the caller overwrites them); ``threads`` as in
        ``jit.Kernel.pick``."""
        n = self.n
        tmp = np.empty(n)
        reorder = _reorder.pick(n, threads)
        for name in _FLOAT_FIELDS:
            if name in skip:
                continue
            reorder(getattr(self, name), order, tmp)
        self.uid[:n] = self.uid[:n][order]

    # --- read-only views and derived quantities (never change state) -------------------
    def view(self, name: str) -> np.ndarray:
        return getattr(self, name)[: self.n]

    def _kinetic_parts(self) -> tuple[np.ndarray, np.ndarray]:
        """Each live grain's translational m v^2 / 2 and rotational I omega^2 / 2 [J]."""
        with np.errstate(over="ignore"):  # an exploding run's inf is for the guard to name
            v2 = self.view("vx") ** 2 + self.view("vy") ** 2
            return 0.5 * self.view("mass") * v2, 0.5 * self.inertia() * self.view("omega") ** 2

    def kinetic_energies(self) -> np.ndarray:
        """Each live grain's kinetic energy, translational + rotational [J] (half-step
        velocities)."""
        translational, rotational = self._kinetic_parts()
        return translational + rotational

    def kinetic_energy(self) -> float:
        """Translational + rotational kinetic energy of all grains [J] (half-step velocities).
        Summed part by part (the halving is exact), so the settling criterion keeps its bits."""
        translational, rotational = self._kinetic_parts()
        return float(np.sum(translational) + np.sum(rotational))

    def inertia(self) -> np.ndarray:
        """Moments of inertia of the live disks about their centres, m r^2 / 2 [kg m^2] (derived,
        not stored: the step works it out from m and r)."""
        return 0.5 * self.view("mass") * self.view("radius") ** 2

    def total_mass(self) -> float:
        """Mass of the grains [kg]."""
        return float(np.sum(self.mass[: self.n]))


@kernel
def _reorder(arr, order, tmp):
    """arr[k] <- arr[order[k]] for k < order.size, through ``tmp`` (in threads: a gather, then a
    copy back; numpy's take is serial)."""
    n = order.shape[0]
    for k in prange(n):
        tmp[k] = arr[order[k]]
    for k in prange(n):
        arr[k] = tmp[k]
