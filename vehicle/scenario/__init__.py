"""What to drive: the scenario schema (every default written once), overrides, speed profiles,
reading and preparing a scenario. Imports no engine.

    schema      scenario files: schema, validation, overrides, preparation
    settings    the settings an engine runs with, and their defaults
    speed       speed profiles (constant, by distance, by time, random)
    speed_limits  the accelerations and jerks a speed profile implies, against documented limits
    work_limits   the work a scenario asks for (steps, samples, memory, files), checked before anything runs
"""
