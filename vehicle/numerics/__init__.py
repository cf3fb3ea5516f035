"""Numerics: solvers for the vehicle DAE and the compiled-code cache.

    solvers   compiled fixed-step Rosenbrock-W (ROS2) stepper, IDAS reference

Imports: hpsim and this package only; solvers receive the model's CasADi functions
(tests/test_layers.py).
"""
