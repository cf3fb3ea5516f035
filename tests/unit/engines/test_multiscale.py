"""Multiscale mode (vehicle.engines.multiscale, issue 11 §2): windows of the road with the full model, the slow
states advanced between them, an a-posteriori error estimate.

- on a short drive the multiscale result matches the full run within the error the multiscale run states
  (per axle: final strut temperature and wheel load change), and the estimate is not vacuous;
- the slow linear model between windows integrates the model's own slow equations: with the ride switched
  off (flat road) the multiscale mode reproduces the full run's cooling/warming far inside its error;
- bad multiscale keys are refused before any work (exit code 2, file and key named).
"""
from __future__ import annotations

import textwrap

import numpy as np
import pytest
import yaml

from vehicle.engines.build import build_engine
from vehicle.results.run import run_in_memory
from vehicle.scenario.schema import read_scenario_text
from vehicle.analysis.summary import report_from

from tests.helpers import assert_bad_scenario_exits_2

BASE = {"description": "multiscale test", "vehicle": {"name": "apc_8x8"}, "road": {"iso_class": "D", "seed": 3},
        "speed": "20 km/h", "distance": "3 km", "ambient_temperature": "25 degC",
        "initial_temperatures": ["45 degC", "40 degC", "35 degC", "30 degC"],
        "output": {"interval": "1 s", "stats_interval": "0.5 km"}}
MULTISCALE = {"mode": "multiscale", "window": "200 m", "spacing": "600 m", "warm_up": "40 m"}


def _run(solver: dict, **changes):
    data = {**BASE, **changes, "solver": solver}
    sink = run_in_memory(read_scenario_text(yaml.safe_dump(data), "ms.yaml", "."))
    return sink, report_from(sink, "ms")


def test_the_python_api_runs_the_multiscale_mode(pair):
    """vehicle.Simulation with the scenario key gives the same run as the runner (deterministic windows)."""
    import vehicle

    res = vehicle.Simulation({**BASE, "solver": MULTISCALE}).run()
    rep = res.summary()
    _, (_, ms) = pair
    assert rep["solver_mode"] == "multiscale"
    assert [a["T_end_C"] for a in rep["axles"]] == pytest.approx([a["T_end_C"] for a in ms["axles"]], abs=1e-9)
    assert "solver mode multiscale" in res.report(print_it=False)


@pytest.fixture(scope="module")
def pair():
    return _run({}), _run(MULTISCALE)


@pytest.fixture(scope="module")
def road_rate_run():
    return _run({**MULTISCALE, "proxy": "road_rate"})


def assert_within_stated_error(full: dict, ms: dict) -> None:
    """The multiscale run's end temperatures and load shifts per axle against the full run's, within the stated
    error: a 95 % interval of the window sampling error (ERROR_COVERAGE, Student t from 5 windows), so each axle
    falls outside with 5 % probability. At most one of the four axles may be outside (two or more: 1.4 % if the
    interval is right) and none by more than twice. Which axle lands where is a draw: the windows' ride is
    chaotic, and a rounding-level change of the engine (its exp/log by 1 ulp) moved axle 3's dN error from 0.55
    to 1.18 of its interval on this drive, the full run's dN by up to 0.0008 pp."""
    est = ms["estimated_error"]
    for key, errors in (("T_end_C", est["T_end_K"]), ("dN_pct", est["dN_pct"])):
        ratio = [abs(a_ms[key] - a_full[key]) / e for a_full, a_ms, e in zip(full["axles"], ms["axles"], errors)]
        assert sum(r > 1.0 for r in ratio) <= 1 and max(ratio) <= 2.0, (key, ratio)


def test_multiscale_with_the_road_rate_proxy_matches_the_full_run_within_its_stated_error(pair, road_rate_run):
    (_, full), _ = pair
    _, ms = road_rate_run
    est = ms["estimated_error"]
    assert est["control_variate"] and est["proxy"] == "road_rate"
    assert_within_stated_error(full, ms)
    for a_full, eT in zip(full["axles"], est["T_end_K"]):
        assert 0 < eT < 0.2 * (a_full["T_end_C"] - a_full["T_start_C"])


def test_multiscale_matches_the_full_run_within_its_stated_error(pair):
    (full_sink, full), (ms_sink, ms) = pair
    assert full["solver_mode"] == "full" and ms["solver_mode"] == "multiscale"
    est = ms["estimated_error"]
    assert est["proxy"] == "linear_model"                     # the default proxy
    # 5 windows: the road-proxy control variate is on (Student t with 5 - 3 = 2 degrees of freedom: 4.3)
    assert est["windows"] == 5 and est["control_variate"] and est["sigmas"] > 4.0
    # it drove less than half the road with the full model
    assert est["covered_km"] < 0.5 * ms["distance_km"]
    assert_within_stated_error(full, ms)
    for a_full, eT in zip(full["axles"], est["T_end_K"]):
        rise = a_full["T_end_C"] - a_full["T_start_C"]
        assert rise > 2.0                                     # the struts did warm up: something to estimate
        # the estimate is informative: well below the temperature rise it qualifies
        assert 0 < eT < 0.2 * rise
    # the dissipated energy is extrapolated over the gaps as well (within 10 % of the full run)
    assert ms["energy_dissipated_MJ"] == pytest.approx(full["energy_dissipated_MJ"], rel=0.1)
    # time and distance of the stored samples jump over the gaps but never go back
    t = np.asarray(ms_sink.series("time"))
    assert np.all(np.diff(t) > 0) and np.max(np.diff(t)) > 10.0
    # the results say which mode wrote them, in the file's own terms
    assert ms_sink.summary_attrs()["solver_mode"] == "multiscale"
    assert full_sink.summary_attrs()["solver_mode"] == "full"
    ds = ms_sink.to_xarray("summary")
    assert ds["estimated_error_axle_temperature"].dims == ("axle",)


def test_slow_model_between_windows_follows_the_model_on_a_flat_road():
    """On a smooth road the ride dissipates next to nothing: the temperatures relax towards ambient through the
    model's own heat-loss equations, which the gaps integrate by the windows' linearisation."""
    changes = {"road": {"iso_class": "A", "seed": 3}, "initial_temperatures": ["60 degC", "50 degC", "40 degC",
                                                                                 "30 degC"]}
    _, full = _run({}, **changes)
    _, ms = _run(MULTISCALE, **changes)
    for a_full, a_ms in zip(full["axles"], ms["axles"]):
        change = a_full["T_end_C"] - a_full["T_start_C"]
        assert abs(change) > 0.1
        assert a_ms["T_end_C"] == pytest.approx(a_full["T_end_C"], abs=0.05 * abs(change) + 0.01)


def _scenario(tmp_path, solver: str):
    text = textwrap.dedent(f"""\
        vehicle: {{name: apc_8x8}}
        road: {{iso_class: D, seed: 1}}
        speed: 20 km/h
        distance: 3 km
        ambient_temperature: 25 degC
        solver: {solver}
        """)
    p = tmp_path / "bad.yaml"
    p.write_text(text)
    return p


@pytest.mark.parametrize("solver, key, words", [
    ("{mode: multiscale, window: 10 m}", "solver.window", ["[50, 1e+06] m", "10"]),
    ("{mode: multiscale, warm_up: -5 m}", "solver.warm_up", ["[0, 10000] m"]),
    ("{mode: fast}", "solver.mode", ["'full'", "'multiscale'"]),
    ("{window: 200 m}", "solver", ["only with mode: multiscale"]),
    ("{mode: multiscale, window: 400 m, spacing: 420 m}", "solver", ["spacing", "window + warm_up"]),
    ("{mode: multiscale, spacing: 2 km}", "solver.spacing", ["at least 3", "1000 m"]),
    ("{mode: multiscale, placement: everywhere}", "solver.placement", ["systematic", "stratified"]),
    ("{mode: multiscale, control_variate: maybe}", "solver.control_variate", ["boolean", "maybe"]),
    ("{control_variate: false}", "solver", ["only with mode: multiscale"]),
    ("{mode: multiscale, proxy: linear}", "solver.proxy", ["'road_rate'", "'linear_model'", "linear"]),
    ("{proxy: road_rate}", "solver", ["only with mode: multiscale"]),
    ("{mode: multiscale, paired_windows: sometimes}", "solver.paired_windows", ["boolean", "sometimes"]),
    ("{paired_windows: false}", "solver", ["only with mode: multiscale"]),
])
def test_bad_multiscale_keys_exit_2(tmp_path, capsys, solver, key, words):
    assert_bad_scenario_exits_2(_scenario(tmp_path, solver), key, words, capsys)


# --- the control-variate (regression) estimator: exact limits ------------------------------------------------
def _strata(nw=12, m=3, seed=5):
    rng = np.random.default_rng(seed)
    p_win = rng.uniform(1.0, 2.0, (nw, m))
    p_stretch = rng.uniform(1.0, 2.0, (nw, m))
    return rng, p_win, p_stretch


def test_control_variate_is_exact_when_the_forcing_is_linear_in_the_proxy():
    """y = a + b p in every window and stretch: the corrected stratum values are the stretch's own, the
    residuals vanish (the stated error with them), with or without the time column."""
    from vehicle.engines.control_variate import control_variate

    _, pw, ps = _strata()
    a, b = np.array([0.3, -1.0, 2.0]), np.array([1.5, 0.2, -4.0])
    t = np.linspace(0.0, 1e4, pw.shape[0])
    for tt in (None, t):
        yc, beta, res, dof, _ = control_variate(a + b * pw, pw, ps, tt)
        assert beta == pytest.approx(b, rel=1e-9)
        np.testing.assert_allclose(yc, a + b * ps, rtol=1e-9, atol=1e-12)
        assert np.max(np.abs(res)) < 1e-9
        assert dof == pw.shape[0] - (3 if tt is not None else 2)


def test_control_variate_reduces_to_the_plain_estimate_for_an_uncorrelated_proxy():
    """A proxy orthogonal to the forcings (after the intercept and the time trend) gets a zero slope: the
    strata keep the plain window values and the residuals are those of the plain estimate; a proxy without
    scatter likewise."""
    from vehicle.engines.control_variate import control_variate

    rng, _, ps = _strata()
    nw, m = ps.shape
    t = np.linspace(0.0, 1e4, nw)
    y = rng.normal(5.0, 1.0, (nw, m))
    X0 = np.column_stack([np.ones(nw), t - t.mean()])
    proj = np.eye(nw) - X0 @ np.linalg.pinv(X0)
    pw = np.empty((nw, m))
    for j in range(m):
        r = proj @ rng.normal(size=nw)
        ry = proj @ y[:, j]
        pw[:, j] = 1.5 + 0.1 * (r - ry * (r @ ry) / (ry @ ry))     # centred, orthogonal to y's residual
    yc, beta, res, _, _ = control_variate(y, pw, ps, t)
    assert np.max(np.abs(beta)) < 1e-9
    np.testing.assert_allclose(yc, y, atol=1e-9)
    np.testing.assert_allclose(res, proj @ y, atol=1e-9)
    yc0, beta0, res0, _, _ = control_variate(y, np.full((nw, m), 1.5), ps, t)
    assert np.all(beta0 == 0) and np.array_equal(yc0, y)
    np.testing.assert_allclose(res0, proj @ y, atol=1e-9)


def test_control_variate_cuts_the_sampling_error_of_a_noisy_linear_forcing():
    """Monte Carlo of the estimator on synthetic strata: y = a + b p + noise (noise 1/3 of the proxy's scatter).
    The regression estimate of the strata total has a smaller error than the plain one, near the theory's
    1 - R^2 (Cochran 1977 eq. 7.10), and its slope's spread matches the stated H H^T sigma^2."""
    from vehicle.engines.control_variate import control_variate

    rng = np.random.default_rng(11)
    nw, trials, b, sd = 15, 400, 2.0, 1.0 / 3.0
    err_plain, err_cv, slopes, pred = [], [], [], []
    for _ in range(trials):
        pw = rng.normal(0.0, 1.0, (nw, 1))
        ps = rng.normal(0.0, 1.0, (nw, 1))
        y = 1.0 + b * pw + rng.normal(0.0, sd, (nw, 1))
        truth = 1.0 + b * ps + rng.normal(0.0, sd, (nw, 1))
        yc, beta, res, dof, H = control_variate(y, pw, ps)
        err_plain.append(np.sum(y - truth))
        err_cv.append(np.sum(yc - truth))
        slopes.append(beta[0])
        pred.append(np.sum(res ** 2) / dof * float(H[0] @ H[0]))
    ratio = np.var(err_cv) / np.var(err_plain)
    r2 = b ** 2 / (b ** 2 + sd ** 2)
    assert ratio < 0.25 and ratio == pytest.approx(1 - r2, rel=0.6)
    assert np.var(slopes) == pytest.approx(np.mean(pred), rel=0.3)


def test_linear_flow_matches_the_matrix_exponential():
    """The gaps' propagators by one eigen-decomposition equal scipy's expm (with a zero eigenvalue: oil volume
    without levelling)."""
    from vehicle.engines.slow_flow import LinearFlow, propagators

    rng = np.random.default_rng(2)
    A = -np.diag([1 / 6300, 1 / 110, 1 / 10, 0.0]) + 1e-4 * rng.normal(size=(4, 4))
    A[3] = 0.0
    flow = LinearFlow(A)
    for t in (0.0, 5.0, 400.0, 5000.0):
        Phi, _, Gam = propagators(A, np.zeros(4), t)
        np.testing.assert_allclose(flow.phi(t), Phi, rtol=1e-8, atol=1e-10)
        np.testing.assert_allclose(flow.gamma(t), Gam, rtol=1e-8, atol=1e-8 * max(t, 1))


def test_weighted_layout_ends_with_the_drive():
    """The last window of the weighted placement ends at the drive's end (the final state's short thermal
    memories are simulated), windows never overlap and stay inside the drive."""
    from vehicle.scenario.settings import MultiscaleSettings

    ms = MultiscaleSettings(window_m=400.0, spacing_m=7000.0, warm_up_m=30.0)
    v = 20 / 3.6
    D = 106e3
    out = ms.weighted_windows(D, 430.0, 6300.0, lambda s: s / v, lambda t: t * v, D / v)
    assert out[-1][1] == pytest.approx(D)
    ends = [430.0] + [b for _, b in out]
    starts = [a for a, _ in out]
    assert all(a >= e - 1e-9 for a, e in zip(starts, ends[:-1]))
    assert all(b - a == pytest.approx(430.0) for a, b in out)
    assert len(out) == 15


def test_window_forcings_take_out_the_state_dependence_window_by_window():
    """Each window's slow rates carried to one state by the window's own Jacobian (`window_forcings`).
    (1) Exact to first order: with a curved state dependence the remainder is the curvature's f''/2 (x - x_ref)^2.
    (2) The apc's oil-to-wall exchange h_k (T_oil - T_wall): the film coefficient h_k grows with the road's
    stroking (real forcing) and multiplies a slow state that differs from window to window. With one mean
    Jacobian the windows' forcings keep (h_k - hbar) x_k, a product of the road and the state that no road
    proxy explains; carried by each window's own Jacobian they are road_k - h_k x_ref, a function of the road
    alone: a proxy linear in the road explains them exactly (zero residuals of `control_variate`).
    (3) A linear model (one A) gives r - A xbar plus a constant: the same scatter as before."""
    from vehicle.engines.control_variate import control_variate
    from vehicle.engines.slow_flow import window_forcings

    # (1) rate f(x) = road - k0 (1 + c x) x  (x: K above a reference)
    k0, c, road = 0.02, 0.01, 0.3
    x = np.linspace(0.0, 30.0, 9)[:, None]
    r = road - k0 * (1 + c * x) * x
    A = (-k0 * (1 + 2 * c * x))[:, :, None]
    b = window_forcings(A, r, x)
    x_ref = x.mean()
    remainder = k0 * c * (x - x_ref) ** 2                   # f(x) + f'(x) (x_ref - x) - f(x_ref) = -f''/2 (.)^2
    assert np.allclose(b - (road - k0 * (1 + c * x_ref) * x_ref), remainder)
    # (2) road power and exchange coefficient both linear in a proxy p; the windows at scattered states x_k
    rng = np.random.default_rng(1)
    nw = 12
    p = rng.uniform(0.5, 1.5, nw)
    P, h = 0.05 * p, 0.01 * (1 + 0.4 * p)
    xk = 9.0 + rng.normal(0.0, 2.0, nw)
    r = (P - h * xk)[:, None]
    A = (-h)[:, None, None]
    t = np.arange(nw, dtype=float)
    new = window_forcings(A, r, xk[:, None])
    old = r - xk[:, None] * A.mean(axis=0)[0, 0]
    res_new = control_variate(new, p[:, None], p[:, None], t)[2]
    res_old = control_variate(old, p[:, None], p[:, None], t)[2]
    assert np.max(np.abs(res_new)) < 1e-12 * np.max(np.abs(new))
    assert np.std(res_old) > 1e-3 * np.std(old)
    # (3) a linear model: the old forcing plus a constant
    A_lin = np.broadcast_to(np.array([[[-0.02, 0.01], [0.005, -0.01]]]), (9, 2, 2))
    X2 = np.column_stack([x[:, 0], 0.5 * x[:, 0] + 3.0])
    R2 = np.random.default_rng(0).normal(size=(9, 2)) + X2 @ A_lin[0].T
    d = window_forcings(A_lin, R2, X2) - (R2 - X2 @ A_lin[0].T)
    assert np.allclose(d, d[0], atol=1e-12)


def test_linear_model_proxy_matches_a_time_domain_simulation_of_the_linear_vehicle():
    """The linear-model proxy's strut velocities (`strut_velocity_from_spectrum`: FFT of the road under each tyre times
    the linearised vehicle's transfer functions, interpolated) against a direct time-domain simulation of the same
    state-space model (scipy.signal.lsim on a fine grid, road heights and rates given analytically, from rest):
    the mean square velocity of each strut over a stretch (the proxy of a window) agrees within 1 %, and the
    velocities themselves sample by sample. The road: independent smooth random signals under each tyre, tapered
    in and out so that both start and end at rest (the FFT's periodic signal is then the simulated one)."""
    from scipy.signal import StateSpace, lsim

    from vehicle.physics import linear
    from vehicle.physics.params import load_vehicle
    from vehicle.scenario.settings import MultiscaleSettings
    from vehicle.engines.control_variate import road_spectrum, strut_velocity_from_spectrum

    lin = linear.linearise(load_vehicle("apc_8x8"), None,
                           friction_velocity_m_s=MultiscaleSettings.LINEAR_PROXY_FRICTION_VELOCITY_M_S)
    n = lin.model.n
    rate = MultiscaleSettings.LINEAR_PROXY_RATE_HZ
    rng = np.random.default_rng(7)
    f = rng.uniform(0.3, 9.0, (n, 40))                    # Hz: body modes to wheel hop
    amp = rng.uniform(0.2, 1.0, (n, 40)) * 1e-2 / f       # m: a rougher road at low frequency
    ph = rng.uniform(0, 2 * np.pi, (n, 40))
    T_sig, T_tail, ramp = 60.0, 30.0, 5.0

    def road(t):
        """heights and rates (n, len(t)) of the tapered sums of sines (zero outside [0, T_sig])"""
        w = np.clip(np.minimum(t, T_sig - t) / ramp, 0.0, 1.0)
        wt = 0.5 - 0.5 * np.cos(np.pi * w)
        dwt = np.where((w > 0) & (w < 1), 0.5 * np.pi * np.sin(np.pi * w) / ramp
                       * np.where(t < T_sig / 2, 1.0, -1.0), 0.0)
        arg = 2 * np.pi * f[:, :, None] * t + ph[:, :, None]
        s = np.sum(amp[:, :, None] * np.sin(arg), axis=1)
        ds = np.sum(amp[:, :, None] * 2 * np.pi * f[:, :, None] * np.cos(arg), axis=1)
        return wt * s, dwt * s + wt * ds

    t_c = np.arange(0.0, T_sig + T_tail, 1.0 / rate)
    v_fft = strut_velocity_from_spectrum(lambda fr: linear.strut_velocity_response(lin, fr),
                                         road_spectrum(road(t_c)[0]), rate,
                                         MultiscaleSettings.LINEAR_PROXY_FREQUENCIES)
    t_f = np.arange(0.0, T_sig + T_tail, 1.0 / (16 * rate))
    r, dr = road(t_f)
    sys_ = StateSpace(lin.A, np.hstack([lin.B_road, lin.B_rate]), lin.C_velocity,
                      np.hstack([lin.D_velocity_road, lin.D_velocity_rate]))
    _, v_sim, _ = lsim(sys_, np.vstack([r, dr]).T, t_f)
    v_sim = v_sim[::16].T                                  # on the proxy's grid
    stretch = (t_c > 15.0) & (t_c < 45.0)                  # a "window" inside the steady part
    ms_fft, ms_sim = np.mean(v_fft[:, stretch] ** 2, axis=1), np.mean(v_sim[:, stretch] ** 2, axis=1)
    assert np.all(ms_sim > 1e-6)                           # the struts do move (mm/s and more)
    assert ms_fft == pytest.approx(ms_sim, rel=0.01)
    assert np.max(np.abs(v_fft - v_sim)) < 0.01 * np.max(np.abs(v_sim))


def test_spectral_product_by_interval_equals_the_interpolated_transfer_functions():
    """`strut_velocity_from_spectrum` forms V = H_k R + w (dH_k R) per interval of the transfer functions' grid:
    the same sums as interpolating each H_ij to every FFT line first (the reference below), to rounding."""
    from vehicle.engines.control_variate import road_spectrum, strut_velocity_from_spectrum

    rng = np.random.default_rng(3)
    n, N, nf, rate = 4, 5003, 41, 25.0
    roads = rng.normal(size=(n, N))
    Hc = rng.normal(size=(nf, n, n)) + 1j * rng.normal(size=(nf, n, n))
    R, L, _ = spec = road_spectrum(roads)
    got = strut_velocity_from_spectrum(lambda f: Hc, spec, rate, nf)
    f = np.fft.rfftfreq(L, 1.0 / rate)
    x = f / (rate / 2 / (nf - 1))
    k = np.minimum(x.astype(np.intp), nf - 2)
    w = x - k
    V = np.zeros_like(R)
    for i in range(n):
        for j in range(n):
            V[i] += (Hc[k, i, j] * (1.0 - w) + Hc[k + 1, i, j] * w) * R[j]
    ref = np.fft.irfft(V, n=L, axis=1)[:, :N]
    assert np.max(np.abs(got - ref)) < 1e-12 * np.max(np.abs(ref))


def test_on_grid_array_interpolates_a_uniform_grid_as_np_interp():
    """The proxy's road under each tyre: a uniform grid indexed by division (`on_grid_array`) against np.interp on
    the grid's positions: equal to the rounding of the position (s ~ 1e5 m), held at both ends."""
    from vehicle.engines.control_variate import on_grid, on_grid_array

    rng = np.random.default_rng(4)
    h = 0.05
    z = rng.normal(size=200_001)
    s = np.concatenate([[-3.0, 0.0], np.sort(rng.uniform(0.0, (z.size - 1) * h, 5000)), [(z.size - 1) * h, 1e4]])
    got = on_grid_array(z, h, s)
    ref = np.interp(s, np.arange(z.size) * h, z)
    position_ulp = np.spacing((z.size - 1) * h) / h          # index units
    assert np.max(np.abs(got - ref)) <= 4 * position_ulp * np.max(np.abs(np.diff(z)))
    assert got[0] == z[0] and abs(got[-1] - z[-1]) <= 2 * np.spacing(abs(z[-2]) + abs(z[-1]))
    assert got[7] == on_grid(z, h, float(s[7]))


def test_linear_model_proxy_can_match_a_given_rms_strut_velocity():
    """The optional equivalent linearisation by variance (`_linear_proxy_setup(match)`, off by default): the
    friction velocity amplitude found gives the linear vehicle the requested RMS strut velocity over the stretch,
    and a smaller RMS needs a smaller amplitude (more friction damping, c = 4 F_C / (pi V))."""
    from vehicle.scenario.schema import prepare

    data = {**BASE, "solver": MULTISCALE}
    _, drive = build_engine(prepare(read_scenario_text(yaml.safe_dump(data), "ms.yaml", ".")))
    t_a, t_b = 20.0, 80.0
    found = {}
    for target in (0.05, 0.08):
        drive._linear_proxy_setup((t_a, t_b, target))
        t, c = drive._proxy_t
        ms = np.array([np.interp(t_b, t, ci) - np.interp(t_a, t, ci) for ci in c]) / (t_b - t_a)
        assert np.sqrt(np.mean(ms)) == pytest.approx(target, rel=0.03)
        found[target] = drive.proxy_friction_velocity_m_s
    assert found[0.05] < found[0.08]


def test_stated_covariance_of_the_regression_estimate_matches_monte_carlo():
    """Synthetic strata with a known residual variance: window y_k = a + c t_k + b p_k + e_w,k, the stretch it
    stands for a + c t_k + b q_k + e_s,k (Var e_s = Var e_w L/tu); the regression estimate of the weighted sum
    sum_k Q_k stretch_k. The stated covariance (`stratified_error_covariance`) equals the Monte Carlo variance of
    the error; leaving out the covariance of each window's residual in its stratum and in the slope does not
    (a layout where the weights grow with the proxy, so that term is large)."""
    from vehicle.engines.control_variate import control_variate, stratified_error_covariance

    rng = np.random.default_rng(5)
    nw, trials, sd = 12, 4000, 0.5
    t = np.linspace(0.0, 1e4, nw)
    pw = rng.normal(0.0, 1.0, nw)
    ps = pw + 1.0 + 0.3 * rng.normal(size=nw)          # the stretches' proxy away from the windows'
    Q = 1.0 + 0.8 * (pw - pw.mean()) / pw.std()         # weights growing with the proxy
    own = np.full(nw, 0.2)                              # L / tu
    errs = []
    for _ in range(trials):
        y = 1.0 + 2e-4 * t + 2.0 * pw + rng.normal(0.0, sd, nw)
        truth = 1.0 + 2e-4 * t + 2.0 * ps + rng.normal(0.0, sd * np.sqrt(own))
        yc, beta, res, dof, H = control_variate(y[:, None], pw[:, None], ps[:, None], t)
        errs.append(float(Q @ (yc[:, 0] - truth)))
    _, _, _, _, H = control_variate(y[:, None], pw[:, None], ps[:, None], t)   # H depends on the design only
    Cb = np.array([[sd ** 2]])
    Mb = np.array([[float(Q @ (ps - pw))]])
    Qk = Q[:, None, None]
    stated = stratified_error_covariance(Qk, own, Cb, Mb, H)[0, 0]
    without_cross = (stratified_error_covariance(Qk, own, Cb)[0, 0] + (Mb @ (Cb * (H @ H.T)) @ Mb.T)[0, 0])
    measured = np.var(errs)
    assert stated == pytest.approx(measured, rel=0.08)
    assert abs(without_cross / measured - 1) > 0.25
    # no control variate: the plain stratified variance, sum (1 + L/tu) Q^2 sd^2
    assert stratified_error_covariance(Qk, own, Cb)[0, 0] == pytest.approx(np.sum((1 + own) * Q ** 2) * sd ** 2)


def test_station_patterns_are_orthonormal_mean_first_then_position():
    """The apc's 8 stations (4 axles, 2 sides): orthonormal patterns, the first the vehicle's mean, the second
    linear in the station's position, the side-difference ones opposite on the two sides; stations that do not
    give n independent patterns: the identity."""
    from vehicle.engines.control_variate import station_patterns

    x = np.repeat([0.0, 1.55, 3.45, 5.0], 2)
    side = np.arange(8) % 2
    P = station_patterns(x, side)
    np.testing.assert_allclose(P @ P.T, np.eye(8), atol=1e-12)
    np.testing.assert_allclose(P[0], np.full(8, 1 / np.sqrt(8)), atol=1e-12)
    xc = x - x.mean()
    np.testing.assert_allclose(P[1], xc / np.linalg.norm(xc), atol=1e-12)
    for row in P[:4]:                       # side sums: equal on both sides of an axle
        np.testing.assert_allclose(row[0::2], row[1::2], atol=1e-12)
    for row in P[4:]:                       # side differences: opposite
        np.testing.assert_allclose(row[0::2], -row[1::2], atol=1e-12)
    np.testing.assert_array_equal(station_patterns(np.array([0.0, 0.0, 1.0, 1.0]), np.zeros(4, int)), np.eye(4))


def test_pattern_regression_keeps_a_common_scatter_out_of_the_station_differences():
    """Synthetic strata of 8 stations: every window's forcing has a large part common to all stations that the
    proxy does not explain (sd 3) plus the proxy's share and a small per-station scatter. The error of a
    difference between the stations (orthogonal to the mean and to the linear pattern, as the after-drive loads)
    is several times smaller with the regression pattern by pattern (`station_patterns`) than station by station
    (per-station slopes fit the common part differently and it leaks into the difference), and in both cases
    the stated covariance (`stratified_error_covariance` in the regression's basis) matches the Monte Carlo
    variance."""
    from vehicle.engines.control_variate import control_variate, station_patterns, stratified_error_covariance

    rng = np.random.default_rng(8)
    n, nw, trials, sd_c, sd_e = 8, 14, 1500, 3.0, 0.2
    x = np.repeat([0.0, 1.55, 3.45, 5.0], 2)
    g = np.repeat([0.06, -0.08, -0.02, 0.04], 2)
    g -= np.polyval(np.polyfit(x, g, 1), x)               # a difference the mean and the pitch pattern do not see
    t = np.linspace(0.0, 1e4, nw)
    pw = rng.normal(0.0, 1.0, (nw, 1)) + rng.normal(0.0, 0.5, (nw, n))
    ps = rng.normal(0.0, 1.0, (nw, 1)) + rng.normal(0.0, 0.5, (nw, n))
    Q = np.ones(nw)
    cov_true = sd_c ** 2 * np.ones((n, n)) + sd_e ** 2 * np.eye(n)
    out = {}
    for name, T in (("stations", np.eye(n)), ("patterns", station_patterns(x, np.arange(n) % 2))):
        errs = []
        for _ in range(trials):
            y = 1.0 + 2.0 * pw + rng.normal(0.0, sd_c, (nw, 1)) + rng.normal(0.0, sd_e, (nw, n))
            truth = 1.0 + 2.0 * ps + rng.normal(0.0, sd_c, (nw, 1)) + rng.normal(0.0, sd_e, (nw, n))
            zc = control_variate(y @ T.T, pw @ T.T, ps @ T.T, t)[0]
            errs.append(g @ (Q @ (zc @ T - truth)))
        H = control_variate(np.zeros((nw, n)), pw @ T.T, ps @ T.T, t)[4]
        Mb = np.sum(Q[:, None, None] * T.T[None, :, :] * ((ps - pw) @ T.T)[:, None, :], axis=0)
        Qk = Q[:, None, None] * T.T[None, :, :]
        cov = stratified_error_covariance(Qk, np.ones(nw), T @ cov_true @ T.T, Mb, H)
        out[name] = (np.var(errs), float(g @ cov @ g))
    for measured, stated in out.values():
        assert stated == pytest.approx(measured, rel=0.12)
    assert out["patterns"][0] < 0.3 * out["stations"][0]


def test_warm_up_correction_carries_the_difference_through_the_window():
    """A linear slow model x' = b + A x with a fast (oil against wall, 2 min) and a slow mode: a window whose
    warm-up was simulated with extra heat (x_warm_end off the modelled crossing) and then followed the model for
    L. Its end state plus the correction equals the end state of the model crossing the warm-up and the window
    from x_start; the difference added undecayed would not (the fast mode has shed part of it)."""
    from vehicle.engines.slow_flow import LinearFlow, warm_up_correction

    A = np.array([[-1 / 120.0, 1 / 120.0], [1 / 240.0, -1 / 240.0 - 1 / 6000.0]])
    b = np.array([0.05, 0.001])
    flow = LinearFlow(A)
    x_start, tw, L = np.array([360.0, 352.0]), 6.0, 68.0

    def cross(x, t):
        return flow.phi(t) @ x + flow.gamma(t) @ b
    modelled_end = cross(cross(x_start, tw), L)
    x_warm_end = cross(x_start, tw) + np.array([5.0, 0.2])       # a start transient's heat
    simulated_end = cross(x_warm_end, L)
    corrected = simulated_end + warm_up_correction(flow, b, x_start, x_warm_end, tw, L)
    np.testing.assert_allclose(corrected, modelled_end, rtol=0, atol=1e-9)
    undecayed = simulated_end + (cross(x_start, tw) - x_warm_end)
    assert abs(undecayed[0] - modelled_end[0]) > 1.0


def test_the_stated_errors_student_factor_is_scipy_stats_t():
    """error_factor: the two-sided 95 % quantile of Student's t (3.18 for 3 degrees of freedom, 2.09 for 19), the
    numbers scipy.stats.t.ppf gives, without importing scipy.stats."""
    from scipy.stats import t as student_t

    from vehicle.engines.slow_flow import ERROR_COVERAGE, error_factor

    for dof in (1, 2, 3, 5, 17, 19, 60, 1000):
        assert error_factor(dof) == student_t.ppf(0.5 + ERROR_COVERAGE / 2, dof)
    assert error_factor(3) == pytest.approx(3.182, abs=1e-3) and error_factor(19) == pytest.approx(2.093, abs=1e-3)
    assert error_factor(0) == error_factor(1)


def test_slaving_matrix_equals_finite_differences_over_every_slow_state():
    """The slaving matrix S = dx/dx_slow of the standing vehicle (`SlowManifold.slaving`) solves equilibria only for the slow
    states the standing vehicle depends on (the oil's temperatures and volumes); its other columns, written as unit
    columns, equal the finite differences of `SlowManifold.rest_state` over every slow state bit for bit; the oil temperature's
    columns move the deflections (a warmer gas stands higher) and the gas temperatures."""
    from vehicle.scenario.schema import prepare

    data = {**BASE, "solver": MULTISCALE}
    _, drive = build_engine(prepare(read_scenario_text(yaml.safe_dump(data), "slaving test", ".")))
    x = drive.initial_state().x.copy()
    x[drive.T_oil_index] += np.linspace(1.0, 4.0, drive.model.n)
    base = drive.manifold.rest_state(x)
    expected = np.zeros((drive.model.nx, len(drive.slow_index)))
    for k, j in enumerate(drive.slow_index):
        h = 1e-4 * max(abs(x[j]), 1e-3)
        xp = x.copy()
        xp[j] += h
        expected[:, k] = (drive.manifold.rest_state(xp) - base) / h
    S = drive.manifold.slaving(x)
    np.testing.assert_array_equal(S, expected)
    k_oil = list(drive.slow_index).index(drive.T_oil_index[0])
    moved = np.flatnonzero(S[:, k_oil])
    assert len(moved) > 3 and drive.model.idx("z") in moved
