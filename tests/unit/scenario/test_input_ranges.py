"""Input that used to be accepted silently or gave impossible results (issue 13): physical ranges of
parameters, levelling settings that blow up, a road shorter than the drive, limits that disagree
with their messages, calibrate's stopping rules, foreign file content in messages."""
from __future__ import annotations

import math
import re
from pathlib import Path
from types import SimpleNamespace

import pytest

from hpsim.errors import UserInputError
from vehicle import cli
from vehicle.physics.params import load_vehicle
from vehicle.scenario.schema import prepare, read_scenario_text
from tests.helpers import SHORT_SCENARIO

SCENARIO = SHORT_SCENARIO


def _prepare(tmp_path, extra: str = "", text: str = SCENARIO):
    return prepare(read_scenario_text(text + extra, "s.yaml", tmp_path))


@pytest.mark.parametrize("override, says", [
    ("{all: {overrides: {geometry.gas_volume_extended: 0}}}", "gas_volume_extended must be > 0"),
    ("{all: {overrides: {geometry.stroke: -0.1 m}}}", "stroke must be > 0"),
    ("{all: {overrides: {friction.F0_compression: -100 N}}}", "F0_compression must be >= 0"),
    ("{all: {overrides: {friction.viscous: -1 N*s/m}}}", "viscous must be >= 0"),
    ("{all: {overrides: {valve.discharge_coefficient: 1.5}}}", "discharge_coefficient must be in [0, 1]"),
    ("{all: {overrides: {oil.bulk_modulus: 0 Pa}}}", "bulk_modulus must be > 0"),
])
def test_strut_parameters_must_be_physical(tmp_path, override, says):
    with pytest.raises(UserInputError, match=r"struts\.axle1 .*" + re.escape(says)):
        _prepare(tmp_path, f"struts: {override}\n")


@pytest.mark.parametrize("override, says", [
    ("heat.emissivity: -0.2", "emissivity must be in [0, 1]"),
    ("heat.emissivity: 1.2", "emissivity must be in [0, 1]"),
    ("heat.natural_convection: -5 W/(m^2*K)", "natural_convection must be >= 0"),
    ("heat.convection_multiplier: -1", "convection_multiplier must be >= 0"),
    ("compensation.smoothing: 0 m", "smoothing must be in [0.0001, 0.02]"),
])
def test_vehicle_parameters_must_be_physical(tmp_path, override, says):
    with pytest.raises(UserInputError, match=re.escape(says)):
        _prepare(tmp_path, f"vehicle: {{name: apc_8x8, overrides: {{{override}}}}}\n",
                 SCENARIO.replace("vehicle: {name: apc_8x8}\n", ""))


# the settings of issue 13 that gave 646 K gas and the hull 0.4 m off within 1 km, each inside the
# old documented ranges: now outside the (physical, stable) ones, with the range in the message
@pytest.mark.parametrize("key, value, says", [
    ("time_constant", "0.1 s", "must be in [2, 3600] s"),
    ("filter_time_constant", "0.1 s", "must be in [1, 3600] s"),
    ("flow_limit", "1e-2 m^3/s", "must be in [1e-09, 0.0001] m^3/s"),
    ("smoothing", "0 mm", "must be in [0.1, 20] mm"),
])
def test_compensation_settings_that_blow_up_are_refused(tmp_path, key, value, says):
    with pytest.raises(UserInputError, match=rf"s\.yaml: compensation\.{key}: " + re.escape(says)):
        _prepare(tmp_path, f"compensation: {{enabled: true, {key}: {value}}}\n")


def test_compensation_at_the_ends_of_its_ranges_is_accepted(tmp_path):
    prep = _prepare(tmp_path, "compensation: {enabled: true, time_constant: 2 s, filter_time_constant: 1 s, "
                              "dead_band: 0 mm, flow_limit: 1e-4 m^3/s, smoothing: 0.1 mm}\n")
    c = prep.vehicle.compensation
    assert (c.time_constant, c.filter_time_constant, c.dead_band, c.flow_limit, c.smoothing) == \
        (2.0, 1.0, 0.0, 1e-4, pytest.approx(1e-4))


def _csv(path: Path, length_m: float, step_m: float = 0.5) -> Path:
    n = int(round(length_m / step_m)) + 1
    path.write_text("distance_m,left_m,right_m\n" + "".join(f"{i * step_m},0,0\n" for i in range(n)))
    return path


def test_csv_road_shorter_than_the_drive_is_refused(tmp_path):
    _csv(tmp_path / "short.csv", 150.0)
    text = SCENARIO.replace("road: {iso_class: D, seed: 3}", "road: {csv: short.csv}")
    prep = prepare(read_scenario_text(text, "s.yaml", tmp_path))
    with pytest.raises(UserInputError, match=r"s\.yaml: road\.csv: the profile in short\.csv is 150 m long, "
                                             r"the drive needs 201\.35 m"):
        prep.road()


def test_csv_road_long_enough_is_driven(tmp_path):
    _csv(tmp_path / "long.csv", 250.0)
    text = SCENARIO.replace("road: {iso_class: D, seed: 3}", "road: {csv: long.csv}")
    road = prepare(read_scenario_text(text, "s.yaml", tmp_path)).road()
    assert road.length_m == 250.0


def test_explicit_road_length_shorter_than_the_drive_is_refused(tmp_path):
    text = SCENARIO.replace("road: {iso_class: D, seed: 3}", "road: {iso_class: D, length: 150 m}")
    with pytest.raises(UserInputError, match=r"road\.length: 150 m is shorter than the drive, which needs 201\.35 m"):
        prepare(read_scenario_text(text, "s.yaml", tmp_path))


def test_distance_beyond_its_range_names_distance(tmp_path):
    text = SCENARIO.replace("distance: 200 m", "distance: 20000 km")
    with pytest.raises(UserInputError, match=r"s\.yaml: distance: must be in \[0\.001, 1000\] km, got 20000 km"):
        prepare(read_scenario_text(text, "s.yaml", tmp_path))


def test_longest_distance_builds_a_valid_road_spec(tmp_path):
    """The end of the distance range is drivable: its default road is within the road's own limits."""
    prep = prepare(read_scenario_text(SCENARIO.replace("distance: 200 m", "distance: 1000 km"), "s.yaml", tmp_path))
    assert prep.road_spec.length > 1000e3


def test_foreign_file_content_is_not_echoed(tmp_path, capsys):
    secret = "root:x:0:0:SECRET-ROOT-LINE:/root:/bin/bash"
    (tmp_path / "passwd").write_text(secret + "\nuser:x:1000:1000::/home/user:/bin/sh\n")
    code = cli.main(["road", "psd", str(tmp_path / "passwd")])
    err = capsys.readouterr().err
    assert code == 2 and "SECRET" not in err and "passwd" in err
    (tmp_path / "rig.csv").write_text("amplitude_m,SECRET_COLUMN\n1,2\n")
    code = cli.main(["strut", "fit", "--data", str(tmp_path / "rig.csv"), "--fit", "F0"])
    err = capsys.readouterr().err
    assert code == 2 and "SECRET" not in err and "rig.csv" in err


# --- calibrate's stopping rules, on a synthetic monotone rise (no drives) -----------------------------
@pytest.fixture
def synthetic_calibration(tmp_path, monkeypatch):
    """calibrate_heat with `_run` replaced by rise(ratio) = 60 K / (1 + 20 ratio): smooth and monotone
    decreasing like the real one, between 60 K (no forced convection) and ~1.5 K (ratio 2)."""
    import vehicle.studies.calibration as cal

    (tmp_path / "s.yaml").write_text(SCENARIO)
    calls = []

    def fake_run(src, parameter, value):
        calls.append(value)
        prepared = prepare(src)
        drive = SimpleNamespace(settings=SimpleNamespace(speed=SimpleNamespace(speeds_m_per_s=[20 / 3.6])))
        return 60.0 / (1.0 + 20.0 * value), prepared, drive

    monkeypatch.setattr(cal, "_run", fake_run)
    return cal, tmp_path / "s.yaml", calls


def test_calibrate_stops_when_the_first_run_is_within_tolerance(synthetic_calibration):
    cal, path, calls = synthetic_calibration
    shipped = load_vehicle("apc_8x8").heat.air_speed_ratio     # the calibrated value in vehicle/data/apc_8x8.yaml
    res = cal.calibrate_heat(path, 60.0 / (1 + 20 * shipped) + 0.05, tol_K=0.1, log=lambda m: None)
    # one calibration run, then the noise probe at it: the synthetic rise is smooth (floor ~1e-13 K), so the
    # probe stops after its minimum of two runs at rounding-level changes of the ratio
    assert len(calls) == 3 and res["noise_probe_runs"] == 2 and res["value"] == pytest.approx(shipped)
    assert all(c == pytest.approx(shipped, rel=1e-11) for c in calls) and res["noise_floor_K"] < 1e-9


def test_calibrate_converges_on_a_reachable_target(synthetic_calibration):
    cal, path, calls = synthetic_calibration
    res = cal.calibrate_heat(path, 20.0, tol_K=1e-3, log=lambda m: None)
    assert res["value"] == pytest.approx(0.1, rel=1e-3) and abs(res["achieved_rise_K"] - 20.0) < 1e-3


@pytest.mark.parametrize("target", [59.99, 200.0, 0.5])
def test_calibrate_says_when_the_target_is_unreachable(synthetic_calibration, target):
    cal, path, calls = synthetic_calibration
    assert not 60.0 / (1 + 20 * 2.0) < target < 60.0 / (1 + 20 * 1e-3)     # outside what ratios in range give
    with pytest.raises(UserInputError, match=r"--target-rise: .* is not reachable"):
        cal.calibrate_heat(path, target, tol_K=1e-3, log=lambda m: None)
    assert len(calls) <= 8 and all(math.isfinite(v) for v in calls)


@pytest.mark.parametrize("tolerance", [0.0, -1.0, float("nan")])
def test_calibrate_needs_a_positive_tolerance(synthetic_calibration, tolerance):
    cal, path, calls = synthetic_calibration
    with pytest.raises(UserInputError, match=r"--tolerance: must be > 0 K"):
        cal.calibrate_heat(path, 20.0, tol_K=tolerance, log=lambda m: None)
    assert not calls

