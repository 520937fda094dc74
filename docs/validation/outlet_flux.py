"""Packing fraction and speed of the grains at the outlet of the Beverloo case during steady
discharge, at a fill height of H/B given on the command line (docs/validation.md, section 5,
sixth session).

    python docs/validation/outlet_flux.py 1      # H = B
    python docs/validation/outlet_flux.py 2      # H = 2 B

The silo, grains and re-insertion are those of ``silodem validate`` (``validate.beverloo``,
D = 9 d, B = 76.5 d, seed 1, 3 s of discharge).  From 0.5 s after the gate opens, at the end
of every check interval: for the grains whose centres lie over the outlet (|x - B/2| < D/2) in
bands of height around the outlet line (-d..d) and above it (d..3d, 3d..6d), the area
fraction phi and the area-weighted downward speed v, and the mean speed of those in the
middle third of the outlet.  Prints one JSON line with the time averages and the flux they
give, rho_s phi v D t [kg/s], beside the steady rate W measured from the discharged mass."""

import json
import sys

import numpy as np

from silodem.silo.procedure import SiloRun
from silodem.validate import beverloo as bev

H_over_B = float(sys.argv[1])
cfg = bev.config(9.0, H_over_B, 3.0, seed=1)
run = SiloRun(cfg)
D, B, d = cfg.silo.outlet_width, cfg.silo.cell_width, bev.D_GRAIN
xc = B / 2
BANDS = {"-1d..+1d": (-d, d), "+1d..+3d": (d, 3 * d), "+3d..+6d": (3 * d, 6 * d)}
rows = []

def sample(r):
    if r.state.phase != "discharge" or r.sim.time - r.events["discharge_start_time"] < 0.5:
        return
    p = r.sim.particles
    n = p.n
    x, y, vy, rad = p.x[:n], p.y[:n], p.vy[:n], p.radius[:n]
    row = {}
    for name, (y0, y1) in BANDS.items():
        inside = (np.abs(x - xc) < D / 2) & (y > y0) & (y < y1)
        area = np.pi * rad[inside] ** 2
        phi = area.sum() / (D * (y1 - y0))
        v = -(area * vy[inside]).sum() / max(area.sum(), 1e-30)  # area-weighted, downward +
        centre = inside & (np.abs(x - xc) < D / 6)
        vc = -vy[centre].mean() if centre.any() else np.nan
        row[name] = (phi, v, vc)
    rows.append(row)

run.chunk_hooks.append(sample)
run.run()
rate = bev.rate_of(*bev.discharge_curve(run))
out = {"H/B": H_over_B, "W": rate.rate, "err": rate.err, "samples": len(rows)}
for name in BANDS:
    phi, v, vc = np.nanmean([r[name] for r in rows], axis=0)
    out[name] = {"phi": round(float(phi), 4), "v_mean": round(float(v), 4),
                 "v_centre": round(float(vc), 4),
                 "rho_s*phi*v*D*t": round(float(cfg.material.density * phi * v * D
                                                * cfg.material.thickness), 4)}
print(json.dumps(out))
