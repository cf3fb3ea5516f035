"""Quantities with units: "41.8 kN", "4.8 MPa", "20 degC", "115 mm".

Bare numbers are SI. Everything inside hpsim is SI (m, s, kg, N, Pa, K, W, J).
Parsing is done by pint; this module only fixes the registry and the error
messages.
"""
from __future__ import annotations

import functools
import math
from typing import Any

from .errors import UserInputError


@functools.lru_cache(maxsize=1)
def registry():
    import pint

    # Offset units (degC) are converted to kelvin when they take part in arithmetic.
    return pint.UnitRegistry(autoconvert_offset_to_baseunit=True)


def parse_quantity(value: Any, unit: str, *, where: str = "value") -> float:
    """Return `value` expressed in `unit` (an SI unit string such as "Pa", "K", "m/s").

    `value` may be a number (taken as already in `unit`) or a string with units.
    `where` names the argument or key in error messages.
    """
    if isinstance(value, bool):
        raise UserInputError(f"{where}: expected a quantity in {unit}, got {value!r}")
    if isinstance(value, (int, float)):
        out = float(value)
    elif isinstance(value, str):
        text = value.strip()
        if not text:
            raise UserInputError(f"{where}: empty value, expected a quantity in {unit}")
        ureg = registry()
        try:
            q = ureg.Quantity(text)
        except Exception as exc:  # pint raises several error types
            raise UserInputError(
                f"{where}: cannot read {value!r} as a quantity ({exc.__class__.__name__}); "
                f"expected e.g. '12.5 {unit}'"
            ) from None
        if isinstance(q, (int, float)):
            out = float(q)
        elif q.dimensionless and ureg.Quantity(1, unit).dimensionless:
            out = float(q.to(unit).magnitude)
        elif q.dimensionless:
            if q.units != ureg.dimensionless:
                # "12 parsecs/furlong" is a pure number to pint: units that cancel are no quantity in `unit`
                raise UserInputError(f"{where}: {value!r} is not a quantity in {unit} (its units {q.units} cancel)")
            # a bare number in a string: SI
            out = float(q.magnitude)
        else:
            try:
                out = float(q.to(unit).magnitude)
            except Exception:
                raise UserInputError(
                    f"{where}: {value!r} has units of {q.dimensionality}, expected {unit}"
                ) from None
    else:
        raise UserInputError(f"{where}: expected a quantity in {unit}, got {value!r}")
    if not math.isfinite(out):
        raise UserInputError(f"{where}: {value!r} is not a finite number")
    return out


def parse_quantity_list(text: str, unit: str, *, where: str = "value") -> list[float]:
    """Comma-separated quantities: "10mm,50mm" -> [0.01, 0.05]."""
    items = [t for t in str(text).split(",") if t.strip()]
    if not items:
        raise UserInputError(f"{where}: expected one or more quantities in {unit}")
    return [parse_quantity(t, unit, where=where) for t in items]


def kelvin_to_celsius(t_kelvin):
    return t_kelvin - 273.15


def celsius_to_kelvin(t_celsius):
    return t_celsius + 273.15
