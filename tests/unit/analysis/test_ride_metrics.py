"""Drive totals of the ride statistics rows (vehicle.analysis.ride_metrics): a signal cut into statistics
intervals of unequal length must give the whole signal's ISO 2631-1 weighted RMS and VDV, mean
absorbed power, dynamic load coefficient, time shares and travel percentiles."""
from __future__ import annotations

import json

import numpy as np
import pytest

from vehicle.physics import ride
from vehicle.analysis import ride_metrics
from vehicle.physics.outputs import variable_name as _name

EDGES = np.linspace(0.0, 0.24, 49)            # strut travel bins [m]


class RowsView:
    """The part of a results view (vehicle.results.reader.ResultsView) the totals read."""

    def __init__(self, rows: dict, seats, stations):
        self.rows = {_name(k): np.asarray(v, float) for k, v in rows.items()}
        self.stations = stations
        self.scenario_attrs = {"resolved_json": json.dumps({"vehicle": {"seats": [{"name": s} for s in seats]}})}

    def stats_series(self, name):
        return self.rows.get(name)

    def summary_values(self):
        return {_name("strut_travel_bin_edges_m"): EDGES}

    def summary_attrs(self):
        return {}                       # no shock numbers recorded: they would come from series

    def series(self, name):
        return None                     # statistics rows only (the seats' shock numbers need series)


@pytest.fixture(scope="module")
def drive():
    dt = 1e-3
    t = np.arange(0.0, 100.0, dt) + dt / 2          # midpoint samples: sums are the integrals
    cuts = [0.0, 10.0, 30.0, 60.0, 100.0]          # whole periods of every sine in every interval
    a = np.stack([0.6 * np.sin(2 * np.pi * 1.3 * t) + 0.3 * np.sin(2 * np.pi * 4.5 * t),
                  0.9 * np.sin(2 * np.pi * 0.5 * t) * (1 + (t > 60))])          # seat a_w [m/s^2]
    P = 1.5 + np.sin(2 * np.pi * 0.5 * t) ** 2 * (t / 50)                         # absorbed power [W]
    F = 3e4 + np.stack([4e3 * np.sin(2 * np.pi * 1.3 * t), 8e3 * np.sin(2 * np.pi * 4.5 * t) * (1 + (t > 30))])
    x = 0.112 + np.stack([0.03 * np.sin(2 * np.pi * 1.3 * t), 0.05 * np.sin(2 * np.pi * 0.5 * t) * (t / 100)])
    off, stop = F < 2.6e4, x > 0.155                                               # "lift-off", "on a stop"
    rows = {k: [] for k in ("duration_s", "weighted_rms_acceleration_m_s2", "vdv_m_s175", "absorbed_power_W",
                            "dynamic_load_coefficient", "lift_off_share", "end_stop_time_s", "strut_travel_min_m",
                            "strut_travel_max_m", "strut_travel_histogram_s")}
    for lo, hi in zip(cuts, cuts[1:]):
        k = (t >= lo) & (t < hi)
        T = hi - lo
        rows["duration_s"].append(T)
        rows["weighted_rms_acceleration_m_s2"].append(ride.weighted_rms((a[:, k] ** 2).sum(1) * dt, T))
        rows["vdv_m_s175"].append(ride.vibration_dose_value((a[:, k] ** 4).sum(1) * dt))
        rows["absorbed_power_W"].append([P[k].mean(), 2 * P[k].mean()])
        rows["dynamic_load_coefficient"].append(ride.dynamic_load_coefficient(F[:, k].sum(1) * dt,
                                                                              (F[:, k] ** 2).sum(1) * dt, T))
        rows["lift_off_share"].append(off[:, k].mean(1))
        rows["end_stop_time_s"].append(stop[:, k].sum(1) * dt)
        rows["strut_travel_min_m"].append(x[:, k].min(1))
        rows["strut_travel_max_m"].append(x[:, k].max(1))
        rows["strut_travel_histogram_s"].append([np.histogram(xi, EDGES)[0] * dt for xi in x[:, k]])
    view = RowsView(rows, ["driver", "rear_crew"], ["axle1_left", "axle1_right"])
    return ride_metrics.summarise(view), dict(a=a, P=P, F=F, x=x, off=off, stop=stop, dt=dt, T=100.0)


def test_ride_totals_are_those_of_the_whole_drive(drive):
    out, s = drive
    for k, seat in enumerate(out["seats"]):
        a_w = np.sqrt((s["a"][k] ** 2).sum() * s["dt"] / s["T"])
        assert seat["weighted_rms_acceleration_m_s2"] == pytest.approx(a_w, rel=1e-12)
        assert seat["vdv_m_s175"] == pytest.approx(((s["a"][k] ** 4).sum() * s["dt"]) ** 0.25, rel=1e-12)
        assert seat["comfort"] == ride.comfort_band(a_w)
    assert [st["seat"] for st in out["seats"]] == ["driver", "rear_crew"]
    assert out["seats"][0]["absorbed_power_W"] == pytest.approx(s["P"].mean(), rel=1e-9)


def test_road_holding_totals_are_those_of_the_whole_drive(drive):
    out, s = drive
    for k, st in enumerate(out["stations"]):
        F = s["F"][k]
        assert st["dynamic_load_coefficient"] == pytest.approx(F.std() / F.mean(), rel=1e-6)
        assert st["lift_off_share"] == pytest.approx(s["off"][k].mean(), rel=1e-12)
        assert st["end_stop_time_s"] == pytest.approx(s["stop"][k].sum() * s["dt"], rel=1e-12)
        assert st["strut_travel_min_m"] == s["x"][k].min() and st["strut_travel_max_m"] == s["x"][k].max()
        width = EDGES[1] - EDGES[0]
        for q in ride_metrics.PERCENTILES:
            assert st[f"strut_travel_p{q}_m"] == pytest.approx(np.percentile(s["x"][k], q), abs=width)
    rows = ride_metrics.axle_rows(out, ["axle1"])
    assert rows[0]["strut_travel_max_m"] == max(s["x"][0].max(), s["x"][1].max())
