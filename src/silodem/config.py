"""Run configuration: the validated schema of a silodem TOML file.

Every quantity is in SI units; the unit of each key is written in its description.
Unknown keys are errors (``extra="forbid"``), so a typo never silently falls back to a default.

Stiffness convention (PFC2D's, Itasca manual "Contact models"): ``material.kn`` and
``walls.kn`` are the stiffnesses of the *bodies*; the stiffness of a contact between two
bodies a and b is the series value ``k = k_a k_b / (k_a + k_b)``.  Two equal grains of
stiffness k therefore touch with stiffness k/2.  ``material.contact_model = "hertz_mindlin"``
takes Young's moduli and Poisson's ratios of grains and walls instead (docs/physics.md); the
keys of the law not chosen are refused, not ignored (``law_keys``).
"""

from __future__ import annotations

import math
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

MAX_NAME_BYTES = 200  # a folder name's limit is 255 bytes; room for '-quick', '.tmp', ...


def folder_name(value: str, key: str) -> str:
    """``value`` when it can name one folder (a run's default ``runs/<name>``, a study's
    ``studies/<name>``); ValueError otherwise."""
    if value in (".", "..") or "/" in value or "\\" in value or not value.isprintable():
        raise ValueError(f"{key} {value!r} cannot name a results folder: give one without '/', "
                         "'\\' or control characters, and not '.' or '..'")
    if not value.strip():
        raise ValueError(f"{key} {value!r} is blank: give a name for the results folder")
    size = len(value.encode("utf-8"))
    if size > MAX_NAME_BYTES:  # (it failed later, blamed on --out, with a folder made)
        raise ValueError(f"{key} is {size} bytes long; at most {MAX_NAME_BYTES}, as it names "
                         "a results folder")
    return value


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", validate_assignment=True, allow_inf_nan=False,
                              strict=True)


def _law_field(body: str, key: str):
    """The field of one contact-law key of a ``body`` ("grain" or "wall"): unset by default,
    required or refused by ``law_keys`` according to ``material.contact_model``."""
    text = {"kn": ("normal stiffness [N/m] (contact = springs in series; linear law)", 0),
            "ks": ("shear stiffness [N/m] (contact = springs in series; linear law)", 0),
            "young_modulus": ("Young's modulus E [Pa] (Hertz-Mindlin law)", 0),
            "poisson_ratio": ("Poisson's ratio nu [-] (Hertz-Mindlin law)", 1)}
    meaning, is_ratio = text[key]
    limits = {"ge": 0, "le": 0.5} if is_ratio else {"gt": 0}
    return Field(None, description=f"{body} {meaning}", **limits)


class Material(_Strict):
    """Grain properties (the paper's Tables 1-2, column "Grain-Grain")."""

    density: float = Field(gt=0, description="grain density rho [kg/m^3]")
    radius_min: float = Field(gt=0, description="smallest grain radius [m] (with "
                              "radius_distribution = 'discrete': radii's, when left out)")
    radius_max: float = Field(gt=0, description="largest grain radius [m] (with "
                              "radius_distribution = 'discrete': radii's, when left out)")
    radius_distribution: Literal["uniform", "uniform_mass", "discrete"] = Field(
        "uniform", description="'uniform': radii uniform in [radius_min, radius_max] (Tables "
        "1-2); 'uniform_mass': equal mass of grains in equal radius intervals of that range; "
        "'discrete': the sizes of radii (radius_min and radius_max, when unset, their "
        "smallest and largest)"
    )
    radii: list[float] | None = Field(
        None, description="the grain radii of radius_distribution = 'discrete' [m]"
    )
    radius_shares: list[float] | None = Field(
        None, description="each of radii's share of the grains by number, summing to 1 [-]; "
        "unset: equal shares"
    )
    thickness: float = Field(1.0, gt=0, description="out-of-plane thickness t of a disk [m]")
    contact_model: Literal["linear", "hertz_mindlin"] = Field(
        "linear", description="'linear': the paper's springs kn, ks; 'hertz_mindlin': Hertz's "
        "normal and Mindlin's no-slip shear stiffness from young_modulus and poisson_ratio"
    )
    kn: float | None = _law_field("grain", "kn")
    ks: float | None = _law_field("grain", "ks")
    young_modulus: float | None = _law_field("grain", "young_modulus")
    poisson_ratio: float | None = _law_field("grain", "poisson_ratio")
    friction_deg: float = Field(ge=0, lt=90, description="grain-grain friction angle phi_G [deg]")
    restitution: float | None = Field(
        0.5, gt=0, le=1,
        description="normal restitution coefficient e of a contact [-], which sets the "
                    "damping ratio; without tension (the default) a contact ends as its force "
                    "vanishes and rebounds a little faster (0.55 for 0.5; docs/physics.md)",
    )
    damping_ratio: float | None = Field(
        None, ge=0, lt=1,
        description="normal critical-damping ratio zeta [-]; replaces restitution's e",
    )
    local_damping: float = Field(
        0.0, ge=0, lt=1, description="PFC local (non-viscous) damping coefficient alpha [-]"
    )
    allow_tension: bool = Field(
        False, description="allow an attractive normal force while a contact separates"
    )

    @model_validator(mode="before")
    @classmethod
    def _damping_ratio_replaces_restitution(cls, data: Any) -> Any:
        """A damping_ratio beside the default restitution (a scenario file's e = 0.5 and a
        ``--set material.damping_ratio``) leaves restitution unset, so that the resolved and
        saved config show only the damping in force; another restitution is refused below."""
        default_e = cls.model_fields["restitution"].default
        if (isinstance(data, dict) and data.get("damping_ratio") is not None
                and data.get("restitution", default_e) == default_e):
            data = {**data, "restitution": None}
        return data

    @model_validator(mode="before")
    @classmethod
    def _discrete_bounds(cls, data: Any) -> Any:
        """With discrete radii, radius_min and radius_max default to their smallest and
        largest, so that a config gives each size once."""
        if (isinstance(data, dict) and data.get("radius_distribution") == "discrete"
                and isinstance(data.get("radii"), list) and data["radii"]
                and all(isinstance(r, (int, float)) for r in data["radii"])):
            data = {"radius_min": min(data["radii"]), "radius_max": max(data["radii"]),
                    **data}
        return data

    @model_validator(mode="after")
    def _check(self) -> Material:
        self._check_sizes()
        if self.radius_max < self.radius_min:
            raise ValueError(
                f"material.radius_max ({self.radius_max}) must be >= material.radius_min "
                f"({self.radius_min})"
            )
        law_keys(self, "material", self.contact_model)
        if self.damping_ratio is not None and self.restitution is not None:
            raise ValueError(
                f"material.restitution ({self.restitution}) and material.damping_ratio "
                f"({self.damping_ratio}) both set the normal damping; give one of them"
            )
        return self

    def _check_sizes(self) -> None:
        """The keys of the discrete distribution: given together with it, and consistent."""
        if self.radius_distribution != "discrete":
            for key in ("radii", "radius_shares"):
                if getattr(self, key) is not None:
                    raise ValueError(f"material.{key} is read only with "
                                     "radius_distribution = 'discrete'; set that too, or "
                                     f"remove material.{key}")
            return
        if not self.radii:
            raise ValueError("material.radius_distribution = 'discrete' needs the grain radii: "
                             "give material.radii, e.g. [0.01, 0.02]")
        if any(not (math.isfinite(r) and r > 0) for r in self.radii):
            raise ValueError(f"material.radii must hold positive radii [m], not {self.radii}")
        if len(set(self.radii)) != len(self.radii):
            raise ValueError(f"material.radii must not repeat a radius: {self.radii}")
        bounds = {"radius_min": min(self.radii), "radius_max": max(self.radii)}
        wrong = {k: v for k, v in bounds.items() if getattr(self, k) != v}
        if wrong:
            given = " and ".join(f"material.{k} ({getattr(self, k)})" for k in wrong)
            fix = " and ".join(f"material.{k} = {v}" for k, v in wrong.items())
            raise ValueError(f"{given} must be the smallest and largest of material.radii "
                             f"{self.radii}: set {fix} too")
        s = self.radius_shares
        if s is None:
            return
        if len(s) != len(self.radii):
            raise ValueError(f"material.radius_shares has {len(s)} values for "
                             f"{len(self.radii)} radii; give one share per radius")
        if any(not (math.isfinite(v) and v > 0) for v in s):
            raise ValueError(f"material.radius_shares must hold positive shares, not {s}")
        if abs(sum(s) - 1.0) > 1e-9:
            raise ValueError(f"material.radius_shares sum to {sum(s):.12g}, not 1: give "
                             "each radius's share of the grains by number")

    @property
    def normal_damping_ratio(self) -> float:
        """zeta from ``damping_ratio`` if set, else from ``restitution`` (see physics docs):
        -ln e / sqrt(pi^2 + ln^2 e) for the linear law, sqrt(5/6) times that for the
        Hertz-Mindlin law (``engine.hertz``)."""
        from silodem.engine import contact, hertz

        if self.damping_ratio is not None:
            return self.damping_ratio
        e = 1.0 if self.restitution is None else self.restitution
        law = hertz if self.contact_model == "hertz_mindlin" else contact
        return law.damping_ratio_from_restitution(e)


LAW_KEYS = {"linear": ("kn", "ks"), "hertz_mindlin": ("young_modulus", "poisson_ratio")}


def law_keys(section: BaseModel, name: str, model: str) -> None:
    """Raise ValueError unless ``section`` (``material`` or ``walls``) gives exactly the keys
    of contact model ``model`` (``LAW_KEYS``): none missing, none of the other law's."""
    for key in LAW_KEYS[model]:
        if getattr(section, key) is None:
            raise ValueError(f"{name}.{key} is required by material.contact_model = '{model}'")
    for other, keys in LAW_KEYS.items():
        for key in keys:
            if other != model and getattr(section, key) is not None:
                raise ValueError(
                    f"{name}.{key} belongs to the '{other}' law, but material.contact_model is "
                    f"'{model}' (which takes {name}.{' and '.join(LAW_KEYS[model])}); remove it")


class WallMaterial(_Strict):
    """Wall properties (Tables 1-2, column "Grain-Wall")."""

    kn: float | None = _law_field("wall", "kn")
    ks: float | None = _law_field("wall", "ks")
    young_modulus: float | None = _law_field("wall", "young_modulus")
    poisson_ratio: float | None = _law_field("wall", "poisson_ratio")
    friction_deg: float = Field(ge=0, lt=90, description="grain-wall friction angle phi_P [deg]")
    hopper_friction_deg: float | None = Field(
        None, ge=0, lt=90, description="grain-wall friction angle of the two hopper walls "
        "phi_Ph [deg] (a hopper lined otherwise than the cell); unset: friction_deg; a flat "
        "silo has no hopper walls and does not read it")

    def hopper_mu(self) -> float:
        """tan of the hopper walls' friction angle [-]: hopper_friction_deg, else
        friction_deg."""
        deg = self.friction_deg if self.hopper_friction_deg is None else self.hopper_friction_deg
        return math.tan(math.radians(deg))


class Silo(_Strict):
    """Silo geometry.  z = 0 is the outlet (gate) level; x = 0 is the left wall of the cell."""

    kind: Literal["flat", "hopper"] = Field(description="flat-bottomed, or cell + planar hopper")
    cell_width: float = Field(gt=0, description="cell width B [m]")
    wall_height: float = Field(gt=0, description="height of the top of the vertical walls [m]")
    outlet_width: float = Field(gt=0, description="outlet (slot) width D, centred [m]")
    hopper_angle_from_horizontal_deg: float = Field(
        45.0,
        gt=0,
        lt=90,
        description="hopper wall slope theta measured FROM THE HORIZONTAL [deg] (the paper's "
        "'slope'; hopper theory uses 90 - theta, measured from the vertical); kind 'hopper' "
        "only, a flat silo ignores it",
    )

    @model_validator(mode="after")
    def _check(self) -> Silo:
        if self.outlet_width >= self.cell_width:
            raise ValueError(
                f"silo.outlet_width ({self.outlet_width}) must be smaller than silo.cell_width "
                f"({self.cell_width})"
            )
        theta = self.hopper_angle_from_horizontal_deg
        if self.kind == "hopper" and not 90.0 - theta < 90.0:  # (the hopper theory's angle
            # from the vertical would be 90 deg: report.html was not written)
            raise ValueError(
                f"silo.hopper_angle_from_horizontal_deg = {theta:.3g} deg cannot be told from a "
                "flat floor (90 deg - theta, the angle from the vertical, is 90 deg in floating "
                "point); give silo.kind = 'flat', or a steeper hopper")
        if self.kind == "hopper" and self.hopper_height >= self.wall_height:
            raise ValueError(
                f"silo.wall_height ({self.wall_height}) must exceed the hopper height "
                f"{self.hopper_height:.4g} m given by cell_width, outlet_width and the angle"
            )
        return self

    @property
    def hopper_height(self) -> float:
        """Height of the cell-hopper junction above the outlet [m] (0 for a flat bottom)."""
        if self.kind == "flat":
            return 0.0
        theta = math.radians(self.hopper_angle_from_horizontal_deg)
        return 0.5 * (self.cell_width - self.outlet_width) * math.tan(theta)


class Fill(_Strict):
    """How the silo is filled (Fig. 1: generation, then settling under gravity)."""

    method: Literal["pour", "loose"] = Field(
        "pour",
        description="'pour': rain grains from a band under the top of the walls at `rate`; "
        "'loose': place all grains at once on a jittered lattice, then let them fall",
    )
    n_particles: int = Field(
        gt=0, le=10_000_000, description="number of grains to put in the silo [-]"
    )
    rate: float = Field(
        200.0, gt=0,
        description="pouring rate [grains/s] (method 'pour'); an upper bound: a batch places "
        "only the grains that find room in the band",
    )
    band_height: float = Field(
        0.6, gt=0, description="height of the pouring band under the wall top [m]"
    )
    initial_speed: float = Field(0.0, ge=0, description="downward speed of poured grains [m/s]")
    max_time: float = Field(60.0, gt=0, description="give up pouring after this time [s]")


class Settle(_Strict):
    """Equilibrium criterion that ends a settling phase (after filling)."""

    criterion: Literal["force_ratio", "kinetic_energy"] = Field(
        "force_ratio",
        description="'force_ratio': mean unbalanced force / mean contact force (PFC's ratio); "
        "'kinetic_energy': mean kinetic energy per grain [J]",
    )
    threshold: float = Field(1e-3, gt=0, description="settled when the criterion is below this "
                             "([-] for force_ratio, [J] for kinetic_energy)")
    max_time: float = Field(10.0, gt=0, description="stop settling after this time [s] (warns; "
                            "checked every 0.05 s of simulated time)")
    min_time: float = Field(0.2, ge=0, description="settle at least this long [s]")

    @model_validator(mode="after")
    def _check(self) -> Settle:
        if self.min_time > self.max_time:
            raise ValueError(f"settle.min_time ({self.min_time}) must not exceed "
                             f"settle.max_time ({self.max_time})")
        return self


MAX_STOP_FRACTION = 1000.0  # with re-insertion: the mass may pass this many times [-]


class Discharge(_Strict):
    """Discharge: the gate under the outlet is withdrawn."""

    enabled: bool = Field(True, description="run the discharge phase")
    gate_speed: float | None = Field(
        None, gt=0, description="speed at which the gate slides open sideways, under the "
        "floor, as a slide gate does [m/s]; unset: the gate is removed at once (the paper's)"
    )
    stop_fraction: float = Field(
        0.9, gt=0, le=MAX_STOP_FRACTION, description="stop when this fraction of the mass in "
        "the silo at the gate's opening, less any mass lost through a wall since, has left "
        "through the outlet [-]; above 1 (the mass passing more than once) with reinsert only"
    )
    max_time: float = Field(30.0, gt=0, description="stop after this discharge time [s] "
                            "(checked every 0.05 s of simulated time)")
    clog_time: float = Field(
        2.0, gt=0, description="no grain leaving for this long [s] means a clog (arch)"
    )
    reinsert: bool = Field(False, description="re-insert discharged grains at the top; a grain "
                           "counts in stop_fraction each time it leaves, so a steady flow "
                           "runs until stop_fraction (up to 1000) times the mass has passed, "
                           "or max_time")

    @model_validator(mode="after")
    def _check(self) -> Discharge:
        if self.stop_fraction > 1.0 and not self.reinsert:
            raise ValueError(
                f"discharge.stop_fraction ({self.stop_fraction}) above 1 needs "
                "discharge.reinsert = true: without re-insertion at most the whole mass leaves"
            )
        return self


class TimeStep(_Strict):
    """Time step.  ``dt`` unset: dt = safety * dt_crit (see physics docs)."""

    dt: float | None = Field(None, gt=0, description="time step [s]; must not exceed dt_crit")
    safety: float = Field(0.2, gt=0, le=1, description="fraction of dt_crit used when dt unset [-]")


class Output(_Strict):
    """What is recorded."""

    sample_interval: float = Field(0.02, gt=0, description="time-series sampling interval [s]")
    png: bool = Field(True, description="draw settled.png and final.png (the grains and "
                      "their force network)")
    frame_interval: float = Field(
        0.1, gt=0, description="interval between the frames (grains, contacts, walls) saved to "
        "results.h5 /frames for 'silodem animate' [s]"
    )
    vtk_interval: float | None = Field(
        None, gt=0, description="interval between the ParaView (VTK) files written to "
        "DIR/vtk/ [s]; unset: none"
    )


class Checkpoint(_Strict):
    """Checkpoints: the full state, saved so that an interrupted run resumes exactly."""

    enabled: bool = Field(
        True, description="write checkpoint.h5 while the run goes (results.h5 is refreshed at "
        "the same moments either way)"
    )
    every_steps: int = Field(
        20000, ge=1, description="write a checkpoint once this many time steps have passed "
        "since the last one [-]"
    )
    every_wall_seconds: float = Field(
        600.0, gt=0, description="also write one once this much wall-clock time has passed "
        "since the last one [s]"
    )


class Measure(_Strict):
    """Measurements and report (docs/measurements.md): stress circles, wall profiles, flow."""

    interval: float = Field(0.02, gt=0, description="measurement sampling interval [s]")
    window: float = Field(
        1.0, gt=0, description="averaging window [s]: the last `window` s of settling give the "
        "'after filling' profiles, `window` s of discharge the 'during discharge' ones"
    )
    discharge_delay: float = Field(
        0.5, ge=0, description="the discharge window starts this long after the gate opens "
        "(a sliding gate: begins to slide) [s]"
    )
    wall_bin: float | None = Field(
        None, gt=0, description="bin length along the walls and height of the profile bins "
        "[m]; unset: two mean grain diameters"
    )
    strip_width: float | None = Field(
        None, gt=0, description="width of the near-wall strips whose Love-Weber stress gives "
        "the stress along the walls [m]; unset: two mean grain diameters"
    )
    coordination_band: float | None = Field(
        None, gt=0, description="height of the band across the silo, centred on the "
        "cell-hopper junction, where the coordination number of Fig. 2 is counted [m]; unset: "
        "four mean grain diameters"
    )
    switch_zone_half_height: float | None = Field(
        None, gt=0, description="the switch zone is the junction height +- this [m]; its peak "
        "wall stress is reported; unset: two mean grain diameters, at most half the hopper's "
        "height"
    )
    circle_names: list[str] | None = Field(
        None, description="names of the measurement circles [-]; unset (with circle_x, "
        "circle_z, circle_radius): three circles at the switch zone"
    )
    circle_x: list[float] | None = Field(
        None, description="x of each circle's centre, from the left wall [m]"
    )
    circle_z: list[float] | None = Field(
        None, description="z of each circle's centre, above `circle_z_from` [m]"
    )
    circle_radius: list[float] | None = Field(None, description="radius of each circle [m]")
    circle_z_from: Literal["outlet", "junction"] = Field(
        "junction", description="circle_z is measured from the outlet or from the junction"
    )
    grid_cell: float | None = Field(
        None, gt=0, description="cell size of the velocity field grid [m]; unset: one mean "
        "grain diameter"
    )
    field_cell: float | None = Field(
        None, gt=0, description="cell size of the grid of the bulk density and stress fields "
        "[m], about: the width and the height of the silo are each cut into the whole number "
        "of equal cells nearest to it; unset: four mean grain diameters"
    )
    field_kernel: Literal["box", "gaussian"] = Field(
        "box", description="coarse-graining of the density and stress fields: 'box' (a grain's "
        "mass shared among the cells by the area of its disk in each, its stress in the cell "
        "of its centre) or 'gaussian' (smooth, at the cell centres)"
    )
    field_width: float | None = Field(
        None, gt=0, description="width w (standard deviation) of the Gaussian of "
        "field_kernel = 'gaussian' [m], at least half the grid's largest cell side (the "
        "field cell rounded to a whole number across the silo); unset: that half"
    )
    mass_flow_index_threshold: float = Field(
        0.3, gt=0, le=1, description="flow is mass flow when v_wall / v_centre above the "
        "junction is at least this [-] (Johanson's mass flow index)"
    )
    angle_of_repose_deg: float | None = Field(
        None, gt=0, lt=90, description="angle of repose phi_r of the grains [deg], for the "
        "EN 1991-4 (§5.3) wall loads of squat and intermediate silos in the report; unset: "
        "the grain-grain friction angle phi_G"
    )
    report: bool = Field(True, description="write report.html with every figure after a run")

    @model_validator(mode="after")
    def _check(self) -> Measure:
        if self.field_width is not None and self.field_kernel != "gaussian":
            raise ValueError("measure.field_width is the width of field_kernel = 'gaussian'; "
                             "set that too, or remove measure.field_width")
        lists = {"circle_names": self.circle_names, "circle_x": self.circle_x,
                 "circle_z": self.circle_z, "circle_radius": self.circle_radius}
        given = [k for k, v in lists.items() if v is not None]
        if not given:
            return self
        if len(given) != len(lists):
            missing = ", ".join(f"measure.{k}" for k in lists if k not in given)
            raise ValueError(f"measurement circles need all four lists; missing: {missing}")
        sizes = {len(v) for v in lists.values()}
        if len(sizes) != 1:
            raise ValueError("measure.circle_names, circle_x, circle_z and circle_radius must "
                             "have the same length")
        if not self.circle_names:  # (the report, the study table read the circles)
            raise ValueError("measure.circle_names, circle_x, circle_z and circle_radius are "
                             "empty: give at least one circle, or leave all four out for the "
                             "default three at the junction")
        if len(set(self.circle_names)) != len(self.circle_names):
            raise ValueError("measure.circle_names must be unique")
        if not all(name.strip() for name in self.circle_names):
            raise ValueError("measure.circle_names must not be empty")
        if "band" in self.circle_names:  # the junction band's columns are band_* (api.py)
            raise ValueError("measure.circle_names: 'band' is the junction band's name; "
                             "give the circle another")
        for key in ("circle_x", "circle_z", "circle_radius"):
            if not all(math.isfinite(v) for v in lists[key]):
                raise ValueError(f"measure.{key} must hold finite numbers")
        if any(r <= 0 for r in self.circle_radius):
            raise ValueError("measure.circle_radius must hold positive radii [m]")
        return self


class Config(_Strict):
    """A complete silodem run."""

    name: str = Field("custom", min_length=1,
                      description="scenario name; the default results folder is runs/<name>")
    description: str = Field("", description="free text")
    seed: int = Field(ge=0, le=2**63 - 1,
                      description="seed of the random generator (radii, positions)")
    gravity: float = Field(9.81, ge=0, description="gravitational acceleration g [m/s^2]")
    material: Material
    walls: WallMaterial
    silo: Silo
    fill: Fill
    settle: Settle = Settle()
    discharge: Discharge = Discharge()
    time: TimeStep = TimeStep()
    output: Output = Output()
    measure: Measure = Measure()
    checkpoint: Checkpoint = Checkpoint()

    @field_validator("name")
    @classmethod
    def _name(cls, name: str) -> str:
        return folder_name(name, "name")

    @model_validator(mode="after")
    def _check(self) -> Config:
        law_keys(self.walls, "walls", self.material.contact_model)
        if self.silo.outlet_width <= 2.0 * self.material.radius_max:
            raise ValueError(
                f"silo.outlet_width ({self.silo.outlet_width}) must exceed the largest grain "
                f"diameter {2 * self.material.radius_max}"
            )
        if self.fill.band_height < 2.0 * self.material.radius_max:
            raise ValueError(
                f"fill.band_height ({self.fill.band_height}) must be at least one grain diameter "
                f"{2 * self.material.radius_max}"
            )
        if self.fill.band_height > self.silo.wall_height:
            raise ValueError(
                f"fill.band_height ({self.fill.band_height}) must not exceed silo.wall_height "
                f"({self.silo.wall_height}): the band lies under the top of the walls"
            )
        return self
