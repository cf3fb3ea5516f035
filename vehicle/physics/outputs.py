"""The one output table: every quantity a drive stores, declared once.

Each entry maps a *drive key* (what an engine hands its sink: `strut_temperature_K`, `wheel_load`, ...) to
its stored variable: CF name, UDUNITS units, long name, extra dimension (after `time` or `km`) and, for a
time series, how a drive computes it from a block of states and model outputs (`From`) and whether the
time-parallel join corrects it (`From.join`). Engines (vehicle.engines) compute the series from it; the
results layer (vehicle.results: sinks, reader, the file layout in vehicle.results.variables), the
scenario's `output.store` and the analysis read it.

Adding a stored time series is one entry here (docs/CONTRIBUTING.md has a worked example that a test
runs). Its extra dimension follows from its width unless given: n_stations -> `station`, n_axles ->
`axle`, no width -> none. A key missing from the table raises UnknownDriveKey when the file layout is
made, before the drive starts.
"""
from __future__ import annotations

from dataclasses import dataclass

AUTO = "auto"
JOINS = ("state", "output", "quadrature")


@dataclass(frozen=True)
class From:
    """How a drive computes a time series from a block (vehicle.engines.full.Drive.block_outputs):

    kind "time", "distance"      the samples' time [s] and distance [m]
         "input"                 a model input row (name: vehicle.physics.model input name: speed, acceleration)
         "heat_node"             a node of each strut's heat network (name: surface, wall, oil; vehicle.physics.thermal)
         "state"                 one model state (name: z, theta, phi, ...)
         "station_state"         one state per station (name: V_oil -> V_oil[0..n-1])
         "energy"                a station's energy quadrature (name: valve, friction, gas, ...)
         "output"                a model output per station (name: VehicleModel.split_outputs key)
         "axle_heights", "hull_accelerations"   the model's axle heights and hull accelerations
    join  how the time-parallel join (vehicle.engines.time_parallel) corrects it for the slow-state correction:
          "state" (the slow states moved, through the slaving), "output" (through d(output)/d(slow states)),
          "quadrature" (offset by the previous segments' totals), None (not corrected: time, inputs, the
          hull accelerations)."""

    kind: str
    name: str = ""
    join: str | None = None

    def __post_init__(self):
        if self.join is not None and self.join not in JOINS:
            raise ValueError(f"From.join: {self.join!r}, expected one of {JOINS} or None")


@dataclass(frozen=True)
class Var:
    """A results variable. dim: "station", "axle", "seat", None (no extra dimension), AUTO (from the width) or
    a tuple of two of them (("station", "travel_bin"): a (n_stations, n_bins) value).
    role: "data", "record" (the group's record coordinate: time, km) or "coord" (a coordinate along
    the record dimension: distance). scale multiplies the drive's SI value (km = m * 1e-3). series: for a
    time series, how a drive computes it from a block (`From`); None for statistics, equilibria, summaries."""

    name: str
    units: str
    long_name: str
    dim: str | None = AUTO
    role: str = "data"
    scale: float = 1.0
    standard_name: str | None = None
    series: From | None = None

    def attrs(self) -> dict:
        out = {"units": self.units, "long_name": self.long_name}
        if self.standard_name:
            out["standard_name"] = self.standard_name
        return out


@dataclass(frozen=True)
class Split:
    """A (k, n) drive array whose rows are different quantities: one variable per row."""

    parts: tuple[Var, ...]
    series: From | None = None


_HULL = (("heave", "m s-2", "vertical acceleration of the hull at its centre of gravity"),
         ("pitch", "rad s-2", "pitch acceleration of the hull"),
         ("roll", "rad s-2", "roll acceleration of the hull"))
_ENERGY = {"valve": "energy dissipated in the damping valves of the strut since the start",
           "friction": "energy dissipated by seal friction in the strut since the start",
           "gas": "heat from the gas to the strut body since the start",
           "end_stop": "energy dissipated in the end stops of the strut since the start",
           "strut_work": "work done on the strut since the start",
           "tyre_work": "work done on the tyre since the start",
           "road_work": "work done by the road on the tyre since the start",
           "longitudinal_work": "work of the longitudinal acceleration's pitch moment and anti-pitch linkage "
                                "forces on hull and wheel since the start (the hull's share per station)"}
_POWER = {"valve": "power dissipated in the damping valves of the strut",
          "friction": "power dissipated by seal friction in the strut",
          "gas": "heat flow from the gas to the strut body",
          "end_stop": "power dissipated in the end stops of the strut"}

# drive key -> variable. Keys of blocks, statistics rows, equilibria and the summary in one table.
VARIABLES: dict[str, Var | Split] = {
    # time series (block keys)
    "t_s": Var("time", "s", "time since the start of the drive", None, "record", standard_name="time",
                series=From("time")),
    "distance_m": Var("distance", "m", "distance driven since the start", None, "coord", series=From("distance")),
    "speed_m_per_s": Var("speed", "m s-1", "vehicle speed", None, series=From("input", "speed")),
    "longitudinal_acceleration_m_per_s2": Var("longitudinal_acceleration", "m s-2",
                                              "longitudinal acceleration of the speed profile (+ forward)", None,
                                              series=From("input", "acceleration")),
    # the strut heat network (vehicle.physics.thermal): "strut temperature" is the outer surface (pyrometer)
    "strut_temperature_K": Var("strut_temperature", "K", "outer surface temperature of the strut (pyrometer)",
                               "station", series=From("heat_node", "surface", join="state")),
    "wall_temperature_K": Var("wall_temperature", "K", "temperature of the oil-wetted steel of the strut (wall node)",
                              "station", series=From("heat_node", "wall", join="state")),
    "oil_temperature_K": Var("oil_temperature", "K", "oil temperature in the strut", "station",
                             series=From("heat_node", "oil", join="state")),
    "mean_gas_temperature_K": Var("mean_gas_temperature", "K", "gas temperature in the strut, mean over the "
                                  "interval's output samples (the gas swings with every bump)", "station"),
    "axle_height_change_m": Var("axle_height_change", "m",
                                "hull height change at the axle against the charged state", "axle",
                                series=From("axle_heights", join="output")),
    "hull_acceleration": Split(tuple(Var(f"{d}_acceleration", u, t, None) for d, u, t in _HULL),
                               series=From("hull_accelerations")),
    "heave_m": Var("heave", "m", "hull heave (up) against the charged state", None, series=From("state", "z", join="state")),
    "pitch_rad": Var("pitch", "rad", "hull pitch against the charged state", None,
                      series=From("state", "theta", join="state")),
    "roll_rad": Var("roll", "rad", "hull roll against the charged state", None, series=From("state", "phi", join="state")),
    "oil_added_m3": Var("oil_added_volume", "m3", "oil volume added to the strut by the levelling system", "station",
                         series=From("station_state", "V_oil", join="state")),
    "pump_oil_volume_m3": Var("pump_oil_volume", "m3", "oil volume the levelling pump moved into and out of the "
                              "strut since the start (integral of the absolute flow)", "station",
                              series=From("station_state", "V_pump", join="quadrature")),
    "strut_force": Var("strut_force", "N", "force of the strut (positive pushing its ends apart)", "station",
                        series=From("output", "strut_force", join="output")),
    "strut_deflection": Var("strut_deflection", "m", "strut deflection (0 at full extension)", "station",
                             series=From("output", "strut_deflection", join="output")),
    "gas_pressure": Var("gas_pressure", "Pa", "absolute gas pressure in the strut", "station",
                         series=From("output", "gas_pressure", join="output")),
    "gas_temperature": Var("gas_temperature", "K", "gas temperature in the strut", "station",
                            series=From("output", "gas_temperature", join="output")),
    "wheel_load": Var("wheel_load", "N", "vertical tyre force on the road", "station",
                       series=From("output", "wheel_load", join="output")),
    **{f"energy_{e}_J": Var(f"energy_{e}", "J", text, "station", series=From("energy", e, join="quadrature"))
       for e, text in _ENERGY.items()},
    # statistics rows (one per output.stats_interval of distance)
    "distance_end_m": Var("km", "km", "distance at the end of the statistics interval", None, "record", 1e-3),
    "duration_s": Var("duration", "s", "duration of the statistics interval", None),
    **{f"power_{e}_W": Var(f"power_{e}", "W", f"mean {text} over the interval", "station") for e, text in _POWER.items()},
    "window_start_m": Var("window_start", "km", "multiscale mode: distance at the start of the window's averaged "
                          "stretch (the row's interval ends at km)", None, "coord", 1e-3),
    # summary of a multiscale run (vehicle.engines.multiscale): a-posteriori error of the sampled road; of a
    # time-parallel run (vehicle.engines.time_parallel): estimated error of the slow-state correction at the joins
    "estimated_error_strut_temperature_K": Var("estimated_error_strut_temperature", "K", "multiscale mode: "
                                               "estimated error (95 % interval) of the final strut temperature; "
                                               "time_parallel: of the correction", "station"),
    "estimated_error_axle_temperature_K": Var("estimated_error_axle_temperature", "K", "multiscale mode: estimated "
                                              "error (95 % interval) of the final mean strut temperature of the axle; "
                                              "time_parallel: of the correction", "axle"),
    "estimated_error_load_change_pct": Var("estimated_error_load_change", "percent", "multiscale mode: estimated "
                                           "error (95 % interval) of the wheel load change of the axle; "
                                           "time_parallel: of the correction", "axle"),
    "pump_oil_volume_interval_m3": Var("pump_oil_volume_interval", "m3", "oil volume the levelling pump moved "
                                       "into and out of the strut in the interval", "station"),
    "rms_strut_velocity_m_per_s": Var("rms_strut_velocity", "m s-1", "RMS strut velocity over the interval",
                                      "station"),
    # ride and road holding (vehicle.physics.ride, vehicle.analysis.ride_metrics)
    "weighted_rms_acceleration_m_s2": Var("weighted_rms_acceleration", "m s-2", "ISO 2631-1 Wk frequency-weighted "
                                          "RMS vertical acceleration at the seat over the interval", "seat"),
    "weighted_rms_lateral_acceleration_m_s2": Var("weighted_rms_lateral_acceleration", "m s-2",
                                                  "ISO 2631-1 Wd frequency-weighted RMS lateral acceleration at the "
                                                  "seat (hull roll) over the interval", "seat"),
    "vdv_m_s175": Var("vibration_dose_value", "m s-1.75", "ISO 2631-1 vibration dose value (Wk) at the seat over "
                      "the interval", "seat"),
    "absorbed_power_W": Var("absorbed_power", "W", "mean vertical absorbed power at the seat over the interval",
                            "seat"),
    "dynamic_load_coefficient": Var("dynamic_load_coefficient", "1", "standard deviation over mean of the tyre "
                                    "load over the interval", "station"),
    "lift_off_share": Var("lift_off_share", "1", "share of the interval with the tyre off the ground", "station"),
    "end_stop_time_s": Var("end_stop_time", "s", "time on an end stop of the strut in the interval", "station"),
    "end_stop_energy_J": Var("end_stop_energy", "J", "energy dissipated in the end stops in the interval",
                             "station"),
    "strut_travel_min_m": Var("strut_travel_min", "m", "smallest strut deflection in the interval (to the "
                              "travel-bin width)", "station"),
    "strut_travel_max_m": Var("strut_travel_max", "m", "largest strut deflection in the interval (to the "
                              "travel-bin width)", "station"),
    "strut_travel_histogram_s": Var("strut_travel_histogram", "s", "time in each strut-travel bin in the interval "
                                    "(bin edges: strut_travel_bin_edges; the outer bins open)",
                                    ("station", "travel_bin")),
    "strut_travel_bin_edges_m": Var("strut_travel_bin_edges", "m", "edges of the strut-travel bins",
                                    ("station", "travel_bin_edge")),
    "rms_hull_acceleration": Split(tuple(Var(f"rms_{d}_acceleration", u, f"RMS {t} over the interval", None)
                                         for d, u, t in _HULL)),
    # equilibria (vehicle.physics.equilibrium.Equilibrium fields; heave_m, pitch_rad, roll_rad as above)
    "wheel_displacement_m": Var("wheel_displacement", "m", "wheel displacement (up) against the charged state",
                                "station"),
    "wheel_loads_N": Var("wheel_load", "N", "vertical tyre force on the road", "station"),
    "strut_forces_N": Var("strut_force", "N", "force of the strut (positive pushing its ends apart)", "station"),
    "strut_deflections_m": Var("strut_deflection", "m", "strut deflection (0 at full extension)", "station"),
    "gas_pressures_Pa": Var("gas_pressure", "Pa", "absolute gas pressure in the strut", "station"),
    # the standing strut's oil and gas temperature (the statics' temperature; before the drive every
    # node of the heat network is at it)
    "temperatures_K": Var("oil_temperature", "K", "oil temperature in the strut", "station"),
    # the weighing bands (vehicle.physics.weighing): nominal = frictionless, low/high over all seal-friction states
    **{f"wheel_loads_{e}_N": Var(f"wheel_load_{e}", "N", f"wheel load of the standing vehicle ({e})", "station")
       for e in ("nominal", "low", "high")},
    **{f"axle_loads_{e}_N": Var(f"axle_load_{e}", "N", f"axle load of the standing vehicle ({e})", "axle")
       for e in ("nominal", "low", "high")},
    **{f"station_height_change_{e}_m": Var(f"station_height_change_{e}", "m",
                                           f"hull height change above the station ({e})", "station")
       for e in ("nominal", "low", "high")},
    **{f"axle_height_change_{e}_m": Var(f"axle_height_change_{e}", "m", f"hull height change at the axle ({e})", "axle")
       for e in ("nominal", "low", "high")},
    "static_friction_rebound_N": Var("static_friction_rebound", "N", "static seal friction holding the strut "
                                     "against extension", "station"),
    "static_friction_compression_N": Var("static_friction_compression", "N", "static seal friction holding the strut "
                                         "against compression", "station"),
}


# time series stored whatever `output.store` says
ALWAYS_STORED = ("t_s", "distance_m")


def series_keys() -> tuple[str, ...]:
    """The time series a drive produces, in the table's order: what `output.store` picks from (read from the table
    when called, so an entry added to VARIABLES is a stored series at once)."""
    return tuple(k for k, v in VARIABLES.items() if v.series is not None and k not in ALWAYS_STORED)


def joined(join: str) -> tuple[str, ...]:
    """The time series the time-parallel join corrects in the given way ("state", "output", "quadrature")."""
    return tuple(k for k, v in VARIABLES.items() if v.series is not None and v.series.join == join)


class UnknownDriveKey(KeyError):
    """A drive key that VARIABLES does not know (a programming error: add the key to the table)."""

    def __str__(self):
        return str(self.args[0])


def lookup(key: str) -> Var | Split:
    try:
        return VARIABLES[key]
    except KeyError:
        raise UnknownDriveKey(
            f"results variable table (vehicle/physics/outputs.py VARIABLES) has no entry for the drive key {key!r}: "
            f"add one line, e.g. {key!r}: Var(\"<cf_name>\", \"<udunits>\", \"<long name>\")") from None


def variable_name(drive_key: str) -> str:
    """The stored variable name of a drive key (the key itself for a split or unknown key)."""
    entry = VARIABLES.get(drive_key)
    return entry.name if isinstance(entry, Var) else drive_key
