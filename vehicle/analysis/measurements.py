"""Measurement files: what a vehicle test measured, with units, sources and uncertainties (docs/measurements.md;
read by `hpsim validate`).

    description: "example test, values invented"
    source: "test report 12/2026"                         # optional; else the description is the source
    instruments:
      pyrometer: {uncertainty: 2 K}                       # standard uncertainty (1 sigma) of one reading
      photogrammetry: {uncertainty: 5 mm}
      scale: {uncertainty: 20 daN, source: "class III overrun scale"}
    points:
      - {quantity: surface_temperature, axle: 1, before: 20.0 degC, after: 80.0 degC, instrument: pyrometer}
      - {quantity: height, wheel: 2R, after: 1470 mm, uncertainty: 3 mm, instrument: photogrammetry}
    series:
      - {quantity: surface_temperature, axle: 1, csv: logs/t1.csv, x: {column: time_s, unit: s},
         y: {column: T_C, unit: degC}}
      - {quantity: surface_temperature, axle: 2, mdf: logs/run.mf4, y: {channel: T2, unit: degC}}

Every value carries its unit (pint through hpsim.units; a bare number is refused: a measurement without a
unit is ambiguous). A point is per axle (`axle: k`, the mean of its two wheels, as hpsim report shows) or per
wheel (`wheel: 1L`/`1R`, a station); `before` and `after` (either or both) are readings standing before and
after the drive; with both, the change (after - before) is compared, so a temperature rise written in degC
readings is a difference in K. An uncertainty is given per value or per instrument (one of them is
required); for a temperature it is a difference (K, not degC).

Series are logged over time (x in s, min, h) or distance (m, km), from CSV (a UTF-8 file, BOM and CRLF
tolerated, `#` comment lines skipped) or MDF4 (`mdf:`, through asammdf: the optional extra
`pip install -e ".[mdf]"`; x is the channel's time stamps unless `x: {channel: ...}` names a distance channel).

`read_measurements(path)` returns a MeasurementFile; every error is a UserInputError naming the file, the
key (`points[2].after`) and the allowed range.
"""
from __future__ import annotations

import csv
import io
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hpsim.config import load_yaml, read_text_file
from hpsim.errors import UserInputError
from hpsim.units import parse_quantity, registry
from hpsim.extras import install_hint


@dataclass(frozen=True)
class QuantityKind:
    """A measurable quantity: its SI unit, the unit shown, the allowed range of a reading [SI] and of an
    uncertainty [SI], and the instrument type that reads it by default."""

    si: str
    shown: str
    reading: tuple[float, float]
    uncertainty_max: float
    instrument: str
    absolute_temperature: bool = False


# allowed ranges: wide physical bounds of a wheeled vehicle test (not tuned to any test)
QUANTITIES: dict[str, QuantityKind] = {
    "surface_temperature": QuantityKind("K", "degC", (213.15, 573.15), 50.0, "pyrometer", True),
    "oil_temperature": QuantityKind("K", "degC", (213.15, 573.15), 50.0, "thermocouple", True),
    "height": QuantityKind("m", "mm", (0.0, 5.0), 0.5, "photogrammetry"),
    "wheel_load": QuantityKind("N", "daN", (0.0, 5e5), 5e4, "scale"),
}
INSTRUMENT_TYPES = ("pyrometer", "thermocouple", "photogrammetry", "scale", "plain")
POINT_KEYS = {"quantity", "axle", "wheel", "before", "after", "instrument", "uncertainty", "source", "note"}
SERIES_KEYS = {"quantity", "axle", "wheel", "csv", "mdf", "x", "y", "instrument", "uncertainty", "source", "note"}
INSTRUMENT_KEYS = {"uncertainty", "source", "type", "delay", "emissivity_setting", "note"}
TOP_KEYS = {"description", "source", "instruments", "points", "series"}
MAX_AXLE = 20
X_UNITS = {"[time]": ("s", "time"), "[length]": ("m", "distance")}
DELAY_RANGE_S = (0.0, 24 * 3600.0)
MAX_SERIES_ROWS = 2_000_000


@dataclass(frozen=True)
class Instrument:
    name: str
    type: str                      # one of INSTRUMENT_TYPES: which measurement model applies
    uncertainty: float | None      # standard uncertainty [SI of the quantity it reads], None: per value
    unit: str                      # unit the file wrote the uncertainty in
    source: str = ""
    delay_s: float | None = None   # time from stopping to reading (None: the model's prior)
    emissivity_setting: float | None = None   # a pyrometer's emissivity setting (None: the model's prior)


@dataclass(frozen=True)
class Point:
    where: str                     # "points[0]" for messages
    quantity: str
    axle: int                      # 1-based
    side: str | None               # None: the axle (mean of its wheels); "L" / "R": one wheel
    before: float | None           # SI
    after: float | None            # SI
    unit: str                      # the unit the file wrote the readings in (for display)
    instrument: Instrument
    uncertainty: float             # standard uncertainty of one reading [SI]
    source: str = ""

    @property
    def label(self) -> str:
        return f"axle {self.axle}" + (f" {self.side}" if self.side else "")

    @property
    def compared(self) -> str:
        """'change' (after - before) when both readings are given, else 'after' or 'before'."""
        if self.before is not None and self.after is not None:
            return "change"
        return "after" if self.after is not None else "before"

    @property
    def measured(self) -> float:
        """The compared measured value [SI] (a change: after - before)."""
        if self.compared == "change":
            return self.after - self.before
        return self.after if self.after is not None else self.before

    @property
    def measured_uncertainty(self) -> float:
        """Standard uncertainty of the compared value [SI]: two independent readings for a change."""
        return self.uncertainty * (math.sqrt(2.0) if self.compared == "change" else 1.0)


@dataclass(frozen=True)
class Series:
    where: str
    quantity: str
    axle: int
    side: str | None
    x: np.ndarray                  # SI: s (time) or m (distance)
    x_kind: str                    # "time" or "distance"
    y: np.ndarray                  # SI
    unit: str                      # the y unit as written
    instrument: Instrument
    uncertainty: float
    file: str
    source: str = ""
    x_unit: str = ""               # the x unit as written ("" for an MDF channel's time stamps: s)

    @property
    def label(self) -> str:
        return f"axle {self.axle}" + (f" {self.side}" if self.side else "")


@dataclass
class MeasurementFile:
    path: str
    description: str
    source: str
    instruments: dict[str, Instrument] = field(default_factory=dict)
    points: list[Point] = field(default_factory=list)
    series: list[Series] = field(default_factory=list)


# --- helpers ---------------------------------------------------------------------------------------
def _unit_text(value: Any, where: str) -> str:
    """The unit a quantity string is written in ('degC', 'mm'); bare numbers are refused."""
    if isinstance(value, bool) or not isinstance(value, str) or not value.strip():
        raise UserInputError(f"{where}: expected a quantity with its unit such as '80 degC' or '1470 mm', "
                             f"got {value!r} (every measured value carries its unit)")
    try:
        q = registry().Quantity(value.strip())
    except Exception:
        raise UserInputError(f"{where}: cannot read {value!r} as a quantity, expected e.g. '80 degC'") from None
    if isinstance(q, (int, float)) or (q.dimensionless and q.units == registry().dimensionless):
        raise UserInputError(f"{where}: {value!r} has no unit; write it with one, e.g. '80 degC' or '1470 mm'")
    return format(q.units, "~C").replace("°C", "degC")


def _reading(value: Any, kind: QuantityKind, where: str) -> tuple[float, str]:
    unit = _unit_text(value, where)
    x = parse_quantity(value, kind.si, where=where)
    lo, hi = kind.reading
    if not lo <= x <= hi:
        Q = registry().Quantity
        show = lambda v: f"{Q(v, kind.si).to(kind.shown).magnitude:.6g} {kind.shown}"  # noqa: E731
        raise UserInputError(f"{where}: {value!r} outside the allowed range [{show(lo)}, {show(hi)}]")
    return x, unit


def uncertainty_value(value: Any, si: str, limit: float, where: str) -> float:
    """A standard uncertainty [SI] > 0; a temperature's is a difference (K), never degC."""
    _unit_text(value, where)
    if si == "K" and isinstance(value, str) and ("deg" in value or "°" in value):
        raise UserInputError(f"{where}: a temperature uncertainty is a difference: give it in K, got {value!r}")
    u = parse_quantity(value, si, where=where)
    if not 0.0 < u <= limit:
        raise UserInputError(f"{where}: {value!r} outside the allowed range (0, {limit:g} {si}]")
    return u


def _location(item: dict, where: str) -> tuple[int, str | None]:
    if ("axle" in item) == ("wheel" in item):
        raise UserInputError(f"{where}: give exactly one of axle (1, 2, ...) or wheel (1L, 1R, 2L, ...)")
    if "axle" in item:
        a = item["axle"]
        if isinstance(a, bool) or not isinstance(a, int) or not 1 <= a <= MAX_AXLE:
            raise UserInputError(f"{where}.axle: expected an axle number in [1, {MAX_AXLE}], got {a!r}")
        return a, None
    m = re.fullmatch(r"\s*(\d{1,2})\s*([LRlr])\s*", str(item["wheel"]))
    if not m or not 1 <= int(m.group(1)) <= MAX_AXLE:
        raise UserInputError(f"{where}.wheel: expected an axle number and a side such as 1L or 3R "
                             f"(axles 1-{MAX_AXLE}), got {item['wheel']!r}")
    return int(m.group(1)), m.group(2).upper()


def _mapping(node: Any, where: str, allowed: set[str]) -> dict:
    if not isinstance(node, dict):
        raise UserInputError(f"{where}: expected a mapping, got {type(node).__name__}")
    unknown = sorted(set(map(str, node)) - allowed)
    if unknown:
        raise UserInputError(f"{where}: unknown key {unknown[0]!r}; allowed: {', '.join(sorted(allowed))}")
    return node


def _quantity(item: dict, where: str) -> str:
    q = item.get("quantity")
    if q not in QUANTITIES:
        raise UserInputError(f"{where}.quantity: {q!r}; allowed: {', '.join(QUANTITIES)}")
    return q


# --- instruments -----------------------------------------------------------------------------------
def _instrument(name: str, node: Any, where: str) -> Instrument:
    node = _mapping(node if node is not None else {}, where, INSTRUMENT_KEYS)
    typ = node.get("type", name if name in INSTRUMENT_TYPES else "plain")
    if typ not in INSTRUMENT_TYPES:
        raise UserInputError(f"{where}.type: {typ!r}; allowed: {', '.join(INSTRUMENT_TYPES)}")
    u, unit = None, ""
    if "uncertainty" in node:
        unit = _unit_text(node["uncertainty"], f"{where}.uncertainty")
        dim = registry().Quantity(node["uncertainty"]).dimensionality
        si = next((k.si for k in QUANTITIES.values() if registry().Quantity(1, k.si).dimensionality == dim), None)
        if si is None:
            raise UserInputError(f"{where}.uncertainty: {node['uncertainty']!r}: expected a temperature (K), a "
                                 "length (mm) or a force (daN)")
        limit = max(k.uncertainty_max for k in QUANTITIES.values() if k.si == si)
        u = uncertainty_value(node["uncertainty"], si, limit, f"{where}.uncertainty")
    delay = None
    if "delay" in node:
        delay = parse_quantity(node["delay"], "s", where=f"{where}.delay")
        _unit_text(node["delay"], f"{where}.delay")
        if not DELAY_RANGE_S[0] <= delay <= DELAY_RANGE_S[1]:
            raise UserInputError(f"{where}.delay: {node['delay']!r} outside the allowed range [0, 24 h]")
    eps = None
    if "emissivity_setting" in node:
        eps = node["emissivity_setting"]
        if isinstance(eps, bool) or not isinstance(eps, (int, float)) or not 0.1 <= eps <= 1.0:
            raise UserInputError(f"{where}.emissivity_setting: expected a number in [0.1, 1], got {eps!r}")
        eps = float(eps)
    return Instrument(name=name, type=typ, uncertainty=u, unit=unit, source=str(node.get("source", "")),
                      delay_s=delay, emissivity_setting=eps)


def _instrument_of(item: dict, quantity: str, instruments: dict, where: str) -> tuple[Instrument, float]:
    """The instrument of a point or series and the standard uncertainty of one reading [SI]."""
    kind = QUANTITIES[quantity]
    name = item.get("instrument")
    if name is None and kind.instrument in instruments:
        inst = instruments[kind.instrument]      # the file's instrument of the quantity's default type
    elif name is None:
        inst = Instrument(name=kind.instrument, type=kind.instrument, uncertainty=None, unit="")
    elif name not in instruments:
        raise UserInputError(f"{where}.instrument: {name!r} is not in instruments "
                             f"(defined: {', '.join(instruments) or 'none'})")
    else:
        inst = instruments[name]
    if "uncertainty" in item:
        u = uncertainty_value(item["uncertainty"], kind.si, kind.uncertainty_max, f"{where}.uncertainty")
    elif inst.uncertainty is not None:
        dim_ok = registry().Quantity(1, inst.unit).dimensionality == registry().Quantity(1, kind.si).dimensionality
        if not dim_ok:
            raise UserInputError(f"{where}.instrument: {inst.name!r} has an uncertainty in {inst.unit}, which "
                                 f"cannot measure {quantity} ({kind.shown})")
        u = inst.uncertainty
    else:
        raise UserInputError(f"{where}.uncertainty: missing; give an uncertainty with the value or with its "
                             f"instrument (e.g. instruments: {{{inst.name}: {{uncertainty: ...}}}})")
    return inst, u


# --- points and series -----------------------------------------------------------------------------
def _point(item: Any, where: str, instruments: dict, default_source: str) -> Point:
    item = _mapping(item, where, POINT_KEYS)
    quantity = _quantity(item, where)
    kind = QUANTITIES[quantity]
    axle, side = _location(item, where)
    values, units = {}, []
    for key in ("before", "after"):
        if key in item:
            values[key], unit = _reading(item[key], kind, f"{where}.{key}")
            units.append(unit)
    if not values:
        raise UserInputError(f"{where}: give before, after or both (readings with units)")
    inst, u = _instrument_of(item, quantity, instruments, where)
    return Point(where=where, quantity=quantity, axle=axle, side=side, before=values.get("before"),
                 after=values.get("after"), unit=units[-1], instrument=inst, uncertainty=u,
                 source=str(item.get("source", default_source)))


def _column_spec(node: Any, where: str, mdf: bool) -> dict:
    node = _mapping(node, where, {"column", "channel", "unit"})
    key = "channel" if mdf else "column"
    if key not in node or not isinstance(node[key], str) or not node[key].strip():
        raise UserInputError(f"{where}.{key}: expected the name of a {'channel' if mdf else 'CSV column'}")
    if "unit" not in node or not isinstance(node["unit"], str):
        raise UserInputError(f"{where}.unit: expected a unit such as 's', 'km' or 'degC'")
    return {"name": node[key].strip(), "unit": node["unit"].strip()}


def _unit_scale(unit: str, si: str, where: str):
    """Function converting values in `unit` to SI `si` (offset units such as degC included)."""
    ureg = registry()
    try:
        ureg.Quantity(1.0, unit).to(si)
    except Exception:
        raise UserInputError(f"{where}: {unit!r} is not a unit of {si}") from None
    return lambda a: np.asarray(ureg.Quantity(np.asarray(a, float), unit).to(si).magnitude, float)


def _x_kind(unit: str, where: str) -> tuple[str, str]:
    ureg = registry()
    try:
        dim = str(ureg.Quantity(1.0, unit).dimensionality)
    except Exception:
        raise UserInputError(f"{where}: cannot read the unit {unit!r}; allowed: a time (s, min, h) or a "
                             "distance (m, km)") from None
    if dim not in X_UNITS:
        raise UserInputError(f"{where}: {unit!r} is neither a time (s, min, h) nor a distance (m, km)")
    return X_UNITS[dim]


def read_csv_columns(path: Path, columns: list[str], where: str) -> list[np.ndarray]:
    """Named numeric columns of a CSV file (UTF-8, BOM and CRLF tolerated, '#' lines skipped)."""
    text = read_text_file(path, max_bytes=200 * 1024 * 1024)
    lines = [ln for ln in io.StringIO(text, newline=None).read().splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if len(lines) < 3:
        raise UserInputError(f"{path}: expected a header and at least two rows ({where})")
    if len(lines) > MAX_SERIES_ROWS:
        raise UserInputError(f"{path}: more than {MAX_SERIES_ROWS} rows, at most {MAX_SERIES_ROWS} in one series "
                             "(resample the log)")
    try:
        dialect = csv.Sniffer().sniff(lines[0], delimiters=",;\t")
    except csv.Error:
        dialect = csv.excel
    rows = list(csv.reader(lines, dialect))
    header = [h.strip() for h in rows[0]]
    out = []
    for c in columns:
        if c not in header:
            raise UserInputError(f"{where}: column {c!r} not in {path} (columns: {', '.join(header)})")
        j = header.index(c)
        vals = []
        for i, r in enumerate(rows[1:], start=2):
            try:
                vals.append(float(r[j]))
            except (ValueError, IndexError):
                raise UserInputError(f"{path}:{i}: column {c!r}: expected a number, got "
                                     f"{(r[j] if j < len(r) else '')[:20]!r}") from None
        out.append(np.asarray(vals, float))
    return out


def read_mdf_channels(path: Path, y_channel: str, x_channel: str | None, where: str):
    """(x, y) of MDF4 channels through asammdf (x: y's time stamps unless x_channel is given)."""
    try:
        from asammdf import MDF
    except ImportError:
        raise UserInputError(f'{where}.mdf: reading MDF4 needs asammdf: ' + install_hint("mdf")) from None
    if not path.is_file():
        raise UserInputError(f"{where}.mdf: {path}: file not found")
    try:
        mdf = MDF(str(path))
    except Exception as exc:
        raise UserInputError(f"{where}.mdf: {path}: not a readable MDF file ({exc.__class__.__name__})") from None
    try:
        sig = _mdf_get(mdf, y_channel, path, where)
        y, x = _mdf_numbers(sig.samples, y_channel, path, where), np.asarray(sig.timestamps, float)
        if x_channel is not None:
            xs = _mdf_get(mdf, x_channel, path, where)
            x = np.interp(sig.timestamps, xs.timestamps, _mdf_numbers(xs.samples, x_channel, path, where))
    finally:
        mdf.close()
    return x, y


def _mdf_get(mdf, name, path, where):
    """The channel's signal; its length is checked against MAX_SERIES_ROWS (the CSV row limit) before it is read."""
    try:
        found = mdf.whereis(name)
    except Exception:
        found = ()
    if not found:
        raise UserInputError(f"{where}: channel {name!r} not in {path}")
    try:
        samples = int(mdf.groups[found[0][0]].channel_group.cycles_nr)
    except (AttributeError, IndexError, TypeError, ValueError):
        samples = 0                 # not told by the file: the length is checked on the samples read
    try:
        sig = None if samples > MAX_SERIES_ROWS else mdf.get(name)
    except Exception:
        raise UserInputError(f"{where}: channel {name!r} of {path} cannot be read") from None
    if sig is None or len(sig.samples) > MAX_SERIES_ROWS:
        raise UserInputError(f"{where}: channel {name!r} of {path}: {max(samples, 0 if sig is None else len(sig.samples))}"
                             f" samples, at most {MAX_SERIES_ROWS} in one series (resample the log)")
    return sig


def _mdf_numbers(samples, name, path, where) -> np.ndarray:
    """A channel's samples as floats; a channel of text, bytes or records is a one-line error naming it."""
    a = np.asarray(samples)
    if a.dtype.kind not in "biuf":
        what = {"S": "byte strings", "U": "text", "O": "objects", "V": "records"}.get(a.dtype.kind, str(a.dtype))
        raise UserInputError(f"{where}: channel {name!r} of {path} holds {what}, not numbers")
    return a.astype(float)


def _series(item: Any, where: str, instruments: dict, base: Path, default_source: str) -> Series:
    item = _mapping(item, where, SERIES_KEYS)
    quantity = _quantity(item, where)
    kind = QUANTITIES[quantity]
    axle, side = _location(item, where)
    if ("csv" in item) == ("mdf" in item):
        raise UserInputError(f"{where}: give exactly one of csv (a CSV file) or mdf (an MDF4 file)")
    mdf = "mdf" in item
    ys = _column_spec(item.get("y"), f"{where}.y", mdf)
    to_y = _unit_scale(ys["unit"], kind.si, f"{where}.y.unit")
    path = Path(str(item["mdf" if mdf else "csv"]))
    path = path if path.is_absolute() else base / path
    if mdf:
        xs = _column_spec(item["x"], f"{where}.x", True) if "x" in item else {"name": None, "unit": "s"}
        x_si, x_kind = _x_kind(xs["unit"], f"{where}.x.unit")
        x, y = read_mdf_channels(path, ys["name"], xs["name"], where)
    else:
        if "x" not in item:
            raise UserInputError(f"{where}.x: missing: the time or distance column, e.g. {{column: time_s, unit: s}}")
        xs = _column_spec(item["x"], f"{where}.x", False)
        x_si, x_kind = _x_kind(xs["unit"], f"{where}.x.unit")
        x, y = read_csv_columns(path, [xs["name"], ys["name"]], where)
    x = _unit_scale(xs["unit"], x_si, f"{where}.x.unit")(x)
    y = to_y(y)
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if x.size < 2 or np.any(np.diff(x) <= 0):
        raise UserInputError(f"{where}: {path.name}: x ({xs['name'] or 'time'}) must hold at least two finite, "
                             "strictly increasing values")
    lo, hi = kind.reading
    bad = (y < lo) | (y > hi)
    if np.any(bad):
        i = int(np.argmax(bad))
        raise UserInputError(f"{where}: {path.name}: y value {y[i]:.6g} {kind.si} (sample {i + 1}) outside the "
                             f"allowed range [{lo:g}, {hi:g}] {kind.si}")
    inst, u = _instrument_of(item, quantity, instruments, where)
    return Series(where=where, quantity=quantity, axle=axle, side=side, x=x, x_kind=x_kind, y=y, unit=ys["unit"],
                  instrument=inst, uncertainty=u, file=str(path), source=str(item.get("source", default_source)),
                  x_unit=xs["unit"])


def read_measurements(path: str | Path) -> MeasurementFile:
    """Read and check a measurement file (module docstring). Errors name the file, key and range."""
    path = Path(path)
    data = load_yaml(path)
    name = str(path)
    try:
        return parse_measurements(data, name, path.resolve().parent)
    except UserInputError as exc:
        msg = str(exc)
        raise UserInputError(msg if msg.startswith(name) else f"{name}: {msg}") from None


def parse_measurements(data: Any, name: str, base: Path) -> MeasurementFile:
    data = _mapping(data, "(top level)", TOP_KEYS)
    desc = data.get("description", "")
    if not isinstance(desc, str):
        raise UserInputError("description: expected text")
    source = str(data.get("source", desc))
    inst_node = data.get("instruments") or {}
    if not isinstance(inst_node, dict):
        raise UserInputError("instruments: expected a mapping of instrument names")
    instruments = {str(k): _instrument(str(k), v, f"instruments.{k}") for k, v in inst_node.items()}
    out = MeasurementFile(path=name, description=desc, source=source, instruments=instruments)
    for key in ("points", "series"):
        node = data.get(key) or []
        if not isinstance(node, list):
            raise UserInputError(f"{key}: expected a list")
    for i, item in enumerate(data.get("points") or []):
        out.points.append(_point(item, f"points[{i}]", instruments, source))
    for i, item in enumerate(data.get("series") or []):
        out.series.append(_series(item, f"series[{i}]", instruments, base, source))
    if not out.points and not out.series:
        raise UserInputError("no points and no series: nothing measured")
    return out
