"""The Python API: run scenarios and read results from a notebook or a script.

    import vehicle
    sim = vehicle.Simulation("scenarios/quick_demo.yaml", overrides={"speed": "30 km/h"})
    res = sim.run()                 # in memory; sim.run(out="x.h5") writes HDF5 as `hpsim run` does
    res.report()                    # the per-axle table of `hpsim report` (res.summary() gives the numbers)
    ds = res.to_xarray()            # DataTree: time/distance/station/axle/km coordinates, units in attrs
    res.plot("dashboard.png")       # the dashboard of `hpsim plot`
    vehicle.open_results("x.h5")    # any results file -> the same Results object
    vehicle.optimize("scenarios/optimize_strut.yaml", "strut_opt", trials=24)   # `hpsim optimize`: the front

Overrides are scenario key paths, as in sweeps (`vehicle.overrides.heat.capacity`,
`road.iso_class`, `struts.all.overrides.valve.bleed_area`, ...). A parameter change reuses the
compiled model of an earlier run in the same process (parameters are inputs of the compiled code).

Arguments are checked as the CLI checks its files: every error is a `hpsim.errors.UserInputError` with the
one-line message `hpsim` prints (an unknown series or group: `UnknownName`, also a `KeyError`, listing the valid
names). Numbers may be NumPy scalars or arrays; a scenario mapping is copied when the Simulation is made (later
changes to it do not reach the drive); relative file paths in a mapping refer to `base_dir` (default: the working
directory when the Simulation is made).
"""
from __future__ import annotations

import numbers
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from hpsim.errors import UserInputError

from vehicle.physics.outputs import VARIABLES, Split
from vehicle.physics.params import load_vehicle, vehicle_file
from vehicle.physics.vehicle_builder import spec_from_values, write_vehicle
from vehicle.physics.vehicle_check import check_vehicle
from vehicle.scenario.schema import ScenarioSource, apply_overrides, prepare, read_scenario
from vehicle.results.reader import open_results as _open
from vehicle.results.run import run_in_memory, run_scenario
from vehicle.analysis.ride_metrics import summarise
from vehicle.analysis.summary import report_from

__all__ = ["Simulation", "Results", "open_results", "Vehicle", "UnknownName", "optimize"]


class UnknownName(UserInputError, KeyError):
    """A series, statistics variable or group that the results do not hold; the message lists the valid names."""

    def __str__(self) -> str:             # the message as given (KeyError would quote it)
        return str(self.args[0]) if self.args else ""


def plain(value: Any, where: str) -> Any:
    """A deep copy of a scenario value as YAML holds it: NumPy scalars and arrays as Python numbers and lists, tuples
    as lists, paths as strings; anything else is a UserInputError naming the key."""
    if value is None or isinstance(value, (str, bool)):
        return value
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real):
        return float(value)
    if isinstance(value, np.ndarray):
        return plain(value.tolist(), where)
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, Mapping):
        out = {}
        for k, v in value.items():
            if isinstance(k, np.generic):
                k = k.item()
            if not isinstance(k, (str, int)) or isinstance(k, bool):
                raise UserInputError(f"{where}: key {k!r}: expected a string (a scenario key)")
            out[k] = plain(v, f"{where}.{k}" if where else str(k))
        return out
    if isinstance(value, (list, tuple)):
        return [plain(v, f"{where}[{i}]") for i, v in enumerate(value)]
    raise UserInputError(f"{where or 'scenario'}: {type(value).__name__} is not a scenario value (numbers, strings "
                         "with units such as '20 km/h', lists and mappings)")


class Results:
    """Results of one drive, in memory or in a file: the same reading interface either way."""

    def __init__(self, view, path: Path | None = None):
        self._view = view           # vehicle.results.reader.ResultsView (MemorySink or ResultsFile)
        self.path = path
        self._closed = False

    @property
    def view(self):
        """The results view (vehicle.results.reader.ResultsView); a closed Results says so."""
        if self._closed:
            again = f"vehicle.open_results({str(self.path)!r})" if self.path else "Simulation.run()"
            raise UserInputError(f"{self.path or self._view.name}: these Results are closed; open them again with "
                                 f"{again}")
        return self._view

    def _unknown(self, what: str, name, valid: list[str]) -> UnknownName:
        return UnknownName(f"{self.path or self._view.name}: no {what} {name!r}; the results hold: "
                           f"{', '.join(valid) or 'none'}")

    def _names(self, reader) -> list[str]:
        """The file names of the variables `reader` (view.series or view.stats_series) finds."""
        names = []
        for entry in VARIABLES.values():
            names += [p.name for p in (entry.parts if isinstance(entry, Split) else [entry])]
        return [n for n in dict.fromkeys(names) if reader(n) is not None]

    def summary(self) -> dict:
        """The per-axle numbers `hpsim report --json` prints (temperatures, dh, dN, bands, warnings, ...)."""
        return report_from(self.view, str(self.path or self.view.name))

    def report(self, print_it: bool = True) -> str:
        """The per-axle table of `hpsim report` (printed, and returned as text)."""
        from vehicle.presentation.report import format_report

        text = format_report(self.summary())
        if print_it:
            print(text)
        return text

    def ride(self) -> dict:
        """Ride and road holding over the drive (what `hpsim report` tables and `--json` "ride" hold).

        Per seat: the ISO 2631-1 weighted RMS accelerations (Wk vertical, Wd lateral), comfort band, VDV and absorbed
        power, and from series stored densely enough the crest factor, MTVV and ISO 2631-5 spinal dose (Sed, per
        drive and per day; vehicle.physics.shocks). Per station: the dynamic load coefficient, lift-off share, end-stop time and energy, strut
        travel min/max/percentiles and histogram (vehicle.analysis.ride_metrics)."""
        return summarise(self.view)

    def stats(self, name: str):
        """One per-interval statistics variable by its file name (e.g. "weighted_rms_acceleration",
        "dynamic_load_coefficient", "strut_travel_histogram"): (km, ...) array."""
        value = self.view.stats_series(str(name))
        if value is None:
            raise self._unknown("statistics variable", name, self._names(self.view.stats_series))
        return value

    def to_xarray(self, group: str | None = None):
        """All groups as an xarray.DataTree, or one group (`"timeseries"`, `"stats"`, `"equilibrium/after"`, ...)
        as an xarray.Dataset: named dimensions, coordinates and units, as xarray reads the HDF5 file."""
        if group is not None and group not in self.view.groups():
            raise self._unknown("group", group, self.view.groups())
        return self.view.to_xarray(group)

    def series(self, name: str):
        """One stored variable by its file name (e.g. "strut_temperature", "wheel_load")."""
        value = self.view.series(str(name))
        if value is None:
            raise self._unknown("time series", name, self._names(self.view.series))
        return value

    def plot(self, out: str | Path = "dashboard.png") -> Path:
        """The dashboard figure (PNG/PDF/SVG by extension)."""
        from vehicle.presentation.plots import dashboard

        return dashboard(self.view if self.path is None else self.path, out)

    def close(self) -> None:
        if not self._closed:
            self._view.close()
            self._closed = True

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __repr__(self) -> str:
        where = self.path or "memory"
        if self._closed:
            return f"<vehicle.Results {self._view.name!r} ({where}), closed>"
        return f"<vehicle.Results {self.view.name!r} ({where}), status {self.view.status()}>"


class Vehicle:
    """A vehicle file (docs/vehicles.md) as an object: check it, hand it to `Simulation` in place of a name.

        truck = vehicle.Vehicle.from_file("truck_6x6")          # a built-in name or a path
        car = vehicle.Vehicle.new("car.yaml", positions=["0 m", "2.9 m"], mass="3.2 t", cg_x="1.3 m",
                                  track="1.7 m", ride_height="0.9 m", motion_ratio=0.5)
        car.check().ok; car.check().as_dict()["mode_summary"]
        vehicle.Simulation("scenarios/quick_demo.yaml", vehicle=car, overrides={"initial_temperatures": "30 degC"})
    """

    def __init__(self, path: str | Path):
        self.path = vehicle_file(path).resolve()
        self.params = load_vehicle(self.path)      # schema errors here (UserInputError naming file and key)

    @classmethod
    def from_file(cls, path: str | Path) -> "Vehicle":
        return cls(path)

    @classmethod
    def new(cls, path: str | Path, *, positions, track, ride_height, axle_loads=None, mass=None, cg_x=None,
            struts="apc", name: str | None = None, overwrite: bool = False, **options) -> "Vehicle":
        """Write a vehicle file as `hpsim vehicle new` does (quantities with units or SI numbers; lists per axle
        or one value) and load it. options: strut_deflection, motion_ratio, unsprung_mass, tyre_radius,
        cg_height, charging_temperature, description."""
        spec = spec_from_values(name or Path(path).stem, positions=positions, track=track, ride_height=ride_height,
                                axle_loads=axle_loads, mass=mass, cg_x=cg_x, struts=struts, **options)
        return cls(write_vehicle(spec, path, overwrite=overwrite))

    @property
    def name(self) -> str:
        return self.params.name

    def check(self, modes: bool = True):
        """`hpsim vehicle check` (vehicle.physics.vehicle_check.CheckReport: .ok, .errors, .warnings, .as_dict())."""
        return check_vehicle(self.params, str(self.path), modes=modes)

    def __repr__(self) -> str:
        return f"<vehicle.Vehicle {self.name!r} ({self.path}), {self.params.n_axles} axles>"


class Simulation:
    """A scenario (file or mapping) with overrides, validated at construction.

    Parameters
    ----------
    scenario
        A path to a scenario file, or a mapping of scenario keys (copied now: changing it later does not change
        this Simulation).
    overrides
        A mapping of scenario key paths to values.
    base_dir
        The folder relative file paths of a mapping refer to (road and speed CSVs, vehicle and strut files;
        default: the working directory now). A file's paths refer to its own folder.
    vehicle
        A Vehicle, a built-in name or a vehicle file, replacing the scenario's vehicle (keeping its vehicle
        overrides). A mapping may also hold a Vehicle as its `vehicle`."""

    def __init__(self, scenario: str | Path | Mapping, overrides: Mapping[str, Any] | None = None, *,
                 base_dir: str | Path | None = None, vehicle: "Vehicle | str | Path | None" = None):
        if isinstance(scenario, Mapping) and isinstance(scenario.get("vehicle"), Vehicle):
            scenario = {**scenario, "vehicle": {"file": str(scenario["vehicle"].path)}}
        if vehicle is not None:
            if overrides is not None and not isinstance(overrides, Mapping):
                raise UserInputError(f"overrides: expected a mapping of scenario key paths to values (e.g. "
                                     f"{{'speed': '30 km/h'}}), got {type(overrides).__name__}")
            path = vehicle.path if isinstance(vehicle, Vehicle) else Vehicle(vehicle).path
            overrides = {**(overrides or {}), "vehicle.file": str(path), "vehicle.name": None}

        if overrides is not None and not isinstance(overrides, Mapping):
            raise UserInputError(f"overrides: expected a mapping of scenario key paths to values (e.g. "
                                 f"{{'speed': '30 km/h'}}), got {type(overrides).__name__}")
        if isinstance(scenario, Mapping):
            data = plain(scenario, "")
            base = Path(base_dir if base_dir is not None else Path.cwd()).resolve()
            src = ScenarioSource(text=yaml.safe_dump(data, sort_keys=False), name=f"<scenario mapping, paths from {base}>",
                                 base_dir=base, data=data)
        elif isinstance(scenario, (str, Path)):
            src = read_scenario(scenario)
        else:
            raise UserInputError(f"scenario: expected a scenario file path or a mapping of scenario keys, got "
                                 f"{type(scenario).__name__}")
        if overrides:
            overrides = plain(overrides, "overrides")
            data = apply_overrides(src.data, overrides)
            text = f"# {src.name} with overrides {overrides}\n" + yaml.safe_dump(data, sort_keys=False)
            src = ScenarioSource(text=text, name=f"{src.name} (with overrides)", base_dir=src.base_dir, data=data)
        self.source = src
        self.prepared = prepare(src)          # every check now, before anything runs

    @property
    def scenario(self):
        """The validated scenario (pydantic model, SI values)."""
        return self.prepared.scenario

    def run(self, out: str | Path | None = None, *, overwrite: bool = False, resume: bool = False,
            progress: bool = False) -> Results:
        """Drive the scenario: in memory (default) or into an HDF5 file exactly as `hpsim run` writes it."""
        if out is None:
            return Results(run_in_memory(self.source))
        run_scenario(self.source, out, overwrite=overwrite, resume=resume, progress=progress)
        return open_results(out)


def open_results(path: str | Path) -> Results:
    """Any hpsim results file (also one written by an older hpsim, or a run that stopped) -> Results."""
    return Results(_open(path), Path(path))


def optimize(study: str | Path, output_dir: str | Path | None = None, *, trials: int | None = None,
             workers: int | None = None, scheduler: str | None = None, storage: str | None = None,
             ensemble: int | None = None, log=None, before_start=None) -> dict:
    """Run an optimisation study file (`hpsim optimize`, docs/optimize.md) into `output_dir` (default: the study
    file's name); returns the summary with its Pareto front.

        s = vehicle.optimize("scenarios/optimize_strut.yaml", "strut_opt", trials=24)
        s["pareto"][0]["design"], s["pareto"][0]["objectives"], s["pareto"][0]["vehicle_file"]

    The study resumes from `output_dir` when run again (no finished trial runs twice). storage: an Optuna database
    URL in place of `<output_dir>/study.db`. ensemble: the trials K at a time as ensemble lanes (`hpsim optimize
    --ensemble`; None: chosen, 1: off). log: a function given each progress line. before_start(trials to run)
    is called before any runs. Also writes pareto.png.
    """
    from vehicle.presentation.optimize_plots import pareto_plot
    from vehicle.studies.optimize_runner import check_objectives, optuna_module, run_study
    from vehicle.studies.optimize_study import load_study

    optuna_module()
    spec = load_study(study, trials=trials)
    if spec.trials is None:
        raise UserInputError(f"trials: give the number of trials (--trials, or trials: in the study file {study})")
    check_objectives(spec, log)
    out = Path(output_dir) if output_dir is not None else Path(Path(study).stem)
    summary = run_study(spec, out, workers=workers, scheduler=scheduler, storage=storage, log=log,
                        before_start=before_start, ensemble=ensemble)
    summary["files"]["pareto_png"] = str(pareto_plot(summary, out / "pareto.png"))
    return summary
