"""A drive: the vehicle DAE over a road with a speed profile, fast, in bounded memory.

`Drive` ties a `VehicleModel` to a road (terrain.Road, enveloped by each axle's tyre contact
length), a speed profile (`vehicle.runs.speed.SpeedProfile`: constant, table, recorded or
generated), ambient and initial temperatures and levelling on/off. It integrates with the compiled
ROS2 stepper in blocks; each block's inputs (road under each tyre at its own distance behind axle 1
on its axle's pass surface, speed, ambient, the profile's longitudinal acceleration) are sampled just
in time, so memory does not grow with distance. After every block it hands decimated time series,
finished per-km statistics and a checkpoint to a sink (an HDF5 writer, or nothing), so a long
run that fails or is interrupted keeps what it did and can resume.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import cached_property
from typing import Callable, Protocol

import numpy as np

from hpsim.errors import SimulationError, UserInputError

from vehicle.physics import thermal
from vehicle.physics.equilibrium import EquilibriumSolver, charge_gas_masses
from vehicle.physics import ride
from vehicle.physics.model import DISSIPATION_TERMS, ENERGY_TERMS, HULL_ACCELERATIONS, VehicleModel
from vehicle.numerics.error_estimate import StepDoublingEstimate, check_spacing_s, window_steps
from vehicle.numerics.codegen import precompile
from vehicle.numerics.solvers import Ros2, compiled_outputs, outputs_graph
from vehicle.runs.speed import SpeedProfile   # noqa: F401  (the drive's speed profile; re-exported)
from vehicle.scenario.work_limits import samples_per_call


@dataclass
class DriveSettings:
    distance_m: float
    speed: SpeedProfile
    ambient_K: float = 298.15
    initial_temperatures_K: np.ndarray | float = 298.15
    compensation: bool = False
    dt_s: float = 0.004
    output_interval_s: float = 1.0
    samples_per_block: int = 10
    stats_interval_m: float = 1000.0
    # step-doubling error estimate (vehicle.numerics.error_estimate): tolerance on the relative error of
    # the strut heat, and every how many sample blocks one window is checked (0: no estimate)
    tolerance: float = 0.10
    error_check_every: int = 10

    def validate(self):
        if not self.distance_m > 0:
            raise UserInputError(f"distance: must be > 0 m, got {self.distance_m}")
        if not 1e-4 <= self.dt_s <= 0.02:
            raise UserInputError(f"solver.dt: must be in [0.1, 20] ms, got {self.dt_s * 1e3:.4g} ms")
        k = self.output_interval_s / self.dt_s
        if abs(k - round(k)) > 1e-6 or round(k) < 1:
            raise UserInputError(f"output.interval: must be a whole number of steps of {self.dt_s * 1e3:.4g} ms, "
                                 f"got {self.output_interval_s} s")


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
    """What a caller of `Drive.run` sees of every block besides the sink's outputs (vehicle.runs.time_parallel
    keeps a segment's states and raw statistics intervals to correct them when the segments are joined)."""

    def block(self, X: np.ndarray, U: np.ndarray, memory: np.ndarray, outputs: dict) -> None:
        """The block's states (nx, samples), inputs and solver memory at the samples, and its output series."""

    def intervals(self, intervals: list[tuple]) -> None:
        """The statistics intervals the block ended (`Drive._stats_intervals`)."""


class Drive:
    """A drive of `model` over `road` with `settings`, integrated by `solver` (default: the compiled
    ROS2 at settings.dt_s); `run(sink)` hands samples, statistics and checkpoints to a sink."""

    # the drive ends at its distance: after the last whole output interval, a partial one (the steps left, one
    # sample at the end); False: at the last whole interval (the multiscale and time-parallel engines)
    partial_last_sample = True

    def __init__(self, model: VehicleModel, road, settings: DriveSettings, *, gas_masses=None, solver=None):
        if solver is not None:
            settings.dt_s = solver.dt
        settings.validate()
        self.model = model
        self.settings = settings
        # the road each station reads: enveloped by its axle's tyre (one envelope per distinct contact length)
        envelopes: dict = {}
        self.station_roads = []
        for i in range(model.n):
            L = float(model.tyre[i].contact_length)
            if L not in envelopes:
                envelopes[L] = road.enveloped(L) if L > 0 else road
            self.station_roads.append(envelopes[L])
        self.road = self.station_roads[0]
        t0 = time.perf_counter()
        self.gas_masses = charge_gas_masses(model) if gas_masses is None else np.asarray(gas_masses, float)
        self.equilibrium_solver = EquilibriumSolver(model)
        self.p = model.run_parameters(self.gas_masses, settings.compensation)
        self.K = int(round(settings.output_interval_s / settings.dt_s))
        self.M = samples_per_call(self.K, settings.samples_per_block)   # a long interval: fewer samples per call
        solver = solver or Ros2(settings.dt_s)
        # the block outputs in one compiled call per block (the samples of a full block); the baseline engine of
        # the benchmarks (solver.legacy_outputs) and an uncompiled solver keep CasADi's virtual machine
        outputs_compiled = getattr(solver, "compile", False) and not getattr(solver, "legacy_outputs", False)
        self.s_grid, self.t_grid = settings.speed.time_grid(settings.distance_m + 1.0)
        self.total_time_s = float(np.interp(settings.distance_m, self.s_grid, self.t_grid))
        estimate = settings.error_check_every > 0 and hasattr(solver, "refined_solver")
        # the step-doubling window: ERROR_WINDOW_S of drive whatever the output interval (an estimate of the step's
        # error must not depend on how often results are stored)
        self.error_steps = window_steps(settings.dt_s)
        if hasattr(solver, "block_graph"):
            # the libraries this drive needs, compiled together (one compiler each) when not in the cache yet
            graphs = [solver.block_graph(model, self.K, self.M)]
            if estimate:
                graphs.append(solver.refined_solver(2).block_graph(model, 2 * self.error_steps, 1))
                if self._coarse_sample() is None:
                    graphs.append(solver.refined_solver(1).block_graph(model, self.error_steps, 1))
            if self._tail_steps() and hasattr(solver, "refined_solver"):
                graphs.append(solver.refined_solver(1).block_graph(model, 1, 1))
            if outputs_compiled:
                graphs.append(outputs_graph(model, self.M))
            precompile([g for g in graphs if g is not None])
        self.solver = solver.bind(model, self.K, self.M)
        self.outputs = model.output_function_ode()
        self.compiled_outputs = compiled_outputs(model, self.M) if outputs_compiled else None
        # the drive's end closes the statistics interval it cuts (a partial row); a piece of a drive that another
        # continues (vehicle.runs.time_parallel) leaves it open
        self.close_last_interval = True
        self.build_s = time.perf_counter() - t0
        n = model.n
        self.quad_index = np.array([model.idx(f"E_{e}[{i}]") for e in ENERGY_TERMS for i in range(n)]
                                   + [model.idx(f"I_v2[{i}]") for i in range(n)]
                                   + [model.idx(f"I_{a}2") for a in HULL_ACCELERATIONS])
        # the strut heat network (vehicle.physics.thermal): the surface is what a pyrometer reads and
        # what "strut temperature" means in results; the statics after the drive see the oil (and the
        # gas, which follows the oil within seconds at rest)
        self.node_index = {node: np.array([model.idx(f"T_{node}[{i}]") for i in range(n)]) for node in thermal.NODES}
        self.T_index = self.node_index["surface"]
        self.T_oil_index = self.node_index["oil"]
        self.T_wall_index = self.node_index["wall"]
        # the gas node: the strut's T_gas state (energy-equation gas), else the gas is at the oil temperature
        self.T_gas_index = np.array([model.idx(f"T_gas[{i}]") if "T_gas" in model.struts[i].state_names
                                     else model.idx(f"T_oil[{i}]") for i in range(n)])
        # the ride quadratures after them (vehicle.physics.model.VehicleModel.ride_index): positions in quad_index
        self.ride_slots, k = {}, len(self.quad_index)
        for q, idx in model.ride_index.items():
            self.ride_slots[q] = k + np.arange(idx.size).reshape(idx.shape)
            k += idx.size
        if model.ride_index:
            self.quad_index = np.concatenate([self.quad_index] + [idx.ravel() for idx in model.ride_index.values()])
        self.travel_bin_edges_m = model.travel_bin_edges()
        self.heat_index = [model.energy_index[e] for e in DISSIPATION_TERMS]
        self.error_estimate = None
        self._probes = {}
        if estimate:
            self.error_estimate = StepDoublingEstimate(settings.dt_s, settings.tolerance, settings.output_interval_s,
                                                       n, names=[str(s) for s in model.station_names])
            t0 = time.perf_counter()
            self._probe(2)                   # compiled (or fetched) now: part of the set-up, not of the run
            self.build_s += time.perf_counter() - t0

    # --- initial state --------------------------------------------------------------------------
    def initial_equilibrium(self):
        T0 = np.broadcast_to(np.asarray(self.settings.initial_temperatures_K, float), (self.model.n,))
        return self.equilibrium_solver.solve(T0, self.gas_masses)

    def initial_state(self) -> DriveState:
        x = self.model.state_at_rest(self.initial_equilibrium(), self.gas_masses)
        return DriveState(t_s=0.0, s_m=0.0, x=x, next_stats_m=self.settings.stats_interval_m,
                          last_stats={"t_s": 0.0, "q": x[self.quad_index].copy(), "gas_sum": np.zeros(self.model.n),
                                      "gas_n": 0},
                          solver_memory=np.zeros_like(self.solver.get_state()))

    def describe(self):
        """(one block of samples, one statistics row, one state dict) with the keys and shapes the drive
        will hand to a sink, so a sink can lay out its storage before the drive starts."""
        st = self.initial_state()
        t = np.array([0.0])
        block = self._block_outputs(st.x[:, None], self.inputs(t), t, t, st.solver_memory[:, None])
        row = self._stats_row(self.settings.stats_interval_m, 1.0, np.zeros(len(self.quad_index)), st.x)
        return block, row, st.as_dict()

    # --- inputs -----------------------------------------------------------------------------------
    def distance_at(self, t):
        return np.interp(t, self.t_grid, self.s_grid)

    @cached_property
    def _input_groups(self) -> list[tuple]:
        """The stations grouped by the surface their tyre reads: (enveloped road, track, pass, station indices,
        their distances behind the first axle [m])."""
        m, P = self.model, self.model.params
        groups: dict = {}
        for i in range(m.n):
            track = "left" if i % 2 == 0 else "right"
            surface, k = self.station_roads[i], P.station_axle(i)
            key = (id(surface), track, id(surface.heights(track, k)))
            groups.setdefault(key, (surface, track, k, []))[3].append(i)
        return [(surface, track, k, np.array(st), np.array([float(m.a[i]) for i in st]))
                for surface, track, k, st in groups.values()]

    def inputs(self, t: np.ndarray) -> np.ndarray:
        """Input matrix (nu, len(t)) by name (`VehicleModel.input_matrix`): road height and rate under each
        tyre (axle k reads pass k of the ground, terrain.passes: the wheels ahead of it have rolled over it),
        speed, ambient, the speed profile's longitudinal acceleration a = v dv/ds (0 at constant speed)."""
        m = self.model
        s = self.distance_at(t)
        v = self.settings.speed.speed(s)
        road, rate = np.empty((m.n, len(t))), np.empty((m.n, len(t)))
        for surface, track, pass_index, stations, offsets in self._input_groups:
            # the stations on one surface in one call (elementwise: the same values as one call per station)
            road[stations], slope = surface.evaluate(s[None, :] - offsets[:, None], track, pass_index=pass_index)
            rate[stations] = slope * v
        return m.input_matrix(len(t), road=road, road_rate=rate, speed=v, ambient=self.settings.ambient_K,
                              acceleration=self.settings.speed.acceleration(s))

    # --- error estimate -------------------------------------------------------------------------
    def _probe(self, factor: int):
        """The solver at dt/factor bound for one window of error_steps * factor steps (factor 1: the coarse run,
        when the window is not one of the block's samples)."""
        if factor not in self._probes:
            self._probes[factor] = self.solver.refined_solver(factor).bind(self.model, self.error_steps * factor, 1)
        return self._probes[factor]

    def _coarse_sample(self) -> int | None:
        """The column of a block's samples that ends the error window (None: the window is integrated again)."""
        j, rest = divmod(self.error_steps, self.K)
        return j - 1 if rest == 0 and 1 <= j <= self.M else None

    def _heat(self, x) -> np.ndarray:
        """Energy each strut has dissipated (valve, friction, gas, end stops) [J] in state(s) x."""
        return sum(x[idx] for idx in self.heat_index)

    def _check_error(self, st: "DriveState", x_coarse: np.ndarray) -> None:
        """Step doubling on this block's first sample: integrate it again from the same start with dt/2 (and
        dt/4 once the estimate exceeds the tolerance) and add the differences to the estimate."""
        est = self.error_estimate
        factors = (2, 4) if est.exceeded() else (2,)
        j = self._coarse_sample()
        probes = [self._probe(f) for f in ((1,) if j is None else ()) + factors]   # a first compile: not counted
        t0 = time.perf_counter()
        dt, W = self.settings.dt_s, self.error_steps
        if j is None:                      # the window again at dt (it is not a sample of the block)
            coarse = probes.pop(0)
            coarse.set_state(st.solver_memory)
            x_coarse = coarse.advance(st.x, self.inputs(st.t_s + dt * np.arange(W + 1)), self.p)[:, -1]
        else:
            x_coarse = x_coarse[:, j]
        levels = [(1, x_coarse)]
        for factor, probe in zip(factors, probes):
            t_cols = st.t_s + (dt / factor) * np.arange(W * factor + 1)
            probe.set_state(st.solver_memory)
            x = probe.advance(st.x, self.inputs(t_cols), self.p)[:, -1]
            if not np.all(np.isfinite(x)):
                break
            levels.append((factor, x))
        for level, ((_, xc), (_, xf)) in enumerate(zip(levels, levels[1:])):
            est.add(level, self._heat(xc) - self._heat(st.x), self._heat(xf) - self._heat(st.x),
                    self.model.strut_deflections(xc[:, None])[:, 0], self.model.strut_deflections(xf[:, None])[:, 0])
        est.cost_s += time.perf_counter() - t0

    # --- run --------------------------------------------------------------------------------------
    def run(self, sink: DriveSink | None = None, state: DriveState | None = None,
            progress: Callable[[float, float, float], None] | None = None,
            checkpoint_every_blocks: int = 6, observer: "BlockObserver | None" = None) -> "DriveResult":
        m, S = self.model, self.settings
        st = self.initial_state() if state is None else state
        self.solver.set_state(st.solver_memory)
        dt = S.dt_s
        wall0 = time.perf_counter()
        integ_s = 0.0
        blocks = 0
        sample_dt = self.K * dt
        # error windows every error_check_every blocks of at least check_spacing_s (the first block is left out)
        spacing = check_spacing_s(self.K * self.M * dt)
        next_check = st.t_s + spacing
        # whole output samples within the distance, then the partial last one (_tail)
        while st.t_s + sample_dt <= self.total_time_s + 1e-9:
            t_cols = st.t_s + dt * np.arange(self.K * self.M + 1)
            U = self.inputs(t_cols)
            ti = time.perf_counter()
            X = self.solver.advance(st.x, U, self.p)
            memory = self.solver.memory_samples
            integ_s += time.perf_counter() - ti
            # (the first block is left out: the start from rest is a transient unlike the drive, with little of its heat)
            if self.error_estimate is not None and st.t_s >= next_check - 1e-9 and np.all(np.isfinite(X[:, 0])):
                self._check_error(st, X)
                next_check = st.t_s + spacing * self.settings.error_check_every
            t_samples = st.t_s + dt * self.K * np.arange(1, self.M + 1)
            s_samples = self.distance_at(t_samples)
            self._check(X, t_samples, s_samples, st.x)
            # keep only samples within the drive
            keep = t_samples <= self.total_time_s + 1e-9
            if not np.all(keep):
                X, t_samples, s_samples, memory = X[:, keep], t_samples[keep], s_samples[keep], memory[:, keep]
            U_samples = U[:, self.K * np.arange(1, X.shape[1] + 1)]
            block = self._block_outputs(X, U_samples, t_samples, s_samples, memory)
            intervals = self._stats_intervals(st, X, t_samples, s_samples)
            rows = [self._stats_row(*interval) for interval in intervals]
            if observer is not None:
                observer.block(X, U_samples, memory, block)
                observer.intervals(intervals)
            st = DriveState(t_s=float(t_samples[-1]), s_m=float(s_samples[-1]), x=X[:, -1].copy(),
                            next_stats_m=st.next_stats_m, last_stats=st.last_stats,
                            sample_index=st.sample_index + X.shape[1], solver_memory=memory[:, -1].copy())
            if sink is not None:
                sink.samples(block)
                if rows:
                    sink.stats(rows)
            blocks += 1
            last = st.t_s + sample_dt > self.total_time_s + 1e-9
            if sink is not None and (blocks % checkpoint_every_blocks == 0 or last):
                sink.checkpoint(st.as_dict())
            if progress is not None:
                progress(st.s_m, float(S.speed.speed(st.s_m)), st.t_s)
            if not np.all(keep):
                break
        if self._tail_steps(st.t_s):
            ti = time.perf_counter()
            st = self._tail(st, sink, observer, progress)
            integ_s += time.perf_counter() - ti
        wall = time.perf_counter() - wall0
        final_T = st.x[self.T_oil_index]
        V_oil = np.array([st.x[m.idx(f"V_oil[{i}]")] for i in range(m.n)])
        after = self.equilibrium_solver.solve(final_T, self.gas_masses, V_oil)
        error = None if self.error_estimate is None else self.error_estimate.summary(integ_s)
        return DriveResult(state=st, after=after, wall_s=wall, integration_s=integ_s, solver_error=error)

    def _tail_steps(self, t_s: float | None = None) -> int:
        """Steps of the partial last output interval from t_s (default: the last whole sample) to the drive's end
        (0: the drive ends on a whole sample, or the engine keeps whole intervals)."""
        solver = getattr(self, "solver", None)          # None while the drive is being built
        if not self.partial_last_sample or (solver is not None and not hasattr(solver, "refined_solver")):
            return 0
        dt = self.settings.dt_s
        sample_dt = self.K * dt
        if t_s is None:
            t_s = np.floor(self.total_time_s / sample_dt + 1e-9) * sample_dt
        rest = self.total_time_s - t_s
        return int(np.ceil(rest / dt - 1e-6)) if rest > 1e-6 * dt else 0

    def _tail(self, st: "DriveState", sink, observer, progress) -> "DriveState":
        """The partial last output interval: its steps one by one (a one-step compiled function), one sample at the
        drive's end (within a step of it), its statistics row closed, a checkpoint."""
        n = self._tail_steps(st.t_s)
        dt = self.settings.dt_s
        if "tail" not in self._probes:
            self._probes["tail"] = self.solver.refined_solver(1).bind(self.model, 1, 1)
        one = self._probes["tail"]
        one.set_state(st.solver_memory)
        t_cols = st.t_s + dt * np.arange(n + 1)
        U = self.inputs(t_cols)
        x = st.x
        for k in range(n):
            x = one.advance(x, U[:, k:k + 2], self.p)[:, -1]
        X, memory = x[:, None], one.memory_samples
        t_samples = t_cols[-1:]
        s_samples = self.distance_at(t_samples)
        self._check(X, t_samples, s_samples, st.x)
        block = self._block_outputs(X, U[:, -1:], t_samples, s_samples, memory)
        intervals = self._stats_intervals(st, X, t_samples, s_samples, final=True)
        if observer is not None:
            observer.block(X, U[:, -1:], memory, block)
            observer.intervals(intervals)
        st = DriveState(t_s=float(t_samples[-1]), s_m=float(s_samples[-1]), x=x.copy(), next_stats_m=st.next_stats_m,
                        last_stats=st.last_stats, sample_index=st.sample_index + 1,
                        solver_memory=memory[:, -1].copy())
        if sink is not None:
            sink.samples(block)
            rows = [self._stats_row(*interval) for interval in intervals]
            if rows:
                sink.stats(rows)
            sink.checkpoint(st.as_dict())
        if progress is not None:
            progress(st.s_m, float(self.settings.speed.speed(st.s_m)), st.t_s)
        return st

    # a state this far outside physics means the integration has failed, whatever the solver says
    PHYSICAL_TEMPERATURE_K = (150.0, 273.15 + 400.0)
    STROKE_MARGIN_M = 0.02

    def _advice(self) -> str:
        S = self.settings
        v_max = float(np.max(S.speed.speeds_m_per_s)) * 3.6
        return (f"scenario extremes: speed up to {v_max:.4g} km/h, solver.dt {S.dt_s * 1e3:.4g} ms; "
                f"try a smaller solver.dt (e.g. {S.dt_s * 500:.3g} ms) or a lower speed / smoother road")

    def _check(self, X, t, s, x_before=None):
        """Stop with a SimulationError naming the strut, the state and what to change when the solution
        is non-finite or outside physical bounds (deflection beyond the end stops, temperatures)."""
        m = self.model
        finite = np.isfinite(X)
        if not np.all(finite):
            col = int(np.argmax(~np.all(finite, axis=0)))
            bad = [m.layout.names[k] for k in np.flatnonzero(~finite[:, col])]
            first = bad[0]
            station = None
            if "[" in first:
                k = int(first[first.index("[") + 1:-1])
                station = m.station_names[k] if k < m.n else None
            where = f"strut {station}, state {first.split('[')[0]}" if station else f"state {first}"
            last = ""
            if station is not None:
                prev = X[:, col - 1] if col > 0 else x_before
                if prev is not None and np.all(np.isfinite(prev)):
                    k = m.station_names.index(station)
                    x_def = float(m.strut_deflections(prev[:, None])[k, 0])
                    last = (f"; last finite sample: deflection {x_def * 1e3:.1f} mm, strut temperature "
                            f"{prev[m.idx(f'T_surface[{k}]')] - 273.15:.1f} degC (surface), "
                            f"{prev[m.idx(f'T_oil[{k}]')] - 273.15:.1f} degC (oil)")
            raise SimulationError(
                f"the solution became non-finite at {s[col] / 1e3:.3f} km (t = {t[col]:.1f} s), first in {where} "
                f"({len(bad)} states non-finite){last}; {self._advice()}")
        deflections = m.strut_deflections(X)
        for i in range(m.n):
            stroke = m.struts[i].p.geometry.stroke
            xs = deflections[i]
            bad = (xs < -self.STROKE_MARGIN_M) | (xs > stroke + self.STROKE_MARGIN_M)
            if np.any(bad):
                col = int(np.argmax(bad))
                where = "bottomed out (beyond the bump stop)" if xs[col] > stroke else "over-extended (beyond the rebound stop)"
                raise SimulationError(
                    f"strut {m.station_names[i]} {where} at {s[col] / 1e3:.3f} km (t = {t[col]:.1f} s): deflection "
                    f"{xs[col] * 1e3:.1f} mm, stroke 0-{stroke * 1e3:.0f} mm, strut temperature "
                    f"{X[m.idx(f'T_oil[{i}]'), col] - 273.15:.1f} degC (oil); {self._advice()}")
        T = X[np.concatenate([self.node_index[node] for node in thermal.NODES])]
        lo, hi = self.PHYSICAL_TEMPERATURE_K
        bad = (T < lo) | (T > hi)
        if np.any(bad):
            k, col = (int(v[0]) for v in np.nonzero(bad))
            i, node = k % m.n, thermal.NODES[k // m.n]
            raise SimulationError(
                f"strut {m.station_names[i]} {node} temperature {T[i, col] - 273.15:.1f} degC at {s[col] / 1e3:.3f} km "
                f"(t = {t[col]:.1f} s) is outside any physical range ({lo - 273.15:.0f} to {hi - 273.15:.0f} degC): "
                f"the heat balance has failed; {self._advice()}")

    def _block_outputs(self, X, U, t, s, memory) -> dict:
        m = self.model
        n = X.shape[1]
        if self.compiled_outputs is not None and n == self.M:
            Y, acc, heights = self.compiled_outputs(X, np.broadcast_to(memory, (m.n_memory, n)), U, self.p)
        else:
            Y, acc, heights = self.outputs.map(n)(X, np.broadcast_to(memory, (m.n_memory, n)), U,
                                                  np.repeat(self.p[:, None], n, axis=1))
        outs = m.split_outputs(np.asarray(Y))
        block = {"t_s": t, "distance_m": s, "speed_m_per_s": U[m.input_index["speed"]],
                 "longitudinal_acceleration_m_per_s2": U[m.input_index["acceleration"]],
                 "strut_temperature_K": X[self.T_index],
                 "wall_temperature_K": X[self.T_wall_index],
                 "oil_temperature_K": X[self.T_oil_index],
                 "axle_height_change_m": np.asarray(heights),
                 "hull_acceleration": np.asarray(acc),
                 "heave_m": X[m.idx("z")], "pitch_rad": X[m.idx("theta")], "roll_rad": X[m.idx("phi")],
                 "oil_added_m3": np.array([X[m.idx(f"V_oil[{i}]")] for i in range(m.n)])}
        for k in ("strut_force", "strut_deflection", "gas_pressure", "gas_temperature", "wheel_load"):
            block[k] = outs[k]
        for e in ENERGY_TERMS:
            block[f"energy_{e}_J"] = X[m.energy_index[e]]
        return block

    def _stats_intervals(self, st: DriveState, X, t, s, final: bool = False) -> list[tuple]:
        """Every statistics interval ended in this block, as the arguments of `_stats_row` (distance at the end,
        duration, quadrature differences, state at the end, interval mean gas temperature); the last partial
        one at the drive's end if `close_last_interval`. Advances st.next_stats_m and st.last_stats."""
        rows = []
        q = X[self.quad_index]
        T = X
        t_last, q_last = st.last_stats["t_s"], st.last_stats["q"]
        s0, t0, q0, T0 = st.s_m, st.t_s, st.x[self.quad_index], st.x
        # the gas temperature swings by kelvins with every bump: its interval mean over the output samples
        Tg = X[self.T_gas_index]
        g_sum = np.broadcast_to(np.asarray(st.last_stats.get("gas_sum", 0.0), float), (self.model.n,)).copy()
        g_n = int(st.last_stats.get("gas_n", 0))
        for j in range(len(t)):
            g_sum += Tg[:, j]
            g_n += 1
            while s[j] >= st.next_stats_m - 1e-9:
                # the quadratures are smooth and monotone: interpolate them to the boundary
                a = (st.next_stats_m - s0) / (s[j] - s0) if s[j] > s0 else 1.0
                tb, qb, Tb = t0 + a * (t[j] - t0), q0 + a * (q[:, j] - q0), T0 + a * (T[:, j] - T0)
                rows.append((st.next_stats_m, tb - t_last, qb - q_last, Tb, g_sum / g_n if g_n else Tg[:, j]))
                t_last, q_last = tb, qb
                g_sum, g_n = np.zeros(self.model.n), 0
                st.next_stats_m += self.settings.stats_interval_m
            s0, t0, q0, T0 = s[j], t[j], q[:, j], T[:, j]
        last = final or (t[-1] + self.K * self.settings.dt_s > self.total_time_s + 1e-9 and not self._tail_steps())
        if self.close_last_interval and last and t[-1] > t_last + 1e-9:
            rows.append((s[-1], t[-1] - t_last, q[:, -1] - q_last, T[:, -1], g_sum / g_n if g_n else Tg[:, -1]))
            t_last, q_last = t[-1], q[:, -1]
            g_sum, g_n = np.zeros(self.model.n), 0
        st.last_stats = {"t_s": t_last, "q": q_last, "gas_sum": g_sum, "gas_n": g_n}
        return rows

    def _stats_row(self, s_end, duration, dq, x_end, gas_mean=None) -> dict:
        """One statistics row; x_end: the state at the interval's end (its temperatures are reported);
        gas_mean: the interval mean of the gas temperature (default its value at the end)."""
        n = self.model.n
        nE = len(ENERGY_TERMS)
        E = dq[: nE * n].reshape(nE, n)
        row = {"distance_end_m": float(s_end), "duration_s": float(duration),
               "strut_temperature_K": x_end[self.T_index].copy(),
               "wall_temperature_K": x_end[self.T_wall_index].copy(),
               "oil_temperature_K": x_end[self.T_oil_index].copy(),
               "mean_gas_temperature_K": np.array(x_end[self.T_gas_index] if gas_mean is None else gas_mean,
                                                  float)}
        for k, e in enumerate(ENERGY_TERMS):
            if e in DISSIPATION_TERMS:
                row[f"power_{e}_W"] = E[k] / max(duration, 1e-12)
        row["rms_strut_velocity_m_per_s"] = np.sqrt(np.maximum(dq[nE * n: nE * n + n], 0) / max(duration, 1e-12))
        row["rms_hull_acceleration"] = np.sqrt(np.maximum(dq[nE * n + n: nE * n + n + len(HULL_ACCELERATIONS)], 0)
                                               / max(duration, 1e-12))
        if self.ride_slots:
            row.update(self._ride_row(duration, dq, E[ENERGY_TERMS.index("end_stop")]))
        return row

    def _ride_row(self, duration, dq, end_stop_energy_J) -> dict:
        """Ride and road-holding statistics of an interval from the differences of the ride quadratures
        (vehicle.physics.ride; the keys vehicle.runs.ride_metrics reads)."""
        Q = {q: dq[k] for q, k in self.ride_slots.items()}
        T = max(duration, 1e-12)
        row = {}
        if len(self.model.seat_names):
            row["weighted_rms_acceleration_m_s2"] = ride.weighted_rms(Q["aw2"], T)
            row["weighted_rms_lateral_acceleration_m_s2"] = ride.weighted_rms(Q["awl2"], T)
            row["vdv_m_s175"] = ride.vibration_dose_value(Q["aw4"])
            row["absorbed_power_W"] = np.maximum(Q["pabs"], 0.0) / T
        row["dynamic_load_coefficient"] = ride.dynamic_load_coefficient(Q["F"], Q["F2"], T)
        row["lift_off_share"] = np.clip(Q["lift"] / T, 0.0, 1.0)
        row["end_stop_time_s"] = np.maximum(Q["stop"], 0.0)
        row["end_stop_energy_J"] = np.asarray(end_stop_energy_J, float).copy()
        hist = ride.travel_histogram(Q["above"], duration)
        row["strut_travel_min_m"], row["strut_travel_max_m"] = ride.travel_range(hist, self.travel_bin_edges_m)
        row["strut_travel_histogram_s"] = hist
        return row


@dataclass
class DriveResult:
    state: DriveState
    after: object
    wall_s: float
    integration_s: float
    solver_error: dict | None = None         # the step-doubling estimate's summary entries (None: not estimated)
