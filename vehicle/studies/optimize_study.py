"""The study file of `hpsim optimize` (docs/optimize.md): what is designed, on which load cases, towards what.

    base: quick_demo.yaml                 # scenario file, relative to the study file
    cases:                                # load cases; every trial drives all of them (default: one, the base)
      - {name: ride, distance: 2 km, road.iso_class: C}
      - {name: thermal, base: mileage_106km_multiscale.yaml}
    design:                               # scenario key paths, bounds with units; log: true for areas
      vehicle.overrides.charging.fill_pressure_offset: [-0.8 MPa, 0.8 MPa]
      struts.all.overrides.valve.bleed_area: {range: [5e-6 m^2, 3e-5 m^2], log: true}
    objectives:                           # key paths of `hpsim report --json` (optimize_objectives)
      ride.seats.driver.weighted_rms_acceleration_m_s2: {case: ride, goal: min}
      max(axles.T_oil_end_C): {case: thermal, goal: min}
    constraints:
      max(ride.stations.end_stop_time_s) <= 0: {case: ride}
    trials: 40                            # optional: the budget (--trials overrides it)
    population: 8                         # optional: trials per generation (NSGA-II's population)
    sampler: nsga2                        # optional: nsga2 (default for several objectives) or tpe (for one)
    seed: 0

Everything is checked before anything runs: each design key is applied at both bounds to every case and the
scenario prepared (an unknown key or a value out of range names the key), and a bound without units is refused
where the key is a quantity.
"""
from __future__ import annotations

import hashlib
import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from hpsim.config import Model, load_yaml, validate
from hpsim.errors import UserInputError
from hpsim.units import parse_quantity

from vehicle.scenario.schema import ScenarioSource, apply_overrides, prepare, read_scenario
from vehicle.studies.optimize_objectives import GOALS, Constraint, Objective, ReportPath
from vehicle.studies.study_folder import check_case_count, safe_names

SAMPLERS = ("nsga2", "tpe")
DEFAULT_POPULATION = 8          # trials per generation: NSGA-II needs a few, more than the workers of one machine
MAX_DESIGN_VARIABLES = 50
# a unit no hpsim key is given in: a key that refuses it as "has units of" is a quantity, whose bounds need units
_PROBE_UNIT_VALUE = "1 mol"
_BOUND = re.compile(r"^\s*(?P<number>[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?)\s*(?P<unit>.*?)\s*$")


class StudySpec(Model):
    description: str = ""
    base: str
    cases: list[dict[str, Any]] = []
    design: dict[str, Any] = {}
    objectives: dict[str, dict[str, Any]] = {}
    constraints: dict[str, dict[str, Any] | None] = {}
    trials: int | None = None
    population: int | None = None
    sampler: str | None = None
    seed: int = 0


@dataclass(frozen=True)
class DesignVariable:
    """A scenario key path varied between `low` and `high`, in `unit` ("" for numbers without units)."""

    path: str
    low: float
    high: float
    unit: str = ""
    log: bool = False

    def override(self, value: float):
        """The scenario value for `value` (in this variable's unit): a string with units, or the number."""
        return f"{value!r} {self.unit}" if self.unit else float(value)

    def label(self) -> str:
        return f"{self.path} [{self.unit}]" if self.unit else self.path


@dataclass
class Case:
    """A load case: its scenario (base and the case's overrides) before the design is applied."""

    name: str
    source: ScenarioSource


@dataclass
class Study:
    """A parsed, checked study: what the runner (vehicle.studies.optimize_runner) needs."""

    name: str
    design: list[DesignVariable]
    objectives: list[Objective]
    constraints: list[Constraint] = field(default_factory=list)
    cases: list[Case] = field(default_factory=list)
    trials: int | None = None
    population: int = DEFAULT_POPULATION
    sampler: str = "nsga2"
    seed: int = 0
    file: str = ""               # the study file, for messages

    def fingerprint(self) -> str:
        """A hash of the definition (not the budget): a study folder made from another definition is refused."""
        text = json.dumps({"design": [vars(d) for d in self.design],
                           "objectives": [(o.name, o.path.text, o.case, o.goal) for o in self.objectives],
                           "constraints": [(c.name, c.path.text, c.case, c.op, c.bound) for c in self.constraints],
                           "cases": [(c.name, c.source.text) for c in self.cases],
                           "population": self.population, "sampler": self.sampler, "seed": self.seed},
                          sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def trial_source(self, case: Case, design: dict[str, float], trial: int) -> ScenarioSource:
        """The scenario of `case` with the design values {path: value in the variable's unit} applied."""
        overrides = {d.path: d.override(design[d.path]) for d in self.design}
        merged = apply_overrides(case.source.data, overrides)
        text = (f"# trial {trial}, case {case.name} of study {self.name}: {overrides}\n"
                + yaml.safe_dump(merged, sort_keys=False))
        return ScenarioSource(text=text, name=f"{self.name} trial {trial} case {case.name}",
                              base_dir=case.source.base_dir, data=merged)


def parse_bound(value, where: str) -> tuple[float, str]:
    """(number, unit text) of a bound: a number, or a string '5e-6 m^2'."""
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise UserInputError(f"{where}: expected a number or a quantity such as '0.8 MPa', got {value!r}")
    if isinstance(value, (int, float)):
        return float(value), ""
    m = _BOUND.match(value)
    if not m:
        raise UserInputError(f"{where}: cannot read {value!r}; expected a number followed by its unit, e.g. '0.8 MPa'")
    return float(m["number"]), m["unit"]


def design_variable(path: str, value, where: str) -> DesignVariable:
    """A design entry: [low, high] or {range: [low, high], log: bool}; both bounds in one unit (the second
    converted to the first's)."""
    log = False
    if isinstance(value, dict):
        unknown = set(value) - {"range", "log"}
        if unknown:
            raise UserInputError(f"{where}: unknown key {sorted(unknown)[0]!r}; give range: [low, high] and log: "
                                 "true/false")
        log = value.get("log", False)
        if not isinstance(log, bool):
            raise UserInputError(f"{where}.log: expected true or false, got {log!r}")
        value = value.get("range")
    if not isinstance(value, list) or len(value) != 2:
        raise UserInputError(f"{where}: expected [low, high] or {{range: [low, high], log: true}}, got {value!r}")
    low, unit = parse_bound(value[0], f"{where}: low bound")
    high, unit_high = parse_bound(value[1], f"{where}: high bound")
    if bool(unit) != bool(unit_high):
        raise UserInputError(f"{where}: give both bounds with units or both without, got {value!r}")
    if unit and unit_high != unit:
        high = parse_quantity(value[1], unit, where=f"{where}: high bound")
    if not low < high:
        raise UserInputError(f"{where}: the low bound must be below the high bound, got {value!r}")
    if log and low <= 0:
        raise UserInputError(f"{where}: log: true needs bounds > 0, got {value!r}")
    return DesignVariable(path, low, high, unit, log)


def _objective(key: str, value: dict, case_names: list[str], where: str) -> Objective:
    unknown = set(value) - {"case", "goal", "path"}
    if unknown:
        raise UserInputError(f"{where}: unknown key {sorted(unknown)[0]!r}; give case, goal (min or max) and "
                             "optionally path (then the key is the objective's name)")
    goal = value.get("goal")
    if goal not in GOALS:
        raise UserInputError(f"{where}.goal: expected min or max, got {goal!r}")
    case = _case_of(value, case_names, where)
    path = ReportPath.parse(value.get("path", key), f"{where}.path" if "path" in value else where)
    return Objective(key, path, case, goal)


def _case_of(value: dict, case_names: list[str], where: str) -> str:
    case = value.get("case")
    if case is None:
        if len(case_names) > 1:
            raise UserInputError(f"{where}.case: the study has {len(case_names)} cases ({', '.join(case_names)}); "
                                 "say which one")
        return case_names[0]
    if str(case) not in case_names:
        raise UserInputError(f"{where}.case: no case {case!r}; the study's cases are {', '.join(case_names)}")
    return str(case)


def _read_base(text: str, study_path: Path, where: str) -> ScenarioSource:
    base_path = Path(text)
    if not base_path.is_absolute():
        base_path = study_path.resolve().parent / base_path
    if not base_path.exists():
        raise UserInputError(f"{where}: scenario file {text!r} not found (looked at {base_path})")
    return read_scenario(base_path)


def load_cases(spec: StudySpec, path: Path) -> list[Case]:
    """The load cases with their overrides applied and their names made safe (nothing prepared yet)."""
    base = _read_base(spec.base, path, f"{path}: base")
    given = spec.cases or [{"name": "base"}]
    check_case_count(len(given), str(path))
    names = safe_names([str(c.get("name", f"case{k + 1}")) for k, c in enumerate(given)])
    cases = []
    for k, (case, name) in enumerate(zip(given, names)):
        overrides = {key: v for key, v in case.items() if key not in ("name", "base")}
        src = _read_base(case["base"], path, f"{path}: cases.{k}.base") if "base" in case else base
        try:
            merged = apply_overrides(src.data, overrides)
        except UserInputError as exc:
            raise UserInputError(f"{path}: cases.{k} ({name}): {exc}") from None
        text = f"# case {name} of study {path.name}: base {src.name} with {overrides}\n" + \
            yaml.safe_dump(merged, sort_keys=False)
        cases.append(Case(name, ScenarioSource(text=text, name=f"{path} case {name}", base_dir=src.base_dir,
                                               data=merged)))
    return cases


def check_design(study: Study, where: str) -> None:
    """Each design key applied at its bounds to every case, the scenario prepared; a bound without units refused
    where the key is a quantity. One line naming the key, else nothing."""
    for d in study.design:
        key = f"{where}: design.{d.path}"
        for case in study.cases:
            for value in (d.low, d.high):
                try:
                    prepare(study.trial_source(case, {**middle(study), d.path: value}, 0))
                except UserInputError as exc:
                    raise UserInputError(f"{key}: {value:g} {d.unit} on case {case.name}: {exc}") from None
            if not d.unit and _needs_units(case, d.path):
                raise UserInputError(f"{key}: bounds need units (the key is a quantity), e.g. [{d.low:g} UNIT, "
                                     f"{d.high:g} UNIT]")


def middle(study: Study) -> dict:
    """The design at the middle of every range (geometric for log: true)."""
    return {d.path: (d.low * d.high) ** 0.5 if d.log else 0.5 * (d.low + d.high) for d in study.design}


def _needs_units(case: Case, path: str) -> bool:
    try:
        prepare(ScenarioSource(text="", name="unit probe", base_dir=case.source.base_dir,
                               data=apply_overrides(case.source.data, {path: _PROBE_UNIT_VALUE})))
    except UserInputError as exc:
        return "has units of" in str(exc)
    return False


def load_study(path: str | Path, *, trials: int | None = None, check: bool = True) -> Study:
    """Parse and check a study file (nothing runs); UserInputError with one line naming the key otherwise."""
    path = Path(path)
    data = load_yaml(path)
    if not isinstance(data, dict):
        raise UserInputError(f"{path}: expected a mapping with base, design and objectives")
    spec = validate(StudySpec, data, str(path))
    if not spec.design:
        raise UserInputError(f"{path}: design: empty; give at least one scenario key with its bounds, e.g. "
                             "vehicle.overrides.charging.fill_pressure_offset: [-0.8 MPa, 0.8 MPa]")
    if len(spec.design) > MAX_DESIGN_VARIABLES:
        raise UserInputError(f"{path}: design: {len(spec.design)} keys, at most {MAX_DESIGN_VARIABLES}")
    if not spec.objectives:
        raise UserInputError(f"{path}: objectives: empty; give at least one key path of `hpsim report --json` with "
                             "its goal, e.g. load_shift_pct: {goal: min}")
    cases = load_cases(spec, path)
    names = [c.name for c in cases]
    design = [design_variable(k, v, f"{path}: design.{k}") for k, v in spec.design.items()]
    objectives = [_objective(k, v, names, f"{path}: objectives.{k}") for k, v in spec.objectives.items()]
    seen: dict = {}
    for o in objectives:
        other = seen.setdefault((o.path.text, o.case), o)
        if other.goal != o.goal:
            raise UserInputError(f"{path}: objectives.{o.name}: goal {o.goal} conflicts with objectives.{other.name} "
                                 f"(goal {other.goal}) on the same quantity and case")
        if other is not o:
            raise UserInputError(f"{path}: objectives.{o.name}: the same quantity as objectives.{other.name}")
    constraints = [Constraint.parse(k, _case_of(v or {}, names, f"{path}: constraints.{k}"), f"{path}: constraints.{k}")
                   for k, v in spec.constraints.items()]
    sampler = spec.sampler or ("nsga2" if len(objectives) > 1 else "tpe")
    if sampler not in SAMPLERS:
        raise UserInputError(f"{path}: sampler: expected {' or '.join(SAMPLERS)}, got {sampler!r}")
    budget = trials if trials is not None else spec.trials
    if budget is not None and budget < 1:
        raise UserInputError(f"{'--trials' if trials is not None else f'{path}: trials'}: must be >= 1, got {budget}")
    if budget is not None:
        check_case_count(budget * len(cases), str(path), what="drives", advice="fewer --trials or cases")
    population = spec.population if spec.population is not None else DEFAULT_POPULATION
    if population < 2:
        raise UserInputError(f"{path}: population: must be >= 2 trials per generation, got {population}")
    if spec.seed < 0:
        raise UserInputError(f"{path}: seed: must be >= 0, got {spec.seed}")
    study = Study(path.stem, design, objectives, constraints, cases, budget, population, sampler, spec.seed, str(path))
    if check:
        check_design(study, str(path))
    return study
