"""Objectives and constraints of `hpsim optimize`: key paths into a case's `hpsim report --json` (docs/optimize.md).

A key path is dotted: `load_shift_pct`, `ride.seats.driver.weighted_rms_acceleration_m_s2`. A segment after a list
picks the item whose name field (seat, station, axle, name) or index is that segment; any other segment is read from
every item, giving one value per item, which `max(...)`, `min(...)` or `mean(...)` reduce to one number:
`max(axles.T_oil_end_C)`, `max(ride.stations.end_stop_time_s)`.

A constraint is `PATH <= BOUND` or `PATH >= BOUND`; its margin is how far inside the bound the value is (>= 0:
kept, < 0: violated). Violated designs stay in the study, marked, and never enter the front.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

from hpsim.errors import UserInputError

REDUCERS = {"max": max, "min": min, "mean": lambda v: sum(v) / len(v)}
ITEM_NAME_FIELDS = ("seat", "station", "axle", "name")
GOALS = ("min", "max")
_REDUCED = re.compile(r"^\s*(?P<fn>[a-z]+)\(\s*(?P<path>[^()]+?)\s*\)\s*$")
_SEGMENT = re.compile(r"^[A-Za-z0-9_+-]+$")
_CONSTRAINT = re.compile(r"^(?P<expr>.+?)\s*(?P<op><=|>=)\s*(?P<bound>\S+)\s*$")


class PathError(ValueError):
    """A key path that a report does not hold (the message says which segment and what is there)."""


@dataclass(frozen=True)
class ReportPath:
    """A key path into a report, optionally reduced over list items (`max(axles.T_oil_end_C)`)."""

    text: str
    segments: tuple[str, ...]
    reducer: str | None = None

    @classmethod
    def parse(cls, text: str, where: str) -> "ReportPath":
        """Parse `PATH` or `REDUCER(PATH)`; a UserInputError naming `where` otherwise."""
        text = str(text).strip()
        reducer, path = None, text
        m = _REDUCED.match(text)
        if m:
            reducer, path = m["fn"], m["path"]
            if reducer not in REDUCERS:
                raise UserInputError(f"{where}: {reducer}(...) is not a reduction; use {', '.join(REDUCERS)}")
        segments = tuple(path.split("."))
        if not path or not all(_SEGMENT.match(s) for s in segments):
            raise UserInputError(f"{where}: {text!r} is not a key path of `hpsim report --json` (dotted names such "
                                 "as ride.seats.driver.weighted_rms_acceleration_m_s2 or max(axles.T_oil_end_C))")
        return cls(text, segments, reducer)

    def value(self, report: dict) -> float:
        """The number at this path in `report`; PathError when the report does not hold it, ValueError when it
        holds no finite number there (a drive that did not produce the quantity)."""
        values, over_items = _walk(report, self.segments)
        if over_items and self.reducer is None:
            raise PathError(f"{self.text}: {len(values)} values (one per item); reduce them with max(...), "
                            "min(...) or mean(...)")
        if not over_items and self.reducer is not None:
            raise PathError(f"{self.text}: one value, nothing for {self.reducer}(...) to reduce")
        numbers = [_number(v, self.text) for v in values]
        if not numbers:
            raise PathError(f"{self.text}: no items in the report")
        return float(REDUCERS[self.reducer](numbers)) if self.reducer else numbers[0]


def _number(v, text: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        if v is None:
            raise ValueError(f"{text}: the report holds no value (null) for this drive")
        raise PathError(f"{text}: {type(v).__name__} in the report, not a number")
    if not math.isfinite(v):
        raise ValueError(f"{text}: not a finite number ({v})")
    return float(v)


def _item_name(item) -> str | None:
    if isinstance(item, dict):
        for k in ITEM_NAME_FIELDS:
            if k in item:
                return str(item[k])
    return None


def _walk(node, segments: tuple[str, ...]) -> tuple[list, bool]:
    """(values at the path, whether they were collected over list items)."""
    nodes, over_items, here = [node], False, []
    for seg in segments:
        out = []
        for n in nodes:
            if isinstance(n, list):
                picked = [it for k, it in enumerate(n) if _item_name(it) == seg or str(k) == seg]
                if picked:
                    out.append(picked[0])
                    continue
                over_items = True
                n_items = [it for it in n if isinstance(it, dict)]
                missing = [it for it in n_items if seg not in it]
                if not n_items or missing:
                    names = [str(x) for x in (_item_name(it) for it in n) if x is not None]
                    keys = sorted({k for it in n_items for k in it})
                    raise PathError(f"{'.'.join(here + [seg])}: not an item name ({', '.join(names) or 'none'}) nor "
                                    f"a key of every item ({', '.join(keys) or 'none'})")
                out += [it[seg] for it in n_items]
            elif isinstance(n, dict):
                if seg not in n:
                    raise PathError(f"{'.'.join(here + [seg])}: not in the report (there: "
                                    f"{', '.join(sorted(map(str, n))) or 'nothing'})")
                out.append(n[seg])
            else:
                raise PathError(f"{'.'.join(here)}: a value, it has no key {seg!r}")
        nodes = out
        here.append(seg)
    return nodes, over_items


@dataclass(frozen=True)
class Objective:
    """An objective: the value at `path` in the report of case `case`, minimised or maximised."""

    name: str
    path: ReportPath
    case: str
    goal: str              # "min" or "max"


@dataclass(frozen=True)
class Constraint:
    """`path <= bound` or `path >= bound` on case `case`; margin >= 0 when kept."""

    name: str
    path: ReportPath
    case: str
    op: str                # "<=" or ">="
    bound: float

    @classmethod
    def parse(cls, text: str, case: str, where: str) -> "Constraint":
        m = _CONSTRAINT.match(str(text))
        if not m:
            raise UserInputError(f"{where}: {text!r}: expected 'PATH <= BOUND' or 'PATH >= BOUND' "
                                 "(e.g. max(ride.stations.end_stop_time_s) <= 0)")
        try:
            bound = float(m["bound"])
        except ValueError:
            raise UserInputError(f"{where}: bound {m['bound']!r}: expected a number in the report's unit") from None
        if not math.isfinite(bound):
            raise UserInputError(f"{where}: bound {m['bound']!r}: expected a finite number")
        return cls(str(text).strip(), ReportPath.parse(m["expr"], where), case, m["op"], bound)

    def margin(self, value: float) -> float:
        """How far inside the bound `value` is (negative: violated), in the report's unit."""
        return self.bound - value if self.op == "<=" else value - self.bound


def check_against(report: dict, objectives, constraints, case: str, where: str) -> None:
    """Every path of `case`'s objectives and constraints found in `report` (a probe drive's): a UserInputError
    naming the first that is not, before the study starts."""
    for item in [*objectives, *constraints]:
        if item.case != case:
            continue
        try:
            item.path.value(report)
        except PathError as exc:
            kind = "objectives" if isinstance(item, Objective) else "constraints"
            raise UserInputError(f"{where}: {kind}.{item.name}: {exc}") from None
        except ValueError:
            pass            # in the report, no number on the probe's short drive: the full drives tell


def case_values(reports: dict, objectives, constraints) -> tuple[dict, dict]:
    """({objective name: value}, {constraint name: margin}) of one trial from its cases' reports {case: report}.
    Raises ValueError (PathError included) naming the quantity a report does not give."""
    obj = {o.name: o.path.value(reports[o.case]) for o in objectives}
    con = {c.name: c.margin(c.path.value(reports[c.case])) for c in constraints}
    return obj, con
