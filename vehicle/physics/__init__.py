"""Vehicle physics: the equations and parameters, nothing about how they are run.

    params        typed vehicle parameters from YAML (VehicleParams, load_vehicle)
    hull          rigid hull in bounce, pitch and roll: kinematics and Newton-Euler
    tyre          point-contact tyre with lift-off
    thermal       strut heat: convection, radiation, the heat node
    compensation  levelling (pressure compensation) law
    model         the vehicle DAE (VehicleModel): states, inputs, parameters, equations
    equilibrium   statics: charging the gas springs, standing equilibrium

Imports: hpsim, struts, terrain and this package only (tests/test_layers.py).
"""
