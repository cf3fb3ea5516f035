"""Studies: many runs of one definition (sweeps, uncertainty quantification) in one folder."""
