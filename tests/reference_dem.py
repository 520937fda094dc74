"""A deliberately simple reference DEM: every pair checked (O(N^2)), plain Python loops, history
in a dict keyed by grain uids.  Same equations as the paper (and docs/physics.md), written
independently of the numba kernels so that the fast paths can be compared with it."""

from __future__ import annotations

import math

import numpy as np


def _stiffness(overlap, r_eff, kn, ks, hertz):
    """(elastic normal force [N], normal and shear stiffness [N/m]).  Linear: kn delta, kn,
    ks.  Hertz-Mindlin with kn = 2 E*, ks = 8 G*: Hertz's 4/3 E* sqrt(R*) delta^(3/2) and
    Mindlin's 2 E* a, 8 G* a with a = sqrt(R* delta) (Johnson, Contact Mechanics, 1985)."""
    if not hertz:
        return kn * overlap, kn, ks
    e_star, g_star, a = kn / 2, ks / 8, math.sqrt(r_eff * overlap)
    return 4 / 3 * e_star * math.sqrt(r_eff) * overlap**1.5, 2 * e_star * a, 8 * g_star * a


def _law(f_elastic, vn, vt, fs_old, ks, cn, mu, tension, dt):
    fn = f_elastic - cn * vn
    if fn < 0.0 and not tension:
        fn = 0.0
    fs = fs_old - ks * vt * dt
    cap = mu * fn if fn > 0.0 else 0.0
    return fn, max(-cap, min(cap, fs))


class ReferenceDEM:
    """Grains (x, y, vx, vy, w, r, m) and two-sided wall segments; gravity along -y."""

    def __init__(self, x, y, vx, vy, w, r, m, uid, walls, kn, ks, mu, zeta, dt, g,
                 tension=False, hertz=False):
        self.x, self.y, self.vx, self.vy, self.w = (np.array(a, float) for a in (x, y, vx, vy, w))
        self.r, self.m = np.array(r, float), np.array(m, float)
        self.uid = list(uid)
        self.walls = walls  # list of (ax, ay, bx, by, kn, ks, mu)
        self.kn, self.ks, self.mu, self.zeta, self.dt, self.g = kn, ks, mu, zeta, dt, g
        self.tension, self.hertz = tension, hertz
        self.hist: dict[tuple, float] = {}

    def forces(self):
        n = len(self.x)
        fx, fy, tq = np.zeros(n), np.zeros(n), np.zeros(n)
        new_hist = {}
        for i in range(n):
            for j in range(i + 1, n):
                dx, dy = self.x[j] - self.x[i], self.y[j] - self.y[i]
                d = math.hypot(dx, dy)
                if d >= self.r[i] + self.r[j]:
                    continue
                nx, ny = dx / d, dy / d
                # contact point velocities: v + w x (p - centre)
                wri, wrj = self.w[i] * self.r[i], self.w[j] * self.r[j]
                vci = (self.vx[i] - wri * ny, self.vy[i] + wri * nx)
                vcj = (self.vx[j] + wrj * ny, self.vy[j] - wrj * nx)
                rv = (vcj[0] - vci[0], vcj[1] - vci[1])
                vn = rv[0] * nx + rv[1] * ny
                vt = -rv[0] * ny + rv[1] * nx
                meff = self.m[i] * self.m[j] / (self.m[i] + self.m[j])
                r_eff = self.r[i] * self.r[j] / (self.r[i] + self.r[j])
                f_el, sn, ss = _stiffness(self.r[i] + self.r[j] - d, r_eff, self.kn, self.ks,
                                          self.hertz)
                cn = 2 * self.zeta * math.sqrt(sn * meff)
                key = (min(self.uid[i], self.uid[j]), max(self.uid[i], self.uid[j]))
                fn, fs = _law(f_el, vn, vt, self.hist.get(key, 0.0), ss, cn, self.mu,
                              self.tension, self.dt)
                if fn != 0.0 or fs != 0.0:
                    new_hist[key] = fs
                Fx, Fy = fn * nx - fs * ny, fn * ny + fs * nx
                fx[j] += Fx
                fy[j] += Fy
                fx[i] -= Fx
                fy[i] -= Fy
                tq[i] += -self.r[i] * fs
                tq[j] += -self.r[j] * fs
        for i in range(n):
            for w, (ax, ay, bx, by, kn, ks, mu) in enumerate(self.walls):
                ux, uy = bx - ax, by - ay
                along = ((self.x[i] - ax) * ux + (self.y[i] - ay) * uy) / (ux * ux + uy * uy)
                s = min(1.0, max(0.0, along))
                cx, cy = ax + s * ux, ay + s * uy
                dx, dy = self.x[i] - cx, self.y[i] - cy
                d = math.hypot(dx, dy)
                if d >= self.r[i] or d == 0.0:
                    continue
                nx, ny = dx / d, dy / d
                wri = self.w[i] * self.r[i]
                vc = (self.vx[i] + wri * ny, self.vy[i] - wri * nx)
                vn = vc[0] * nx + vc[1] * ny
                vt = -vc[0] * ny + vc[1] * nx
                f_el, sn, ss = _stiffness(self.r[i] - d, self.r[i], kn, ks, self.hertz)
                cn = 2 * self.zeta * math.sqrt(sn * self.m[i])
                key = ("wall", self.uid[i], w)
                fn, fs = _law(f_el, vn, vt, self.hist.get(key, 0.0), ss, cn, mu, self.tension,
                              self.dt)
                if fn != 0.0 or fs != 0.0:
                    new_hist[key] = fs
                fx[i] += fn * nx - fs * ny
                fy[i] += fn * ny + fs * nx
                tq[i] += -self.r[i] * fs
        self.hist = new_hist
        return fx, fy, tq

    def step(self):
        fx, fy, tq = self.forces()
        inertia = 0.5 * self.m * self.r**2
        self.vx += fx / self.m * self.dt
        self.vy += (fy / self.m - self.g) * self.dt
        self.w += tq / inertia * self.dt
        self.x += self.vx * self.dt
        self.y += self.vy * self.dt
        return fx, fy, tq
