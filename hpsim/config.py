"""Safe YAML loading and typed parameter models with units.

Parameter files hold quantities either as plain values ("4.8 MPa", 0.7) or with
their provenance: {value: "4.8 MPa", source: "seed 000 §2"}. Models declare the
SI unit of each field with `Quantity("Pa")`; validation errors are rewritten to
name the file, the key path, the value and what is allowed.
"""
from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import yaml
from pydantic import BaseModel, BeforeValidator, ConfigDict, ValidationError

from .errors import UserInputError
from .units import parse_quantity


def _strip_source(value: Any) -> Any:
    if isinstance(value, dict) and "value" in value and set(value) <= {"value", "source", "note", "prior"}:
        return value["value"]
    return value


def Quantity(unit: str):
    """Annotated float type parsed from a number (SI) or a string with units."""

    def _parse(value: Any) -> float:
        value = _strip_source(value)
        return parse_quantity(value, unit, where=f"quantity in {unit}")

    return Annotated[float, BeforeValidator(_parse)]


def QuantityList(unit: str):
    """Annotated list of floats, each a number (SI) or a string with units."""

    def _parse(value: Any) -> list[float]:
        value = _strip_source(value)
        if not isinstance(value, (list, tuple)):
            raise ValueError(f"expected a list of quantities in {unit}")
        return [parse_quantity(_strip_source(v), unit, where=f"item {i} (in {unit})") for i, v in enumerate(value)]

    return Annotated[list[float], BeforeValidator(_parse)]


def Plain():
    """Annotated float that also accepts the {value:, source:} provenance form."""
    return Annotated[float, BeforeValidator(_strip_source)]


class Model(BaseModel):
    """Base for parameter models: unknown keys are errors (typo safety)."""

    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True)


def load_yaml(path: str | Path) -> Any:
    """Parse YAML safely (no object construction from tags); errors name the file and line."""
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise UserInputError(f"{path}: file not found") from None
    except OSError as exc:
        raise UserInputError(f"{path}: cannot read ({exc.strerror})") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"{path}:{mark.line + 1}:{mark.column + 1}" if mark else str(path)
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise UserInputError(f"{where}: YAML syntax error: {problem}") from None


def format_validation_error(exc: ValidationError, source: str) -> str:
    """One line per problem: file, key path, value, what is allowed."""
    lines = []
    for err in exc.errors():
        loc = ".".join(str(p) for p in err["loc"]) or "(top level)"
        msg = err["msg"]
        if msg.startswith("Value error, "):
            msg = msg[len("Value error, "):]
        if err["type"] == "extra_forbidden":
            msg = "unknown key (check the spelling)"
        value = err.get("input")
        quiet = err["type"] in ("missing", "extra_forbidden") or isinstance(value, dict) or "got" in msg
        shown = "" if quiet else f" (got {value!r})"
        lines.append(f"{source}: {loc}: {msg}{shown}")
    return "; ".join(lines)


def validate(model: type[BaseModel], data: Any, source: str):
    """Validate `data` against `model`, raising UserInputError that names `source` and keys."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise UserInputError(format_validation_error(exc, source)) from None


def deep_update(base: dict, overrides: dict) -> dict:
    """Return a copy of `base` with nested `overrides` applied (dotted keys allowed)."""
    out = dict(base)
    for key, value in overrides.items():
        if "." in key:
            head, rest = key.split(".", 1)
            out[head] = deep_update(dict(out.get(head) or {}), {rest: value})
        elif isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = deep_update(out[key], value)
        else:
            out[key] = value
    return out
