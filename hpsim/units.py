"""Quantities with units: "41.8 kN", "4.8 MPa", "20 degC", "115 mm".

Bare numbers are SI. Everything inside hpsim is SI (m, s, kg, N, Pa, K, W, J).
Parsing is done by pint; this module only fixes the registry and the error
messages. Conversions that succeeded are kept in hpsim's private cache folder
(`hpsim.cache`, one small JSON file per pint version and version of this module),
so that a command whose quantities were all seen before neither imports pint nor
builds its registry (together ~0.6 s).
"""
from __future__ import annotations

import atexit
import functools
import hashlib
import json
import math
import numbers
import os
import re
import tempfile
from importlib import metadata
from pathlib import Path
from typing import Any

from .cache import trusted_cache_dir
from .errors import UserInputError

# A quantity is a short text: a number and a unit expression ("41.8 kN", "5e-12 m^3/(Pa*s)").
# Longer or odd-shaped text never reaches pint, whose parser takes minutes on some long strings
# and evaluates number towers such as "10**10**10" exactly.
MAX_QUANTITY_CHARS = 64
MAX_LIST_ITEMS = 100
_NUMBER = r"[+-]?(?:\d{1,30}(?:\.\d{0,30})?|\.\d{1,30})(?:[eE][+-]?\d{1,3})?"
_TOKEN = re.compile(rf"\s*(?:(?P<number>{_NUMBER})|(?P<name>[^\W\d]\w*|°\w*|%)|(?P<power>\*\*|\^)|(?P<op>[*/()]))")
_EXPONENT = re.compile(r"[+-]?\d{1,2}(?:\.\d{1,3})?")
MAX_PARENTHESES = 4


def _shown(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else f"{text[:30]}...' ({len(str(value))} characters)"


def check_quantity_text(text: str, where: str, unit: str) -> None:
    """Refuse text that is not shaped like a quantity before the unit library sees it."""
    example = f"expected e.g. '12.5 {unit}'"
    if len(text) > MAX_QUANTITY_CHARS:
        raise UserInputError(f"{where}: {_shown(text)} is too long for a quantity (at most {MAX_QUANTITY_CHARS} "
                             f"characters); {example}")
    pos, depth, prev = 0, 0, None
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None or m.end() == pos:
            if text[pos:].strip() == "":
                break
            raise UserInputError(f"{where}: {_shown(text)}: cannot read character {pos + 1} of a quantity; {example}")
        kind = m.lastgroup
        token = m.group(kind)
        if kind == "op" and token == "(":
            depth += 1
            if depth > MAX_PARENTHESES:
                raise UserInputError(f"{where}: {_shown(text)}: more than {MAX_PARENTHESES} nested parentheses "
                                     f"in a quantity; {example}")
        elif kind == "op" and token == ")":
            depth -= 1
        if prev == "power":
            # an exponent is a small number applied to a unit: "m**3", "s^-1" (never a tower)
            if kind != "number" or not _EXPONENT.fullmatch(token):
                raise UserInputError(f"{where}: {_shown(text)}: an exponent must be a number of at most two digits "
                                     f"after a unit, e.g. 'm**3'; {example}")
            kind = "exponent"
        elif kind == "power" and prev not in ("name", "close"):
            raise UserInputError(f"{where}: {_shown(text)}: '**' or '^' must follow a unit, e.g. 'm**3'; {example}")
        elif kind == "power" and prev == "exponent":
            raise UserInputError(f"{where}: {_shown(text)}: exponent of an exponent; {example}")
        prev = "close" if token == ")" else kind
        pos = m.end()


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
    if isinstance(value, bool) or type(value).__name__ == "bool_":
        raise UserInputError(f"{where}: expected a quantity in {unit}, got {_shown(value)}")
    if isinstance(value, numbers.Real):          # int, float and NumPy's numbers
        out = float(value)
    elif isinstance(value, str):
        text = value.strip()
        if not text:
            raise UserInputError(f"{where}: empty value, expected a quantity in {unit}")
        if (text, unit) in _PARSED:               # a sweep validates the same strings in every case
            return _PARSED[(text, unit)]
        known = _stored().get(f"{unit}\0{text}")
        if known is not None:
            _PARSED[(text, unit)] = known
            return known
        check_quantity_text(text, where, unit)
        ureg = registry()
        try:
            q = ureg.Quantity(text)
        except Exception as exc:  # pint raises several error types
            raise UserInputError(
                f"{where}: cannot read {_shown(value)} as a quantity ({exc.__class__.__name__}); "
                f"expected e.g. '12.5 {unit}'"
            ) from None
        if isinstance(q, (int, float)):
            out = float(q)
        elif q.dimensionless and ureg.Quantity(1, unit).dimensionless:
            out = float(q.to(unit).magnitude)
        elif q.dimensionless:
            if q.units != ureg.dimensionless:
                # "12 parsecs/furlong" is a pure number to pint: units that cancel are no quantity in `unit`
                raise UserInputError(f"{where}: {_shown(value)} is not a quantity in {unit} "
                                     f"(its units {q.units} cancel)")
            # a bare number in a string: SI
            out = float(q.magnitude)
        else:
            try:
                out = float(q.to(unit).magnitude)
            except Exception:
                raise UserInputError(
                    f"{where}: {_shown(value)} has units of {q.dimensionality}, expected {unit}"
                ) from None
    else:
        raise UserInputError(f"{where}: expected a quantity in {unit}, got {_shown(value)}")
    if not math.isfinite(out):
        raise UserInputError(f"{where}: {_shown(value)} is not a finite number")
    if isinstance(value, str) and len(_PARSED) < _PARSED_MAX:
        _PARSED[(value.strip(), unit)] = out
        _NEW[f"{unit}\0{value.strip()}"] = out
    return out


# successful conversions of quantity strings (pint takes ~1 ms each; validating a study's cases repeats them)
_PARSED: dict = {}
_PARSED_MAX = 100_000
# conversions kept on disk (`_stored`): at most this many, those of this process added at its exit
_STORED_MAX = 20_000
_NEW: dict = {}


def _store_path() -> Path | None:
    """The file of stored conversions in the trusted cache folder (None: no trusted folder, or pint not found)."""
    try:
        pint_version = metadata.version("pint")
    except metadata.PackageNotFoundError:
        return None
    d = trusted_cache_dir()
    if d is None:
        return None
    digest = hashlib.sha256(Path(__file__).read_bytes() + pint_version.encode()).hexdigest()[:16]
    return d / f"quantities_{digest}.json"


@functools.lru_cache(maxsize=1)
def _stored() -> dict:
    """The conversions stored by earlier processes ("unit\\0text" -> SI value), read once; their writer is
    registered to run at exit. Anything but finite numbers is ignored (a damaged file costs pint time, nothing
    else)."""
    path = _store_path()
    if path is None:
        return {}
    atexit.register(_write_new, path)
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    if not isinstance(data, dict):
        return {}
    return {k: float(v) for k, v in data.items()
            if isinstance(k, str) and type(v) in (int, float) and math.isfinite(v)}


def _write_new(path: Path) -> None:
    """Add this process's new conversions to the stored ones (written to a temporary name and renamed: atomic)."""
    if not _NEW:
        return
    merged = {**_stored(), **_NEW}
    if len(merged) > _STORED_MAX:
        return
    try:
        fd, tmp = tempfile.mkstemp(prefix=".quantities-", dir=path.parent)
        with os.fdopen(fd, "w") as fh:
            json.dump(merged, fh)
        os.replace(tmp, path)
    except OSError:
        pass


def parse_quantity_list(text: str, unit: str, *, where: str = "value") -> list[float]:
    """Comma-separated quantities: "10mm,50mm" -> [0.01, 0.05]."""
    items = [t for t in str(text).split(",") if t.strip()]
    if not items:
        raise UserInputError(f"{where}: expected one or more quantities in {unit}")
    if len(items) > MAX_LIST_ITEMS:
        raise UserInputError(f"{where}: {len(items)} values, at most {MAX_LIST_ITEMS}")
    return [parse_quantity(t, unit, where=where) for t in items]
