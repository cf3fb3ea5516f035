"""`hpsim strut ...` through vehicle.cli.main: outputs, files, and one-line user errors (exit 2)."""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from struts.fit import with_values
from struts.params import load_strut
from struts.rig import cycle_test, static_point
from vehicle.cli import main


def run(capsys, *argv):
    try:
        code = main(list(argv))
    except SystemExit as exc:       # argparse errors exit directly
        code = exc.code
    out = capsys.readouterr()
    return code, out.out, out.err


def read_csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


# --- outputs ------------------------------------------------------------------------------------

def test_static_json(capsys):
    code, out, err = run(capsys, "strut", "static", "--strut", "apc", "--load", "41.8kN", "--p0", "4.8MPa",
                         "--temperature", "20degC", "--n", "1.3", "--json")
    assert code == 0, err
    res = json.loads(out)
    assert set(res) == {"static_deflection_m", "stiffness_N_per_m", "gas_pressure_Pa", "gas_temperature_K"}
    assert res["static_deflection_m"] == pytest.approx(0.112, abs=0.002)       # REFERENCE §1
    assert res["gas_temperature_K"] == pytest.approx(293.15)
    area = load_strut("apc").geometry.gas_area
    assert res["gas_pressure_Pa"] * area == pytest.approx(41.8e3, rel=1e-9)     # p A = load at rest
    assert res["stiffness_N_per_m"] > 0


def test_static_isothermal_is_softer(capsys):
    outs = {}
    for proc in ("polytropic", "isothermal"):
        code, out, err = run(capsys, "strut", "static", "--load", "41.8kN", "--process", proc, "--json")
        assert code == 0, err
        outs[proc] = json.loads(out)
    assert outs["isothermal"]["static_deflection_m"] > outs["polytropic"]["static_deflection_m"]


def test_cycle_json_plot_csv(capsys, tmp_path):
    png, csv_path = tmp_path / "loops.png", tmp_path / "loops.csv"
    code, out, err = run(capsys, "strut", "cycle", "--strut", "apc", "--amplitude", "10mm,20mm", "--frequency",
                         "0.5Hz", "--mean", "115mm", "--cycles", "2", "--json", "--plot", str(png),
                         "--csv", str(csv_path))
    assert code == 0, err
    res = json.loads(out)
    assert isinstance(res, list) and len(res) == 2          # amplitudes x frequencies
    keys = {"amplitude_m", "frequency_Hz", "mean_m", "energy_per_cycle_J", "energy_by_mechanism_J",
            "peak_force_compression_N", "peak_force_rebound_N"}
    for item, A in zip(res, (0.01, 0.02)):
        assert keys <= set(item)
        assert item["amplitude_m"] == pytest.approx(A)
        assert item["frequency_Hz"] == pytest.approx(0.5)
        assert item["mean_m"] == pytest.approx(0.115)
        assert isinstance(item["energy_by_mechanism_J"], dict)
        assert sum(item["energy_by_mechanism_J"].values()) == pytest.approx(item["energy_per_cycle_J"], rel=1e-6)
        # resisting forces add in compression and subtract in rebound
        assert item["peak_force_compression_N"] > 41.8e3 > item["peak_force_rebound_N"]
    assert res[1]["energy_per_cycle_J"] > res[0]["energy_per_cycle_J"]
    assert png.stat().st_size > 1000 and png.read_bytes()[:4] == b"\x89PNG"
    rows = read_csv(csv_path)
    assert len(rows) == 2 * 401
    # the CSV loop closes on the same energy: E = closed integral of F dx (seed 000 eq. 7)
    for A, item in zip((0.01, 0.02), res):
        loop = [r for r in rows if float(r["amplitude_m"]) == pytest.approx(A)]
        x = np.array([float(r["x_m"]) for r in loop])
        F = np.array([float(r["force_N"]) for r in loop])
        E = float(np.sum(0.5 * (F[1:] + F[:-1]) * np.diff(x)))
        assert E == pytest.approx(item["energy_per_cycle_J"], rel=0.01)
        F_sum = sum(np.array([float(r[k]) for r in loop])
                    for k in ("gas_force_N", "valve_force_N", "friction_force_N", "end_stop_force_N"))
        assert np.allclose(F_sum, F, rtol=1e-6, atol=1e-3)


def test_characteristic_csv(capsys, tmp_path):
    path = tmp_path / "char.csv"
    code, out, err = run(capsys, "strut", "characteristic", "--strut", "apc", "--csv", str(path))
    assert code == 0, err
    rows = read_csv(path)
    assert set(rows[0]) == {"x_m", "force_N", "gas_pressure_Pa"}
    x = np.array([float(r["x_m"]) for r in rows])
    F = np.array([float(r["force_N"]) for r in rows])
    p = load_strut("apc")
    assert x[0] == 0.0 and x[-1] == pytest.approx(p.geometry.stroke)
    assert F[0] == pytest.approx(p.charge.pressure * p.geometry.gas_area, rel=1e-6)   # fill at full extension
    assert np.all(np.diff(F) > 0) and np.all(np.diff(F, 2) > 0)                       # gas spring hardens


def test_fit_json_recovers_friction(capsys, tmp_path):
    """Energies made by the model with F0 = 1500 N; the file's 1648 N is the start."""
    apc = load_strut("apc")
    truth = with_values(apc, ["F0"], [1500.0])
    path = tmp_path / "rig.csv"
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["amplitude_m", "frequency_Hz", "mean_m", "energy_J"])
        for A, f in ((0.01, 0.1), (0.01, 1.0)):
            w.writerow([A, f, 0.115, repr(cycle_test(truth, A, f, 0.115, cycles=2).energy_per_cycle_J)])
    code, out, err = run(capsys, "strut", "fit", "--strut", "apc", "--data", str(path), "--fit", "F0",
                         "--cycles", "2", "--json")
    assert code == 0, err
    res = json.loads(out)
    assert res["initial"]["F0"] == pytest.approx(1648.0)
    assert res["fitted"]["F0"] == pytest.approx(1500.0, rel=0.01)
    lo, hi = res["confidence_95"]["F0"]
    assert lo <= res["fitted"]["F0"] <= hi


def test_static_cli_matches_rig(capsys):
    code, out, _ = run(capsys, "strut", "static", "--strut", "yin2023", "--load", "4.3kN", "--json")
    assert code == 0
    res = json.loads(out)
    ref = static_point(load_strut("yin2023"), 4300.0, process="polytropic")   # the command's default process
    assert res["static_deflection_m"] == pytest.approx(ref["static_deflection_m"], rel=1e-9)
    assert 0 < res["static_deflection_m"] < load_strut("yin2023").geometry.stroke


# --- user errors: one line naming the argument and the allowed range, exit code 2 ---------------

CYCLE = ["strut", "cycle", "--strut", "apc", "--frequency", "1Hz", "--cycles", "1"]


@pytest.mark.parametrize("argv, argument, allowed", [
    (["strut", "static", "--strut", "nosuch", "--load", "40kN"], "--strut", "apc"),
    (["strut", "static", "--strut", "apc", "--load", "500kN"], "--load", "kN at full compression"),
    (CYCLE + ["--amplitude", "-10mm", "--mean", "115mm"], "--amplitude", "> 0"),
    (CYCLE + ["--amplitude=-10mm", "--mean", "115mm"], "--amplitude", "> 0"),
    (CYCLE + ["--amplitude", "10mm", "--mean", "230mm"], "--mean", "stroke [0, 234] mm"),
    (CYCLE + ["--amplitude", "10mm", "--mean", "-5mm"], "--mean", "stroke [0, 234] mm"),
    (CYCLE + ["--amplitude", "12 parsecs/furlong", "--mean", "115mm"], "--amplitude", "stroke [0, 234] mm"),
    (CYCLE + ["--amplitude", "abc", "--mean", "115mm"], "--amplitude", "stroke [0, 234] mm"),
    (["strut", "static", "--load", "12 parsecs/furlong"], "--load", "> 0 N"),
    (["strut", "static", "--load", "abc"], "--load", "> 0 N"),
    (["strut", "static", "--load", "40kN", "--temperature", "abc"], "--temperature", "degC"),
    (["strut", "static", "--load", "40kN", "--p0", "12 parsecs/furlong"], "--p0", "MPa"),
    (["strut", "cycle", "--amplitude", "10mm", "--frequency", "0Hz", "--mean", "115mm"], "--frequency", "(0, 50"),
])
def test_user_errors(capsys, argv, argument, allowed):
    code, out, err = run(capsys, *argv)
    assert code == 2
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    assert argument in lines[0] and allowed in lines[0], lines[0]
