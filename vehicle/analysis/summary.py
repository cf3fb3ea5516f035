"""Per-axle summaries of drive results (what `hpsim report` and `hpsim compare` print), from any
results (a file through vehicle.results.reader.open_results, or a MemorySink).

Per axle, values are the mean of the left and right station (the dissipated energy: their sum, so that the
axles add up to the vehicle's total):
  T_start_C / T_end_C    strut temperature before / after the drive: the outer surface (what the
                         seed-000 pyrometer read; the heat network's surface node)
  T_surface_end_C, T_oil_end_C, T_gas_end_C   the surface (= T_end_C) and oil temperatures at the end,
                         the gas temperature's mean over the last statistics interval (it swings by
                         kelvins with every bump); None in files written before the heat network
  dh_mm                  hull height change at the axle, after-drive equilibrium minus
                         before-drive equilibrium (both standing on flat ground)
  N_before_daN / N_after_daN, dN_pct   wheel load in those two equilibria and its change
  energy_dissipated_MJ   valve + friction + gas heat + end-stop energy of the axle's two struts
  pump_oil_volume_m3     oil volume the levelling pump moved into and out of the axle's two struts (int |q| dt,
                         vehicle.physics.compensation), oil_added_m3 the net volume added (int q dt, negative when
                         drained); 0 without compensation, None in files written before the pump's volume
  N_charged_daN, dN_charged_pct   the charged (set-up) wheel load and the after-drive change
                         against it
  dN_band_pct, dh_band_mm  [low, high] of dN_pct and dh_mm that two weighings with seal friction
                         can give (vehicle.physics.weighing; None without /equilibrium/*_band)
Whole vehicle: load_shift_pct = 100 * sum_axles |N_after - N_before| / sum_axles N_before
(the load redistribution in one number), load_shift_vs_charged_pct (the same against the
charged loads; equal to load_shift_pct when the struts start at the charging temperature),
mean_temperature_rise_K, pump_oil_volume_m3 and oil_added_m3 (the axles' sums).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from hpsim.errors import UserInputError

from vehicle.physics.outputs import VARIABLES, Var
from vehicle.physics.weighing import difference_bands
from vehicle.results import validity
from vehicle.results.reader import ResultsView, check_files, open_results  # noqa: F401  (re-exported)
from vehicle.analysis import ride_metrics
from vehicle.analysis.internal_drift import damping_over_drive

DISSIPATION = ("valve", "friction", "gas", "end_stop")


def _axle_mean(a) -> np.ndarray:
    a = np.asarray(a, float)
    return 0.5 * (a[0::2] + a[1::2])


def _axle_sum(a) -> np.ndarray:
    a = np.asarray(a, float)
    return a[0::2] + a[1::2]


def _last_row(r: ResultsView, name: str):
    a = r.series(name)
    return None if a is None or len(a) == 0 else a[-1]


def dissipated_energy_J(r: ResultsView) -> np.ndarray | None:
    """Per station: valve + friction + gas + end-stop energy at the end (or the last sample)."""
    total = None
    final = r.summary_values()
    for e in DISSIPATION:
        v = final.get(f"energy_{e}")
        if v is None:
            v = _last_row(r, f"energy_{e}")
        if v is None:
            return None
        total = v if total is None else total + v
    return total


def final_station_value(r: ResultsView, name: str):
    """Per station: a variable's value at the drive's end (/summary, else its last stored sample); None when the
    file has neither."""
    v = r.summary_values().get(name)
    return v if v is not None else _last_row(r, name)


def equilibrium_temperature(eq: dict):
    """The standing strut temperature of an equilibrium group (oil_temperature; strut_temperature in files
    written before the heat network)."""
    return eq["oil_temperature"] if "oil_temperature" in eq else eq["strut_temperature"]


def report(path: str | Path, check: bool = True) -> dict:
    """The report of a results file. check=False: the file was just written by this process (`hpsim run`), so the
    child-process read check for damaged files (`open_results`) is skipped."""
    with open_results(path, check=check) as r:
        return report_from(r, str(path))


def report_from(r: ResultsView, name: str) -> dict:
    sc = r.scenario_attrs
    summ = r.summary_attrs()
    status = r.status()
    axles = r.axles
    before = r.equilibrium("before")
    after = r.equilibrium("after")
    if before is None:
        raise UserInputError(f"{name}: no before-drive equilibrium (the run stopped before it started)")
    charged = r.equilibrium("charged")
    Nc = _axle_mean(charged["wheel_load"]) if charged is not None else np.full(len(axles), np.nan)
    # before the drive every node of a strut is at the standing temperature (files before the heat
    # network called it strut_temperature)
    T0 = _axle_mean(equilibrium_temperature(before)) - 273.15
    N0 = _axle_mean(before["wheel_load"])
    h0 = np.asarray(before["axle_height_change"], float)
    T_end = _end_temperatures(r, after, len(axles))
    T1 = T_end["surface"]
    N1, h1 = ((_axle_mean(after["wheel_load"]), np.asarray(after["axle_height_change"], float)) if after is not None
              else (np.full(len(axles), np.nan),) * 2)       # a run stopped before its after-drive weighing
    per_axle, totals = _station_totals(r, len(axles))
    bands = weighing_difference_bands({k: r.equilibrium(k) for k in ("before_band", "after_band")}, len(axles))
    n_done = r.counts()[0]
    dist_km, sim_s = _driven(r, summ, status)
    wall = float(summ.get("wall_s", 0.0))
    num = _finite_or_none
    rows = []
    for k, a in enumerate(axles):
        rows.append({"axle": k + 1, "T_start_C": num(T0[k]), "T_end_C": num(T1[k]),
                     "T_surface_end_C": num(T_end["surface"][k]), "T_oil_end_C": num(T_end["oil"][k]),
                     "T_gas_end_C": num(T_end["gas"][k]), "dh_mm": num((h1[k] - h0[k]) * 1e3),
                     "N_before_daN": num(N0[k] / 10.0), "N_after_daN": num(N1[k] / 10.0),
                     "dN_pct": num(100.0 * (N1[k] - N0[k]) / N0[k]),
                     "energy_dissipated_MJ": num(per_axle["energy_dissipated_MJ"][k]),
                     "N_charged_daN": num(Nc[k] / 10.0), "dN_charged_pct": num(100.0 * (N1[k] - Nc[k]) / Nc[k]),
                     "dN_band_pct": bands["dN_band_pct"][k], "dh_band_mm": bands["dh_band_mm"][k],
                     "pump_oil_volume_m3": num(per_axle["pump_oil_volume_m3"][k]),
                     "oil_added_m3": num(per_axle["oil_added_m3"][k])})
    shift = 100.0 * np.sum(np.abs(N1 - N0)) / np.sum(N0)
    shift_charged = 100.0 * np.sum(np.abs(N1 - Nc)) / np.sum(Nc)
    compensation, ambient_C = _compensation_and_ambient(sc, name)
    out = {"file": name, "status": status, "complete": status == "complete",
           "distance_km": dist_km, "planned_distance_km": float(sc["distance_m"]) / 1e3,
           "simulated_s": sim_s, "wall_s": wall, "n_samples": n_done,
           "axles": rows,
           "load_shift_pct": num(shift),
           "max_abs_dN_pct": num(np.max(np.abs(100.0 * (N1 - N0) / N0))),
           "load_shift_vs_charged_pct": num(shift_charged),
           "mean_temperature_rise_K": num(np.mean(T1 - T0)),
           **totals,
           "compensation": compensation,
           "ambient_C": ambient_C,
           "hpsim_version": str(sc.get("hpsim_version", ""))}
    out.update(solver_mode_summary(r, summ, len(axles)))
    out.update(_solver_notes(summ))
    out.update(_checks(r))
    return out


def _station_totals(r: ResultsView, n_axles: int) -> tuple[dict, dict]:
    """What the struts accumulated over the drive, per axle (both struts summed) and for the vehicle: dissipated
    energy [MJ], oil moved by the levelling pump and oil added [m^3]; NaN per axle and None in total where the file
    does not hold it."""
    per_station = {"energy_dissipated_MJ": dissipated_energy_J(r),
                   "pump_oil_volume_m3": final_station_value(r, "pump_oil_volume"),
                   "oil_added_m3": final_station_value(r, "oil_added_volume")}
    scale = {"energy_dissipated_MJ": 1e-6, "pump_oil_volume_m3": 1.0, "oil_added_m3": 1.0}
    per_axle = {k: _axle_sum(v) * scale[k] if v is not None else np.full(n_axles, np.nan)
                for k, v in per_station.items()}
    totals = {k: _finite_or_none(np.sum(v) * scale[k]) if v is not None else None for k, v in per_station.items()}
    return per_axle, totals


def _finite_or_none(v) -> float | None:
    v = float(v)
    return None if not np.isfinite(v) else v


def _end_temperatures(r: ResultsView, after: dict | None, n_axles: int) -> dict:
    """Per axle at the drive's end [degC]: "surface" and "oil" (the summary's values, else the last statistics
    row's), "gas" (its mean over the last statistics interval: the gas swings by kelvins with every bump)."""
    final = r.summary_values()
    T_end = {}
    for key, var in (("surface", "strut_temperature"), ("oil", "oil_temperature")):
        v = final.get(var) if after is not None else None
        if v is None:
            v = _last_row(r, var)
        T_end[key] = _axle_mean(v) - 273.15 if v is not None else np.full(n_axles, np.nan)
    g = r.stats_series("mean_gas_temperature")
    T_end["gas"] = _axle_mean(g[-1]) - 273.15 if g is not None and len(g) else np.full(n_axles, np.nan)
    if after is not None and final.get("strut_temperature") is None and "strut_temperature" in after:
        T_end["surface"] = _axle_mean(after["strut_temperature"]) - 273.15     # a file without /summary values
    return T_end


def _driven(r: ResultsView, summ: dict, status: str) -> tuple[float, float]:
    """(km, s) driven: the summary's of a complete run, else the last checkpoint's."""
    if "distance_km" in summ and status == "complete":
        return float(summ["distance_km"]), float(summ["simulated_s"])
    st = r.state()
    return (st["s_m"] / 1e3, st["t_s"]) if st is not None else (0.0, 0.0)


def _compensation_and_ambient(sc: dict, name: str) -> tuple[bool, float]:
    """(compensation enabled, ambient temperature [degC]) from the stored resolved scenario."""
    try:
        S = json.loads(sc["resolved_json"])["scenario"]
        return bool(S["compensation"]["enabled"]), S["ambient_temperature"] - 273.15
    except (ValueError, KeyError, TypeError):
        raise UserInputError(f"{name}: damaged results file: /scenario attribute 'resolved_json' is not the "
                             "resolved scenario") from None


def _solver_notes(summ: dict) -> dict:
    """The solver's error estimate, tolerance and advice, and the run's error, as the summary holds them."""
    out = {}
    for k in ("solver_error_estimate", "solver_tolerance", "solver_advice"):
        if k in summ:
            out[k] = _finite_or_none(summ[k]) if k != "solver_advice" else str(summ[k])
    if "error" in summ:
        out["error"] = str(summ["error"])
    return out


def _checks(r: ResultsView) -> dict:
    """Ride metrics, validity warnings and (integrated struts with internal maps only) the damping's drift."""
    out = {"ride": ride_metrics.summarise(r), "warnings": validity.check(r)}
    drift = damping_over_drive(r)
    if drift is not None:
        out["damping_over_drive"] = drift
    return out


def solver_mode_summary(r: ResultsView, summ: dict, n_axles: int) -> dict:
    """`solver_mode` (full, multiscale or time_parallel) and, for a time-parallel run, its segments and the
    correction's estimated error per axle; for a multiscale run (vehicle.engines.multiscale), its window layout
    and a-posteriori error estimate: per axle, the error of T_end [K] and of dN [pp] (estimated_error_sigmas
    standard deviations of the road-sampling error)."""
    mode = str(summ.get("solver_mode", "full"))
    out = {"solver_mode": mode}
    if mode not in ("multiscale", "time_parallel"):
        return out
    values = r.summary_values() or {}

    def per_axle(name):
        v = values.get(name)
        return [None] * n_axles if v is None else [float(x) for x in np.asarray(v, float)]

    if mode == "time_parallel":
        # vehicle.engines.time_parallel: the estimated error of the slow-state correction (not a sampling interval)
        out["estimated_error"] = {
            "T_end_K": per_axle("estimated_error_axle_temperature"),
            "dN_pct": per_axle("estimated_error_load_change"),
            "segments": int(summ.get("time_parallel_segments", 0)),
            "lanes": int(summ.get("time_parallel_lanes", 1)),      # segments per process, in lockstep
            "coarse_mismatch_K": float(summ.get("time_parallel_coarse_mismatch_K", np.nan))}
        return out

    out["estimated_error"] = {
        "sigmas": float(summ.get("estimated_error_sigmas", 2.0)),
        "T_end_K": per_axle("estimated_error_axle_temperature"),
        "dN_pct": per_axle("estimated_error_load_change"),
        "windows": int(summ.get("multiscale_windows", 0)),
        "window_m": float(summ.get("multiscale_window_m", np.nan)),
        "spacing_m": float(summ.get("multiscale_spacing_m", np.nan)),
        "covered_km": float(summ.get("multiscale_covered_km", np.nan)),
        "paired": int(summ.get("multiscale_paired_windows", 0)),     # from a predicted start, beside the one before
        "control_variate": bool(summ.get("multiscale_control_variate", False)),
        "proxy": str(summ.get("multiscale_proxy", "road_rate" if summ.get("multiscale_control_variate") else "none"))}
    return out


def weighing_difference_bands(eq, n_axles: int) -> dict:
    """Per axle [low, high] of dN [%] and dh [mm] from /equilibrium/before_band and /after_band
    (vehicle.physics.weighing.band_datasets; two independent weighings: low = after_low -
    before_high, see difference_bands), or None per axle when the file has no bands."""
    none = {"dN_band_pct": [None] * n_axles, "dh_band_mm": [None] * n_axles}
    if not eq or eq.get("before_band") is None or eq.get("after_band") is None:
        return none
    # the reader names variables as the file does (CF names): back to the drive's keys
    by_name = {v.name: k for k, v in VARIABLES.items() if isinstance(v, Var)}

    def drive_keys(group):
        return {by_name.get(name, name): value for name, value in group.items()}

    try:
        d = difference_bands(drive_keys(eq["before_band"]), drive_keys(eq["after_band"]))
    except KeyError:
        return none
    return {k: [[float(x) if np.isfinite(x) else None for x in row] for row in v] for k, v in d.items()}


# --- compare -------------------------------------------------------------------------------------
def axle_value(run: dict, k: int, key: str):
    """Run `run`'s value of `key` on axle k + 1 (a compare() run), None when the run's vehicle has fewer axles."""
    return run["axles"][k].get(key) if k < len(run["axles"]) else None


def compare(paths, check: bool = True) -> dict:
    """The runs side by side; `n_axles` is the most axles of any run (vehicles of different axle counts are compared
    axle by axle, `axle_value` is None on an axle a vehicle does not have). check=False: the caller read or wrote
    every file whole already (a study's own cases), so the child-process read check (`check_files`) is skipped."""
    if check:
        check_files(paths)                # all read whole in one child process, then each opened
    reps = [report(p, check=False) for p in paths]
    return {"n_axles": max(len(r["axles"]) for r in reps), "runs": [{"file": r["file"], "status": r["status"], "distance_km": r["distance_km"],
                      "compensation": r["compensation"], "load_shift_pct": r["load_shift_pct"],
                      "load_shift_vs_charged_pct": r["load_shift_vs_charged_pct"],
                      "mean_temperature_rise_K": r["mean_temperature_rise_K"], "axles": r["axles"],
                      "ride": r.get("ride", {}), "warnings": r.get("warnings", []),
                      "hpsim_version": r.get("hpsim_version", "")} for r in reps]}
