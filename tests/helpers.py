"""Shared helpers of the tests (no tests here): the repository's paths, short scenarios written as files,
`hpsim` as a subprocess started as at a terminal, the malformed-scenario check, and small drives built
from the shipped parameter files. Fixtures that use them: tests/conftest.py."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]
SCENARIOS = REPO / "scenarios"

# a short drive of the shipped 8x8 on a class D road: what most tests change a few keys (or lines) of
SHORT_SCENARIO = """\
vehicle: {name: apc_8x8}
road: {iso_class: D, seed: 3}
speed: 20 km/h
distance: 200 m
ambient_temperature: 25 degC
"""
BASE_SCENARIO = yaml.safe_load(SHORT_SCENARIO)


# the minimal measurement file of issue 23 (values invented; docs/measurements.md): points only
MEASUREMENT_POINTS = """\
description: "example test, values invented"
instruments:
  pyrometer: {uncertainty: 2 K}
  photogrammetry: {uncertainty: 5 mm}
  scale: {uncertainty: 20 daN}
points:
  - {quantity: surface_temperature, axle: 1, before: 20.0 degC, after: 80.0 degC, instrument: pyrometer}
  - {quantity: height, axle: 1, before: 1400 mm, after: 1470 mm, instrument: photogrammetry}
  - {quantity: wheel_load, axle: 1, before: 3000 daN, after: 3100 daN, instrument: scale}
"""


def scenario_yaml(**changes) -> str:
    """BASE_SCENARIO with top-level keys changed (None removes a key), as YAML text."""
    data = {**BASE_SCENARIO, **changes}
    return yaml.safe_dump({k: v for k, v in data.items() if v is not None}, sort_keys=False)


def write_scenario(folder: Path, name: str = "scenario.yaml", text: str | None = None, **changes) -> Path:
    """A scenario file in `folder`: the given YAML text, or BASE_SCENARIO with `changes`."""
    path = Path(folder) / name
    path.write_text(text if text is not None else scenario_yaml(**changes))
    return path


# `hpsim` as a command started at a terminal: Ctrl-C raises KeyboardInterrupt. A test run started in the
# background by a non-interactive shell (`cmd &`, nohup) has SIGINT ignored, and an ignored signal stays
# ignored across fork and exec (Python then installs no handler): the interrupt tests would test nothing
_AS_AT_A_TERMINAL = ("import runpy, signal; signal.signal(signal.SIGINT, signal.default_int_handler); "
                     "runpy.run_module('vehicle.cli', run_name='__main__', alter_sys=True)")


def hpsim_subprocess(args: list[str], cwd=None, env=None, **kw) -> subprocess.Popen:
    """`hpsim ARGS` in a new Python process, with Ctrl-C's default meaning (see _AS_AT_A_TERMINAL)."""
    e = dict(os.environ)
    e.update(env or {})
    return subprocess.Popen([sys.executable, "-c", _AS_AT_A_TERMINAL, *map(str, args)], cwd=cwd, env=e, **kw)


def run_hpsim(args: list[str], cwd=None, timeout=300, env=None) -> subprocess.CompletedProcess:
    p = hpsim_subprocess(args, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out, err = p.communicate(timeout=timeout)
    return subprocess.CompletedProcess(p.args, p.returncode, out, err)


def assert_bad_scenario_exits_2(path: Path, key: str, words, capsys) -> None:
    """A malformed scenario file: loading it raises a UserInputError naming the file, the key and `words`; through
    the command line `hpsim run` prints one line on stderr, no traceback, exits with 2 and writes nothing."""
    import pytest

    from hpsim.errors import UserInputError
    from vehicle import cli
    from vehicle.scenario.schema import load_prepared

    with pytest.raises(UserInputError) as err:
        load_prepared(path)
    msg = str(err.value)
    assert str(path) in msg and key in msg, msg
    for w in words:
        assert w in msg, msg
    out_file = path.parent / "out.h5"
    capsys.readouterr()
    code = cli.main(["run", str(path), "-o", str(out_file), "--no-progress"])
    err_text = capsys.readouterr().err
    assert code == 2
    assert key in err_text and "Traceback" not in err_text and len(err_text.strip().splitlines()) == 1, err_text
    assert not out_file.exists()


# --- small drives built from the shipped parameter files ---------------------------------------------
from terrain import RoadSpec, build_road  # noqa: E402
from vehicle.engines.full import Drive  # noqa: E402
from vehicle.physics.model import VehicleModel  # noqa: E402
from vehicle.physics.params import load_vehicle  # noqa: E402
from vehicle.scenario.settings import DriveSettings  # noqa: E402
from vehicle.scenario.speed import SpeedProfile  # noqa: E402


def make_drive(distance_m=200.0, road=None, vehicle="apc_8x8", overrides=None, speed_kmh=20.0, **settings):
    model = VehicleModel(load_vehicle(vehicle, overrides))
    if road is None:
        road = build_road(RoadSpec(iso_class="D", length=distance_m + 20.0, seed=3))
    s = DriveSettings(distance_m=distance_m, speed=SpeedProfile.constant(speed_kmh / 3.6), **settings)
    return Drive(model, road, s)


def quarter_car_at_wheel(model, temperature_K: float, gas_mass_kg: float) -> tuple[float, float, float]:
    """The first strut's linearised stiffness and damping at the equilibrium, from its own laws, referred to the wheel
    (r^2 k, r^2 c), and the strut's damping c_strut: the static gas force differentiated by central differences,
    the valve's linear coefficient A_valve^2 / (dq/ddp) from its flow law. (k_s, c_s, c_strut)."""
    from struts import valves

    strut = model.struts[0]
    x0, h = model.x_charged, 1e-6
    k_strut = float(strut.static_gas_force(x0 + h, temperature_K, gas_mass_kg)
                    - strut.static_gas_force(x0 - h, temperature_K, gas_mass_kg)) / (2 * h)
    kw = strut.valve_arguments(temperature_K)
    dq = float(valves.valve_flow(1.0, **kw) - valves.valve_flow(-1.0, **kw)) / 2.0
    c_strut = strut.p.geometry.valve_area ** 2 / dq
    r = model.r[0]
    return r * r * k_strut, r * r * c_strut, c_strut
