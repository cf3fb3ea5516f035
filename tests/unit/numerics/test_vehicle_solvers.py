"""The vehicle's solver contract (issue 9): the stiff Jacobian, the integrated strut on the vehicle at the
default step, solver objects passed in, and parameters as run-time inputs of one compiled model."""
from __future__ import annotations

import numpy as np
import pytest

from hpsim.errors import SimulationError

from terrain import RoadSpec, build_road
from vehicle.numerics import lanes, solvers
from vehicle.physics.model import VehicleModel
from vehicle.physics.params import VehicleParams, load_vehicle
from vehicle.engines.full import Drive
from vehicle.scenario.settings import DriveSettings
from vehicle.scenario.speed import SpeedProfile

from tests.helpers import make_drive


def test_structural_jacobian_equals_the_exact_one_for_the_separated_strut():
    """The hand-written stiff Jacobian (struts' k, c through the hull kinematics) equals CasADi's AD Jacobian of
    the explicit-ODE right-hand side, at a moving state off equilibrium."""
    drive = make_drive(distance_m=50.0)
    m = drive.model
    assert not m.has_stiff_strut_states
    rng = np.random.default_rng(1)
    x = drive.initial_state().x.copy()
    for i in range(m.n):
        x[m.idx(f"dw[{i}]")] = rng.normal(0.0, 0.3)
        x[m.idx(f"w[{i}]")] += rng.normal(0.0, 0.01)
    for nm in ("dz", "dtheta", "dphi"):
        x[m.idx(nm)] = rng.normal(0.0, 0.05)
    U = drive.inputs(np.array([3.0]))[:, 0]
    # memory = the converged valve pressure drops, so one warm Newton step is exact and AD sees the flow balance
    mem = np.zeros(m.n_memory)
    for _ in range(30):
        _, mem = m.ode_function(x, mem, U, drive.p)
        mem = np.asarray(mem).ravel()
    J_struct = np.asarray(m.jacobian_function(x, mem, U, drive.p))
    J_exact = np.asarray(m.exact_stiff_jacobian_function(x, mem, U, drive.p))
    scale = np.max(np.abs(J_exact), axis=1, keepdims=True) + 1e-12
    assert np.max(np.abs(J_struct - J_exact) / scale) < 1e-6


def _yin_vehicle(oil_model: str | None = None) -> VehicleParams:
    """The 8x8 on yin2023 struts as seed 001's identified model (struts.identify.PAPER_MODEL: the chamber numerics
    these tests are about, without the physical strut's seal, which needs 2 ms; the file's chambers: quasi_steady;
    oil_model overrides them)."""
    from struts.identify import PAPER_MODEL

    data = load_vehicle("apc_8x8").model_dump()
    for axle in data["axles"]:
        axle["strut"] = "yin2023"
        axle["strut_overrides"] = dict(PAPER_MODEL)
        if oil_model is not None:
            axle["strut_overrides"]["valve.oil_model"] = oil_model
    return VehicleParams.model_validate(data)


class _Samples:
    """A drive sink keeping the sampled strut deflections."""

    def __init__(self):
        self.deflection = []

    def start(self, info):
        pass

    def samples(self, block):
        self.deflection.append(block["strut_deflection"])

    def stats(self, rows):
        pass

    def checkpoint(self, state):
        pass


# the yin2023 drives of the tests below: ISO class C, 100 m at 20 km/h, samples every 0.2 s, one step-doubling window
# per block of 2 samples (the 4 ms block function and its 2 ms probe are shared by the tests in one process)
def _yin_drive(model, dt=None, error_check_every=1):
    road = build_road(RoadSpec(iso_class="C", length=160.0, seed=0))
    settings = DriveSettings(distance_m=100.0, speed=SpeedProfile.constant(20 / 3.6), output_interval_s=0.2,
                             samples_per_block=2, error_check_every=error_check_every)
    return Drive(model, road, settings, solver=None if dt is None else solvers.Ros2(dt))


def test_integrated_strut_runs_on_the_vehicle_at_the_default_step():
    """yin2023 struts on the 8x8 at the default 4 ms step (issue 9). Their chamber-pressure difference relaxes through
    the valves in 0.2-2 ms, which a 4 ms step cannot follow: with compressible chambers the ROS2 stages overshoot it,
    the valve power from the stages heats the 3.5 kJ/K oil node and the drive leaves physics (p_r 5 MPa above p_c at
    rest, 117 kJ of valve heat instead of 3 kJ on this road). The file's quasi-steady chambers (struts/integrated.py)
    take that relaxation as instantaneous, valid for omega tau << 1 (tau 0.07-0.6 ms on this vehicle: omega tau < 0.04
    at 10 Hz; tests/test_integrated_strut.py). Then 4 ms agrees with 1 ms: each strut's heat and oil-node rise within
    0.8 %, the deflection samples within 0.14 mm (measured; 2 ms: 0.18 %, 0.03 mm, second order); asserted within 2 %,
    2 % and 0.5 mm. The step-doubling estimate of the 4 ms run (0.7 % measured) meets the default 10 % tolerance."""
    m = VehicleModel(_yin_vehicle())
    assert all(st.quasi_steady and st.algebraic_names == ("dp_valve",) for st in m.struts)
    heat, rise, defl, runs = {}, {}, {}, {}
    for dt in (None, 0.001):
        d = _yin_drive(m, dt, error_check_every=1 if dt is None else 0)
        sink = _Samples()
        res = d.run(sink)
        key = d.settings.dt_s
        assert np.all(np.isfinite(res.state.x))
        heat[key] = sum(res.state.x[m.energy_index[e]] for e in ("valve", "friction", "end_stop"))
        rise[key] = res.state.x[d.T_oil_index] - 298.15
        defl[key] = np.hstack(sink.deflection)
        runs[key] = res
    assert set(heat) == {0.004, 0.001}                        # None -> the default step, 4 ms
    assert np.all(rise[0.004] > 0.05)                         # the struts really work (0.09-0.12 K in 18 s)
    assert np.max(np.abs(heat[0.004] / heat[0.001] - 1)) < 0.02
    assert np.max(np.abs(rise[0.004] / rise[0.001] - 1)) < 0.02
    assert defl[0.004].shape == defl[0.001].shape
    assert np.max(np.abs(defl[0.004] - defl[0.001])) < 5e-4
    err = runs[0.004].solver_error
    assert err["solver_error_estimate"] < err["solver_tolerance"]
    assert "meets the tolerance" in err["solver_advice"]


def test_a_parameter_change_reuses_the_compiled_model(monkeypatch):
    """Changing a number (heat capacity, tyre stiffness, the struts' bleed area) builds no new code: the parameters
    are an input of the compiled function. A structural change (a mechanism switched on) does; so does giving one
    axle a strut of its own (one more distinct strut in the model)."""
    road = build_road(RoadSpec(iso_class="D", length=140.0, seed=2))
    calls = []
    real, real_c = solvers.compile_function, lanes.compile_library
    # (the drives hand codegen.Library objects, named before any graph is built)
    monkeypatch.setattr(solvers, "compile_function", lambda fn, **kw: calls.append(fn.name) or real(fn, **kw))
    # the block steppers with batched calls (vehicle.numerics.lanes) are C of their own (codegen.CLibrary)
    monkeypatch.setattr(lanes, "compile_library", lambda lib, **kw: calls.append(lib.name) or real_c(lib, **kw))
    solvers._BLOCK_FUNCTIONS.clear()

    def run(overrides):
        from vehicle.scenario.schema import apply_overrides

        data = apply_overrides(load_vehicle("apc_8x8").model_dump(), overrides or {})
        m = VehicleModel(VehicleParams.model_validate(data))
        d = Drive(m, road, DriveSettings(distance_m=100.0, speed=SpeedProfile.constant(20 / 3.6)))
        return m, d, d.run()

    m0, d0, r0 = run(None)
    n0 = len(calls)                 # the block function, the block outputs and the error estimate's half-step one
    assert n0 == 3
    m1, d1, r1 = run({"heat.capacity": "20 kJ/K", "tyre.stiffness": "1.2 MN/m",
                      **{f"axles.{k}.strut_overrides": {"valve.bleed_area": "1.5e-5 m^2"} for k in range(4)}})
    assert len(calls) == n0, "a parameter change must not generate or compile code"
    assert m1.structure == m0.structure
    assert d1.solver.fn is d0.solver.fn
    # ... and the new values are really used: a smaller heat capacity heats faster
    rise0 = r0.state.x[d0.T_index] - d0.initial_state().x[d0.T_index]
    rise1 = r1.state.x[d1.T_index] - d1.initial_state().x[d1.T_index]
    assert np.all(rise1 > 1.4 * rise0)
    # the reused model gives what a model built for those values gives
    solvers._BLOCK_FUNCTIONS.clear()
    _, d2, r2 = run({"heat.capacity": "20 kJ/K", "tyre.stiffness": "1.2 MN/m",
                     **{f"axles.{k}.strut_overrides": {"valve.bleed_area": "1.5e-5 m^2"} for k in range(4)}})
    np.testing.assert_allclose(r2.state.x, r1.state.x, rtol=0, atol=0)
    # a structural change: the leakage path switched on adds terms -> new code
    m3, _, _ = run({f"axles.{k}.strut_overrides": {"valve.leakage": "1e-13 m^3/(Pa*s)"} for k in range(4)})
    assert m3.structure != m0.structure
    # (calls[n0:2 n0]: the rebuild after clearing the memo)
    assert calls[n0:2 * n0] == calls[:n0] and calls[-1] not in calls[:n0]


def test_a_drive_compiles_its_libraries_together(monkeypatch, tmp_path):
    """From an empty compile cache a drive builds its three libraries (the block stepper with batched calls, which
    also serves the one-step stepper of its partial last output interval (40 m are 7.2 s) since its steps and
    samples are arguments; the error estimate's half-step stepper; the block outputs) in one go: as many compilers
    as there are cores (up to the three) are started before the first is waited for, and `compile_function` then
    finds every one of them in the cache. The drive's result is the one of the libraries built one by one."""
    import os

    from vehicle.numerics import codegen, compiler_processes

    monkeypatch.setenv(codegen.CACHE_ENV, str(tmp_path / "cache"))
    events = []                                          # ("start" | "finish", the library's stem), in order
    real_start, real_finish = compiler_processes.start_build, compiler_processes.finish_build

    def start(job):
        events.append(("start", job.stem))
        return real_start(job)

    def finish(started):
        try:
            return real_finish(started)
        finally:
            events.append(("finish", started.job.stem))
    monkeypatch.setattr(compiler_processes, "start_build", start)
    monkeypatch.setattr(compiler_processes, "finish_build", finish)
    solvers._BLOCK_FUNCTIONS.clear()
    road = build_road(RoadSpec(iso_class="D", length=60.0, seed=5))
    m = VehicleModel(load_vehicle("apc_8x8"))
    settings = dict(distance_m=40.0, speed=SpeedProfile.constant(20 / 3.6))
    d = Drive(m, road, DriveSettings(**settings))
    assert len(events) == 6                          # built by precompile, none again by compile_function or compile_c
    assert len({stem for _, stem in events}) == 3
    at_once = min(3, os.cpu_count() or 1)
    assert [kind for kind, _ in events[:at_once + 1]] == ["start"] * at_once + ["finish"], events
    together = d.run().state.x
    # one by one (compile_function alone, as before precompile existed), into another empty cache
    monkeypatch.setenv(codegen.CACHE_ENV, str(tmp_path / "cache2"))
    monkeypatch.setattr("vehicle.engines.binding.precompile", lambda fns: 0)
    solvers._BLOCK_FUNCTIONS.clear()
    alone = Drive(m, road, DriveSettings(**settings)).run().state.x
    assert len(events) == 12 and [kind for kind, _ in events[6:]] == ["start", "finish"] * 3   # one by one
    np.testing.assert_array_equal(together, alone)
    solvers._BLOCK_FUNCTIONS.clear()          # the other tests use the default cache


def test_the_idas_reference_is_a_solver_object_the_drive_accepts():
    """The same Drive runs on IDAS (algebraic valves, adaptive steps) and agrees with the compiled ROS2 (over 1 s of
    drive: whole output intervals, which IDAS, having no one-step stepper for a partial last interval, keeps to)."""
    road = build_road(RoadSpec(iso_class="D", length=40.0, seed=4))
    m = VehicleModel(load_vehicle("apc_8x8"))
    out = {}
    for solver in (solvers.Ros2(0.004), solvers.Idas(0.004)):
        d = Drive(m, road, DriveSettings(distance_m=20 / 3.6, speed=SpeedProfile.constant(20 / 3.6),
                                         output_interval_s=0.2, samples_per_block=1), solver=solver)
        out[solver.name] = d.run().state.x
    z = m.idx("z")
    assert abs(out["ros2"][z] - out["idas"][z]) < 5e-4   # 0.5 mm: the O(h^2) error of 4 ms steps over 5.6 m
    nodes = [m.idx(f"T_{node}[{i}]") for node in ("oil", "wall", "surface") for i in range(m.n)]
    assert np.max(np.abs(out["ros2"][nodes] - out["idas"][nodes])) < 1e-3


def _estimate(model, road, dt, distance_m=200.0):
    d = Drive(model, road, DriveSettings(distance_m=distance_m, speed=SpeedProfile.constant(20 / 3.6),
                                         error_check_every=1, samples_per_block=2), solver=solvers.Ros2(dt))
    res = d.run()
    assert res.solver_error["solver_error_windows"] >= 3
    return res.solver_error


def test_the_error_estimate_flags_compressible_chambers_at_4_ms_and_advises_2_ms():
    """A step known to be too large: yin2023 with compressible chambers (valve.oil_model: compressible, seed 001
    eq. 5-7 as written) at 4 ms, where the stages overshoot the 0.2-2 ms chamber relaxation. Either the step-doubling
    estimate (vehicle.numerics.error_estimate) exceeds the default tolerance and advises 2 ms, or the stages
    overshoot so far that the drive stops saying to take a smaller step; and at the advised 2 ms the drive runs.
    Which of the two happens is decided by rounding: with the seed's silicone fluid the drive went non-finite within
    its first second until the step's exp/log changed by an ulp (issue 26); it now runs with an estimate 6.7x the
    tolerance, the half-step run's 50x (outside the convergent range; 580x was measured with the mineral oil)."""
    m = VehicleModel(_yin_vehicle("compressible"))
    assert not any(st.quasi_steady for st in m.struts)
    tol = DriveSettings(distance_m=1.0, speed=SpeedProfile.constant(1.0)).tolerance
    road = build_road(RoadSpec(iso_class="C", length=260.0, seed=0))
    try:
        coarse = _estimate(m, road, 0.004, 40.0)                # 3 windows of 2 s
    except SimulationError as exc:
        assert "smaller solver.dt (e.g. 2 ms)" in str(exc)
    else:
        assert coarse["solver_error_estimate"] > 3 * tol
        assert coarse["solver_advice"].endswith("reduce solver.dt to 2 ms") or "reduce solver.dt to 2 ms " in \
            coarse["solver_advice"]
    fine = _estimate(m, road, 0.002, 40.0)                # the advice holds: the drive runs
    assert np.isfinite(fine["solver_error_estimate"])


def test_the_error_estimate_passes_the_default_strut_at_4_ms_and_falls_with_the_order():
    """The apc strut at the default 4 ms is within the default tolerance, and the step-doubling estimate falls
    when the step halves. (4.0x measured before the thermal network; 1.3x after: a window's heat error is at the
    level of its noise for this strut, of varying sign from the non-smooth seal friction and valves.)"""
    m = VehicleModel(load_vehicle("apc_8x8"))
    road = build_road(RoadSpec(iso_class="D", length=360.0, seed=3))
    e4 = _estimate(m, road, 0.004, 300.0)
    e2 = _estimate(m, road, 0.002, 300.0)
    assert e4["solver_error_estimate"] < e4["solver_tolerance"]
    assert "meets the tolerance" in e4["solver_advice"]
    assert 1.0 < e4["solver_error_estimate"] / e2["solver_error_estimate"]
    # the worst pointwise deflection falls too, more slowly (1.3-2.2x measured: the seal friction's stick-slip is not
    # smooth, which lowers the observed order of a pointwise error; the heat is an integral and keeps order 2)
    assert 1.0 < e4["solver_error_deflection_m"] / e2["solver_error_deflection_m"]
    assert 0 < e4["solver_error_deflection_m"] < 1e-3          # heights: well below a millimetre


def test_the_error_estimate_costs_a_few_percent_at_the_defaults():
    """At the defaults (every 10th block of 10 samples) the extra half-step integrations cost about 2 % of the
    integration (2 / (samples_per_block * every)); measured by wall time, so only bounded loosely."""
    d = make_drive(distance_m=700.0)
    res = d.run()
    err = res.solver_error
    assert err["solver_error_windows"] >= 1
    # 700 m = 12 blocks, 2 checked (blocks 1 and 11): 2 * 2 / (12 * 10) = 3.3 % of the steps, plus the inputs of the
    # half-step windows; the 2 % holds for long drives
    assert err["solver_error_cost_pct"] < 15.0


def test_indicator_quadratures_take_the_rectangle_rule_and_the_physics_is_unchanged():
    """The current engine integrates the quadratures of indicator functions (time lifted off, on an end stop, above
    each travel-bin edge) by the rectangle rule on the first stage, y + h g(y): every other state of a step is
    bit-identical to the trapezoid step's, and those states are exactly the indicator quadratures."""
    import casadi as ca

    drive = make_drive(distance_m=50.0)
    m = drive.model
    names = [m.layout.names[k] for k in m.indicator_quadrature_indices()]
    expected = {f"I_{q}[{i}]" for i in range(m.n) for q in ("lift", "stop")} | \
        {f"I_above{k}[{i}]" for i in range(m.n) for k in range(1, m.travel_bin_edges().shape[1] - 1)}
    assert set(names) == expected and len(names) == len(expected)
    rng = np.random.default_rng(2)
    x = drive.initial_state().x.copy()
    for i in range(m.n):
        x[m.idx(f"dw[{i}]")] = rng.normal(0.0, 0.3)
    U = drive.inputs(np.array([3.0, 3.004]))
    solver = solvers.Ros2(0.004, compile=False)

    xs, mem, u0, u1 = solver.step_symbols(m)
    p = ca.SX.sym("p", m.np)

    def evaluated(x_next):
        return np.asarray(ca.Function("step", [xs, mem, u0, u1, p], [x_next])(x, np.zeros(m.n_memory), U[:, 0],
                                                                              U[:, 1], drive.p)).ravel()
    rect = evaluated(solver.stages(m, xs, mem, u0, u1, p)[0])
    trap = evaluated(solvers.ros2_stages(m, 0.004, xs, mem, u0, u1, p).x_next)     # every state by the method
    ind = np.array(m.indicator_quadrature_indices())
    other = np.setdiff1d(np.arange(m.nx), ind)
    np.testing.assert_array_equal(rect[other], trap[other])
    f0 = np.asarray(m.ode_function(x, np.zeros(m.n_memory), U[:, 0], drive.p)[0]).ravel()
    np.testing.assert_allclose(rect[ind], x[ind] + 0.004 * f0[ind], rtol=0, atol=1e-15)
