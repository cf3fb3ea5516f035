"""Speed profiles (issue 10 §3): recorded drives by time and by distance, stop-go cycles, random speed.

Checks kinematics that can fail: the exact time of a linear v(s) ramp and its acceleration v dv/ds,
a constant-acceleration recording converted to distance, the same drive recorded by time and by
distance giving the same table, stop-go stops lasting what was asked, the random profile's trip
average, spread and correlation length, and the scenario's messages.
"""
import math

import numpy as np
import pytest

from hpsim.errors import UserInputError
from vehicle.scenario.schema import load_prepared
from vehicle.scenario.speed import (MIN_SPEED_M_PER_S, CsvSpeedSpec, RandomSpeedSpec, SpeedTable, StopGoSpec,
                                parse_column, random_profile, read_speed_csv, smooth_noise, stop_go_profile)


def test_linear_ramp_over_distance_has_its_analytic_time_and_acceleration():
    v0, k, L = 2.0, 0.01, 500.0                          # v = v0 + k s  [m/s]
    table = SpeedTable(np.array([0.0, L]), np.array([v0, v0 + k * L]))
    s = np.array([0.0, 10.0, 250.0, 499.0])
    assert np.allclose(table.acceleration(s), (v0 + k * s) * k, rtol=1e-12)
    assert table.acceleration(np.array([-1.0, L + 1]))  == pytest.approx([0.0, 0.0])   # held speed
    _, t = table.time_grid(L)
    assert t[-1] == pytest.approx(math.log((v0 + k * L) / v0) / k, rel=1e-12)       # ∫ ds / (v0 + k s)


def test_constant_acceleration_recording_converts_to_distance():
    a = 0.8
    t = np.linspace(0.0, 20.0, 11)                       # 0 .. 16 m/s, recorded every 2 s
    table = SpeedTable.from_time_series(t, 1.0 + a * t)
    s = np.linspace(1.0, 150.0, 40)
    assert np.allclose(table.acceleration(s), a, rtol=0.03)      # pieces of <= 5 % speed change
    assert np.allclose(table.speed(s), np.sqrt(1.0 + 2 * a * s), rtol=1e-3)   # v^2 = v0^2 + 2 a s
    st = table.statistics(float(table.distances_m[-1]))
    assert st["duration_s"] == pytest.approx(20.0, rel=1e-3)


def _write(path, header, rows):
    path.write_text(header + "\n" + "\n".join(",".join(f"{x:.10g}" for x in r) for r in rows) + "\n")


def test_a_drive_recorded_by_time_and_by_distance_gives_the_same_table(tmp_path):
    # 5 km/h start, accelerate to 30 km/h at 0.5 m/s^2, cruise, brake to 10 km/h at 1 m/s^2, cruise
    t = np.arange(0.0, 200.0, 0.5)
    v = np.clip(5 / 3.6 + 0.5 * t, None, 30 / 3.6)
    brake = t > 120
    v[brake] = np.maximum(30 / 3.6 - 1.0 * (t[brake] - 120), 10 / 3.6)
    s = np.concatenate([[0.0], np.cumsum(np.diff(t) * 0.5 * (v[1:] + v[:-1]))])
    _write(tmp_path / "by_time.csv", "time_s,speed_km_h", zip(t, v * 3.6))
    _write(tmp_path / "by_distance.csv", "distance_km,speed [m/s]", zip(s / 1e3, v))
    L = float(s[-1])
    a = read_speed_csv(CsvSpeedSpec(csv="by_time.csv", by="time"), L, tmp_path)
    b = read_speed_csv(CsvSpeedSpec(csv="by_distance.csv"), L, tmp_path)       # by: from the header
    grid = np.linspace(0.0, L, 777)
    assert np.allclose(a.speed(grid), b.speed(grid), atol=0.03)               # m/s
    assert a.statistics(L)["duration_s"] == pytest.approx(199.5, rel=2e-3)
    assert b.statistics(L)["duration_s"] == pytest.approx(199.5, rel=2e-3)
    ramp = grid[(grid > 2) & (grid < 65)]                                      # 5 -> 30 km/h: 67 m
    assert np.allclose(a.acceleration(ramp), 0.5, rtol=0.03)


def test_a_recorded_stop_is_kept_as_time_at_the_creeping_speed(tmp_path):
    t = [0.0, 10.0, 10.0 + 1e-3, 40.0, 40.0 + 1e-3, 60.0]
    v = [20.0, 20.0, 0.0, 0.0, 20.0, 20.0]
    _write(tmp_path / "stop.csv", "time_s,speed_km_h", zip(t, v))
    table = read_speed_csv(CsvSpeedSpec(csv="stop.csv"), 100.0, tmp_path)
    st = table.statistics(float(table.distances_m[-1]))
    assert st["time_at_min_speed_s"] == pytest.approx(30.0, abs=0.05)
    assert "driven at that creeping speed" in table.description


def test_recorded_drive_shorter_than_the_distance_is_refused_or_repeated(tmp_path):
    _write(tmp_path / "lap.csv", "distance_m,speed_km_h", [(0, 10), (100, 20), (200, 10)])
    with pytest.raises(UserInputError, match="covers 200 m.*repeat: true"):
        read_speed_csv(CsvSpeedSpec(csv="lap.csv"), 1000.0, tmp_path)
    table = read_speed_csv(CsvSpeedSpec(csv="lap.csv", repeat=True), 1000.0, tmp_path)
    assert table.speed(np.array([50.0, 650.0, 900.0])) * 3.6 == pytest.approx([15.0, 15.0, 20.0])


@pytest.mark.parametrize("name,kind,factor", [("time_s", "time", 1.0), ("time_min", "time", 60.0),
                                              ("distance_km", "distance", 1e3), ("speed_km_h", "speed", 1 / 3.6),
                                              ("speed [km/h]", "speed", 1 / 3.6), ("speed_mph", "speed", 0.44704)])
def test_csv_column_names_carry_their_units(name, kind, factor):
    k, f = parse_column(name, "test")
    assert k == kind and f == pytest.approx(factor, rel=1e-9)


def test_stop_go_cycles_stop_as_long_as_asked_and_accelerate_as_asked():
    spec = StopGoSpec(cruise_speed="36 km/h", stop_duration="25 s", acceleration="0.8 m/s^2",
                      deceleration="1.2 m/s^2", spacing="400 m")
    table = stop_go_profile(spec, 4000.0)
    st = table.statistics(4000.0)
    assert st["time_at_min_speed_s"] == pytest.approx(10 * 25.0, rel=1e-6)      # 10 stops in 4 km
    d_acc, d_dec, d_stop = spec.ramp_distances()
    acc = np.linspace(0.1 * d_acc, 0.9 * d_acc, 50)
    dec = 400.0 - d_stop - np.linspace(0.1 * d_dec, 0.9 * d_dec, 50)
    assert np.allclose(table.acceleration(acc), 0.8, rtol=0.03)
    assert np.allclose(table.acceleration(dec), -1.2, rtol=0.03)
    assert table.speed(np.array([200.0])) == pytest.approx(10.0)
    # one cycle: ramps at constant acceleration, cruise, stop
    t_cycle = (10 - MIN_SPEED_M_PER_S) * (1 / 0.8 + 1 / 1.2) + (400 - d_acc - d_dec - d_stop) / 10.0 + 25.0
    assert st["duration_s"] == pytest.approx(10 * t_cycle, rel=2e-3)


def test_smooth_noise_has_unit_variance_and_the_requested_correlation_length():
    ell, ds = 20.0, 2.0
    g = smooth_noise(200_000, ds, ell, seed=5)
    assert g.var() == pytest.approx(1.0, abs=0.05)
    lag = int(ell / ds)
    rho = np.mean(g[:-lag] * g[lag:]) / g.var()
    assert rho == pytest.approx(math.exp(-0.5), abs=0.04)                     # exp(-ds^2 / (2 l^2)) at ds = l


def test_random_profile_has_the_requested_trip_average_and_spread_and_is_reproducible():
    spec = RandomSpeedSpec(mean="20 km/h", spread="6 km/h", correlation_length="40 m", seed=2,
                           min="5 km/h", max="40 km/h")
    L = 30e3
    table = random_profile(spec, L)
    st = table.statistics(L)
    assert st["mean_speed_m_per_s"] == pytest.approx(20 / 3.6, rel=1e-9)    # distance / drive time
    assert st["duration_s"] == pytest.approx(L / (20 / 3.6), rel=1e-9)
    assert st["spread_m_per_s"] == pytest.approx(6 / 3.6, rel=1e-3)
    v = table.speed(np.linspace(0, L, 10001))
    assert v.min() >= 5 / 3.6 - 1e-12 and v.max() <= 40 / 3.6 + 1e-12
    # smooth: the accelerations stay those of a driver (prior 0.5-1.5 m/s^2 peaks)
    assert 0.05 < st["rms_acceleration_m_per_s2"] < 0.5 and st["max_abs_acceleration_m_per_s2"] < 2.0
    again = random_profile(spec, L)
    assert np.array_equal(again.speeds_m_per_s, table.speeds_m_per_s)
    other = random_profile(spec.model_copy(update={"seed": 3}), L)
    assert not np.allclose(other.speed(np.linspace(0, L, 101)), table.speed(np.linspace(0, L, 101)))


def test_unreachable_spread_is_an_error_naming_the_bounds():
    spec = RandomSpeedSpec(mean="20 km/h", spread="15 km/h", min="5 km/h", max="30 km/h")
    with pytest.raises(UserInputError, match=r"spread of 15 km/h.*min 5 and max 30 km/h"):
        random_profile(spec, 5e3)


SCENARIO = """vehicle: {{name: apc_8x8}}
road: {{iso_class: D, seed: 1}}
speed: {speed}
distance: 2 km
ambient_temperature: 25 degC
"""


@pytest.mark.parametrize("speed,needle", [
    ("{stop_go: {cruise_speed: 30 km/h, spacing: 1 km, deceleration: 10 m/s^2}}",
     "speed: stop_go.deceleration: deceleration must be in [0.05, 5] m/s^2, got 10 m/s^2"),
    ("{random: {mean: 20 km/h, spread: 5 km/h, correlation_length: 0.1 m}}",
     "speed: random.correlation_length: correlation_length must be in [1, 100000] m, got 0.1 m"),
    ("{random: {mean: 200 km/h, spread: 5 km/h}}", "speed: random.mean: mean must be in [0.5, 150] km/h"),
    ("{random: {mean: 20 km/h, spread: 5 km/h, sead: 1}}", "speed: random.sead: unknown key"),
    ("{csv: drive.csv, by: speed}", "speed: by: Input should be 'time' or 'distance'"),
    ("{stop_go: {cruise_speed: 30 km/h, spacing: 30 m}}", "spacing 30 m is shorter than one cycle"),
    ("{walk: 3 km/h}", "speed: unknown form ['walk']"),
])
def test_scenario_speed_forms_are_validated_with_the_key_and_range(tmp_path, speed, needle):
    path = tmp_path / "s.yaml"
    path.write_text(SCENARIO.format(speed=speed))
    with pytest.raises(UserInputError) as exc:
        load_prepared(path)
    assert needle in str(exc.value) and "s.yaml" in str(exc.value)


def test_scenario_builds_the_table_the_drive_uses(tmp_path):
    _write(tmp_path / "drive.csv", "time_s,speed_km_h", [(0, 10), (100, 30), (400, 30), (500, 5)])
    path = tmp_path / "s.yaml"
    path.write_text(SCENARIO.format(speed="{csv: drive.csv, by: time}"))
    prep = load_prepared(path)
    speed = prep.settings().speed
    assert isinstance(speed, SpeedTable) and speed is prep.speed_profile
    assert speed.speed(np.array([0.0])) == pytest.approx(10 / 3.6)
    for form in ("20 km/h", "{profile: [[0 km, 10 km/h], [2 km, 30 km/h]]}"):
        path.write_text(SCENARIO.format(speed=form))
        sp = load_prepared(path).settings().speed
        assert isinstance(sp, SpeedTable)
        expect = 0.0 if form == "20 km/h" else (10 / 3.6) * (20 / 3.6 / 2000)
        assert sp.acceleration(np.array([0.0]))[0] == pytest.approx(expect)
