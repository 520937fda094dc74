"""The Beverloo case's fill-height check under the Hertz-Mindlin law (docs/validation.md,
section 5, twenty-second session): does the rate's growth with the fill height belong to the
linear law?

    python docs/validation/hertz_height.py 1e9 1        # E = 1 GPa, H = B, seed 1
    python docs/validation/hertz_height.py 1e9 2 2      # the same, H = 2 B, seed 2

The silo, grains, fill and re-insertion are those of ``silodem validate``
(``validate.beverloo``, D = 9 d, B = 76.5 d), 3 s of discharge; only the contact law changes:
``material.contact_model = "hertz_mindlin"`` with Young's modulus E (first argument) and
Poisson's ratio 0.3 for the grains, steel walls (E = 200 GPa, 0.3), the same friction and
restitution.  With E = 1 GPa the tangent stiffness 2 E* sqrt(R* delta) is 1.9-2.2e5 N/m at
the 1.5-2.4 N of a contact near the floor (``engine.hertz``), two to three times the linear
case's k_n = 8e4 N/m.  The time step is the law's own (``silo.materials``: the stiffness at
the design overlaps, with the impact of a grain falling from the wall top), about 3e-6 s, so a
run costs 8-9 min at H = B and 21-22 min at 2 B on one core.  Prints one JSON line: E, H/B,
the seed, dt, the steady rate W and its batch-means error [kg/s], the grains that passed."""

import json
import sys

from silodem.config import Config
from silodem.validate import beverloo as bev

E, H_over_B = float(sys.argv[1]), float(sys.argv[2])
seed = int(sys.argv[3]) if len(sys.argv) > 3 else 1
raw = bev.config(9.0, H_over_B, 3.0, seed=seed).model_dump()
for part in ("material", "walls"):
    raw[part]["kn"] = raw[part]["ks"] = None
raw["material"].update(contact_model="hertz_mindlin", young_modulus=E, poisson_ratio=0.3)
raw["walls"].update(young_modulus=2e11, poisson_ratio=0.3)
raw["name"] += f"-hertz{E:g}"
cfg = Config.model_validate(raw)
print(json.dumps({"E": E, "H/B": H_over_B, "seed": seed, **bev.variant_rate(cfg)}))
