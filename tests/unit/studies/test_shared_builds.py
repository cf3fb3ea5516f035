"""The cases of a study's worker process share the model, vehicle check and road of one vehicle
(vehicle.engines.shared_builds): each case's results equal, bit for bit, the same case run alone in a fresh
process state, and a case of another vehicle (another parameter value) gets its own model."""
from __future__ import annotations

import importlib.util

import pytest
import yaml

from hpsim.errors import UserInputError
from tests.helpers import BASE_SCENARIO, REPO
from vehicle.engines.build import build_engine
from vehicle.engines.shared_builds import SharedBuilds, process_builds
from vehicle.physics.weighing import weighing_solver
from vehicle.results.run import run_scenario
from vehicle.scenario.schema import prepare, read_scenario_text
from vehicle.studies.sweep import run_case


def _compare_h5():
    """benchmarks/compare_results.py's comparison of two files: every numeric dataset and attribute, bit for bit
    (timings, dates and paths left out)."""
    spec = importlib.util.spec_from_file_location("compare_results", REPO / "benchmarks" / "compare_results.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.compare_h5


def _source(name: str, tmp_path, **changes):
    data = {**BASE_SCENARIO, "distance": "150 m", "output": {"interval": "0.5 s", "stats_interval": "50 m"}, **changes}
    return read_scenario_text(yaml.safe_dump(data, sort_keys=False), name, tmp_path)


# a: the base; b: the same vehicle on the same road at another speed (the model, check, road and the weighing
# before the drive shared with a); c: another bleed area (its own model, a's road); d: another road seed (a's
# model, its own road)
CASES = {"a": {}, "b": {"speed": "26 km/h"},
         "c": {"struts": {"all": {"overrides": {"valve.bleed_area": "1.5e-5 m^2"}}}},
         "d": {"road": {"iso_class": "D", "seed": 4}}}


def test_cases_sharing_a_vehicle_equal_each_case_run_alone(tmp_path):
    compare_h5 = _compare_h5()
    (tmp_path / "alone").mkdir()
    (tmp_path / "shared").mkdir()
    for name, changes in CASES.items():              # alone: every part built for the drive
        run_scenario(_source(name, tmp_path, **changes), tmp_path / "alone" / f"{name}.h5", progress=False)
    builds = SharedBuilds()
    for name, changes in CASES.items():              # one after the other in this process, as a worker runs them
        run_scenario(_source(name, tmp_path, **changes), tmp_path / "shared" / f"{name}.h5", progress=False,
                     shared=builds)
    for name in CASES:
        assert compare_h5(tmp_path / "alone" / f"{name}.h5", tmp_path / "shared" / f"{name}.h5") == [], name
    # b and d drove a's model and had its check (c has its own), b and c drove a's road (d has another seed)
    assert builds.hits == {"model": 2, "check": 2, "road": 2}
    # and c's results are its own, not a's
    assert compare_h5(tmp_path / "alone" / "a.h5", tmp_path / "alone" / "c.h5") != []


def test_a_model_is_shared_by_the_drives_of_one_vehicle_only(tmp_path):
    builds = SharedBuilds()
    model_a, _ = build_engine(prepare(_source("a", tmp_path)), shared=builds)
    assert build_engine(prepare(_source("b", tmp_path, **CASES["b"])), shared=builds)[0] is model_a
    model_c, _ = build_engine(prepare(_source("c", tmp_path, **CASES["c"])), shared=builds)
    assert model_c is not model_a and model_c.structure == model_a.structure      # one compiled model, two vehicles
    assert model_c.struts[0].p.valve.bleed_area == 1.5e-5 != model_a.struts[0].p.valve.bleed_area


def test_a_repeated_weighing_is_a_copy(tmp_path):
    model, drive = build_engine(prepare(_source("a", tmp_path)))
    solver = weighing_solver(model)
    first = solver.bands(300.0, drive.gas_masses)
    first["wheel_loads"]["low"][:] = 0.0              # a caller changing its result changes no later weighing
    again = solver.bands(300.0, drive.gas_masses)
    assert again["wheel_loads"]["low"].min() > 0.0


def test_a_refused_vehicle_is_refused_for_every_case_with_its_own_name(tmp_path):
    builds = SharedBuilds()
    for name in ("first.yaml", "second.yaml"):
        prep = prepare(_source(name, tmp_path, struts={"all": {"type": "yin2023"}}))
        with pytest.raises(UserInputError, match=rf"^{name}: vehicle check: axles.0.strut: strut yin2023 is too small"):
            build_engine(prep, shared=builds)
    assert builds.hits["check"] == 1


def test_a_sweep_worker_shares_between_its_cases(tmp_path):
    text = yaml.safe_dump({**BASE_SCENARIO, "distance": "100 m"})
    before = dict(process_builds().hits)
    for k in range(2):
        r = run_case(text, f"case{k}", str(tmp_path), str(tmp_path / f"case{k}.h5"))
        assert r["status"] == "done", r
    assert process_builds().hits["model"] > before["model"] and process_builds().hits["road"] > before["road"]
