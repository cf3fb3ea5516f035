"""Issue 27, the Python API fails as clearly as the CLI: NumPy numbers accepted, overrides only as a mapping, the
scenario mapping copied at construction, relative paths from a stated base, unknown names listing the valid ones,
a closed Results saying so; every error a UserInputError with the CLI's one-line message."""
from __future__ import annotations

import numpy as np
import pytest
import yaml

import vehicle
from hpsim.errors import UserInputError
from vehicle.api import UnknownName

from tests.integration.test_fuzz import SCENARIO


@pytest.fixture
def scenario():
    return yaml.safe_load(SCENARIO)


def test_numpy_numbers_are_numbers(scenario):
    scenario["distance"] = np.float64(60.0)
    scenario["initial_temperatures"] = np.array([298.15, 299.15, 300.15, 301.15])   # K (SI)
    sim = vehicle.Simulation(scenario, overrides={"solver.dt": np.float64(0.004), "output.chunk_samples": np.int64(64)})
    S = sim.scenario
    assert S.distance == 60.0 and S.solver.dt == pytest.approx(0.004)
    assert S.output.chunk_samples == 64 and len(S.initial_temperatures) == 4


@pytest.mark.parametrize("overrides", ["speed: 30 km/h", ["speed", "30 km/h"], 3, ("speed", "30 km/h")])
def test_overrides_must_be_a_mapping(scenario, overrides):
    with pytest.raises(UserInputError, match="overrides: expected a mapping") as exc:
        vehicle.Simulation(scenario, overrides=overrides)
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize("value,says", [(object(), "not a scenario value"), ({1, 2}, "not a scenario value")])
def test_values_that_are_not_scenario_values(scenario, value, says):
    scenario["speed"] = value
    with pytest.raises(UserInputError, match=says):
        vehicle.Simulation(scenario)


def test_a_tuple_is_a_list_and_checked_as_one(scenario):
    scenario["speed"] = (20.0, "km/h")
    with pytest.raises(UserInputError, match="speed"):
        vehicle.Simulation(scenario)


def test_the_scenario_mapping_is_copied_and_paths_refer_to_the_stated_base(scenario, tmp_path, monkeypatch):
    csv = tmp_path / "road.csv"
    csv.write_text("distance_m,left_m,right_m\n" + "".join(f"{0.05 * i:.2f},0,0\n" for i in range(2000)))
    scenario["road"] = {"csv": "road.csv"}
    sim = vehicle.Simulation(scenario, base_dir=tmp_path)
    scenario["distance"] = "600 m"
    scenario["road"]["csv"] = "elsewhere.csv"
    assert sim.scenario.distance == 60.0
    assert sim.prepared.road().length_m >= 60.0                       # read from tmp_path, not the cwd
    monkeypatch.chdir(tmp_path)
    scenario["road"]["csv"] = "road.csv"
    elsewhere = tmp_path / "sub"
    elsewhere.mkdir()
    with pytest.raises(UserInputError, match=str(elsewhere / "road.csv")):
        vehicle.Simulation(scenario, base_dir=elsewhere).prepared.road()


def test_the_api_message_is_the_cli_message(scenario, tmp_path, capsys):
    from vehicle import cli

    scenario["speed"] = "900 km/h"
    with pytest.raises(UserInputError) as exc:
        vehicle.Simulation(scenario)
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(scenario))
    assert cli.main(["run", str(path), "-o", str(tmp_path / "o.h5"), "--no-progress"]) == 2
    cli_message = capsys.readouterr().err.strip()
    tail = str(exc.value).split(": ", 1)[1]           # the same after the name of the scenario
    assert cli_message.endswith(tail)


def test_unknown_names_list_the_valid_ones_and_closed_results_say_so(scenario, tmp_path):
    res = vehicle.Simulation(scenario).run(out=tmp_path / "o.h5")
    for call, what in ((lambda: res.series("nonexistent"), "time series"), (lambda: res.stats("nope"), "statistics"),
                       (lambda: res.to_xarray("nonexistent"), "group")):
        with pytest.raises(UnknownName, match=f"no {what}") as exc:
            call()
        assert isinstance(exc.value, KeyError) and isinstance(exc.value, UserInputError)
    with pytest.raises(KeyError, match="strut_temperature"):
        res.series("strut_temperatur")
    assert res.series("strut_temperature").shape[0] == res.series("time").shape[0]
    res.close()
    res.close()
    for call in (res.summary, lambda: res.series("time"), lambda: res.to_xarray("stats")):
        with pytest.raises(UserInputError, match="closed; open them again with vehicle.open_results"):
            call()
    assert "closed" in repr(res)
