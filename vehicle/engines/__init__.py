"""Engines: how a drive is integrated (the ensemble engine: many cases in lockstep, vehicle.engines.ensemble)."""
