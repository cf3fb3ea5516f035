"""One way from a prepared scenario to an engine (vehicle.engines.contract.Engine): the scenario's
`solver.mode` and `solver.time_parallel` pick the engine; each is built from the same model, road and
settings. A new engine is one module and one line in ENGINES (docs/CONTRIBUTING.md)."""
from __future__ import annotations

from typing import Callable

from hpsim.errors import UserInputError
from hpsim.stages import timed

from vehicle.scenario.settings import resolve_segments, resolve_time_parallel_lanes
from vehicle.scenario.work_limits import segments_for
from vehicle.engines.choice import engine_for
from vehicle.engines.contract import Engine
from vehicle.engines.full import Drive
from vehicle.engines.multiscale import MultiscaleDrive
from vehicle.engines.shared_builds import OwnBuilds, SharedBuilds
from vehicle.engines.time_parallel import MIN_SEGMENT_S, TimeParallelDrive


def _full(model, road, prepared, make_solver=None) -> Engine:
    settings = prepared.settings()
    return Drive(model, road, settings, solver=None if make_solver is None else make_solver(settings.dt_s))


def _multiscale(model, road, prepared, make_solver=None) -> Engine:
    settings = prepared.settings()
    return MultiscaleDrive(model, road, settings, prepared.scenario.solver.multiscale_settings(),
                           solver=None if make_solver is None else make_solver(settings.dt_s))


def _segments(prepared) -> int:
    """solver.time_parallel resolved (the processes): "auto" takes one per CPU, at most one per MIN_SEGMENT_S of
    drive."""
    tp = prepared.scenario.solver.time_parallel
    return segments_for(resolve_segments(tp), tp == "auto", prepared.duration_s(), MIN_SEGMENT_S)


def _time_parallel(model, road, prepared, make_solver=None) -> Engine:
    workers = _segments(prepared)
    lanes = resolve_time_parallel_lanes(prepared.scenario.solver.time_parallel_lanes, workers, prepared.duration_s(),
                                        MIN_SEGMENT_S)
    return TimeParallelDrive(model, road, prepared.settings(), workers * lanes, lanes=lanes)


# engine name -> builder(model, road, prepared, make_solver); the full and multiscale drives step with make_solver (an
# ensemble lane's solver), the time-parallel drive builds its own
ENGINES = {"full": _full, "multiscale": _multiscale, "time_parallel": _time_parallel}


def engine_name(prepared) -> str:
    """The engine a scenario asks for (`choice.engine_for`): its solver.mode, "time_parallel" for a full drive in
    P > 1 segments."""
    return engine_for(prepared.scenario.solver.mode, _segments(prepared))


def build_engine(prepared, make_solver: Callable[[float], object] | None = None,
                 shared: SharedBuilds | None = None) -> tuple[object, Engine]:
    """(model, engine) of a prepared scenario (vehicle.scenario.schema.Prepared), ready to run: its work size checked
    first (refused beyond the limits, before anything is compiled).

    make_solver(dt): the solver a full drive steps with (a solver of vehicle.numerics.contract, e.g. an ensemble
    lane's); None: the compiled ROS2. shared: the model, vehicle check and road shared with the other drives of a
    study's worker process (`vehicle.engines.shared_builds`); None: all built for this drive."""
    prepared.check_work()
    builds = shared if shared is not None else OwnBuilds()
    model = timed("build: model", builds.model, prepared)
    builds.check_vehicle(prepared, model)  # the quiet `hpsim vehicle check`: warnings logged, errors refuse the drive
    road = timed("road", builds.road, prepared)
    try:
        builder = ENGINES[engine_name(prepared)]
        return model, timed("build: drive (the compile included)", builder, model, road, prepared, make_solver)
    except UserInputError as exc:
        raise UserInputError(f"{prepared.source.name}: {exc}") from None
