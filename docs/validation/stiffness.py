"""The Beverloo case's steady rate with stiffer contacts (docs/validation.md, section 5, eleventh
session): is the rate's growth with the fill height a property of soft grains?

    python docs/validation/stiffness.py 100 1      # k_n = k_s = 100 x 8e4 N/m, H = B
    python docs/validation/stiffness.py 100 2      # the same, H = 2 B

The silo, grains, fill and re-insertion are those of ``silodem validate``
(``validate.beverloo``, D = 9 d, B = 76.5 d), seed 1, 3 s of discharge; only the contact
stiffness of grains and walls is multiplied by the first argument.  The time step follows
(dt = 0.2 dt_crit, dt_crit ~ 1/sqrt(k_n)), so a run at 100 x costs about ten times one at 1 x
(about 9 min at H = B and 25 min at 2 B on one core).  Prints one JSON line: the factor, H/B,
the steady rate W and its batch-means error [kg/s], the grains that passed."""

import json
import sys

from silodem.config import Config
from silodem.validate import beverloo as bev

factor, H_over_B = float(sys.argv[1]), float(sys.argv[2])
raw = bev.config(9.0, H_over_B, 3.0, seed=1).model_dump()
for part in ("material", "walls"):
    raw[part]["kn"] *= factor
    raw[part]["ks"] *= factor
raw["name"] += f"-k{factor:g}"
cfg = Config.model_validate(raw)
print(json.dumps({"k_factor": factor, "H/B": H_over_B, **bev.variant_rate(cfg)}))
