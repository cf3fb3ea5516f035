"""Charging methods (issue 10 §5, issue 13 charge.pressure): each reproduces its defining condition exactly.

load_and_height: the standing (isothermal) vehicle carries the charging loads at the charging
deflection; gas_pressure: every strut holds its file's charge.pressure at full extension at its
charge.temperature, and a charge.pressure override changes the gas mass; polytropic_convention:
seed 000's eq. 5 from full extension carries the charging loads at the charging deflection (and
with the strut file's own numbers gives its 4.8 MPa). A charge.pressure override under the other
methods is refused with a message saying that charging.method decides the gas mass.
"""
import numpy as np
import pytest

from hpsim.errors import UserInputError
from struts import gas as gaslaw
from vehicle.physics.equilibrium import EquilibriumSolver, charge_gas_masses
from vehicle.physics.model import VehicleModel
from vehicle.physics.params import GRAVITY, load_vehicle
from vehicle.scenario.schema import load_prepared


def _model(method, strut_overrides=None, **overrides):
    P = load_vehicle("apc_8x8")
    if strut_overrides is not None:
        overrides["axles"] = [{**a.model_dump(), "strut_overrides": strut_overrides} for a in P.axles]
    return VehicleModel(load_vehicle("apc_8x8", {"charging.method": method, **overrides}))


def _strut_loads(model):
    return (model.charged_wheel_loads - model.m_u * GRAVITY) / model.r


def _fill_pressure(strut, m_gas, T):
    V = float(strut.extended_gas_volume(T))
    return float(gaslaw.pressure(T, V / m_gas, strut.gas, strut.p.gas.eos))


def test_load_and_height_carries_the_charging_loads_at_the_charging_heights_standing():
    model = _model("load_and_height")
    masses = charge_gas_masses(model)
    T = model.params.charging.temperature
    eq = EquilibriumSolver(model).solve(T, masses)
    assert np.allclose(eq.wheel_loads_N, model.charged_wheel_loads, rtol=0, atol=1e-6)
    assert np.allclose(eq.strut_deflections_m, model.x_charged, atol=1e-12)
    assert np.allclose(eq.axle_height_change_m, 0.0, atol=1e-12)
    # the standing law of an energy-equation strut is isothermal
    F = [float(s.static_gas_force(model.x_charged, T, m, process="isothermal")) for s, m in zip(model.struts, masses)]
    assert np.allclose(F, _strut_loads(model), rtol=1e-10)


def test_gas_pressure_reproduces_each_struts_charge_and_honours_a_pressure_override():
    model = _model("gas_pressure")
    masses = charge_gas_masses(model)
    for strut, m in zip(model.struts, masses):
        c = strut.p.charge
        assert _fill_pressure(strut, m, c.temperature) == pytest.approx(c.pressure, rel=1e-10)
    high = _model("gas_pressure", {"charge.pressure": "5.8 MPa"})
    m_high = charge_gas_masses(high)
    assert _fill_pressure(high.struts[0], m_high[0], high.struts[0].p.charge.temperature) == pytest.approx(5.8e6, rel=1e-10)
    assert np.all(m_high > 1.15 * masses)            # more gas: ~ 5.8 / 4.8 (real-gas corrected)
    # and the standing vehicle rises
    T = model.params.charging.temperature
    h_low = EquilibriumSolver(model).solve(T, masses).axle_height_change_m
    h_high = EquilibriumSolver(high).solve(T, m_high).axle_height_change_m
    assert np.all(h_high > h_low + 0.02)


def test_polytropic_convention_carries_the_loads_by_seed_000_eq_5():
    model = _model("polytropic_convention")
    masses = charge_gas_masses(model)
    T, x = model.params.charging.temperature, model.x_charged
    F = [float(s.static_gas_force(x, T, m, process="polytropic")) for s, m in zip(model.struts, masses)]
    assert np.allclose(F, _strut_loads(model), rtol=1e-10)
    # hand check, seed 000 eq. 5: F = p_ext A (V_ext / (V_ext - A x))^n
    s, m = model.struts[6], masses[6]
    g, n = s.p.geometry, s.p.gas.polytropic_exponent
    V = float(s.extended_gas_volume(T))
    assert _fill_pressure(s, m, T) * g.gas_area * (V / (V - g.gas_area * x)) ** n == pytest.approx(F[6], rel=1e-10)


def test_polytropic_convention_with_the_seed_numbers_gives_the_strut_files_charge():
    """REFERENCE §1: 4.8 MPa at 20 degC, n = 1.3, gives 41.8 kN at about 112 mm."""
    strut_load = 41.8e3
    m_u, r = 450.0, 0.7
    load = r * strut_load + m_u * GRAVITY
    model = _model("polytropic_convention", **{"charging.temperature": "20 degC",
                                               "charging.wheel_loads": [load] * 4})
    masses = charge_gas_masses(model)
    p_fill = _fill_pressure(model.struts[0], masses[0], 293.15)
    assert p_fill == pytest.approx(4.8e6, rel=0.01)
    # while the isothermal standing strut at 4.8 MPa carries 41.8 kN near 135 mm, not 112 mm
    s = model.struts[0]
    m48 = s.charge_gas_mass
    from scipy.optimize import brentq
    x_iso = brentq(lambda x: float(s.static_gas_force(x, 293.15, m48, process="isothermal")) - strut_load, 0.05, 0.2)
    assert 0.130 < x_iso < 0.140


def test_methods_differ_standing_where_the_issue_says():
    T = 298.15
    heights = {}
    for method in ("load_and_height", "gas_pressure", "polytropic_convention"):
        model = _model(method)
        heights[method] = EquilibriumSolver(model).solve(T, charge_gas_masses(model)).strut_deflections_m
    assert np.allclose(heights["load_and_height"], 0.112)
    assert np.all(heights["gas_pressure"] > 0.120) and np.all(heights["polytropic_convention"] > 0.130)


def test_charge_pressure_override_is_refused_unless_charging_by_pressure(tmp_path):
    path = tmp_path / "s.yaml"
    text = """vehicle: {{name: apc_8x8{vo}}}
struts: {{all: {{overrides: {{charge.pressure: 5 MPa}}}}}}
road: {{iso_class: D, seed: 1}}
speed: 20 km/h
distance: 100 m
ambient_temperature: 25 degC
"""
    path.write_text(text.format(vo=""))
    with pytest.raises(UserInputError) as exc:
        load_prepared(path)
    msg = str(exc.value)
    assert "s.yaml" in msg and "charge.pressure has no effect with charging.method 'load_and_height'" in msg
    assert "charging.method decides the gas mass" in msg and "charging.method: gas_pressure" in msg
    path.write_text(text.format(vo=", overrides: {charging.method: gas_pressure}"))
    prep = load_prepared(path)
    model = prep.model()
    m = charge_gas_masses(model)
    assert _fill_pressure(model.struts[0], m[0], model.struts[0].p.charge.temperature) == pytest.approx(5e6, rel=1e-10)


def test_unknown_charging_method_is_named():
    with pytest.raises(UserInputError, match="charging.method: must be one of load_and_height, gas_pressure, "
                                             "polytropic_convention, got 'by_feel'"):
        load_vehicle("apc_8x8", {"charging.method": "by_feel"})
