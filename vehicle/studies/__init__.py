"""Studies of many runs: parameter sweeps, uncertainty quantification, calibration.

    sweep:       many scenarios in parallel
    uq:          priors drawn, Sobol' indices, prediction bands
    calibration: the one heat-transfer parameter against a measured mean rise (noise-aware)
    uq_per_axle: priors drawn per axle or station (independent or correlated)
    validate:    predictions beside measurements (hpsim validate)
    cost:        what a study will cost before it starts (drives, estimated wall time)
    study_folder: one writer per study folder, sanitised case names, each case's definition recorded
    confidence:  how far a sensitivity ranking can be trusted
"""
