"""Parameters as run-time inputs of compiled models.

A compiled model should not have to be regenerated and recompiled because a number changed
(a sweep, a calibration, a notebook). `symbolic_copy` turns a typed parameter model (pydantic,
`hpsim.config.Model`) into a copy whose numeric values are CasADi symbols, collected in a
`ParameterVector`; the equations are then built on the copy, and the compiled function takes
the vector's values as an input. What stays a Python value is *structure*:

- strings, booleans, integers, None, free-text dicts (layout, gas model, friction model, ...),
- numbers that are exactly zero: a zero switches a mechanism off (no leakage, no check valve,
  no hysteresis band), and the equations drop the term; changing it from zero compiles anew,
- fields a caller declares structural (`keep`).

`ParameterVector.structure` fingerprints all of that (names and order of the symbolic values,
every structural value), so two parameter sets with equal structure share one compiled model.
"""
from __future__ import annotations

import hashlib
import json
from typing import Any, Callable

import casadi as ca
import numpy as np
from pydantic import BaseModel


class ParameterVector:
    """Named numeric parameters as CasADi symbols: the `theta` input of a compiled model."""

    def __init__(self):
        self.names: list[str] = []
        self.values: list[float] = []
        self._symbols: list[ca.SX] = []
        self._skeleton: dict[str, Any] = {}

    def add(self, name: str, value: float) -> ca.SX:
        s = ca.SX.sym(name)
        self.names.append(name)
        self.values.append(float(value))
        self._symbols.append(s)
        return s

    def __len__(self) -> int:
        return len(self.names)

    @property
    def symbols(self) -> ca.SX:
        return ca.vertcat(*self._symbols) if self._symbols else ca.SX(0, 1)

    def numeric(self) -> np.ndarray:
        return np.asarray(self.values, float)

    def note_structure(self, path: str, value: Any) -> None:
        self._skeleton[path] = value

    @property
    def structure(self) -> str:
        """Hash of everything that shapes the equations (not the values of the symbols)."""
        text = json.dumps({"symbols": self.names, "structure": self._skeleton}, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def _is_number(value: Any) -> bool:
    return isinstance(value, (float, np.floating)) and not isinstance(value, bool)


def symbolic_copy(model: BaseModel, vec: ParameterVector, path: str = "",
                  keep: Callable[[str], bool] = lambda path: False):
    """Copy of `model` (validated values) with every non-zero float a symbol of `vec` (see module doc).

    The copy is built with `model_construct` (no validation: the values are symbols), so its
    methods (derived quantities such as a sprung mass) work on the symbols too.
    """
    def convert(value: Any, where: str):
        if isinstance(value, BaseModel):
            return symbolic_copy(value, vec, where, keep)
        if isinstance(value, list):
            return [convert(v, f"{where}.{k}") for k, v in enumerate(value)]
        if isinstance(value, tuple):
            return tuple(convert(v, f"{where}.{k}") for k, v in enumerate(value))
        if _is_number(value) and value != 0.0 and not keep(where):
            return vec.add(where, value)
        # free-form mappings (a strut's overrides, calibration notes) carry no structure of their own: what
        # they change shows in the parameters they were applied to
        vec.note_structure(where, "<mapping>" if isinstance(value, dict) else value)
        return value

    fields = {name: convert(getattr(model, name), f"{path}.{name}" if path else name)
              for name in type(model).model_fields}
    return type(model).model_construct(**fields)
