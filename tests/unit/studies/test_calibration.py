"""The heat-transfer calibration is reproducible (issue 6): `hpsim calibrate` finds back a known value.

A short version of the mileage scenario is run with a known wheel-bay air speed ratio; its mean
strut temperature rise becomes the target, and the calibration, started from the shipped value,
must recover the ratio (the rise is smooth and monotone in it).
"""
from pathlib import Path

import pytest

from vehicle.studies.calibration import _run, calibrate_heat
from vehicle.scenario.schema import read_scenario
from tests.helpers import REPO

ROOT = REPO


def test_calibration_recovers_a_known_air_speed_ratio(tmp_path):
    # a small heat capacity lets the struts reach their steady state within the short drive, where the
    # rise is set by the heat transfer (~10 K per unit of the ratio); with the real 35 kJ/K the 1.5 km
    # rise is almost all stored heat and the ratio would be identified only to about +-10 %
    text = (ROOT / "scenarios" / "mileage_106km.yaml").read_text().replace("distance: 106 km", "distance: 1.5 km")
    text = text.replace("  overrides: {}", '  overrides: {heat.capacity: "2 kJ/K"}', 1)
    assert "2 kJ/K" in text
    scenario = tmp_path / "short.yaml"
    scenario.write_text(text)
    known = 0.3
    target, _, _ = _run(read_scenario(scenario), "heat.air_speed_ratio", known)
    assert target > 5.0   # the struts really heat up in 1.5 km
    res = calibrate_heat(scenario, target, tol_K=2e-3, log=lambda m: None)
    assert res["value"] == pytest.approx(known, rel=0.03)
    assert abs(res["achieved_rise_K"] - target) < 2e-3
