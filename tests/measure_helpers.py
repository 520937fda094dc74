"""A tiny hopper silo that fills, settles and discharges in a few seconds of wall time."""

from __future__ import annotations

from silodem.config import (
    Config,
    Discharge,
    Fill,
    Material,
    Measure,
    Settle,
    Silo,
    WallMaterial,
)


def tiny_hopper_config(**measure) -> Config:
    return Config(
        name="tiny-hopper", seed=7,
        material=Material(density=800.0, radius_min=0.045, radius_max=0.055, kn=2e6, ks=2e6,
                          friction_deg=25.0, restitution=0.5),
        walls=WallMaterial(kn=2e6, ks=2e6, friction_deg=24.0),
        silo=Silo(kind="hopper", cell_width=1.2, wall_height=2.4, outlet_width=0.4,
                  hopper_angle_from_horizontal_deg=50.0),
        fill=Fill(method="pour", n_particles=150, rate=600.0, band_height=0.4),
        settle=Settle(threshold=2e-3, max_time=1.5, min_time=0.3),
        discharge=Discharge(stop_fraction=0.9, max_time=4.0),
        measure=Measure(window=0.3, discharge_delay=0.2, **measure),
    )
