"""The engine contract: what every engine offers (`Engine`), what it hands a result sink (`DriveSink`), what a
caller may observe of each block (`BlockObserver`), and the state and result of a drive. An engine is
made from a prepared scenario by `vehicle.engines.build.build_engine`; the results layer runs it
through this contract only (vehicle.results.run).

Engines: `vehicle.engines.full.Drive` (mode "full"), `vehicle.engines.multiscale.MultiscaleDrive`
("multiscale"), `vehicle.engines.time_parallel.TimeParallelDrive` ("time_parallel"). How to add one:
docs/CONTRIBUTING.md.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Protocol

import numpy as np

from hpsim.cancellation import NEVER, CancelToken


class Engine(Protocol):
    """A drive of a vehicle model over a road with settings (vehicle.scenario.settings.DriveSettings).

    mode:            "full", "multiscale", "time_parallel": recorded as the results' solver_mode
    model, settings: the vehicle model and the drive settings it runs
    gas_masses:      the struts' gas masses [kg] as charged (recorded with the results)
    total_time_s:    the drive's duration [s]
    build_s:         set-up wall time [s] (model, compilation, proxies)
    T_index:         the state indices of the reported strut temperatures (the surface node, per station)
    resumable:       False: an interrupted run is not continued but started again (`--overwrite`)
    """

    mode: str
    model: object
    settings: object
    gas_masses: np.ndarray
    total_time_s: float
    build_s: float
    T_index: np.ndarray
    resumable: bool = True

    def initial_equilibrium(self):
        """The standing vehicle before the drive (vehicle.physics.equilibrium.Equilibrium)."""

    def initial_state(self) -> "DriveState":
        """The state the drive starts from."""

    def describe(self) -> tuple[dict, dict, dict]:
        """(one block of samples, one statistics row, one state dict) with the keys and shapes the sink will get,
        so that a file's datasets can all be made before the drive starts (SWMR cannot create objects)."""

    def run(self, sink: "DriveSink | None" = None, state: "DriveState | None" = None,
            progress: Callable | None = None, checkpoint_every_blocks: int = 6,
            cancel: CancelToken = NEVER) -> "DriveResult":
        """Drive from `state` (None: the start) to the end, handing samples, statistics rows and checkpoints to
        `sink`; resumable from any checkpoint the sink kept. Once `cancel` is requested the engine returns
        normally at its next checkpoint with what it has (nothing is raised); the caller reads
        `cancel.requested` to tell a stopped run from a finished one."""

    def final_values(self, state: "DriveState") -> dict:
        """The /summary values of the drive's end (energies, temperatures, whole-drive ride numbers)."""

    def summary_extra(self) -> dict:
        """What this engine adds to the results' /summary (its error estimates); {} for none."""


class DriveSink(Protocol):
    def start(self, info: dict) -> None: ...
    def samples(self, block: dict) -> None: ...
    def stats(self, rows: list[dict]) -> None: ...
    def checkpoint(self, state: dict) -> None: ...


@dataclass
class DriveState:
    """Everything needed to continue a drive: the resume checkpoint."""

    t_s: float
    s_m: float
    x: np.ndarray
    next_stats_m: float
    last_stats: dict               # quadratures and time at the last km boundary
    sample_index: int = 0
    solver_memory: np.ndarray = field(default_factory=lambda: np.zeros(0))   # what the solver carries

    def as_dict(self) -> dict:
        return {"t_s": self.t_s, "s_m": self.s_m, "x": self.x.copy(), "next_stats_m": self.next_stats_m,
                "last_stats_t_s": self.last_stats["t_s"], "last_stats_q": self.last_stats["q"].copy(),
                # the running sum of the gas temperature samples since the last boundary (its interval mean)
                "last_stats_gas_sum": np.asarray(self.last_stats["gas_sum"], float).copy(),
                "last_stats_gas_n": int(self.last_stats.get("gas_n", 0)),
                "sample_index": self.sample_index, "solver_memory": np.asarray(self.solver_memory, float).copy()}

    @classmethod
    def from_dict(cls, d: dict) -> "DriveState":
        return cls(t_s=float(d["t_s"]), s_m=float(d["s_m"]), x=np.asarray(d["x"], float),
                   next_stats_m=float(d["next_stats_m"]),
                   last_stats={"t_s": float(d["last_stats_t_s"]), "q": np.asarray(d["last_stats_q"], float),
                               "gas_sum": np.asarray(d.get("last_stats_gas_sum", 0.0), float),
                               "gas_n": int(d.get("last_stats_gas_n", 0))},
                   sample_index=int(d["sample_index"]),
                   solver_memory=np.atleast_1d(np.asarray(d.get("solver_memory", []), float)))


class BlockObserver(Protocol):
    """What a caller of `Drive.run` sees of every block besides the sink's outputs (vehicle.engines.time_parallel
    keeps a segment's states and raw statistics intervals to correct them when the segments are joined)."""

    def block(self, X: np.ndarray, U: np.ndarray, memory: np.ndarray, outputs: dict) -> None:
        """The block's states (nx, samples), inputs and solver memory at the samples, and its output series."""

    def intervals(self, intervals: list[tuple]) -> None:
        """The statistics intervals the block ended (`Drive._stats_intervals`)."""


@dataclass
class DriveResult:
    state: DriveState
    after: object
    wall_s: float
    integration_s: float
    solver_error: dict | None = None         # the step-doubling estimate's summary entries (None: not estimated)
