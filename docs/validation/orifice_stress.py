"""The stress above the outlet of the Beverloo case during steady discharge, at a fill height of
H/B given on the command line (docs/validation.md, section 5, fifth session).

    python docs/validation/orifice_stress.py 1      # H = B
    python docs/validation/orifice_stress.py 2      # H = 2 B
    python docs/validation/orifice_stress.py 6 39.78   # H = 6 B in a silo of B = 39.78 d

The silo, grains and re-insertion are those of ``silodem validate`` (``validate.beverloo``,
D = 9 d, seed 1, 3 s of discharge; B = 76.5 d, or the width B/d given as a second argument, e.g.
39.78 = 1.02 (D + 30 d), the narrowest the issue allows).  From 0.5 s after the gate opens, at
the end of every check interval: the Love-Weber stress (``measure.stress``) of the grains whose
centres lie in boxes of width D over the outlet (heights 0-D, D-2D, 2D-4D above the floor) and
in a box of the same size in the corner next to the left wall, and the mean vertical pressure
on the two floor segments.  Prints one JSON line: the steady rate and the time-averaged
stresses [Pa] (compression positive)."""

import json
import sys

import numpy as np

from silodem.engine import quantities as q
from silodem.measure.stress import contact_points_walls, grain_moments, region_stress
from silodem.silo.procedure import SiloRun
from silodem.validate import beverloo as bev

H_over_B = float(sys.argv[1])
if len(sys.argv) > 2:  # another cell width: every width in validate.beverloo comes from here
    B_over_d = float(sys.argv[2])
    bev.cell_width = lambda D_over_d=None: B_over_d * bev.D_GRAIN
cfg = bev.config(9.0, H_over_B, 3.0, seed=1)
run = SiloRun(cfg)
D, B, t = cfg.silo.outlet_width, cfg.silo.cell_width, cfg.material.thickness
xc = B / 2
BOXES = {"outlet 0-D": (xc - D / 2, xc + D / 2, 0.0, D),
         "outlet D-2D": (xc - D / 2, xc + D / 2, D, 2 * D),
         "outlet 2D-4D": (xc - D / 2, xc + D / 2, 2 * D, 4 * D),
         "corner 0-D": (0.05, 0.05 + D, 0.0, D)}
samples = []


def sample(r: SiloRun) -> None:
    if r.state.phase != "discharge" or r.sim.time - r.events["discharge_start_time"] < 0.5:
        return
    sim, p, w = r.sim, r.sim.particles, r.sim.walls
    n = p.n
    x, y, rad = p.x[:n], p.y[:n], p.radius[:n]
    gc, wc = q.grain_contacts(sim), q.wall_contacts(sim)
    cx, cy = contact_points_walls(x, y, wc.grain, wc.wall, w.ax, w.ay, w.bx, w.by)
    M = grain_moments(n, x, y, rad, gc.i, gc.j, gc.fx, gc.fy, wc.grain, cx, cy, wc.fx, wc.fy)
    row = {}
    for name, (x0, x1, y0, y1) in BOXES.items():
        inside = (x > x0) & (x < x1) & (y > y0) & (y < y1)
        row[name] = region_stress(M, inside, (x1 - x0) * (y1 - y0), t)[:2]
    on_walls = q.force_on_walls(sim)
    floor = [w.names.index("left_floor"), w.names.index("right_floor")]
    row["floor"] = -on_walls[floor, 1].sum() / ((B - D) * t)
    samples.append(row)


run.chunk_hooks.append(sample)
run.run()
rate = bev.rate_of(*bev.discharge_curve(run))
out = {"H/B": H_over_B, "rate kg/s": rate.rate, "err": rate.err, "samples": len(samples),
       "floor pressure": float(np.mean([s["floor"] for s in samples]))}
for name in BOXES:
    sxx, syy = np.mean([s[name] for s in samples], axis=0)
    out[name] = {"sigma_xx": float(sxx), "sigma_yy": float(syy)}
print(json.dumps(out))
