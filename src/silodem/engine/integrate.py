"""Central-difference (leap-frog) integration, the paper's eqs. (6)-(9).

Velocities live at half steps: with the forces F(t) of positions x(t),

    v(t + dt/2) = v(t - dt/2) + (F(t)/m + g) dt,       omega(t + dt/2) = omega(t - dt/2) + M(t)/I dt
    x(t + dt)   = x(t) + v(t + dt/2) dt

PFC local damping (Itasca PFC2D manual, "local damping"): with alpha > 0 each component of the
unbalanced force (contacts + gravity) and of the moment is reduced by alpha*|F| in the direction
opposing the current (half-step) velocity, F_d = -alpha |F| sign(v).
"""

from __future__ import annotations

import math

import numpy as np

from silodem.jit import kernel, prange

_CHUNKS = 64


@kernel
def leapfrog(n, x, y, vx, vy, omega, fx, fy, torque, mass, inv_mass, inv_inertia,
             x_ref, y_ref, gravity, alpha, dt):
    """Advance the first ``n`` grains by one step; return the largest squared displacement
    from the reference positions of the last neighbour-list build [m^2]."""
    chunk_max = np.zeros(_CHUNKS)
    size = (n + _CHUNKS - 1) // _CHUNKS
    for c in prange(_CHUNKS):
        m2 = 0.0
        for p in range(c * size, min(n, (c + 1) * size)):
            ftx = fx[p]
            fty = fy[p] - mass[p] * gravity
            mz = torque[p]
            if alpha > 0.0:
                ftx -= alpha * abs(ftx) * np.sign(vx[p])
                fty -= alpha * abs(fty) * np.sign(vy[p])
                mz -= alpha * abs(mz) * np.sign(omega[p])
            vx[p] += ftx * inv_mass[p] * dt
            vy[p] += fty * inv_mass[p] * dt
            omega[p] += mz * inv_inertia[p] * dt
            x[p] += vx[p] * dt
            y[p] += vy[p] * dt
            ddx = x[p] - x_ref[p]
            ddy = y[p] - y_ref[p]
            d2 = ddx * ddx + ddy * ddy
            if d2 > m2 or math.isnan(d2):
                m2 = d2 if not math.isnan(d2) else np.inf
        chunk_max[c] = m2
    return chunk_max.max()
