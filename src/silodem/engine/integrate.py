"""Central-difference (leap-frog) integration, the paper's eqs. (6)-(9), after each grain's
wall contacts have been computed and added to its sums.

Velocities live at half steps: with the forces F(t) of positions x(t),

    v(t + dt/2) = v(t - dt/2) + (F(t)/m + g) dt,       omega(t + dt/2) = omega(t - dt/2) + M(t)/I dt
    x(t + dt)   = x(t) + v(t + dt/2) dt

F(t), M(t) are summed per grain in a fixed order: its grain-grain contacts by
``contact.pair_forces`` (see there), then its wall contacts here (``contact.wall_contact``, in
candidate order), so a run has the same bits for any number of threads.  The torque of a
contact on each of its grains is -r * F_s (see ``silodem.engine.contact``).

The wall contacts are computed in the same pass as the update, while the grain's state is in
registers: a separate pass over the wall candidates would fetch the grains next to the walls,
scattered through the arrays, from memory once more (at 1e6 grains that cost 5 ns per grain
and step, a fifth of the step).

PFC local damping (Itasca PFC2D manual, "local damping"): with alpha > 0 each component of the
unbalanced force (contacts + gravity) and of the moment is reduced by alpha*|F| in the direction
opposing the current (half-step) velocity, F_d = -alpha |F| sign(v).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from silodem.engine.contact import wall_contact
from silodem.jit import kernel, njit, prange

HERTZ = False  # compile-time constant of the kernel: True in its Hertz-Mindlin copy


@kernel
def walls_and_leapfrog(strip_start, blocks, w_start, wc_w, wc_fs, wc_fn, wc_fx, wc_fy, walls,
                       x, y, vx, vy, omega, fx, fy, torque, radius, mass,
                       x_ref, y_ref, gravity, zeta, allow_tension, alpha, dt, runs,
                       collect, wall_gap, wall_drift, fast_d2, fast):
    """Compute each grain's wall contacts (candidates ``w_start[i]:w_start[i+1]`` of the
    neighbour list, walls ``Walls.arrays()``, ``contact.wall_contact``) and add them to the
    sums of its grain-grain contacts (``fx, fy``, and in ``torque`` the sum of their shear
    forces, from ``contact.pair_forces``), store the totals (``torque``: -r * sum(F_s)),
    advance the grains of the strips (``strip_start``, all grains) one step, and return the
    displacements since the last neighbour-list build: (largest squared displacement [m^2]
    (inf if a position is not finite), and the bounding box min dx, max dx, min dy, max dy of
    the displacement vectors [m]).  Each thread takes one run of strips (``blocks``), the
    same grains as in ``pair_forces``, so that they are still in its core's cache, and
    writes its run's largest squared displacement and box to its row of ``runs`` (at least
    one row per run, 8 columns; given, not allocated here).

    If ``collect``, for the list test by cells (``list_validity.cells_keep_list``) it also
    lists the grains of each run whose squared displacement reaches ``fast_d2`` [m^2] (in
    ``fast``, from the run's first grain on: that index in column 7, their number in column 5)
    and sets column 6 to 1 if a grain's displacement plus the walls' drift ``wall_drift`` [m]
    reaches its ``wall_gap`` [m]; without ``collect`` (or without the build's arrays) nothing
    is listed and column 6 is 1, so that the test cannot pass."""
    (ax, ay, bx, by, w_vx, w_vy, w_kn, w_ks, w_mu, w_active, w_cap_a, w_cap_b, w_guard,
     w_one_sided) = walls
    n_blocks = blocks.shape[0] - 1
    n_all = strip_start[strip_start.shape[0] - 1]
    cells = collect and wall_gap.shape[0] >= n_all and fast.shape[0] >= n_all > 0
    for c in prange(n_blocks):
        first = strip_start[blocks[c]]
        n_fast = 0
        near_wall = 0.0 if cells else 1.0  # not listed: the test by cells must not pass
        m2 = 0.0
        lox = np.inf
        hix = -np.inf
        loy = np.inf
        hiy = -np.inf
        for p_ in range(strip_start[blocks[c]], strip_start[blocks[c + 1]]):
            p = numba.uint64(p_)  # unsigned: no negative-index test on each access
            sx = fx[p]
            sy = fy[p]
            ss = torque[p]
            r = radius[p]
            m = mass[p]
            k0 = w_start[p_]
            k1 = w_start[p_ + 1]
            if k1 > k0:  # a grain with no wall candidate keeps its stored sums: no write-back
                for k in range(k0, k1):
                    w = wc_w[k]
                    fn, fs, fwx, fwy = wall_contact(
                        x[p], y[p], vx[p], vy[p], omega[p], r, m, ax[w], ay[w], bx[w], by[w],
                        w_vx[w], w_vy[w], w_kn[w], w_ks[w], w_mu[w], w_active[w], w_cap_a[w],
                        w_cap_b[w], w_guard[w, 0], w_guard[w, 1], w_guard[w, 2], w_guard[w, 3],
                        w_one_sided[w], wc_fs[k], wc_fn[k], zeta, allow_tension, HERTZ, dt)
                    wc_fs[k] = fs
                    wc_fn[k] = fn
                    wc_fx[k] = fwx
                    wc_fy[k] = fwy
                    sx += fwx
                    sy += fwy
                    ss += fs
                fx[p] = sx
                fy[p] = sy
            mz = -r * ss
            torque[p] = mz
            fty = sy - m * gravity
            if alpha > 0.0:
                sx -= alpha * abs(sx) * np.sign(vx[p])
                fty -= alpha * abs(fty) * np.sign(vy[p])
                mz -= alpha * abs(mz) * np.sign(omega[p])
            # 1/m (the bits Particles.add stores in inv_mass) and 1/I = 2/(m r^2) worked out
            # from m and r: two arrays fewer to stream (-17 % time here at 3e5 grains)
            inv_m = 1.0 / m
            vx[p] += sx * inv_m * dt
            vy[p] += fty * inv_m * dt
            omega[p] += mz * (2.0 / (m * (r * r))) * dt
            x[p] += vx[p] * dt
            y[p] += vy[p] * dt
            ddx = x[p] - x_ref[p]
            ddy = y[p] - y_ref[p]
            d2 = ddx * ddx + ddy * ddy
            if not d2 <= m2:  # also catches NaN
                m2 = d2 if not math.isnan(d2) else np.inf
            if cells:
                if d2 >= fast_d2:
                    fast[first + n_fast] = p_
                    n_fast += 1
                room = wall_gap[p] - wall_drift
                if not (room > 0.0 and d2 < room * room):
                    near_wall = 1.0
            lox = min(lox, ddx)
            hix = max(hix, ddx)
            loy = min(loy, ddy)
            hiy = max(hiy, ddy)
        runs[c, 0] = m2
        runs[c, 1] = lox
        runs[c, 2] = hix
        runs[c, 3] = loy
        runs[c, 4] = hiy
        runs[c, 5] = n_fast
        runs[c, 6] = near_wall
        runs[c, 7] = first
    return _reduce(runs, n_blocks)


# the reductions in a serial helper: in a parallel kernel numba turns each numpy call into a
# parallel loop of its own (the five here and two np.zeros cost ~7 us a step at 1e3 grains)
@njit
def _reduce(runs, n):
    """The largest squared displacement and the bounding box over the first ``n`` runs."""
    m2, lox, hix, loy, hiy = 0.0, np.inf, -np.inf, np.inf, -np.inf
    for c in range(n):
        if not runs[c, 0] <= m2:  # also keeps an inf
            m2 = runs[c, 0]
        lox = min(lox, runs[c, 1])
        hix = max(hix, runs[c, 2])
        loy = min(loy, runs[c, 3])
        hiy = max(hiy, runs[c, 4])
    return m2, lox, hix, loy, hiy


# the same loop for the Hertz-Mindlin law (engine/hertz.py): HERTZ bound to True (last in the
# module: the copy sees the module's names as they are when it is made, ``_reduce`` included)
walls_and_leapfrog_hertz = walls_and_leapfrog.variant("_hertz", HERTZ=True)
