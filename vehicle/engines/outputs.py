"""The one table of results variables: what each key a drive hands to its sink is called in a
results file (and in `to_xarray()`), its dimensions, CF/UDUNITS units and long name.

A drive (vehicle.engines.full) hands its sink dicts keyed by *drive keys* (`strut_temperature_K`,
`wheel_load`, `hull_acceleration`, ...): blocks of time series, arrays (n,) or (width, n);
statistics rows, scalars or (width,); equilibria (vehicle.physics.equilibrium.Equilibrium
fields). The file and the xarray datasets use *variable names* from this table: CF-style, no unit
suffix, one quantity per variable (the hull accelerations, m s-2 and rad s-2, are split into
heave/pitch/roll variables), the same name for the same quantity in every group.

Adding a drive key is one line in VARIABLES. Its extra dimension (after `time` or `km`) follows
from its width unless given: n_stations -> `station`, n_axles -> `axle`, no width -> none.
Keys whose width could be ambiguous (3 hull degrees of freedom on a 3-axle vehicle) are split
explicitly. A key missing from the table raises UnknownDriveKey when the file layout is made,
before the drive starts.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

# the groups of a results file (docs/hdf5.md) and their record dimension
RECORD_DIM = {"timeseries": "time", "stats": "km"}
EQUILIBRIA = ("charged", "before", "after", "before_band", "after_band")
STATIC_GROUPS = tuple(f"equilibrium/{e}" for e in EQUILIBRIA) + ("summary",)
DATA_GROUPS = ("timeseries", "stats") + STATIC_GROUPS
LABEL_DIMS = ("station", "axle")
# dimensions whose size is the value's width (not the number of stations or axles): the seats of the
# vehicle file (labelled with their names when known), the strut-travel bins and their edges
FREE_DIMS = ("seat", "travel_bin", "travel_bin_edge")

AUTO = "auto"


@dataclass(frozen=True)
class Var:
    """A results variable. dim: "station", "axle", "seat", None (no extra dimension), AUTO (from the width) or
    a tuple of two of them (("station", "travel_bin"): a (n_stations, n_bins) value).
    role: "data", "record" (the group's record coordinate: time, km) or "coord" (a coordinate along
    the record dimension: distance). scale multiplies the drive's SI value (km = m * 1e-3)."""

    name: str
    units: str
    long_name: str
    dim: str | None = AUTO
    role: str = "data"
    scale: float = 1.0
    standard_name: str | None = None

    def attrs(self) -> dict:
        out = {"units": self.units, "long_name": self.long_name}
        if self.standard_name:
            out["standard_name"] = self.standard_name
        return out


@dataclass(frozen=True)
class Split:
    """A (k, n) drive array whose rows are different quantities: one variable per row."""

    parts: tuple[Var, ...]


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
    "t_s": Var("time", "s", "time since the start of the drive", None, "record", standard_name="time"),
    "distance_m": Var("distance", "m", "distance driven since the start", None, "coord"),
    "speed_m_per_s": Var("speed", "m s-1", "vehicle speed", None),
    "longitudinal_acceleration_m_per_s2": Var("longitudinal_acceleration", "m s-2",
                                              "longitudinal acceleration of the speed profile (+ forward)", None),
    # the strut heat network (vehicle.physics.thermal): "strut temperature" is the outer surface (pyrometer)
    "strut_temperature_K": Var("strut_temperature", "K", "outer surface temperature of the strut (pyrometer)",
                               "station"),
    "wall_temperature_K": Var("wall_temperature", "K", "temperature of the oil-wetted steel of the strut (wall node)",
                              "station"),
    "oil_temperature_K": Var("oil_temperature", "K", "oil temperature in the strut", "station"),
    "mean_gas_temperature_K": Var("mean_gas_temperature", "K", "gas temperature in the strut, mean over the "
                                  "interval's output samples (the gas swings with every bump)", "station"),
    "axle_height_change_m": Var("axle_height_change", "m",
                                "hull height change at the axle against the charged state", "axle"),
    "hull_acceleration": Split(tuple(Var(f"{d}_acceleration", u, t, None) for d, u, t in _HULL)),
    "heave_m": Var("heave", "m", "hull heave (up) against the charged state", None),
    "pitch_rad": Var("pitch", "rad", "hull pitch against the charged state", None),
    "roll_rad": Var("roll", "rad", "hull roll against the charged state", None),
    "oil_added_m3": Var("oil_added_volume", "m3", "oil volume added to the strut by the levelling system", "station"),
    "strut_force": Var("strut_force", "N", "force of the strut (positive pushing its ends apart)", "station"),
    "strut_deflection": Var("strut_deflection", "m", "strut deflection (0 at full extension)", "station"),
    "gas_pressure": Var("gas_pressure", "Pa", "absolute gas pressure in the strut", "station"),
    "gas_temperature": Var("gas_temperature", "K", "gas temperature in the strut", "station"),
    "wheel_load": Var("wheel_load", "N", "vertical tyre force on the road", "station"),
    **{f"energy_{e}_J": Var(f"energy_{e}", "J", text, "station") for e, text in _ENERGY.items()},
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


class UnknownDriveKey(KeyError):
    """A drive key that VARIABLES does not know (a programming error: add the key to the table)."""

    def __str__(self):
        return str(self.args[0])


def lookup(key: str) -> Var | Split:
    try:
        return VARIABLES[key]
    except KeyError:
        raise UnknownDriveKey(
            f"results variable table (vehicle/engines/outputs.py VARIABLES) has no entry for the drive key {key!r}: "
            f"add one line, e.g. {key!r}: Var(\"<cf_name>\", \"<udunits>\", \"<long name>\")") from None


@dataclass(frozen=True)
class FileVariable:
    """One variable as stored: where it comes from (drive key, row of a split, scale) and how it is laid out."""

    name: str
    key: str
    dims: tuple[str, ...]
    attrs: dict = field(hash=False, compare=False)
    role: str = "data"
    row: int | None = None
    scale: float = 1.0

    def take(self, value, record: bool) -> np.ndarray:
        """The drive's array (..., n) or (width,)/scalar -> the stored layout ((n, width) record-major)."""
        a = np.asarray(value, float)
        if self.row is not None:
            a = a[self.row]
        if record and a.ndim >= 2:
            a = np.moveaxis(a, -1, 0)
        return a * self.scale if self.scale != 1.0 else a


def _width_dim(key: str, var: Var, shape: tuple, n_stations: int, n_axles: int) -> tuple[str, ...]:
    if not shape:
        if var.dim not in (None, AUTO):
            raise ValueError(f"drive key {key!r}: the table gives dim {var.dim!r} but the value has no width")
        return ()
    sizes = {"station": n_stations, "axle": n_axles}
    if isinstance(var.dim, tuple):
        if len(shape) != len(var.dim):
            raise ValueError(f"drive key {key!r}: values of shape {shape} do not match the table's dims {var.dim}")
        for d, width in zip(var.dim, shape):
            if d not in FREE_DIMS and sizes.get(d) != width:
                raise ValueError(f"drive key {key!r}: width {width} does not match the table's dim {d!r}")
        return var.dim
    if len(shape) > 1:
        raise ValueError(f"drive key {key!r}: values of shape {shape} are not supported (at most one width axis)")
    width = shape[0]
    if var.dim in FREE_DIMS:
        return (var.dim,)
    if var.dim == AUTO:
        dims = [d for d, n in sizes.items() if n == width]
        if len(dims) != 1:
            raise ValueError(f"drive key {key!r}: width {width} is neither the {n_stations} stations nor the "
                             f"{n_axles} axles; give its dim in vehicle/engines/outputs.py VARIABLES")
        return (dims[0],)
    if var.dim is None or sizes.get(var.dim) != width:
        raise ValueError(f"drive key {key!r}: width {width} does not match the table's dim {var.dim!r}")
    return (var.dim,)


def file_variables(key: str, width_shape: tuple, group: str, n_stations: int, n_axles: int) -> list[FileVariable]:
    """The stored variables of one drive key. width_shape: the value's shape without the sample axis
    ((), (width,) or (k,) for a split)."""
    entry = lookup(key)
    record = RECORD_DIM.get(group)
    lead = (record,) if record else ()
    if isinstance(entry, Split):
        if tuple(width_shape) != (len(entry.parts),):
            raise ValueError(f"drive key {key!r}: expected {len(entry.parts)} rows, got shape {width_shape}")
        return [FileVariable(v.name, key, lead, v.attrs(), v.role, j, v.scale) for j, v in enumerate(entry.parts)]
    dims = lead if entry.role == "record" else lead + _width_dim(key, entry, tuple(width_shape), n_stations, n_axles)
    return [FileVariable(entry.name, key, dims, entry.attrs(), entry.role, None, entry.scale)]


def label_attrs(dim: str) -> dict:
    return {"station": {"long_name": "wheel station (axle-major, left first)"},
            "axle": {"long_name": "axle (front first)"},
            "seat": {"long_name": "seat on the hull (vehicle file's seats)"}}[dim]


def group_dataset(group: str, arrays: dict, stations, axles, attrs: dict | None = None, seats=None):
    """An xarray.Dataset of one group from drive-keyed arrays (record groups: drive-shaped (..., n)
    arrays; static groups: (width,) or scalars) -- the same names, dims, coordinates and attributes
    that the HDF5 file holds (tests/test_results_xarray.py checks both)."""
    xr = require_xarray()
    record = RECORD_DIM.get(group)
    n_st, n_ax = len(stations), len(axles)
    data_vars, coords = {}, {}
    for key, value in arrays.items():
        a = np.asarray(value, float)
        width_shape = a.shape[:-1] if record else a.shape
        for v in file_variables(key, width_shape, group, n_st, n_ax):
            arr = v.take(a, bool(record))
            if v.role == "record":
                coords[v.name] = ((v.name,), arr, v.attrs)
            elif v.role == "coord":
                coords[v.name] = (v.dims, arr, v.attrs)
            else:
                data_vars[v.name] = (v.dims, arr, v.attrs)
    coords["station"] = (("station",), np.array([str(s) for s in stations]), label_attrs("station"))
    coords["axle"] = (("axle",), np.array([str(a) for a in axles]), label_attrs("axle"))
    if seats and any("seat" in v[0] for v in data_vars.values()):
        coords["seat"] = (("seat",), np.array([str(s) for s in seats]), label_attrs("seat"))
    return xr.Dataset(data_vars, coords=coords, attrs=dict(attrs or {}))


def require_xarray():
    try:
        import xarray
    except ImportError:
        raise ImportError("to_xarray() needs xarray and h5netcdf: pip install xarray h5netcdf") from None
    return xarray
