"""The Python API: run scenarios and read results from a notebook or a script.

    import vehicle
    sim = vehicle.Simulation("scenarios/quick_demo.yaml", overrides={"speed": "30 km/h"})
    res = sim.run()                 # in memory; sim.run(out="x.h5") writes HDF5 as `hpsim run` does
    res.report()                    # the per-axle table of `hpsim report` (res.summary() gives the numbers)
    ds = res.to_xarray()            # DataTree: time/distance/station/axle/km coordinates, units in attrs
    res.plot("dashboard.png")       # the dashboard of `hpsim plot`
    vehicle.open_results("x.h5")    # any results file -> the same Results object

Overrides are scenario key paths, as in sweeps (`vehicle.overrides.heat.capacity`,
`road.iso_class`, `struts.all.overrides.valve.bleed_area`, ...). A parameter change reuses the
compiled model of an earlier run in the same process (parameters are inputs of the compiled code).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from vehicle.physics.params import load_vehicle, vehicle_file
from vehicle.physics.vehicle_builder import spec_from_values, write_vehicle
from vehicle.physics.vehicle_check import check_vehicle
from vehicle.scenario.schema import ScenarioSource, apply_overrides, prepare, read_scenario
from vehicle.results.reader import open_results as _open
from vehicle.results.run import run_in_memory, run_scenario
from vehicle.analysis.ride_metrics import summarise
from vehicle.analysis.summary import report_from

__all__ = ["Simulation", "Results", "open_results", "Vehicle"]


class Results:
    """Results of one drive, in memory or in a file: the same reading interface either way."""

    def __init__(self, view, path: Path | None = None):
        self.view = view            # vehicle.results.reader.ResultsView (MemorySink or ResultsFile)
        self.path = path

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
        """Ride and road holding over the drive (what `hpsim report` tables and `--json` "ride" hold): per seat
        the ISO 2631-1 weighted RMS accelerations (Wk vertical, Wd lateral), comfort band, VDV and absorbed
        power, and from series stored densely enough the crest factor, MTVV and ISO 2631-5 spinal dose (Sed, per
        drive and per day; vehicle.physics.shocks); per station the dynamic load coefficient, lift-off share, end-stop time and energy, strut
        travel min/max/percentiles and histogram (vehicle.analysis.ride_metrics)."""
        return summarise(self.view)

    def stats(self, name: str):
        """One per-interval statistics variable by its file name (e.g. "weighted_rms_acceleration",
        "dynamic_load_coefficient", "strut_travel_histogram"): (km, ...) array."""
        return self.view.stats_series(name)

    def to_xarray(self, group: str | None = None):
        """All groups as an xarray.DataTree, or one group (`"timeseries"`, `"stats"`, `"equilibrium/after"`, ...)
        as an xarray.Dataset: named dimensions, coordinates and units, as xarray reads the HDF5 file."""
        return self.view.to_xarray(group)

    def series(self, name: str):
        """One stored variable by its file name (e.g. "strut_temperature", "wheel_load")."""
        return self.view.series(name)

    def plot(self, out: str | Path = "dashboard.png") -> Path:
        """The dashboard figure (PNG/PDF/SVG by extension)."""
        from vehicle.presentation.plots import dashboard

        return dashboard(self.view if self.path is None else self.path, out)

    def close(self) -> None:
        self.view.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __repr__(self) -> str:
        where = self.path or "memory"
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
    """A scenario (file, mapping or YAML text) with overrides, validated at construction. `vehicle` (a Vehicle,
    a built-in name or a vehicle file) replaces the scenario's vehicle, keeping its vehicle overrides; a mapping
    may also hold a Vehicle as its `vehicle`."""

    def __init__(self, scenario: str | Path | dict, overrides: dict[str, Any] | None = None, *,
                 base_dir: str | Path | None = None, vehicle: "Vehicle | str | Path | None" = None):
        if isinstance(scenario, dict) and isinstance(scenario.get("vehicle"), Vehicle):
            scenario = {**scenario, "vehicle": {"file": str(scenario["vehicle"].path)}}
        if vehicle is not None:
            path = vehicle.path if isinstance(vehicle, Vehicle) else Vehicle(vehicle).path
            overrides = {**(overrides or {}), "vehicle.file": str(path), "vehicle.name": None}
        if isinstance(scenario, dict):
            import yaml

            src = ScenarioSource(text=yaml.safe_dump(scenario, sort_keys=False), name="<scenario dict>",
                                 base_dir=Path(base_dir or ".").resolve(), data=scenario)
        else:
            src = read_scenario(scenario)
        if overrides:
            import yaml

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
