"""The FMI 2.0 FMUs of `hpsim export fmu` (vehicle.fmu; docs/fmu.md), driven by FMPy as another tool would.

- The strut FMU against the rig (`hpsim strut cycle`, struts.rig: IDAS on the same strut equations, the body held
  at the rig temperature; here the FMU's heat capacity set to 1e12 J/K through FMI so its nodes stay there): energy
  per cycle within 0.5 % and the force trace within 1 % of its range at 0.1 Hz / 50 mm and 1 Hz / 10 mm. Measured:
  0.001 % and 0.005 %, the force within 0.001 % of its range (the fixed 1 ms step's error, far inside the limits).
- The heat the strut puts out per cycle after a long test: the issue asks for a 10 min test (60 cycles at 0.1 Hz:
  benchmarks/fmu.py, 14 s of rig time); here 20 cycles at 1 Hz within 1 %.
- The vehicle FMU against a drive of the quick demo (300 m): identical to rounding for the first seconds; after
  that the seal friction's stick-slip amplifies rounding differences: the drive against itself with another block
  layout (output interval 0.02 s instead of 0.1 s, i.e. other compiled code) differs by 238 N in wheel load
  (0.71 % of the static load) and by the same amount from the FMU; the test allows the issue's 1 % of the static
  load, and 0.05 K of strut temperature (measured 1e-4 K).
- State save/restore, parameters through FMI against the same override in hpsim, and a run in a fresh process
  that cannot import hpsim.
"""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
import textwrap

import fmpy
import fmpy.validation
import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from struts.params import load_strut
from struts.rig import cycle_test
from vehicle.fmu.build import build_fmu
from vehicle.fmu.exports import strut_spec, vehicle_spec
from tests.helpers import REPO
from vehicle.engines.build import build_engine
from vehicle.scenario.schema import apply_overrides, prepare, read_scenario

MEAN_M = 0.115           # seed 000 Table 1 mean deflection
T_RIG_K = 293.15         # the rig temperature (the strut file's charge temperature)
ISOTHERMAL = {"heat.capacity": 1e12}      # the rig holds the strut body at its temperature
CASES = [(0.05, 0.1, 0.01), (0.01, 1.0, 0.002)]      # amplitude [m], frequency [Hz], communication step [s]


class Driven:
    """An FMU instance stepped through FMPy's FMU2Slave: inputs set at each communication point, outputs read
    there (direct feedthrough), then fmi2DoStep."""

    def __init__(self, path, start_values: dict | None = None):
        self.md = read_model_description(str(path))
        self.unzipped = extract(str(path))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.unzipped,
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName="test")
        self.fmu.instantiate()
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        if start_values:
            self.set(start_values)

    def set(self, values: dict):
        self.fmu.setReal([self.vr[k] for k in values], [float(v) for v in values.values()])

    def derivatives(self, values: dict):
        self.fmu.setRealInputDerivatives([self.vr[k] for k in values], [1] * len(values),
                                         [float(v) for v in values.values()])

    def get(self, names) -> np.ndarray:
        return np.array(self.fmu.getReal([self.vr[n] for n in names]))

    def close(self):
        self.fmu.terminate()
        self.fmu.freeInstance()
        shutil.rmtree(self.unzipped, ignore_errors=True)


@pytest.fixture(scope="module")
def strut_fmu(tmp_path_factory):
    path = tmp_path_factory.mktemp("fmu") / "apc.fmu"
    build_fmu(strut_spec("apc", motion_centre_m=MEAN_M, T_start_K=T_RIG_K), path)
    return path


def drive_strut(path, A, f, cycles, comm, start=None,
                names=("force", "E_work", "E_valve", "E_friction", "E_gas", "E_end_stop"),
                mean=MEAN_M, T_K=T_RIG_K) -> dict:
    """The rig's motion x = mean + A sin(w t) through FMI: deflection, its rate and the rate's derivative."""
    w = 2 * np.pi * f
    n = int(round(cycles / f / comm))
    d = Driven(path, {"motion_centre": mean, "T_start": T_K, "ambient_temperature": T_K, **ISOTHERMAL,
                      **(start or {})})
    d.set({"deflection": mean, "deflection_rate": A * w})
    d.fmu.exitInitializationMode()
    Y = np.empty((n + 1, len(names)))
    for k in range(n + 1):
        t = k * comm
        d.set({"deflection": mean + A * np.sin(w * t), "deflection_rate": A * w * np.cos(w * t)})
        d.derivatives({"deflection_rate": -A * w * w * np.sin(w * t)})
        Y[k] = d.get(names)
        if k < n:
            d.fmu.doStep(t, comm)
    d.close()
    return {k: Y[:, i] for i, k in enumerate(names)}


def last_cycle(series, samples_per_cycle):
    return series[-1] - series[-1 - samples_per_cycle]


def test_model_descriptions_validate_with_units_and_sources(strut_fmu, vehicle_case):
    for path in (strut_fmu, vehicle_case["fmu"]):
        assert fmpy.validation.validate_fmu(str(path)) == []
        md = read_model_description(str(path))
        units = {u.name: u for u in md.unitDefinitions}
        for v in md.modelVariables:
            assert v.unit in (None, *units), v.name
            assert v.description, v.name
    md = read_model_description(str(strut_fmu))
    pa = {u.name: u for u in md.unitDefinitions}["Pa"].baseUnit
    assert (pa.kg, pa.m, pa.s) == (1, -1, -2)
    by_name = {v.name: v for v in md.modelVariables}
    assert by_name["strut.friction.F0_compression"].unit == "N"
    assert "seed 000 Table 1" in by_name["strut.friction.F0_compression"].description      # the file's source
    assert float(by_name["heat.capacity"].start) == pytest.approx(35e3)
    assert by_name["gas_mass"].causality == "calculatedParameter"


@pytest.mark.parametrize("A, f, comm", CASES)
def test_strut_fmu_cycle_matches_the_rig(strut_fmu, A, f, comm):
    spc = int(round(1 / f / comm))
    rig = cycle_test(load_strut("apc"), A, f, MEAN_M, cycles=3, T_K=T_RIG_K, samples_per_cycle=spc)
    res = drive_strut(strut_fmu, A, f, 3, comm)
    assert last_cycle(res["E_work"], spc) == pytest.approx(rig.energy_per_cycle_J, rel=0.005)
    force = res["force"][-spc - 1:]
    assert np.max(np.abs(force - rig.force_N)) < 0.01 * np.ptp(rig.force_N)


def test_integrated_strut_fmu_cycle_matches_the_rig(tmp_path):
    """The seed-001 strut (shared gas-oil chamber, quasi-steady chambers, valve pressure drop eliminated by the
    integrated strut's own flow balance): 1 Hz / 10 mm about 60 mm (measured 0.004 % and 0.001 % of the range)."""
    params = load_strut("yin2023")
    mean, T_K, A, f, comm = 0.06, params.charge.temperature, 0.01, 1.0, 0.002
    path = tmp_path / "yin2023.fmu"
    build_fmu(strut_spec("yin2023", motion_centre_m=mean, T_start_K=T_K), path)
    spc = int(round(1 / f / comm))
    rig = cycle_test(params, A, f, mean, cycles=3, T_K=T_K, samples_per_cycle=spc)
    res = drive_strut(path, A, f, 3, comm, mean=mean, T_K=T_K)
    assert last_cycle(res["E_work"], spc) == pytest.approx(rig.energy_per_cycle_J, rel=0.005)
    assert np.max(np.abs(res["force"][-spc - 1:] - rig.force_N)) < 0.01 * np.ptp(rig.force_N)


def test_strut_fmu_heat_output_over_a_long_test(strut_fmu):
    A, f, comm, cycles = 0.01, 1.0, 0.002, 20
    spc = int(round(1 / f / comm))
    rig = cycle_test(load_strut("apc"), A, f, MEAN_M, cycles=cycles, T_K=T_RIG_K, samples_per_cycle=spc)
    res = drive_strut(strut_fmu, A, f, cycles, comm)
    heat = sum(last_cycle(res[k], spc) for k in ("E_valve", "E_friction", "E_gas", "E_end_stop"))
    assert heat == pytest.approx(rig.heat_out_J, rel=0.01)


def test_strut_fmu_heat_network_conserves_energy(strut_fmu):
    """With the heat network on (35 kJ/K, 1 min at 1 Hz / 20 mm, air at 2 m/s): the heat stored in the oil, wall
    and surface nodes is the heat the strut made (valve, gas, friction, end stops) less what it lost, to rounding
    (the nodes and the quadratures take the same explicit trapezoid: a linear invariant it keeps exactly)."""
    A, f, comm = 0.02, 1.0, 0.01
    names = ("E_valve", "E_friction", "E_gas", "E_end_stop", "E_lost", "T_oil", "T_wall", "T_surface")
    res = drive_strut(strut_fmu, A, f, 60, comm, start={"heat.capacity": 35e3, "air_speed": 2.0}, names=names)
    md = read_model_description(str(strut_fmu))
    start = {v.name: float(v.start) for v in md.modelVariables if v.start is not None}
    C = 35e3
    C_oil = C * start["heat.oil_capacity_fraction"]
    C_surface = (C - C_oil) * start["heat.surface_capacity_fraction"]
    stored = sum(c * (res[f"T_{node}"][-1] - T_RIG_K)
                 for c, node in ((C_oil, "oil"), (C - C_oil - C_surface, "wall"), (C_surface, "surface")))
    made = sum(res[k][-1] for k in ("E_valve", "E_friction", "E_gas", "E_end_stop"))
    assert made > 1e3 and res["T_oil"][-1] > T_RIG_K + 0.1
    assert stored == pytest.approx(made - res["E_lost"][-1], rel=1e-9)


def test_strut_fmu_parameter_through_fmi_acts_as_the_override(strut_fmu):
    """charge.pressure set through FMI: the FMU recalculates the gas mass (calculatedParameter) and the cycle
    energy is the rig's with the same override, and not the default's."""
    A, f, comm = 0.05, 0.1, 0.01
    spc = int(round(1 / f / comm))
    p_new = 5.6e6
    res = drive_strut(strut_fmu, A, f, 3, comm, start={"strut.charge.pressure": p_new})
    over = load_strut("apc", {"charge": {"pressure": p_new}})
    rig = cycle_test(over, A, f, MEAN_M, cycles=3, T_K=T_RIG_K, samples_per_cycle=spc)
    default = cycle_test(load_strut("apc"), A, f, MEAN_M, cycles=3, T_K=T_RIG_K, samples_per_cycle=spc)
    E = last_cycle(res["E_work"], spc)
    assert E == pytest.approx(rig.energy_per_cycle_J, rel=0.005)
    assert abs(default.energy_per_cycle_J / rig.energy_per_cycle_J - 1) > 0.02     # the override shows
    d = Driven(strut_fmu, {"strut.charge.pressure": p_new})
    d.fmu.exitInitializationMode()
    from struts.model import make_strut

    assert d.get(["gas_mass"])[0] == pytest.approx(make_strut(over).charge_gas_mass, rel=1e-10)
    d.close()


def test_state_save_restore_reproduces_a_step_exactly(strut_fmu):
    d = Driven(strut_fmu, ISOTHERMAL)
    d.fmu.exitInitializationMode()
    names = [v.name for v in d.md.modelVariables if v.causality == "output"]
    t, h = 0.0, 0.05
    for k in range(20):
        d.set({"deflection": MEAN_M + 0.02 * np.sin(k / 3), "deflection_rate": 0.05 * np.cos(k / 3)})
        d.fmu.doStep(t, h)
        t += h
    state = d.fmu.getFMUstate()
    blob = d.fmu.serializeFMUstate(state)
    d.set({"deflection": MEAN_M + 0.03, "deflection_rate": -0.2})
    d.fmu.doStep(t, h)
    first = d.get(names)
    for restore in (state, d.fmu.deSerializeFMUstate(blob)):
        d.fmu.setFMUstate(restore)
        d.set({"deflection": MEAN_M + 0.03, "deflection_rate": -0.2})
        d.fmu.doStep(t, h)
        np.testing.assert_array_equal(d.get(names), first)
    assert not np.array_equal(d.get(["E_work"]), np.zeros(1))
    d.fmu.freeFMUstate(state)
    d.close()


# --- the vehicle ---------------------------------------------------------------------------------
def _quick_demo(overrides=None):
    src = read_scenario(REPO / "scenarios" / "quick_demo.yaml")
    src.data = apply_overrides(src.data, {"distance": "300 m", "output.interval": "0.1 s",
                                          "solver.error_check_every": 0, **(overrides or {})})
    return prepare(src)


class _Collect:
    def __init__(self):
        self.blocks = []

    def start(self, info):
        pass

    def samples(self, block):
        self.blocks.append(block)

    def stats(self, rows):
        pass

    def checkpoint(self, state):
        pass


def run_drive(prepared) -> dict:
    model, drive = build_engine(prepared)
    sink = _Collect()
    result = drive.run(sink)
    cat = {k: np.hstack([b[k] for b in sink.blocks]) for k in ("t_s", "wheel_load", "strut_temperature_K")}
    return {"model": model, "drive": drive, "integration_s": result.integration_s, **cat}


def run_vehicle_fmu(path, run, start=None) -> dict:
    """The FMU fed the drive's inputs at every step of 4 ms (values and their chord derivatives), outputs read at
    the drive's samples."""
    model, drive = run["model"], run["drive"]
    dt, K = drive.settings.dt_s, drive.K
    n = int(round(run["t_s"][-1] / dt))
    U = drive.inputs(dt * np.arange(n + 1))
    d = Driven(path, start)
    inputs = [v.name for v in d.md.modelVariables if v.causality == "input"]
    vrs = [d.vr[nm] for nm in inputs]
    names = [f"wheel_load_{s}" for s in model.station_names] + [f"T_surface_{s}" for s in model.station_names]
    d.fmu.setReal(vrs, list(U[:, 0]))
    d.fmu.exitInitializationMode()
    Y = []
    for k in range(n + 1):
        d.fmu.setReal(vrs, list(U[:, k]))
        if k % K == 0 and k > 0:
            Y.append(d.get(names))
        if k < n:
            d.fmu.setRealInputDerivatives(vrs, [1] * len(vrs), list((U[:, k + 1] - U[:, k]) / dt))
            d.fmu.doStep(k * dt, dt)
    d.close()
    Y = np.array(Y).T
    return {"wheel_load": Y[:model.n], "strut_temperature_K": Y[model.n:]}


@pytest.fixture(scope="module")
def vehicle_case(tmp_path_factory):
    prepared = _quick_demo()
    path = tmp_path_factory.mktemp("fmu") / "vehicle.fmu"
    build_fmu(vehicle_spec(prepared), path)
    run = run_drive(prepared)
    return {"fmu": path, "run": run, "fmu_run": run_vehicle_fmu(path, run)}


def test_vehicle_fmu_reproduces_the_drive(vehicle_case):
    run, fmu = vehicle_case["run"], vehicle_case["fmu_run"]
    static = float(np.mean(run["model"].charged_wheel_loads))
    dW = np.abs(fmu["wheel_load"] - run["wheel_load"])
    assert dW.shape == run["wheel_load"].shape
    # the first half second: the same equations to rounding (the FMU wraps the whole step, `Ros2.step_functions`;
    # the engine runs it split around the struts, vehicle.numerics.split_step). Measured: below 4e-9 N over the
    # first 0.8 s; then the valves' warm starts amplify the rounding (docs/engines.md, "Lanes across struts")
    assert np.max(dW[:, :5]) < 1e-6 * static
    assert np.max(dW) < 0.01 * static
    assert np.max(np.abs(fmu["strut_temperature_K"] - run["strut_temperature_K"])) < 0.05


def test_vehicle_fmu_parameter_through_fmi_acts_as_the_override(vehicle_case):
    """heat.capacity a quarter through FMI and as a scenario override: the same temperatures, other than the
    default's."""
    over = run_drive(_quick_demo({"vehicle.overrides.heat.capacity": "8.75 kJ/K"}))
    fmu = run_vehicle_fmu(vehicle_case["fmu"], over, {"vehicle.heat.capacity": 8750.0})
    T_default = vehicle_case["run"]["strut_temperature_K"]
    assert np.max(np.abs(fmu["strut_temperature_K"] - over["strut_temperature_K"])) < 0.05
    assert np.max(np.abs(over["strut_temperature_K"] - T_default)) > 0.2


def test_fmus_run_in_a_process_without_hpsim(strut_fmu, vehicle_case, tmp_path):
    """FMPy's simulate_fmu on both FMUs in `python -I`, outside the repository, with hpsim's import paths and
    its editable-install finder removed and its packages refused by an import hook: `import vehicle` fails there,
    and CasADi is never loaded."""
    script = textwrap.dedent("""
        import json, sys
        repo = sys.argv[1]
        # the repository's own folders (a virtual environment made inside the clone, as .ci/run makes, stays: it is
        # where FMPy is installed, not hpsim's code)
        sys.path[:] = [p for p in sys.path if not p.startswith(repo) or "site-packages" in p]
        sys.meta_path[:] = [f for f in sys.meta_path if "editable" not in repr(f).lower()]

        class Hidden:            # also hidden when installed into site-packages (not editable)
            def find_spec(self, name, path=None, target=None):
                if name.split(".")[0] in ("hpsim", "struts", "terrain", "vehicle"):
                    raise ImportError(f"{name} hidden")
                return None

        sys.meta_path.insert(0, Hidden())
        try:
            import vehicle
            sys.exit("hpsim importable")
        except ImportError:
            pass
        import fmpy
        out = {}
        for path, stop in zip(sys.argv[2:], (2.0, 1.0)):
            res = fmpy.simulate_fmu(path, stop_time=stop, output_interval=0.02)
            out[path] = {name: float(res[name][-1]) for name in res.dtype.names}
        out["casadi_loaded"] = "casadi" in sys.modules
        print(json.dumps(out))
    """)
    proc = subprocess.run([sys.executable, "-I", "-c", script, str(REPO), str(strut_fmu), str(vehicle_case["fmu"])],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out.pop("casadi_loaded") is False
    strut, vehicle = out[str(strut_fmu)], out[str(vehicle_case["fmu"])]
    # at rest at the start deflection: the gas force of the strut file's charge, stable
    assert strut["force"] == pytest.approx(strut["force_gas"], rel=1e-9)
    assert strut["force"] > 0 and np.isfinite(list(strut.values())).all()
    static = float(np.mean(vehicle_case["run"]["model"].charged_wheel_loads))
    loads = [v for k, v in vehicle.items() if k.startswith("wheel_load_")]
    # standing on a flat road: the wheel loads sum to the weight
    assert sum(loads) == pytest.approx(static * len(loads), rel=0.01)


def test_export_command_line_errors(monkeypatch, capsys):
    from vehicle.cli import main

    assert main(["export", "fmu", "--strut", "apc", "--dt", "50ms", "-o", "x.fmu"]) == 2
    assert "--dt" in capsys.readouterr().err
    assert main(["export", "fmu", "--strut", "apc", "--set", "friction.F0_compression", "-o", "x.fmu"]) == 2
    assert "KEY=VALUE" in capsys.readouterr().err
    # without FMPy (the FMI headers): one line naming the extra
    import vehicle.fmu.build as build

    monkeypatch.setattr(build.importlib.util, "find_spec", lambda name: None)
    assert main(["export", "fmu", "--strut", "apc", "-o", "x.fmu"]) == 2
    err = capsys.readouterr().err
    assert 'pip install -e ".[fmu]"' in err and len(err.strip().splitlines()) == 1


# --- hostile use through FMI ---------------------------------------------------------------------------
def test_parameters_out_of_range_and_a_nan_time_are_fmi2_errors_with_a_logged_message(strut_fmu):
    """modelDescription.xml carries every parameter's min/max; a value outside (a negative charge pressure or
    stroke, NaN) is refused with fmi2Error and a logged message, the value kept; fmi2DoStep(t = NaN) is an error,
    not a step to t = NaN; the importer's process goes on (the FMU is used again after each refusal)."""
    from fmpy.fmi1 import FMICallException

    md = read_model_description(str(strut_fmu))
    params = {v.name: v for v in md.modelVariables if v.causality == "parameter"}
    pressure, stroke = params["strut.charge.pressure"], params["strut.geometry.stroke"]
    assert 0 < float(pressure.min) < float(pressure.start) < float(pressure.max)
    assert 0 < float(stroke.min) and float(params["motion_centre"].max) == pytest.approx(float(stroke.start))
    d = Driven(strut_fmu)
    for name, bad in (("strut.charge.pressure", -1e6), ("strut.geometry.stroke", -0.1), ("T_start", float("nan"))):
        with pytest.raises(FMICallException) as err:
            d.set({name: bad})
        assert err.value.status == 3                                  # fmi2Error
    assert d.get(["strut.charge.pressure"])[0] == pytest.approx(float(pressure.start))     # kept
    d.fmu.exitInitializationMode()
    with pytest.raises(FMICallException):
        d.fmu.doStep(float("nan"), 0.01)
    d.fmu.doStep(0.0, 0.01)                                            # and the instance still steps
    assert np.isfinite(d.get(["force"])[0])
    d.close()


def test_export_refuses_a_motion_centre_outside_the_stroke(tmp_path, capsys):
    from vehicle.cli import main

    out = tmp_path / "x.fmu"
    assert main(["export", "fmu", "--strut", "apc", "--mean", "500mm", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--mean" in err and "[0, 234] mm" in err and len(err.strip().splitlines()) == 1 and not out.exists()
