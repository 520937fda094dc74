"""The linear contact law of the paper (eqs. 1-5) and the force kernels that apply it.

For a contact with overlap ``delta`` [m] and relative velocity of the contact point split into a
normal part ``v_n`` (negative when the bodies approach) and a tangential part ``v_t`` [m/s]:

    F_n = k_n * delta - c_n * v_n                    (normal spring + viscous dashpot, eqs. 1, 3, 5)
    F_n = max(F_n, 0)                                unless tension is allowed
    F_s <- F_s - k_s * v_t * dt                      (incremental shear spring, eqs. 2, 4)
    |F_s| <= mu * max(F_n, 0),  mu = tan(phi)        (Coulomb slip)
    c_n = 2 * zeta * sqrt(k_n * m_eff),  m_eff = m_a m_b / (m_a + m_b)  (m_eff = m for a wall)

The normal force is written in total form, k_n*delta, which equals the paper's incremental sum
of k_n*v_n*dt for a linear spring; the dashpot, which the paper's eq. (3) writes inside the
increment, acts as a force of the current step only, as in PFC's and LAMMPS's linear laws. In 2D
the shear force is a scalar along the tangent t = (-n_y, n_x) of the current normal n; this *is*
the rotation of the shear force with the contact frame that PFC applies in 3D. A contact that
opens (delta <= 0) forgets its shear force.

Contact stiffnesses are the series values of the two bodies (PFC2D convention):
k = k_a k_b / (k_a + k_b); they are resolved once at set-up, never in the loop.

The Hertz-Mindlin law (engine/hertz.py) is this law at the tangent stiffnesses
S_n = 2 E* sqrt(R* delta), S_s = 8 G* sqrt(R* delta), applied to 2/3 delta (``hertz_mindlin``).
The kernels are compiled once per law: ``HERTZ``, a module constant that numba freezes at
compilation, is True in their copies ``pair_forces_hertz`` (and
``integrate.walls_and_leapfrog_hertz``).

Sign conventions: for a pair (i, j), n points from i to j and the force computed is the force
on j (the force on i is its opposite).  For a grain-wall contact n points from the wall to the
grain and the force is the force on the grain.  The torque on each grain is -r * F_s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from silodem.engine.walls import END_CAP, END_FACE
from silodem.jit import kernel, prange


def series(k_a: float, k_b: float) -> float:
    """Stiffness of two springs in series [N/m]: k_a k_b / (k_a + k_b)."""
    return k_a * k_b / (k_a + k_b)


def damping_ratio_from_restitution(e: float) -> float:
    """zeta = -ln e / sqrt(pi^2 + ln^2 e): the damping ratio whose linear spring-dashpot contact,
    with tension allowed, rebounds with normal restitution e (e.g. Schwager & Poeschel,
    Granular Matter 9 (2007) 465)."""
    if not 0.0 < e <= 1.0:
        raise ValueError(f"restitution must be in (0, 1], got {e}")
    if e == 1.0:
        return 0.0
    le = math.log(e)
    return -le / math.sqrt(math.pi**2 + le**2)


@dataclass(frozen=True)
class GrainLaw:
    """Contact parameters between two grains, already combined (series stiffness, or the
    effective moduli of the Hertz-Mindlin law)."""

    kn: float  # contact normal stiffness [N/m]; Hertz-Mindlin: 2 E* [Pa]
    ks: float  # contact shear stiffness [N/m]; Hertz-Mindlin: 8 G* [Pa]
    mu: float  # friction coefficient tan(phi_G) [-]
    zeta: float  # normal critical-damping ratio [-], used for grain-grain and grain-wall
    allow_tension: bool = False
    local_damping: float = 0.0  # PFC local damping alpha [-], applied in the integrator
    hertz: bool = False  # the Hertz-Mindlin law (``hertz_mindlin``, engine/hertz.py)


def damped_step_factor(zeta: float) -> float:
    """sqrt(1 + 4 zeta^2) - 2 zeta [-]: the factor by which a normal dashpot of damping ratio
    zeta shrinks a contact's time-step limit sqrt(m_eff / k), 1 at zeta = 0.

    The leap-frog takes the dashpot force from v(t - dt/2); for one mode x'' = -w^2 x -
    2 z w x' the step (x, v) -> (x + dt v', v') with v' = v (1 - 2 z w dt) - w^2 dt x has
    trace 2 - y^2 - 2 z y and determinant 1 - 2 z y (y = w dt), so it is stable (Jury) for
    y^2 + 4 z y < 4.  The undamped limit sqrt(m_eff / k) is half a lone contact's, room for a
    mode up to 4x stiffer (several contacts on one grain); such a mode, w = 2 sqrt(k / m_eff),
    has the dashpot's ratio c / k unchanged, so z = 2 zeta, and its stability reads
    y_c^2 + 4 zeta y_c < 1 for y_c = dt sqrt(k / m_eff): y_c < sqrt(1 + 4 zeta^2) - 2 zeta.
    """
    return math.sqrt(1.0 + 4.0 * zeta * zeta) - 2.0 * zeta


def critical_time_step(m_min: float, law: GrainLaw, wall_kn: np.ndarray,
                       wall_ks: np.ndarray) -> float:
    """dt_crit [s] = min over contact kinds of sqrt(m_eff / k), the normal kinds' times
    ``damped_step_factor(law.zeta)`` (the shear spring has no dashpot).

    m_eff is m_min/2 (normal) and m_min/6 (shear, the rotational inertia of two disks with
    I = m r^2/2 included) for grain-grain contacts, m_min and m_min/3 for grain-wall contacts.
    A single undamped contact is stable for dt < 2 sqrt(m_eff/k); dropping the factor 2 leaves
    room for a grain pressed by several contacts at once (Cundall & Strack 1979; PFC manual);
    the damping factor keeps that room with the dashpot on.
    """
    if law.hertz:
        raise ValueError("critical_time_step takes stiffnesses: give a Hertz-Mindlin law its "
                         "tangent stiffnesses first (silo.materials.linearised)")
    # Python floats, not numpy scalars: a ratio of a very soft wall may overflow to inf,
    # which min() then passes over, without numpy's overflow warning
    m_min = float(m_min)
    damped = damped_step_factor(float(law.zeta)) ** 2
    ratios = [0.5 * m_min / float(law.kn) * damped, m_min / 6.0 / float(law.ks)]
    for kn, ks in zip(np.atleast_1d(wall_kn).tolist(), np.atleast_1d(wall_ks).tolist()):
        ratios += [m_min / kn * damped, m_min / 3.0 / ks]
    return math.sqrt(min(ratios))


@numba.njit(inline="always", cache=True)
def linear_law(overlap, v_n, v_t, fs_old, kn, ks, cn, mu, allow_tension, dt):
    """Normal and shear force [N] of one touching contact (see module docstring)."""
    fn = kn * overlap - cn * v_n
    if not allow_tension:  # the same for every contact of a run: a branch always predicted
        fn = max(fn, 0.0)
    fs = fs_old - ks * v_t * dt
    cap = mu * max(fn, 0.0)
    # min/max, not if/else: whether a contact slides is a coin toss the branch predictor
    # loses in a flowing packing (the pair loop at 1e5 grains in the packed silo: -13 %)
    return fn, min(max(fs, -cap), cap)


@numba.njit(inline="always", cache=True)
def hertz_mindlin(kn, ks, r_eff, overlap):
    """The Hertz-Mindlin law as the linear law at its tangent stiffnesses (engine/hertz.py,
    docs/physics.md): ``kn, ks`` hold 2 E* and 8 G* [Pa], ``r_eff`` is R* [m].  Returns
    the normal and shear stiffness S_n = 2 E* a, S_s = 8 G* a [N/m], a = sqrt(R* delta) the
    contact's half-width, and the overlap 2/3 delta [m] that ``linear_law`` multiplies by S_n
    to give Hertz's elastic force 4/3 E* sqrt(R*) delta^(3/2)."""
    a = math.sqrt(r_eff * max(overlap, 0.0))
    return kn * a, ks * a, (2.0 / 3.0) * overlap


@numba.njit(inline="always", cache=True)
def pair_contact(d2, dx, dy, rsum, dvx, dvy, spin, m_eff, r_eff, fs_old, kn, ks, mu, zeta,
                 allow_tension, hertz, dt):
    """One touching grain-grain pair (d2 < rsum^2) from scalars: squared distance [m^2] and
    centre offset j - i (dx, dy) [m], radius sum [m], velocity difference v_j - v_i [m/s], spin
    sum w_i r_i + w_j r_j [m/s], effective mass [kg], effective radius R* [m] (used by the
    Hertz-Mindlin law only, ``hertz``), shear force of the last step [N].
    Returns (F_n, F_s, force on j x, y) [N]."""
    d = math.sqrt(d2)
    inv_d = 1.0 / d
    nx = dx * inv_d
    ny = dy * inv_d
    # velocity of j's contact point relative to i's: v_j + w_j x (-r_j n) - v_i - w_i x (r_i n)
    rvx = dvx + spin * ny
    rvy = dvy - spin * nx
    v_n = rvx * nx + rvy * ny
    v_t = -rvx * ny + rvy * nx
    overlap = rsum - d
    if hertz:  # a compile-time constant (``HERTZ``): no test in the loop
        kn, ks, overlap = hertz_mindlin(kn, ks, r_eff, overlap)
    cn = 2.0 * zeta * math.sqrt(kn * m_eff)
    fn, fs = linear_law(overlap, v_n, v_t, fs_old, kn, ks, cn, mu, allow_tension, dt)
    return fn, fs, fn * nx - fs * ny, fn * ny + fs * nx


@numba.njit(inline="always", cache=True)
def pair_offset(i, j, x, y, radius):
    """Centre offset j - i (dx, dy) [m], its square d2 [m^2] and the radius sum [m] of grains
    i and j: they touch when d2 < rsum^2 (the one touch test of the pair loop, which the list
    test by cells repeats on the same positions)."""
    dx = x[j] - x[i]
    dy = y[j] - y[i]
    return dx, dy, dx * dx + dy * dy, radius[i] + radius[j]


@numba.njit(inline="always", cache=True)
def add_pair(i, k, pair_j, pair_fs, pair_fn, x, y, vx, vy, omega, radius, inv_mass,
             fx, fy, fs_sum, kn, ks, mu, zeta, allow_tension, hertz, dt, sx, sy, ss, branch):
    """Candidate ``k`` of grain ``i``: contact law, history, and its force added to grain j's
    sums and to grain i's running sums ``sx, sy, ss`` (returned).  A candidate that does not
    touch gets F_n = F_s = 0 (a contact that opens forgets its shear force) and adds nothing.

    ``branch`` (a compile-time constant) says how "does not touch" is handled: by a branch
    that skips the law, or by evaluating the law and selecting zeros (no branch to
    mispredict).  Both give the same bits: adding +0.0 to a sum that starts at +0.0 (and so
    is never -0.0) changes nothing."""
    j = numba.uint64(pair_j[k])
    dx, dy, d2, rsum = pair_offset(i, j, x, y, radius)
    touch = d2 < rsum * rsum
    if branch and not touch:
        pair_fs[k] = 0.0
        pair_fn[k] = 0.0
        return sx, sy, ss
    fn, fs, fkx, fky = pair_contact(
        d2, dx, dy, rsum, vx[j] - vx[i], vy[j] - vy[i],
        omega[j] * radius[j] + omega[i] * radius[i], 1.0 / (inv_mass[i] + inv_mass[j]),
        radius[i] * radius[j] / rsum if hertz else 1.0, pair_fs[k], kn, ks, mu, zeta,
        allow_tension, hertz, dt)
    if not branch:  # selects, not branches
        fn = fn if touch else 0.0
        fs = fs if touch else 0.0
        fkx = fkx if touch else 0.0
        fky = fky if touch else 0.0
    pair_fs[k] = fs
    pair_fn[k] = fn
    fx[j] += fkx
    fy[j] += fky
    fs_sum[j] += fs
    return sx - fkx, sy - fky, ss + fs


@numba.njit(inline="always", cache=True)
def strip_pairs(s, strip_start, i_start, i_apart, pair_j, pair_fs, pair_fn,
                x, y, vx, vy, omega, radius, inv_mass, fx, fy, fs_sum,
                kn, ks, mu, zeta, allow_tension, hertz, dt):
    """The candidates of the grains of strip ``s``, grain by grain in list order: contact law,
    and each force added to the sums of both grains (grain i's own pairs summed in
    registers).  Updates the shear history ``pair_fs[k]`` and writes the normal force
    ``pair_fn[k]`` of every candidate (both 0 for one that does not touch).  The force vector
    is not stored: two fewer stores per pair, and ``quantities.grain_contacts`` rebuilds it
    from F_n and F_s.

    Each grain's candidates that touched at the list build come first (up to ``i_apart[i]``;
    ``neighbors``): most of them still touch, so they are evaluated without a branch on the
    touch test; the rest, most of which still do not touch, skip the law by a branch.  Either
    way the branch predictor rarely misses, which it did on about one candidate in four when
    touching and apart candidates came mixed (a large system's contacts are too many for it
    to learn; docs/performance-history.md, fifteenth session)."""
    for i_ in range(strip_start[s], strip_start[s + 1]):
        # unsigned indices: numba then skips its negative-index test on every access (-10 to
        # -25 % time here)
        i = numba.uint64(i_)
        sx = fx[i]
        sy = fy[i]
        ss = fs_sum[i]
        for k in range(i_start[i_], i_apart[i_]):
            sx, sy, ss = add_pair(i, k, pair_j, pair_fs, pair_fn, x, y, vx, vy, omega, radius,
                                  inv_mass, fx, fy, fs_sum, kn, ks, mu, zeta, allow_tension,
                                  hertz, dt, sx, sy, ss, False)
        for k in range(i_apart[i_], i_start[i_ + 1]):
            sx, sy, ss = add_pair(i, k, pair_j, pair_fs, pair_fn, x, y, vx, vy, omega, radius,
                                  inv_mass, fx, fy, fs_sum, kn, ks, mu, zeta, allow_tension,
                                  hertz, dt, sx, sy, ss, True)
        fx[i] = sx
        fy[i] = sy
        fs_sum[i] = ss


HERTZ = False  # compile-time constant of the kernels: True in their Hertz-Mindlin copies


@kernel
def pair_forces(strip_start, blocks, i_start, i_apart, pair_j, pair_fs, pair_fn,
                x, y, vx, vy, omega, radius, inv_mass, fx, fy, fs_sum,
                kn, ks, mu, zeta, allow_tension, dt):
    """Grain-grain contacts of the candidate list, and each grain's sums of their forces.

    Updates the shear history ``pair_fs`` and writes the normal force ``pair_fn`` of every
    candidate, and adds each force to ``fx, fy`` and its shear force to ``fs_sum`` of both
    grains (one evaluation per pair).

    The grains are cut into strips of whole cell rows (``strip_start``, from the rebuild); the
    half stencil reaches at most one row up, so a strip writes only to its own grains and to
    the first row of the next strip.  The even strips run first, then the odd ones: two strips
    of one parity never write the same grain, so they run in parallel with no race, and every
    grain receives its terms in the same order with or without threads (in an even strip its
    own strip's pairs in list order, then the lower strip's; in an odd strip the lower
    strip's, then its own): the same bits for any thread count.  Each grain's
    candidates are listed touching-at-the-build first (``i_apart``, ``strip_pairs``).  Each even
    strip first zeroes the sums of its grains and of the next strip's.

    ``blocks`` cuts the strips into runs of consecutive strips, one per thread (strips
    blocks[b]:blocks[b+1]; ``NeighborList.blocks``): each thread works the even, then the odd
    strips of its own run, so a grain's state stays in one core's cache from step to step and
    only the rows at the ends of a run are written by two threads.  The cut changes no
    result."""
    n_strips = strip_start.shape[0] - 1
    for b in prange(blocks.shape[0] - 1):
        for s in range(blocks[b] + (blocks[b] & 1), blocks[b + 1], 2):  # even strips
            for g in range(strip_start[s], strip_start[min(s + 2, n_strips)]):
                fx[g] = 0.0
                fy[g] = 0.0
                fs_sum[g] = 0.0
            strip_pairs(s, strip_start, i_start, i_apart, pair_j, pair_fs, pair_fn, x, y,
                        vx, vy, omega, radius, inv_mass, fx, fy, fs_sum, kn, ks, mu, zeta,
                        allow_tension, HERTZ, dt)
    for b in prange(blocks.shape[0] - 1):
        for s in range(blocks[b] + 1 - (blocks[b] & 1), blocks[b + 1], 2):  # odd strips
            strip_pairs(s, strip_start, i_start, i_apart, pair_j, pair_fs, pair_fn,
                        x, y, vx, vy, omega, radius, inv_mass, fx, fy, fs_sum,
                        kn, ks, mu, zeta, allow_tension, HERTZ, dt)


@numba.njit(inline="always", cache=True)
def closest_point(px, py, ax, ay, bx, by):
    """Closest point of segment A-B to P, and where it lies: 0 on the face, 1 at A, 2 at B
    (an end also where P is exactly on the face's normal there: ``wall_contact`` decides)."""
    ux = bx - ax
    uy = by - ay
    s = ((px - ax) * ux + (py - ay) * uy) / (ux * ux + uy * uy)
    if s <= 0.0:
        return ax, ay, 1
    if s >= 1.0:
        return bx, by, 2
    return ax + s * ux, ay + s * uy, 0


@numba.njit(inline="always", cache=True)
def wall_contact(px, py, pvx, pvy, pomega, r, m, ax, ay, bx, by, w_vx, w_vy, w_kn, w_ks, w_mu,
                 active, cap_a, cap_b, gax, gay, gbx, gby, one_sided, fs_old, fn_old, zeta,
                 allow_tension, hertz, dt):
    """One grain-wall candidate from scalars: the grain at (px, py) [m] with velocity
    (pvx, pvy) [m/s], spin ``pomega`` [rad/s], radius ``r`` [m] and mass ``m`` [kg]; the wall
    from (ax, ay) to (bx, by) [m] with its velocity, stiffnesses, friction and flags (one
    entry of each ``Walls.arrays()``); the candidate's shear and normal force of the last step
    [N].  Returns (F_n, F_s, force on the grain x, y) [N], all zero when they do not touch.
    ``cap_a, cap_b``: what the ends are (``walls.END_*``); ``gax, gay`` / ``gbx, gby``: the
    guards of the caps at A / B (``Walls.guard``).
    Scalars only, no arrays: numba then keeps no reference counts in the caller's loop.

    n points from the closest point of the wall to the grain's centre.  One-sided walls: a
    contact on the face that already exists (non-zero force at the last step) keeps the wall's
    inner normal and the overlap r - (signed distance) even after the centre has been pressed
    past the line (soft contacts, fast impacts), so the grain is pushed back, not through; a new
    contact can only start from the inner side."""
    if not active:
        return 0.0, 0.0, 0.0, 0.0
    cx, cy, where = closest_point(px, py, ax, ay, bx, by)
    if where != 0 and (cap_a if where == 1 else cap_b) == END_FACE \
            and (px - cx) * (bx - ax) + (py - cy) * (by - ay) == 0.0:
        where = 0  # the centre is on the normal at a joint this face closes (walls.py)
    if where == 0 and one_sided:
        ux = bx - ax
        uy = by - ay
        length = math.sqrt(ux * ux + uy * uy)
        nx = -uy / length
        ny = ux / length
        d = (px - cx) * nx + (py - cy) * ny
        existing = fn_old != 0.0 or fs_old != 0.0
        if not (d < r and (d > 0.0 or existing)):
            return 0.0, 0.0, 0.0, 0.0
    else:
        dx = px - cx
        dy = py - cy
        # an end counts where it is capped, at a convex corner only in the wedge its guard
        # (g*) leaves (walls.py)
        counts = (where == 0
                  or (where == 1 and cap_a == END_CAP and dx * gax + dy * gay <= 0.0)
                  or (where == 2 and cap_b == END_CAP and dx * gbx + dy * gby <= 0.0))
        d = math.sqrt(dx * dx + dy * dy)
        if not (counts and 0.0 < d < r):
            return 0.0, 0.0, 0.0, 0.0
        nx = dx / d
        ny = dy / d
    # grain contact point velocity v + w x (-r n), relative to the wall's velocity
    rvx = pvx + pomega * r * ny - w_vx
    rvy = pvy - pomega * r * nx - w_vy
    v_n = rvx * nx + rvy * ny
    v_t = -rvx * ny + rvy * nx
    overlap = r - d
    if hertz:  # a compile-time constant (``HERTZ``); a flat wall: R* = r
        w_kn, w_ks, overlap = hertz_mindlin(w_kn, w_ks, r, overlap)
    cn = 2.0 * zeta * math.sqrt(w_kn * m)
    fn, fs = linear_law(overlap, v_n, v_t, fs_old, w_kn, w_ks, cn, w_mu, allow_tension, dt)
    return fn, fs, fn * nx - fs * ny, fn * ny + fs * nx


# the same loop for the Hertz-Mindlin law (hertz_mindlin): HERTZ bound to True (last in the
# module: the copy sees the module's names as they are when it is made)
pair_forces_hertz = pair_forces.variant("_hertz", HERTZ=True)
