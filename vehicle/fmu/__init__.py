"""FMI 2.0 co-simulation export of the strut (with its heat network) and of the whole vehicle (docs/fmu.md).

`strut_unit` is one strut with its heat network as a model the compiled ROS2 solver steps. `exports` makes the
specification of either FMU (the strut's, or the vehicle DAE's with the start state solved at export: functions,
variables, units, sources). `build` turns a specification into an .fmu archive (the solver's step, the outputs and
the start state generated as C by CasADi, the FMI wrapper `fmi2_wrapper.c`, modelDescription.xml from
`description`, a binary for this platform and the sources).
"""
