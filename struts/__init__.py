"""Hydropneumatic strut models: gas, oil, valves, friction; rig tests (no vehicle knowledge)."""
