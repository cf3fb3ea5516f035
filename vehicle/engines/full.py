"""A drive: the vehicle DAE over a road with a speed profile, fast, in bounded memory.

`Drive` ties a `VehicleModel` to a road (terrain.Road, enveloped by each axle's tyre contact
length), a speed profile (`vehicle.scenario.speed.SpeedProfile`: constant, table, recorded or
generated), ambient and initial temperatures and levelling on/off. It integrates with the compiled
ROS2 stepper in blocks; each block's inputs (road under each tyre at its own distance behind axle 1
on its axle's pass surface, speed, ambient, the profile's longitudinal acceleration) are sampled just
in time, so memory does not grow with distance. After every block it hands decimated time series,
finished per-km statistics and a checkpoint to a sink (an HDF5 writer, or nothing), so a long
run that fails or is interrupted keeps what it did and can resume.
"""
from __future__ import annotations

import time
from dataclasses import fields
from typing import Callable

import numpy as np

from hpsim.cancellation import NEVER, CancelToken

from vehicle.physics.model import VehicleModel
from vehicle.numerics.error_estimate import StepDoublingEstimate, check_spacing_s, window_steps
from vehicle.numerics.solvers import Ros2
from vehicle.scenario.settings import DriveSettings
from vehicle.scenario.work_limits import samples_per_call
from vehicle.engines.binding import bind_solver
from vehicle.engines.contract import BlockObserver, DriveResult, DriveSink, DriveState
from vehicle.engines.recorder import BlockRecorder
from vehicle.engines.state_index import StateIndex
from vehicle.engines.vehicle_on_road import VehicleOnRoad


class Drive:
    """A drive of `model` over `road` with `settings`, integrated by `solver` (default: the compiled
    ROS2 at settings.dt_s); `run(sink)` hands samples, statistics and checkpoints to a sink. The full-resolution
    engine (vehicle.engines.contract.Engine)."""

    mode = "full"

    # the drive ends at its distance: after the last whole output interval, a partial one (the steps left, one
    # sample at the end); False: at the last whole interval (the multiscale and time-parallel engines)
    partial_last_sample = True

    def __init__(self, model: VehicleModel, road, settings: DriveSettings, *, gas_masses=None, solver=None,
                 partial_last_sample: bool | None = None):
        if partial_last_sample is not None:
            self.partial_last_sample = partial_last_sample
        if solver is not None:
            settings.dt_s = solver.dt
        settings.validate()
        self.model = model
        self.settings = settings
        t0 = time.perf_counter()
        # the parts: the vehicle on its road (envelopes, charge, inputs, distance map), then the solver bound to
        # its block shape, then the recorder of the blocks it integrates
        self.vehicle = VehicleOnRoad(model, road, settings, gas_masses)
        self.station_roads, self.road = self.vehicle.station_roads, self.vehicle.station_roads[0]
        self.gas_masses, self.equilibrium_solver = self.vehicle.gas_masses, self.vehicle.equilibrium_solver
        self.p, self.s_grid, self.t_grid = self.vehicle.p, self.vehicle.s_grid, self.vehicle.t_grid
        self.total_time_s = self.vehicle.total_time_s
        self.K = int(round(settings.output_interval_s / settings.dt_s))
        self.M = samples_per_call(self.K, settings.samples_per_block)   # a long interval: fewer samples per call
        self.end = self.vehicle.end(self.K)
        solver = solver or Ros2(settings.dt_s)
        # the block outputs in one compiled call per block (the samples of a full block); the baseline engine of
        # the benchmarks (capabilities.compiled_outputs False) and an uncompiled solver keep CasADi's virtual machine
        caps = self._caps = solver.capabilities
        estimate = settings.error_check_every > 0 and caps.step_doubling
        # the step-doubling window: ERROR_WINDOW_S of drive whatever the output interval (an estimate of the step's
        # error must not depend on how often results are stored)
        self.error_steps = window_steps(settings.dt_s)
        graphs = []
        if caps.compiled:             # the probes' libraries, compiled with the block function when missing
            if estimate:
                graphs.append(solver.refined_solver(2).block_graph(model, 2 * self.error_steps, 1))
                if self._coarse_sample() is None:
                    graphs.append(solver.refined_solver(1).block_graph(model, self.error_steps, 1))
            if self.partial_last_sample and self.end.tail_steps:
                graphs.append(solver.refined_solver(1).block_graph(model, 1, 1))
        bound = bind_solver(solver, model, self.K, self.M, graphs=graphs)
        self.solver, self.compiled_outputs = bound.solver, bound.outputs
        self.recorder = BlockRecorder(self.vehicle, settings.distance_m, self.M, self.compiled_outputs)
        # the drive's end closes the statistics interval it cuts (a partial row); a piece of a drive that another
        # continues (vehicle.engines.time_parallel) leaves it open
        self.close_last_interval = True
        self.build_s = time.perf_counter() - t0
        # where each quantity sits in the state vector (vehicle.engines.state_index), as attributes of the drive
        self.index = self.vehicle.index
        for f in fields(StateIndex):
            setattr(self, f.name, getattr(self.index, f.name))
        self.travel_bin_edges_m = self.recorder.travel_bin_edges_m
        self.error_estimate = None
        self._probes = {}
        if estimate:
            self.error_estimate = StepDoublingEstimate(settings.dt_s, settings.tolerance, settings.output_interval_s,
                                                       model.n, names=[str(s) for s in model.station_names])
            t0 = time.perf_counter()
            self._probe(2)                   # compiled (or fetched) now: part of the set-up, not of the run
            self.build_s += time.perf_counter() - t0

    # --- the parts' services, as the engine contract and the engines built on this drive read them ----------
    @property
    def outputs(self):
        return self.recorder.outputs

    def initial_equilibrium(self):
        return self.vehicle.initial_equilibrium()

    def initial_state(self) -> DriveState:
        return self.vehicle.initial_state(np.zeros_like(self.solver.get_state()))

    def distance_at(self, t):
        return self.vehicle.distance_at(t)

    def inputs(self, t: np.ndarray) -> np.ndarray:
        return self.vehicle.inputs(t)

    def stats_row(self, s_end, duration, dq, x_end, gas_mean=None) -> dict:
        return self.recorder.stats_row(s_end, duration, dq, x_end, gas_mean)

    def final_values(self, state: DriveState) -> dict:
        return self.recorder.final_values(state)

    def describe(self):
        """(one block of samples, one statistics row, one state dict) with the keys and shapes the drive
        will hand to a sink, so a sink can lay out its storage before the drive starts."""
        st = self.initial_state()
        t = np.array([0.0])
        block = self.recorder.block_outputs(st.x[:, None], self.inputs(t), t, t, st.solver_memory[:, None])
        row = self.stats_row(self.settings.stats_interval_m, 1.0, np.zeros(len(self.quad_index)), st.x)
        return block, row, st.as_dict()

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
            checkpoint_every_blocks: int = 6, observer: "BlockObserver | None" = None,
            cancel: CancelToken = NEVER) -> "DriveResult":
        """Drive from `state` (None: the start) to `self.end`, block by block, then the partial last interval
        (`_tail`). Stops early, returning normally with what it has, once `cancel` is requested (checked after
        each checkpointed block)."""
        m, S = self.model, self.settings
        st = self.initial_state() if state is None else state
        self.solver.set_state(st.solver_memory)
        dt = S.dt_s
        wall0 = time.perf_counter()
        integ_s = 0.0
        blocks = 0
        # error windows every error_check_every blocks of at least check_spacing_s (the first block is left out)
        spacing = check_spacing_s(self.K * self.M * dt)
        next_check = st.t_s + spacing
        left, tail = self.end.steps_left(st.t_s)          # whole samples, then the partial last interval's steps
        tail = tail if self._tail_steps() else 0
        while left > 0:
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
            self.recorder.check(X, t_samples, s_samples, st.x)
            take = min(self.M, left)                       # only samples within the drive
            X, t_samples, s_samples, memory = X[:, :take], t_samples[:take], s_samples[:take], memory[:, :take]
            left -= take
            U_samples = U[:, self.K * np.arange(1, take + 1)]
            blocks += 1
            checkpoint = blocks % checkpoint_every_blocks == 0 or left == 0
            st = self._record(st, X, U_samples, t_samples, s_samples, memory, sink, observer, progress,
                              ends=left == 0 and not tail, checkpoint=checkpoint)
            if checkpoint and cancel.requested:
                # stopped: the block's state only, no after-drive equilibrium (the drive is resumed from here)
                return DriveResult(state=st, after=None, wall_s=time.perf_counter() - wall0, integration_s=integ_s)
        else:
            if tail:
                ti = time.perf_counter()
                st = self._tail(st, tail, sink, observer, progress)
                integ_s += time.perf_counter() - ti
        wall = time.perf_counter() - wall0
        final_T = st.x[self.T_oil_index]
        V_oil = np.array([st.x[m.idx(f"V_oil[{i}]")] for i in range(m.n)])
        after = self.equilibrium_solver.solve(final_T, self.gas_masses, V_oil)
        error = None if self.error_estimate is None else self.error_estimate.summary(integ_s)
        return DriveResult(state=st, after=after, wall_s=wall, integration_s=integ_s, solver_error=error)

    def _record(self, st: DriveState, X, U, t, s, memory, sink, observer, progress, *, ends: bool,
                checkpoint: bool) -> DriveState:
        """`BlockRecorder.record`, the last interval closed at the drive's end unless this drive is a piece of one
        that another continues (`close_last_interval` False)."""
        return self.recorder.record(st, X, U, t, s, memory, sink, observer, progress,
                                    ends=ends and self.close_last_interval, checkpoint=checkpoint or ends)

    def _tail_steps(self) -> int:
        """Steps of the partial last output interval after the last whole sample (`DriveEnd.tail_steps`; 0 when
        the engine keeps whole intervals)."""
        if not self.partial_last_sample or not self._caps.step_doubling:    # the one-step solver is a refined one
            return 0
        return self.end.tail_steps

    def _tail(self, st: "DriveState", n: int, sink, observer, progress) -> "DriveState":
        """The partial last output interval: its n steps one by one (a one-step compiled function), one sample at
        the drive's end, recorded as a block that ends the drive."""
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
        self.recorder.check(X, t_samples, s_samples, st.x)
        return self._record(st, X, U[:, -1:], t_samples, s_samples, memory, sink, observer, progress, ends=True,
                            checkpoint=True)

    def summary_extra(self) -> dict:
        """The full drive adds nothing to /summary beyond the step-doubling estimate of its result."""
        return {}
