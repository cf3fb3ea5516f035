"""Scenario files: the schema rejects malformed files before any work, naming file, key, value and
what is allowed; the shipped scenarios validate; `hpsim vehicle equilibrium` arguments."""
from __future__ import annotations

import json
import textwrap
from pathlib import Path

import numpy as np
import pytest

from hpsim.errors import UserInputError
from vehicle import cli
from vehicle.scenario.schema import apply_overrides, load_prepared, prepare, read_scenario

from tests.helpers import REPO, assert_bad_scenario_exits_2

SCENARIOS = REPO / "scenarios"

GOOD = """\
vehicle: {name: apc_8x8}
road: {iso_class: D, seed: 1}
speed: 20 km/h
distance: 2 km
ambient_temperature: 25 degC
initial_temperatures: [24.8 degC, 25.3 degC, 24.8 degC, 24.6 degC]
compensation: {enabled: false}
solver: {dt: 4 ms}
output: {interval: 1 s, stats_interval: 1 km}
"""


def _write(tmp_path, text, name="s.yaml") -> Path:
    p = tmp_path / name
    p.write_text(textwrap.dedent(text))
    return p


def _run_cli(argv, capsys):
    code = cli.main(argv)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("path", sorted(SCENARIOS.glob("*.yaml")), ids=lambda p: p.name)
def test_shipped_files_validate(path):
    if "sweep" in path.name:
        from vehicle.studies.sweep import load_sweep

        _, _, cases = load_sweep(path)
        assert cases and all(c["source"].data for c in cases)
        if path.name == "compensation_sweep.yaml":      # on/off x road class D/E
            assert sorted((c["overrides"]["compensation.enabled"], c["overrides"]["road.iso_class"]) for c in cases) \
                == [(False, "D"), (False, "E"), (True, "D"), (True, "E")]
    elif path.name.startswith("optimize_"):             # an optimisation study: its cases are scenarios
        from vehicle.studies.optimize_study import load_study

        study = load_study(path)
        assert study.cases and study.design and study.objectives
    else:
        prep = load_prepared(path)
        assert prep.scenario.distance > 0
        assert len(prep.initial_temperatures_K) == prep.vehicle.n_stations


def test_mileage_scenario_matches_the_seed_test():
    prep = load_prepared(SCENARIOS / "mileage_106km.yaml")
    S = prep.scenario
    assert S.distance == pytest.approx(106e3)
    assert S.speed == pytest.approx(20 / 3.6)
    assert S.ambient_temperature == pytest.approx(298.15)
    assert prep.road_spec.iso_class == "D"
    assert not S.compensation.enabled and not prep.vehicle.compensation.enabled
    # per-axle temperatures map onto both stations of the axle (axle-major, left first)
    np.testing.assert_allclose(prep.initial_temperatures_K - 273.15, np.repeat([24.8, 25.3, 24.8, 24.6], 2))
    assert S.solver.dt == pytest.approx(0.004) and S.output.interval == 1.0 and S.output.stats_interval == 1000.0
    # the road covers the whole drive plus the vehicle's length
    assert prep.road_spec.length >= 106e3 + max(a.position for a in prep.vehicle.axles)
    comp = load_prepared(SCENARIOS / "mileage_106km_compensated.yaml")
    assert comp.scenario.compensation.enabled and comp.vehicle.compensation.enabled
    assert comp.vehicle.compensation.dead_band == pytest.approx(0.015)


# (description, scenario text, key the message must name, words it must contain)
BAD = [
    ("missing key", GOOD.replace("distance: 2 km\n", ""), "distance", ["Field required"]),
    ("typo", GOOD.replace("ambient_temperature", "ambient_temprature"), "ambient_temprature", ["unknown key"]),
    ("nested typo", GOOD.replace("solver: {dt: 4 ms}", "solver: {dt: 4 ms, dtt: 2 ms}"), "solver.dtt",
     ["unknown key"]),
    ("wrong unit", GOOD.replace("distance: 2 km", "distance: 20 km/h"), "distance", ["20 km/h", "expected m"]),
    ("out of range", GOOD.replace("speed: 20 km/h", "speed: 500 km/h"), "speed", ["500", "150"]),
    ("out of range temperature", GOOD.replace("24.6 degC]", "400 degC]"), "initial_temperatures",
     ["item 3", "400", "200"]),
    ("wrong type", GOOD.replace("enabled: false", "enabled: maybe"), "compensation.enabled", ["maybe", "bool"]),
    ("wrong type list", GOOD.replace("stats_interval: 1 km", "stats_interval: [1 km]"), "output.stats_interval",
     ["quantity"]),
    ("not a whole number of steps", GOOD.replace("interval: 1 s", "interval: 1.001 s"), "output.interval",
     ["whole number"]),
    ("road class", GOOD.replace("iso_class: D", "iso_class: Z"), "road.iso_class", ["'Z'", "A, B"]),
    ("road typo", GOOD.replace("seed: 1", "sead: 1"), "road.sead", ["unknown key"]),
    ("vehicle override", GOOD.replace("vehicle: {name: apc_8x8}",
                                      "vehicle: {name: apc_8x8, overrides: {axles.0.motion_ratio: 5}}"),
     "axles.0", ["motion_ratio", "5"]),
    ("vehicle override typo", GOOD.replace("vehicle: {name: apc_8x8}",
                                           "vehicle: {name: apc_8x8, overrides: {heat.capacty: 1}}"),
     "heat.capacty", ["unknown key"]),
    ("unknown vehicle", GOOD.replace("name: apc_8x8", "name: apc_6x6"), "vehicle.name", ["apc_6x6", "apc_8x8"]),
    ("strut axle", GOOD + "struts: {axle9: {overrides: {charge.pressure: 5 MPa}}}\n", "struts.axle9",
     ["4 axles"]),
    ("strut key", GOOD + "struts: {front: {}}\n", "struts", ["'front'", "axle1"]),
    ("temperature count", GOOD.replace("[24.8 degC, 25.3 degC, 24.8 degC, 24.6 degC]", "[25 degC, 26 degC]"),
     "initial_temperatures", ["got 2", "1 (all struts), 4 (one per axle) or 8"]),
    ("speed profile", GOOD.replace("speed: 20 km/h", "speed: {profile: [[0 km, 20 km/h], [0 km, 15 km/h]]}"),
     "speed", ["increase"]),
    ("store", GOOD.replace("stats_interval: 1 km}", "stats_interval: 1 km, store: [wheel_lode]}"), "output.store",
     ["wheel_lode", "wheel_load"]),
]


@pytest.mark.parametrize("what,text,key,words", BAD, ids=[b[0] for b in BAD])
def test_malformed_scenarios_name_the_key(tmp_path, capsys, what, text, key, words):
    assert_bad_scenario_exits_2(_write(tmp_path, text), key, words, capsys)


def test_yaml_syntax_error_names_file_and_line(tmp_path, capsys):
    path = _write(tmp_path, GOOD.replace("speed: 20 km/h", "speed: [20 km/h"))
    code, out, err = _run_cli(["run", str(path), "--no-progress"], capsys)
    assert code == 2 and f"{path}:" in err and "YAML syntax error" in err and "Traceback" not in err


def test_yaml_is_parsed_safely(tmp_path, capsys):
    marker = tmp_path / "pwned"
    path = _write(tmp_path, GOOD.replace("speed: 20 km/h", f"speed: !!python/object/apply:os.system ['touch {marker}']"))
    code, out, err = _run_cli(["run", str(path), "--no-progress"], capsys)
    assert code == 2 and str(path) in err
    assert not marker.exists()


def test_missing_file(tmp_path, capsys):
    code, out, err = _run_cli(["run", str(tmp_path / "nope.yaml")], capsys)
    assert code == 2 and "nope.yaml" in err and "not found" in err


def test_overrides_reach_vehicle_struts_and_compensation(tmp_path):
    # charge.pressure takes effect only when the vehicle charges by pressure (issue 10 §5)
    text = GOOD.replace("vehicle: {name: apc_8x8}", "vehicle: {name: apc_8x8, overrides: {heat.capacity: 20 kJ/K, "
                                                    "axles.1.unsprung_mass: 500 kg, charging.method: gas_pressure}}")
    text = text.replace("compensation: {enabled: false}", "compensation: {enabled: true, dead_band: 5 mm}")
    text += "struts: {all: {overrides: {charge.pressure: 5 MPa}}, axle2: {overrides: {valve.bleed_area: 1e-5 m^2}}}\n"
    prep = load_prepared(_write(tmp_path, text))
    V = prep.vehicle
    assert V.heat.capacity == pytest.approx(20e3)
    assert V.axles[1].unsprung_mass == pytest.approx(500.0) and V.axles[0].unsprung_mass == pytest.approx(450.0)
    assert V.compensation.enabled and V.compensation.dead_band == pytest.approx(0.005)
    assert V.compensation.time_constant == pytest.approx(15.0)        # vehicle value kept
    assert all(a.strut_overrides["charge"]["pressure"] == "5 MPa" for a in V.axles)
    assert "valve" in V.axles[1].strut_overrides and "valve" not in V.axles[0].strut_overrides
    from struts.params import load_strut

    s1 = load_strut(V.axles[1].strut, V.axles[1].strut_overrides)
    assert s1.valve.bleed_area == pytest.approx(1e-5) and s1.charge.pressure == pytest.approx(5e6)
    assert prep.settings().compensation is True
    # the road's track width follows the vehicle unless given
    assert prep.road_spec.track_width == pytest.approx(V.track)


def test_speed_profile_and_defaults(tmp_path):
    text = GOOD.replace("speed: 20 km/h", "speed: {profile: [[0 km, 20 km/h], [1 km, 10 km/h]]}")
    text = text.replace("initial_temperatures: [24.8 degC, 25.3 degC, 24.8 degC, 24.6 degC]\n", "")
    prep = load_prepared(_write(tmp_path, text))
    S = prep.settings()
    assert S.speed.speed(500.0) == pytest.approx(15 / 3.6)
    np.testing.assert_allclose(prep.initial_temperatures_K, 298.15)     # default: ambient


def test_apply_overrides_with_list_indices():
    data = {"a": {"b": 1, "c": [{"x": 1}, {"x": 2}]}}
    out = apply_overrides(data, {"a.c.1.x": 5, "a": {"b": 2}, "d.e": 3})
    assert out == {"a": {"b": 2, "c": [{"x": 1}, {"x": 5}]}, "d": {"e": 3}}
    assert data["a"]["c"][1]["x"] == 2              # input untouched
    with pytest.raises(UserInputError, match="index 7 out of range"):
        apply_overrides(data, {"a.c.7.x": 1})


def test_scenario_stored_text_round_trip(tmp_path):
    path = _write(tmp_path, GOOD)
    src = read_scenario(path)
    assert src.text == path.read_text() and src.base_dir == tmp_path.resolve()
    assert prepare(src).resolved()["scenario"]["distance"] == pytest.approx(2000.0)


# --- hpsim vehicle equilibrium -------------------------------------------------------------------
def test_equilibrium_at_charging_temperature_is_the_charged_state(capsys):
    code, out, err = _run_cli(["vehicle", "equilibrium", "--temperatures", "25degC", "--json"], capsys)
    assert code == 0, err
    table = json.loads(out)
    assert set(table) == {"axles", "pitch_mrad", "roll_mrad", "total_load_N"}
    assert [a["axle"] for a in table["axles"]] == [1, 2, 3, 4]
    for a in table["axles"]:
        assert set(a) == {"axle", "dh_mm", "N_left_daN", "N_right_daN", "N_mean_daN", "dN_pct"}
        assert abs(a["dh_mm"]) < 0.05 and abs(a["dN_pct"]) < 0.05
    # the loads carry the vehicle's weight (seed 000 Table 2 loads)
    assert table["total_load_N"] == pytest.approx(2 * 10 * (3300 + 3290 + 3420 + 3470), rel=1e-3)


def test_equilibrium_hot_struts_lift_the_hull(capsys):
    code, out, _ = _run_cli(["vehicle", "equilibrium", "--temperatures", "45degC", "--json"], capsys)
    hot = json.loads(out)
    # gas expands with temperature: every axle rises, loads barely change (uniform temperature)
    assert all(a["dh_mm"] > 5.0 for a in hot["axles"])
    assert all(abs(a["dN_pct"]) < 0.5 for a in hot["axles"])
    # uneven: hot front and rear axles carry more than the middle ones (statically indeterminate hull)
    code, out, _ = _run_cli(["vehicle", "equilibrium", "--temperatures", "60degC,25degC,25degC,60degC", "--json"],
                            capsys)
    uneven = json.loads(out)["axles"]
    assert uneven[0]["dN_pct"] > 1 and uneven[3]["dN_pct"] > 1 and uneven[1]["dN_pct"] < -1
    # 8 values: per strut, axle-major, left first -> a hot left side rolls the hull
    code, out, _ = _run_cli(["vehicle", "equilibrium", "--temperatures",
                             "45degC,25degC,45degC,25degC,45degC,25degC,45degC,25degC", "--json"], capsys)
    rolled = json.loads(out)
    assert code == 0 and abs(rolled["roll_mrad"]) > 1.0


@pytest.mark.parametrize("arg", ["25degC,26degC", "25degC,25degC,25degC", "1,2,3,4,5,6,7,8,9"])
def test_equilibrium_wrong_count(capsys, arg):
    code, out, err = _run_cli(["vehicle", "equilibrium", "--temperatures", arg], capsys)
    assert code == 2 and "--temperatures" in err and "1 (all struts), 4 (one per axle) or 8" in err
    assert "Traceback" not in err


def test_equilibrium_bad_unit(capsys):
    code, out, err = _run_cli(["vehicle", "equilibrium", "--temperatures", "25 m"], capsys)
    assert code == 2 and "--temperatures" in err and "'25 m'" in err
