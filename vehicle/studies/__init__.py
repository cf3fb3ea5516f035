"""Studies over many drives: sweeps, uncertainty quantification, calibration, validation against measurements."""
