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

from vehicle.runs.scenario import ScenarioSource, apply_overrides, prepare, read_scenario

__all__ = ["Simulation", "Results", "open_results"]


class Results:
    """Results of one drive, in memory or in a file: the same reading interface either way."""

    def __init__(self, view, path: Path | None = None):
        self.view = view            # vehicle.runs.reader.ResultsView (MemorySink or ResultsFile)
        self.path = path

    def summary(self) -> dict:
        """The per-axle numbers `hpsim report --json` prints (temperatures, dh, dN, bands, warnings, ...)."""
        from vehicle.runs.summary import report_from

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
        drive and per day; vehicle.analysis.shocks); per station the dynamic load coefficient, lift-off share, end-stop time and energy, strut
        travel min/max/percentiles and histogram (vehicle.runs.ride_metrics)."""
        from vehicle.runs.ride_metrics import summarise

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


class Simulation:
    """A scenario (file, mapping or YAML text) with overrides, validated at construction."""

    def __init__(self, scenario: str | Path | dict, overrides: dict[str, Any] | None = None, *,
                 base_dir: str | Path | None = None):
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
        from vehicle.runs.results import run_in_memory, run_scenario

        if out is None:
            return Results(run_in_memory(self.source))
        run_scenario(self.source, out, overwrite=overwrite, resume=resume, progress=progress)
        return open_results(out)


def open_results(path: str | Path) -> Results:
    """Any hpsim results file (also one written by an older hpsim, or a run that stopped) -> Results."""
    from vehicle.runs.reader import open_results as _open

    return Results(_open(path), Path(path))
