"""The runner of `hpsim optimize`: an Optuna study stored in SQLite inside the study folder, run generation by
generation on local processes or a Dask cluster (the workers of `hpsim sweep`, vehicle.studies.sweep.execute).

A generation is `population` trials asked together, evaluated in parallel and told as each ends. Its sampler is
seeded with the study's seed and the generation's index, and sees only finished trials, so a study killed
mid-generation and run again asks the same designs: the trials left running are evaluated again from their
stored designs, the finished ones never (no trial runs twice), and the study goes on as if never stopped.

An evaluator is a picklable callable `evaluate(number, design) -> dict` that never raises: `status` ("done",
"failed" or "interrupted"), `error` (the reason of a failure) and `reports` ({case name: report}, the
`hpsim report --json` of each case's drive). `DriveEvaluator` drives the study's cases; a test may give another.

A generation of `DriveEvaluator` trials runs as ensembles (vehicle.engines.ensemble): the trials K at a time, each
trial's drives the lanes of one vector step, case after case (every trial drives the same cases in the same order,
so the lanes meet case by case). Each lane's drive equals the drive on its own (a multiscale lane integrates its
windows one after the other: docs/engines.md, "Vector lanes").
"""
from __future__ import annotations

import json
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from hpsim.errors import SimulationError, UserInputError
from hpsim.extras import install_hint

from vehicle.analysis.summary import report
from vehicle.engines.ensemble import eligible, grouped_jobs
from vehicle.engines.shared_builds import process_builds
from vehicle.results.run import RunInterrupted, run_scenario
from vehicle.scenario.schema import prepare
from vehicle.studies.cost import format_duration
from vehicle.studies.optimize_objectives import case_values
from vehicle.studies.optimize_pareto import front_of, summarise, trial_rows
from vehicle.studies.optimize_study import Study
from vehicle.studies.study_folder import StudyLock, case_state
from vehicle.studies.sweep import dask_client, execute

STUDY_DB = "study.db"
STUDY_NAME = "hpsim-optimize"
TRIALS_DIR = "trials"
PROBE_SOLVER_KEYS = ("dt", "tolerance", "samples_per_block")   # kept for the objectives' probe drive (full mode)
PROGRESS_FRONT_EVERY = 5         # the front's size in every 5th progress line: finding it reads every trial


def optuna_module():
    """Optuna, or a UserInputError saying how to install it (the optional `optimize` extra)."""
    try:
        import optuna
    except ImportError:
        raise UserInputError(f"hpsim optimize needs Optuna: {install_hint('optimize')}") from None
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    return optuna


@dataclass
class DriveEvaluator:
    """Drives every case of `study` with a trial's design into `<out_dir>/trials/<number>/<case>.h5`.

    Each case's scenario is prepared and its vehicle checked (`hpsim vehicle check`'s statics) before it drives;
    a refused or failed drive fails the trial with its reason. A drive left incomplete by a stopped study resumes.
    The cases of one design drive one vehicle: its model, check and roads are shared in the worker process
    (`vehicle.engines.shared_builds`).
    """

    study: Study
    out_dir: str

    def __call__(self, number: int, design: dict, make_solver: Callable[[float], object] | None = None) -> dict:
        """make_solver: an ensemble lane's solver factory (`vehicle.engines.ensemble.run_lockstep`), for every drive."""
        t0 = time.perf_counter()
        reports = {}
        try:
            folder = Path(self.out_dir) / TRIALS_DIR / f"{number:05d}"
            folder.mkdir(parents=True, exist_ok=True)
            shared = process_builds()
            for case in self.study.cases:
                src = self.study.trial_source(case, design, number)
                prepared = prepare(src)
                shared.check_vehicle(prepared, shared.model(prepared))
                out = folder / f"{case.name}.h5"
                state = case_state(out, src)
                if state != "complete":
                    run_scenario(src, out, resume=state == "resume", overwrite=state.startswith("changed"),
                                 progress=False, shared=shared, make_solver=make_solver)
                # a drive finished here was written whole by this process: the child-process read check is for others
                reports[case.name] = report(out, check=state == "complete")
            return {"status": "done", "error": "", "reports": reports, "seconds": time.perf_counter() - t0}
        except (UserInputError, SimulationError) as exc:
            return {"status": "failed", "error": str(exc), "reports": {}, "seconds": time.perf_counter() - t0}
        except (KeyboardInterrupt, RunInterrupted):
            return {"status": "interrupted", "error": "interrupted", "reports": {}, "seconds": time.perf_counter() - t0}
        except Exception as exc:  # a bug: the trial fails with the traceback's last lines, the study goes on
            tb = traceback.format_exc().strip().splitlines()[-3:]
            return {"status": "failed", "error": f"{type(exc).__name__}: {exc} ({' | '.join(tb)})", "reports": {},
                    "seconds": time.perf_counter() - t0}

    def can_be_lanes(self) -> bool:
        """Whether every case's drive can be an ensemble lane (`ensemble.eligible`: not time-parallel; the design
        keys change values, not the solver section)."""
        return all(eligible(case.source.data) for case in self.study.cases)


def make_sampler(study: Study, generation: int):
    """The sampler of one generation, seeded by the study's seed and the generation's index."""
    optuna = optuna_module()
    seed = int(np.random.SeedSequence([study.seed, generation]).generate_state(1)[0])
    if study.sampler == "tpe":
        return optuna.samplers.TPESampler(seed=seed, n_startup_trials=study.population, multivariate=True)
    return optuna.samplers.NSGAIISampler(seed=seed, population_size=study.population)


def distributions(study: Study) -> dict:
    optuna = optuna_module()
    return {d.path: optuna.distributions.FloatDistribution(d.low, d.high, log=d.log) for d in study.design}


def fast_commits(engine) -> None:
    """SQLite in write-ahead-log mode with synchronous=NORMAL on every connection: a commit no longer waits for the
    disk (the study makes some twenty per trial); the file stays consistent when a process is killed, only a power
    cut may lose the last commits, and a lost trial runs again."""
    from sqlalchemy import event

    def pragmas(connection, _record) -> None:
        cursor = connection.cursor()
        cursor.execute("PRAGMA journal_mode=WAL")
        cursor.execute("PRAGMA synchronous=NORMAL")
        cursor.close()

    event.listen(engine, "connect", pragmas)
    engine.dispose()                  # connections opened before the listener are closed; new ones get the pragmas


@dataclass
class StoredStudy:
    """An Optuna study and the storage it lives in (trial attributes are set through the storage's public API)."""

    optuna: object
    storage: object

    def trial(self, number: int):
        """The running trial `number` (asked by this process or by one stopped before it)."""
        optuna = optuna_module()
        study_id = self.storage.get_study_id_from_name(STUDY_NAME)
        return optuna.trial.Trial(self.optuna, self.storage.get_trial_id_from_study_id_trial_number(study_id, number))


def open_study(study: Study, out_dir: Path, storage: str | None = None) -> StoredStudy:
    """The Optuna study in `storage` (default: SQLite in `<out_dir>/study.db`; an Optuna database URL shares a
    study between processes or machines; "memory": in this process only, nothing resumes), created or loaded; one
    made from another definition is refused."""
    optuna = optuna_module()
    if storage == "memory":
        storage = optuna.storages.InMemoryStorage()
    else:
        url = storage or f"sqlite:///{(out_dir / STUDY_DB).resolve()}"
        try:
            storage = optuna.storages.RDBStorage(url)
        except Exception as exc:            # SQLAlchemy's errors: a bad URL, a database that cannot be reached
            raise UserInputError(f"--storage: cannot open the study database {url!r} ({type(exc).__name__}: "
                                 f"{str(exc).splitlines()[0]})") from None
        if url.startswith("sqlite:"):
            fast_commits(storage.engine)
    directions = ["minimize" if o.goal == "min" else "maximize" for o in study.objectives]
    ostudy = optuna.create_study(study_name=STUDY_NAME, storage=storage, directions=directions, load_if_exists=True,
                                 sampler=make_sampler(study, 0))
    given = ostudy.user_attrs.get("fingerprint")
    if given is None:
        ostudy.set_user_attr("fingerprint", study.fingerprint())
        ostudy.set_user_attr("objectives", [o.name for o in study.objectives])
    elif given != study.fingerprint():
        raise UserInputError(f"{out_dir}: holds a study of another definition (design, objectives, constraints, "
                             "cases, population, sampler or seed changed); give another folder with -o")
    return StoredStudy(ostudy, storage)


def check_objectives(study: Study, log: Callable[[str], None] | None = None) -> None:
    """Every objective and constraint path found in the report of a short drive (PROBE_DISTANCE_M, in memory, full
    mode) of its case at the middle of the design: a UserInputError naming the first that is not, before the study starts."""
    from vehicle.analysis.summary import report_from
    from vehicle.results.run import run_in_memory
    from vehicle.studies.cost import PROBE_DISTANCE_M
    from vehicle.studies.optimize_objectives import check_against
    from vehicle.studies.optimize_study import middle

    for case in study.cases:
        if not any(item.case == case.name for item in [*study.objectives, *study.constraints]):
            continue
        src = study.trial_source(case, middle(study), 0)
        src.data["distance"] = min(PROBE_DISTANCE_M, float(prepare(src).scenario.distance))
        # the full mode on the short stretch (a multiscale drive needs windows spread over a long one): the report
        # holds the same keys
        src.data["solver"] = {k: v for k, v in (src.data.get("solver") or {}).items() if k in PROBE_SOLVER_KEYS}
        (log or (lambda m: None))(f"case {case.name}: checking the objectives on a {src.data['distance']:.0f} m "
                                  "drive of the middle design")
        sink = run_in_memory(src)
        check_against(report_from(sink, src.name), study.objectives, study.constraints, case.name,
                      study.file or study.name)


def pending_trials(ostudy) -> list:
    optuna = optuna_module()
    states = (optuna.trial.TrialState.RUNNING, optuna.trial.TrialState.WAITING)
    return [t for t in ostudy.get_trials(deepcopy=False) if t.state in states]


def run_study(study: Study, out_dir: str | Path, *, evaluate: Callable[[int, dict], dict] | None = None,
              trials: int | None = None, workers: int | None = None, scheduler: str | None = None, client=None,
              log: Callable[[str], None] | None = None, before_start: Callable[[int], None] | None = None,
              storage: str | None = None, ensemble: int | None = None) -> dict:
    """Run `study` until `trials` trials (default: the study's) have finished; returns the folder's state
    (vehicle.studies.optimize_pareto.summarise).

    evaluate: default DriveEvaluator; workers: local processes (1: in this process); scheduler or client: a Dask
    cluster. storage: where the Optuna study lives (open_study). before_start(trials to run) is called before any
    runs (the cost preview may stop it). ensemble: a DriveEvaluator's trials K at a time as ensemble lanes (1: each
    on its own; None: chosen as `hpsim sweep` chooses, `ensemble.group_size`). Ctrl-C leaves the study resumable:
    run it again with the same folder.
    """
    log = log or (lambda m: None)
    out_dir = Path(out_dir)
    budget = trials if trials is not None else study.trials
    if budget is None or budget < 1:
        raise UserInputError(f"--trials: give the number of trials (>= 1), got {budget}")
    out_dir.mkdir(parents=True, exist_ok=True)
    with StudyLock(out_dir):
        stored = open_study(study, out_dir, storage)
        ostudy = stored.optuna
        evaluate = evaluate or DriveEvaluator(study, str(out_dir.resolve()))
        done_before = sum(t.state.is_finished() for t in ostudy.get_trials(deepcopy=False))
        todo = max(0, budget - done_before)
        log(f"{study.name}: {budget} trials of {len(study.cases)} case(s), {done_before} done before, "
            f"{todo} to run in generations of {study.population}; study in {storage or out_dir / STUDY_DB}")
        if before_start is not None and todo:
            before_start(todo)
        own_client = client is None and scheduler is not None
        client = dask_client(scheduler) if own_client else client
        try:
            _generations(study, stored, evaluate, budget, workers, client, log, out_dir, ensemble)
        except KeyboardInterrupt:
            left = len(pending_trials(ostudy))
            log(f"{study.name}: interrupted; {left} trial(s) of this generation will run again, finished ones are "
                f"kept. Continue with the same command and folder {out_dir}")
            raise
        finally:
            if own_client:
                client.close()
        return summarise(study, ostudy.get_trials(deepcopy=False), out_dir)


def _generations(study, stored, evaluate, budget, workers, client, log, out_dir, ensemble=None) -> None:
    ostudy = stored.optuna
    dist = distributions(study)
    t0, n_run = time.perf_counter(), 0
    while True:
        pending = pending_trials(ostudy)
        n_all = len(ostudy.get_trials(deepcopy=False))
        first = min((t.number for t in pending), default=n_all)
        ostudy.sampler = make_sampler(study, first // study.population)
        if not pending:
            if n_all >= budget:
                return
            size = min(study.population - n_all % study.population, budget - n_all)
            pending = [ostudy.ask(dist) for _ in range(size)]
        designs = {t.number: {d.path: float(t.params[d.path]) for d in study.design} for t in pending}
        jobs = [(str(n), (n, designs[n])) for n in sorted(designs)]

        def finished(tag: str, result: dict) -> None:
            nonlocal n_run
            number = int(tag)
            if result.get("status") == "interrupted":
                return
            error = tell(study, stored, number, result)
            n_run += 1
            n_done = sum(t.state.is_finished() for t in ostudy.get_trials(deepcopy=False))
            rate = (time.perf_counter() - t0) / n_run
            front = len(front_of(study, trial_rows(study, ostudy.get_trials(deepcopy=False)))) \
                if n_run % PROGRESS_FRONT_EVERY == 0 or n_done >= budget else None
            what = f"FAILED: {error}" if error else "done"
            size = "" if front is None else f"; front {front} design(s)"
            log(f"[{n_done}/{budget}] trial {number}: {what}{size}; about "
                f"{format_duration(rate * max(0, budget - n_done))} left")

        lanes = ensemble if isinstance(evaluate, DriveEvaluator) and evaluate.can_be_lanes() else 1
        fn, jobs, unpack = grouped_jobs(evaluate, jobs, lanes, [True] * len(jobs), workers)
        execute(fn, jobs, workers=workers, client=client, key_prefix=f"hpsim-optimize-{study.name}-{out_dir.name}",
                finished=lambda tag, r: [finished(t, rr) for t, rr in unpack(tag, r)])
        if pending_trials(ostudy):
            raise KeyboardInterrupt        # a trial was interrupted: the generation stays resumable


def tell(study: Study, stored: StoredStudy, number: int, result: dict) -> str:
    """Record a trial's result: objectives and constraint margins, or the reason it failed (returned; "" when
    it did not)."""
    optuna = optuna_module()
    trial = stored.trial(number)
    trial.set_user_attr("seconds", float(result.get("seconds", 0.0)))
    if result["status"] == "done":
        try:
            objectives, margins = case_values(result["reports"], study.objectives, study.constraints)
        except ValueError as exc:
            result = {**result, "status": "failed", "error": f"the report of a case does not give {exc}"}
        else:
            trial.set_user_attr("constraint_margins", json.dumps(list(margins.values())))
            for k, margin in enumerate(margins.values()):
                trial.set_constraint(f"c{k}", -margin)             # Optuna: feasible when <= 0
            stored.optuna.tell(number, [objectives[o.name] for o in study.objectives])
            return ""
    error = str(result.get("error") or "failed")
    trial.set_user_attr("error", error)
    stored.optuna.tell(number, state=optuna.trial.TrialState.FAIL)
    return error
