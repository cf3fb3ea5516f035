"""Calibration of the one heat-transfer parameter against a measured mean temperature rise.

Seed 000 §4.4 gives one number for the heat model: the mean rise of the strut surface
temperature over all struts after the 106 km drive (about 54 K, REFERENCE §4), read by pyrometer.
We calibrate exactly one parameter against it, by default `heat.air_speed_ratio` (the fraction of
the vehicle speed that reaches the strut in the wheel bay, which sets the forced convection), and
compare it with the rise of the heat network's outer SURFACE node (vehicle.physics.thermal;
`drive.T_index`), not the oil inside. Everything per axle stays a prediction.

    hpsim calibrate scenarios/mileage_106km.yaml --target-rise 54K

Each evaluation is a full run of the scenario. The first guess uses the steady-state
relation dT ~ P / (h A): the total coefficient needed is h_now * rise_now / target, and the
forced-convection part is inverted for the air speed. Then it steps on a least-squares line through the
evaluations (rise against the log of the ratio), not secants: below a few millikelvin the rise is noise
(seal stick-slip; a change of the ratio by 1e-12 moves the 1.5 km rise by millikelvins, docs/validation.md
"Calibration"). At the first point near the answer the noise is measured (vehicle.numerics.noisy_root:
runs at rounding-level changes of the ratio) and a tolerance below it is refused (exit 2, the floor in
the message): such a tolerance could only be met by luck.
"""
from __future__ import annotations

import math
import time

import numpy as np

from hpsim.errors import UserInputError

from vehicle.numerics import noisy_root
from vehicle.physics import thermal
from vehicle.scenario.schema import apply_overrides, read_scenario, prepare
from vehicle.engines.build import build_engine


def _run(src, parameter: str, value: float):
    data = apply_overrides(src.data, {f"vehicle.overrides.{parameter}": value})
    prepared = prepare(type(src)(**{**src.__dict__, "data": data}))
    model, drive = build_engine(prepared)
    T0 = np.asarray(drive.initial_equilibrium().temperatures_K)
    res = drive.run()
    T1 = res.state.x[drive.T_index]          # the surface node: what the pyrometer read
    return float(np.mean(T1 - T0)), prepared, drive


# the calibrated ratio stays within these: below, forced convection is nil; above 2 the air at the
# strut would be faster than twice the vehicle speed (vehicle.physics.params.Heat allows [0, 2])
RATIO_BOUNDS = (1e-3, 2.0)
# "near the answer", where the noise is measured: a rise within this fraction of the target (or within the
# tolerance). The noise belongs to the drive at the calibrated value; 2 % is one or two regression steps away
NEAR_FRACTION = 0.02


def calibrate_heat(scenario_path, target_rise_K: float, parameter: str = "heat.air_speed_ratio",
                   tol_K: float = 0.1, max_runs: int = 8, log=print) -> dict:
    if parameter != "heat.air_speed_ratio":
        raise UserInputError("--parameter: only heat.air_speed_ratio is supported")
    if not tol_K > 0:
        raise UserInputError(f"--tolerance: must be > 0 K, got {tol_K:g} K")
    if not target_rise_K > 0:
        raise UserInputError(f"--target-rise: must be > 0 K, got {target_rise_K:g} K")
    src = read_scenario(scenario_path)
    heat = prepare(src).vehicle.heat
    return _iterate(src, parameter, heat, target_rise_K, tol_K, max_runs, scenario_path, log)


def _steady_state_guess(heat, drive, rise, target_rise_K) -> float:
    """The second point, from physics: the steady state scales with 1/h; the forced-convection part of the h
    needed is inverted for the air speed ratio."""
    v_mean = float(np.mean(drive.settings.speed.speeds_m_per_s))
    h_now = float(thermal.convection_coefficient(heat, v_mean))
    h_need = h_now * rise / target_rise_K
    forced_need = max(h_need - heat.natural_convection - 0.3 * heat.air_conductivity / heat.diameter, 0.1)

    def forced(ratio):
        return float(thermal.churchill_bernstein_h(ratio * v_mean, heat.diameter, heat.air_conductivity,
                                                   heat.air_kinematic_viscosity, heat.air_prandtl))

    lo, hi = 1e-4, 5.0
    for _ in range(60):   # bisection on the monotone forced-convection law
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if forced(mid) < forced_need else (lo, mid)
    return math.sqrt(lo * hi)


def _iterate(src, parameter, heat, target_rise_K, tol_K, max_runs, scenario_path, log) -> dict:
    """Run 1 at the shipped value, run 2 at the steady-state guess, then steps on a regression of the
    evaluations (vehicle.numerics.noisy_root). At the first point near the answer (NEAR_FRACTION) the rise's
    noise is measured and a tolerance below it refused; no point is accepted before that."""
    lo_bound, hi_bound = RATIO_BOUNDS
    t0 = time.perf_counter()
    history, probes, floor, slope = [], [], None, None
    value = heat.air_speed_ratio
    for k in range(1, max_runs + 1):
        rise, _, drive = _run(src, parameter, value)
        history.append((value, rise))
        log(f"run {k}: {parameter} = {value:.5g} -> mean rise {rise:.4f} K")
        if floor is None and abs(rise - target_rise_K) < max(tol_K, NEAR_FRACTION * target_rise_K):
            floor, probes = _check_noise(src, parameter, value, rise, tol_K, log)
            history.extend((value, r) for _, r in probes)       # at the nominal value: the regression averages them
        estimate = noisy_root.mean_at(history, value)
        if floor is not None and abs(estimate - target_rise_K) < tol_K:
            return _result(parameter, value, target_rise_K, estimate, history, t0, scenario_path, floor, len(probes))
        fit = noisy_root.regression_root(history, target_rise_K)
        if k == 1:
            value_next = _steady_state_guess(heat, drive, rise, target_rise_K)
        elif fit is not None and fit[1] < 0:          # the rise falls with the ratio: a line that rises is noise
            value_next, slope = fit
        elif slope is not None:
            value_next = math.exp(math.log(value) + (target_rise_K - estimate) / slope)
        else:
            value_next = value * 0.8
        v2, r2 = value, estimate
        value = min(max(value_next, lo_bound), hi_bound)
        if value == v2 and v2 in RATIO_BOUNDS:
            # the next step would run the bound again: no ratio in range gives the target
            raise UserInputError(
                f"--target-rise: {target_rise_K:g} K is not reachable: {parameter} = {v2:g} (its bound, allowed "
                f"[{lo_bound:g}, {hi_bound:g}]) gives a mean rise of {r2:.4g} K")
    raise UserInputError(f"calibration did not reach {target_rise_K} K +- {tol_K} K in {max_runs} runs (noise floor "
                         f"{'not measured' if floor is None else f'{floor:.2g} K'})")


def _check_noise(src, parameter, value, rise, tol_K, log):
    """(floor, probes): the noise of the mean rise at `value`; UserInputError when tol_K is below it."""
    floor, probes = noisy_root.noise_floor(lambda v: _run(src, parameter, v)[0], value, rise, tol_K, log=log)
    log(f"noise floor of the mean rise: {floor:.2g} K ({noisy_root.FLOOR_SIGMAS:g} standard deviations of "
        f"{len(probes) + 1} runs at {parameter} = {value:.5g} changed by up to {(len(probes) + 1) // 2}e-12)")
    if tol_K < floor:
        raise UserInputError(
            f"--tolerance: {tol_K:.3g} K is below the noise floor of the mean rise, {floor:.2g} K "
            f"({noisy_root.FLOOR_SIGMAS:g} standard deviations of {len(probes) + 1} runs whose {parameter} differs "
            f"by rounding-level amounts, 1e-12 relative: seal stick-slip makes the drive's outcome noisy at this "
            f"level); ask for at least {floor:.2g} K")
    return floor, probes


def _result(parameter, value, target_rise_K, rise, history, t0, scenario_path, floor=None, n_probes=0) -> dict:
    return {"parameter": parameter, "value": value, "target_rise_K": target_rise_K, "achieved_rise_K": rise,
            "noise_floor_K": floor, "noise_probe_runs": n_probes,
            "runs": [{"value": v, "mean_rise_K": r} for v, r in history],
            "wall_s": time.perf_counter() - t0, "scenario": str(scenario_path)}
