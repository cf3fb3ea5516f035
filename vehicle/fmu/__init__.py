"""FMI 2.0 co-simulation export of the strut (with its heat network) and of the whole vehicle (docs/fmu.md).

`strut_unit` is one strut with its heat network as a model the compiled ROS2 solver steps, `vehicle_unit` the
vehicle DAE with an exported initial state; `build` turns either into an .fmu archive (the solver's step and the
outputs generated as C by CasADi, the FMI wrapper `fmi2_wrapper.c`, modelDescription.xml, a binary for this
platform and the sources).
"""
