"""How the struts' damping and friction moved with temperature over a drive (issue 21; seed 001 §5.2).

Per axle (mean of left and right), for the first and the last statistics interval of the drive:
  T_oil_C             the oil node's mean temperature [degC] (the strut's body temperature of the maps)
  c_valve_kNs_m       equivalent valve damping P_valve / v_rms^2 [kN s/m at the strut]: the linear damper that
                      dissipates the interval's valve power at its RMS strut velocity
  c_friction_kNs_m    the same for the seal friction (P_friction / v_rms^2)
  coulomb_*_N         the strut's mapped Coulomb friction per stroke at that oil temperature (struts.maps; the
                      maps hold it constant over frequency, seed 001 §5.2); None without a map
For struts with internal maps only (`None` otherwise): the table answers what the maps do on the vehicle.
"""
from __future__ import annotations

import json

import numpy as np

from struts.maps import map_value
from struts.params import StrutParams

__all__ = ["damping_over_drive"]


def _maps_of(resolved: dict, n_axles: int) -> list:
    """The internal maps of each axle's strut from the results file's resolved scenario (None without)."""
    struts = resolved.get("struts") or {}      # {"axle1": strut parameters, ...}
    out = []
    for k in range(n_axles):
        data = struts.get(f"axle{k + 1}") if isinstance(struts, dict) else None
        maps = None
        if isinstance(data, dict) and data.get("internal_maps"):
            maps = StrutParams.model_validate(data).internal_maps
        out.append(maps)
    return out


def damping_over_drive(r) -> list[dict] | None:
    """Per-axle rows (module docstring) from a results view (vehicle.results.reader.ResultsView), or None when no
    strut has internal maps or the file has fewer than one statistics interval."""
    try:
        resolved = json.loads(r.scenario_attrs["resolved_json"])
    except (KeyError, ValueError, TypeError):
        return None
    n_axles = len(r.axles)
    maps = _maps_of(resolved, n_axles)
    if not any(m is not None for m in maps):
        return None
    P_v, P_f = r.stats_series("power_valve"), r.stats_series("power_friction")
    v_rms, T_oil = r.stats_series("rms_strut_velocity"), r.stats_series("oil_temperature")
    if any(a is None or len(a) == 0 for a in (P_v, P_f, v_rms, T_oil)):
        return None

    def axle(a, i):
        a = np.asarray(a[i], float)
        return 0.5 * (a[0::2] + a[1::2])

    rows = []
    for k in range(n_axles):
        row = {"axle": k + 1}
        if maps[k] is not None:     # outside it the maps hold their edge values (struts.maps)
            row["maps_range_C"] = [maps[k].temperatures[0] - 273.15, maps[k].temperatures[-1] - 273.15]
        for tag, i in (("first", 0), ("last", -1)):
            v2 = axle(v_rms, i)[k] ** 2
            T = axle(T_oil, i)[k]
            row[f"T_oil_{tag}_C"] = float(T - 273.15)
            row[f"c_valve_{tag}_kNs_m"] = float(axle(P_v, i)[k] / v2 / 1e3) if v2 > 0 else None
            row[f"c_friction_{tag}_kNs_m"] = float(axle(P_f, i)[k] / v2 / 1e3) if v2 > 0 else None
            for d in ("compression", "rebound"):
                m = maps[k]
                has = m is not None and getattr(m, f"coulomb_{d}") is not None
                row[f"coulomb_{d}_{tag}_N"] = float(map_value(m, f"coulomb_{d}", T, m.frequencies[0])) if has else None
        rows.append(row)
    return rows
