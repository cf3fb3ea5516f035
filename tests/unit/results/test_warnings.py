"""Validity warnings (vehicle.results.validity), each provoked by a small drive made to provoke it.

* hot: struts started at 190 degC on a class E road (a tiny version of the class E case of
  scenarios/compensation_sweep.yaml, whose struts reach 167-213 degC): the gas pushes every strut
  onto its rebound stop standing, before and after the drive; seal and oil limits and the oil
  data's range are exceeded; the stops take energy while driving.
* cold: -40 degC and gas charges 3.6 MPa short: the struts rest on the bump stop; the seals are
  below their limit and the oil below its data.
* benign: 45 degC on a class C road: nothing to say.
Warnings the drive's statistics rows make possible (time on the stops, tyre lift-off, the
solver's error estimate) are checked when the rows carry their keys.
"""
from __future__ import annotations

import csv
import shutil
import json

import numpy as np
import h5py
import pytest

from struts.params import load_strut
from vehicle.presentation.report import format_report
from vehicle.physics.outputs import variable_name
from vehicle.results import validity as W
from vehicle.results.reader import open_results
from vehicle.results.run import run_scenario
from vehicle.scenario.schema import read_scenario_text
from vehicle.analysis.summary import report

SCENARIOS = {
    "hot": """\
description: struts started at 190 degC on a class E road
vehicle: {name: apc_8x8}
road: {iso_class: E, seed: 2}
speed: 20 km/h
distance: 0.3 km
ambient_temperature: 25 degC
initial_temperatures: 190 degC
output: {interval: 0.1 s, stats_interval: 0.1 km}
""",
    "cold": """\
description: under-charged struts at -40 degC resting on the bump stop
vehicle: {name: apc_8x8, overrides: {charging.fill_pressure_offset: -3.6 MPa}}
road: {iso_class: A, seed: 2}
speed: 10 km/h
distance: 0.05 km
ambient_temperature: -40 degC
output: {interval: 0.1 s, stats_interval: 0.05 km}
""",
    "benign": """\
description: warm struts on a smooth road
vehicle: {name: apc_8x8}
road: {iso_class: C, seed: 2}
speed: 20 km/h
distance: 0.2 km
ambient_temperature: 45 degC
output: {interval: 0.1 s, stats_interval: 0.1 km}
""",
}


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("warnings")
    out = {}
    for name, text in SCENARIOS.items():
        path = d / f"{name}.h5"
        run_scenario(read_scenario_text(text, f"{name}.yaml", d), path, progress=False)
        out[name] = path
    return out


def _by_code(path):
    with open_results(path) as r:
        found = W.check(r)
    codes = {}
    for w in found:
        codes.setdefault(w["code"], []).append(w)
    return found, codes


def test_hot_struts_rest_on_the_rebound_stop_and_exceed_their_limits(runs):
    found, codes = _by_code(runs["hot"])
    limits = load_strut("apc").limits
    stations = [f"axle{k}_{s}" for k in range(1, 5) for s in ("left", "right")]
    on_stop = codes["equilibrium_on_stop"]
    assert len(on_stop) == 2                                   # before and after the drive
    assert [w["km"] for w in on_stop] == [0.0, pytest.approx(0.3)]
    for w in on_stop:
        assert "rebound stop" in w["message"] and w["struts"] == stations and w["value"] <= 0.5
    seal, = codes["seal_temperature"]
    # the seal limit applies to the hotter of the oil and the wall (heat network): the hottest seen, which
    # the valves' heat raises above the 190 degC start during the drive
    with h5py.File(runs["hot"], "r") as f:
        hottest = np.max(np.maximum(f["timeseries/oil_temperature"][()], f["timeseries/wall_temperature"][()])) - 273.15
    assert seal["value"] == pytest.approx(hottest) and hottest >= 190.0
    assert seal["limit"] == pytest.approx(limits.seal_max_temperature - 273.15)
    assert "above the seal limit (100 degC)" in seal["message"] and seal["km"] < 0.01
    assert codes["oil_temperature"][0]["limit"] == pytest.approx(135.0)
    assert codes["oil_data_range"][0]["severity"] == "note"
    stop_energy, = codes["end_stop_energy"]
    assert stop_energy["km"] in (pytest.approx(0.1), pytest.approx(0.2), pytest.approx(0.3))
    # the warnings are in the file, the report (table and JSON) and its text
    with h5py.File(runs["hot"], "r") as f:
        stored = json.loads(f["summary"].attrs["warnings_json"])
        cell = f["summary"].attrs["warnings"]
    assert [w["code"] for w in stored] == [w["code"] for w in found]
    assert "equilibrium_on_stop(all struts@0.000km)" in cell
    rep = report(runs["hot"])
    assert [w["code"] for w in rep["warnings"]] == [w["code"] for w in found]
    text = format_report(rep)
    assert "warning: the standing equilibrium after the drive rests on the rebound stop" in text


def test_cold_under_charged_struts_rest_on_the_bump_stop(runs):
    _, codes = _by_code(runs["cold"])
    stroke = load_strut("apc").geometry.stroke
    for w in codes["equilibrium_on_stop"]:
        assert "bump stop" in w["message"] and w["value"] >= 1e3 * stroke - 0.5
    seal, = codes["seal_temperature"]
    assert "below the seal limit (-30 degC)" in seal["message"]
    assert "below" in codes["oil_data_range"][0]["message"]
    assert "oil_temperature" not in codes


def test_benign_drive_has_no_warnings(runs):
    found, _ = _by_code(runs["benign"])
    assert found == []


def test_rows_with_stop_time_lift_off_and_solver_error(runs):
    """Time on the stops and tyre lift-off come from the drive's statistics rows, the solver's error estimate from
    the summary: the hot drive carries all three, and with thresholds of zero each is flagged."""
    with open_results(runs["hot"]) as r:
        for key in ("end_stop_time_s", "lift_off_share"):
            assert r.stats_series(variable_name(key)) is not None, key
        assert W._Data(r).summary_value("solver_error_estimate") is not None
        strict = W.Thresholds(end_stop_time_share=0.0, lift_off_share=0.0, solver_error=0.0)
        codes = {w["code"] for w in W.check(r, strict)}
    assert {"end_stop_time", "tyre_lift_off", "solver_error"} <= codes, codes


def test_sweep_summary_has_a_warnings_column(runs, tmp_path):
    from vehicle.studies.sweep import summarise

    cases = [{"name": n, "overrides": {"case": n}, "file": runs[n]} for n in ("hot", "benign")]
    result = summarise(tmp_path / "sweep.yaml", tmp_path, cases, {n: {"status": "done"} for n in ("hot", "benign")})
    with open(result["summary_csv"], newline="") as fh:
        rows = {r["case"]: r for r in csv.DictReader(fh)}
    assert "seal_temperature(all struts@" in rows["hot"]["warnings"]
    assert rows["benign"]["warnings"] == ""


def test_the_run_records_its_warnings_and_a_report_checks_again(runs, tmp_path):
    """The run checks the file it finishes and records the warnings in /summary (in the same write as the summary);
    a report checks the data again rather than believe the record (an edited record saying "no warnings" changes
    nothing)."""
    with open_results(runs["hot"]) as r:
        found = W.check(r)
        recorded = json.loads(r.summary_attrs()["warnings_json"])
    assert found and recorded == json.loads(json.dumps(found))
    edited = tmp_path / "edited.h5"                      # a file whose record says: no warnings
    shutil.copy(runs["hot"], edited)
    with h5py.File(edited, "r+") as f:
        f["summary"].attrs["warnings_json"] = "[]"
    assert report(edited)["warnings"] == found
    assert report(runs["hot"])["warnings"] == found
