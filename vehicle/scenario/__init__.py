"""What to drive: the scenario schema (every default written once), overrides, speed profiles,
reading and preparing a scenario. Imports no engine.

    schema      scenario files: schema, validation, overrides, preparation
    speed       speed profiles (constant, by distance, by time, random)
"""
