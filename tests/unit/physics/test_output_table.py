"""The output table (vehicle/physics/outputs.py): one entry is all a new stored series needs. Runs the worked
example of docs/CONTRIBUTING.md ("... a stored output") as written there."""
from __future__ import annotations

import re

import numpy as np
import pytest

from tests.helpers import REPO, scenario_yaml
from vehicle.physics import outputs
from vehicle.physics.outputs import VARIABLES, From, joined, series_keys
from vehicle.results.run import run_in_memory
from vehicle.scenario.schema import read_scenario_text


def _contributing_example() -> str:
    text = (REPO / "docs" / "CONTRIBUTING.md").read_text()
    part = text[text.index("### ... a stored output"):text.index("### ... an engine")]
    return re.search(r"```python\n(.*?)```", part, flags=re.S).group(1)


@pytest.fixture
def with_heave_velocity():
    before = dict(VARIABLES)
    exec(_contributing_example(), {})
    yield
    VARIABLES.clear()
    VARIABLES.update(before)


def test_the_worked_example_adds_a_stored_series_that_is_the_derivative_of_heave(with_heave_velocity, tmp_path):
    assert "heave_velocity_m_per_s" in series_keys() and "heave_velocity_m_per_s" in joined("state")
    # samples every 20 ms so that a central difference of the stored heave resolves the body motion (~1-2 Hz)
    text = scenario_yaml(distance="60 m", output={"interval": "20 ms", "stats_interval": "30 m"})
    sink = run_in_memory(read_scenario_text(text, "s.yaml", tmp_path))
    ds = sink.to_xarray("timeseries")
    v = ds["heave_velocity"]
    assert v.attrs["units"] == "m s-1"
    t, z, w = ds["time"].values, ds["heave"].values, v.values
    dzdt = np.gradient(z, t)
    inner = slice(5, -5)
    # the central difference's error is h^2/6 z''' (h = 20 ms, body modes ~1.5 Hz: ~0.1 %) plus the step's; the
    # tyre's hop (~8 Hz) reaches the hull a little: 5 % of the RMS velocity holds it with margin
    rms = np.sqrt(np.mean(w[inner] ** 2))
    assert rms > 1e-3                                  # the hull moves on a class D road
    assert np.max(np.abs(dzdt[inner] - w[inner])) < 0.05 * np.max(np.abs(w[inner])) + 0.02 * rms


def test_every_time_series_says_how_it_is_computed_and_joined():
    kinds = {"time", "distance", "input", "heat_node", "state", "station_state", "energy", "output", "axle_heights",
             "hull_accelerations"}
    for key in series_keys():
        f = VARIABLES[key].series
        assert f.kind in kinds, key
    # the join corrects what depends on the slow states and leaves time, inputs and accelerations alone
    assert set(joined("quadrature")) == {k for k in series_keys() if k.startswith("energy_")} | {"pump_oil_volume_m3"}
    assert "speed_m_per_s" not in joined("state") + joined("output") + joined("quadrature")
    with pytest.raises(ValueError, match="From.join"):
        From("state", "z", join="sometimes")
    assert outputs.variable_name("strut_temperature_K") == "strut_temperature"
