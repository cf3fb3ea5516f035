"""Typed vehicle parameters (hull, stations, tyres, heat, compensation, charging) from YAML.

`load_vehicle("apc_8x8")` or a path. Quantities accept units; every value in the shipped
file carries its source or "assumed". Hull mass and CG may be omitted: they are then derived
from the charging loads (sum of wheel loads = weight, moment balance), which is how the
REFERENCE §3 numbers were derived.
"""
from __future__ import annotations

import os
from importlib import resources
from pathlib import Path
from typing import Literal

from pydantic import Field, ValidationError, field_validator, model_validator

from hpsim.config import Model, Plain, Quantity, QuantityList, deep_update, load_yaml, validate
from hpsim.errors import UserInputError

GRAVITY = 9.80665  # m/s^2, standard gravity (ISO 80000-3)

m = Quantity("m")
kg = Quantity("kg")
K = Quantity("K")
N = Quantity("N")
s = Quantity("s")
Number = Plain()


class Tyre(Model):
    # unloaded radius: the wheel centre stands radius - static deflection above the ground, the height
    # of the unsprung masses' inertial force under longitudinal acceleration (hull.longitudinal_pitch_moment)
    radius: m | None = None
    stiffness: Quantity("N/m")
    damping: Quantity("N*s/m")
    contact_length: m = 0.35       # enveloping filter length (REFERENCE §5)
    lift_off_smoothing: m = 1e-4   # width of the smooth no-tension law

    _must_be_positive = ("lift_off_smoothing",)

    @model_validator(mode="after")
    def _check(self):
        if self.stiffness <= 0 or (self.radius is not None and self.radius <= 0):
            raise ValueError("tyre stiffness and radius must be > 0")
        if self.damping < 0 or self.contact_length < 0:
            raise ValueError("tyre damping and contact_length must be >= 0")
        return self


class AxleTyre(Model):
    """Per-axle override of the vehicle's `tyre:` (docs/vehicles.md "tyre"): the keys given replace the vehicle's values
    for the two wheels of this axle (`VehicleParams.axle_tyre`); the merged tyre is validated as a `Tyre`."""

    radius: m | None = None
    stiffness: Quantity("N/m") | None = None
    damping: Quantity("N*s/m") | None = None
    contact_length: m | None = None
    lift_off_smoothing: m | None = None

    def given(self) -> dict:
        return {k: getattr(self, k) for k in type(self).model_fields if getattr(self, k) is not None}


# allowed ranges of a station's heat environment (SI; docs/physics.md "Per-station heat environment"):
# a wheel bay's air moves at most twice the vehicle speed; a film coefficient above 500 W/m^2K is
# boiling or a water jet, not air; a local heat source above 5 kW would be a fire; an ambient offset
# beyond -50/+150 K is no longer the air around a strut
ENVIRONMENT_RANGES = {
    "air_speed_ratio": (0.0, 2.0),            # -
    "film_coefficient": (0.0, 500.0),         # W/(m^2 K)
    "ambient_offset": (-50.0, 150.0),         # K
    "view_factor": (0.0, 1.0),                # -
    "heat_source": (0.0, 5000.0),             # W
}


def _check_environment(model):
    for name, (lo, hi) in ENVIRONMENT_RANGES.items():
        value = getattr(model, name)
        if value is not None and not lo <= value <= hi:
            raise ValueError(f"{name} must be in [{lo:g}, {hi:g}] (SI), got {value:g}")
    if getattr(model, "film_coefficient") is not None and model.film_coefficient <= 0:
        raise ValueError(f"film_coefficient must be > 0 W/(m^2 K), got {model.film_coefficient:g}")


class AxleHeat(Model):
    """Per-axle overrides of the vehicle's heat environment (docs/physics.md "Per-station heat
    environment"); a field left out keeps the vehicle's `heat` value. Give air_speed_ratio or
    film_coefficient, not both."""

    air_speed_ratio: Number | None = None                   # wheel-bay air speed / vehicle speed
    film_coefficient: Quantity("W/(m**2*K)") | None = None  # outside convection (replaces natural + forced)
    ambient_offset: K | None = None                         # local air minus ambient [K]
    view_factor: Number | None = None                       # radiation view factor to the ambient
    heat_source: Quantity("W") | None = None                # local heat onto the strut surface (engine, exhaust)

    @model_validator(mode="after")
    def _check(self):
        if self.air_speed_ratio is not None and self.film_coefficient is not None:
            raise ValueError("give air_speed_ratio or film_coefficient, not both")
        _check_environment(self)
        return self


def strut_reference(value, where: str = "strut") -> str:
    """A strut reference as the one string the loaders take: a built-in name ("apc") or a path.

    Accepted spellings (docs/vehicles.md "Strut files"): `apc`, `my_strut.yaml`, `{type: apc}` (a built-in
    strut) and `{file: my_strut.yaml}` (an own strut file: the documented spelling); `{type: my_strut.yaml}`
    is accepted too (a path given as a type)."""
    if isinstance(value, str):
        return value
    if isinstance(value, dict) and len(value) == 1 and set(value) <= {"type", "file"}:
        (key, ref), = value.items()
        if not isinstance(ref, str) or not ref:
            raise ValueError(f"{where}.{key}: expected a strut name or a path, got {ref!r}")
        if key == "file" and not ref.endswith((".yaml", ".yml")):
            raise ValueError(f"{where}.file: expected a path to a .yaml strut file, got {ref!r} (a built-in strut "
                             f"is given as {where}: {ref} or {where}: {{type: {ref}}})")
        return ref
    raise ValueError(f"{where}: expected a built-in strut name (apc), {{type: apc}} or {{file: my_strut.yaml}}, "
                     f"got {value!r}")


# Allowed geometry of every vehicle file and of `hpsim vehicle new` (SI, one table for both): a track from a
# light utility vehicle's to beyond the widest road-legal vehicle (2.55 m overall width, EU 2015/719) with
# wide off-road tyres; a motion ratio (strut travel / wheel travel) of a real linkage; axles within 30 m of
# axle 1, the datum of the positions and of hull.cg_x
VEHICLE_RANGES = {
    "track": (0.5, 5.0),              # m
    "motion_ratio": (0.1, 2.0),       # -
    "axle_position": (0.0, 30.0),     # m behind axle 1
}


def check_range(name: str, value: float, unit: str = "") -> None:
    """ValueError naming `name`, the allowed range of VEHICLE_RANGES and the value when it lies outside."""
    lo, hi = VEHICLE_RANGES[name]
    if not lo <= value <= hi:
        raise ValueError(f"{name} must be in [{lo:g}, {hi:g}]{' ' + unit if unit else ''}, got {value:g}"
                         f"{' ' + unit if unit else ''}")


class Axle(Model):
    position: m                     # behind axle 1 [m]
    strut: str = "apc"              # built-in strut name or path (strut_reference: also {type: ...}, {file: ...})
    unsprung_mass: kg               # per wheel station
    motion_ratio: Number            # strut travel / wheel travel
    strut_overrides: dict = {}      # e.g. {"valve.bleed_area": "1.2e-5 m^2"} (charge.pressure: charging.method gas_pressure)
    tyre: AxleTyre | None = None    # overrides of the vehicle's tyre on this axle (None: the vehicle's tyre)
    heat: AxleHeat | None = None  # this axle's heat environment where it differs from the vehicle's `heat`

    @field_validator("strut", mode="before")
    @classmethod
    def _strut(cls, v):
        return strut_reference(v)

    @model_validator(mode="after")
    def _check(self):
        if self.unsprung_mass <= 0:
            raise ValueError(f"unsprung_mass must be > 0 kg, got {self.unsprung_mass}")
        check_range("motion_ratio", self.motion_ratio)
        check_range("axle_position", self.position, "m")
        return self


class Hull(Model):
    mass: kg | None = None          # sprung mass; None: derived from the charging loads
    cg_x: m | None = None           # behind axle 1; None: derived from the charging loads
    cg_y: m = 0.0                   # to the left of the centre line
    cg_height: m                    # sprung-mass CG above the ground (longitudinal load transfer)
    pitch_inertia: Quantity("kg*m**2")
    roll_inertia: Quantity("kg*m**2")
    # the hull's outline, for `hpsim vehicle check` (seats inside it); None: the defaults of docs/vehicles.md
    # (vehicle.physics.vehicle_check.hull_outline)
    front_overhang: m | None = None     # hull ahead of axle 1
    rear_overhang: m | None = None      # hull behind the last axle
    width: m | None = None              # overall hull width
    height: m | None = None             # roof above the ground

    _must_be_positive = ("front_overhang", "rear_overhang", "width", "height")

    @model_validator(mode="after")
    def _check(self):
        if self.mass is not None and self.mass <= 0:
            raise ValueError(f"mass must be > 0 kg, got {self.mass}")
        if self.pitch_inertia <= 0 or self.roll_inertia <= 0:
            raise ValueError("pitch_inertia and roll_inertia must be > 0 kg m^2")
        if not 0.2 <= self.cg_height <= 5.0:
            raise ValueError(f"cg_height must be in [0.2, 5] m above the ground, got {self.cg_height:g} m")
        return self


class Longitudinal(Model):
    """How the longitudinal tyre forces of the speed profile's acceleration load the hull (docs/scenarios.md;
    vehicle.physics.hull.longitudinal_pitch_moment, linkage_forces).

    drive_distribution / brake_distribution: relative share of the drive (a > 0) and brake (a < 0)
        force per axle, split equally between its two wheels; normalised to a sum of 1; None: equal on
        every axle (all-wheel drive, brakes on all wheels).
    anti_squat / anti_dive: fraction of the pitch moment of acceleration / braking reacted by the
        suspension linkage geometry instead of the springs (0: none, the reference of Gillespie 1992
        §7 with the instant centres at ground level; 1: the hull does not pitch on its springs).
    """

    drive_distribution: QuantityList("") | None = None
    brake_distribution: QuantityList("") | None = None
    anti_squat: Number = 0.0
    anti_dive: Number = 0.0

    _must_be_fraction = ("anti_squat", "anti_dive")

    @field_validator("drive_distribution", "brake_distribution")
    @classmethod
    def _shares(cls, v):
        if v is not None and (any(x < 0 for x in v) or sum(v) <= 0):
            raise ValueError(f"the shares must be >= 0 with a sum > 0, got {v}")
        return v


class Heat(Model):
    """Strut heat network (vehicle.physics.thermal; docs/physics.md) and the default heat environment of
    every station (axles[k].heat overrides it)."""

    capacity: Quantity("J/K")                   # total of the strut's nodes (oil + steel), REFERENCE §8
    surface_area: Quantity("m**2")
    diameter: m                                 # outer cylinder diameter (forced convection)
    natural_convection: Quantity("W/(m**2*K)") = 5.0
    emissivity: Number = 0.9
    # forced convection over a cylinder in cross flow (Churchill-Bernstein); the air speed at
    # the strut is this fraction of the vehicle speed (wheel bay shielding): the calibrated parameter
    air_speed_ratio: Number = 0.5
    air_conductivity: Quantity("W/(m*K)") = 0.026
    air_kinematic_viscosity: Quantity("m**2/s") = 1.6e-5
    air_prandtl: Number = 0.71
    convection_multiplier: Number = 1.0   # scales the outside convective coefficient (sensitivity studies)
    # the default environment of every station (docs/physics.md "Per-station heat environment")
    film_coefficient: Quantity("W/(m**2*K)") | None = None   # replaces natural + forced outside convection
    ambient_offset: K = 0.0
    view_factor: Number = 1.0
    heat_source: Quantity("W") = 0.0
    # the network (docs/physics.md "Strut heat network"; defaults are the apc_8x8 file's values, see its sources)
    oil_capacity_fraction: Number = 0.1        # of capacity: the oil node
    surface_capacity_fraction: Number = 0.2    # of the steel (capacity - oil): the outer skin node
    bore_diameter: m = 0.11                    # inner diameter of the cylinder wall
    wall_conductivity: Quantity("W/(m*K)") = 45.0
    wetted_area: Quantity("m**2") = 0.2        # oil-wetted inner area of the cylinder
    oil_column_height: m = 0.3                 # natural-convection length in the oil
    oil_conductivity: Quantity("W/(m*K)") = 0.13
    oil_specific_heat: Quantity("J/(kg*K)") = 1900.0
    oil_film_multiplier: Number = 1.0          # scales the oil-side film coefficient (correlation prior)
    mount_conductance: Quantity("W/K") = 1.0   # conduction into the hull and wheel-carrier mounts

    _must_be_positive = ("air_conductivity", "air_kinematic_viscosity", "air_prandtl", "wall_conductivity",
                         "wetted_area", "oil_column_height", "oil_conductivity", "oil_specific_heat",
                         "oil_film_multiplier", "bore_diameter")
    _must_be_non_negative = ("natural_convection", "convection_multiplier", "mount_conductance")
    _must_be_fraction = ("emissivity",)

    @model_validator(mode="after")
    def _check(self):
        if self.capacity <= 0 or self.surface_area <= 0 or self.diameter <= 0:
            raise ValueError("capacity, surface_area and diameter must be > 0")
        _check_environment(self)
        for name in ("oil_capacity_fraction", "surface_capacity_fraction"):
            if not 0.0 < getattr(self, name) < 1.0:
                raise ValueError(f"{name} must be in (0, 1), got {getattr(self, name):g}")
        if not self.bore_diameter < self.diameter:
            raise ValueError(f"bore_diameter ({self.bore_diameter:g} m) must be < diameter ({self.diameter:g} m)")
        return self


# Allowed settings of the levelling loop (SI; docs/scenarios.md "compensation"). It must stay a
# slow loop beside the suspension's own body modes (1-2 Hz, 6-12 rad/s): a closed-loop time
# constant of at least 2 s keeps its bandwidth below a tenth of them, and a filter of at least 1 s
# takes the body motion (attenuated 6x at 1 Hz) out of the deflection signal. A levelling pump
# moves a strut slowly: 1e-4 m^3/s (6 L/min per strut) extends the APC strut at 22 mm/s, a tenth
# of its ride velocities; more is a second actuator. The dead band's edges are blended over
# `smoothing`, which divides (hpsim.symbolic.ramp): it must be > 0.
COMPENSATION_RANGES = {
    "time_constant": (2.0, 3600.0),            # s
    "filter_time_constant": (1.0, 3600.0),     # s
    "dead_band": (0.0, 0.1),                   # m
    "flow_limit": (1e-9, 1e-4),                # m^3/s
    "smoothing": (1e-4, 0.02),                 # m
}


class Compensation(Model):
    """Pressure compensation (levelling) per strut (REFERENCE §9)."""

    enabled: bool = False
    time_constant: s = 15.0          # closed-loop time constant of the mean deflection
    filter_time_constant: s = 10.0   # low-pass of the measured deflection
    dead_band: m = 0.015             # half width of the dead band on the filtered deflection error
    flow_limit: Quantity("m**3/s") = 2e-5
    smoothing: m = 1e-3

    @model_validator(mode="after")
    def _stable(self):
        for name, (lo, hi) in COMPENSATION_RANGES.items():
            value = getattr(self, name)
            if not lo <= value <= hi:
                raise ValueError(f"{name} must be in [{lo:g}, {hi:g}] (SI), got {value:g}: a levelling loop "
                                 "stays slow beside the 1-2 Hz body modes (docs/scenarios.md)")
        return self


class Seat(Model):
    """A seat on the hull where ride comfort is evaluated (vehicle.physics.ride): position from the
    sprung CG, x + rearward (as the axle positions), y + left, z + up (lateral reading in roll)."""

    name: str
    x_from_cg: m
    y_from_cg: m = 0.0
    z_from_cg: m = 0.0


CHARGING_METHODS = ("load_and_height", "gas_pressure", "polytropic_convention")


class Charging(Model):
    """How the gas charges were set while stationary (seed 000 §3; REFERENCE §3; docs/vehicles.md "charging").

    `method` decides the gas mass of every strut (vehicle.physics.equilibrium.charge_gas_masses):
      load_and_height        the wheel_loads are carried at strut_deflection at `temperature` with
                             the standing (isothermal) gas law of the strut file
      gas_pressure           each strut file's charge: charge.pressure at full extension at
                             charge.temperature (a strut override of charge.pressure takes effect)
      polytropic_convention  the wheel_loads are carried at strut_deflection at `temperature` with
                             seed 000's spring law p V^n = const from full extension (eq. 5), the
                             convention behind the strut file's 4.8 MPa / 41.8 kN / 112 mm
    The charged pose (strut_deflection, wheel_loads) stays the reference of all displacements;
    with gas_pressure or polytropic_convention the standing vehicle does not sit exactly there.
    """

    method: Literal[CHARGING_METHODS] = "load_and_height"
    wheel_loads: QuantityList("N")   # per axle, per wheel (left = right)
    # hull height at each axle when charged: informational (heights are reported as changes from
    # the charged pose, which strut_deflection defines)
    heights: QuantityList("m") | None = None
    temperature: K
    strut_deflection: m              # strut deflection at the charged state (same at every station)
    # charge every strut this much above (or below) the set-up charge: the gas mass follows the
    # fill pressure at full extension at the charging temperature (sensitivity studies)
    fill_pressure_offset: Quantity("Pa") = 0.0

    @field_validator("method", mode="before")
    @classmethod
    def _method(cls, v):
        # {value: ..., source: ...} like the quantities: the vehicle file says why it uses a method
        if isinstance(v, dict) and "value" in v and set(v) <= {"value", "source", "note"}:
            v = v["value"]
        if v not in CHARGING_METHODS:
            raise ValueError(f"must be one of {', '.join(CHARGING_METHODS)}, got {v!r}")
        return v


class VehicleParams(Model):
    name: str
    description: str = ""
    track: m
    axles: list[Axle] = Field(min_length=2)
    hull: Hull
    tyre: Tyre
    heat: Heat
    compensation: Compensation = Compensation()
    longitudinal: Longitudinal = Longitudinal()
    charging: Charging
    seats: list[Seat] = []          # ride-comfort evaluation points (driver, crew)

    @field_validator("seats")
    @classmethod
    def _seat_names(cls, v):
        names = [st.name for st in v]
        if len(set(names)) != len(names):
            raise ValueError(f"seat names must differ, got {names}")
        return v

    @model_validator(mode="after")
    def _check(self):
        n = len(self.axles)
        pos = [a.position for a in self.axles]
        if pos[0] != 0.0:
            raise ValueError(f"axles.0.position: axle 1 is the datum of the positions and of hull.cg_x (0 m), got "
                             f"{pos[0]:g} m; subtract {pos[0]:g} m from every position (and from hull.cg_x)")
        if any(b <= a for a, b in zip(pos, pos[1:])):
            raise ValueError(f"axles: positions must increase from front to rear, got {pos}")
        if len(self.charging.wheel_loads) != n or len(self.charging.heights or [0] * n) != n:
            raise ValueError(f"charging: wheel_loads and heights need one value per axle ({n})")
        if any(w <= 0 for w in self.charging.wheel_loads):
            raise ValueError("charging.wheel_loads must be > 0 N")
        check_range("track", self.track, "m")
        for k in range(n):
            tyre = self.axle_tyre(k)
            if self.axles[k].tyre is not None:
                try:
                    Tyre.model_validate(tyre.model_dump())
                except ValidationError as exc:
                    msg = "; ".join(e["msg"].removeprefix("Value error, ") for e in exc.errors())
                    raise ValueError(f"axles.{k}.tyre: {msg}") from None
            if tyre.radius is None:
                raise ValueError(f"tyre.radius (axle {k + 1}): needed, the wheel-centre height of the unsprung "
                                 "masses' inertial force under longitudinal acceleration")
            if not 0.1 <= tyre.radius <= self.hull.cg_height + 1.0:
                raise ValueError(f"tyre.radius (axle {k + 1}) must be in [0.1 m, hull.cg_height + 1 m], "
                                 f"got {tyre.radius:g} m")
        L = self.longitudinal
        for name, shares, anti in (("drive_distribution", L.drive_distribution, L.anti_squat),
                                   ("brake_distribution", L.brake_distribution, L.anti_dive)):
            if shares is not None and len(shares) != n:
                raise ValueError(f"longitudinal.{name}: needs one share per axle ({n}), got {len(shares)}")
            used = [self.axles[k].position for k in range(n) if shares is None or shares[k] > 0]
            if anti > 0 and len(set(used)) < 2:
                raise ValueError(f"longitudinal.{name}: an anti-pitch linkage needs forces on at least two axles "
                                 "(a pure pitch couple); give two axles a share or set the anti factor to 0")
        if self.charging.method != "gas_pressure":
            for k, axle in enumerate(self.axles):
                if _has_key(axle.strut_overrides, "charge.pressure"):
                    raise ValueError(
                        f"axles.{k}.strut_overrides: charge.pressure has no effect with charging.method "
                        f"{self.charging.method!r}: charging.method decides the gas mass (here from "
                        "charging.wheel_loads at charging.strut_deflection); set charging.method: gas_pressure "
                        "(in a scenario: vehicle.overrides: {charging.method: gas_pressure}) to charge by "
                        "pressure, or use charging.fill_pressure_offset")
        return self

    # --- derived ------------------------------------------------------------------------------
    @property
    def n_axles(self) -> int:
        return len(self.axles)

    @property
    def n_stations(self) -> int:
        return 2 * len(self.axles)

    def station_axle(self, i: int) -> int:
        """Stations are axle-major, left first: 0 = axle 1 left, 1 = axle 1 right, ..."""
        return i // 2

    def station_y(self, i: int) -> float:
        """Lateral position [m], + left."""
        return 0.5 * self.track if i % 2 == 0 else -0.5 * self.track

    def station_names(self) -> list[str]:
        return [f"axle{self.station_axle(i) + 1}_{'left' if i % 2 == 0 else 'right'}"
                for i in range(self.n_stations)]

    def per_station(self, values, where: str):
        """One value for all stations, one per axle or one per station (axle-major, left first)."""
        import numpy as np

        v = np.atleast_1d(np.asarray(values, float))
        if len(v) == 1:
            return np.full(self.n_stations, v[0])
        if len(v) == self.n_axles:
            return np.repeat(v, 2)
        if len(v) == self.n_stations:
            return v.copy()
        raise UserInputError(
            f"{where}: got {len(v)} values; allowed: 1 (all struts), {self.n_axles} (one per axle) "
            f"or {self.n_stations} (one per strut, axle-major, left first)")

    def axle_tyre(self, k: int) -> Tyre:
        """The tyre of axle k: the vehicle's `tyre`, with the axle's `tyre` overrides (works on symbolic copies)."""
        over = self.axles[k].tyre
        if over is None:
            return self.tyre
        fields = {name: getattr(self.tyre, name) for name in type(self.tyre).model_fields}
        fields.update(over.given())
        return Tyre.model_construct(**fields)

    def max_contact_length(self) -> float:
        """The longest tyre envelope of all axles [m] (how far ahead of an axle the road is read)."""
        return max(float(self.axle_tyre(k).contact_length) for k in range(self.n_axles))

    def axle_shares(self, which: str):
        """Normalised per-axle share of the drive ("drive") or brake ("brake") force (sum 1)."""
        v = getattr(self.longitudinal, f"{which}_distribution")
        if v is None:
            return [1.0 / self.n_axles] * self.n_axles
        total = sum(v)
        return [x / total for x in v]

    def unsprung_mass_total(self) -> float:
        return sum(2 * a.unsprung_mass for a in self.axles)

    def sprung_mass(self) -> float:
        if self.hull.mass is not None:
            return self.hull.mass
        return sum(2 * w for w in self.charging.wheel_loads) / GRAVITY - self.unsprung_mass_total()

    def sprung_cg_x(self) -> float:
        if self.hull.cg_x is not None:
            return self.hull.cg_x
        num = sum(2 * (w - a.unsprung_mass * GRAVITY) * a.position
                  for w, a in zip(self.charging.wheel_loads, self.axles))
        den = sum(2 * (w - a.unsprung_mass * GRAVITY) for w, a in zip(self.charging.wheel_loads, self.axles))
        return num / den

    def total_weight(self) -> float:
        return (self.sprung_mass() + self.unsprung_mass_total()) * GRAVITY


def _has_key(mapping: dict, dotted: str) -> bool:
    """True if `mapping` sets `dotted` ("charge.pressure"), as a dotted key or nested mappings."""
    if not isinstance(mapping, dict):
        return False
    if dotted in mapping:
        return True
    head, _, rest = dotted.partition(".")
    for key, value in mapping.items():
        if key == head and rest:
            return _has_key(value, rest)
        if str(key).startswith(head + ".") and _has_key({str(key)[len(head) + 1:]: value}, rest):
            return True
    return False


def builtin_vehicles() -> list[str]:
    folder = resources.files("vehicle") / "data"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".yaml"))


def vehicle_file(name_or_path: str | Path) -> Path:
    p = Path(name_or_path)
    if p.suffix in (".yaml", ".yml"):
        if not p.exists():
            raise UserInputError(f"vehicle file {p}: not found")
        return p
    if str(name_or_path) in builtin_vehicles():
        return Path(str(resources.files("vehicle") / "data" / f"{name_or_path}.yaml"))
    raise UserInputError(f"vehicle: unknown vehicle {str(name_or_path)!r}; built-in: {', '.join(builtin_vehicles())} "
                         "(or a path to a .yaml file)")


def load_vehicle(name_or_path: str | Path, overrides: dict | None = None, source: str | None = None) -> VehicleParams:
    path = vehicle_file(name_or_path)
    data = load_yaml(path)
    if not isinstance(data, dict):
        raise UserInputError(f"{path}: expected a mapping of vehicle parameters")
    if overrides:
        data = deep_update(data, overrides)
    return validate(VehicleParams, with_strut_paths(data, path.resolve().parent), source or str(path))


def with_strut_paths(data: dict, base_dir: Path) -> dict:
    """The vehicle mapping with every own strut file (`strut: {file: my_strut.yaml}` or a path) made absolute
    from `base_dir`, the vehicle file's folder (docs/vehicles.md "Strut files")."""
    axles = data.get("axles")
    if not isinstance(axles, list):
        return data
    out = []
    for k, axle in enumerate(axles):
        if isinstance(axle, dict) and "strut" in axle:
            try:
                ref = strut_reference(axle["strut"], f"axles.{k}.strut")
            except ValueError:
                ref = None          # the schema reports it, naming the file
            if ref is not None and ref.endswith((".yaml", ".yml")) and not Path(ref).expanduser().is_absolute():
                # normalised: "../" resolves even while the vehicle file's folder is not written yet
                axle = {**axle, "strut": os.path.normpath(base_dir / Path(ref).expanduser())}
        out.append(axle)
    return {**data, "axles": out}
