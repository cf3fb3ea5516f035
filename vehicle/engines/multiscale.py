"""Multiscale drive: the ride simulated on windows of the real road, the slow (thermal, levelling) states
advanced between them by the windows' averaged linear model, each stretch corrected by a road proxy known
for the whole road (control variate), with an a-posteriori estimate of the sampling error. How and why,
with the measurements behind each choice: docs/engines.md, "Multiscale mode"."""
from __future__ import annotations

import time
from dataclasses import fields
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np

from hpsim.cancellation import NEVER, CancelToken
from hpsim.errors import SimulationError, UserInputError
from hpsim.stages import timed
from hpsim.threads import InlineExecutor

from vehicle.physics.model import DISSIPATION_TERMS
from vehicle.scenario.settings import MultiscaleSettings
from vehicle.numerics.solvers import Ros2
from vehicle.scenario.work_limits import samples_per_call
from vehicle.engines.binding import bind_solver
from vehicle.engines.contract import DriveResult, DriveState
from vehicle.engines.recorder import BlockRecorder
from vehicle.engines.state_index import StateIndex
from vehicle.engines.vehicle_on_road import VehicleOnRoad
from vehicle.engines.control_variate import band_power_cumulative, on_grid, station_patterns
from vehicle.engines.linear_proxy import LinearProxy
from vehicle.engines.slow_manifold import SlowManifold
from vehicle.engines.window_pair import WindowPair
from vehicle.engines.slow_flow import (ERROR_COVERAGE, LinearFlow, error_factor, slow_rate_jacobian, slow_rate_library,
                                       total_variation_along, warm_up_correction)
from vehicle.engines.window_estimates import WindowEstimator, WindowRecord

MODE = "multiscale"


class MultiscaleDrive:
    """The ride integrated on windows of the road with the full model, the slow states carried between them
    (module docstring). Composed of the vehicle on its road, a block recorder for the windows' samples, the slow
    manifold and a solver (default: the compiled ROS2 at settings.dt_s)."""

    mode = MODE
    resumable = False                 # it takes seconds: an interrupted run starts again
    MIN_CV_WINDOWS = 5      # the control variate needs a few residual degrees of freedom (windows less 3)

    def __init__(self, model, road, settings, multiscale: MultiscaleSettings, *, gas_masses=None, solver=None):
        if solver is not None:
            settings.dt_s = solver.dt
        settings.validate()
        self.model, self.settings, self.ms = model, settings, multiscale
        self.state_only = False          # True: only the states are wanted (no error estimate), as for a coarse run
        t0 = time.perf_counter()
        self.vehicle = VehicleOnRoad(model, road, settings, gas_masses)
        v = self.vehicle
        self.station_roads, self.gas_masses = v.station_roads, v.gas_masses
        self.equilibrium_solver = v.equilibrium_solver
        self.p, self.s_grid, self.t_grid, self.total_time_s = v.p, v.s_grid, v.t_grid, v.total_time_s
        self.index = v.index
        for f in fields(StateIndex):
            setattr(self, f.name, getattr(self.index, f.name))
        self.K = int(round(settings.output_interval_s / settings.dt_s))
        self.M = samples_per_call(self.K, settings.samples_per_block)
        self.end = v.end(self.K)         # the windows end on whole samples, the slow states at `end.time_s`
        solver = solver or Ros2(settings.dt_s)
        # a solver bound to its thread (an ensemble lane) integrates every window there, one after the other, and
        # the proxy is set up there too: its graphs are built under the lanes' lock (vehicle.engines.ensemble)
        self.beside = not solver.capabilities.thread_bound
        self.paired = self.ms.paired_windows and self.beside
        bound = bind_solver(solver, model, self.K, self.M, libraries=[slow_rate_library(model)])
        self.solver = bound.solver
        self.recorder = BlockRecorder(v, settings.distance_m, self.M, bound.outputs)
        # the standing vehicle at the slow states, shared with whoever composes this drive (time_parallel)
        self.manifold = SlowManifold(model, self.equilibrium_solver, self.gas_masses, self.T_oil_index, self.s_grid,
                                     self.t_grid)
        self.slow_index, self.ext_index = self.manifold.slow_index, self.manifold.ext_index
        self.J_slow = slow_rate_jacobian(model, compiled=solver.capabilities.compiled)
        self._J_sums: dict = {}
        self.oil_index = self.manifold.oil_index
        self._oil_in_slow = np.searchsorted(self.slow_index, self.oil_index)     # V_oil among the slow states
        self.build_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        self._proxy_setup()
        self.estimator = WindowEstimator(self.slow_index, self.ext_index, self.slow_station, self.cv_basis,
                                         self.cv_quad, self.cv_quad_station, self.T_oil_index)
        # the linear-model proxy's first part starts now, beside what comes before the drive (`_start_proxy`)
        self._proxy_start = self._start_proxy() if self._linear_proxy_pending else None
        self.build_s += time.perf_counter() - t0
        self.estimate: dict | None = None
        self.window_log: list[WindowRecord] = []

    # --- the engine contract through the parts ---------------------------------------------------------
    def initial_equilibrium(self):
        return self.vehicle.initial_equilibrium()

    def initial_state(self) -> DriveState:
        return self.vehicle.initial_state(np.zeros_like(self.solver.get_state()))

    def distance_at(self, t):
        return self.vehicle.distance_at(t)

    def inputs(self, t: np.ndarray) -> np.ndarray:
        return self.vehicle.inputs(t)

    def final_values(self, state: DriveState) -> dict:
        return self.recorder.final_values(state)

    def describe(self):
        """The full drive's layout (`Drive.describe`), plus where each window's averages start."""
        st = self.initial_state()
        t = np.array([0.0])
        block = self.recorder.block_outputs(st.x[:, None], self.inputs(t), t, t, st.solver_memory[:, None])
        row = self.recorder.stats_row(self.settings.stats_interval_m, 1.0, np.zeros(len(self.quad_index)), st.x)
        row["window_start_m"] = 0.0
        return block, row, st.as_dict()

    # --- the road proxy of the control variate ------------------------------------------------------
    def _linear_proxy_inputs(self) -> tuple:
        """What `_linear_proxy_setup` needs from the drive's solvers (the initial strut temperatures and the vehicle
        standing at them, the same for every friction velocity), computed on the calling thread: the set-up itself
        may then run on another one."""
        T0 = self.initial_state().x[self.T_oil_index]
        return T0, self.equilibrium_solver.solve(T0, self.gas_masses)

    def _linear_proxy_setup(self, match=None, inputs=None):
        """The linear-model proxy (`LinearProxy`) set up at once, its friction velocity amplitude matched to
        match = (t_a, t_b, rms) or LINEAR_PROXY_FRICTION_VELOCITY_M_S (match=None). inputs: `_linear_proxy_inputs()`
        (computed here when None). A drive sets it up in three parts where a core idles (`_start_proxy`)."""
        proxy = LinearProxy(self, self._linear_proxy_inputs() if inputs is None else inputs)
        proxy.prepare()
        proxy.match(match)
        self._use_linear_proxy(proxy, proxy.finish())

    def _use_linear_proxy(self, proxy: LinearProxy, result: tuple) -> None:
        t, c, V = result
        self._proxy_t = (t, c)
        self.proxy_friction_velocity_m_s = V
        self.proxy_setup_s = proxy.setup_s

    def _proxy_setup(self):
        """Per station: the cumulative band-passed squared road rate of the road it reads (`band_power_cumulative`,
        once per distinct surface), or the linear model's squared strut velocity (`_linear_proxy_setup`), and which
        station each slow state and dissipated energy belongs to."""
        m = self.model
        names = m.layout.names
        self._proxy_c, cache = [], {}
        self._proxy_t = None
        t0 = time.perf_counter()
        n_windows = int(np.ceil(self.settings.distance_m / self.ms.spacing_m - 1e-9))
        # the linear-model proxy: started when the drive is built, matched to the first window's RMS strut velocity
        self._linear_proxy_pending = (self.ms.control_variate and self.ms.proxy == "linear_model"
                                      and n_windows >= self.MIN_CV_WINDOWS)
        if self._linear_proxy_pending:
            self._proxy_t = (np.zeros(2), np.zeros((m.n, 2)))
        # (no control variate: no proxy, `proxy` gives zeros; the time-parallel coarse run is one)
        for i in range(m.n if (self._proxy_t is None and self.ms.control_variate) else 0):
            road = self.station_roads[i]
            track, pas = ("left" if i % 2 == 0 else "right"), m.params.station_axle(i)
            z = road.heights(track, pas)
            key = (id(road), id(z))
            if key not in cache:
                d = road.distance_m
                cache[key] = (road.spacing_m, band_power_cumulative(road.knot_slopes(track, pas), road.spacing_m,
                                                                    self.settings.speed.speed(d),
                                                                    self.ms.PROXY_BAND_HZ))
            self._proxy_c.append(cache[key])

        def station(j):
            nm = names[j]
            return int(nm[nm.index("[") + 1:-1]) if "[" in nm else -1
        self.slow_station = np.array([station(j) for j in self.slow_index])
        self.cv_basis = self._pattern_basis(names)
        self.cv_quad = np.array([j for j in self.ext_index
                                 if names[j].split("[")[0] in [f"E_{e}" for e in DISSIPATION_TERMS] + ["I_v2"]], int)
        self.cv_quad_station = np.array([station(j) for j in self.cv_quad], int)
        self.proxy_setup_s = time.perf_counter() - t0

    def _pattern_basis(self, names) -> np.ndarray:
        """The orthonormal change of basis of the slow states in which the control variate regresses
        (`_control_variate`): each kind of per-station slow state (T_oil[0..n-1], ...) by the station patterns
        (`station_patterns`), the others as they are. The identity with CV_PATTERNS off."""
        ns = len(self.slow_index)
        T = np.eye(ns)
        if not self.ms.CV_PATTERNS:
            return T
        m = self.model
        P = station_patterns(np.asarray(m.a, float), np.arange(m.n) % 2)
        kinds: dict = {}
        for k, j in enumerate(self.slow_index):
            if self.slow_station[k] >= 0:
                kinds.setdefault(names[j].split("[")[0], {})[int(self.slow_station[k])] = k
        for slots in kinds.values():
            if len(slots) == m.n:
                idx = [slots[i] for i in range(m.n)]
                T[np.ix_(idx, idx)] = P
        return T

    def proxy(self, s0_m: float, s1_m: float) -> np.ndarray:
        """Mean of each station's road proxy over the drive from s0 to s1 (time mean; 0 for an empty stretch)."""
        dt = self.manifold.time_at(s1_m) - self.manifold.time_at(s0_m)
        if dt <= 0:
            return np.zeros(self.model.n)
        if self._proxy_t is not None:
            t0, t1 = self.manifold.time_at(s0_m), self.manifold.time_at(s1_m)
            return (self._cumulative_proxy_at(t1) - self._cumulative_proxy_at(t0)) / dt
        out = np.zeros(self.model.n)
        for i, (h, c) in enumerate(self._proxy_c):
            a = float(self.model.a[i])
            out[i] = (on_grid(c, h, s1_m - a) - on_grid(c, h, s0_m - a)) / dt
        return out

    def _cumulative_proxy_at(self, t: float) -> np.ndarray:
        """Each station's cumulative proxy C (`_proxy_t`) at time t [s], np.interp(t, grid, C_i), from the two grid
        points around t: the grid is the shared, read-only proxy road's (vehicle.engines.proxy_roads), and np.interp
        copies a read-only array whole on every call. The same bracket and arithmetic, so the same bits."""
        tg, c = self._proxy_t
        j = int(np.searchsorted(tg, t, side="right"))
        lo, hi = max(j - 1, 0), min(j + 1, tg.size)
        return np.array([np.interp(t, tg[lo:hi], ci[lo:hi]) for ci in c])

    # --- one window ------------------------------------------------------------------------------
    def integrate(self, solver, x0, t0, t_end, t_warm) -> dict:
        """The full model on `solver` from (x0, t0) to t_end (whole sample intervals): the blocks (states, sample
        times, the solver's memory and the inputs at the samples), the integration's wall time and the window's
        arrays up to the warm-up's end t_warm and after it (`_window_arrays`), computed here rather than on the
        drive's thread. Reads the model, the road and the settings only, so a window integrates on a thread beside
        another (`paired_windows`). Stops after a block with a non-finite state (`_window` reports it)."""
        S = self.settings
        dt, K, M = S.dt_s, self.K, self.M
        sample_dt = K * dt
        solver.set_state(np.zeros_like(solver.get_state()))
        n_samples = max(int(np.ceil((t_end - t0) / sample_dt - 1e-9)), 1)
        blocks, wall = [], 0.0
        x, t = x0, t0
        done = 0
        while done < n_samples:
            t_cols = t + dt * np.arange(K * M + 1)
            U = self.inputs(t_cols)
            ti = time.perf_counter()
            X = solver.advance(x, U, self.p)
            wall += time.perf_counter() - ti
            take = min(M, n_samples - done)
            t_s = t + sample_dt * np.arange(1, M + 1)
            blocks.append((X, t_s, solver.memory_samples, U[:, K * np.arange(1, take + 1)], take))
            if not np.all(np.isfinite(X)):
                break
            x, t = X[:, take - 1].copy(), float(t_s[take - 1])
            done += take
        run = {"x0": x0, "blocks": blocks, "integration_s": wall}
        run["arrays"] = self._window_arrays(t0, t_warm, t_end, run)
        return run

    def _window_times(self, c0: float, c1: float, t_total: float) -> tuple:
        """(start, warm-up end, end) [s] of the window from c0 to c1 [m]. A window integrates whole output samples
        from its start, which lies off the sample grid: its end is held to the last whole sample before t_total
        [s], so that no window integrates past the drive's end (the slow model carries the rest)."""
        t0 = self.manifold.time_at(c0)
        sample_dt = self.K * self.settings.dt_s
        within = max(np.floor((t_total - t0) / sample_dt + 1e-9), 1.0) * sample_dt
        t_end = min(self.manifold.time_at(c1), t0 + within)
        return t0, min(self.manifold.time_at(min(c0 + self.ms.warm_up_m, c1)), t_end), t_end

    def _window_arrays(self, t0, t_warm, t_end, run) -> dict:
        """The window's samples checked (`BlockRecorder.check`; its error kept, raised by `window_record`: a window integrated from a
        predicted start may be integrated again) and joined: states X, times T, solver memory MEM, inputs U, the
        first sample of the averaged stretch a, and J, the sum of the slow rates' Jacobian over that stretch."""
        sample_dt = self.K * self.settings.dt_s
        x0 = run["x0"]                   # where the window was integrated from (a predicted start, when paired)
        n_samples = max(int(np.ceil((t_end - t0) / sample_dt - 1e-9)), 1)
        n_warm = min(int(np.ceil((t_warm - t0) / sample_dt - 1e-9)), n_samples - 1)
        xs, ts, mems, Us = [x0[:, None]], [np.array([t0])], [np.zeros((self.model.n_memory, 1))], []
        samples = []
        x = x0
        try:
            for X, t_s, memory, U_s, take in run["blocks"]:
                s_s = self.distance_at(t_s)
                self.recorder.check(X, t_s, s_s, x)
                X, t_s, s_s, memory = X[:, :take], t_s[:take], s_s[:take], memory[:, :take]
                samples.append((X, U_s, t_s, s_s, memory))
                xs.append(X)
                ts.append(t_s)
                mems.append(memory)
                Us.append(U_s)
                x = X[:, -1]
        except SimulationError as exc:
            return {"error": exc}
        X = np.concatenate(xs, axis=1)
        MEM = np.concatenate(mems, axis=1)
        U = np.concatenate(Us, axis=1)
        a = n_warm                       # first sample of the averaged stretch (index into X, T)
        avg = slice(a + 1, None)         # samples inside the averaged stretch (U has no column for sample 0)
        N = X.shape[1] - a - 1
        # the sum over the samples inside CasADi (a map with a reduced output: one (ns, nx) matrix back, not N)
        J_sum = self._J_sums.get(N)
        if J_sum is None:
            J_sum = self._J_sums[N] = self.J_slow.map("J_slow_sum", "serial", N, [3], [0])
        J = np.asarray(J_sum(X[:, avg], MEM[:, avg], U[:, a:], self.p))
        T = np.concatenate(ts)
        # the totals' rates over the averaged stretch (the squared strut velocities' among them: `_match_proxy`)
        q_rate = (X[self.ext_index, -1] - X[self.ext_index, a]) / (T[-1] - T[a])
        return {"error": None, "samples": samples, "X": X, "T": T, "MEM": MEM, "a": a, "N": N, "J": J,
                "q_rate": q_rate}

    def window_record(self, run: dict) -> WindowRecord:
        """The record of the window `integrate` gave (run: from run["x0"], with its arrays): the averaged slow
        model, the end state, ..., with its samples for the sink (`_to_sink`)."""
        arrays = run["arrays"]
        if arrays["error"] is not None:
            raise arrays["error"]
        X, T, MEM, a, N, J = (arrays[k] for k in ("X", "T", "MEM", "a", "N", "J"))
        # d(slow rates)/d(all states), averaged, times how the state moves with the slow states (fast states
        # slaved to them: a gas temperature follows its strut's): A = mean(J) S
        A = (J / N) @ self.manifold.slaving(X[:, -1])
        dur = T[-1] - T[a]
        xa, xb = X[:, a], X[:, -1]
        r = (xb[self.slow_index] - xa[self.slow_index]) / dur
        xbar = 0.5 * (X[self.slow_index, a:-1] + X[self.slow_index, a + 1:]).mean(axis=1)  # trapezoid
        row = self.recorder.stats_row(float(self.distance_at(T[-1])), dur, xb[self.quad_index] - xa[self.quad_index],
                                      xb, X[self.T_gas_index, a + 1:].mean(axis=1))
        row["window_start_m"] = float(self.distance_at(T[a]))
        return WindowRecord(x_end=xb.copy(), x_avg0=xa.copy(), t_end=float(T[-1]), t_avg0=float(T[a]), A=A, r=r,
                            xbar=xbar, b=r - A @ xbar, q_rate=arrays["q_rate"], row=row, memory=MEM[:, -1].copy(),
                            samples=arrays["samples"], integration_s=run["integration_s"])

    def _to_sink(self, sink, records: list) -> None:
        """The processed windows' samples, statistics rows and checkpoints to the sink, in order (emptied). Called
        while the next windows integrate: the outputs are evaluated beside them."""
        while records:
            w = records.pop(0)
            blocks, w.samples = w.samples, []          # written: the samples are not kept
            for block in blocks:
                sink.samples(self.recorder.block_outputs(*block))
            sink.stats([w.row])
            st = DriveState(t_s=w.t_end, s_m=w.s_end, x=w.x_end, next_stats_m=self.settings.distance_m + 1.0,
                            last_stats={"t_s": w.t_end, "q": w.x_end[self.quad_index].copy(),
                                        "gas_sum": np.zeros(self.model.n), "gas_n": 0},
                            solver_memory=w.memory)
            sink.checkpoint(st.as_dict())

    def _predicted_start(self, x: np.ndarray, t_from: float, w_prev: dict, s_next_m: float) -> np.ndarray:
        """The vehicle at rest at the start of the window at s_next_m, predicted from the state x at t_from (the start
        of the window before it) by the averaged slow model of the window before that (`w_prev`): the slow states by
        its linear flow, the totals by its rates (`paired_windows`)."""
        tau = max(self.manifold.time_at(s_next_m) - t_from, 0.0)
        flow, xp = w_prev.flow, x.copy()
        xp[self.slow_index] = flow.phi(tau) @ x[self.slow_index] + flow.gamma(tau) @ w_prev.b
        xp[self.ext_index] = x[self.ext_index] + w_prev.q_rate * tau
        return self.manifold.rest_state(xp)

    def _start_proxy(self) -> tuple:
        """The linear-model proxy's first part (`LinearProxy.prepare`) started on a thread of its own when the drive
        is built: it runs beside the output file's set-up and the first window, on the core they leave idle.
        (the thread, the proxy)."""
        beside = (ThreadPoolExecutor(max_workers=1, thread_name_prefix="hpsim-proxy") if self.beside
                  else InlineExecutor())
        proxy = LinearProxy(self, self._linear_proxy_inputs())
        beside.submit(timed, "drive: the proxy's set-up", proxy.prepare)
        return beside, proxy

    def _match_proxy(self, beside: ThreadPoolExecutor, proxy: LinearProxy, arrays: dict) -> Future:
        """The proxy's friction velocity amplitude matched to the first window's RMS strut velocity over its
        averaged stretch (`LinearProxy.match`; `_window_arrays`), on the proxy's thread after its first part: started
        before the window's record is made (its slaving matrix takes a while), so that it runs beside that."""
        T, a = arrays["T"], arrays["a"]
        iv = np.searchsorted(self.ext_index, [self.model.idx(f"I_v2[{i}]") for i in range(self.model.n)])
        match = ((float(T[a]), float(T[-1]), float(np.sqrt(np.mean(arrays["q_rate"][iv]))))
                 if self.ms.LINEAR_PROXY_MATCH_RMS else None)
        return beside.submit(timed, "drive: the proxy's set-up", proxy.match, match)

    def _finish_proxy(self, beside: ThreadPoolExecutor, proxy: LinearProxy, matched: Future) -> Future:
        """The proxy over the whole road (`LinearProxy.finish`) started on the proxy's thread (after its match) when
        the drive's windows run one at a time: the last one, and the one before it when its predicted start was not
        kept (the windows before them run two at once). The drive uses it after its last window."""
        def after_match():
            matched.result()             # the match's error, if any, is this job's too
            return timed("drive: the proxy's set-up", proxy.finish)
        return beside.submit(after_match)

    def _drive_windows(self, sink, progress, t_total: float, pair: WindowPair, unwritten: list,
                       cancel: CancelToken = NEVER) -> tuple:
        """Every window in order, the slow states carried across the gaps between them: (the window records, the
        state at the drive's end); the linear-model proxy is set up beside them (`_start_proxy`). With
        `paired_windows` the window after each odd one integrates beside it from a predicted start
        (`_predicted_start`); its warm-up correction carries it to its true start. The processed windows wait in
        `unwritten` and go to the sink while the next ones integrate."""
        S = self.settings
        D = S.distance_m
        x = self.initial_state().x.copy()
        windows = self.ms.windows(D)
        records = []
        proxy_job = finished = None      # the proxy's match, then its whole-road pass (futures)
        proxy_start = self._proxy_start
        pending = None                   # the next window, integrating beside the current one
        k = -1
        while k + 1 < len(windows):
            k += 1
            c0, c1 = windows[k]
            t0, t_warm, t_end = self._window_times(c0, c1, t_total)
            if k > 0:
                x = self.manifold.rest_state(x)
            run = None
            if pending is not None:      # integrated beside the window before, from a predicted start
                run, pending = pending.result(), None
                if not self._close_enough(run["x0"], x):
                    run = None           # integrated again, from its true start
            predicted = run is not None
            if run is None:
                job = pair.submit(0, x, t0, t_warm, t_end)
                # the last window is integrated from its true start: it ends with the drive, whose short memories
                # (the oil against its wall, the gas) it simulates rather than samples
                if self.paired and records and k + 2 < len(windows):
                    nxt = self._window_times(*windows[k + 1], t_total)
                    pending = pair.submit(1, self._predicted_start(x, t0, records[-1], windows[k + 1][0]), *nxt)
                if sink is not None:
                    self._to_sink(sink, unwritten)        # while they integrate
                if proxy_job is not None and pending is None and k >= len(windows) - 2:
                    finished = self._finish_proxy(*proxy_start, proxy_job)
                    proxy_job = None
                run = job.result()
            if k == 0 and proxy_start is not None and run["arrays"]["error"] is None:
                proxy_job = self._match_proxy(*proxy_start, run["arrays"])
            w = self.window_record(run)
            w.flow = LinearFlow(w.A)
            w.predicted_start = predicted             # integrated from a predicted start (`paired_windows`)
            if k == 0 and self.ms.placement == "weighted":
                lam = np.linalg.eigvals(w.A).real
                lam = lam[lam < -1e-12]
                tau = -1.0 / np.max(lam) if len(lam) else t_total
                w.tau_slow_s = float(tau)
                windows = windows[:1] + self.ms.weighted_windows(D, windows[0][1], tau, self.manifold.time_at,
                                                                  self.distance_at, t_total)
            if k > 0:
                # the warm-up settles the start from rest (the tyres meet a road that is not flat): its extra
                # dissipation is not the road's. The slow states and totals cross it as they cross a gap, by the
                # window's averaged model; the averaged stretch adds its own change. The slow states' difference
                # at the warm-up's end (modelled - simulated) is carried through the averaged stretch by the same
                # model, e^{A L}: the simulated stretch started from the simulated state, and a difference in a
                # state with a short memory (the oil against its wall, ~2 min) has partly decayed by the window's
                # end (in a linear model exactly: x_end(x_a + d) = x_end(x_a) + e^{A L} d; docs/engines.md, "Warm-up").
                # A window integrated from a predicted start (paired) is carried to its true start, x, the same way
                x_start = x
                tw = w.t_avg0 - t0
                w.x_end[self.slow_index] += warm_up_correction(w.flow, w.b, x_start[self.slow_index],
                                                                  w.x_avg0[self.slow_index], tw,
                                                                  w.t_end - w.t_avg0)
                w.x_end[self.ext_index] += (x_start[self.ext_index] + w.q_rate * tw) - w.x_avg0[self.ext_index]
            # the gap: to the next window's start, or to the end of the drive
            t_next = self.manifold.time_at(windows[k + 1][0]) if k + 1 < len(windows) else self.end.time_s
            tau = max(t_next - w.t_end, 0.0)
            x = w.x_end.copy()
            Phi, forced = w.flow.phi(tau), w.flow.gamma(tau) @ w.b
            x[self.slow_index] = Phi @ x[self.slow_index] + forced
            x[self.ext_index] = x[self.ext_index] + w.q_rate * tau
            if S.compensation:           # the pump's oil follows the levelling oil's path, not the window's mean rate
                x[self.pump_index] = w.x_end[self.pump_index] + total_variation_along(
                    w.flow, w.x_end[self.slow_index], w.b, tau, self._oil_in_slow)
            w.t_start, w.t_gap_end, w.tau, w.s_start = t0, t_next, tau, c0
            w.s_end, w.s_gap_end = float(self.distance_at(w.t_end)), float(self.distance_at(t_next))
            w.s_avg0 = float(self.distance_at(w.t_avg0))
            w.tw = (w.t_avg0 - t0) if k > 0 else 0.0
            records.append(w)
            unwritten.append(w)
            if progress is not None:
                progress(float(self.distance_at(t_next)), float(S.speed.speed(self.distance_at(t_next))), t_next)
            if cancel.requested:
                if pending is not None:
                    pending.cancel()
                return records, None
        if proxy_job is not None:        # the proxy was matched after the last window (a drive of one window)
            finished = self._finish_proxy(*proxy_start, proxy_job)
        if finished is not None:
            self._use_linear_proxy(proxy_start[1], finished.result())
        return records, x

    def _drive_windows_to(self, sink, progress, t_total: float, pair: WindowPair,
                          cancel: CancelToken = NEVER) -> tuple:
        """`_drive_windows`, every processed window written to the sink at the end, or when the drive fails, before
        the failure is raised (nothing computed is lost)."""
        unwritten: list = []
        try:
            return self._drive_windows(sink, progress, t_total, pair, unwritten, cancel)
        finally:
            if sink is not None:
                self._to_sink(sink, unwritten)

    def _close_enough(self, x_predicted: np.ndarray, x_true: np.ndarray) -> bool:
        """A paired window's predicted start is used (carried to the true start by the window's linear model) when no
        strut temperature is further than PAIRED_START_TOLERANCE_K from the true start's: the carry is exact to first
        order, its remainder grows with the offset squared."""
        nodes = self.heat_nodes_index
        return bool(np.max(np.abs(x_predicted[nodes] - x_true[nodes])) <= self.ms.PAIRED_START_TOLERANCE_K)

    # --- the drive -------------------------------------------------------------------------------
    def run(self, sink=None, state: DriveState | None = None, progress=None, checkpoint_every_blocks: int = 6,
            cancel: CancelToken = NEVER):
        """Every window, the slow states carried across the gaps to the drive's end, the control variate and the
        sampling error. Once `cancel` is requested it returns after the window being integrated, its state at
        that window's end and no estimate (a multiscale run is not resumed: it is run again)."""
        if state is not None and state.s_m > 0:
            raise UserInputError("solver.mode multiscale: a multiscale run cannot be resumed (it takes seconds): "
                                 "run it again with --overwrite")
        S = self.settings
        D = S.distance_m
        # the windows end on whole output samples; the slow states are carried across the last gap to the drive's
        # end (`DriveEnd.time_s`, where its distance is reached)
        t_total, t_end = self.end.whole_time_s, self.end.time_s
        wall0 = time.perf_counter()
        pair = WindowPair(self)
        try:
            records, x = self._drive_windows_to(sink, progress, t_total, pair, cancel)
        finally:
            pair.close()
            if self._proxy_start is not None:          # its jobs end (or, the drive failed, are dropped) by themselves
                self._proxy_start[0].shutdown(wait=False, cancel_futures=True)
                self._proxy_start = None               # set up once: a second run reuses the proxy
        if x is None:                                  # cancelled: the state at the last window's end
            return self._stopped(records, time.perf_counter() - wall0)
        for w in records:       # the road proxy over the averaged stretch and what the window stands for (warm-up, gap)
            w.p_win, w.p_warm = self.proxy(w.s_avg0, w.s_end), self.proxy(w.s_start, w.s_avg0)
            w.p_gap = self.proxy(w.s_end, w.s_gap_end)
        cv = None
        if self.ms.control_variate and len(records) >= self.MIN_CV_WINDOWS:
            cv = self._control_variate(records, t_end)
            x = x.copy()
            x[self.slow_index] += cv["dx_slow"]
            x[self.cv_quad] += cv["dq"]
        self.estimate = {} if self.state_only else self.road_sampling_error(records, t_end, cv)
        final = DriveState(t_s=float(t_end), s_m=float(self.distance_at(t_end)), x=x, next_stats_m=D + 1.0,
                           last_stats={"t_s": float(t_end), "q": x[self.quad_index].copy(),
                                       "gas_sum": np.zeros(self.model.n), "gas_n": 0},
                           solver_memory=np.zeros_like(self.solver.get_state()))
        if sink is not None:
            sink.checkpoint(final.as_dict())
        V_oil = x[self.oil_index]
        after = self.equilibrium_solver.solve(x[self.T_oil_index], self.gas_masses, V_oil)
        self.window_log = records
        if not self.state_only:
            self.estimate.update(self.load_error(final, after))
        return DriveResult(state=final, after=after, wall_s=time.perf_counter() - wall0, integration_s=self._integration_s(records))

    @staticmethod
    def _integration_s(records: list) -> float:
        """The windows' integration wall time [s] (their solver calls), summed in drive order."""
        total = 0.0
        for w in records:
            total += w.integration_s
        return total

    def _stopped(self, records: list, wall_s: float) -> DriveResult:
        """The result of a cancelled run: the state at the end of its last window (the start if none ran)."""
        if records:
            w = records[-1]
            st = DriveState(t_s=w.t_end, s_m=w.s_end, x=w.x_end, next_stats_m=self.settings.distance_m + 1.0,
                            last_stats={"t_s": w.t_end, "q": w.x_end[self.quad_index].copy(),
                                        "gas_sum": np.zeros(self.model.n), "gas_n": 0},
                            solver_memory=w.memory)
        else:
            st = self.initial_state()
        after = self.equilibrium_solver.solve(st.x[self.T_oil_index], self.gas_masses, st.x[self.oil_index])
        self.window_log, self.estimate = records, {}
        return DriveResult(state=st, after=after, wall_s=wall_s, integration_s=self._integration_s(records))

    # --- control variate ------------------------------------------------------------------------
    def _control_variate(self, records, t_end: float) -> dict:
        """`WindowEstimator.control_variate` of this drive's windows."""
        return self.estimator.control_variate(records, t_end)

    def road_sampling_error(self, records, t_end: float, cv: dict | None = None) -> dict:
        """`WindowEstimator.road_sampling_error` of this drive's windows."""
        return self.estimator.road_sampling_error(records, t_end, cv)

    def load_error(self, final: DriveState, after) -> dict:
        """Per-station and per-axle temperature errors and the per-axle wheel-load-change error (95 % interval,
        `error_factor` sigma) from the slow states' covariance, through the after-drive equilibrium."""
        m = self.model
        cov = self.estimate["cov"]
        pos = {int(j): k for k, j in enumerate(self.slow_index)}
        iT = [pos[int(j)] for j in self.T_index]             # the reported strut temperature (Drive.T_index)
        iT_eq = [pos[int(j)] for j in self.T_oil_index]      # the temperature the standing vehicle's loads follow
        iV = [pos[int(j)] for j in self.oil_index if int(j) in pos]
        n, n_ax = m.n, m.params.n_axles
        axle_of = np.array([m.params.station_axle(i) for i in range(n)])
        W_ax = np.zeros((n_ax, n))
        for i in range(n):
            W_ax[axle_of[i], i] = 1.0 / np.sum(axle_of == axle_of[i])
        cov_T = cov[np.ix_(iT, iT)]
        sig_T_station = np.sqrt(np.maximum(np.diag(cov_T), 0.0))
        sig_T_axle = np.sqrt(np.maximum(np.diag(W_ax @ cov_T @ W_ax.T), 0.0))
        G = self.manifold.load_sensitivity(final.x, after, W_ax, self.initial_equilibrium().wheel_loads_N,
                                           self.settings.compensation)
        idx = iT_eq + (iV if len(iV) == n else [])
        G = G[:, :len(idx)]
        sig_dN = np.sqrt(np.maximum(np.diag(G @ cov[np.ix_(idx, idx)] @ G.T), 0.0))
        k = error_factor(self.estimate["dof"])
        return {"sigmas": k, "strut_temperature_K": k * sig_T_station, "axle_temperature_K": k * sig_T_axle,
                "load_change_pct": k * sig_dN}

    def summary_extra(self) -> dict:
        """What the results add for this mode: /summary attributes and per-station/axle error variables."""
        e = self.estimate or {}
        ms = self.ms
        attrs = {"solver_mode": MODE, "multiscale_windows": int(e.get("n_windows", 0)),
                 "multiscale_window_m": float(ms.window_m), "multiscale_spacing_m": float(ms.spacing_m),
                 "multiscale_warm_up_m": float(ms.warm_up_m), "multiscale_placement": ms.placement,
                 "multiscale_covered_km": float(e.get("covered_m", 0.0)) / 1e3,
                 "multiscale_paired_windows": sum(bool(w.predicted_start) for w in self.window_log),
                 "multiscale_control_variate": bool(e.get("control_variate", False)),
                 "multiscale_proxy": ms.proxy if e.get("control_variate", False) else "none",
                 "estimated_error_sigmas": float(e.get("sigmas", np.nan)),
                 "estimated_error_coverage": ERROR_COVERAGE}
        if e:
            attrs["estimated_error_temperature_K"] = float(np.max(e["axle_temperature_K"]))
            attrs["estimated_error_load_change_pct"] = float(np.max(e["load_change_pct"]))
        values = {}
        if e:
            values = {"estimated_error_strut_temperature_K": e["strut_temperature_K"],
                      "estimated_error_axle_temperature_K": e["axle_temperature_K"],
                      "estimated_error_load_change_pct": e["load_change_pct"]}
        return {"attrs": attrs, "values": values}


def integrated_time_s(settings, multiscale: MultiscaleSettings) -> float:
    """The simulated time [s] the full model integrates in a multiscale drive, known before the drive is built: its
    planned windows (`MultiscaleSettings.windows`, warm-ups included), each in whole solver calls of M samples of
    K steps, as `MultiscaleDrive.integrate` advances them. settings: the drive's `DriveSettings` (distance, speed
    profile, dt, output interval, samples per block). The weighted placement moves the windows after the first once
    the first is driven but keeps their number and length, so under a varying speed this is approximate; a paired
    window integrated again from its true start is not counted."""
    distance = float(settings.distance_m)
    s, t = settings.speed.time_grid(distance + 1.0)
    t_total = float(np.interp(distance, s, t))
    K = int(round(settings.output_interval_s / settings.dt_s))
    M = samples_per_call(K, settings.samples_per_block)
    call_s = K * M * settings.dt_s
    total = 0.0
    for c0, c1 in multiscale.windows(distance):
        t0, t1 = float(np.interp(c0, s, t)), min(float(np.interp(c1, s, t)), t_total)
        samples = max(int(np.ceil((t1 - t0) / (K * settings.dt_s) - 1e-9)), 1)
        total += int(np.ceil(samples / M)) * call_s
    return total
