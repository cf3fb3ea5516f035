"""Studies over many drives: sweeps, uncertainty quantification, calibration, and what they cost."""
