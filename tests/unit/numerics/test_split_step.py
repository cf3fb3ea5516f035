"""The ROS2 step split around the struts (vehicle.numerics.split_step, issue 26 "lanes across struts").

The split step is the whole step's arithmetic in another grouping: one step from the same state agrees with the
whole step (`Ros2.step_functions`) to rounding; its compiled forms (a case's stations in one vector, station after
station, any lane count, GCC or Clang) agree with each other bit for bit; a vehicle whose stations do not share
one strut kernel keeps the whole step.
"""
from __future__ import annotations

import shutil

import numpy as np
import pytest

from terrain import RoadSpec, build_road
from vehicle.engines.full import Drive
from vehicle.numerics import split_step
from vehicle.numerics.lanes import LaneStepper
from vehicle.numerics.solvers import Ros2
from vehicle.physics.model import VehicleModel
from vehicle.physics.params import load_vehicle
from vehicle.scenario.settings import DriveSettings
from vehicle.scenario.speed import SpeedProfile

DT = 0.004
# one step from the same state, split against whole: rounding only. Measured largest relative difference over the
# 60 states: 4.7e-14 (apc_8x8), 3.6e-15 (truck_6x6); values below 1e-6 of their row's scale compared on that scale
ONE_STEP_RTOL = 1e-12


def _model(name: str, **overrides) -> VehicleModel:
    return VehicleModel(load_vehicle(name, overrides or None))


def _drive_states(model: VehicleModel, steps: int):
    """(states z (steps + 1, nz), inputs U (steps + 1, nu), parameters p) of a drive at 20 km/h over ISO class D:
    the whole step's trajectory (z includes the valves' warm starts)."""
    road = build_road(RoadSpec(iso_class="D", length=200.0, seed=3))
    s = DriveSettings(distance_m=100.0, speed=SpeedProfile.constant(20 / 3.6), error_check_every=0)
    drive = Drive(model, road, s, solver=Ros2(DT))
    st = drive.initial_state()
    U = np.asarray(drive.inputs(DT * np.arange(steps + 1)), float)
    U = U.T if U.shape[0] == model.nu else U
    p = np.asarray(drive.p, float)
    whole = LaneStepper(Ros2(DT, strut_lanes=False), model, 1, batched=True)
    z0 = np.concatenate([st.x, drive.solver.memory])
    Z = whole.advance(z0[:, None], np.ascontiguousarray(U[:, :, None]), p[:, None], 1, steps)[:, :, 0]
    return np.vstack([z0, Z]), U, p


def _one_step_difference(model: VehicleModel, steps: int) -> float:
    Z, U, p = _drive_states(model, steps)
    split = LaneStepper(Ros2(DT), model, 1, batched=True)
    whole = LaneStepper(Ros2(DT, strut_lanes=False), model, 1, batched=True)
    pw_s, pw_w = split.parametric(p[:, None]), whole.parametric(p[:, None])
    worst = 0.0
    scale = np.maximum(np.max(np.abs(Z), axis=0), 1e-300)
    for k in range(steps):
        a = split.step(Z[k][:, None], U[k][:, None], U[k + 1][:, None], pw_s)[:, 0]
        b = whole.step(Z[k][:, None], U[k][:, None], U[k + 1][:, None], pw_w)[:, 0]
        assert np.all(np.isfinite(a))
        worst = max(worst, float(np.max(np.abs(a - b) / np.maximum(np.abs(b), 1e-6 * scale))))
    return worst


@pytest.mark.parametrize("vehicle, front_strut", [
    ("apc_8x8", None),
    # six stations (the kernel's vector padded to eight), the front axle's strut with other parameters
    ("truck_6x6", {"friction.F0_rebound": "1200 N", "gas.thermal_time_constant": "14 s"}),
])
def test_one_split_step_equals_the_whole_step_to_rounding(vehicle, front_strut):
    model = _with_front_strut(vehicle, front_strut)
    split = split_step.build(Ros2(DT), model)
    assert split is not None and split.stations == model.n and split.padded == 8
    assert _one_step_difference(model, 60) < ONE_STEP_RTOL


def _with_front_strut(vehicle: str, strut_overrides: dict | None) -> VehicleModel:
    """The vehicle with its front axle's strut file overridden by `strut_overrides` (None: as shipped)."""
    if not strut_overrides:
        return _model(vehicle)
    axles = [a.model_dump() for a in load_vehicle(vehicle).axles]
    axles[0]["strut_overrides"] = strut_overrides
    return _model(vehicle, axles=axles)


def test_the_stations_parameters_enter_the_kernel_as_lanes():
    """A front strut with another friction: one kernel for all stations, its parameters differing per station (the
    kernel's parameter rows of the front stations differ from the others' where the friction enters)."""
    model = _with_front_strut("truck_6x6", {"friction.F0_rebound": "1200 N"})
    split = split_step.build(Ros2(DT), model)
    p = np.asarray(model.run_parameters(np.full(model.n, 1.0), False), float)
    pw = np.asarray(split.parametric(p), float).ravel()
    k1 = pw[split.offsets["k1"]:split.offsets["k2"]].reshape(-1, split.padded)
    assert np.array_equal(k1[:, 0], k1[:, 1]) and np.array_equal(k1[:, 2], k1[:, 5])
    assert not np.array_equal(k1[:, 0], k1[:, 2])
    assert np.array_equal(k1[:, 6], k1[:, 0]) and np.array_equal(k1[:, 7], k1[:, 0])     # padding: station 0


def test_compiled_forms_of_the_split_step_agree_bit_for_bit():
    """The scalar engine's block (a case's stations in one vector, batched calls), the same built for AVX2 and SSE2
    (the stations in two and four vectors), the same with the kernel two stations per call over scalar lanes (what
    a compiler without GCC's vector types builds), the ensemble's lanes (4 and 8 cases of
    different parameters) and, where installed, Clang: the same bits, lane by lane."""
    model = _model("apc_8x8")
    steps, K = 200, 10
    Z, U, p = _drive_states(model, steps)
    rng = np.random.default_rng(1)
    theta = np.arange(p.size) >= model.n_run
    P = p[:, None] * (1.0 + 0.02 * rng.random((p.size, 8)) * theta[:, None])
    Ul = np.ascontiguousarray(np.repeat(U[:, :, None], 8, 2))

    def run(stepper, lanes, first=0):
        return stepper.advance(np.repeat(Z[0][:, None], lanes, 1), np.ascontiguousarray(Ul[:, :, first:first + lanes]),
                               np.ascontiguousarray(P[:, first:first + lanes]), K, steps // K)

    scalar = LaneStepper(Ros2(DT), model, 1, batched=True)
    one = [run(scalar, 1, lane)[:, :, 0] for lane in range(8)]
    assert all(np.all(np.isfinite(z)) for z in one)
    assert not np.array_equal(one[0], one[1])
    split = Ros2(DT).split_step_functions(model)
    stationwise = LaneStepper.from_functions(split, split.parametric, 1, "hpsim_test_split_stationwise", batch=8,
                                             flags=("-DHPSIM_KERNEL_STATIONWISE",))
    assert "kernel_1_group(" in stationwise.source and "STATIONS(kernel_1" in stationwise.source
    for lane in range(2):
        assert np.array_equal(run(stationwise, 1, lane)[:, :, 0], one[lane]), lane
    for isa in ("avx2", "sse2"):           # the stations in two vectors of 4, four of 2 (AVX-512: one of 8)
        narrow = LaneStepper(Ros2(DT), model, 1, batched=True, isa=isa)
        assert narrow.source is None or f"#define KW {4 if isa == 'avx2' else 2}" in narrow.source  # None: cached
        for lane in range(2):
            assert np.array_equal(run(narrow, 1, lane)[:, :, 0], one[lane]), (isa, lane)
    for lanes in (4, 8):
        got = run(LaneStepper(Ros2(DT), model, lanes), lanes)
        for lane in range(lanes):
            assert np.array_equal(got[:, :, lane], one[lane]), (lanes, lane)
    if shutil.which("clang"):
        got = run(LaneStepper(Ros2(DT), model, 4, cc="clang"), 4)
        for lane in range(4):
            assert np.array_equal(got[:, :, lane], one[lane]), ("clang", lane)


def test_a_vehicle_without_one_strut_kernel_keeps_the_whole_step():
    """The integrated strut has stiff internal states (an exact Jacobian): no split, the whole step's C."""
    model = _model("light_4x4_integrated")
    assert split_step.build(Ros2(DT), model) is None
    whole = LaneStepper(Ros2(DT), model, 1, batched=True, load=False).spec.build().decode()
    split = LaneStepper(Ros2(DT), _model("apc_8x8"), 1, batched=True, load=False).spec.build().decode()
    # the strut kernel's loads and stores (`lanes.emit_kernel`) are in the split step's C only
    assert "K_STORE(" in split and "K_STORE(" not in whole
