"""Strut models by layout: `make_strut(params)` picks the model class for a parameter file.

    separated   struts.separated.SeparatedStrut (seed 000)
    integrated  struts.integrated.IntegratedStrut (seed 001)

Both implement `struts.protocol.Strut`.
"""
from __future__ import annotations

from .integrated import IntegratedStrut
from .params import StrutParams
from .protocol import MECHANISMS, Strut, StrutInputs
from .separated import SeparatedStrut

__all__ = ["MECHANISMS", "IntegratedStrut", "SeparatedStrut", "Strut", "StrutInputs", "make_strut", "STRUT_LAYOUTS"]

STRUT_LAYOUTS = {"separated": SeparatedStrut, "integrated": IntegratedStrut}


def make_strut(params: StrutParams, gas_properties=None, *, check: bool = True) -> Strut:
    """The model for a parameter set's layout. check=False skips the geometry checks (used for the
    symbolic copy of already checked parameters, whose values are CasADi symbols)."""
    cls = STRUT_LAYOUTS[params.layout]
    if check:
        cls.check_parameters(params)
    return cls(params, gas_properties)
