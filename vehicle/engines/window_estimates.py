"""What the multiscale drive makes of its windows' records: the windows themselves (`WindowRecord`), the control
variate's correction of the final state and the a-posteriori covariance of the road-sampling error
(docs/engines.md, "Multiscale mode"). Pure NumPy on the records; `MultiscaleDrive` composes a `WindowEstimator`."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vehicle.engines.control_variate import control_variate, stratified_error_covariance, variance_ratio
from vehicle.engines.slow_flow import LinearFlow, window_forcings


@dataclass
class WindowRecord:
    """One window of the multiscale drive: what `MultiscaleDrive.window_record` makes of its integration, then
    the gap after it and the road proxy's means (`_drive_windows`, `run`). Times [s], distances [m].

    x_avg0, x_end, t_avg0, t_end:  the state and time at the start of its averaged stretch and at its end
    A, r, xbar, b, q_rate:         its averaged slow model dx_s/dt = b + A x_s (r: the slow rates, xbar: the mean
                                   slow state) and the totals' rates
    row, memory, samples:          its statistics row, the solver memory at its end, its samples for the sink
    flow:                          `LinearFlow` of A; predicted_start: integrated from a predicted start (paired)
    t_start, t_gap_end, tau, tw:   its start, the end of the gap after it, the gap's and the warm-up's durations
    s_start, s_avg0, s_end, s_gap_end:  the same as distances
    p_win, p_warm, p_gap:          the road proxy's means over the window, its warm-up and its gap
    """

    x_end: np.ndarray
    x_avg0: np.ndarray
    t_end: float
    t_avg0: float
    A: np.ndarray
    r: np.ndarray
    xbar: np.ndarray
    b: np.ndarray
    q_rate: np.ndarray
    row: dict
    memory: np.ndarray
    samples: list
    integration_s: float = 0.0
    flow: LinearFlow | None = None
    predicted_start: bool = False
    tau_slow_s: float | None = None
    t_start: float = 0.0
    t_gap_end: float = 0.0
    tau: float = 0.0
    tw: float = 0.0
    s_start: float = 0.0
    s_avg0: float = 0.0
    s_end: float = 0.0
    s_gap_end: float = 0.0
    p_win: np.ndarray | None = None
    p_warm: np.ndarray | None = None
    p_gap: np.ndarray | None = None


class WindowEstimator:
    """The control variate and the sampling error of a drive's windows.

    Parameters
    ----------
    slow_index, ext_index:   the slow states and the totals (quadratures) in the state vector
    slow_station:            the station of each slow state (-1: the vehicle's)
    cv_basis:                the orthonormal basis of the slow states in which the control variate regresses
    cv_quad, cv_quad_station: the dissipated energies' states regressed too, and their stations
    T_oil_index:             the oil temperature states (the variance ratio is reported for them)
    """

    def __init__(self, slow_index, ext_index, slow_station, cv_basis, cv_quad, cv_quad_station, T_oil_index):
        self.slow_index, self.ext_index, self.slow_station = slow_index, ext_index, slow_station
        self.cv_basis, self.cv_quad, self.cv_quad_station = cv_basis, cv_quad, cv_quad_station
        self.T_oil_index = T_oil_index

    def _per_component(self, p: np.ndarray, stations: np.ndarray) -> np.ndarray:
        """A station proxy vector (n,) spread over components by their station (the mean for -1)."""
        return np.where(stations >= 0, p[np.maximum(stations, 0)], p.mean())

    def control_variate(self, records, t_end: float) -> dict:
        """The regression estimate (`control_variate`) of every stratum's forcing, as a correction of the final
        state. The slow states' forcings b_k (`window_forcings`) and the dissipated energies' rates are each
        regressed on its station's road proxy over the window. The slope times the proxy's difference between the stretch
        the window stands for (warm-up, gap) and the window is added to that stretch's forcing and carried to
        the end of the drive by the linear slow model (the gaps' response is linear in their forcing).

        The slow states' forcings are regressed pattern by pattern (`cv_basis`, `station_patterns`): each pattern
        of a kind of slow state over the stations (the vehicle's mean, linear in position, ...) on the same pattern
        of the proxy. The regression estimate holds for any linear combination of the strata (Cochran 1977 ch. 7).
        Per station, the windows' large common part (the whole vehicle's dissipation, and the state dependence's
        remainder shared by all struts, large in a cold first window) is fitted with a slope per station. It then
        leaks into the differences between the stations, which the after-drive loads follow; per pattern it stays
        in the mean. Returned in that basis: `residuals`, `H`, `beta`, and `M_beta` (final
        slow states per pattern slope); `basis` maps the slow states to the patterns."""
        A_mean = np.mean([w.A for w in records], axis=0)
        flow = LinearFlow(A_mean)
        st, qst = self.slow_station, self.cv_quad_station
        T = self.cv_basis
        t = np.array([w.t_avg0 for w in records])
        Y = window_forcings([w.A for w in records], [w.r for w in records], [w.xbar for w in records]) @ T.T
        PWs = np.array([self._per_component(w.p_win, st) for w in records])
        PW = PWs @ T.T
        tu = np.array([w.tw + w.tau for w in records])

        def stretch(w, stations):
            tot = w.tw + w.tau
            if tot <= 0:
                return self._per_component(w.p_win, stations)
            return self._per_component((w.tw * w.p_warm + w.tau * w.p_gap) / tot, stations)
        PS = np.array([stretch(w, st) for w in records]) @ T.T
        _, beta, res, dof, H = control_variate(Y, PW, PS, t)
        # the correction, and how the final slow state moves with each slope (for the slope's own error)
        ns = len(self.slow_index)
        dx, Mb = np.zeros(ns), np.zeros((ns, ns))
        for k, w in enumerate(records):
            for dur, t_from, p in ((w.tw, w.t_avg0, w.p_warm), (w.tau, w.t_gap_end, w.p_gap)):
                if dur <= 0:
                    continue
                G = flow.phi(max(t_end - t_from, 0.0)) @ flow.gamma(dur) @ T.T
                D = (self._per_component(p, st) - PWs[k]) @ T.T
                dx += G @ (beta * D)
                Mb += G * D[None, :]
        QW = np.array([self._per_component(w.p_win, qst) for w in records])
        QS = np.array([stretch(w, qst) for w in records])
        Yq = np.array([w.q_rate[np.searchsorted(self.ext_index, self.cv_quad)] for w in records])
        _, beta_q, _, _, _ = control_variate(Yq, QW, QS, t)
        dq = np.sum(tu[:, None] * beta_q * (QS - QW), axis=0)
        # how much of the forcings' scatter the proxy explains (the plain estimate's residuals: [1, t] only)
        _, _, res0, _, _ = control_variate(Y, np.zeros_like(PW), PW, t)
        return {"dx_slow": dx, "dq": dq, "beta": beta, "residuals": res, "dof": dof, "H": H, "M_beta": Mb,
                "basis": T, "variance_ratio": variance_ratio(res, res0, self.T_oil_slots())}

    def T_oil_slots(self) -> np.ndarray:
        pos = {int(j): k for k, j in enumerate(self.slow_index)}
        return np.array([pos[int(j)] for j in self.T_oil_index])

    def road_sampling_error(self, records, t_end: float, cv: dict | None = None) -> dict:
        """Covariance of the final slow states from the scatter of the window forcings b_k (`window_forcings`),
        propagated through the linear slow model (module docstring); with the
        control variate (cv) the scatter is the regression's residual scatter, plus the slope's own error."""
        ns = len(self.slow_index)
        nw = len(records)
        A_mean = np.mean([w.A for w in records], axis=0)
        flow = LinearFlow(A_mean)
        B = window_forcings([w.A for w in records], [w.r for w in records], [w.xbar for w in records])
        # the sampling error is the scatter about the forcing's slow drift along the drive (each gap follows its
        # own window, so a drift is followed): residuals of a straight line in time, 2 degrees of freedom
        t = np.array([w.t_avg0 for w in records])
        if cv is not None:
            res, dof = cv["residuals"], cv["dof"]
            Cb = res.T @ res / dof
        elif nw >= 4:
            T = np.column_stack([np.ones(nw), t - t.mean()])
            res = B - T @ np.linalg.lstsq(T, B, rcond=None)[0]
            Cb = res.T @ res / (nw - 2)
            dof = nw - 2
        elif nw >= 2:
            Cb = np.atleast_2d(np.cov(B.T, ddof=1))
            dof = nw - 1
        else:
            Cb = np.full((ns, ns), np.nan)
            dof = 1
        # the error of each stratum's total: the window's deviation from the local mean (variance Cb) and the
        # unsimulated stretch's own (Cb L / tu, windows much longer than the road's correlation length):
        # tu^2 Cb (1 + L / tu) (Cochran 1977 eq. 5.6: N^2 (1 - f) S^2 / n, N = L + tu, n = L), carried to the end
        # of the drive; with the control variate the slope's error too, which moves every stratum's correction
        # together and shares each window's residual with its stratum (`stratified_error_covariance`)
        Q, own = np.zeros((nw, ns, ns)), np.zeros(nw)
        for k, w in enumerate(records):
            tu = w.tau + w.tw          # the stretch the window stands for, not driven (gap, warm-up)
            if tu <= 0:
                continue
            Q[k] = flow.phi(max(t_end - w.t_gap_end, 0.0)) @ flow.gamma(tu)
            if cv is not None:
                Q[k] = Q[k] @ cv["basis"].T          # from the patterns' errors (Cb in that basis)
            own[k] = (w.t_end - w.t_avg0) / tu
        cov = stratified_error_covariance(Q, own, Cb, *((cv["M_beta"], cv["H"]) if cv is not None else ()))
        out = {"cov": cov, "n_windows": nw, "dof": dof,
               "covered_m": float(sum(w.s_end - w.s_start for w in records)),
               "control_variate": cv is not None}
        if cv is not None:
            out["variance_ratio"] = cv["variance_ratio"]
        return out
