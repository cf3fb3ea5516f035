"""Running the physics: drives, scenarios, result sinks, summaries, sweeps, calibration.

    drive        a drive over a road with a speed profile, in blocks, into a sink
    scenario     scenario files: schema, validation, preparation
    results      the HDF5 result sink (checkpoints, resume)
    summary      per-axle summaries read back from results
    sweep        many scenarios in parallel
    calibration  the one heat-transfer parameter against a measured mean rise

Imports: hpsim, struts, terrain, vehicle.physics, vehicle.numerics and this package
(tests/test_layers.py).
"""
