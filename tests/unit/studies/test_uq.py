"""Uncertainty quantification (`hpsim uq`, vehicle.studies.uq, hpsim.priors).

- the study machinery (design, runner, records, SALib analysis) reproduces the analytic Sobol'
  indices of the Ishigami function routed through the same code as the drives;
- priors: units, distributions (SALib's scaling against the analytic quantiles), errors that
  name the file and the key path;
- drawn values reach the vehicle and every strut through the scenario overrides;
- resume: an interrupted study finishes without re-running finished cases, other settings are refused;
- end to end through the CLI on a 200 m drive.
"""
from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
import yaml

from hpsim.errors import UserInputError
from hpsim.priors import collect_priors, parse_prior
from tests.helpers import SHORT_SCENARIO
from vehicle import cli
from vehicle.studies import uq

# --- the Ishigami function: analytic Sobol' indices (Ishigami & Homma 1990; Sobol' & Levitan 1999)
A, B = 7.0, 0.1
ISHIGAMI_PRIORS = "\n".join(f"x{i}: {{value: 0, prior: {{uniform: [-3.141592653589793, 3.141592653589793]}}}}"
                            for i in (1, 2, 3))


def ishigami(case: str, values: dict) -> dict:
    x1, x2, x3 = values["x1"], values["x2"], values["x3"]
    return {"y": math.sin(x1) + A * math.sin(x2) ** 2 + B * x3 ** 4 * math.sin(x1)}


def ishigami_exact():
    V1 = 0.5 * (1 + B * math.pi ** 4 / 5) ** 2
    V2 = A ** 2 / 8
    V13 = B ** 2 * math.pi ** 8 * (1 / 18 - 1 / 50)
    V = V1 + V2 + V13
    return {"S1": [V1 / V, V2 / V, 0.0], "ST": [(V1 + V13) / V, V2 / V, V13 / V], "mean": A / 2, "var": V}


def ishigami_params():
    return uq.parameters_from(collect_priors(yaml.safe_load(ISHIGAMI_PRIORS), "ishigami.yaml"))


def test_ishigami_sobol_indices_match_the_analytic_values(tmp_path):
    exact = ishigami_exact()
    assert exact["S1"][0] == pytest.approx(0.314, abs=1e-3) and exact["ST"][2] == pytest.approx(0.244, abs=1e-3)
    s = uq.run_study(tmp_path / "ishigami", ishigami_params(), ishigami, method="sobol", samples=2048, seed=3, workers=1)
    assert s["cases"] == 2048 * 5 and s["done"] == s["cases"] and not s["failed"]
    rows = {r["parameter"]: r for r in s["sobol"]["y"]["rows"]}
    # tolerance 0.02 (N = 2048; the errors measured over seeds 1-3 were <= 0.007), and the analytic
    # value inside SALib's bootstrap 95 % interval (half-widths 0.02-0.06 here)
    for i, name in enumerate(("x1", "x2", "x3")):
        for index in ("S1", "ST"):
            error = abs(rows[name][index] - exact[index][i])
            assert error < 0.02 and error <= rows[name][f"{index}_conf"] < 0.1, (name, index)
    assert s["most_influential"]["y"][0] == "x1"          # largest total index
    band = s["bands"]["y"]
    assert band["mean"] == pytest.approx(exact["mean"], abs=0.1)
    assert band["sd"] ** 2 == pytest.approx(exact["var"], rel=0.05)
    assert band["p5"] < band["p50"] < band["p95"]
    with open(tmp_path / "ishigami" / "sobol.csv") as fh:
        assert {r["parameter"] for r in csv.DictReader(fh)} == {"x1", "x2", "x3"}


# --- priors ------------------------------------------------------------------------------------
def _prior(text: str, path="p"):
    return parse_prior(yaml.safe_load(text), path, "f.yaml")


def test_prior_units_are_parsed_to_si():
    p = _prior('{value: "450 kg", prior: {uniform: ["0.35 t", "550000 g"]}}')
    assert p.args == pytest.approx((350.0, 550.0)) and p.value == 450.0 and p.unit == "kg"
    t = _prior('{value: "20 degC", prior: {normal: ["21 degC", "3 K"]}}')
    assert t.args == pytest.approx((294.15, 3.0)) and t.value == pytest.approx(293.15)
    c = _prior('{value: "35 kJ/K", prior: {triangular: ["25 kJ/K", "30 kJ/K", "50 kJ/K"]}}')
    assert c.args == pytest.approx((25e3, 30e3, 50e3))
    bare = _prior('{value: 0.7, prior: {uniform: [0.6, 0.8]}}')
    assert bare.unit == "" and bare.override(0.65) == 0.65
    # the value written into a case parses back to the drawn SI value in the field's own unit
    from hpsim.units import parse_quantity

    assert parse_quantity(c.override(41234.5), "J/K") == pytest.approx(41234.5, rel=1e-11)
    assert parse_quantity(t.override(300.0), "K") == pytest.approx(300.0, rel=1e-12)


@pytest.mark.parametrize("text", [
    '{value: "450 kg", prior: {triangular: ["350 kg", "380 kg", "550 kg"]}}',
    '{value: "1e-5 N/Pa", prior: {lognormal: ["1e-5 N/Pa", 3]}}',
    '{value: "20 degC", prior: {normal: ["20 degC", "2 K"]}}',
    '{value: "2 kN*s/m", prior: {uniform: ["1 kN*s/m", "4 kN*s/m"]}}',
])
def test_salib_draws_follow_the_prior(text):
    """SALib's scaling (triangular peak as a fraction, lognormal in ln space) against scipy's quantiles."""
    p = _prior(text)
    par = uq.Parameter(name="p", prior=p, paths=("p",))
    x = uq.design([par], "lhs", 4000, seed=5)[:, 0]
    q = np.array([0.05, 0.5, 0.95])
    assert np.quantile(x, q) == pytest.approx(p.ppf(q), rel=0.01)


@pytest.mark.parametrize("text, message", [
    ('{value: "450 kg", prior: {uniform: ["550 kg", "350 kg"]}}',
     "f.yaml: axles.0.unsprung_mass.prior.uniform: low (550 kg) must be below high (350 kg)"),
    ('{value: "600 kg", prior: {uniform: ["350 kg", "550 kg"]}}',
     "f.yaml: axles.0.unsprung_mass.prior.uniform: the value 600 kg lies outside the prior's range [350 kg, 550 kg]"),
    ('{value: "450 kg", prior: {uniform: ["350 m", "550 kg"]}}',
     "f.yaml: axles.0.unsprung_mass.prior.uniform[0] (low): '350 m' has units of [length], expected kilogram"),
    ('{value: "450 kg", prior: {gaussian: ["450 kg", "50 kg"]}}',
     "f.yaml: axles.0.unsprung_mass.prior: unknown key 'gaussian'"),
    ('{value: "450 kg", prior: {uniform: ["350 kg"]}}',
     "f.yaml: axles.0.unsprung_mass.prior.uniform: expected a list [low, high]"),
    ('{value: "20 degC", prior: {normal: ["20 degC", "2 degC"]}}',
     "a temperature's standard deviation is a difference: give it in K"),
    ('{value: "1e-5 N/Pa", prior: {lognormal: ["1e-5 N/Pa", 0.5]}}',
     "the factor (geometric standard deviation) must be > 1, got 0.5"),
    ('{value: "450 kg", prior: {triangular: ["350 kg", "600 kg", "550 kg"]}}',
     "mode (600 kg) must be in [350 kg, 550 kg]"),
])
def test_bad_prior_names_file_key_and_value(text, message):
    with pytest.raises(UserInputError) as exc:
        collect_priors({"axles": [{"unsprung_mass": yaml.safe_load(text)}]}, "f.yaml")
    assert message in str(exc.value)


def test_prior_without_value_and_mismatched_shared_priors_are_refused():
    with pytest.raises(UserInputError, match=r"f.yaml: tyre.stiffness: a prior needs the value next to it"):
        collect_priors({"tyre": {"stiffness": {"prior": {"uniform": [1, 2]}}}}, "f.yaml")
    data = {"a": {"value": 1, "prior": {"uniform": [0, 2], "shared": "m"}},
            "b": {"value": 1, "prior": {"uniform": [0, 3], "shared": "m"}}}
    with pytest.raises(UserInputError, match=r"f.yaml: b.prior: shared 'm' with a but the distributions differ"):
        uq.parameters_from(collect_priors(data, "f.yaml"))


def test_shipped_files_load_at_their_values_and_carry_the_required_priors():
    from hpsim.config import load_yaml
    from struts.params import load_strut, strut_file
    from vehicle.physics.params import load_vehicle, vehicle_file

    assert load_vehicle("apc_8x8").axles[0].unsprung_mass == 450.0        # `prior` is ignored by the loaders
    assert load_strut("apc").friction.pressure_coefficient == pytest.approx(1.01e-5)
    vehicle = {p.path: p for p in collect_priors(load_yaml(vehicle_file("apc_8x8")), "apc_8x8")}
    strut = {p.path: p for p in collect_priors(load_yaml(strut_file("apc")), "apc")}
    assert "friction.pressure_coefficient" in strut            # fitted but not identified (CI 0..inf)
    assert "heat.air_speed_ratio" not in vehicle                # the calibrated parameter: no prior
    assert {vehicle[f"axles.{k}.unsprung_mass"].shared for k in range(4)} == {"unsprung_mass"}
    for p in list(vehicle.values()) + list(strut.values()):
        assert p.note, f"{p.path}: a prior needs its reasoning in `source`"


# --- scenario -> parameters -> case overrides ------------------------------------------------------
SCENARIO = SHORT_SCENARIO + "output: {interval: 1 s, stats_interval: 0.1 km}\n"


def _source(text: str):
    from vehicle.scenario.schema import read_scenario_text

    return read_scenario_text(text, "s.yaml", ".")


def test_drawn_values_reach_the_vehicle_and_every_strut():
    from struts.params import load_strut
    from vehicle.scenario.schema import ScenarioSource, prepare

    src = _source(SCENARIO)
    params, notes, _ = uq.scenario_parameters(src)
    names = [p.name for p in params]
    assert "vehicle.unsprung_mass" in names and "struts.all.friction.pressure_coefficient" in names
    assert not any(n.startswith("vehicle.compensation.") for n in names) and "compensation is off" in notes[0]
    params = uq.select(params, ["unsprung_mass", "tyre.stiffness", "axles.3.position", "struts.all.friction.*"])
    values = {p.name: float(p.prior.ppf(0.9)) for p in params}
    data = uq.case_scenario(src.data, params, values, distance="150 m")
    prep = prepare(ScenarioSource(text="", name="case", base_dir=src.base_dir, data=data))
    V = prep.vehicle
    assert prep.scenario.distance == 150.0
    assert [a.unsprung_mass for a in V.axles] == pytest.approx([values["vehicle.unsprung_mass"]] * 4, rel=1e-10)
    assert V.tyre.stiffness == pytest.approx(values["vehicle.tyre.stiffness"], rel=1e-10)
    assert V.axles[3].position == pytest.approx(values["vehicle.axles.3.position"], rel=1e-10)
    for axle in V.axles:
        s = load_strut(axle.strut, axle.strut_overrides)
        assert s.friction.pressure_coefficient == pytest.approx(
            values["struts.all.friction.pressure_coefficient"], rel=1e-10)
        assert s.friction.stribeck_velocity == pytest.approx(values["struts.all.friction.stribeck_velocity"], rel=1e-10)


def test_scenario_overrides_decide_what_is_drawn():
    # a value the scenario fixes is not drawn; an axle whose strut differs is drawn on its own
    src = _source(SCENARIO.replace("vehicle: {name: apc_8x8}",
                                   "vehicle: {name: apc_8x8, overrides: {tyre.stiffness: 1.2 MN/m}}\n"
                                   "struts: {axle2: {overrides: {valve.check_dp_crack: 0.2 MPa}}}\n"
                                   "compensation: {enabled: true}"))
    names = [p.name for p in uq.scenario_parameters(src)[0]]
    assert "vehicle.tyre.stiffness" not in names and "vehicle.compensation.flow_limit" in names
    assert "struts.axle1+axle3+axle4.valve.check_dp_crack" in names
    assert "struts.axle2.valve.check_dp_full" in names and "struts.axle2.valve.check_dp_crack" not in names
    per_axle = [p.name for p in uq.scenario_parameters(_source(SCENARIO), per_axle_struts=True)[0]]
    assert {f"struts.axle{k}.friction.viscous" for k in (1, 2, 3, 4)} <= set(per_axle)
    with pytest.raises(UserInputError, match=r"--parameters: 'tyre.stifness' matches no prior"):
        uq.select(uq.scenario_parameters(_source(SCENARIO))[0], ["tyre.stifness"])


def test_prcc_finds_the_monotonic_driver():
    par = [uq.Parameter(name=n, prior=_prior('{value: 0.5, prior: {uniform: [0, 1]}}'), paths=(n,)) for n in "ab"]
    X = uq.design(par, "lhs", 200, seed=2)
    r = uq.prcc(X, np.exp(3 * X[:, 0]))          # y depends on a only, monotonically
    assert r[0] == pytest.approx(1.0, abs=1e-9) and abs(r[1]) < 0.2


# --- resume ----------------------------------------------------------------------------------------
class Interrupting:
    """Ishigami, but Ctrl-C after `stop_after` cases; records which cases ran."""

    def __init__(self, stop_after=None):
        self.stop_after, self.ran = stop_after, []

    def __call__(self, case, values):
        if self.stop_after is not None and len(self.ran) == self.stop_after:
            raise KeyboardInterrupt
        self.ran.append(case)
        return ishigami(case, values)


def test_an_interrupted_study_resumes_without_rerunning_finished_cases(tmp_path):
    out = tmp_path / "study"
    first = Interrupting(stop_after=7)
    with pytest.raises(KeyboardInterrupt):
        uq.run_study(out, ishigami_params(), first, method="sobol", samples=16, seed=1, workers=1)
    assert len(first.ran) == 7 and (out / "samples.csv").exists()
    second = Interrupting()
    s = uq.run_study(out, ishigami_params(), second, method="sobol", samples=16, seed=1, workers=1)
    assert not set(first.ran) & set(second.ran)
    assert len(first.ran) + len(second.ran) == 16 * 5 + 1 and s["done"] == 80
    fresh = uq.run_study(tmp_path / "fresh", ishigami_params(), ishigami, method="sobol", samples=16, seed=1, workers=1)
    assert s["sobol"] == fresh["sobol"] and s["bands"] == fresh["bands"]
    with pytest.raises(UserInputError) as exc:
        uq.run_study(out, ishigami_params(), ishigami, method="sobol", samples=16, seed=2, workers=1)
    assert f"{out}: holds a study made with other settings: seed 1 (now 2)" in str(exc.value)


# --- the command, end to end -------------------------------------------------------------------
def test_uq_command_rejects_bad_settings_with_one_line(tmp_path, capsys):
    (tmp_path / "s.yaml").write_text(SCENARIO)
    assert cli.main(["uq", str(tmp_path / "s.yaml"), "--samples", "20", "-o", str(tmp_path / "u")]) == 2
    err = capsys.readouterr().err
    assert "the Sobol' (Saltelli) design needs a power of 2, got 20 (use 16 or 32)" in err and err.count("\n") == 1
    assert cli.main(["uq", str(tmp_path / "s.yaml"), "--list", "--samples", "16"]) == 0
    out = capsys.readouterr().out
    assert "struts.all.friction.pressure_coefficient" in out and "air_speed_ratio" not in out


def test_tiny_drive_study_end_to_end(tmp_path, capsys):
    from vehicle.results.run import run_scenario
    from vehicle.analysis.summary import report

    scen = tmp_path / "s.yaml"
    scen.write_text(SCENARIO.replace("200 m", "1 km"))
    out = tmp_path / "study"
    args = ["uq", str(scen), "--samples", "2", "--method", "lhs", "--distance", "200 m", "--workers", "1",
            "--parameters", "tyre.contact_length,friction.pressure_coefficient", "-o", str(out), "--json"]
    assert cli.main(args) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["done"] == 2 and s["nominal_done"] and s["failed"] == []
    for name in ("samples.csv", "bands.csv", "ranking.csv", "summary.json", "bands.png", "ranking.png",
                 "cases/nominal.h5", "cases/s00000.h5", "cases/s00001.h5"):
        assert (out / name).stat().st_size > 0, name
    assert set(s["outputs"]) >= {f"axle{k}.{q}" for k in (1, 2, 3, 4) for q in ("rise_K", "dh_mm", "dN_pct")}
    for b in s["bands"].values():
        assert b["p5"] <= b["p50"] <= b["p95"]
    # the drawn friction coefficient is the one the case's struts ran with
    with open(out / "samples.csv") as fh:
        rows = {r["case"]: r for r in csv.DictReader(line for line in fh if not line.startswith("#"))}
    rep = report(out / "cases" / "s00001.h5")
    import h5py

    with h5py.File(out / "cases" / "s00001.h5", "r") as f:
        resolved = json.loads(f["scenario"].attrs["resolved_json"])
    fp = float(rows["s00001"]["struts.all.friction.pressure_coefficient"])
    assert [resolved["struts"][f"axle{k}"]["friction"]["pressure_coefficient"] for k in (1, 2, 3, 4)] == \
        pytest.approx([fp] * 4, rel=1e-10)
    assert resolved["scenario"]["distance"] == 200.0 and rep["complete"]
    # the nominal case is the scenario as written (the priors' values change nothing)
    direct = tmp_path / "direct.h5"
    scen.write_text(SCENARIO)
    run_scenario(scen, direct, progress=False)
    assert s["nominal"]["mean_rise_K"] == pytest.approx(report(direct)["mean_temperature_rise_K"], abs=1e-9)
    # a re-run finds every case done and runs nothing
    assert cli.main(args) == 0
    assert json.loads(capsys.readouterr().out)["ran_now"] == 0


def test_the_ranking_plot_marks_the_bars_its_text_calls_noise(tmp_path):
    """A toy study whose output follows a and not c: c's bar is hatched and faded and the panel says why (its
    interval for all parameters at once includes 0, the line of `uq` says 'not resolved'); a's bar is not."""
    import json as _json

    import yaml as _yaml

    from hpsim.priors import collect_priors as _collect
    from vehicle.presentation.plots import pyplot
    from vehicle.presentation.uq_plots import _mark_unresolved, sensitivity_plot
    from vehicle.studies.confidence import ranked

    priors = _yaml.safe_load("a: {value: 1, prior: {uniform: [0, 2]}}\nc: {value: 1, prior: {uniform: [0, 2]}}")
    params = uq.parameters_from(_collect(priors, "toy.yaml"))
    uq.run_study(tmp_path / "study", params, lambda case, v: {"axle1.rise_K": 3 * v["a"] + 0.0 * v["c"]},
                 method="sobol", samples=32, seed=1, workers=1)
    summary = _json.loads((tmp_path / "study" / "summary.json").read_text())
    resolved = {r["parameter"]: r["resolved"] for r in ranked(summary, "axle1.rise_K")[1]}
    assert resolved["a"] and not resolved["c"]
    fig, ax = pyplot().subplots()
    bars = [ax.barh([0, 1], [0.0, 1.0])]
    note = _mark_unresolved(summary, "axle1.rise_K", ["c", "a"], bars)
    assert "not resolved" in note and bars[0].patches[0].get_hatch() and not bars[0].patches[1].get_hatch()
    pyplot().close(fig)
    assert sensitivity_plot(summary, tmp_path / "rank.png").stat().st_size > 10_000
