"""The vehicle: assembles `struts` and `terrain` into a multi-axle hull DAE and runs scenarios.

Python API (`vehicle.api`, docs/python.md):

    import vehicle
    res = vehicle.Simulation("scenarios/quick_demo.yaml").run()
    res.report(); ds = res.to_xarray(); res.plot("dashboard.png")
    vehicle.open_results("x.h5")
    truck = vehicle.Vehicle.from_file("truck_6x6"); truck.check()   # docs/vehicles.md
    vehicle.optimize("scenarios/optimize_strut.yaml", "strut_opt")     # docs/optimize.md

Subpackages (one-way imports, tests/test_layers.py): physics, numerics <- scenario <- engines <- results <-
analysis <- studies <- presentation, fmu <- cli, api (README.md, "How the code is laid out").
"""
from __future__ import annotations

__all__ = ["Simulation", "Results", "open_results", "Vehicle", "optimize"]


def __getattr__(name):
    # lazy: `import vehicle.physics...` stays light and free of the running layer
    if name in __all__:
        from vehicle import api

        return getattr(api, name)
    raise AttributeError(f"module 'vehicle' has no attribute {name!r}")
