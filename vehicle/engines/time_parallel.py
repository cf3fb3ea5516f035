"""Parallel in time (`solver: {time_parallel: P}`): one drive split into P segments run at full resolution in
P processes at once, with a correction of the slow states (docs/engines.md, "Time-parallel mode").

Parareal with a cheap coarse propagator (Lions, Maday, Turinici 2001; Gander & Vandewalle 2007, SIAM J.
Sci. Comput. 29(2)), one correction sweep:

1. Coarse G: one multiscale run (vehicle.engines.multiscale; one 500 m window per COARSE_SPACING_M, no control
   variate) from the start to the last segment's start predicts the slow states (`model.SLOW_STATES`: thermal nodes, filtered deflection, levelling oil) at every segment
   start. Segment 0 needs no prediction and (one segment per worker) starts at once, while G runs.
2. Fine F: each segment k is the real Drive (compiled ROS2, same dt, same road, same samples) in a worker
   process (forked: the built model and compiled stepper are inherited). With `lanes` L > 1 (scenario
   `solver.time_parallel_lanes`) each worker runs L consecutive segments in lockstep on the lane library
   (vehicle.engines.ensemble: each segment a lane, bit for bit what the scalar engine gives it), P = workers x L;
   all start after G (no lead for segment 0), and the join's error checks below run in lane groups too.
   Segment k > 0 starts from the vehicle standing in equilibrium at the predicted slow states
   (`SlowManifold.rest_state`) a warm-up stretch (default 50 m) before its start, so the ride transient of meeting the road settles before the segment's
   first sample: the fast states forget their start within seconds, the slow ones do not.
3. Correction: the mismatch delta_k = x_s,end(k-1) (corrected) - x_s(k) at the segment start is carried
   through segment k by the slow states' linearisation dx_s/dt = r + A (x_s - xbar) (A: the mean over the
   segment's samples of d(slow rates)/d(slow states) with the fast states slaved, as in the multiscale mode):
   x_s(t) += e^{A (t - t_k)} delta_k. It is applied to the stored temperatures, oil volumes, heave/pitch/roll
   and (through d(outputs)/d(slow states) at a segment state) the heights, forces, pressures and loads, to the
   statistics rows' temperatures and to the final state (the after-drive equilibrium). The quadratures
   (energies, RMS, ride integrals) only accumulate: each segment starts them at zero and they are offset by
   the totals before it; a statistics interval cut by a segment boundary is joined from both sides.
4. A-posteriori error: what the linear correction leaves out, per segment, propagated to the end with the
   following segments' e^{A T}. It has four parts: (a) the change of A with the slow states, A(x + S delta) - A(x) (second order in
   delta); (b) the change of A along the segment (A of its first half against its second half). (c) The restart:
   segment k-1 runs on past the join for one warm-up length (not stored) and the difference between its
   slow-state change there and segment k's is what segment k's different fast start does after the join.
   (d) A has the fast states slaved as the standing vehicle's: how the dissipation responds to the mismatch
   through the ride is not in it (first order in delta). One cheap second coarse correction sees it: the
   multiscale propagation of both starts (predicted and corrected) over the segment on the same CHECK_WINDOWS
   windows, whose difference against e^{A T} delta is taken where it exceeds (a) + (b). Its two propagations
   run in the pool's processes (free once the segments are done) while the join corrects and writes the series. Written to the
   summary per axle (temperature [K]) and through the after-drive equilibrium's sensitivity (wheel-load
   change [pp]), as estimated_error_* like the multiscale mode's.

A run that is resumed (`--resume`) continues serially (the full drive): the segments are not checkpointed.
"""
from __future__ import annotations

import copy
import dataclasses
import resource
import time
import warnings
from concurrent.futures import Future

import numpy as np

from hpsim.cancellation import NEVER, CancelToken
from hpsim.errors import UserInputError

from vehicle.numerics.error_estimate import StepDoublingEstimate
from vehicle.scenario.settings import SEGMENTS_RANGE, MultiscaleSettings
from vehicle.scenario.work_limits import drive_duration_s
from vehicle.engines.contract import DriveResult, DriveState
from vehicle.engines.ensemble import lane_stepper, run_lockstep
from vehicle.engines.full import Drive
from vehicle.engines.multiscale import MultiscaleDrive
from vehicle.engines.pool import can_fork, fork_pool, inherited
from vehicle.engines.slow_flow import propagators
from vehicle.engines.time_parallel_join import SegmentJoiner, SegmentRun

MODE = "time_parallel"
MIN_SEGMENT_S = 60.0              # a segment shorter than this is mostly warm-up: refused
JACOBIAN_SAMPLES = 120            # samples per segment at which the slow-rate Jacobian is averaged
CHECK_WINDOWS = 3                 # windows of the second coarse correction over a segment (the error estimate)
CHECK_WINDOW_M = 500.0            # their averaged stretch (after the coarse run's warm-up)
COARSE_SPACING_M = 10_000.0      # one coarse window per this much road
COARSE_COST = 1.5                 # the coarse run's wall time / the full model's over the road its windows drive


def _check_worker(t0, t1, x, n_windows, slaving):
    """One propagation of the join's error check (`TimeParallelDrive.coarse_propagate`) in a pool worker."""
    d = inherited()
    d.coarse.manifold.share_slaving(slaving)    # computed once in the parent: the same for every propagation
    return d.coarse_propagate(t0, t1, x, n_windows)


def _segment_worker(k, t0, t1, t_warm, x_pred, t_mark, t_tail):
    d = inherited()
    c0, w0 = time.process_time(), time.perf_counter()
    out = d.fine_segment(k, t0, t1, t_warm, x_pred, t_mark, t_tail)
    out.cpu_s = time.process_time() - c0
    out.wall_s = time.perf_counter() - w0
    return out


def _in_lockstep(fn, items: list[tuple], lanes: int, what: str) -> list:
    """fn(make_solver, *item) for every item, each in a lane thread of one `LockstepGroup` (engines.ensemble): their
    drives step together on the lane library, bit for bit what the scalar engine gives each. Results in order."""
    r = run_lockstep(lambda *a, make_solver: ("ok", fn(make_solver, *a)), [(str(i), it) for i, it in enumerate(items)],
                     lanes)
    out = []
    for i in range(len(items)):
        v = r["cases"].get(str(i))
        if not (isinstance(v, tuple) and v[0] == "ok"):
            raise RuntimeError(f"time-parallel: {what} {i} failed in its lane group: "
                               f"{v.get('error') if isinstance(v, dict) else 'not run'}")
        out.append(v[1])
    return out


def _group_worker(items: list[tuple], lanes: int) -> list[SegmentRun]:
    """Several segments (each item: _segment_worker's arguments) in one worker, in lockstep on the lane library.
    The group's CPU time is shared out over its segments by their lengths."""
    d = inherited()
    c0, w0 = time.process_time(), time.perf_counter()
    out = _in_lockstep(d.lane_segment, items, lanes, "segment")
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    span = sum(p.t1 - p.t0 for p in out)
    for p in out:
        p.cpu_s, p.wall_s = cpu * (p.t1 - p.t0) / span, wall
    return out


def _check_group_worker(items: list[tuple], slaving, lanes: int) -> list[np.ndarray]:
    """Several propagations of the join's error check (each item: (t0, t1, x)) in lockstep on the lane library."""
    d = inherited()
    d.coarse.manifold.share_slaving(slaving)
    return _in_lockstep(d.lane_check, items, lanes, "error check")


class _Pick:
    """Item i of a future's list, as a future (one propagation of a lane group of error checks)."""

    def __init__(self, future: Future, i: int):
        self.future, self.i = future, i

    def result(self):
        return self.future.result()[self.i]


def _children_cpu() -> float:
    """CPU time [s] of this process's ended (waited-for) child processes."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _done(value) -> Future:
    """A future that already holds its result (what the pool would hand back)."""
    f = Future()
    f.set_result(value)
    return f


class _SegmentRecorder:
    """`BlockObserver` of a fine segment: its output series, its raw statistics intervals (corrected at the join),
    every stride-th sample's state, memory and inputs (the slow-rate Jacobian), and the slow states at t_mark."""

    def __init__(self, stride: int, t_mark: float | None, slow_index: np.ndarray):
        self.stride, self.t_mark, self.slow_index = stride, t_mark, slow_index
        self.blocks, self.rows, self.Xs, self.Ms, self.Us = [], [], [], [], []
        self.n, self.mark = 0, None

    def block(self, X, U, memory, outputs):
        self.blocks.append(outputs)
        pick = np.flatnonzero((np.arange(X.shape[1]) + self.n) % self.stride == 0)
        self.Xs.append(X[:, pick])
        self.Ms.append(memory[:, pick])
        self.Us.append(U[:, pick])
        self.n += X.shape[1]
        if self.t_mark is not None:
            hit = np.flatnonzero(np.abs(np.asarray(outputs["t_s"]) - self.t_mark) < 1e-6)
            if len(hit):
                self.mark = X[self.slow_index, hit[0]].copy()

    def intervals(self, intervals):
        self.rows += [(float(s_end), float(duration), np.array(dq, float), np.array(x_end, float),
                       None if gas is None else np.array(gas, float))
                      for s_end, duration, dq, x_end, gas in intervals]


class TimeParallelDrive:
    """A full drive split into `segments` segments in time, run in parallel processes and joined with a correction
    of the slow states (module docstring). It composes two engines on one model, road and settings: the full
    drive (`fine`, each segment) and a multiscale drive (`coarse`: the prediction at the segment starts and the
    join's error checks). `correct=False`: joined without the correction (for tests)."""

    mode = MODE

    def __init__(self, model, road, settings, segments: int, *, coarse: MultiscaleSettings | None = None,
                 lanes: int = 1, lane_library: bool = True, warm_up_m: float = 50.0, correct: bool = True):
        lo, hi = SEGMENTS_RANGE
        self.lanes = max(1, min(int(lanes), int(segments)))
        workers = -(-int(segments) // self.lanes)
        if not lo <= workers <= hi:
            raise UserInputError(f"solver.time_parallel: must be in [{lo}, {hi}] (processes) or auto, got {workers}")
        # segments too short refused before anything is compiled (the drive's duration as the drive computes it)
        self.segments = int(segments)
        self._check_segment_length(drive_duration_s(settings.speed, settings.distance_m), workers)
        # the coarse propagation: one window per COARSE_SPACING_M of road, no control variate (docs/engines.md,
        # "Time-parallel mode": the correction takes out the prediction's error to first order)
        # the segments end on whole output intervals, the last at the drive's end (`fine_segment`)
        self.fine = Drive(model, road, settings)
        self.coarse = MultiscaleDrive(model, road, settings,
                                      coarse or MultiscaleSettings(control_variate=False, spacing_m=COARSE_SPACING_M),
                                      gas_masses=self.fine.gas_masses)
        self.model, self.settings, self.gas_masses = model, settings, self.fine.gas_masses
        self.total_time_s = self.fine.total_time_s
        self.T_index = self.fine.T_index
        self.build_s = self.fine.build_s + self.coarse.build_s
        self.warm_up_m = float(warm_up_m)
        self.correct = correct
        self.joiner = SegmentJoiner(self.fine, self.coarse, correct, self.coarse_differences_submit,
                                    self.coarse_difference_result)
        # segments per worker: `lanes` consecutive segments run in lockstep on the lane library (lane_library
        # False: the same segmentation, each segment on the scalar engine in its own worker)
        self.lane_library = bool(lane_library) and self.lanes > 1
        if self.lane_library:
            t0 = time.perf_counter()
            try:          # compiled (or fetched) here, once: the forked workers inherit it
                lane_stepper(model, self.settings.dt_s, self.lanes)
            except RuntimeError as exc:
                warnings.warn(f"time-parallel: {exc}; the segments run on the scalar engine")
                self.lane_library = False
            self.build_s += time.perf_counter() - t0
        self.parareal: dict = {}

    def _check_segment_length(self, total_time_s: float, workers: int) -> None:
        """UserInputError when the segments of a drive of total_time_s [s] are shorter than MIN_SEGMENT_S."""
        seg_s = total_time_s / self.segments
        if self.segments > 1 and seg_s < MIN_SEGMENT_S:
            key = "solver.time_parallel" + (f" x time_parallel_lanes ({workers} x {self.lanes})" if self.lanes > 1 else "")
            raise UserInputError(f"{key}: {self.segments} segments of a {total_time_s:.4g} s drive "
                                 f"are {seg_s:.3g} s each, at least {MIN_SEGMENT_S:g} s are needed: use at most "
                                 f"{max(1, int(total_time_s // MIN_SEGMENT_S))} segments")

    # --- the engine contract: the full drive's layout, start and end --------------------------------
    def describe(self):
        return self.fine.describe()

    def initial_equilibrium(self):
        return self.fine.initial_equilibrium()

    def initial_state(self) -> DriveState:
        return self.fine.initial_state()

    def final_values(self, state: DriveState) -> dict:
        return self.fine.final_values(state)

    # --- layout ---------------------------------------------------------------------------------
    def layout(self) -> tuple[np.ndarray, np.ndarray]:
        """(segment boundary times (P+1), warm-up start times (P)) on the output-sample grid."""
        sample_dt = self.fine.K * self.settings.dt_s
        n = self.fine.end.whole_samples
        P = self.segments
        # segment 0 starts at once, the others after the coarse run: segment 0 is longer by the coarse run's
        # estimated cost, in simulated seconds of the full model (it drives ceil(D_c / spacing) windows of
        # warm-up + window over the D_c = (P-1)/P of the road before the last segment start; plus its per-window
        # work: COARSE_COST times the windows' own time)
        lead = 0.0
        if P > 1 and self.lanes == 1:       # lane groups all start after the coarse run: no lead
            D = self.settings.distance_m
            n_w = int(np.ceil(D * (P - 1) / P / self.coarse.ms.spacing_m - 1e-9))
            span_s = n_w * (self.coarse.ms.warm_up_m + self.coarse.ms.window_m) / (D / (n * sample_dt))
            lead = min(COARSE_COST * span_s / sample_dt, n / (2 * P))
        L = (n - lead) / P
        t = np.array([0.0] + [round(lead + k * L) for k in range(1, P)] + [n], float) * sample_dt
        tw = np.zeros(P)
        for k in range(1, P):
            s = float(self.fine.distance_at(t[k]))
            lead = t[k] - self.coarse.manifold.time_at(max(s - self.warm_up_m, 0.0))
            tw[k] = max(t[k] - np.ceil(lead / sample_dt - 1e-9) * sample_dt, 0.0)
        return t, tw

    # --- coarse propagator ---------------------------------------------------------------------
    def coarse_states(self, times) -> list[np.ndarray]:
        """Full states predicted at `times` by one multiscale run from the start to the last of them."""
        c = copy.copy(self.coarse)
        t_end = float(max(times))
        c.settings = dataclasses.replace(self.settings, distance_m=float(self.fine.distance_at(t_end)))
        c.end = c.end.at_sample(round(t_end / (c.K * self.settings.dt_s)))
        c.state_only = True                 # only the states are wanted: no error estimate of its own
        x0 = c.initial_state().x
        res = c.run(None)
        log = c.window_log
        out = []
        for t in times:
            if t >= t_end - 1e-9:
                out.append(res.state.x.copy())
                continue
            for i, w in enumerate(log):
                if w.t_start - 1e-9 <= t <= w.t_gap_end + 1e-9:
                    # inside a window: forward from the window before it (its model carried on past its gap; the
                    # drive's start for the first), not back from this window's end: e^{A tau} with tau < 0
                    # amplifies the fast slow modes (the oil's ~2 min) by up to e^(window / 10 s)
                    base = w if t >= w.t_end - 1e-9 else (log[i - 1] if i else None)
                    x = (base.x_end if base else x0).copy()
                    m = base or w
                    tau = t - (base.t_end if base else 0.0)
                    Phi, forced, _ = propagators(m.A, m.b, tau)
                    x[self.coarse.slow_index] = Phi @ x[self.coarse.slow_index] + forced
                    x[self.coarse.ext_index] = x[self.coarse.ext_index] + m.q_rate * tau
                    out.append(x)
                    break
            else:
                out.append(res.state.x.copy())
        return out

    def coarse_difference_submit(self, t0, t1, x_a, x_b, n_windows: int = None, pool=None) -> list[Future]:
        """G(x_b) - G(x_a) of the slow states at t1 (`coarse_propagate` from each start at t0 over the same
        windows, whose road noise cancels in the difference), as its two propagations: futures of the pool, or,
        without one, run here (completed futures). `coarse_difference_result` takes the difference."""
        if pool is None:
            return [_done(self.coarse_propagate(t0, t1, x, n_windows)) for x in (x_a, x_b)]
        S = self.coarse.manifold.slaving(np.asarray(x_a, float))
        return [pool.submit(_check_worker, t0, t1, np.asarray(x, float), n_windows, S) for x in (x_a, x_b)]

    def coarse_differences_submit(self, jobs: list[tuple], pool=None) -> list[list]:
        """`coarse_difference_submit` for every (t0, t1, x_a, x_b) of jobs; on the lane library, their propagations
        in lockstep groups of `lanes` per pool task (bit for bit the same numbers)."""
        if pool is None or not self.lane_library or not jobs:
            return [self.coarse_difference_submit(*j, pool=pool) for j in jobs]
        S = self.coarse.manifold.slaving(np.asarray(jobs[0][2], float))
        runs = [(t0, t1, np.asarray(x, float)) for t0, t1, x_a, x_b in jobs for x in (x_a, x_b)]
        L = self.lanes
        futs = [pool.submit(_check_group_worker, runs[g:g + L], S, L) for g in range(0, len(runs), L)]
        picks = [_Pick(futs[i // L], i % L) for i in range(len(runs))]
        return [picks[2 * i: 2 * i + 2] for i in range(len(jobs))]

    def lane_check(self, make_solver, t0, t1, x) -> np.ndarray:
        """`coarse_propagate` in a lane thread of `run_lockstep`: its windows step with the lane's solver."""
        c = copy.copy(self.coarse)
        c.solver = make_solver(self.settings.dt_s).bind(self.model, c.K, c.M)
        return self.coarse_propagate(t0, t1, x, coarse=c)

    @staticmethod
    def coarse_difference_result(runs: list[Future]) -> np.ndarray:
        a, b = (r.result() for r in runs)
        return b - a

    def coarse_propagate(self, t0, t1, x, n_windows: int = None, coarse: MultiscaleDrive | None = None) -> np.ndarray:
        """The slow states at t1 of the multiscale propagation from x at t0 over n_windows windows (one at the
        start of each equal stretch of [t0, t1]; default CHECK_WINDOWS, as many as fit), the linear slow model across
        the gaps (coarse: the multiscale drive that runs the windows, default the drive's own)."""
        c = coarse or self.coarse
        span = c.ms.warm_up_m + CHECK_WINDOW_M
        s0, s1 = float(self.fine.distance_at(t0)), float(self.fine.distance_at(t1))
        # CHECK_WINDOWS, fewer on a segment shorter than their spans (overlapping windows drive the same road again)
        n_windows = n_windows or max(1, min(CHECK_WINDOWS, int((s1 - s0) // span)))
        starts = [s0 + (s1 - s0) * i / n_windows for i in range(n_windows)]
        x = np.asarray(x, float).copy()
        for i, s in enumerate(starts):
            tw0 = c.manifold.time_at(s) if i else t0
            t_end = min(c.manifold.time_at(min(s + span, s1)), t1)
            t_warm = min(c.manifold.time_at(min(s + c.ms.warm_up_m, s1)), t_end)
            x0 = c.manifold.rest_state(x)
            w = c.window_record(c.integrate(c.solver, x0, tw0, t_end, t_warm))
            t_next = c.manifold.time_at(starts[i + 1]) if i + 1 < n_windows else t1
            x = w.x_end.copy()
            Phi, forced, _ = propagators(w.A, w.b, max(t_next - w.t_end, 0.0))
            x[c.slow_index] = Phi @ x[c.slow_index] + forced
        return x[c.slow_index]

    # --- fine propagator (in a worker) -----------------------------------------------------------
    def lane_segment(self, make_solver, k, t0, t1, t_warm, x_pred, t_mark=None, t_tail=None) -> SegmentRun:
        """`fine_segment` in a lane thread of `run_lockstep`: its drive steps with the lane's solver."""
        return self.fine_segment(k, t0, t1, t_warm, x_pred, t_mark, t_tail,
                                  solver=make_solver(self.settings.dt_s))

    def fine_segment(self, k, t0, t1, t_warm, x_pred, t_mark=None, t_tail=None, solver=None) -> SegmentRun:
        """Segment k from t0 to t1 (warm-up from t_warm at the predicted state x_pred). The restart's effect (see
        _join): t_mark, a time shortly after t0 where the slow states are kept; t_tail: the segment goes on
        (not stored) to the next segment's t_mark and keeps its slow states there."""
        seg = copy.copy(self.fine)          # the same drive, with this segment's end and error estimate
        seg.error_estimate = None
        S = self.settings
        if solver is not None:              # a lane of the worker's lane group (`_group_worker`)
            seg.solver = solver.bind(self.model, seg.K, seg.M)
        sample_dt = self.fine.K * S.dt_s
        n_seg = int(round((t1 - t0) / sample_dt))
        last = k == self.segments - 1
        seg.close_last_interval = last      # an interval cut by the segment's end is closed by the next segment
        seg.partial_last_sample = False     # whole intervals up to the last segment's main run
        rec = _SegmentRecorder(max(1, n_seg // JACOBIAN_SAMPLES), t_mark, self.coarse.slow_index)
        n = self.model.n
        if k == 0:
            st = seg.initial_state()
        else:
            x0 = self.coarse.manifold.rest_state(np.asarray(x_pred, float))
            x0[self.coarse.ext_index] = 0.0
            seg.end = self.fine.end.at_sample(round(t0 / sample_dt))
            stw = DriveState(t_s=float(t_warm), s_m=float(self.fine.distance_at(t_warm)), x=x0, next_stats_m=np.inf,
                             last_stats={"t_s": float(t_warm), "q": x0[self.fine.quad_index].copy(), "gas_sum": np.zeros(n),
                                         "gas_n": 0},
                             solver_memory=np.zeros_like(self.fine.solver.get_state()))
            warm = seg.run(None, stw) if t0 > t_warm else None
            x = (warm.state.x if warm is not None else x0).copy()
            x[self.coarse.ext_index] = 0.0                 # the quadratures of the segment start at its first sample
            b = S.stats_interval_m
            s0 = float(self.fine.distance_at(t0))
            st = DriveState(t_s=float(t0), s_m=s0, x=x, next_stats_m=b * (np.floor((s0 + 1e-9) / b) + 1),
                            last_stats={"t_s": float(t0), "q": x[self.fine.quad_index].copy(), "gas_sum": np.zeros(n),
                                        "gas_n": 0},
                            solver_memory=(warm.state.solver_memory if warm is not None
                                           else np.zeros_like(self.fine.solver.get_state())))
        x_start = st.x.copy()

        seg.end = self.fine.end if last else self.fine.end.at_sample(round(t1 / sample_dt))
        seg.partial_last_sample = last      # the last segment ends where the drive does (its partial interval)
        if self.fine.error_estimate is not None:
            e = self.fine.error_estimate
            seg.error_estimate = StepDoublingEstimate(e.dt_s, e.tolerance, e.interval_s, e.n_struts, names=e.names)
        res = seg.run(None, st, observer=rec)
        tail = None
        if t_tail is not None and t_tail > t1:
            seg.end = self.fine.end.at_sample(round(t_tail / sample_dt))
            seg.error_estimate, est = None, seg.error_estimate
            tail = seg.run(None, copy.deepcopy(res.state)).state.x[self.coarse.slow_index].copy()
            seg.error_estimate = est
        blocks = {key: np.concatenate([b[key] for b in rec.blocks], axis=-1) for key in rec.blocks[0]}
        X_sub, M_sub, U_sub = (np.concatenate(a, axis=1) for a in (rec.Xs, rec.Ms, rec.Us))
        # the segment's slow-state Jacobian (whole, halves) here, in parallel, not in the join (the slaving S: the
        # drive's start's, cached, as the join's)
        A = self.joiner.A_parts(X_sub, M_sub, U_sub, self.coarse.manifold.slaving(self.fine.initial_state().x))
        return SegmentRun(k=k, t0=t0, t1=t1, x_start=x_start, mark=rec.mark, tail=tail, x_end=res.state.x.copy(),
                          state=res.state, blocks=blocks, rows=rec.rows, X_sub=X_sub, M_sub=M_sub, U_sub=U_sub, A=A,
                          integration_s=res.integration_s, estimate=seg.error_estimate)

    # --- the drive -------------------------------------------------------------------------------
    def run(self, sink=None, state: DriveState | None = None, progress=None, checkpoint_every_blocks: int = 6,
            cancel: CancelToken = NEVER):
        """The segments in parallel and their join (module docstring), or serially the full drive (a resumed run,
        one segment, no fork). The segments are not checkpointed: once `cancel` is requested, before the join, it
        returns the start state having written nothing (the run is then started again or resumed serially)."""
        # serially: a resumed run, one segment, no fork, or inside a daemonic worker (which cannot start processes)
        if (state is not None and state.s_m > 0) or self.segments <= 1 or not can_fork():
            self.parareal = {}
            return self.fine.run(sink, state, progress, checkpoint_every_blocks, cancel=cancel)       # serially
        wall0 = time.perf_counter()
        t, tw = self.layout()
        P, L = self.segments, self.lanes
        groups = [list(range(g, min(g + L, P))) for g in range(0, P, L)]     # consecutive segments per worker
        # the restart's overlap: the warm-up's length after each segment start
        marks = [None] + [t[k] + (t[k] - tw[k]) for k in range(1, P)]
        tails = marks[1:] + [None]
        children0 = _children_cpu()
        with fork_pool(len(groups), self) as pool:
            futs = []
            if L == 1:                  # segment 0 needs no prediction: it starts at once, while the coarse run goes
                futs.append(pool.submit(_segment_worker, 0, t[0], t[1], 0.0, None, None, tails[0]))
            c0 = time.perf_counter()
            cpu0 = time.process_time()
            self.coarse.manifold.slaving(self.fine.initial_state().x)       # once, shared by the coarse run and the join
            pred = [None] + (self.coarse_states(list(tw[1:])) if P > 1 else [])
            coarse_s = time.perf_counter() - c0
            coarse_cpu = time.process_time() - cpu0
            args = [(k, t[k], t[k + 1], tw[k], pred[k], marks[k], tails[k]) for k in range(P)]
            if self.lane_library:
                futs += [pool.submit(_group_worker, [args[k] for k in g], L) for g in groups]
            else:
                futs += [pool.submit(_segment_worker, *args[k]) for k in range(len(futs), P)]
            parts = []
            for f in futs:
                r = f.result()
                parts += r if isinstance(r, list) else [r]
            if cancel.requested:            # nothing written yet: the drive's start is what it has
                st = self.fine.initial_state()
                return DriveResult(state=st, after=self.fine.initial_equilibrium(), wall_s=time.perf_counter() - wall0,
                                   integration_s=float(sum(p.integration_s for p in parts)))
            # the join, with the pool's processes (free now) running its error checks
            j0, jw0 = time.process_time(), time.perf_counter()
            res = self.joiner.join(parts, sink, progress, pool)
            self.parareal = self.joiner.parareal
            join_cpu, join_wall = time.process_time() - j0, time.perf_counter() - jw0
        w = [p.cpu_s for p in parts]
        # the error checks' CPU: the workers' (waited for when the pool closed) less their segments'
        check_cpu = max(_children_cpu() - children0 - sum(w), 0.0)
        # what the run takes with a core per worker: segment 0, or the coarse run then the slowest other worker; then
        # the join, or its error checks spread over the workers (CPU times: on a shared machine the wall times say
        # more about the other load)
        per_worker = [sum(w[k] for k in g) for g in groups] if L > 1 else w
        critical = (coarse_cpu + max(per_worker) if L > 1 else
                    max(w[0], coarse_cpu + max(w[1:], default=0.0))) + max(join_cpu, check_cpu / len(groups))
        self.parareal.update(coarse_s=coarse_s, coarse_cpu_s=coarse_cpu, worker_cpu_s=w, join_cpu_s=join_cpu,
                             check_cpu_s=check_cpu,
                             join_wall_s=join_wall, workers=len(groups), lanes=L, lane_library=self.lane_library,
                             critical_cpu_s=critical, worker_wall_s=[p.wall_s for p in parts],
                             boundaries_s=t.tolist())
        res.wall_s = time.perf_counter() - wall0
        return res

    # --- what the results add ------------------------------------------------------------------
    def mismatch_axle_K(self) -> np.ndarray:
        """Largest |coarse prediction - fine| of the reported strut temperature at a segment start, per axle [K]."""
        pos = {int(j): i for i, j in enumerate(self.coarse.slow_index)}
        iT = [pos[int(j)] for j in self.T_index]
        mm = self.parareal.get("mismatch") or []
        if not mm:
            return np.zeros(self.model.params.n_axles)
        a = np.max(np.abs(np.array(mm)[:, iT]), axis=0)
        return np.array([a[[i for i in range(self.model.n) if self.model.params.station_axle(i) == ax]].mean()
                         for ax in range(self.model.params.n_axles)])

    def summary_extra(self) -> dict:
        pr = self.parareal
        if not pr or "axle_temperature_K" not in pr:
            return {"attrs": {"solver_mode": "full"}, "values": {}}
        attrs = {"solver_mode": MODE, "time_parallel_segments": int(pr["segments"]),
                 "time_parallel_lanes": int(self.lanes if self.lane_library else 1),
                 "time_parallel_coarse_s": float(pr.get("coarse_s", np.nan)),
                 "time_parallel_worker_cpu_s": float(np.sum(pr.get("worker_cpu_s", [np.nan]))),
                 "time_parallel_coarse_cpu_s": float(pr.get("coarse_cpu_s", np.nan)),
                 "time_parallel_join_cpu_s": float(pr.get("join_cpu_s", np.nan)),
                 "time_parallel_check_cpu_s": float(pr.get("check_cpu_s", np.nan)),
                 "time_parallel_join_s": float(pr.get("join_wall_s", np.nan)),
                 "time_parallel_critical_cpu_s": float(pr.get("critical_cpu_s", np.nan)),
                 "time_parallel_coarse_mismatch_K": float(np.max(self.mismatch_axle_K())),
                 "estimated_error_temperature_K": float(np.max(pr["axle_temperature_K"])),
                 "estimated_error_load_change_pct": float(np.max(pr["load_change_pct"])),
                 "estimated_error_sigmas": float("nan"), "estimated_error_coverage": float("nan")}
        values = {"estimated_error_strut_temperature_K": pr["strut_temperature_K"],
                  "estimated_error_axle_temperature_K": pr["axle_temperature_K"],
                  "estimated_error_load_change_pct": pr["load_change_pct"]}
        return {"attrs": attrs, "values": values}
