"""`hpsim optimize` end to end: bad study files refused with one line naming the key (exit 2), and a small study of
short drives whose Pareto designs are vehicle files that pass `hpsim vehicle check` and drive with `hpsim run`."""
import csv
import json
from pathlib import Path

import pytest

from vehicle import cli
from vehicle.numerics.lanes import LaneStepper
from vehicle.studies.optimize_runner import DriveEvaluator
from vehicle.studies.optimize_study import load_study

pytest.importorskip("optuna")

ROOT = Path(__file__).resolve().parents[2]
BLEED = "struts.all.overrides.valve.bleed_area"
STUDY = f"""
base: {ROOT / 'scenarios' / 'quick_demo.yaml'}
cases:
  - {{name: ride, distance: 300 m, speed: 30 km/h}}
design:
  {BLEED}: {{range: [6e-6 m^2, 3e-5 m^2], log: true}}
  vehicle.overrides.charging.fill_pressure_offset: [-0.3 MPa, 0.3 MPa]
objectives:
  ride.seats.driver.weighted_rms_acceleration_m_s2: {{case: ride, goal: min}}
  max(ride.stations.dynamic_load_coefficient): {{case: ride, goal: min}}
constraints:
  max(ride.stations.end_stop_time_s) <= 0: {{case: ride}}
trials: 3
population: 3
"""


def _write(tmp_path, text: str) -> Path:
    path = tmp_path / "study.yaml"
    path.write_text(text)
    return path


def _refused(tmp_path, capsys, text: str, *extra) -> str:
    code = cli.main(["optimize", str(_write(tmp_path, text)), "-o", str(tmp_path / "out"), "--yes", *extra])
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert err.splitlines()[-1].startswith("hpsim optimize: error: ") and "Traceback" not in err
    assert sum("error" in line for line in err.splitlines()) == 1        # progress lines before it, one error
    return err.splitlines()[-1]


@pytest.mark.parametrize("old, new, named", [
    (f"{BLEED}: {{range: [6e-6 m^2, 3e-5 m^2], log: true}}", "vehicle.overrides.charging.no_such_key: [0 MPa, 1 MPa]",
     "design.vehicle.overrides.charging.no_such_key"),
    ("[6e-6 m^2, 3e-5 m^2]", "[6e-6, 3e-5]", f"design.{BLEED}: bounds need units"),
    (f"{BLEED}:", "struts.all.overrides.valve.no_such_area:", "design.struts.all.overrides.valve.no_such_area"),
    ("constraints:", "  tyre: {path: 'max(ride.stations.dynamic_load_coefficient)', case: ride, goal: max}\nconstraints:",
     "objectives.tyre: goal max conflicts"),
    ("{case: ride, goal: min}\n  max(", "{case: nope, goal: min}\n  max(", "case: no case 'nope'"),
    ("goal: min}\n  max(", "goal: lowest}\n  max(", "goal: expected min or max"),
])
def test_bad_study_files_are_refused_naming_the_key(tmp_path, capsys, old, new, named):
    assert old in STUDY
    assert named in _refused(tmp_path, capsys, STUDY.replace(old, new, 1))
    assert not (tmp_path / "out").exists()             # nothing written


def test_an_empty_design_and_bad_arguments_are_refused(tmp_path, capsys):
    empty = STUDY.split("design:")[0] + "design: {}\nobjectives:" + STUDY.split("objectives:")[1]
    assert "design: empty" in _refused(tmp_path, capsys, empty)
    assert "--trials" in _refused(tmp_path, capsys, STUDY, "--trials", "0")
    assert "--workers" in _refused(tmp_path, capsys, STUDY, "--workers", "0")


def test_an_objective_the_report_does_not_hold_is_refused_before_the_study(tmp_path, capsys):
    text = STUDY.replace("ride.seats.driver.weighted_rms_acceleration_m_s2", "ride.seats.driver.comfort_index")
    err = _refused(tmp_path, capsys, text)
    assert "objectives.ride.seats.driver.comfort_index" in err and "weighted_rms_acceleration_m_s2" in err
    assert not (tmp_path / "out" / "study.db").exists()


def test_a_failed_drive_is_a_failed_trial_with_its_reason(tmp_path):
    study = load_study(_write(tmp_path, STUDY))
    design = {BLEED: 1e-5, "vehicle.overrides.charging.fill_pressure_offset": -60.0}     # below zero charge pressure
    r = DriveEvaluator(study, str(tmp_path))(0, design)
    assert r["status"] == "failed" and "fill_pressure_offset" in r["error"]


@pytest.fixture(scope="module")
def finished_study(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("optimize")
    path = _write(tmp, STUDY)
    code = cli.main(["optimize", str(path), "-o", str(tmp / "out"), "--workers", "1", "--ensemble", "1", "--yes",
                     "--json"])
    assert code == 0
    return tmp


def _trials(folder: Path) -> list[dict]:
    with open(folder / "trials.csv", newline="") as fh:
        return [{k: v for k, v in row.items() if k not in ("seconds", "vehicle_file")} for row in csv.DictReader(fh)]


def test_a_generation_on_ensemble_lanes_gives_the_trials_of_one_by_one(finished_study, monkeypatch):
    """The same study with its generation's three trials as the lanes of one vector step (`--ensemble 4`): the same
    designs, and every objective and margin equal to the trials run one by one to the last printed digit (a lane is
    the scalar engine bit for bit, tests/unit/engines/test_ensemble.py)."""
    out = finished_study / "lanes"
    calls = []                                   # the lane library's block calls: the trials did step together
    advance = LaneStepper.advance
    monkeypatch.setattr(LaneStepper, "advance", lambda self, *a: calls.append(1) or advance(self, *a))
    code = cli.main(["optimize", str(finished_study / "study.yaml"), "-o", str(out), "--workers", "1", "--ensemble",
                     "4", "--yes", "--json"])
    assert code == 0
    lanes, alone = _trials(out), _trials(finished_study / "out")
    assert len(lanes) == 3 and all(r["status"] == "done" for r in lanes), lanes
    assert lanes == alone and calls


def test_the_json_front_names_designs_objectives_constraints_and_vehicle_files(finished_study, capsys):
    cli.main(["optimize", str(finished_study / "study.yaml"), "-o", str(finished_study / "out"), "--yes", "--json"])
    out = json.loads(capsys.readouterr().out)       # run again: nothing to run, the same front
    assert out["trials"] == 3 and out["pareto"]
    for r in out["pareto"]:
        assert list(r["design"]) == [BLEED, "vehicle.overrides.charging.fill_pressure_offset"]
        assert list(r["objectives"]) == ["ride.seats.driver.weighted_rms_acceleration_m_s2",
                                         "max(ride.stations.dynamic_load_coefficient)"]
        assert r["constraints"]["max(ride.stations.end_stop_time_s) <= 0"] >= 0
        assert Path(r["vehicle_file"]).exists()
    with open(finished_study / "out" / "pareto.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert f"{BLEED} [m^2]" in rows[0] and "margin max(ride.stations.end_stop_time_s) <= 0" in rows[0]
    assert {int(r["trial"]) for r in rows} == {r["trial"] for r in out["pareto"]}
    assert (finished_study / "out" / "pareto.png").stat().st_size > 10_000


def test_a_pareto_design_passes_vehicle_check_and_drives(finished_study, capsys):
    front = json.loads((finished_study / "out" / "optimize.json").read_text())["pareto"]
    vehicle_file = front[0]["vehicle_file"]
    assert cli.main(["vehicle", "check", vehicle_file]) == 0
    scenario = finished_study / "drive.yaml"
    scenario.write_text(f"vehicle: {{file: {vehicle_file}}}\nroad: {{iso_class: D, seed: 1}}\nspeed: 30 km/h\n"
                        "distance: 100 m\nambient_temperature: 25 degC\nsolver: {dt: 4 ms}\n")
    assert cli.main(["run", str(scenario), "-o", str(finished_study / "drive.h5"), "--no-progress"]) == 0


def test_the_study_folder_has_an_html_report(finished_study):
    html = finished_study / "report.html"
    assert cli.main(["report", str(finished_study / "out"), "--html", str(html)]) == 0
    text = html.read_text()
    assert "Pareto front" in text and BLEED in text
