"""The one range and quantity check, and its message, for every file, key and argument.

`in_range` accepts the ends as printed ("150 km/h" converts to 41.66666666666667 m/s, one ulp above
150/3.6: a relative slack of 1e-9 of the larger end) and otherwise raises ValueError (pydantic reports
it at the key's path; outside pydantic, `check_range` raises a UserInputError naming the key):

    <name> must be in [<lo>, <hi>] <unit>, got <value> <unit>

Values are SI; `scale` and `offset` show them in the unit the user wrote (km/h: scale 3.6; degC:
offset -273.15).
"""
from __future__ import annotations

from typing import Any

from hpsim.errors import UserInputError
from hpsim.units import parse_quantity

RELATIVE_SLACK = 1e-9


def range_message(value: float, lo: float, hi: float, unit: str = "", scale: float = 1.0, offset: float = 0.0,
                  name: str | None = None, note: str = "") -> str:
    u = f" {unit}" if unit else ""
    head = f"{name} must be in" if name else "must be in"
    tail = f" ({note})" if note else ""
    return (f"{head} [{lo * scale + offset:.6g}, {hi * scale + offset:.6g}]{u}, "
            f"got {value * scale + offset:.6g}{u}{tail}")


def in_range(value: float, lo: float, hi: float, unit: str = "", scale: float = 1.0, offset: float = 0.0,
             name: str | None = None, note: str = "") -> float:
    """value if lo <= value <= hi (within RELATIVE_SLACK of the larger end), else ValueError."""
    slack = RELATIVE_SLACK * max(abs(lo), abs(hi))
    if not lo - slack <= value <= hi + slack:
        raise ValueError(range_message(value, lo, hi, unit, scale, offset, name, note))
    return value


def check_range(key: str, value: float, lo: float, hi: float, unit: str = "", scale: float = 1.0,
                offset: float = 0.0, note: str = "") -> float:
    """in_range for a key outside a pydantic model: UserInputError '<key>: must be in [...]'."""
    try:
        return in_range(value, lo, hi, unit, scale, offset, note=note)
    except ValueError as exc:
        raise UserInputError(f"{key}: {exc}") from None


def check_count(key: str, value: int | None, lo: int = 1) -> None:
    """A count given on the command line (workers, trials): None (not given) or at least `lo`; otherwise a
    UserInputError '<key>: must be >= <lo>, got <value>'."""
    if value is not None and value < lo:
        raise UserInputError(f"{key}: must be >= {lo}, got {value}")


def quantity(unit: str, value: Any, where: str | None = None) -> float:
    """A number or a quantity text in SI `unit`; parse_quantity raises UserInputError (a ValueError), which
    pydantic reports at the key's path."""
    return parse_quantity(value, unit, where=where or f"expected a quantity in {unit}")
