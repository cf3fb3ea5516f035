"""Safe YAML loading and typed parameter models with units.

Parameter files hold quantities either as plain values ("4.8 MPa", 0.7) or with
their provenance: {value: "4.8 MPa", source: "seed 000 §2"}. Models declare the
SI unit of each field with `Quantity("Pa")`; validation errors are rewritten to
name the file, the key path, the value and what is allowed.

Every YAML text (files and scenario text) goes through `parse_yaml`: safe types only, no anchors
or aliases (a "billion laughs" document cannot expand), at most MAX_YAML_DEPTH levels of nesting,
duplicate keys are errors naming the key and both lines. Files are read by `read_text_file`:
UTF-8 only, at most MAX_TEXT_FILE_BYTES, and errors never quote the file's content.
"""
from __future__ import annotations

import copy
import functools
import reprlib
from pathlib import Path
from typing import Annotated, Any, ClassVar

import yaml
from pydantic import BaseModel, BeforeValidator, ConfigDict, ValidationError, model_validator

from .errors import UserInputError
from .files import decode_text, read_regular_bytes
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


def _plain_number(value: Any) -> Any:
    value = _strip_source(value)
    if isinstance(value, bool) or type(value).__name__ == "bool_":
        raise ValueError(f"expected a number, got {value!r} (a YAML true/false)")
    return value


def Plain():
    """Annotated float that also accepts the {value:, source:} provenance form (a boolean is refused: YAML reads
    `yes`, `true`, `on` as one, and pydantic would take it for 1.0)."""
    return Annotated[float, BeforeValidator(_plain_number)]


class Model(BaseModel):
    """Base for parameter models: unknown keys are errors (typo safety).

    Subclasses list the fields that must be physical: `_must_be_positive` (> 0), `_must_be_non_negative` (>= 0),
    `_must_be_fraction` (in [0, 1]); None (an optional field left out) is not checked.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True)
    _must_be_positive: ClassVar[tuple[str, ...]] = ()
    _must_be_non_negative: ClassVar[tuple[str, ...]] = ()
    _must_be_fraction: ClassVar[tuple[str, ...]] = ()

    @model_validator(mode="after")
    def _physical_ranges(self):
        problems = []
        for names, ok, allowed in ((self._must_be_positive, lambda v: v > 0, "> 0"),
                                   (self._must_be_non_negative, lambda v: v >= 0, ">= 0"),
                                   (self._must_be_fraction, lambda v: 0 <= v <= 1, "in [0, 1]")):
            for name in names:
                value = getattr(self, name)
                if value is not None and not ok(value):
                    problems.append(f"{name} must be {allowed}, got {value:g}")
        if problems:
            raise ValueError("; ".join(problems))
        return self


# limits of what a parameter, scenario or sweep file may be (they are a few kB; these are generous)
MAX_TEXT_FILE_BYTES = 4 * 1024 * 1024
MAX_YAML_DEPTH = 40


class _RefusedYAML(yaml.YAMLError):
    def __init__(self, mark, problem: str):
        super().__init__(problem)
        self.problem_mark = mark
        self.problem = problem


class _StrictConstructor:
    """Duplicate keys as errors (the constructor of both loaders below)."""

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            self.flatten_mapping(node)
            first_line: dict = {}
            for key_node, _ in node.value:
                key = self.construct_object(key_node, deep=True)
                try:
                    if key in first_line:
                        raise _RefusedYAML(key_node.start_mark, f"duplicate key {short_repr(key)} "
                                                                f"(first at line {first_line[key] + 1})")
                    first_line[key] = key_node.start_mark.line
                except TypeError:
                    continue      # an unhashable key: SafeConstructor reports it
        return super().construct_mapping(node, deep=deep)


def _refused_node(event, depth: int) -> _RefusedYAML | None:
    """Why a node (its event, at nesting depth `depth`, the document's root at 1) is refused: an alias or anchor
    (expanding aliases is how a small file becomes a huge document), or nesting deeper than MAX_YAML_DEPTH."""
    if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None) is not None:
        return _RefusedYAML(event.start_mark, "YAML anchors and aliases (&name, *name) are not allowed here; "
                                              "write the values out")
    if depth > MAX_YAML_DEPTH:
        return _RefusedYAML(event.start_mark, f"nested deeper than {MAX_YAML_DEPTH} levels")
    return None


class _StrictSafeLoader(_StrictConstructor, yaml.SafeLoader):
    """yaml.SafeLoader without anchors/aliases, with a nesting limit and duplicate keys as errors (pure Python: where
    PyYAML was built without libyaml)."""

    def __init__(self, stream):
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent, index):
        self._depth += 1
        try:
            refused = _refused_node(self.peek_event(), self._depth)
            if refused is not None:
                raise refused
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


_CSafeLoader = getattr(yaml, "CSafeLoader", None)
if _CSafeLoader is not None:
    class _StrictCSafeLoader(_StrictConstructor, _CSafeLoader):
        """libyaml's parser and composer (C: a tenth of the pure-Python loader's time) with the duplicate-key check;
        anchors, aliases and the nesting limit are checked on its events first (`_check_events`)."""


def _check_events(text: str) -> None:
    """Refuse anchors, aliases and deep nesting from libyaml's event stream, before anything is composed."""
    depth = 0
    for event in yaml.parse(text, Loader=_CSafeLoader):
        opens = isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent))
        if opens or isinstance(event, (yaml.ScalarEvent, yaml.AliasEvent)):
            refused = _refused_node(event, depth + 1)
            if refused is not None:
                raise refused
        if opens:
            depth += 1
        elif isinstance(event, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
            depth -= 1


def _load_strict(text: str) -> Any:
    if _CSafeLoader is None:
        return yaml.load(text, Loader=_StrictSafeLoader)
    _check_events(text)
    return yaml.load(text, Loader=_StrictCSafeLoader)


def parse_yaml(text: str, name: str) -> Any:
    """Parse YAML text safely; errors name `name`:line:column and never quote the text.

    The parsed documents of this process are cached by their text (a run reads the strut file once per axle and
    again for the results): each call returns its own deep copy,
    so callers may change what they get."""
    return copy.deepcopy(_parse_yaml_cached(text, name))


@functools.lru_cache(maxsize=64)
def _parse_yaml_cached(text: str, name: str) -> Any:
    try:
        return _load_strict(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"{name}:{mark.line + 1}:{mark.column + 1}" if mark else str(name)
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        kind = "" if isinstance(exc, _RefusedYAML) else "YAML syntax error: "
        raise UserInputError(f"{where}: {kind}{problem}") from None
    except RecursionError:
        raise UserInputError(f"{name}: nested too deeply (at most {MAX_YAML_DEPTH} levels)") from None


def read_text_file(path: str | Path, max_bytes: int = MAX_TEXT_FILE_BYTES) -> str:
    """The UTF-8 text of a small input file; errors name the file and never quote its content."""
    # a regular file only: a FIFO or a device would block or never end (hpsim.files)
    data = read_regular_bytes(path, max_bytes, "a small text file")
    return decode_text(data, str(path))


def load_yaml(path: str | Path) -> Any:
    """Parse a YAML file safely (see `parse_yaml`); errors name the file and line."""
    return parse_yaml(read_text_file(path), str(path))


_REPR = reprlib.Repr()
_REPR.maxstring = _REPR.maxother = 60
_REPR.maxlist = _REPR.maxtuple = _REPR.maxdict = _REPR.maxset = 6
_REPR.maxlevel = 3


def short_repr(value: Any) -> str:
    """A short repr of a value for error messages (long strings and big lists are cut)."""
    return _REPR.repr(value)


def format_validation_error(exc: ValidationError, source: str) -> str:
    """One line per problem: file, key path, value, what is allowed."""
    lines = []
    for err in exc.errors():
        loc = ".".join(short_repr(p) if not isinstance(p, (str, int)) or len(str(p)) > 60 else str(p)
                       for p in err["loc"]) or "(top level)"
        msg = err["msg"]
        if msg.startswith("Value error, "):
            msg = msg[len("Value error, "):]
        if err["type"] == "extra_forbidden":
            msg = "unknown key (check the spelling)"
        value = err.get("input")
        quiet = err["type"] in ("missing", "extra_forbidden") or isinstance(value, dict) or "got" in msg
        shown = "" if quiet else f" (got {short_repr(value)})"
        lines.append(f"{source}: {loc}: {msg}{shown}")
    return "; ".join(lines)


def validate(model: type[BaseModel], data: Any, source: str):
    """Validate `data` against `model`, raising UserInputError that names `source` and keys."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise UserInputError(format_validation_error(exc, source)) from None


def deep_update(base: dict, overrides: dict) -> dict:
    """Return a copy of `base` with nested `overrides` applied (dotted keys allowed; an integer step
    indexes a list that is there: `axles.0.tyre.stiffness`)."""
    out = dict(base)
    for key, value in overrides.items():
        if "." in key:
            head, rest = key.split(".", 1)
            if isinstance(out.get(head), list):
                out[head] = _update_item(out[head], rest, value, head)
            else:
                out[head] = deep_update(dict(out.get(head) or {}), {rest: value})
        elif isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = deep_update(out[key], value)
        else:
            out[key] = value
    return out


def _update_item(items: list, key: str, value, where: str) -> list:
    """Copy of `items` with `key` ("<index>" or "<index>.<rest>") set to `value`."""
    index, _, rest = key.partition(".")
    if not index.isdigit() or int(index) >= len(items):
        raise UserInputError(f"{where}.{key}: {where} is a list of {len(items)}; the step after {where} must be an "
                             f"index 0..{len(items) - 1}")
    out = list(items)
    k = int(index)
    out[k] = deep_update(dict(out[k]) if isinstance(out[k], dict) else {}, {rest: value}) if rest else value
    return out
