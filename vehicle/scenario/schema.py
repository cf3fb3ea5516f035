"""Scenario files: what to drive, where, how fast, and what to keep (docs/scenarios.md).

A scenario is a YAML mapping validated in two steps *before any work starts*:

1. `Scenario` (pydantic, unknown keys rejected at every level): types, units and ranges of the
   scenario's own keys. Every error names the file, the key path, the value and what is allowed.
2. `prepare()`: the parts that need other packages — the vehicle file with its overrides
   (`vehicle.physics.params.VehicleParams`), the strut files with their overrides, the road
   (`terrain.RoadSpec`) and the count of initial temperatures (1, one per axle or one per
   station) — are validated the same way; `vehicle.engines.build.build_engine(prepared)` then builds
   the engine the scenario asks for.

Key paths in overrides may be dotted and may index lists: `axles.0.unsprung_mass` or
`{axles: {0: {unsprung_mass: ...}}}` (see `apply_overrides`).
"""
from __future__ import annotations

import copy
import json
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import Field, StrictBool, StrictInt, ValidationInfo, field_validator, model_validator

from hpsim.config import Model, Quantity, format_validation_error, load_yaml, parse_yaml, read_text_file
from hpsim.errors import UserInputError
from hpsim.priors import values_only
from hpsim.units import parse_quantity
from hpsim.validators import in_range, quantity
from struts.params import load_strut
import terrain

from vehicle.physics.model import VehicleModel
from vehicle.physics.outputs import ALWAYS_STORED, series_keys
from vehicle.physics.params import COMPENSATION_RANGES, VehicleParams, strut_reference, vehicle_file
from vehicle.physics.vehicle_check import pre_drive_check
from vehicle.scenario.settings import (DT_RANGE_S, SEGMENTS_RANGE, TIME_PARALLEL_LANES_RANGE, DriveSettings,
                                       MultiscaleSettings)
from vehicle.scenario.speed import build_speed_profile, parse_speed_spec
from vehicle.scenario.speed_limits import PROFILE_LIMIT_RANGES, check_profile
from vehicle.scenario.work_limits import check_interval, check_scenario, drive_duration_s

K_ = Quantity("K")

# ranges (allowed values) of the scenario's own keys
# 1 m .. 1000 km: the road under a drive is generated whole, at most terrain.profile_io.MAX_ROAD_POINTS
# (1250 km at the default 50 mm spacing), and must reach past the last axle at the end
DISTANCE_RANGE_M = (1.0, 1000e3)
SPEED_RANGE_M_PER_S = (0.1, 150 / 3.6)        # 0.1 m/s .. 150 km/h
AMBIENT_RANGE_K = (273.15 - 60, 273.15 + 60)  # -60 .. 60 degC
STRUT_T_RANGE_K = (273.15 - 60, 273.15 + 200)  # -60 .. 200 degC
# multiscale window layout (solver.window, .spacing, .warm_up): a window must hold some seconds of ride
# (50 m: 9 s at 20 km/h); at most the longest drive
MULTISCALE_RANGES_M = {"window": (50.0, 1000e3), "spacing": (100.0, 1000e3), "warm_up": (0.0, 10e3)}
MULTISCALE_KEYS = ("window", "spacing", "warm_up", "placement", "seed", "control_variate", "proxy", "paired_windows")
MULTISCALE_MIN_WINDOWS = 3                    # the error estimate needs the scatter of the windows
TOLERANCE_RANGE = (1e-4, 1.0)                 # solver.tolerance: 0.01 .. 100 % relative error of the strut heat



# --- the schema ------------------------------------------------------------------------------------
class VehicleChoice(Model):
    """Which vehicle: a built-in name or a file, and overrides of its parameters."""

    name: str | None = None
    file: str | None = None
    overrides: dict[str, Any] = {}

    @model_validator(mode="after")
    def _one(self):
        if (self.name is None) == (self.file is None):
            raise ValueError("give exactly one of vehicle.name (a built-in vehicle) or vehicle.file (a path)")
        return self


class StrutChoice(Model):
    """Strut type and fill of the struts of one axle (both wheels) or of all axles."""

    type: str | None = None                  # built-in strut name ("apc"; a path is accepted too)
    file: str | None = None                  # an own strut file (the documented spelling: docs/vehicles.md)
    overrides: dict[str, Any] = {}           # strut parameters, e.g. {"charge.pressure": "5 MPa"}

    @model_validator(mode="after")
    def _one(self):
        if self.type is not None and self.file is not None:
            raise ValueError("give type (a built-in strut) or file (a strut file), not both")
        if self.file is not None:
            strut_reference({"file": self.file})
        return self

    @property
    def strut(self) -> str | None:
        return self.file if self.file is not None else self.type


class SpeedProfileSpec(Model):
    """Piecewise-linear speed over distance: [[distance, speed], ...] (SI after validation)."""

    profile: list[tuple[float, float]] = Field(min_length=1)


def _speed_profile(value: dict) -> SpeedProfileSpec:
    """{profile: [[distance, speed], ...]} -> SpeedProfileSpec; messages name the point."""
    extra = sorted(set(value) - {"profile"})
    if extra:
        raise ValueError(f"unknown key {extra[0]!r} (check the spelling), allowed: a speed such as '20 km/h' "
                         "or {profile: [[distance, speed], ...]}")
    points = value.get("profile")
    if not isinstance(points, list) or not points:
        raise ValueError("profile: expected a list of [distance, speed] pairs, e.g. [[0 km, 20 km/h], [50 km, 15 km/h]]")
    out = []
    for k, point in enumerate(points):
        if not isinstance(point, (list, tuple)) or len(point) != 2:
            raise ValueError(f"profile item {k}: expected a pair [distance, speed], got {point!r}")
        try:
            s_m = parse_quantity(point[0], "m", where=f"profile item {k}: distance")
            v_ms = parse_quantity(point[1], "m/s", where=f"profile item {k}: speed")
        except UserInputError as exc:
            raise ValueError(str(exc)) from None
        lo, hi = SPEED_RANGE_M_PER_S
        if not lo * (1 - 1e-9) <= v_ms <= hi * (1 + 1e-9):   # the printed ends are allowed
            raise ValueError(f"profile item {k}: speed must be in [{lo * 3.6:.6g}, {hi * 3.6:.6g}] km/h, "
                             f"got {v_ms * 3.6:.6g} km/h")
        if s_m < 0:
            raise ValueError(f"profile item {k}: distance must be >= 0 m, got {s_m:.6g} m")
        out.append((s_m, v_ms))
    d = [p[0] for p in out]
    if any(b <= a for a, b in zip(d, d[1:])):
        raise ValueError(f"profile: the distances must increase, got {[x / 1e3 for x in d]} km")
    if d[0] > 0:
        raise ValueError("profile: the first point must be at 0 km")
    return SpeedProfileSpec(profile=out)


class CompensationSpec(Model):
    """Pressure compensation (levelling), mapped onto the vehicle's `compensation` parameters."""

    enabled: StrictBool = False
    time_constant: float | None = None
    filter_time_constant: float | None = None
    dead_band: float | None = None
    flow_limit: float | None = None
    smoothing: float | None = None

    # ranges: vehicle.physics.params.COMPENSATION_RANGES (a slow loop beside the body modes)
    @field_validator("time_constant", "filter_time_constant", mode="before")
    @classmethod
    def _seconds(cls, v, info: ValidationInfo):
        return None if v is None else in_range(quantity("s", v), *COMPENSATION_RANGES[info.field_name], "s")

    @field_validator("dead_band", "smoothing", mode="before")
    @classmethod
    def _metres(cls, v, info: ValidationInfo):
        return None if v is None else in_range(quantity("m", v), *COMPENSATION_RANGES[info.field_name], "mm", 1e3)

    @field_validator("flow_limit", mode="before")
    @classmethod
    def _flow(cls, v):
        return None if v is None else in_range(quantity("m**3/s", v), *COMPENSATION_RANGES["flow_limit"], "m^3/s")


class SolverSpec(Model):
    dt: float = 0.004                        # fixed step of the ROS2 solver
    samples_per_block: StrictInt = Field(10, ge=1, le=1000)   # output samples per compiled call
    # full: the whole road with the full model; multiscale: windows of the road with the full model, the
    # slow states advanced between them, with an error estimate (vehicle.engines.multiscale)
    mode: Literal["full", "multiscale"] = "full"
    window: float | None = None              # multiscale: averaged stretch of each window (default 500 m)
    spacing: float | None = None             # multiscale: one window per this much road (default 5 km)
    warm_up: float | None = None             # multiscale: stretch before the averaged one (default 50 m)
    placement: Literal["systematic", "stratified", "weighted"] | None = None   # multiscale: where the windows go
    seed: StrictInt | None = Field(None, ge=0)   # multiscale: of the stratified placement
    # multiscale: regression on a road proxy known for the whole road (variance reduction, default true)
    control_variate: StrictBool | None = None
    # multiscale: the control variate's proxy of each window's dissipation: linear_model (default: the linearised
    # vehicle's squared strut velocity under the whole road) or road_rate (the band-passed road rate under each tyre)
    proxy: Literal["road_rate", "linear_model"] | None = None
    # multiscale: the windows in pairs, the second of each from the start the slow model predicts, integrated beside
    # the first (two cores) and carried to its true start by its linear model (default true); false: one by one
    paired_windows: StrictBool | None = None
    # parallel in time (vehicle.engines.time_parallel): the full drive split into segments run in this many
    # processes at once, joined with a correction of the slow states; "auto": one per CPU; 1: serial
    time_parallel: Literal["auto"] | StrictInt | None = None
    # ... and each of these processes runs this many consecutive segments in lockstep on the lane library (one
    # vector instruction for all, bit for bit the scalar engine's per segment); "auto" (default): 4, fewer on a
    # short drive; 1: one segment per process on the scalar engine
    time_parallel_lanes: Literal["auto"] | StrictInt | None = None
    # step-doubling error estimate (vehicle.numerics.error_estimate): the largest relative error of a strut's
    # heat (its temperature rise rate) accepted without a warning, and every how many sample blocks one output
    # sample is integrated again at dt/2 (cost about 2 / (samples_per_block * error_check_every); 0: no estimate)
    # (default 10 %: one 1 s window's heat error at 4 ms is 1-5 %, of varying sign (non-smooth friction and valves),
    # cancelling over a long drive: 0.3 % of the temperature rise at 106 km; an under-resolved strut such as
    # yin2023 at 4 ms is at ~40x)
    tolerance: float = 0.10
    error_check_every: StrictInt = Field(10, ge=0, le=100_000)

    @field_validator("dt", mode="before")
    @classmethod
    def _dt(cls, v):
        return in_range(quantity("s", v), *DT_RANGE_S, "ms", 1e3)

    @field_validator("window", "spacing", "warm_up", mode="before")
    @classmethod
    def _window_lengths(cls, v, info: ValidationInfo):
        return None if v is None else in_range(quantity("m", v), *MULTISCALE_RANGES_M[info.field_name], "m")

    @field_validator("time_parallel", mode="after")
    @classmethod
    def _time_parallel(cls, v):
        if isinstance(v, int) and not SEGMENTS_RANGE[0] <= v <= SEGMENTS_RANGE[1]:
            raise ValueError(f"must be in [{SEGMENTS_RANGE[0]}, {SEGMENTS_RANGE[1]}] (segments, one process each) "
                             f"or auto, got {v}")
        return v

    @field_validator("time_parallel_lanes", mode="after")
    @classmethod
    def _time_parallel_lanes(cls, v):
        lo, hi = TIME_PARALLEL_LANES_RANGE
        if isinstance(v, int) and not lo <= v <= hi:
            raise ValueError(f"must be in [{lo}, {hi}] (segments per process) or auto, got {v}")
        return v

    @model_validator(mode="after")
    def _multiscale_keys(self):
        if self.time_parallel not in (None, 1) and self.mode != "full":
            raise ValueError(f"time_parallel: only with mode: full (mode is {self.mode!r})")
        if self.time_parallel_lanes is not None and self.time_parallel is None:
            raise ValueError("time_parallel_lanes: only with time_parallel (the processes; 2 or more, or auto)")
        given = [k for k in MULTISCALE_KEYS if getattr(self, k) is not None]
        if self.mode != "multiscale":
            if given:
                raise ValueError(f"{', '.join(given)}: only with mode: multiscale (mode is {self.mode!r})")
            return self
        if self.spacing_m < self.window_m + self.warm_up_m - 1e-9:
            raise ValueError(f"spacing ({self.spacing_m:g} m) must be at least window + warm_up "
                             f"({self.window_m:g} m + {self.warm_up_m:g} m): the windows would overlap")
        return self

    # the multiscale layout: the keys given, the others at MultiscaleSettings' defaults (written there only)
    @property
    def window_m(self) -> float:
        return self.multiscale_settings().window_m

    @property
    def spacing_m(self) -> float:
        return self.multiscale_settings().spacing_m

    @property
    def warm_up_m(self) -> float:
        return self.multiscale_settings().warm_up_m

    def multiscale_settings(self) -> MultiscaleSettings:
        given = {"window_m": self.window, "spacing_m": self.spacing, "warm_up_m": self.warm_up,
                 "placement": self.placement, "seed": self.seed, "control_variate": self.control_variate,
                 "proxy": self.proxy, "paired_windows": self.paired_windows}
        return MultiscaleSettings(**{k: v for k, v in given.items() if v is not None})

    @field_validator("tolerance", mode="before")
    @classmethod
    def _tolerance(cls, v):
        return in_range(quantity("dimensionless", v), *TOLERANCE_RANGE, "%", 1e2)


class OutputSpec(Model):
    interval: float = 1.0                    # time between stored samples
    stats_interval: float = 1000.0           # distance per statistics row
    store: Literal["all"] | list[str] = "all"
    compression: StrictInt = Field(4, ge=0, le=9)   # gzip level of the HDF5 datasets (0: none)
    # samples per HDF5 chunk: data is written (and checkpointed) each time a chunk is full, so a
    # killed run loses at most this many samples of work
    chunk_samples: StrictInt = Field(512, ge=1, le=100_000)

    @field_validator("interval", mode="before")
    @classmethod
    def _interval(cls, v):
        return in_range(quantity("s", v), 1e-4, 3600.0, "s")

    @field_validator("stats_interval", mode="before")
    @classmethod
    def _stats(cls, v):
        return in_range(quantity("m", v), 1.0, 1e6, "m")

    @field_validator("store")
    @classmethod
    def _store(cls, v):
        if isinstance(v, list):
            bad = [s for s in v if s not in series_keys() and s not in ALWAYS_STORED]
            if bad:
                raise ValueError(f"unknown series {bad}, allowed: 'all' or a list of {', '.join(series_keys())}")
        return v

    def stored(self) -> set[str]:
        return set(series_keys() if self.store == "all" else self.store) | set(ALWAYS_STORED)


class Scenario(Model):
    description: str = ""
    vehicle: VehicleChoice
    struts: dict[str, StrutChoice] = {}      # keys: "all" or "axle1", "axle2", ...
    road: dict[str, Any]                     # terrain.RoadSpec fields (validated in prepare())
    # "20 km/h", {profile: [[0 km, 20 km/h], ...]}, {csv: ..., by: ...}, {stop_go: {...}} or {random: {...}}
    # (the last three: vehicle.scenario.speed specs; every form becomes a speed table in prepare())
    speed: float | SpeedProfileSpec | Any
    distance: float
    ambient_temperature: float
    initial_temperatures: float | list[float] | None = None   # default: ambient
    # what the speed profile may ask of the vehicle (vehicle.scenario.speed_limits; default 1 g and 50 m/s^3)
    max_acceleration: float | None = None
    max_jerk: float | None = None
    compensation: CompensationSpec = CompensationSpec()
    solver: SolverSpec = SolverSpec()
    output: OutputSpec = OutputSpec()

    @field_validator("speed", mode="before")
    @classmethod
    def _speed(cls, v):
        if isinstance(v, Model):
            return v
        if isinstance(v, dict):
            if "profile" in v:
                return _speed_profile(v)
            return parse_speed_spec(v)
        return in_range(quantity("m/s", v), *SPEED_RANGE_M_PER_S, "km/h", 3.6)

    @field_validator("max_acceleration", "max_jerk", mode="before")
    @classmethod
    def _profile_limits(cls, v, info: ValidationInfo):
        unit, lo, hi, shown = PROFILE_LIMIT_RANGES[info.field_name]
        return None if v is None else in_range(quantity(unit, v), lo, hi, shown)

    @field_validator("distance", mode="before")
    @classmethod
    def _distance(cls, v):
        return in_range(quantity("m", v), *DISTANCE_RANGE_M, "km", 1e-3)

    @field_validator("ambient_temperature", mode="before")
    @classmethod
    def _ambient(cls, v):
        return in_range(quantity("K", v), *AMBIENT_RANGE_K, "degC", 1.0, -273.15)

    @field_validator("initial_temperatures", mode="before")
    @classmethod
    def _initial(cls, v):
        if v is None:
            return None
        if isinstance(v, (list, tuple)):
            if not v:
                raise ValueError("expected one temperature, one per axle or one per station")
            out = []
            for k, t in enumerate(v):
                try:
                    out.append(in_range(quantity("K", t), *STRUT_T_RANGE_K, "degC", 1.0, -273.15))
                except ValueError as exc:
                    raise ValueError(f"item {k}: {exc}") from None
            return out
        return in_range(quantity("K", v), *STRUT_T_RANGE_K, "degC", 1.0, -273.15)

    @field_validator("struts")
    @classmethod
    def _strut_keys(cls, v):
        for key in v:
            if key != "all" and not (key.startswith("axle") and key[4:].isdigit() and int(key[4:]) >= 1):
                raise ValueError(f"unknown key {key!r}: allowed 'all' or 'axle1', 'axle2', ...")
        return v

    @field_validator("road")
    @classmethod
    def _road(cls, v):
        if not isinstance(v, dict):
            raise ValueError("expected a mapping of road settings (see docs/scenarios.md)")
        return v

    @model_validator(mode="after")
    def _profile_covers(self):
        if self.output.interval < self.solver.dt - 1e-12:
            raise ValueError(f"output.interval ({self.output.interval:g} s) must be at least solver.dt "
                             f"({self.solver.dt * 1e3:g} ms)")
        k = self.output.interval / self.solver.dt
        if abs(k - round(k)) > 1e-6:
            raise ValueError(f"output.interval ({self.output.interval:g} s) must be a whole number of solver "
                             f"steps of {self.solver.dt * 1e3:g} ms")
        if self.solver.mode == "multiscale":
            n = int(np.ceil(self.distance / self.solver.spacing_m - 1e-9))
            if n < MULTISCALE_MIN_WINDOWS:
                raise ValueError(f"solver.spacing ({self.solver.spacing_m:g} m) gives {n} window(s) over the "
                                 f"{self.distance:g} m drive: the multiscale mode needs at least "
                                 f"{MULTISCALE_MIN_WINDOWS} (spacing at most {self.distance / MULTISCALE_MIN_WINDOWS:.6g} m)")
        return self


# --- overrides with list indices -----------------------------------------------------------------
def _key_parts(key: str) -> list[str]:
    return [p for p in str(key).split(".")]


def set_path(data: Any, path: str | list, value: Any, where: str = "") -> Any:
    """Return a copy of `data` with `value` at the dotted `path` (dict keys or list indices)."""
    parts = _key_parts(path) if isinstance(path, str) else list(path)
    if not parts:
        return value
    head, rest = parts[0], parts[1:]
    here = f"{where}.{head}" if where else head
    if isinstance(data, list):
        try:
            i = int(head)
        except ValueError:
            raise UserInputError(f"{here}: {where or 'value'} is a list: expected an index 0..{len(data) - 1}") from None
        if not -len(data) <= i < len(data):
            raise UserInputError(f"{here}: index {i} out of range (the list has {len(data)} items)")
        out = list(data)
        out[i] = set_path(out[i], rest, value, here) if rest else _merge(out[i], value, here)
        return out
    out = dict(data) if isinstance(data, dict) else {}
    out[head] = set_path(out.get(head), rest, value, here) if rest else _merge(out.get(head), value, here)
    return out


def _merge(old: Any, new: Any, where: str) -> Any:
    if isinstance(new, dict) and isinstance(old, (dict, list)):
        return apply_overrides(old, new, where)
    return copy.deepcopy(new)


def apply_overrides(data: Any, overrides: dict, where: str = "") -> Any:
    """Apply nested/dotted overrides; list items are addressed by index (`axles.0.position`)."""
    out = copy.deepcopy(data)
    for key, value in (overrides or {}).items():
        out = set_path(out, str(key), value, where)
    return out


# --- loading ---------------------------------------------------------------------------------------
@dataclass
class ScenarioSource:
    """The scenario text as given, where it came from and the folder its relative paths refer to."""

    text: str
    name: str
    base_dir: Path
    data: dict = field(default_factory=dict)


def read_scenario_text(text: str, name: str, base_dir: str | Path) -> ScenarioSource:
    data = parse_yaml(text, name)      # the one safe YAML parser (hpsim.config), as for every file
    if not isinstance(data, dict):
        raise UserInputError(f"{name}: expected a mapping of scenario keys (vehicle, road, speed, distance, ...), "
                             f"got {type(data).__name__}")
    return ScenarioSource(text=text, name=name, base_dir=Path(base_dir).resolve(), data=data)


def read_scenario(path: str | Path) -> ScenarioSource:
    path = Path(path)
    return read_scenario_text(read_text_file(path), str(path), path.resolve().parent)


def validate_scenario(src: ScenarioSource) -> Scenario:
    from pydantic import ValidationError

    try:
        return Scenario.model_validate(values_only(src.data, skip=("vehicle", "struts")))   # priors: hpsim uq
    except ValidationError as exc:
        raise UserInputError(format_validation_error(exc, src.name)) from None


# --- preparation: everything validated, nothing built yet ------------------------------------------
@dataclass
class Prepared:
    source: ScenarioSource
    scenario: Scenario
    vehicle: Any                 # vehicle.physics.params.VehicleParams
    road_spec: Any               # terrain.RoadSpec
    initial_temperatures_K: np.ndarray
    speed_profile: Any = None    # vehicle.scenario.speed.SpeedTable (built and checked in prepare())
    in_memory: bool = False      # the drive's results are kept in memory (a lower work limit)
    work: dict = field(default_factory=dict)   # the work estimate (vehicle.scenario.work_limits), set by check_work()

    def settings(self):
        S = self.scenario
        speed = self.speed_profile or build_speed_profile(S.speed, S.distance, self.source.base_dir)
        return DriveSettings(distance_m=S.distance, speed=speed, ambient_K=S.ambient_temperature,
                             initial_temperatures_K=self.initial_temperatures_K.copy(),
                             compensation=S.compensation.enabled, dt_s=S.solver.dt,
                             output_interval_s=S.output.interval, samples_per_block=S.solver.samples_per_block,
                             stats_interval_m=S.output.stats_interval, tolerance=S.solver.tolerance,
                             error_check_every=S.solver.error_check_every)

    def model(self):
        try:
            return VehicleModel(self.vehicle)
        except UserInputError as exc:
            raise UserInputError(f"{self.source.name}: vehicle/struts: {exc}") from None

    def check_vehicle(self, model=None):
        """The quiet `hpsim vehicle check` before a drive (statics, no modes): warnings logged, errors refuse it."""
        try:
            return pre_drive_check(self.vehicle, model, log=logging.getLogger("hpsim").warning)
        except UserInputError as exc:
            raise UserInputError(f"{self.source.name}: {exc}") from None

    def road(self):
        try:
            road = terrain.build_road(self.road_spec, self.source.base_dir)
        except UserInputError as exc:
            raise UserInputError(f"{self.source.name}: road: {exc}") from None
        needed = road_length_needed(self.scenario, self.vehicle)
        if road.length_m < needed:
            # beyond its end the road would be held flat: a drive on a road that is not there
            key = "crg" if getattr(self.road_spec, "crg", None) else "csv"
            raise UserInputError(f"{self.source.name}: road.{key}: the profile in {getattr(self.road_spec, key)} is "
                                 f"{road.length_m:.6g} m long, the drive needs {needed:.6g} m (distance + the tyre's "
                                 "contact length + 1 m); give a longer profile or a shorter distance")
        return road

    def duration_s(self) -> float:
        """The drive's duration [s] at the scenario's speed profile, as the drive computes it."""
        return drive_duration_s(self.settings().speed, self.scenario.distance)

    def check_work(self) -> dict:
        """The work size, before anything is compiled (vehicle.scenario.work_limits): refused beyond the limits; the
        estimate kept in `work` ("announce": a line saying a long run will take long, or None)."""
        S, duration = self.scenario, self.duration_s()
        check_interval(S.output.interval, duration, S.distance, self.source.name)
        self.work = check_scenario(S, duration, len(self.vehicle.station_names()), self.source.name, self.in_memory)
        return self.work

    def resolved(self) -> dict:
        """Every parameter in SI after defaults and overrides: stored with the results."""
        struts = {}
        for k, axle in enumerate(self.vehicle.axles):
            struts[f"axle{k + 1}"] = load_strut(axle.strut, axle.strut_overrides or None).model_dump(mode="json")
        return {"scenario": self.scenario.model_dump(mode="json"),
                "vehicle": self.vehicle.model_dump(mode="json"),
                "vehicle_derived": {"sprung_mass_kg": self.vehicle.sprung_mass(),
                                    "sprung_cg_x_m": self.vehicle.sprung_cg_x(),
                                    "total_weight_N": self.vehicle.total_weight(),
                                    "station_names": self.vehicle.station_names()},
                "struts": struts,
                "road": _dump(self.road_spec),
                "initial_temperatures_K": self.initial_temperatures_K.tolist(),
                "base_dir": str(self.source.base_dir)}


def _dump(obj) -> Any:
    if hasattr(obj, "model_dump"):
        return obj.model_dump(mode="json")
    return json.loads(json.dumps(obj, default=str))


def resolve_path(p: str, base_dir: Path) -> str:
    q = Path(p).expanduser()
    return str(q if q.is_absolute() else (base_dir / q))


def vehicle_data(S: Scenario, src: ScenarioSource) -> tuple[dict, str]:
    """The vehicle's parameter mapping with the scenario's overrides, struts and compensation applied."""
    if S.vehicle.file is not None:
        path = vehicle_file(resolve_path(S.vehicle.file, src.base_dir))
    else:
        try:
            path = vehicle_file(S.vehicle.name)
        except UserInputError as exc:
            raise UserInputError(f"{src.name}: vehicle.name: {exc}") from None
    data = load_yaml(path)
    if not isinstance(data, dict):
        raise UserInputError(f"{path}: expected a mapping of vehicle parameters")
    try:
        data = apply_overrides(data, S.vehicle.overrides)
    except UserInputError as exc:
        raise UserInputError(f"{src.name}: vehicle.overrides: {exc}") from None
    n_axles = len(data.get("axles") or [])
    # struts: "all" first, then per axle
    for key in sorted(S.struts, key=lambda k: (k != "all", k)):
        choice = S.struts[key]
        axles = range(n_axles) if key == "all" else [int(key[4:]) - 1]
        for k in axles:
            if not 0 <= k < n_axles:
                raise UserInputError(f"{src.name}: struts.{key}: the vehicle has {n_axles} axles (axle1..axle{n_axles})")
            axle = dict(data["axles"][k])
            if choice.strut is not None:
                t = choice.strut
                axle["strut"] = resolve_path(t, src.base_dir) if t.endswith((".yaml", ".yml")) else t
            if choice.overrides:
                axle["strut_overrides"] = apply_overrides(axle.get("strut_overrides") or {}, choice.overrides)
            data["axles"][k] = axle
    # strut files named in the vehicle file are relative to the vehicle file
    for k, axle in enumerate(data.get("axles") or []):
        if isinstance(axle, dict) and isinstance(axle.get("strut"), dict):
            axle = data["axles"][k] = {**axle, "strut": strut_reference(axle["strut"], f"axles.{k}.strut")}
        if isinstance(axle, dict) and str(axle.get("strut", "")).endswith((".yaml", ".yml")):
            base = src.base_dir if any(S.struts.get(n) and S.struts[n].strut for n in ("all", f"axle{k + 1}")) \
                else Path(path).resolve().parent
            data["axles"][k] = {**axle, "strut": resolve_path(axle["strut"], base)}
    comp = {k: v for k, v in S.compensation.model_dump().items() if v is not None}
    data["compensation"] = {**(data.get("compensation") or {}), **comp}
    return data, str(path)


def prepare(src: ScenarioSource) -> Prepared:
    """Validate everything the scenario refers to (vehicle, struts, road, temperatures); build nothing."""
    from pydantic import ValidationError

    S = validate_scenario(src)
    data, vpath = vehicle_data(S, src)
    try:
        vehicle = VehicleParams.model_validate(data)
    except ValidationError as exc:
        raise UserInputError(format_validation_error(exc, f"{src.name}: vehicle ({vpath} with the scenario's "
                                                          "overrides)")) from None
    for k, axle in enumerate(vehicle.axles):
        try:
            load_strut(axle.strut, axle.strut_overrides or None)
        except UserInputError as exc:
            raise UserInputError(f"{src.name}: struts.axle{k + 1} (strut {axle.strut!r}): {exc}") from None
    # initial temperatures: one, one per axle or one per station (axle-major, left first)
    T = S.initial_temperatures if S.initial_temperatures is not None else S.ambient_temperature
    T = vehicle.per_station(T, f"{src.name}: initial_temperatures")
    # road
    road_spec = road_spec_from(S, vehicle, src)
    # speed: every form as the drive's distance -> speed table (a recorded drive is read here)
    try:
        speed = build_speed_profile(S.speed, S.distance, src.base_dir)
        check_profile(speed, S.distance, S.max_acceleration, S.max_jerk)     # what it asks of the vehicle
    except UserInputError as exc:
        raise UserInputError(f"{src.name}: {exc}") from None
    return Prepared(source=src, scenario=S, vehicle=vehicle, road_spec=road_spec, initial_temperatures_K=T,
                    speed_profile=speed)


def road_length_needed(S: Scenario, vehicle) -> float:
    """Road length [m] the front axle reads: the drive's distance plus its last step (1 m, as
    vehicle.engines.full samples it) plus the tyre's enveloping length ahead of the contact point."""
    return S.distance + 1.0 + vehicle.max_contact_length()


def road_spec_from(S: Scenario, vehicle, src: ScenarioSource):
    from pydantic import ValidationError

    try:
        RoadSpec = terrain.RoadSpec
    except (ImportError, AttributeError):
        raise UserInputError("road: the terrain package (terrain.RoadSpec, terrain.build_road) is not available") from None
    data = dict(S.road)
    fields = getattr(RoadSpec, "model_fields", {})
    if "length" in fields and data.get("length") is None and data.get("csv") is None and data.get("crg") is None:
        # the road must reach the last axle at the end of the drive (plus the tyre's envelope)
        wheelbase = max(a.position for a in vehicle.axles)
        data["length"] = S.distance + wheelbase + 2.0 * vehicle.max_contact_length() + 10.0
    if "track_width" in fields and data.get("track_width") is None:
        data["track_width"] = vehicle.track      # left/right coherence at the vehicle's track
    try:
        spec = RoadSpec.model_validate(data)
    except ValidationError as exc:
        msg = format_validation_error(exc, src.name)
        # pydantic's locations are relative to the road mapping: prefix them
        msg = "; ".join(_prefix_loc(part, src.name, "road") for part in msg.split("; "))
        raise UserInputError(msg) from None
    except UserInputError as exc:
        raise UserInputError(f"{src.name}: road: {exc}") from None
    needed = road_length_needed(S, vehicle)
    if spec.length is not None and spec.length < needed:
        raise UserInputError(f"{src.name}: road.length: {spec.length:.6g} m is shorter than the drive, which needs "
                             f"{needed:.6g} m (distance + the tyre's contact length + 1 m); leave road.length out "
                             "to get the default")
    return spec


def _prefix_loc(part: str, name: str, prefix: str) -> str:
    head = f"{name}: "
    if part.startswith(head):
        rest = part[len(head):]
        if rest.startswith("(top level)"):
            rest = rest[len("(top level)"):]
            return f"{head}{prefix}{rest}"
        return f"{head}{prefix}.{rest}"
    return part


def load_prepared(path: str | Path) -> Prepared:
    return prepare(read_scenario(path))
