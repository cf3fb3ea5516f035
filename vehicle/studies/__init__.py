"""Studies of many runs: parameter sweeps, uncertainty quantification, calibration.

    sweep        many scenarios in parallel
    uq           priors drawn, Sobol' indices, prediction bands
    calibration  the one heat-transfer parameter against a measured mean rise (noise-aware)
    cost         what a study will cost before it starts (drives, estimated wall time)
    confidence   how far a sensitivity ranking can be trusted
"""
