"""The control variate of the multiscale drive (docs/engines.md, "Control variate", "Station patterns"):
the regression estimate of each stratum's forcing on a road proxy known for the whole road, the station
patterns it regresses in, the stated error's covariance, and the two proxies (band-passed road rate,
the linear vehicle's strut velocity). Pure functions of NumPy arrays."""
from __future__ import annotations

import numpy as np

def control_variate(y: np.ndarray, p_window: np.ndarray, p_stretch: np.ndarray, t: np.ndarray | None = None):
    """Regression (control-variate) estimate of each stratum's mean forcing (Cochran, Sampling Techniques, 3rd ed.
    1977, ch. 7: the regression estimate, with the slope pooled over the strata as there is one window per
    stratum; Glasserman, Monte Carlo Methods in Financial Engineering 2004, sec. 4.1).

    y (nw, m): a value per window (stratum) and component; p_window (nw, m): the proxy of each component over
    the window; p_stretch (nw, m): the proxy over the part of the stratum the window stands for (known for the
    whole road); t (nw,): the windows' times, or None. Per component j the window values are regressed on
    [1, t - mean(t), p_window_j] (least squares; without t if t is None); the stratum estimate is
        y_k + beta_j (p_stretch_kj - p_window_kj).
    Returns (y_corrected, beta (m,), residuals (nw, m), dof, H (m, nw)): beta_j = H_j . y_j, so the slope's
    error has the covariance C_res[j, l] H_j . H_l. A proxy without scatter gives beta_j = 0 (the plain
    estimate); a y exactly linear in the proxy has zero residuals and the exact stratum values."""
    y = np.asarray(y, float)
    pw, ps = np.asarray(p_window, float), np.asarray(p_stretch, float)
    nw, m = y.shape
    base = [np.ones(nw)] + ([np.asarray(t, float) - np.mean(t)] if t is not None else [])
    X0 = np.column_stack(base)
    beta, H, res = np.zeros(m), np.zeros((m, nw)), np.empty_like(y)
    for j in range(m):
        dp = pw[:, j] - pw[:, j].mean()
        X = np.column_stack([X0, dp])
        if np.ptp(pw[:, j]) > 1e-12 * max(np.max(np.abs(pw[:, j])), 1e-300) and np.linalg.matrix_rank(X) == X.shape[1]:
            Xp = np.linalg.pinv(X)
            H[j] = Xp[-1]
            beta[j] = H[j] @ y[:, j]
        else:
            X = X0
        res[:, j] = y[:, j] - X @ (np.linalg.pinv(X) @ y[:, j])
    dof = nw - X0.shape[1] - 1
    return y + beta * (ps - pw), beta, res, dof, H


def station_patterns(position_m: np.ndarray, side: np.ndarray) -> np.ndarray:
    """Orthonormal patterns over the stations (rows of an (n, n) matrix): for the side sum (1 on every station)
    and the side difference (+1 left, -1 right) in turn, the polynomials 1, x, x^2, ... in the station's
    longitudinal position x (Gram-Schmidt, the vehicle's mean first), as many as there are distinct positions.
    The first is the vehicle's mean (heave-like), the second linear in x (pitch-like), the side difference
    roll-like. The higher ones are the patterns a rigid hull cannot follow, the ones the standing vehicle's
    wheel loads respond to: its loads hardly change with a uniform or a linear oil temperature pattern
    (docs/engines.md, "Control variate"). The identity if the stations do not give n independent patterns."""
    x = np.asarray(position_m, float)
    x = x - x.mean()
    n = x.size
    if np.ptp(x) > 0:
        x = x / np.ptp(x)
    k = len(np.unique(np.round(x, 9)))
    sides = [np.ones(n)] + ([np.where(np.asarray(side) == 0, 1.0, -1.0)] if len(np.unique(side)) > 1 else [])
    cols = [s * x ** j for s in sides for j in range(k)]
    M = np.column_stack(cols)[:, :n]
    if M.shape[1] < n or np.linalg.matrix_rank(M) < n:
        return np.eye(n)
    Q, R = np.linalg.qr(M)
    return (Q * np.sign(np.diag(R))[None, :]).T


def stratified_error_covariance(Q: np.ndarray, own: np.ndarray, Cb: np.ndarray, Mb: np.ndarray | None = None,
                                H: np.ndarray | None = None) -> np.ndarray:
    """Covariance of the final slow states' error of the stratified (and regression) estimate.

    Q (nw, ns, ns): how a unit error of stratum k's mean forcing (over what the window stands for) moves the
    final slow states; own (nw,): L_k / tu_k, the variance of the stretch's own mean relative to a window's
    (windows and stretches much longer than the road's correlation length); Cb (ns, ns): the residual
    covariance of one window's forcing. Stratum k's estimate takes the window's value for the stretch's,
    error e_w,k - e_s,k. With the control variate (Mb (ns, ns): how the final state moves with the slopes,
    `WindowEstimator.control_variate`; H (ns, nw): slope_j = H_j . y_j) each stratum also carries
    beta_hat - beta = sum_k H_k o e_w,k. So window k's own residual enters twice, in its stratum and in the
    slope (R_k = Mb diag(H_k)):

        error = sum_k (Q_k + R_k) e_w,k - Q_k e_s,k
        Cov   = sum_k own_k Q_k Cb Q_k^T + (Q_k + R_k) Cb (Q_k + R_k)^T
    = the strata's own terms (1 + L/tu) Q Cb Q^T, the slope's error Mb (Cb o H H^T) Mb^T, and the covariance of
    the two (the regression estimator's variance, e.g. Cochran, Sampling Techniques, 1977, sec. 7.3, written
    for the weighted sum of strata: the windows' residuals are independent, Var(e_w) = Cb)."""
    Q = np.asarray(Q, float)
    ns = Cb.shape[0]
    cov = np.zeros((ns, ns))
    for k in range(Q.shape[0]):
        W = Q[k] if Mb is None else Q[k] + Mb * H[:, k][None, :]
        cov += own[k] * Q[k] @ Cb @ Q[k].T + W @ Cb @ W.T
    return cov


def band_power_cumulative(slope: np.ndarray, spacing_m: float, speed_m_s: np.ndarray, band_hz) -> np.ndarray:
    """Cumulative time integral [m^2/s] of the squared road rate (slope x speed) passed through a band pass
    (Butterworth, 2nd order each side, at the mean speed's sampling rate) along the grid: C[i] = int_0^s_i
    (band-passed rate)^2 dt, so the mean over a stretch is (C(s1) - C(s0)) / (t1 - t0)."""
    from scipy.signal import butter, sosfilt   # lazy: only the road-rate proxy needs it

    v = np.broadcast_to(np.asarray(speed_m_s, float), slope.shape)
    fs = float(np.mean(v)) / spacing_m
    lo, hi = band_hz
    sos = butter(2, [lo, min(hi, 0.45 * fs)], btype="band", fs=fs, output="sos")
    y = sosfilt(sos, slope * v)
    c = np.empty(slope.size)
    c[0] = 0.0
    np.cumsum(0.5 * (y[1:] ** 2 / v[1:] + y[:-1] ** 2 / v[:-1]) * spacing_m, out=c[1:])
    return c


def road_spectrum(roads: np.ndarray) -> tuple:
    """The road heights under each tyre (n, N) [m], less their means, by the real FFT on a fast length L >= N (the
    signals taken periodic, zero-padded to L): (R (n, L//2+1), L, N). What `strut_velocity_from_spectrum` reads."""
    from scipy.fft import next_fast_len, rfft

    n, N = roads.shape
    L = next_fast_len(N, real=True)
    padded = np.zeros((n, L))                    # written once: no centred copy, no padded copy inside the FFT
    np.subtract(roads, roads.mean(axis=1, keepdims=True), out=padded[:, :N])
    return rfft(padded, axis=1, overwrite_x=True), L, N


def strut_velocity_from_spectrum(H_of_f, spectrum: tuple, rate_hz: float, n_frequencies: int) -> np.ndarray:
    """Each station's strut velocity [m/s] (n, N) of the linear vehicle under the road heights under each tyre
    whose `road_spectrum` is given (sampled at rate_hz; their delays, the wheelbase and the two tracks, are in the
    signals). V_i(f) = sum_j H_ij(f) R_j(f), H on n_frequencies points up to rate_hz / 2 (H_of_f(f) -> (n_f, n, n),
    `linear.strut_velocity_response`) and linearly interpolated between them. Within each interval [f_k, f_k+1] of
    that grid H = H_k + w dH_k, so V = H_k R + w (dH_k R): two (n, n) matrix products per interval over all its FFT
    lines. The signals are taken periodic: the caller pads them (the vehicle's memory: seconds). Parseval: the
    time-domain variance of the result equals the FFT sum of |V(f)|^2 (tests/unit/engines/test_multiscale.py checks
    it against a time-domain simulation of the same linear model)."""
    from scipy.fft import irfft

    R, L, N = spectrum
    f = np.fft.rfftfreq(L, 1.0 / rate_hz)
    fc = np.linspace(0.0, rate_hz / 2, n_frequencies)
    Hc = H_of_f(fc)                                                            # (nc, n, n)
    x = f / fc[1]                                                              # linear interpolation on fc
    k = np.minimum(x.astype(np.intp), n_frequencies - 2)
    w = x - k
    dH = Hc[1:] - Hc[:-1]
    edges = np.searchsorted(k, np.arange(n_frequencies))                      # the FFT lines of interval q
    V = np.empty_like(R)
    for q in range(n_frequencies - 1):
        a, b = edges[q], edges[q + 1]
        if b > a:
            Rq = R[:, a:b]
            V[:, a:b] = Hc[q] @ Rq + w[a:b] * (dH[q] @ Rq)
    return irfft(V, n=L, axis=1)[:, :N]


def on_grid(c: np.ndarray, spacing_m: float, s_m: float) -> float:
    """`on_grid_array` at one point s."""
    return float(on_grid_array(c, spacing_m, s_m))


def on_grid_array(c: np.ndarray, spacing_m: float, s_m: np.ndarray) -> np.ndarray:
    """c (on a uniform grid from 0) linearly interpolated at each s, held at its ends (the grid index by a division,
    where np.interp searches the grid's positions)."""
    x = np.clip(np.asarray(s_m, float) / spacing_m, 0.0, c.size - 1.0)
    i = np.minimum(x.astype(np.intp), c.size - 2)
    x -= i
    return c[i] + x * (c[i + 1] - c[i])


def variance_ratio(res: np.ndarray, res0: np.ndarray, slots: np.ndarray) -> float:
    """Residual variance with the proxy / without it, summed over the given components (oil temperatures)."""
    a = float(np.sum(res[:, slots] ** 2))
    b = float(np.sum(res0[:, slots] ** 2))
    return a / b if b > 0 else float("nan")
