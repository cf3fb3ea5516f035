"""Ride and road-holding numbers of a whole drive from its statistics rows (what `hpsim report` shows).

The drive accumulates, per statistics interval i of duration T_i (vehicle.engines.full; the model's
filter states and quadratures, vehicle.physics.ride), under these drive keys:

    weighted_rms_acceleration_m_s2    per seat: ISO 2631-1 Wk vertical a_w,i
    weighted_rms_lateral_acceleration_m_s2   per seat: Wd lateral (roll), where available
    vdv_m_s175                        per seat: VDV_i = (int a_w^4 dt)^(1/4)
    absorbed_power_W                  per seat: mean absorbed power P_i
    dynamic_load_coefficient          per station: DLC_i = std / mean of the tyre load
    lift_off_share                    per station: share of T_i with the tyre off the ground
    end_stop_time_s, end_stop_energy_J   per station
    strut_travel_min_m, strut_travel_max_m   per station
    strut_travel_histogram_s          per station x travel bin: time in each bin (edges: attribute
                                      bin_edges_m of the dataset, or the summary value
                                      strut_travel_bin_edges_m; one row of edges, or one per station)
    rms_strut_velocity_m_per_s, rms_hull_acceleration   (as before)

Over the drive: a_w = sqrt(sum T_i a_w,i^2 / T) (ISO 2631-1 eq. 1 over the whole time); VDV =
(sum VDV_i^4)^(1/4) (ISO 2631-1 §6.3.2); P = sum T_i P_i / T; DLC = sqrt(sum T_i DLC_i^2 / T).
The DLC is exact when the mean tyre load is the same in every interval (it is the static load). Shares are
time-weighted; end-stop time and energy summed; travel min/max over the rows and travel
percentiles from the summed histogram. Rows or keys a run did not store are left out.
"""
from __future__ import annotations

import json

import numpy as np

from vehicle.physics import ride
from vehicle.results.validity import SHOCK_KEYS, seat_shocks  # noqa: F401  (SHOCK_KEYS: the seat rows' keys)
from vehicle.physics.outputs import variable_name
from vehicle.results.layout import STATS

PERCENTILES = (1, 50, 99)


def _rows(view, key):
    a = view.stats_series(variable_name(key))
    return None if a is None or len(a) == 0 else np.asarray(a, float)


def _bin_edges(view, key="strut_travel_histogram_s"):
    """Travel-bin edges [m]: the histogram dataset's attribute, or a summary value."""
    f = getattr(view, "f", None)
    if f is not None and STATS in f and variable_name(key) in f[STATS]:
        edges = f[STATS][variable_name(key)].attrs.get("bin_edges_m")
        if edges is not None:
            return np.asarray(edges, float)
    v = view.summary_values().get(variable_name("strut_travel_bin_edges_m"))
    return None if v is None else np.asarray(v, float)


def _num(v):
    v = float(v)
    return v if np.isfinite(v) else None


def summarise(view) -> dict:
    """{'seats': [...], 'stations': [...], 'hull': {...}} for the drive; {} when the rows hold none of it."""
    T = _rows(view, "duration_s")
    if T is None or T.sum() <= 0:
        return {}
    out = {"duration_s": float(T.sum())}
    seats = _seats(view, T)
    if seats is not None:
        out["seats"] = seats
    add_shocks(out, view)
    stations = _stations(view, T)
    if stations is not None:
        out["stations"] = stations
    hull = _hull(view, T)
    if hull is not None:
        out["hull"] = hull
    return out


def _rms(a, T):
    """The root mean square over the drive of per-interval RMS values `a` (rows), weighted by the intervals' T [s]."""
    return np.sqrt((T[:, None] * a * a).sum(axis=0) / T.sum())


def _seats(view, T) -> list[dict] | None:
    """Per seat: frequency-weighted RMS accelerations and comfort band, VDV, absorbed power; None without them."""
    total = T.sum()
    resolved = json.loads(view.scenario_attrs["resolved_json"])
    seat_names = [s["name"] for s in resolved.get("vehicle", {}).get("seats", [])]
    aw, vdv, pa = (_rows(view, k) for k in ("weighted_rms_acceleration_m_s2", "vdv_m_s175", "absorbed_power_W"))
    lat = _rows(view, "weighted_rms_lateral_acceleration_m_s2")
    if all(a is None for a in (aw, vdv, pa)):
        return None
    n = next(a.shape[1] for a in (aw, vdv, pa) if a is not None)
    names = seat_names if len(seat_names) == n else [f"seat{k + 1}" for k in range(n)]
    seats = []
    for k, name in enumerate(names):
        s = {"seat": name}
        if aw is not None:
            a = float(_rms(aw, T)[k])
            s.update(weighted_rms_acceleration_m_s2=a, comfort=ride.comfort_band(a))
        if lat is not None:
            s["weighted_rms_lateral_acceleration_m_s2"] = float(_rms(lat, T)[k])
        if vdv is not None:
            s["vdv_m_s175"] = ride.combine_vdv(vdv[:, k])
        if pa is not None:
            s["absorbed_power_W"] = float((T * pa[:, k]).sum() / total)
        seats.append(s)
    return seats


def _stations(view, T) -> list[dict] | None:
    """Per wheel station: dynamic load, lift-off, end stops, strut travel (extremes, percentiles, histogram), strut
    velocity; None when the rows hold none of it."""
    w, total = T[:, None], T.sum()
    stations = [{"station": s} for s in view.stations]
    per_station = {
        "dynamic_load_coefficient": lambda a: _rms(a, T),
        "lift_off_share": lambda a: (w * a).sum(axis=0) / total,
        "end_stop_time_s": lambda a: a.sum(axis=0),
        "end_stop_energy_J": lambda a: a.sum(axis=0),
        "strut_travel_min_m": lambda a: a.min(axis=0),
        "strut_travel_max_m": lambda a: a.max(axis=0),
        "rms_strut_velocity_m_per_s": lambda a: _rms(a, T),
    }
    found = False
    for key, fn in per_station.items():
        a = _rows(view, key)
        if a is None:
            continue
        found = True
        for st, v in zip(stations, fn(a)):
            st[key] = _num(v)
    hist = _rows(view, "strut_travel_histogram_s")
    edges = _bin_edges(view) if hist is not None else None
    if hist is not None and edges is not None:
        found = True
        time_in_bins = hist.sum(axis=0)
        if edges.ndim == 1:
            p = ride.travel_percentiles(time_in_bins, edges, PERCENTILES)
        else:          # edges per station (struts of different strokes)
            p = np.array([ride.travel_percentiles(h, e, PERCENTILES) for h, e in zip(time_in_bins, edges)])
        per_station_edges = np.broadcast_to(edges, (len(stations), time_in_bins.shape[-1] + 1))
        for st, row, h, e in zip(stations, p, time_in_bins, per_station_edges):
            st.update({f"strut_travel_p{q}_m": _num(v) for q, v in zip(PERCENTILES, row)})
            st["strut_travel_histogram_s"] = [float(v) for v in h]
            st["bin_edges_m"] = [float(v) for v in e]
    return stations if found else None


def _hull(view, T) -> dict | None:
    """The hull's RMS heave, pitch and roll accelerations over the drive; None without them."""
    acc = _rows(view, "rms_hull_acceleration")
    if acc is None:        # files that store the hull accelerations split (heave, pitch, roll)
        parts = [view.stats_series(f"rms_{d}_acceleration") for d in ("heave", "pitch", "roll")]
        acc = None if any(p is None or len(p) == 0 for p in parts) else np.stack(parts, axis=1)
    if acc is None:
        return None
    r = _rms(np.asarray(acc, float), T)
    return {"rms_heave_acceleration_m_s2": float(r[0]), "rms_pitch_acceleration_rad_s2": float(r[1]),
            "rms_roll_acceleration_rad_s2": float(r[2])}

def add_shocks(out: dict, view) -> None:
    """Per seat: crest factor, MTVV and the ISO 2631-5 doses (vehicle.physics.shocks) from the stored series,
    when they are dense enough; the seat rows get them under SHOCK_KEYS."""
    found = seat_shocks(view)
    if not found:
        return
    rows = {s["seat"]: s for s in out.setdefault("seats", [])}
    for name, values in found.items():
        row = rows.get(name)
        if row is None:
            row = {"seat": name}
            out["seats"].append(row)
        row.update({k: values[k] for k in SHOCK_KEYS if k in values})


def axle_rows(summary: dict, axles) -> list[dict]:
    """Per axle (worst of left and right) road-holding rows for a table."""
    st = summary.get("stations")
    if not st:
        return []
    rows = []
    for k, axle in enumerate(axles):
        pair = st[2 * k: 2 * k + 2]
        row = {"axle": k + 1}
        for key, pick in (("dynamic_load_coefficient", max), ("lift_off_share", max), ("end_stop_time_s", max),
                          ("end_stop_energy_J", max), ("strut_travel_min_m", min), ("strut_travel_max_m", max),
                          ("strut_travel_p1_m", min), ("strut_travel_p99_m", max),
                          ("rms_strut_velocity_m_per_s", max)):
            vals = [p[key] for p in pair if p.get(key) is not None]
            if vals:
                row[key] = pick(vals)
        rows.append(row)
    return rows
