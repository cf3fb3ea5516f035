"""The time-parallel drive's join (vehicle.engines.time_parallel, module docstring steps 3 and 4): the segments
joined in order, each corrected for its start's mismatch with the slow states' linearisation, its series and
statistics rows handed to the sink, and the correction's a-posteriori error carried to the end of the drive.

`SegmentJoiner` is the part of `TimeParallelDrive` that does this: it is given the drive's `fine` (full) and
`coarse` (multiscale) engines, whether to correct, and the error check's two calls (submit the coarse
propagations of a start's two versions; their difference)."""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
import time

import numpy as np

from vehicle.numerics.error_estimate import StepDoublingEstimate
from vehicle.physics.outputs import joined
from vehicle.engines.contract import DriveResult, DriveState
from vehicle.engines.slow_flow import LinearFlow, matrix_exponential

PIECE_SAMPLES = 500               # samples per block handed to the sink when the segments are joined


def merge_estimates(parts: list[StepDoublingEstimate]) -> StepDoublingEstimate | None:
    """One step-doubling estimate from the segments' (the windows of all segments pooled)."""
    parts = [p for p in parts if p is not None]
    if not parts:
        return None
    out = copy.deepcopy(parts[0])
    for p in parts[1:]:
        out.cost_s += p.cost_s
        for a, b in zip(out.levels, p.levels):
            a.diff_heat_J = a.diff_heat_J + b.diff_heat_J
            a.heat_J = a.heat_J + b.heat_J
            a.max_deflection_diff_m = max(a.max_deflection_diff_m, b.max_deflection_diff_m)
            a.windows += b.windows
    return out


@dataclass
class SegmentRun:
    """One segment as its worker ran it (`TimeParallelDrive.fine_segment`), what the join reads.

    k, t0, t1:       its index and its start and end [s] (on the output-sample grid)
    x_start, x_end:  its state at t0 (after the warm-up from the predicted start) and at its end (uncorrected)
    state:           its drive state at the end (`DriveState`: the statistics interval left open)
    mark, tail:      its slow states shortly after t0 and, past its end, at the next segment's mark (None: none)
    blocks:          its output series, joined over its blocks (drive key -> array)
    rows:            its raw statistics intervals (`BlockRecorder.stats_intervals`)
    X_sub, M_sub, U_sub: every few samples' states, solver memory and inputs (the slow-rate Jacobian)
    A:               the slow states' Jacobian averaged over the segment, its first and its second half
    estimate:        its step-doubling estimate, or None
    integration_s, cpu_s, wall_s:  its solver's wall time, its worker's CPU and wall time [s]
    """

    k: int
    t0: float
    t1: float
    x_start: np.ndarray
    mark: np.ndarray | None
    tail: np.ndarray | None
    x_end: np.ndarray
    state: DriveState
    blocks: dict
    rows: list
    X_sub: np.ndarray
    M_sub: np.ndarray
    U_sub: np.ndarray
    A: tuple
    integration_s: float
    estimate: object | None
    cpu_s: float = 0.0
    wall_s: float = 0.0


@dataclass
class _JoinState:
    """What the join carries from one segment to the next."""

    Q: np.ndarray                                 # quadratures at the previous segment's end (absolute)
    x_true: np.ndarray | None = None              # corrected end of the previous segment
    x_raw_prev: np.ndarray | None = None          # uncorrected end of the previous segment
    carry: tuple | None = None                    # (duration, dq, gas_sum, gas_n) of the interval left open
    prev_tail: np.ndarray | None = None           # the previous segment's slow states past the join
    prev_end_raw: np.ndarray | None = None
    mismatch: list = field(default_factory=list)
    rows: list = field(default_factory=list)
    n_samples: int = 0


class SegmentJoiner:
    """Joins the segments with the correction (the module docstring).

    Parameters
    ----------
    fine, coarse     the full drive each segment ran and the multiscale drive of the prediction and the checks
    correct          False: joined without the correction (for tests)
    submit_checks    submit_checks(jobs, pool) -> per job (t0, t1, x_a, x_b) the two coarse propagations' futures
    check_result     check_result(runs) -> the slow states' difference of a job's two propagations
    """

    def __init__(self, fine, coarse, correct: bool, submit_checks, check_result):
        self.fine, self.coarse, self.correct = fine, coarse, bool(correct)
        self.submit_checks, self.check_result = submit_checks, check_result
        self.model, self.settings = fine.model, fine.settings
        self.T_index, self.gas_masses = fine.T_index, fine.gas_masses
        self.parareal: dict = {}

    def _A(self, X, M, U, Sl) -> np.ndarray:
        return self.A_parts(X, M, U, Sl)[0]

    def A_parts(self, X, M, U, Sl) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The slow states' Jacobian averaged over the samples (X, M, U), over their first and over their second
        half (A's change along a segment), from one evaluation."""
        N = X.shape[1]
        ns = len(self.coarse.slow_index)
        Jd = self.coarse.J_slow.map(N)(X, M, U, np.repeat(self.fine.p[:, None], N, axis=1))
        sp = Jd.sparsity()             # sparse -> dense through the nonzeros (a dense DM converts slowly)
        J = np.zeros((ns, N * self.model.nx))
        J[np.asarray(sp.row(), int), np.repeat(np.arange(sp.size2()), np.diff(np.asarray(sp.colind(), int)))] = \
            np.asarray(Jd.nonzeros(), float)
        J = J.reshape(ns, N, self.model.nx)
        half = N // 2
        return tuple(J[:, sl].mean(axis=1) @ Sl for sl in (slice(None), slice(None, half), slice(half, None)))

    def _output_sensitivity(self, x, mem, u, Sl) -> dict:
        """d(output series)/d(slow states) at the state x (finite differences along the slaved directions)."""
        ns = Sl.shape[1]
        h = 1e-3
        X = np.column_stack([x] + [x + h * Sl[:, j] for j in range(ns)])
        m = self.model
        Y, _, heights = self.fine.outputs.map(ns + 1)(X, np.repeat(mem[:, None], ns + 1, axis=1),
                                                 np.repeat(u[:, None], ns + 1, axis=1),
                                                 np.repeat(self.fine.p[:, None], ns + 1, axis=1))
        outs = m.split_outputs(np.asarray(Y))
        outs["axle_height_change_m"] = np.asarray(heights)
        return {key: (np.asarray(outs[key])[:, 1:] - np.asarray(outs[key])[:, :1]) / h for key in joined("output")
                if key in outs}

    def join(self, parts, sink, progress, pool=None) -> DriveResult:
        """The segments joined in order: each corrected for its start's mismatch (the corrected end of the one
        before), its series and statistics rows handed to the sink, the correction's error estimated."""
        Sl = self.coarse.manifold.slaving(parts[0].x_end)
        # the corrections first (each segment's delta needs the corrected end of the one before), so that the error
        # checks' coarse propagations can start in the pool while the series are corrected and written here
        pre = self._corrections(parts, Sl, pool)
        j = _JoinState(Q=np.zeros(len(self.coarse.ext_index)))
        errors = []                   # per segment: (e without the check, check, Phi_T, delta, e_restart)
        for p, (A, flow, Phi_T, delta, check) in zip(parts, pre):
            errors.append(self._segment_error(p, j, Sl, Phi_T, delta, check))
            dX = self._write_series(p, j, flow, delta, Sl, sink)
            self._join_rows(p, j, flow, delta, Sl, dX)
            # the corrected end state: slow states (and the fast ones slaved to them) moved, quadratures offset
            ext = self.coarse.ext_index
            x_raw = p.x_end.copy()
            j.x_raw_prev = x_raw
            j.x_true = x_raw + Sl @ (Phi_T @ delta)
            j.x_true[ext] = x_raw[ext] - p.x_start[ext] + j.Q
            j.Q = j.x_true[ext].copy()
            if progress is not None:
                s1 = float(self.fine.distance_at(p.t1))
                progress(s1, float(self.settings.speed.speed(s1)), p.t1)
        if sink is not None and j.rows:
            sink.stats(j.rows)
        c0 = time.perf_counter()
        seg_err, err_end = [], np.zeros(len(self.coarse.slow_index))   # the correction's error, carried to the end
        for e, check, Phi_T, delta, e_restart in errors:
            if check is not None:
                e = np.maximum(e, np.abs(self.check_result(check) - Phi_T @ delta))
            seg_err.append(e + np.abs(Phi_T) @ e_restart)
            err_end = np.abs(Phi_T) @ (err_end + e_restart) + e
        coarse_check_s = time.perf_counter() - c0          # the wait for the checks (their own cost if run here)
        return self._joined_result(parts, j, sink, seg_err, err_end, coarse_check_s)

    def _corrections(self, parts, Sl, pool) -> list[tuple]:
        """Per segment (A, its flow, e^{A T}, the start's correction delta, the error check's runs or None)."""
        slow = self.coarse.slow_index
        ns = len(slow)
        pre, jobs, x_slow_prev = [], [], None
        for p in parts:
            k, T = p.k, p.t1 - p.t0
            A = p.A[0]                  # computed in the segment's worker (`fine_segment`)
            flow = LinearFlow(A)           # e^{A t} for the many t of the series and statistics rows
            Phi_T = flow.phi(T)
            delta = np.zeros(ns) if (k == 0 or not self.correct) else x_slow_prev - p.x_start[slow]
            x_slow_prev = p.x_end[slow] + (Sl @ (Phi_T @ delta))[slow]
            # a second, cheap coarse correction: the multiscale propagation of both starts over the segment on the
            # same few windows (their road noise cancels in the difference) sees how the dissipation responds to
            # the mismatch through the ride, which A (fast states slaved at rest) does not
            if k > 0 and self.correct and np.any(delta):
                jobs.append((len(pre), (p.t0, p.t1, p.x_start, p.x_start + Sl @ delta)))
            pre.append([A, flow, Phi_T, delta, None])
        for (i, _), check in zip(jobs, self.submit_checks([j for _, j in jobs], pool)):
            pre[i][4] = check
        return [tuple(p) for p in pre]

    def _segment_error(self, p, j: "_JoinState", Sl, Phi_T, delta, check) -> tuple:
        """(the error the linear correction leaves, the check's runs, e^{A T}, delta, the restart's error)."""
        slow = self.coarse.slow_index
        k, T = p.k, p.t1 - p.t0
        X, M, U = p.X_sub, p.M_sub, p.U_sub
        if k > 0:
            j.mismatch.append(j.x_raw_prev[slow] - p.x_start[slow])
        # the error the linear correction leaves: A's change with the slow states and along the segment
        e = np.zeros(len(slow))
        if check is not None:
            A_shift = self._A(X + (Sl @ delta)[:, None], M, U, Sl)
            A1, A2 = p.A[1:]
            e = np.abs((matrix_exponential(A_shift * T) - Phi_T) @ delta) \
                + 0.5 * np.abs((matrix_exponential(A2 * T) - matrix_exponential(A1 * T)) @ delta)
        # the restart: segment k's fast states at its start are not the serial run's (it started from rest
        # before its warm-up). Segment k-1 went on past the join over the same road as segment k's first
        # warm-up length: the difference of their slow-state changes there is what the different fast states
        # do after the join (they synchronise with the road within it); an error at the segment start,
        # carried through the segment like the errors before it
        e_restart = np.zeros(len(slow))
        if k > 0 and j.prev_tail is not None and p.mark is not None:
            e_restart = np.abs((j.prev_tail - j.prev_end_raw[slow]) - (p.mark - p.x_start[slow]))
        j.prev_tail, j.prev_end_raw = p.tail, p.x_end
        return e, check, Phi_T, delta, e_restart

    def _write_series(self, p, j: "_JoinState", flow, delta, Sl, sink) -> np.ndarray:
        """Segment p's series corrected (the output table's join: slow-state correction e^{A tau} delta at every
        sample on the states and outputs, quadratures offset by the segments before) and handed to the sink.
        Returns the states' correction at the samples (nx, samples)."""
        sample_dt = self.fine.K * self.settings.dt_s
        quad_pos = {int(q): i for i, q in enumerate(self.coarse.ext_index)}
        B = p.blocks
        ts = np.asarray(B["t_s"], float)
        E1 = flow.phi(sample_dt)
        D = np.empty((len(self.coarse.slow_index), len(ts)))
        d = flow.phi(ts[0] - p.t0) @ delta
        for i in range(len(ts)):
            D[:, i] = d
            if i + 1 < len(ts):       # the drive's partial last interval: a shorter step to its end sample
                d = (E1 if ts[i + 1] - ts[i] > sample_dt - 0.5 * self.settings.dt_s else flow.phi(ts[i + 1] - ts[i])) @ d
        dX = Sl @ D                                         # (nx, samples)
        X, M, U = p.X_sub, p.M_sub, p.U_sub
        if np.any(delta):
            for key in joined("state"):
                if key in B:
                    idx = np.atleast_1d(self.fine.series_rows[key])
                    B[key] = B[key] + (dX[idx] if B[key].ndim > 1 else dX[idx[0]])
            G = self._output_sensitivity(X[:, X.shape[1] // 2], M[:, M.shape[1] // 2], U[:, U.shape[1] // 2], Sl)
            for key, g in G.items():
                if key in B:
                    B[key] = B[key] + (g @ D).reshape(B[key].shape)
        for key in joined("quadrature"):
            if key in B:
                idx = self.fine.series_rows[key]
                B[key] = B[key] + j.Q[[quad_pos[int(i)] for i in np.atleast_1d(idx)]].reshape(-1, 1)
        if sink is not None:
            for a in range(0, len(ts), PIECE_SAMPLES):
                sink.samples({key: v[..., a:a + PIECE_SAMPLES] for key, v in B.items()})
        j.n_samples += len(ts)
        return dX

    def _join_rows(self, p, j: "_JoinState", flow, delta, Sl, dX) -> None:
        """Segment p's statistics rows with the temperatures corrected; an interval cut by a boundary is joined
        from both sides (what stays open at the segment's end is carried to the next)."""
        sample_dt = self.fine.K * self.settings.dt_s
        T_gas = self.fine.T_gas_index
        t0, t1 = p.t0, p.t1
        t_prev = t0
        for i, (s_end, dur, dq, x_end, gas) in enumerate(p.rows):
            t_b = t_prev + dur
            t_prev = t_b
            dxb = Sl @ (flow.phi(t_b - t0) @ delta)
            x_end = x_end + dxb
            gas = None if gas is None else gas + dxb[T_gas]
            if i == 0 and j.carry is not None:
                c_dur, c_dq, c_gs, c_gn = j.carry
                nb = max(int(round(dur / sample_dt)), 1)
                if gas is not None and c_gn:
                    gas = (c_gs + gas * nb) / (c_gn + nb)
                dur, dq = dur + c_dur, dq + c_dq
                j.carry = None
            j.rows.append(self.fine.stats_row(s_end, dur, dq, x_end, gas))
        # what stays open at the segment's end (nothing for the last)
        fs = p.state
        open_dq = p.x_end[self.fine.quad_index] - np.asarray(fs.last_stats["q"], float)
        open_dur = t1 - float(fs.last_stats["t_s"])
        gsum = np.asarray(fs.last_stats.get("gas_sum", 0.0), float) * 1.0
        gn = int(fs.last_stats.get("gas_n", 0))
        if gn:
            gsum = gsum + gn * dX[T_gas, -1]
        if not p.rows and j.carry is not None:
            c_dur, c_dq, c_gs, c_gn = j.carry
            j.carry = (c_dur + open_dur, c_dq + open_dq, c_gs + gsum, c_gn + gn)
        else:
            j.carry = (open_dur, open_dq, gsum, gn)

    def _joined_result(self, parts, j: "_JoinState", sink, seg_err, err_end, coarse_check_s) -> DriveResult:
        """The corrected final state (checkpointed), the after-drive equilibrium and the correction's error."""
        last = parts[-1]
        fs = last.state
        qi = self.fine.quad_index
        q_last = np.asarray(fs.last_stats["q"], float) + (j.x_true[qi] - last.x_end[qi])
        final = DriveState(t_s=float(fs.t_s), s_m=float(fs.s_m), x=j.x_true, next_stats_m=fs.next_stats_m,
                           last_stats={"t_s": float(fs.last_stats["t_s"]), "q": q_last,
                                       "gas_sum": np.asarray(fs.last_stats.get("gas_sum", 0.0), float),
                                       "gas_n": int(fs.last_stats.get("gas_n", 0))},
                           sample_index=j.n_samples, solver_memory=np.asarray(fs.solver_memory, float))
        if sink is not None:
            sink.checkpoint(final.as_dict())
        after = self.coarse.equilibrium_solver.solve(j.x_true[self.fine.T_oil_index], self.gas_masses,
                                                     j.x_true[self.coarse.oil_index])
        T_err, dN_err = self._error_bounds(j.x_true, after, err_end)
        self.parareal = {"segments": len(parts), "uncorrected_final_x": j.x_raw_prev, "final_x": j.x_true,
                         "mismatch": j.mismatch, "segment_error": seg_err, "error_end": err_end,
                         "strut_temperature_K": T_err, "axle_temperature_K": self.axle_matrix() @ T_err,
                         "load_change_pct": dN_err, "t_total_s": self.fine.end.whole_time_s, "coarse_check_s": coarse_check_s}
        est = merge_estimates([p.estimate for p in parts])
        integ = float(sum(p.integration_s for p in parts))
        return DriveResult(state=final, after=after, wall_s=0.0, integration_s=integ,
                           solver_error=None if est is None else est.summary(integ))

    def axle_matrix(self) -> np.ndarray:
        m = self.model
        n_ax = m.params.n_axles
        axle_of = np.array([m.params.station_axle(i) for i in range(m.n)])
        W = np.zeros((n_ax, m.n))
        for i in range(m.n):
            W[axle_of[i], i] = 1.0 / np.sum(axle_of == axle_of[i])
        return W

    def _error_bounds(self, x_end, after, err_end) -> tuple[np.ndarray, np.ndarray]:
        """Per station the reported temperature's estimated error [K] and per axle the wheel-load change's [pp]:
        the slow states' error magnitudes added with the magnitudes of the after-drive equilibrium's
        sensitivities (as if all had the same sign: a bound, not an interval)."""
        pos = {int(j): k for k, j in enumerate(self.coarse.slow_index)}
        T_err = err_end[[pos[int(j)] for j in self.T_index]]
        G = self.coarse.manifold.load_sensitivity(x_end, after, self.axle_matrix(),
                                                  self.fine.initial_equilibrium().wheel_loads_N,
                                                  self.settings.compensation)
        e = np.concatenate([err_end[[pos[int(j)] for j in self.fine.T_oil_index]],
                            err_end[[pos[int(j)] for j in self.coarse.oil_index]]])
        return T_err, np.abs(G) @ e
