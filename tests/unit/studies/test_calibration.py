"""The heat-transfer calibration is reproducible (issue 6) and knows its noise (issue 20).

A short version of the mileage scenario is run with a known wheel-bay air speed ratio; its mean
strut temperature rise becomes the target, and the calibration, started from the shipped value,
must recover the ratio.

The rise is smooth in the ratio only down to a few millikelvin: seal stick-slip makes the drive
chaotic at that level, so changing the ratio by 1e-12 (relative) moves the 1.5 km rise by ~3 mK
(measured, casadi 3.8.2 / numpy 2.4.6: eight runs at 0.3 (1 + k 1e-12) and 0.3 (1 + k 1e-9) gave
25.0587 ... 25.0675 K, sample standard deviation 3.3 mK). The exact numbers differ between installs
(compiler, BLAS, libm), the noise level does not. So a 2 mK tolerance is refused with the measured
floor (2 standard deviations of 9 runs, 4-7 mK; measured 6.6 mK at 0.3) in the message, and the recovery is asserted at 30 mK, about
4-5x that floor.
"""
import re

import pytest

from hpsim.errors import UserInputError
from vehicle.numerics import noisy_root
from vehicle.studies.calibration import _run, calibrate_heat
from vehicle.scenario.schema import read_scenario
from tests.helpers import REPO

ROOT = REPO
KNOWN = 0.3
TOLERANCE_K = 0.03      # ~4-5x the measured floor (module docstring); the floor is also checked below it


@pytest.fixture(scope="module")
def short_scenario(tmp_path_factory):
    # a small heat capacity lets the struts reach their steady state within the short drive, where the
    # rise is set by the heat transfer (~10 K per unit of the ratio); with the real 35 kJ/K the 1.5 km
    # rise is almost all stored heat and the ratio would be identified only to about +-10 %
    text = (ROOT / "scenarios" / "mileage_106km.yaml").read_text().replace("distance: 106 km", "distance: 1.5 km")
    text = text.replace("  overrides: {}", '  overrides: {heat.capacity: "2 kJ/K"}', 1)
    assert "2 kJ/K" in text
    scenario = tmp_path_factory.mktemp("calibration") / "short.yaml"
    scenario.write_text(text)
    target, _, _ = _run(read_scenario(scenario), "heat.air_speed_ratio", KNOWN)
    assert target > 5.0   # the struts really heat up in 1.5 km
    return scenario, target


@pytest.mark.slow      # nine 1.5 km drives
def test_calibration_refuses_a_tolerance_below_the_measured_noise_floor(short_scenario):
    scenario, target = short_scenario
    # started at the answer (the first run is the target itself), so the noise probe comes at once
    at_answer = scenario.with_name("at_answer.yaml")
    at_answer.write_text(scenario.read_text().replace('heat.capacity: "2 kJ/K"',
                                                      f'heat.capacity: "2 kJ/K", heat.air_speed_ratio: {KNOWN}'))
    with pytest.raises(UserInputError, match=r"--tolerance: 0\.002 K is below the noise floor") as err:
        calibrate_heat(at_answer, target, tol_K=2e-3, log=lambda m: None)
    floor = float(re.search(r"noise floor of the mean rise, ([0-9.e-]+) K", str(err.value)).group(1))
    # the floor is a measurement: above the 2 mK asked, and below the tolerance the recovery test uses
    assert 2e-3 < floor < TOLERANCE_K


@pytest.mark.slow      # about ten 1.5 km drives
def test_calibration_recovers_a_known_air_speed_ratio_above_the_noise_floor(short_scenario):
    scenario, target = short_scenario
    res = calibrate_heat(scenario, target, tol_K=TOLERANCE_K, log=lambda m: None)
    assert res["noise_floor_K"] < TOLERANCE_K
    assert abs(res["achieved_rise_K"] - target) < TOLERANCE_K
    # ~10 K per unit of the ratio: 30 mK is ~0.003 in the ratio, 1 % of 0.3; 3 % leaves room for the
    # noise of the target itself (one evaluation) and the local curvature of the rise
    assert res["value"] == pytest.approx(KNOWN, rel=0.03)


def test_the_noise_probe_perturbs_by_rounding_level_amounts_only():
    x = 0.3
    steps = [noisy_root.perturbed(x, k) / x - 1 for k in range(1, 6)]
    assert steps == pytest.approx([1e-12, -1e-12, 2e-12, -2e-12, 3e-12], rel=1e-3, abs=1e-16)
    # a smooth function shows no floor (its slope times 3e-12 is far below anything asked)
    floor, samples = noisy_root.noise_floor(lambda v: 60.0 / (1 + 20 * v), x, 60.0 / 7.0, 1e-6)
    assert floor < 1e-9 and len(samples) == 2
    assert noisy_root.floor_of([1.0, 1.0, 1.0]) == 0.0 and noisy_root.floor_of([1.0, 3.0]) == pytest.approx(2 * 2 ** 0.5)


def test_the_regression_root_averages_noise_instead_of_stepping_on_it():
    # y = 10 - 4 ln x with +-5 mK alternating noise, x repeated at 1.0 (a point and its probes) and two others
    points = [(1.0, 10.005), (1.0, 9.995), (1.0, 10.005), (1.0, 9.995), (1.2, 10 - 4 * 0.18232155679395462 + 0.005),
              (0.9, 10 - 4 * -0.10536051565782628 - 0.005)]
    x, slope = noisy_root.regression_root(points, 9.0)
    import math

    assert slope == pytest.approx(-4.0, rel=0.02) and x == pytest.approx(math.exp(0.25), rel=2e-3)


def test_the_command_refuses_with_exit_2_and_the_floor(short_scenario, monkeypatch, capsys):
    """`hpsim calibrate ... --tolerance 2mK` on a rise with 5 mK of noise (a synthetic one: no drives) exits 2
    with one line naming the measured floor."""
    import hashlib
    from types import SimpleNamespace

    import vehicle.studies.calibration as cal
    from vehicle import cli

    scenario, _ = short_scenario

    def noisy_run(src, parameter, value):          # smooth in the ratio, plus reproducible noise of 5 mK
        u = int.from_bytes(hashlib.sha256(repr(value).encode()).digest()[:8], "big") / 2 ** 64
        drive = SimpleNamespace(settings=SimpleNamespace(speed=SimpleNamespace(speeds_m_per_s=[20 / 3.6])))
        return 60.0 / (1.0 + 20.0 * value) + 0.005 * 3 ** 0.5 * (2 * u - 1), None, drive

    monkeypatch.setattr(cal, "_run", noisy_run)
    target = 60.0 / (1.0 + 20.0 * 0.0687)              # at the shipped ratio: the noise probe comes at once
    code = cli.main(["calibrate", str(scenario), "--target-rise", f"{target}K", "--tolerance", "2mK"])
    err = capsys.readouterr().err.strip().splitlines()
    # the runs and the probe are logged (stderr, -q hides them); then one line of error
    assert code == 2 and [line for line in err if "error" in line] == err[-1:]
    assert err[-1].startswith("hpsim calibrate: error: --tolerance: 0.002 K is below the noise floor")
    floor = float(re.search(r"noise floor of the mean rise, ([0-9.e-]+) K", err[-1]).group(1))
    assert 2e-3 < floor < 0.03                         # 2 sigma of 5 mK uniform noise, from 9 runs
