"""How the struts' damping and friction moved with temperature over a drive (seed 001 §5.2).

Per axle (mean of left and right), for the first and the last statistics interval of the drive:
  T_oil_C             the oil node's mean temperature [degC] (the strut's body temperature of the maps)
  c_valve_kNs_m       equivalent valve damping P_valve / v_rms^2 [kN s/m at the strut]: the linear damper that
                      dissipates the interval's valve power at its RMS strut velocity
  c_friction_kNs_m    the same for the seal friction (P_friction / v_rms^2)
  coulomb_*_N         the strut's Coulomb friction per stroke at that oil temperature: mapped (struts.maps; the
                      maps hold it constant over frequency, seed 001 §5.2) or, for a physical strut
                      (internals: physical), its seal's contact law (struts.seal_friction); None without either
For struts with internal maps or physical internals only (`None` otherwise): the table answers how the struts'
damping and friction move with temperature on the vehicle.
"""
from __future__ import annotations

import json

import numpy as np

from struts import seal_friction as seal
from struts.maps import map_value
from struts.params import StrutParams

__all__ = ["damping_over_drive"]


def _coulomb_laws(resolved: dict, n_axles: int) -> list:
    """Per axle: (maps range [degC] or None, coulomb(direction, T_K) -> N) of its strut from the results file's
    resolved scenario, or None when its Coulomb level moves with neither a map nor a physical seal law."""
    struts = resolved.get("struts") or {}      # {"axle1": strut parameters, ...}
    out = []
    for k in range(n_axles):
        data = struts.get(f"axle{k + 1}") if isinstance(struts, dict) else None
        law = None
        if isinstance(data, dict) and data.get("internals") == "physical":
            sp = StrutParams.model_validate(data)
            f, T_ref = sp.friction, sp.oil.reference_temperature
            law = (None, lambda d, T, f=f, T_ref=T_ref: float(seal.contact_coulomb_level(
                getattr(f, f"F0_{d}"), T, T_ref, f.contact_temperature_coefficient)))
        elif isinstance(data, dict) and data.get("internal_maps"):
            m = StrutParams.model_validate(data).internal_maps
            law = ([m.temperatures[0] - 273.15, m.temperatures[-1] - 273.15],
                   lambda d, T, m=m: float(map_value(m, f"coulomb_{d}", T, m.frequencies[0]))
                   if getattr(m, f"coulomb_{d}") is not None else None)
        out.append(law)
    return out


def damping_over_drive(r) -> list[dict] | None:
    """Per-axle rows (module docstring) from a results view (vehicle.results.reader.ResultsView), or None when no
    strut has internal maps or the file has fewer than one statistics interval."""
    try:
        resolved = json.loads(r.scenario_attrs["resolved_json"])
    except (KeyError, ValueError, TypeError):
        return None
    n_axles = len(r.axles)
    laws = _coulomb_laws(resolved, n_axles)
    if not any(law is not None for law in laws):
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
        if laws[k] is not None and laws[k][0] is not None:     # outside it the maps hold their edge values
            row["maps_range_C"] = laws[k][0]
        for tag, i in (("first", 0), ("last", -1)):
            v2 = axle(v_rms, i)[k] ** 2
            T = axle(T_oil, i)[k]
            row[f"T_oil_{tag}_C"] = float(T - 273.15)
            row[f"c_valve_{tag}_kNs_m"] = float(axle(P_v, i)[k] / v2 / 1e3) if v2 > 0 else None
            row[f"c_friction_{tag}_kNs_m"] = float(axle(P_f, i)[k] / v2 / 1e3) if v2 > 0 else None
            for d in ("compression", "rebound"):
                row[f"coulomb_{d}_{tag}_N"] = laws[k][1](d, T) if laws[k] is not None else None
        rows.append(row)
    return rows
