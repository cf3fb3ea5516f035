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
from functools import cached_property
from typing import Callable

import numpy as np

from hpsim.cancellation import NEVER, CancelToken
from hpsim.errors import SimulationError

from vehicle.physics import thermal
from vehicle.physics.equilibrium import charge_gas_masses, equilibrium_solver
from vehicle.physics import ride
from vehicle.physics.model import DISSIPATION_TERMS, ENERGY_TERMS, HULL_ACCELERATIONS, VehicleModel
from vehicle.numerics.error_estimate import StepDoublingEstimate, check_spacing_s, window_steps
from vehicle.numerics.codegen import precompile
from vehicle.numerics.solvers import Ros2, compiled_outputs, outputs_graph
from vehicle.scenario.settings import DriveSettings
from vehicle.scenario.work_limits import samples_per_call
from vehicle.engines.contract import BlockObserver, DriveResult, DriveSink, DriveState
from vehicle.engines.drive_end import DriveEnd
from vehicle.engines.state_index import StateIndex


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
        # the road each station reads: enveloped by its axle's tyre (one envelope per distinct contact length)
        envelopes: dict = {}
        self.station_roads = []
        for i in range(model.n):
            L = float(model.tyre[i].contact_length)
            if L not in envelopes:
                envelopes[L] = road.enveloped(L) if L > 0 else road
            self.station_roads.append(envelopes[L])
        for surface in {id(r): r for r in self.station_roads}.values():    # the splines of what the tyres read
            surface.prepare(sorted({model.params.station_axle(i) for i in range(model.n)
                                    if self.station_roads[i] is surface}))
        self.road = self.station_roads[0]
        t0 = time.perf_counter()
        self.gas_masses = charge_gas_masses(model) if gas_masses is None else np.asarray(gas_masses, float)
        self.equilibrium_solver = equilibrium_solver(model)
        self.p = model.run_parameters(self.gas_masses, settings.compensation)
        self.K = int(round(settings.output_interval_s / settings.dt_s))
        self.M = samples_per_call(self.K, settings.samples_per_block)   # a long interval: fewer samples per call
        solver = solver or Ros2(settings.dt_s)
        # the block outputs in one compiled call per block (the samples of a full block); the baseline engine of
        # the benchmarks (capabilities.compiled_outputs False) and an uncompiled solver keep CasADi's virtual machine
        caps = self._caps = solver.capabilities
        outputs_compiled = caps.compiled_outputs
        self.s_grid, self.t_grid = settings.speed.time_grid(settings.distance_m + 1.0)
        self.total_time_s = float(np.interp(settings.distance_m, self.s_grid, self.t_grid))
        self.end = DriveEnd.of(settings.distance_m, self.total_time_s, settings.dt_s, self.K)
        estimate = settings.error_check_every > 0 and caps.step_doubling
        # the step-doubling window: ERROR_WINDOW_S of drive whatever the output interval (an estimate of the step's
        # error must not depend on how often results are stored)
        self.error_steps = window_steps(settings.dt_s)
        if caps.compiled:
            # the libraries this drive needs, compiled together (one compiler each) when not in the cache yet
            graphs = [solver.block_graph(model, self.K, self.M)]
            if estimate:
                graphs.append(solver.refined_solver(2).block_graph(model, 2 * self.error_steps, 1))
                if self._coarse_sample() is None:
                    graphs.append(solver.refined_solver(1).block_graph(model, self.error_steps, 1))
            if self.partial_last_sample and self.end.tail_steps:
                graphs.append(solver.refined_solver(1).block_graph(model, 1, 1))
            if outputs_compiled:
                graphs.append(outputs_graph(model, self.M))
            precompile([g for g in graphs + self._libraries(model) if g is not None])
        self.solver = solver.bind(model, self.K, self.M)
        self.compiled_outputs = compiled_outputs(model, self.M) if outputs_compiled else None
        # the drive's end closes the statistics interval it cuts (a partial row); a piece of a drive that another
        # continues (vehicle.engines.time_parallel) leaves it open
        self.close_last_interval = True
        self.build_s = time.perf_counter() - t0
        # where each quantity sits in the state vector (vehicle.engines.state_index), as attributes of the drive
        self.index = StateIndex.of(model)
        for f in fields(StateIndex):
            setattr(self, f.name, getattr(self.index, f.name))
        self.travel_bin_edges_m = model.travel_bin_edges()
        self.error_estimate = None
        self._probes = {}
        if estimate:
            self.error_estimate = StepDoublingEstimate(settings.dt_s, settings.tolerance, settings.output_interval_s,
                                                       model.n, names=[str(s) for s in model.station_names])
            t0 = time.perf_counter()
            self._probe(2)                   # compiled (or fetched) now: part of the set-up, not of the run
            self.build_s += time.perf_counter() - t0

    def _libraries(self, model) -> list:
        """Libraries an engine built on this drive needs besides the solver's and the block outputs' (as
        `codegen.Library`, compiled together with those when the cache misses them)."""
        return []

    @cached_property
    def outputs(self):
        """The model's outputs y(x, memory, u, p) in CasADi's virtual machine (`VehicleModel.output_function_ode`):
        for blocks the compiled block outputs do not serve. Built on first use: a drive whose libraries are in the
        compile cache builds no graph it does not evaluate."""
        return self.model.output_function_ode()

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
    def _strokes_m(self) -> np.ndarray:
        """Each station's strut stroke [m] as a column (n, 1) (`_check`)."""
        return np.array([st.p.geometry.stroke for st in self.model.struts])[:, None]

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
            self._check(X, t_samples, s_samples, st.x)
            take = min(self.M, left)                       # only samples within the drive
            X, t_samples, s_samples, memory = X[:, :take], t_samples[:take], s_samples[:take], memory[:, :take]
            left -= take
            U_samples = U[:, self.K * np.arange(1, take + 1)]
            blocks += 1
            checkpoint = blocks % checkpoint_every_blocks == 0 or left == 0
            st = self._record(st, X, U_samples, t_samples, s_samples, memory, sink, observer, progress,
                              ends=left == 0 and not tail, checkpoint=checkpoint)
            if checkpoint and cancel.requested:
                break
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
        """One block's samples checked elsewhere, recorded here: its outputs and the statistics intervals it ends
        (the last closed at the drive's distance when the block `ends` the drive) to the observer and the sink,
        a checkpoint (every few blocks and at the end), progress. Returns the drive state after the block."""
        block = self._block_outputs(X, U, t, s, memory)
        intervals = self._stats_intervals(st, X, t, s, ends=ends)
        if observer is not None:
            observer.block(X, U, memory, block)
            observer.intervals(intervals)
        st = DriveState(t_s=float(t[-1]), s_m=float(s[-1]), x=X[:, -1].copy(), next_stats_m=st.next_stats_m,
                        last_stats=st.last_stats, sample_index=st.sample_index + X.shape[1],
                        solver_memory=memory[:, -1].copy())
        if sink is not None:
            sink.samples(block)
            rows = [self._stats_row(*interval) for interval in intervals]
            if rows:
                sink.stats(rows)
            if checkpoint or ends:
                sink.checkpoint(st.as_dict())
        if progress is not None:
            progress(st.s_m, float(self.settings.speed.speed(st.s_m)), st.t_s)
        return st

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
        self._check(X, t_samples, s_samples, st.x)
        return self._record(st, X, U[:, -1:], t_samples, s_samples, memory, sink, observer, progress, ends=True,
                            checkpoint=True)

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
        strokes = self._strokes_m
        outside = (deflections < -self.STROKE_MARGIN_M) | (deflections > strokes + self.STROKE_MARGIN_M)
        if np.any(outside):                  # the first station out of its stroke, at its first such sample
            i = int(np.argmax(np.any(outside, axis=1)))
            stroke, xs, col = float(strokes[i, 0]), deflections[i], int(np.argmax(outside[i]))
            where = "bottomed out (beyond the bump stop)" if xs[col] > stroke else "over-extended (beyond the rebound stop)"
            raise SimulationError(
                f"strut {m.station_names[i]} {where} at {s[col] / 1e3:.3f} km (t = {t[col]:.1f} s): deflection "
                f"{xs[col] * 1e3:.1f} mm, stroke 0-{stroke * 1e3:.0f} mm, strut temperature "
                f"{X[m.idx(f'T_oil[{i}]'), col] - 273.15:.1f} degC (oil); {self._advice()}")
        T = X[self.heat_nodes_index]
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
        """Every time series of the output table (vehicle.physics.outputs) at a block's samples."""
        m = self.model
        n = X.shape[1]
        if self.compiled_outputs is not None and n <= self.M:
            # fewer samples than a block (the first, a window's or the drive's last): the compiled block outputs on
            # the samples padded with copies of the last (each column is evaluated on its own), the padding dropped
            pad = np.full(self.M, n - 1)
            pad[:n] = np.arange(n)
            Y, acc, heights = (np.asarray(v)[:, :n] for v in self.compiled_outputs(
                X[:, pad], np.broadcast_to(memory, (m.n_memory, n))[:, pad], U[:, pad], self.p))
        else:
            Y, acc, heights = self.outputs.map(n)(X, np.broadcast_to(memory, (m.n_memory, n)), U,
                                                  np.repeat(self.p[:, None], n, axis=1))
        outs = m.split_outputs(np.asarray(Y))
        block = {}
        for key, f in self.series.items():
            rows = self.series_rows.get(key)
            if rows is not None:
                block[key] = X[rows]
            elif f.kind == "time":
                block[key] = t
            elif f.kind == "distance":
                block[key] = s
            elif f.kind == "input":
                block[key] = U[m.input_index[f.name]]
            elif f.kind == "output":
                block[key] = outs[f.name]
            elif f.kind == "axle_heights":
                block[key] = np.asarray(heights)
            elif f.kind == "hull_accelerations":
                block[key] = np.asarray(acc)
            else:
                raise ValueError(f"output table: {key!r} has an unknown series kind {f.kind!r}")
        return block

    def _stats_intervals(self, st: DriveState, X, t, s, ends: bool = False) -> list[tuple]:
        """Every statistics interval ended in this block, as the arguments of `_stats_row` (distance at the end,
        duration, quadrature differences, state at the end, interval mean gas temperature). A block that `ends`
        the drive closes its last interval at the drive's distance (if `close_last_interval`): interpolated to it
        when the end sample passes a boundary there, else at the end sample (within half a step of it). No
        boundary beyond the drive's distance is cut. Advances st.next_stats_m and st.last_stats."""
        rows = []
        q = X[self.quad_index]
        T = X
        end_m = self.end.distance_m
        t_last, q_last = st.last_stats["t_s"], st.last_stats["q"]
        s0, t0, q0, T0 = st.s_m, st.t_s, st.x[self.quad_index], st.x
        # the gas temperature swings by kelvins with every bump: its interval mean over the output samples
        Tg = X[self.T_gas_index]
        g_sum = np.broadcast_to(np.asarray(st.last_stats.get("gas_sum", 0.0), float), (self.model.n,)).copy()
        g_n = int(st.last_stats.get("gas_n", 0))
        closed_at_end = False
        for j in range(len(t)):
            g_sum += Tg[:, j]
            g_n += 1
            while s[j] >= st.next_stats_m - 1e-9 and st.next_stats_m <= end_m:
                # the quadratures are smooth and monotone: interpolate them to the boundary
                a = (st.next_stats_m - s0) / (s[j] - s0) if s[j] > s0 else 1.0
                tb, qb, Tb = t0 + a * (t[j] - t0), q0 + a * (q[:, j] - q0), T0 + a * (T[:, j] - T0)
                rows.append((st.next_stats_m, tb - t_last, qb - q_last, Tb, g_sum / g_n if g_n else Tg[:, j]))
                closed_at_end = st.next_stats_m == end_m
                t_last, q_last = tb, qb
                g_sum, g_n = np.zeros(self.model.n), 0
                st.next_stats_m += self.settings.stats_interval_m
            s0, t0, q0, T0 = s[j], t[j], q[:, j], T[:, j]
        if ends and self.close_last_interval and not closed_at_end and t[-1] > t_last:
            rows.append((end_m, t[-1] - t_last, q[:, -1] - q_last, T[:, -1], g_sum / g_n if g_n else Tg[:, -1]))
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
        (vehicle.physics.ride; the keys vehicle.analysis.ride_metrics reads)."""
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

    def final_values(self, state: DriveState) -> dict:
        """The drive's end as stored in /summary: energies since the start, the heat network's temperatures and
        (with ride metrics) the whole drive's ride numbers from the quadratures since the start."""
        m = self.model
        x = state.x
        values = {f"energy_{e}_J": np.asarray(x[idx], float) for e, idx in m.energy_index.items()}
        values["strut_temperature_K"] = np.asarray(x[self.T_index], float)          # the surface (pyrometer)
        values["wall_temperature_K"] = np.asarray(x[self.T_wall_index], float)
        values["oil_temperature_K"] = np.asarray(x[self.T_oil_index], float)
        if m.ride_metrics:
            values.update(self._ride_row(float(state.t_s), x[self.quad_index], x[m.energy_index["end_stop"]]))
            values["strut_travel_bin_edges_m"] = np.asarray(self.travel_bin_edges_m, float)
        return values

    def summary_extra(self) -> dict:
        """The full drive adds nothing to /summary beyond the step-doubling estimate of its result."""
        return {}
