"""Uncertainty quantification over the parameter priors (`hpsim uq`, docs/uq.md).

A study draws the priors written in a scenario's vehicle and strut files (hpsim.priors), runs
one drive per draw, and reports how far the per-axle predictions move and which assumption
moves them:

1. parameters: every prior of the vehicle file and of the strut files, after the scenario's
   overrides (a value the scenario fixes is not drawn). Strut priors are one draw for all axles
   that use the same strut file (one strut type), or one per axle (`per_axle_struts`). The
   priors of a disabled compensation are left out (they cannot act).
2. design: SALib's Saltelli extension of the Sobol' sequence (`sobol`, N x (D + 2) cases for
   first-order and total indices) or a Latin hypercube (`lhs`, N cases); plus one nominal case
   at the files' values. The matrix is written to DIR/samples.csv with the settings; a re-run
   with other settings is refused, a re-run with the same settings resumes.
3. cases: each draw becomes scenario overrides (`vehicle.overrides.<key path>`,
   `struts.<all|axleN>.overrides.<key path>`), run by a pluggable case runner (the drive
   runner writes DIR/cases/<case>.h5 through vehicle.studies.sweep.run_case) on local processes
   or a Dask cluster (vehicle.studies.sweep.execute). Finished cases are appended to
   DIR/cases.jsonl: a re-run skips them and resumes an interrupted drive from its checkpoint.
4. analysis: 5/50/95 % bands of every output (DIR/bands.csv), first-order and total Sobol
   indices with bootstrap 95 % confidence intervals (SALib.analyze.sobol, DIR/sobol.csv) or,
   for `lhs`, Spearman and partial rank correlation coefficients (DIR/ranking.csv), and
   DIR/summary.json. The figures are drawn by vehicle.presentation.uq_plots.

The outputs of a drive come from its per-axle report (vehicle.analysis.summary.report) through
`case_outputs`: add a line there to study another number.
"""
from __future__ import annotations

import copy
import fnmatch
import hashlib
import json
import math
import re
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np
import yaml

from hpsim.config import deep_update, load_yaml
from hpsim.errors import SimulationError, UserInputError
from hpsim.priors import Prior, collect_priors, correlated_quantile, tie_shared
from struts.params import strut_file

from vehicle.scenario.schema import ScenarioSource, prepare, read_scenario, validate_scenario, vehicle_data
from vehicle.results.run import results_status
from vehicle.analysis.summary import report
from vehicle.studies.sweep import dask_client, execute, run_case
from vehicle.studies.uq_files import read_records, read_samples, study_differences, write_samples
from vehicle.studies.uq_tables import write_bands, write_ranking, write_sobol, write_summary
from vehicle.studies.uq_per_axle import expand_per_axle, latent_nominal, set_path
from vehicle.engines.ensemble import eligible, grouped_jobs

from vehicle.results import provenance
from vehicle.studies.study_folder import StudyLock, check_case_count, check_study_kind

METHODS = ("sobol", "lhs")
GROUPINGS = ("none", "section")
BANDS = (5.0, 50.0, 95.0)
CONF_LEVEL = 0.95
NUM_RESAMPLES = 200          # bootstrap resamples of the Sobol confidence intervals
NOMINAL = "nominal"

# --- outputs of a drive ------------------------------------------------------------------------
# name -> (unit, value from a per-axle row of vehicle.analysis.summary.report); "axle<k>.<name>"
AXLE_OUTPUTS: dict[str, tuple[str, Callable[[dict], Any]]] = {
    "rise_K": ("K", lambda a: None if a.get("T_end_C") is None or a.get("T_start_C") is None
               else a["T_end_C"] - a["T_start_C"]),
    "dh_mm": ("mm", lambda a: a.get("dh_mm")),
    "dN_pct": ("%", lambda a: a.get("dN_pct")),
}
# optional per-axle outputs, kept when the results hold them (None otherwise): the [low, high] band
# of the wheel-load change two weighings with seal friction can give (vehicle.analysis.summary)
OPTIONAL_AXLE_OUTPUTS: dict[str, tuple[str, Callable[[dict], Any]]] = {
    "dN_band_low_pct": ("%", lambda a: (a.get("dN_band_pct") or [None, None])[0]),
    "dN_band_high_pct": ("%", lambda a: (a.get("dN_band_pct") or [None, None])[1]),
}
# name -> (unit, value from the whole report)
VEHICLE_OUTPUTS: dict[str, tuple[str, Callable[[dict], Any]]] = {
    "mean_rise_K": ("K", lambda r: r.get("mean_temperature_rise_K")),
    "load_shift_pct": ("%", lambda r: r.get("load_shift_pct")),
    # the axle-to-axle spread (max - min over the axles) of the rise and of dN (docs/validation.md §5, §9)
    "rise_spread_K": ("K", lambda r: _spread([a["T_end_C"] - a["T_start_C"] for a in r["axles"]])),
    "dN_spread_pp": ("pp", lambda r: _spread([a["dN_pct"] for a in r["axles"]])),
}


def _spread(values: list) -> float | None:
    return None if any(v is None for v in values) else max(values) - min(values)


def case_outputs(rep: dict) -> dict[str, float]:
    """The numbers a study follows, from one drive's report (vehicle.analysis.summary.report)."""
    out: dict[str, float] = {}
    for a in rep["axles"]:
        for name, (_, get) in AXLE_OUTPUTS.items():
            out[f"axle{a['axle']}.{name}"] = get(a)
        for name, (_, get) in OPTIONAL_AXLE_OUTPUTS.items():
            if get(a) is not None:
                out[f"axle{a['axle']}.{name}"] = get(a)
    for name, (_, get) in VEHICLE_OUTPUTS.items():
        out[name] = get(rep)
    missing = [k for k, v in out.items() if v is None or not math.isfinite(float(v))]
    if missing:
        raise SimulationError(f"{rep.get('file', 'results')}: no value for {', '.join(missing)} "
                              f"(status {rep.get('status')})")
    return {k: float(v) for k, v in out.items()}


def output_unit(name: str) -> str:
    m = re.fullmatch(r"axle\d+\.(.+)", name)
    if m and m.group(1) in {**AXLE_OUTPUTS, **OPTIONAL_AXLE_OUTPUTS}:
        return {**AXLE_OUTPUTS, **OPTIONAL_AXLE_OUTPUTS}[m.group(1)][0]
    return VEHICLE_OUTPUTS[name][0] if name in VEHICLE_OUTPUTS else ""


# --- parameters --------------------------------------------------------------------------------
@dataclass(frozen=True)
class Parameter:
    """One independent draw of a study: its prior and where the drawn value goes."""

    name: str                      # "vehicle.tyre.stiffness", "struts.all.friction.pressure_coefficient"
    prior: Prior                   # the distribution (of the first of `paths`)
    paths: tuple[str, ...]         # key paths in the parameter file (several when tied by `shared`)
    target: str = ""               # "vehicle", "struts" or "" (a study without scenario)
    struts: tuple[str, ...] = ()   # for "struts": the scenario keys ("all" or "axle1", ...)
    section: str = ""              # group for `--groups section`: "vehicle.tyre", "struts.all.valve"
    # a per-axle prior with a rank correlation is drawn through independent standard normals (hpsim.priors):
    # latent "common" (no paths) or "member" (its axle's value: prior.ppf(correlated_quantile(common, own)))
    latent: str = ""
    common: str = ""               # for a member: the name of the common latent

    def describe(self) -> dict:
        p = self.prior
        out = {"name": self.name, "paths": list(self.paths), "file": p.source, "value": p.to_unit(p.value),
               "unit": p.unit, "prior": p.describe(), "section": self.section, "reasoning": p.note}
        if self.latent:
            out["drawn_as"] = f"standard normal latent ({self.latent} of a rank-correlated per-{p.per} prior)"
        return out

    def design_prior(self) -> Prior:
        """The distribution the design draws: the prior, or a standard normal for a latent."""
        return STANDARD_NORMAL if self.latent else self.prior

    def nominal(self) -> float:
        """The design value that gives the file's value (a latent member: common at 0, own from the cdf)."""
        if not self.latent:
            return self.prior.value
        return 0.0 if self.latent == "common" else latent_nominal(self.prior)


STANDARD_NORMAL = Prior(path="latent", kind="normal", args=(0.0, 1.0), value=0.0, unit="", si_unit="")


def physical_values(params: list[Parameter], values: dict) -> dict:
    """Design values -> the values that go into the files [SI] (latent members through the copula)."""
    out = dict(values)
    for p in params:
        if p.latent == "member":
            q = correlated_quantile(values[p.common], values[p.name], p.prior.correlation)
            out[p.name] = float(p.prior.ppf(q))
    return out


def parameters_from(priors: list[Prior], prefix: str = "", target: str = "", struts: tuple[str, ...] = (),
                    n_axles: int = 0) -> list[Parameter]:
    """Independent parameters of a list of priors (tied ones become one; a per-axle one one per axle), named
    prefix.path."""
    out = []
    for p in [p for p in priors if p.per]:
        out += expand_per_axle(p, prefix, target, n_axles, Parameter)
    for label, group in tie_shared([p for p in priors if not p.per]):
        name = f"{prefix}.{label}" if prefix else label
        section = f"{prefix}.{group[0].path.split('.')[0]}" if prefix else group[0].path.split(".")[0]
        out.append(Parameter(name=name, prior=group[0], paths=tuple(p.path for p in group), target=target,
                             struts=struts, section=section))
    return out


def _plain(v):
    return v["value"] if isinstance(v, dict) and "value" in v else v


def scenario_parameters(src, *, per_axle_struts: bool = False) -> tuple[list[Parameter], list[str], dict]:
    """Parameters of a scenario (a vehicle.scenario.schema.ScenarioSource), notes on what was left
    out, and the resolved parameter data (for the study's fingerprint)."""
    S = validate_scenario(src)
    data, vpath = vehicle_data(S, src)
    axles = data.get("axles") or []
    notes = []
    skip = tuple(f"axles.{k}.strut_overrides" for k in range(len(axles)))
    vpriors = collect_priors(data, vpath, skip=skip)
    if not bool(_plain((data.get("compensation") or {}).get("enabled", False))):
        off = [p for p in vpriors if p.path.startswith("compensation.")]
        if off:
            notes.append(f"compensation is off in this scenario: its {len(off)} priors are not drawn")
        vpriors = [p for p in vpriors if not p.path.startswith("compensation.")]
    params = parameters_from(vpriors, "vehicle", "vehicle", n_axles=len(axles))
    # the scenario's own priors (road passes, speed profile, start temperatures; docs/uq.md)
    params += parameters_from(collect_priors(src.data, src.name, skip=("vehicle", "struts")), "scenario", "scenario",
                              n_axles=len(axles))
    # struts: axles with the same file and the same priors (after overrides) share one draw
    groups: dict[tuple, list[int]] = {}
    resolved_struts = []
    per_axle = []
    for k, axle in enumerate(axles):
        path = strut_file(axle.get("strut", "apc"))
        sdata = load_yaml(path)
        if axle.get("strut_overrides"):
            sdata = deep_update(sdata, axle["strut_overrides"])
        priors = collect_priors(sdata, str(path))
        per_axle.append(priors)
        resolved_struts.append(sdata)
        key = (k,) if per_axle_struts else (str(Path(path).resolve()), tuple(
            (p.path, p.kind, p.args, p.shared) for p in priors))
        groups.setdefault(key, []).append(k)
    for members in groups.values():
        keys = ("all",) if len(members) == len(axles) else tuple(f"axle{k + 1}" for k in members)
        prefix = "struts." + "+".join(keys)
        params += parameters_from(per_axle[members[0]], prefix, "struts", keys, n_axles=len(axles))
    resolved = {"scenario": src.data, "vehicle": data, "struts": resolved_struts}
    return params, notes, resolved


def select(params: list[Parameter], patterns: list[str] | None) -> list[Parameter]:
    """Parameters named by `patterns`: a full name, its ending after a dot (`tyre.stiffness`) or a
    glob (`struts.all.valve.*`). Every pattern must match."""
    if not patterns:
        return params
    keep = set()
    for pat in patterns:
        hit = [p.name for p in params if p.name == pat or p.name.endswith("." + pat) or fnmatch.fnmatchcase(p.name, pat)]
        if not hit:
            raise UserInputError(f"--parameters: {pat!r} matches no prior; the priors are: "
                                 f"{', '.join(p.name for p in params)}")
        keep.update(hit)
    return [p for p in params if p.name in keep]


def salib_problem(params: list[Parameter], groups: str = "none") -> dict:
    dists, bounds = zip(*(p.design_prior().salib() for p in params))
    problem = {"num_vars": len(params), "names": [p.name for p in params], "bounds": [list(b) for b in bounds],
               "dists": list(dists)}
    if groups == "section":
        problem["groups"] = [p.section for p in params]
    return problem


def design(params: list[Parameter], method: str, samples: int, seed: int, groups: str = "none") -> np.ndarray:
    """The sample matrix (rows: cases, columns: parameters, SI)."""
    import warnings

    problem = salib_problem(params, groups)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        if method == "sobol":
            from SALib.sample import sobol as sobol_sample

            return np.asarray(sobol_sample.sample(problem, samples, calc_second_order=False, seed=seed), float)
        from SALib.sample import latin

        return np.asarray(latin.sample(problem, samples, seed=seed), float)


def check_settings(method: str, samples: int, groups: str, n_params: int) -> None:
    if method not in METHODS:
        raise UserInputError(f"--method: {method!r}: allowed {', '.join(METHODS)}")
    if groups not in GROUPINGS:
        raise UserInputError(f"--groups: {groups!r}: allowed {', '.join(GROUPINGS)}")
    if n_params < 1:
        raise UserInputError("no parameter to draw: the files carry no priors (docs/uq.md shows how to write them)")
    if samples < 2:
        raise UserInputError(f"--samples: must be >= 2, got {samples}")
    if method == "sobol" and samples & (samples - 1):
        lo = 1 << (samples.bit_length() - 1)
        raise UserInputError(f"--samples: the Sobol' (Saltelli) design needs a power of 2, got {samples} "
                             f"(use {lo} or {2 * lo})")
    if method == "lhs" and groups != "none":
        raise UserInputError("--groups: grouped indices need --method sobol (a Latin hypercube ranks each parameter)")


def check_seed(seed) -> None:
    """--seed: an integer in [0, 2**32 - 1] (what the samplers accept)."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= int(seed) < 2**32:
        raise UserInputError(f"--seed: must be an integer in [0, {2**32 - 1}], got {seed!r}")


def n_cases(method: str, samples: int, n_draws: int) -> int:
    """Cases of a design without the nominal one (n_draws: parameters, or groups when grouped)."""
    return samples * (n_draws + 2) if method == "sobol" else samples


# --- the study files ---------------------------------------------------------------------------
def _fingerprint(params: list[Parameter], method: str, samples: int, seed: int, groups: str, model: str) -> dict:
    return {"method": method, "samples": samples, "seed": seed, "groups": groups,
            "parameters": [f"{p.name}: {p.prior.describe()}" for p in params], "model": model}


# --- running cases -----------------------------------------------------------------------------
def run_one(runner: Callable[[str, dict], dict], name: str, values: dict,
            make_solver: Callable[[float], object] | None = None) -> dict:
    """One case in a worker: never raises (except Ctrl-C); returns status, outputs, error, seconds.
    make_solver: an ensemble lane's solver factory (`vehicle.engines.ensemble.run_lockstep`), handed to the runner
    as runner(name, values, make_solver=...); only a `DriveRunner` joins a lane group."""
    t0 = time.perf_counter()
    try:
        outputs = runner(name, values) if make_solver is None else runner(name, values, make_solver=make_solver)
        return {"status": "done", "outputs": {k: float(v) for k, v in outputs.items()}, "error": "",
                "seconds": time.perf_counter() - t0}
    except (UserInputError, SimulationError) as exc:
        return {"status": "failed", "error": str(exc), "seconds": time.perf_counter() - t0}
    except KeyboardInterrupt:
        raise
    except Exception as exc:  # a bug: report it with its traceback's last lines, keep the others going
        tb = traceback.format_exc().strip().splitlines()[-3:]
        return {"status": "failed", "error": f"{type(exc).__name__}: {exc} ({' | '.join(tb)})",
                "seconds": time.perf_counter() - t0}


def case_scenario(base: dict, params: list[Parameter], values: dict, distance: str | None = None) -> dict:
    """The scenario mapping of one case: the base scenario with the drawn values as overrides."""
    data = copy.deepcopy(base)
    values = physical_values(params, values)
    for p in params:
        if not p.paths:
            continue                     # a latent without a value of its own
        value = p.prior.override(values[p.name])
        if p.target == "vehicle":
            veh = data.setdefault("vehicle", {})
            ov = veh["overrides"] = dict(veh.get("overrides") or {})
            for path in p.paths:
                ov[path] = value
        elif p.target == "struts":
            struts = data["struts"] = dict(data.get("struts") or {})
            for key in p.struts:
                choice = struts[key] = dict(struts.get(key) or {})
                ov = choice["overrides"] = dict(choice.get("overrides") or {})
                for path in p.paths:
                    ov[path] = value
        elif p.target == "scenario":
            for path in p.paths:
                set_path(data, path, value)
        else:
            raise UserInputError(f"{p.name}: a parameter without a target cannot go into a scenario")
    if distance is not None:
        data["distance"] = distance
    return data


class DriveRunner:
    """The default case runner: one drive of the scenario with the drawn values, into cases/<case>.h5."""

    def __init__(self, base: dict, name: str, base_dir: str, params: list[Parameter], cases_dir: str,
                 distance: str | None = None):
        self.base, self.name, self.base_dir = base, name, base_dir
        self.params, self.cases_dir, self.distance = params, cases_dir, distance

    def scenario_text(self, case: str, values: dict) -> str:
        data = case_scenario(self.base, self.params, values, self.distance)
        return f"# case {case} of an hpsim uq study of {self.name}\n" + yaml.safe_dump(data, sort_keys=False)

    def __call__(self, case: str, values: dict, make_solver: Callable[[float], object] | None = None) -> dict:
        out = Path(self.cases_dir) / f"{case}.h5"
        ran = results_status(out) != "complete"
        if ran:
            r = run_case(self.scenario_text(case, values), f"{self.name} case {case}", self.base_dir, str(out),
                         make_solver=make_solver)
            if r["status"] != "done":
                if r["status"] == "interrupted" or r.get("error") == "interrupted":
                    raise KeyboardInterrupt     # Ctrl-C: stop the study; the drive's file stays resumable
                raise SimulationError(r["error"])
        # a drive finished here was written whole by this process: the child-process read check is for others
        return case_outputs(report(out, check=not ran))


# --- the study ---------------------------------------------------------------------------------
def run_study(out_dir: str | Path, params: list[Parameter], runner: Callable[[str, dict], dict], *,
              method: str = "sobol", samples: int = 16, seed: int = 0, groups: str = "none",
              workers: int | None = None, scheduler: str | None = None, model: str = "",
              log: Callable[[str], None] | None = None, nominal: bool = True, label: str = "",
              before_start: Callable[[int], None] | None = None, ensemble: int | None = 1) -> dict:
    """Sample, run (resuming), analyse. `runner(case, {parameter name: SI value}) -> {output: value}`
    must be picklable for more than one worker. `model` identifies what the runner computes (a
    resumed study must have the same). Returns the summary (also written to DIR/summary.json)."""
    log = log or (lambda m: None)
    check_settings(method, samples, groups, len(params))
    check_seed(seed)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    with StudyLock(out_dir):                       # one study writing into a folder at a time
        return _run_study(StudyPlan(out_dir, params, runner, method, samples, seed, groups, workers, scheduler, model,
                                    log, nominal, label, before_start, ensemble))


@dataclass(frozen=True)
class StudyPlan:
    """A study to run (`run_study`'s arguments, checked): its folder, parameters and case runner; the design
    (method, samples, seed, groups); where the cases run (workers, scheduler, ensemble lanes); what identifies the
    runner's model; whether the nominal case runs too; how it reports (log, label, before_start)."""

    out_dir: Path
    params: list[Parameter]
    runner: Callable[[str, dict], dict]
    method: str
    samples: int
    seed: int
    groups: str
    workers: int | None
    scheduler: str | None
    model: str
    log: Callable[[str], None]
    nominal: bool
    label: str
    before_start: Callable[[int], None] | None
    ensemble: int | None


def _run_study(plan: StudyPlan) -> dict:
    out_dir, params, runner, log = plan.out_dir, plan.params, plan.runner, plan.log
    method, samples, seed, groups, nominal = plan.method, plan.samples, plan.seed, plan.groups, plan.nominal
    names = [p.name for p in params]
    meta = _fingerprint(params, method, samples, seed, groups, plan.model)
    samples_csv = out_dir / "samples.csv"
    if samples_csv.exists():
        stored, stored_names, rows = read_samples(samples_csv)
        diff = study_differences(stored, meta)
        if diff or stored_names != names:
            raise UserInputError(f"{out_dir}: holds a study made with other settings: {'; '.join(diff or ['parameters'])}. "
                                 f"Re-run with the same settings to resume it, or give another -o folder")
        log(f"{out_dir}: resuming the study in this folder")
    else:
        X = design(params, method, samples, seed, groups)
        rows = ([(NOMINAL, np.array([p.nominal() for p in params]))] if nominal else []) + \
            [(f"s{i:05d}", x) for i, x in enumerate(X)]
        write_samples(samples_csv, meta, names, rows)
        _, _, rows = read_samples(samples_csv)      # the values every case sees, as stored
    records_path = out_dir / "cases.jsonl"
    records = {k: r for k, r in read_records(records_path).items() if r.get("status") == "done"}
    todo = [(name, x) for name, x in rows if name not in records]
    n_design = sum(1 for name, _ in rows if name != NOMINAL)
    log(f"{plan.label or out_dir}: {len(params)} parameters, {method} design of {samples} -> {n_design} cases"
        + (" + nominal" if nominal else "") + f"; {len(rows) - len(todo)} done earlier, {len(todo)} to run")
    if plan.before_start is not None:
        plan.before_start(len(todo))     # the cost preview (vehicle.studies.cost) may stop it here
    t0 = time.perf_counter()
    done, failed_now = 0, {}
    client = dask_client(plan.scheduler) if plan.scheduler else None

    with open(records_path, "a") as fh:
        def finished(case, r):
            nonlocal done
            done += 1
            rec = {"case": case, **r}
            fh.write(json.dumps(rec) + "\n")
            fh.flush()
            if r["status"] == "done":
                records[case] = rec
                log(f"[{done}/{len(todo)}] {case}: done in {r['seconds']:.1f} s")
            else:
                failed_now[case] = r["error"]
                log(f"[{done}/{len(todo)}] {case}: FAILED: {r['error']}")

        jobs = [(name, (runner, name, dict(zip(names, map(float, x))))) for name, x in todo]
        # --ensemble K: the drives K at a time in lockstep (vehicle.engines.ensemble)
        can_join = [isinstance(runner, DriveRunner) and eligible(runner.base)] * len(jobs)
        fn, jobs, unpack = grouped_jobs(run_one, jobs, plan.ensemble, can_join, plan.workers)
        try:
            execute(fn, jobs, workers=plan.workers, client=client, key_prefix=f"hpsim-uq-{out_dir.resolve().name}",
                    finished=lambda tag, r: [finished(case, rr) for case, rr in unpack(tag, r)])
        finally:
            if client is not None:
                client.close()
    summary = analyse(out_dir, params, rows, records, method=method, samples=samples, seed=seed, groups=groups)
    summary["wall_s"] = time.perf_counter() - t0
    summary["ran_now"] = done
    write_summary(out_dir, summary)
    return summary


def run_scenario_study(scenario: str | Path, *, samples: int, method: str = "sobol", seed: int = 0,
                       output_dir: str | Path | None = None, workers: int | None = None,
                       scheduler: str | None = None, parameters: list[str] | None = None,
                       distance: str | None = None, groups: str = "none", per_axle_struts: bool = False,
                       log: Callable[[str], None] | None = None,
                       before_start: Callable[[list], None] | None = None, ensemble: int | None = None) -> dict:
    """`hpsim uq`: a scenario file's priors studied; before_start(a prepared scenario per drive) before any drive."""
    log = log or (lambda m: None)
    src = read_scenario(scenario)
    if distance is not None:
        data = {**src.data, "distance": distance}
        src = ScenarioSource(text=src.text, name=f"{src.name} (--distance {distance})", base_dir=src.base_dir, data=data)
    all_params, notes, resolved = scenario_parameters(src, per_axle_struts=per_axle_struts)
    params = select(all_params, parameters)
    check_settings(method, samples, groups, len(params))
    check_seed(seed)
    # drives: at most a study's worth (vehicle.studies.study_folder), before any sample is drawn
    check_case_count(n_cases(method, samples, len(params)) + 1, "--samples", f"drives ({method} design of {samples})",
                     "a smaller --samples or fewer --parameters")
    for n in notes:
        log(f"{src.name}: {n}")
    out_dir = Path(output_dir) if output_dir else Path(f"{Path(scenario).stem}_uq")
    check_study_kind(out_dir, "uq")
    runner = DriveRunner(src.data, src.name, str(src.base_dir), params, str((out_dir / "cases").resolve()), distance)
    # every check before any drive: the nominal case and a typical draw (its model, for the cost preview) are valid
    nominal_case, typical_case = (prepare(ScenarioSource(text="", name=f"{src.name} ({k})", base_dir=src.base_dir,
                                  data=case_scenario(src.data, params, {p.name: v(p) for p in params}, distance)))
                                  for k, v in (("nominal case", Parameter.nominal),
                                               ("a typical draw", lambda p: p.design_prior().typical())))
    # what the drives are made from: the resolved priors and the hashes of the files the scenario reads (a changed
    # road CSV is another study: its finished cases are not reused, vehicle.results.provenance); the scenario's own
    # content is in `resolved` (after --distance)
    files = provenance.fingerprint(prepare(src))["files"]
    files.pop("scenario", None)
    model = hashlib.sha256(json.dumps([resolved, files], sort_keys=True, default=str).encode()).hexdigest()[:16]
    preview = None if before_start is None else (lambda n: before_start([nominal_case, *[typical_case] * (n - 1)][:n]))
    summary = run_study(out_dir, params, runner, method=method, samples=samples, seed=seed, groups=groups,
                        workers=workers, scheduler=scheduler, model=model, log=log, label=src.name,
                        before_start=preview, ensemble=ensemble)
    summary["scenario"] = str(scenario)
    summary["distance"] = distance
    summary["notes"] = notes
    write_summary(out_dir, summary)
    return summary


# --- analysis ----------------------------------------------------------------------------------
def analyse(out_dir: Path, params: list[Parameter], rows: list[tuple[str, np.ndarray]], records: dict, *,
            method: str, samples: int, seed: int, groups: str) -> dict:
    design_rows = [(name, x) for name, x in rows if name != NOMINAL]
    ok = [(name, x) for name, x in design_rows if name in records]
    failed = [name for name, _ in design_rows if name not in records]
    outputs = []
    for name, _ in ok:
        for k in records[name]["outputs"]:
            if k not in outputs and all(k in records[n]["outputs"] for n, _ in ok):
                outputs.append(k)
    X = np.array([x for _, x in ok]).reshape(len(ok), len(params))
    Y = np.array([[records[n]["outputs"][k] for k in outputs] for n, _ in ok]).reshape(len(ok), len(outputs))
    nominal = records.get(NOMINAL, {}).get("outputs", {})
    summary = {"study": str(out_dir), "method": method, "samples": samples, "seed": seed, "groups": groups,
               "cases": len(design_rows), "done": len(ok), "failed": failed,
               "nominal_done": NOMINAL in records,
               "parameters": [p.describe() for p in params], "outputs": outputs,
               "units": {k: output_unit(k) for k in outputs}, "nominal": {k: nominal.get(k) for k in outputs},
               "bands": bands(Y, outputs, nominal), "files": {}}
    summary["files"]["samples"] = str(out_dir / "samples.csv")
    summary["files"]["bands"] = str(write_bands(out_dir / "bands.csv", summary))
    if not ok:
        summary["sensitivity"] = {"skipped": "no case finished"}
        return summary
    if method == "sobol":
        if failed:
            summary["sensitivity"] = {"skipped": f"Sobol' indices need every case of the design: {len(failed)} of "
                                                 f"{len(design_rows)} failed (e.g. {failed[0]}); re-run to retry them"}
        else:
            summary["sobol"] = sobol_indices(params, Y, outputs, groups, seed)
            summary["files"]["sobol"] = str(write_sobol(out_dir / "sobol.csv", summary["sobol"]))
    else:
        summary["ranking"] = rank_correlations(params, X, Y, outputs)
        summary["files"]["ranking"] = str(write_ranking(out_dir / "ranking.csv", summary["ranking"]))
    summary["most_influential"] = most_influential(summary)
    return summary


def bands(Y: np.ndarray, outputs: list[str], nominal: dict) -> dict:
    out = {}
    for j, k in enumerate(outputs):
        y = Y[:, j]
        if y.size == 0:
            continue
        p = np.percentile(y, BANDS)
        out[k] = {"p5": float(p[0]), "p50": float(p[1]), "p95": float(p[2]), "mean": float(np.mean(y)),
                  "sd": float(np.std(y, ddof=1)) if y.size > 1 else 0.0, "min": float(np.min(y)),
                  "max": float(np.max(y)), "nominal": nominal.get(k), "n": int(y.size)}
    return out


def sobol_indices(params: list[Parameter], Y: np.ndarray, outputs: list[str], groups: str, seed: int) -> dict:
    """First-order and total indices per output with bootstrap confidence intervals (SALib)."""
    from SALib.analyze import sobol as sobol_analyze

    problem = salib_problem(params, groups)
    names = list(dict.fromkeys(problem["groups"])) if "groups" in problem else problem["names"]
    out = {}
    for j, k in enumerate(outputs):
        y = Y[:, j]
        if not np.ptp(y) > 1e-12 * max(1.0, float(np.max(np.abs(y)))):
            out[k] = {"constant": True, "rows": [{"parameter": n, "S1": 0.0, "S1_conf": 0.0, "ST": 0.0, "ST_conf": 0.0}
                                                  for n in names]}
            continue
        Si = sobol_analyze.analyze(problem, y, calc_second_order=False, num_resamples=NUM_RESAMPLES,
                                   conf_level=CONF_LEVEL, seed=seed + 1)
        out[k] = {"constant": False, "rows": [{"parameter": n, "S1": float(Si["S1"][i]), "S1_conf": float(Si["S1_conf"][i]),
                                               "ST": float(Si["ST"][i]), "ST_conf": float(Si["ST_conf"][i])}
                                              for i, n in enumerate(names)]}
    return out


def prcc(X: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Partial rank correlation coefficients of y with each column of X (Marino et al. 2008):
    the correlation of the ranks of x_j and y after removing the linear effect of the other ranks."""
    from scipy.stats import rankdata

    n, d = X.shape
    if n < d + 3:
        return np.full(d, np.nan)
    R = np.column_stack([rankdata(X[:, j]) for j in range(d)])
    ry = rankdata(y)
    out = np.empty(d)
    for j in range(d):
        A = np.column_stack([np.ones(n), np.delete(R, j, axis=1)])
        rx = R[:, j] - A @ np.linalg.lstsq(A, R[:, j], rcond=None)[0]
        e = ry - A @ np.linalg.lstsq(A, ry, rcond=None)[0]
        den = math.sqrt(float(rx @ rx) * float(e @ e))
        out[j] = float(rx @ e) / den if den > 0 else np.nan
    return out


def rank_correlations(params: list[Parameter], X: np.ndarray, Y: np.ndarray, outputs: list[str]) -> dict:
    from scipy.stats import spearmanr

    out = {}
    for j, k in enumerate(outputs):
        y = Y[:, j]
        constant = not np.ptp(y) > 0
        pr = np.full(len(params), np.nan) if constant else prcc(X, y)
        rows = []
        for i, p in enumerate(params):
            rho = np.nan if constant or np.ptp(X[:, i]) == 0 else float(spearmanr(X[:, i], y).statistic)
            rows.append({"parameter": p.name, "spearman": rho, "prcc": float(pr[i])})
        out[k] = {"constant": constant, "rows": rows}
    return out


def _influence(row: dict) -> float:
    """Sort key: the total index (sobol), else |PRCC|, else |Spearman| (lhs); NaN last."""
    for k in ("ST", "prcc", "spearman"):
        v = row.get(k)
        if v is not None and math.isfinite(v):
            return abs(v) if k != "ST" else v
    return -math.inf


def most_influential(summary: dict, top: int = 5) -> dict:
    """Per output the `top` parameters by total index (sobol) or |PRCC| (lhs)."""
    table = summary.get("sobol") or summary.get("ranking") or {}
    return {k: [r["parameter"] for r in sorted(v["rows"], key=_influence, reverse=True)[:top]]
            for k, v in table.items() if not v["constant"]}
