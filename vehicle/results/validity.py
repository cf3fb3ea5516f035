"""Validity warnings of a drive's results: what makes a result suspect, with the strut and the km.

`check(view)` reads a results view (vehicle.results.reader: a file or memory) and returns a list of
warnings, each a dict:

    code       what was found (one of CODES)
    severity   "warning" (the result may be wrong or the hardware out of its rating) or "note"
               (the model extrapolates its data)
    struts     the stations concerned (axle1_left, ...); where: the same as text ("all struts", "axle1")
    km         where it first happened (distance at the end of the first statistics interval that
               shows it, or of the first sample; None for the equilibria)
    value, limit, unit   the worst value and the limit it crossed
    message    one line for a person

A flagged result stays written: the warnings go into the report (`hpsim report`, `run`, `compare`)
and the sweep's summary CSV. Thresholds are in `Thresholds` (defaults documented there); strut
temperature limits come from the strut files (`limits:`, struts.params.Limits) as resolved with
the run.
"""
from __future__ import annotations

import functools
import json
from dataclasses import dataclass

import numpy as np

from struts.oil import viscosity_extrapolation_range
from vehicle.physics import shocks
from vehicle.physics.outputs import variable_name

CODES = ("end_stop_time", "end_stop_energy", "equilibrium_on_stop", "seal_temperature", "oil_temperature",
         "oil_data_range", "tyre_lift_off", "solver_error")


@dataclass(frozen=True)
class Thresholds:
    """When a warning is raised (defaults: engineering judgement, stated so).

    end_stop_time_share     time on an end stop / interval duration: 0.1 %
    end_stop_energy_share   end-stop energy / energy the strut dissipated: 1 %
    lift_off_share          time a tyre is off the ground / interval duration: 1 %
    stop_margin_m           an equilibrium deflection within this of a stroke end rests on the stop
                            (None: the strut's end-stop smoothing width, where its force starts)
    solver_error            relative error estimate of the solver when the summary gives no
                            tolerance: 1e-3
    oil_extrapolation       the oil data's range note: only where the two standard extrapolations of the
                            datasheet viscosities (Walther/ASTM D341 and Andrade, struts.oil) differ by more
                            than this: 10 %, a quarter of the spread the viscosity prior already carries
                            (apc: 10-22 mm^2/s at 40 degC), which the prediction bands cover. For the apc oil:
                            10.8-162 degC, so a drive at 25 degC ambient is not flagged
    """

    end_stop_time_share: float = 1e-3
    end_stop_energy_share: float = 1e-2
    lift_off_share: float = 1e-2
    stop_margin_m: float | None = None
    solver_error: float = 1e-3
    oil_extrapolation: float = 0.1


def check(view, thresholds: Thresholds | None = None) -> list[dict]:
    """All warnings of a results view (vehicle.results.reader.ResultsView)."""
    th = thresholds or Thresholds()
    data = _Data(view)
    out = []
    for fn in (_end_stop_time, _end_stop_energy, _equilibria, _temperatures, _lift_off, _solver):
        out.extend(fn(data, th))
    for w in out:
        w["where"] = struts_text(w["struts"], data.stations)
    return out


def summary_warnings_of(view) -> dict:
    """Check the results of a view (a file being finished, vehicle.results.layout.finish_file): the /summary
    attributes that record its warnings, `warnings` (the short form, as in the sweep CSV) and `warnings_json` (the
    full list); with them, when the series are dense enough, the seats' shock numbers (`seat_shocks_json`)."""
    found = check(view)
    shocks = seat_shocks(view)
    attrs = {"warnings": summary_cell(found), "warnings_json": json.dumps(found)}
    if shocks:
        attrs["seat_shocks_json"] = json.dumps(shocks)
    return attrs


SHOCK_KEYS = ("crest_factor", "mtvv_m_s2", "mtvv_ratio", "dose_z_m_s2", "dose_y_m_s2", "sed_MPa", "daily_sed_MPa",
              "daily_exposure_s", "sed_assessment", "a_w_unreliable")


def seat_shocks(view) -> dict:
    """{seat: the shock numbers under SHOCK_KEYS} of a results view: as the file recorded them after the run
    (/summary attribute seat_shocks_json), else computed from its series (vehicle.physics.shocks; {} when
    they are too sparse)."""
    stored = view.summary_attrs().get("seat_shocks_json")
    if stored:
        return json.loads(str(stored))
    resolved = json.loads(view.scenario_attrs["resolved_json"])
    found = shocks.drive_shocks(view, resolved.get("vehicle", {}).get("seats", []))
    return {name: {k: v[k] for k in SHOCK_KEYS if k in v} for name, v in found.items()}


def format_warnings(warnings: list[dict]) -> list[str]:
    return [f"{w['severity']}: {w['message']}" for w in warnings]


def summary_cell(warnings: list[dict]) -> str:
    """The sweep CSV cell: code(struts@km); ... ('' when none)."""
    return "; ".join(str(w if isinstance(w, ValidityWarning) else ValidityWarning(w)) for w in warnings)


# --- reading ----------------------------------------------------------------------------------------
class _Data:
    """What the checks need from a view, read once."""

    def __init__(self, view):
        self.view = view
        self.stations = list(view.stations)
        resolved = json.loads(view.scenario_attrs["resolved_json"])
        self.struts = [resolved["struts"][f"axle{k // 2 + 1}"] for k in range(len(self.stations))]
        self.km = self._stats("distance_end_m")
        self.duration = self._stats("duration_s")

    def _stats(self, key):
        a = self.view.stats_series(variable_name(key))
        return None if a is None or len(a) == 0 else np.asarray(a, float)

    def stats(self, key):
        return self._stats(key) if self.km is not None else None

    def series(self, key):
        a = self.view.series(variable_name(key))
        return None if a is None or len(a) == 0 else np.asarray(a, float)

    def summary_value(self, key):
        attrs = self.view.summary_attrs()
        if key in attrs:
            return attrs[key]
        return self.view.summary_values().get(variable_name(key))


class ValidityWarning(dict):
    """A warning (a plain dict, JSON-ready) whose str() is its short form: code(where@km)."""

    def __str__(self):
        where = self.get("where") or ",".join(self["struts"])
        at = f"@{self['km']:.3f}km" if self.get("km") is not None else ""
        return f"{self['code']}({where}{at})" if where or at else self["code"]


def _warning(code, severity, struts, km, value, limit, unit, message) -> ValidityWarning:
    return ValidityWarning(code=code, severity=severity, struts=list(struts), km=None if km is None else float(km),
                           value=None if value is None else float(value),
                           limit=None if limit is None else float(limit), unit=unit, message=message)


def _first_km(km, flags) -> float | None:
    """Distance at the end of the first interval (row) where any station is flagged."""
    rows = np.flatnonzero(np.any(flags, axis=1))
    return None if len(rows) == 0 else float(km[rows[0]])


def _names(data, mask) -> list[str]:
    return [s for s, m in zip(data.stations, mask) if m]


def struts_text(names: list[str], stations: list[str]) -> str:
    """'all struts', or axles where both struts are named ('axle1, axle3_left')."""
    if set(names) == set(stations):
        return "all struts"
    out = []
    for k in range(0, len(stations), 2):
        pair = [s for s in stations[k:k + 2] if s in names]
        if len(pair) == 2:
            out.append(pair[0].rsplit("_", 1)[0])
        else:
            out.extend(pair)
    return ", ".join(out)


def _share_check(data, th_share, key, code, what) -> list[dict]:
    """A per-station time share per interval (key: seconds or a share) above a threshold."""
    raw = data.stats(key)
    if raw is None or data.duration is None:
        return []
    share = raw if key.endswith("share") else raw / np.maximum(data.duration, 1e-12)[:, None]
    flags = share > th_share
    if not flags.any():
        return []
    total = (share * data.duration[:, None]).sum(axis=0) / data.duration.sum()
    struts = _names(data, flags.any(axis=0))
    km = _first_km(data.km, flags)
    worst = float(share.max())
    return [_warning(code, "warning", struts, km, 100 * worst, 100 * th_share, "%",
                     f"{what} {100 * worst:.2g} % of an interval (limit {100 * th_share:.2g} %; "
                     f"{100 * total.max():.2g} % over the drive) at {struts_text(struts, data.stations)}, first by {km:.3f} km")]


def _end_stop_time(data, th):
    return _share_check(data, th.end_stop_time_share, "end_stop_time_s", "end_stop_time",
                        "struts on an end stop for")


def _lift_off(data, th):
    return _share_check(data, th.lift_off_share, "lift_off_share", "tyre_lift_off", "tyres off the ground for")


def _end_stop_energy(data, th):
    """End-stop energy as a share of what the strut dissipated, per interval."""
    p_stop = data.stats("power_end_stop_W")
    if p_stop is None:
        return []
    p_all = p_stop.copy()
    for key in ("power_valve_W", "power_friction_W", "power_gas_W"):
        p = data.stats(key)
        if p is not None:
            p_all = p_all + np.abs(p)
    share = p_stop / np.maximum(p_all, 1e-12)
    flags = share > th.end_stop_energy_share
    if not flags.any():
        return []
    E_stop = (p_stop * data.duration[:, None]).sum(axis=0)
    E_all = (p_all * data.duration[:, None]).sum(axis=0)
    struts = _names(data, flags.any(axis=0))
    km = _first_km(data.km, flags)
    worst = float(share.max())
    return [_warning("end_stop_energy", "warning", struts, km, 100 * worst, 100 * th.end_stop_energy_share, "%",
                     f"end stops take {100 * worst:.2g} % of the dissipated energy in an interval (limit "
                     f"{100 * th.end_stop_energy_share:.2g} %; {np.max(E_stop) / 1e3:.3g} kJ, "
                     f"{100 * np.max(E_stop / np.maximum(E_all, 1e-12)):.2g} % over the drive) at "
                     f"{struts_text(struts, data.stations)}, first by {km:.3f} km")]


def _equilibria(data, th):
    out = []
    for which, when in (("before", "before the drive"), ("after", "after the drive")):
        eq = data.view.equilibrium(which)
        if not eq or variable_name("strut_deflections_m") not in eq:
            continue
        x = np.asarray(eq[variable_name("strut_deflections_m")], float)
        rebound, bump = [], []
        for s, xs, st in zip(data.stations, x, data.struts):
            margin = th.stop_margin_m if th.stop_margin_m is not None else st["end_stops"]["smoothing"]
            if xs <= margin:
                rebound.append((s, xs))
            elif xs >= st["geometry"]["stroke"] - margin:
                bump.append((s, xs))
        km = 0.0 if which == "before" else (float(data.km[-1]) if data.km is not None else None)
        for found, stop in ((rebound, "the rebound stop (full extension)"), (bump, "the bump stop (full compression)")):
            if not found:
                continue
            names = [s for s, _ in found]
            lo, hi = min(v for _, v in found), max(v for _, v in found)
            out.append(_warning("equilibrium_on_stop", "warning", names, km, 1e3 * (lo if found is rebound else hi),
                                None, "mm",
                                f"the standing equilibrium {when} rests on {stop} at {struts_text(names, data.stations)} (deflection "
                                f"{1e3 * lo:.1f}..{1e3 * hi:.1f} mm): its heights and wheel loads are set by the stop, "
                                "not by the gas springs"))
    return out


def _temperatures(data, th):
    """Strut temperatures against the seal and oil limits and the oil data's range. Which node of the heat
    network (vehicle.physics.thermal): the seal sits in the bore, wetted by the oil and rubbing on the
    wall, so its limit applies to the hotter of oil and wall; the oil's limits to the oil. Files written
    before the heat network have one strut temperature for all."""
    def read(key):
        T, km_of = data.series(key), data.series("distance_m")
        if T is None or km_of is None:             # time series not stored: the statistics rows
            return data.stats(key), data.km
        return T, km_of / 1e3

    T_surface, km_of = read("strut_temperature_K")
    if T_surface is None:
        return []
    T_oil, _ = read("oil_temperature_K")
    T_wall, _ = read("wall_temperature_K")
    T_oil = T_surface if T_oil is None else T_oil
    T_seal = T_oil if T_wall is None else np.maximum(T_oil, T_wall)
    node_T = {"seal_temperature": (T_seal, "seal (hotter of oil and wall)"), "oil_temperature": (T_oil, "oil"),
              "oil_data_range": (T_oil, "oil")}
    checks = []
    for st in data.struts:
        lim, oil = st.get("limits") or {}, st["oil"]
        (T1, nu1), (T2, nu2) = sorted([(oil["viscosity_T1"], oil["viscosity_nu1"]), (oil["viscosity_T2"], oil["viscosity_nu2"])])
        lo_data, hi_data = _oil_data_range(float(T1), float(nu1), float(T2), float(nu2), float(th.oil_extrapolation))
        checks.append({"seal_temperature": (lim.get("seal_min_temperature"), lim.get("seal_max_temperature")),
                       "oil_temperature": (None, lim.get("oil_max_temperature")),
                       "oil_data_range": (lo_data, hi_data)})
    out = []
    for code, severity, what in (("seal_temperature", "warning", "the seal limit"),
                                 ("oil_temperature", "warning", "the oil's service limit"),
                                 ("oil_data_range", "note", "where the oil data's viscosity extrapolations disagree by "
                                  f"{100 * th.oil_extrapolation:.0f} %")):
        lo = np.array([np.nan if c[code][0] is None else c[code][0] for c in checks])
        hi = np.array([np.nan if c[code][1] is None else c[code][1] for c in checks])
        T, node = node_T[code]
        with np.errstate(invalid="ignore"):
            above, below = T > hi, T < lo
        for flags, side, limit in ((above, "above", hi), (below, "below", lo)):
            if not flags.any():
                continue
            rows = np.flatnonzero(flags.any(axis=1))
            struts = _names(data, flags.any(axis=0))
            cols = flags.any(axis=0)
            worst = float(np.max(T[:, cols]) if side == "above" else np.min(T[:, cols]))
            lim = float(np.nanmin(limit[cols]) if side == "above" else np.nanmax(limit[cols]))
            km = float(km_of[rows[0]])
            out.append(_warning(code, severity, struts, km, worst - 273.15, lim - 273.15, "degC",
                                f"strut {node} temperature {worst - 273.15:.1f} degC is {side} {what} ({lim - 273.15:.0f} degC) "
                                f"at {struts_text(struts, data.stations)}, first at {km:.3f} km"))
    return out


@functools.lru_cache(maxsize=64)
def _oil_data_range(T1_K: float, nu1_m2_s: float, T2_K: float, nu2_m2_s: float, rel: float) -> tuple[float, float]:
    """`viscosity_extrapolation_range` of an oil, found once per process (a bisection; every strut of a vehicle and
    every file of a study usually share their oil)."""
    return viscosity_extrapolation_range(T1_K, nu1_m2_s, T2_K, nu2_m2_s, rel)


def _solver(data, th):
    err = data.summary_value("solver_error_estimate")
    if err is None:
        return []
    err = float(np.max(np.asarray(err, float)))
    tol = data.summary_value("solver_tolerance")
    # the run's own tolerance (solver.tolerance) unless the caller set a threshold of its own
    tol = th.solver_error if tol is None or th.solver_error != Thresholds.solver_error else float(tol)
    if not err > tol:
        return []
    hint = data.summary_value("solver_advice")
    return [_warning("solver_error", "warning", [], None, err, tol, "",
                     f"solver error estimate {err:.2g} exceeds the tolerance {tol:.2g}"
                     + (f": {hint}" if hint else ": reduce solver.dt"))]

