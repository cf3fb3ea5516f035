"""A tour of the Python API (docs/python.md), as a script: run it with `python examples/notebook_tour.py`.

A short drive in memory with an override, the per-axle report, the results as xarray, the same drive
written to HDF5 and read back, and the dashboard figure.
"""
from pathlib import Path
import sys
import tempfile

import vehicle

ROOT = Path(__file__).resolve().parents[1]
out_dir = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="hpsim_tour_"))

sim = vehicle.Simulation(ROOT / "scenarios" / "quick_demo.yaml",
                         overrides={"distance": "300 m", "speed": "30 km/h"})
res = sim.run()                                  # in memory
res.report()

tree = res.to_xarray()                           # xarray.DataTree of every group
ts = tree["timeseries"].to_dataset()
print(ts["strut_temperature"])                   # (time, station), units K

# Two different "wheel load" numbers, named as the report names them:
summary = res.summary()
# dN [%] (the report's column; summary "max_abs_dN_pct"): the change of the STANDING wheel load between the
# weighings before and after the drive, as the struts warmed up: a fraction of a percent
print("report dN, largest |dN| [%]:", round(summary["max_abs_dN_pct"], 3))
# DLC (the report's road-holding column): the RMS of the DYNAMIC wheel load while driving over the static
# load, per station; its peaks are tens of percent on a class D road, and say nothing about dN
print("report DLC, largest over the stations:",
      round(max(st["dynamic_load_coefficient"] for st in summary["ride"]["stations"]), 3))
print("peak dynamic wheel load while driving, above the mean static load at the start [%] (neither dN nor DLC):",
      round(float(100 * (ts["wheel_load"].max() / ts["wheel_load"].isel(time=0).mean() - 1)), 1))

path = out_dir / "tour.h5"
with sim.run(out=path, overwrite=True) as from_file:   # the same run, written as `hpsim run` writes it
    assert from_file.summary()["axles"] == res.summary()["axles"]
    print("dashboard:", from_file.plot(out_dir / "tour_dashboard.png"))
print("results file:", path)
