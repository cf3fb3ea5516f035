"""Nitrogen gas models: ideal gas and Benedict-Webb-Rubin (BWR), energy equation, polytropic law.

Pure functions, SI units (Pa, K, m^3, kg, J, W, s). Specific volume v [m^3/kg] = V/m.
Except `specific_volume`, `gas_mass` and `isochoric_pressure` (NumPy only, they invert the
equation of state iteratively), every function accepts NumPy values or CasADi SX/MX symbols.

Equations
- Ideal gas: p = R T / v.
- BWR per kg (REFERENCE §6): p = RT/v + (B0 R T - A0 - C0/T^2)/v^2 + (b R T - a)/v^3 + a alpha/v^6
  + c/(v^3 T^2) (1 + gamma/v^2) exp(-gamma/v^2).
- Real-gas cv (thermodynamic identity (dcv/dv)_T = T (d2p/dT2)_v, integrated from the ideal-gas
  limit v -> inf; as used with BWR by van der Westhuizen & Els 2015):
  cv(T, v) = cv0(T) + int_inf^v T (d2p/dT2)_v dv'
           = cv0(T) + 6 C0/(T^3 v) - 3c/(gamma T^3) [2 - (2 + gamma/v^2) exp(-gamma/v^2)].
- Energy equation of a closed gas mass exchanging heat with a wall at T_w with time constant tau
  (REFERENCE §6; van der Westhuizen & Els 2015): dT/dt = (T_w - T)/tau - (T/cv) (dp/dT)_v dv/dt.
- Polytropic law (seed 000 eq. 1 / eq. 5): p = p_ref (V_ref/V)^n.

Internal energy and entropy (relative to an arbitrary reference) are provided for energy and
isentrope checks: u = u0(T) + int_inf^v (T p_T - p) dv', s = s0(T) + R ln v + int_inf^v (p_T - R/v') dv'.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from importlib.resources import files

import numpy as np
import yaml

from hpsim.errors import UserInputError
from hpsim.symbolic import exp, is_symbolic, log

EOS = ("ideal", "bwr")
_BWR_KEYS = ("A0", "B0", "C0", "a", "b", "c", "alpha", "gamma")


@dataclass(frozen=True)
class GasProperties:
    """Gas constants loaded from struts/data/<name>.yaml (every value with its source there)."""

    R: float                      # J/kg/K, specific gas constant
    cv0: tuple[float, ...]        # J/kg/K, cv0(T) = sum_i cv0[i] (T/cv0_T_scale)^i (ideal-gas part)
    cv0_T_scale: float            # K
    A0: float                     # Pa m^6/kg^2
    B0: float                     # m^3/kg
    C0: float                     # Pa m^6 K^2/kg^2
    a: float                      # Pa m^9/kg^3
    b: float                      # m^6/kg^2
    c: float                      # Pa m^9 K^2/kg^3
    alpha: float                  # m^9/kg^3
    gamma: float                  # m^6/kg^2
    T_min: float = 200.0          # K, validity range of specific_volume()/gas_mass()
    T_max: float = 600.0          # K
    p_max: float = 100.0e6        # Pa
    name: str = "nitrogen"
    sources: dict = field(default_factory=dict, compare=False, hash=False, repr=False)


# --- loading --------------------------------------------------------------------------------

def _value(entry, where: str) -> float:
    value = entry.get("value") if isinstance(entry, dict) else entry
    if isinstance(value, str):            # YAML 1.1 reads "1e6" (no exponent sign) as a string
        try:
            value = float(value)
        except ValueError:
            pass
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise UserInputError(f"{where}: expected a finite number (SI), got {value!r}")
    return float(value)


def _source(entry) -> str:
    return str(entry.get("source", "")) if isinstance(entry, dict) else ""


def load_gas(name: str = "nitrogen") -> GasProperties:
    """Load gas properties from the package file struts/data/<name>.yaml (read once per process: every strut of
    every model built asks for them, and parsing YAML is slow next to a lookup; the properties are frozen)."""
    if isinstance(name, str) and name in _LOADED:
        return _LOADED[name]
    gas = _read_gas(name)
    _LOADED[name] = gas
    return gas


# the gases read by this process, by name
_LOADED: dict = {}


def _read_gas(name: str) -> GasProperties:
    resource = files("struts") / "data" / f"{name}.yaml"
    where = f"struts/data/{name}.yaml"
    if not isinstance(name, str) or not name.isidentifier() or not resource.is_file():
        raise UserInputError(f"gas name {name!r}: no file struts/data/<name>.yaml; available: 'nitrogen'")
    try:
        data = yaml.safe_load(resource.read_text())
    except yaml.YAMLError as exc:
        raise UserInputError(f"{where}: YAML syntax error: {exc}") from None
    try:
        sources = {"R": _source(data["R"])}
        kw = {"R": _value(data["R"], f"{where}: R")}
        cv0 = data["cv0"]
        coeffs = cv0["coefficients"]["value"] if isinstance(cv0["coefficients"], dict) else cv0["coefficients"]
        if not isinstance(coeffs, list) or not coeffs:
            raise UserInputError(f"{where}: cv0.coefficients: expected a non-empty list of numbers, got {coeffs!r}")
        kw["cv0"] = tuple(_value(x, f"{where}: cv0.coefficients[{i}]") for i, x in enumerate(coeffs))
        kw["cv0_T_scale"] = _value(cv0["T_scale"], f"{where}: cv0.T_scale")
        sources["cv0"] = _source(cv0["coefficients"])
        for key in _BWR_KEYS:
            kw[key] = _value(data["bwr"][key], f"{where}: bwr.{key}")
            sources[key] = _source(data["bwr"][key])
        val = data["validity"]
        for key in ("T_min", "T_max", "p_max"):
            kw[key] = _value(val[key], f"{where}: validity.{key}")
            sources[key] = _source(val[key])
    except (KeyError, TypeError) as exc:
        raise UserInputError(f"{where}: missing or malformed key {exc}") from None
    if kw["R"] <= 0 or kw["cv0_T_scale"] <= 0 or not 0 < kw["T_min"] < kw["T_max"] or kw["p_max"] <= 0:
        raise UserInputError(f"{where}: R, cv0.T_scale, p_max must be > 0 and 0 < T_min < T_max")
    return GasProperties(**kw, name=str(data.get("name", name)), sources=sources)


def _check_eos(eos: str) -> None:
    if eos not in EOS:
        raise UserInputError(f"eos: {eos!r} is not one of {', '.join(map(repr, EOS))}")


# --- ideal-gas part ---------------------------------------------------------------------------

def cv0(T_K, gas: GasProperties):
    """Ideal-gas cv0(T) [J/kg/K]: polynomial in T/T_scale (fit source in nitrogen.yaml)."""
    th = T_K / gas.cv0_T_scale
    out = 0.0 * th + gas.cv0[-1]
    for coef in reversed(gas.cv0[:-1]):
        out = out * th + coef
    return out


def _u0(T_K, gas):
    """int cv0 dT [J/kg] (reference: 0 at T = 0)."""
    th = T_K / gas.cv0_T_scale
    out = 0.0 * th
    for i, coef in reversed(list(enumerate(gas.cv0))):
        out = (out + coef / (i + 1)) * th
    return out * gas.cv0_T_scale


def _s0(T_K, gas):
    """int cv0/T dT [J/kg/K] (reference: a0 ln(1 K) = 0)."""
    th = T_K / gas.cv0_T_scale
    out = 0.0 * th
    for i, coef in reversed(list(enumerate(gas.cv0))):
        if i == 0:
            break
        out = (out + coef / i) * th
    return out + gas.cv0[0] * log(T_K)


# --- BWR pieces -------------------------------------------------------------------------------

def _exp_integral(v, gas):
    """E(v) = [2 - (2 + gamma/v^2) exp(-gamma/v^2)] / (2 gamma) = -int_inf^v (1 + gamma/v'^2) e^(-gamma/v'^2) / v'^3 dv'."""
    U = gas.gamma / (v * v)
    return (2.0 - (2.0 + U) * exp(-U)) / (2.0 * gas.gamma)


def pressure(T_K, v_m3_per_kg, gas: GasProperties, eos: str = "bwr"):
    """Pressure p(T, v) [Pa]: ideal gas R T/v or BWR (REFERENCE §6)."""
    _check_eos(eos)
    T, v = T_K, v_m3_per_kg
    if eos == "ideal":
        return gas.R * T / v
    R = gas.R
    r = 1.0 / v
    r2 = r * r
    r3 = r2 * r
    return (R * T * r
            + (gas.B0 * R * T - gas.A0 - gas.C0 / (T * T)) * r2
            + (gas.b * R * T - gas.a) * r3
            + gas.a * gas.alpha * r3 * r3
            + gas.c * r3 / (T * T) * (1.0 + gas.gamma * r2) * exp(-gas.gamma * r2))


def dp_dT_at_constant_v(T_K, v, gas: GasProperties, eos: str = "bwr"):
    """(dp/dT)_v [Pa/K], analytic derivative of `pressure` (REFERENCE §6)."""
    _check_eos(eos)
    T = T_K
    R = gas.R
    if eos == "ideal":
        return R / v + 0.0 * T
    r = 1.0 / v
    r2 = r * r
    r3 = r2 * r
    return (R * r
            + (gas.B0 * R + 2.0 * gas.C0 / (T * T * T)) * r2
            + gas.b * R * r3
            - 2.0 * gas.c * r3 / (T * T * T) * (1.0 + gas.gamma * r2) * exp(-gas.gamma * r2))


def dp_dv_at_constant_T(T_K, v, gas: GasProperties, eos: str = "bwr"):
    """(dp/dv)_T [Pa kg/m^3], analytic derivative of `pressure` (REFERENCE §6); negative."""
    _check_eos(eos)
    T = T_K
    R = gas.R
    if eos == "ideal":
        return -R * T / (v * v)
    r = 1.0 / v
    r2 = r * r
    g = gas.gamma
    dp_drho = (R * T
               + 2.0 * (gas.B0 * R * T - gas.A0 - gas.C0 / (T * T)) * r
               + 3.0 * (gas.b * R * T - gas.a) * r2
               + 6.0 * gas.a * gas.alpha * r2 * r2 * r
               + gas.c / (T * T) * (3.0 * r2 + 3.0 * g * r2 * r2 - 2.0 * g * g * r2 * r2 * r2) * exp(-g * r2))
    return -r2 * dp_drho


def cv_departure(T_K, v, gas: GasProperties, eos: str = "bwr"):
    """cv - cv0 [J/kg/K] = int_inf^v T (d2p/dT2)_v dv' (analytic for BWR; 0 for the ideal gas)."""
    _check_eos(eos)
    if eos == "ideal":
        return 0.0 * T_K + 0.0 * v
    T3 = T_K * T_K * T_K
    return 6.0 * gas.C0 / (T3 * v) - 6.0 * gas.c / T3 * _exp_integral(v, gas)


def cv(T_K, v, gas: GasProperties, eos: str = "bwr"):
    """Isochoric heat capacity [J/kg/K]: cv0(T) + real-gas departure (van der Westhuizen & Els 2015)."""
    return cv0(T_K, gas) + cv_departure(T_K, v, gas, eos)


def internal_energy_departure(T_K, v, gas: GasProperties, eos: str = "bwr"):
    """u - u0(T) [J/kg] = int_inf^v (T (dp/dT)_v - p) dv' (analytic for BWR; 0 for the ideal gas)."""
    _check_eos(eos)
    if eos == "ideal":
        return 0.0 * T_K + 0.0 * v
    T2 = T_K * T_K
    r = 1.0 / v
    r2 = r * r
    return (-(gas.A0 + 3.0 * gas.C0 / T2) * r
            - 0.5 * gas.a * r2
            + 0.2 * gas.a * gas.alpha * r2 * r2 * r
            + 3.0 * gas.c / T2 * _exp_integral(v, gas))


def internal_energy(T_K, v, gas: GasProperties, eos: str = "bwr"):
    """Specific internal energy u(T, v) [J/kg] relative to an arbitrary reference: int cv0 dT + departure."""
    return _u0(T_K, gas) + internal_energy_departure(T_K, v, gas, eos)


def entropy(T_K, v, gas: GasProperties, eos: str = "bwr"):
    """Specific entropy s(T, v) [J/kg/K], arbitrary reference: int cv0/T dT + R ln v + int_inf^v (p_T - R/v') dv'."""
    _check_eos(eos)
    s = _s0(T_K, gas) + gas.R * log(v)
    if eos == "ideal":
        return s
    T3 = T_K * T_K * T_K
    r = 1.0 / v
    return (s - (gas.B0 * gas.R + 2.0 * gas.C0 / T3) * r
            - 0.5 * gas.b * gas.R * r * r
            + 2.0 * gas.c / T3 * _exp_integral(v, gas))


# --- energy equation and heat flow ----------------------------------------------------------

def gas_temperature_rate(T_K, T_wall_K, tau_s, v, dv_dt, gas: GasProperties, eos: str = "bwr"):
    """dT/dt [K/s] = (T_w - T)/tau - (T/cv) (dp/dT)_v dv/dt (REFERENCE §6, van der Westhuizen & Els 2015)."""
    return ((T_wall_K - T_K) / tau_s
            - T_K / cv(T_K, v, gas, eos) * dp_dT_at_constant_v(T_K, v, gas, eos) * dv_dt)


def heat_flow_to_wall(T_K, T_wall_K, tau_s, mass_kg, cv_J_per_kgK):
    """Heat flow [W] from the gas to the wall, m cv (T - T_w)/tau (the loss term of the REFERENCE §6 energy equation)."""
    return mass_kg * cv_J_per_kgK * (T_K - T_wall_K) / tau_s


# --- polytropic law ---------------------------------------------------------------------------

def polytropic_pressure(p_ref_Pa, V_ref_m3, V_m3, n):
    """p = p_ref (V_ref/V)^n [Pa] (seed 000 eq. 1; force F = p A is seed 000 eq. 5)."""
    return p_ref_Pa * (V_ref_m3 / V_m3) ** n


# --- inverse of the equation of state (NumPy only) ------------------------------------------

def _check_range(p, T, gas):
    if np.any(~np.isfinite(T)) or np.any(T < gas.T_min) or np.any(T > gas.T_max):
        bad = T[(~np.isfinite(T)) | (T < gas.T_min) | (T > gas.T_max)].ravel()[0]
        raise UserInputError(f"T_K: {float(bad):.6g} K is outside the {gas.name} model range {gas.T_min:g}-{gas.T_max:g} K")
    if np.any(~np.isfinite(p)) or np.any(p <= 0) or np.any(p > gas.p_max):
        bad = p[(~np.isfinite(p)) | (p <= 0) | (p > gas.p_max)].ravel()[0]
        raise UserInputError(f"p_Pa: {float(bad):.6g} Pa is outside the {gas.name} model range 0 < p <= {gas.p_max:g} Pa")


def specific_volume(p_Pa, T_K, gas: GasProperties, eos: str = "bwr"):
    """Specific volume v [m^3/kg] with pressure(T, v) = p: NumPy only; raises UserInputError (a ValueError) outside validity.

    BWR: bracketed Newton iteration on the density (p is monotonic in density for T >= 150 K).
    """
    _check_eos(eos)
    if is_symbolic(p_Pa, T_K):
        raise TypeError("specific_volume is NumPy only (iterative inverse); use pressure() in symbolic models")
    p, T = np.broadcast_arrays(np.asarray(p_Pa, dtype=float), np.asarray(T_K, dtype=float))
    _check_range(p, T, gas)
    rho_ideal = p / (gas.R * T)
    if eos == "ideal":
        return (1.0 / rho_ideal)[()]
    lo = np.zeros_like(rho_ideal)
    hi = 2.0 * rho_ideal
    for _ in range(60):                       # expand the bracket until p(hi) > p
        short = pressure(T, 1.0 / hi, gas) <= p
        if not short.any():
            break
        lo = np.where(short, hi, lo)
        hi = np.where(short, 2.0 * hi, hi)
    rho = 0.5 * (lo + hi)
    rho = np.where((rho_ideal > lo) & (rho_ideal < hi), rho_ideal, rho)
    for _ in range(100):
        v = 1.0 / rho
        f = pressure(T, v, gas) - p
        lo = np.where(f < 0, rho, lo)
        hi = np.where(f > 0, rho, hi)
        dfdrho = -v * v * dp_dv_at_constant_T(T, v, gas)
        step = f / dfdrho
        new = rho - step
        new = np.where((new >= lo) & (new <= hi) & (dfdrho > 0), new, 0.5 * (lo + hi))
        done = np.abs(new - rho) <= 1e-14 * rho
        rho = new
        if done.all():
            break
    else:  # pragma: no cover - the bracket guarantees convergence
        raise RuntimeError("specific_volume: BWR inversion did not converge")
    return (1.0 / rho)[()]


def gas_mass(p_Pa, T_K, V_m3, gas: GasProperties, eos: str = "bwr"):
    """Gas mass [kg] = V / specific_volume(p, T) (NumPy only)."""
    V = np.asarray(V_m3, dtype=float)
    if np.any(~(V > 0)):
        raise UserInputError(f"V_m3: gas volume must be > 0 m^3, got {V_m3!r}")
    return (V / specific_volume(p_Pa, T_K, gas, eos))[()]


def isochoric_pressure(p_ref_Pa, T_ref_K, T_K, gas: GasProperties, eos: str = "bwr"):
    """Pressure [Pa] at T of the gas that has p_ref at T_ref, same mass and volume (seed 000 eq. 6 logic; NumPy only)."""
    v = specific_volume(p_ref_Pa, T_ref_K, gas, eos)
    return pressure(np.asarray(T_K, dtype=float), v, gas, eos)[()]
