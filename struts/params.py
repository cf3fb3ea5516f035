"""Typed strut parameters loaded from YAML files with units and provenance.

A strut file (struts/data/<name>.yaml, or any path) holds every quantity as
`key: "4.8 MPa"` or `key: {value: "4.8 MPa", source: "seed 000 §2"}`; bare numbers
are SI. Unknown keys are rejected. `load_strut("apc")` returns a `StrutParams`.
"""
from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Literal

from pydantic import model_validator

from hpsim.config import Model, Plain, Quantity, deep_update, load_yaml, validate
from hpsim.errors import UserInputError

from .maps import InternalMaps

Pa = Quantity("Pa")
K = Quantity("K")
m = Quantity("m")
m2 = Quantity("m**2")
m3 = Quantity("m**3")
s = Quantity("s")
N = Quantity("N")
m_per_s = Quantity("m/s")
N_s_per_m = Quantity("N*s/m")
N_per_m = Quantity("N/m")
per_K = Quantity("1/K")
kg_per_m3 = Quantity("kg/m**3")
m2_per_s = Quantity("m**2/s")
Pa_per_K = Quantity("Pa/K")
Number = Plain()


class Geometry(Model):
    """Areas and volumes (seed 000 eq. 2-5 for the separated strut)."""

    _must_be_positive = ("gas_area", "gas_volume_extended", "stroke", "valve_area", "oil_volume")
    _must_be_non_negative = ("piston_area", "rod_area", "rod_chamber_volume", "piston_chamber_oil_volume")

    gas_area: m2                 # A = A_o1 - A_d: gas volume change per unit deflection
    gas_volume_extended: m3      # V_g0 at full extension (x = 0), at the charge temperature
    stroke: m                    # usable deflection from full extension to the bump stop
    valve_area: m2               # oil displaced through the damping valve per unit deflection
    oil_volume: m3               # total oil volume (thermal expansion, seed 000 eq. 6)
    # integrated strut (seed 001 eq. 1, 5-7): piston area A_c, rod area A_r (= gas_area, the
    # volume the rod pushes into the strut per unit deflection), rod-side chamber volume at full
    # extension, emulsion volume in the piston-side chamber at full extension and charge pressure
    piston_area: m2 = 0.0
    rod_area: m2 = 0.0
    rod_chamber_volume: m3 = 0.0
    piston_chamber_oil_volume: m3 = 0.0


class Charge(Model):
    """Gas charge: pressure at full extension at the charge temperature (seed 000 §2)."""

    pressure: Pa
    temperature: K

    @model_validator(mode="after")
    def _positive(self):
        if self.pressure <= 0:
            raise ValueError(f"charge.pressure must be > 0 Pa, got {self.pressure}")
        if self.temperature <= 0:
            raise ValueError(f"charge.temperature must be > 0 K, got {self.temperature}")
        return self


class Gas(Model):
    _must_be_positive = ("thermal_time_constant",)
    eos: Literal["ideal", "bwr"] = "bwr"
    # "energy": gas temperature state with heat exchange (REFERENCE §6);
    # "polytropic": p V^n = const from the state at full extension (seed 000 eq. 1, 5)
    process: Literal["energy", "polytropic"] = "energy"
    polytropic_exponent: Number = 1.3
    thermal_time_constant: s = 2.0


class Oil(Model):
    _must_be_positive = ("density", "reference_temperature", "bulk_modulus", "viscosity_T1", "viscosity_nu1",
                 "viscosity_T2", "viscosity_nu2")
    _must_be_non_negative = ("expansion", "bulk_modulus_slope")
    density: kg_per_m3                   # at reference temperature
    reference_temperature: K
    expansion: per_K                     # volumetric thermal expansion beta_o (seed 000 eq. 6)
    bulk_modulus: Pa
    bulk_modulus_slope: Pa_per_K = 0.0   # fall per kelvin (seed 001: 8 MPa/K)
    # Walther/ASTM D341 viscosity from two datasheet points (REFERENCE §7)
    viscosity_T1: K
    viscosity_nu1: m2_per_s
    viscosity_T2: K
    viscosity_nu2: m2_per_s


class Valve(Model):
    """Damping valve assembly between the oil chambers (REFERENCE §7)."""

    _must_be_positive = ("bleed_area", "critical_reynolds", "compliant_oil_volume", "number_of_orifices")
    _must_be_non_negative = ("check_area_max", "check_dp_crack", "check_dp_full", "relief_comp_area",
                             "relief_comp_crack", "relief_comp_full", "relief_reb_area", "relief_reb_crack",
                             "relief_reb_full", "leakage", "check_number")
    _must_be_fraction = ("discharge_coefficient", "check_discharge_coefficient")

    discharge_coefficient: Number = 0.7
    bleed_area: m2
    # laminar-turbulent transition of the orifice law: Re_crit at the bleed hydraulic diameter
    critical_reynolds: Number = 1000.0
    check_area_max: m2 = 0.0
    check_dp_crack: Pa = 0.1e6
    check_dp_full: Pa = 0.5e6
    relief_comp_area: m2 = 0.0
    relief_comp_crack: Pa = 10e6
    relief_comp_full: Pa = 12e6
    relief_reb_area: m2 = 0.0
    relief_reb_crack: Pa = 10e6
    relief_reb_full: Pa = 12e6
    leakage: Quantity("m**3/(Pa*s)") = 0.0
    # "compressible": the valve pressure drop is a state, built by the flow mismatch acting on the
    # compliance V/beta of the oil ahead of the valve (continuity with compressibility, seed 001
    # eq. 5-6); "incompressible": an algebraic variable (seed 000 eq. 2, oil incompressible; layout
    # separated); "quasi_steady" (layout integrated): the chamber-pressure relaxation through the valves
    # taken as instantaneous (singular-perturbation reduction, struts.integrated), the valve pressure
    # drop an algebraic variable, the emulsion's compressibility kept in the volume balance
    oil_model: Literal["compressible", "incompressible", "quasi_steady"] = "compressible"
    compliant_oil_volume: m3 = 1.0e-3
    number_of_orifices: Number = 1.0
    check_number: Number = 1.0
    # discharge coefficient of the check valves (seed 001 eq. 12: C_v); None: discharge_coefficient
    check_discharge_coefficient: Number | None = None
    # the check valves' own laminar-turbulent transition (struts.orifice): critical Reynolds number at their
    # hydraulic diameter at full opening; None: the bleed's transition (one law for the whole assembly)
    check_critical_reynolds: Number | None = None
    check_hydraulic_diameter: m | None = None


REVERSAL_MEMORY_TIME_S = 0.005     # default of friction.reversal_memory_time: 5 ms, inside the 31 ms half period at 8 Hz


class Friction(Model):
    """Seal friction: Coulomb (pressure dependent) + Stribeck + viscous (REFERENCE §7, seed 001 eq. 2-3)."""

    _must_be_positive = ("stribeck_velocity", "smoothing_velocity", "hysteresis_smoothing_displacement",
                         "bristle_stiffness", "reversal_memory_time")
    _must_be_non_negative = ("F0_compression", "F0_rebound", "pressure_coefficient", "breakaway_ratio", "viscous",
                             "hysteresis_velocity_compression", "hysteresis_velocity_rebound", "bristle_damping")

    model: Literal["stribeck", "lugre"] = "stribeck"
    F0_compression: N
    F0_rebound: N
    pressure_coefficient: Quantity("N/Pa") = 0.0     # f_p in F_C = F0 + f_p p
    breakaway_ratio: Number = 1.0                    # K_brk = F_static / F_C
    stribeck_velocity: m_per_s = 0.01
    viscous: N_s_per_m = 0.0
    smoothing_velocity: m_per_s = 1e-3               # width of the smooth sign
    hysteresis_velocity_compression: m_per_s = 0.0   # seed 001 eq. 3 band (0: off)
    hysteresis_velocity_rebound: m_per_s = 0.0
    hysteresis_smoothing_displacement: m = 1e-3      # eps_x: width of sgn(x) in the band (numerical)
    # time constant of the reversal memory (the stroke direction, struts.friction.stroke_direction_rate) once
    # the velocity has left the band: numerical, well below a half period. None: REVERSAL_MEMORY_TIME_S (kept out
    # of the parameters so that a strut without a band compiles exactly as before)
    reversal_memory_time: s | None = None
    bristle_stiffness: N_per_m = 1e7                 # LuGre sigma0
    bristle_damping: N_s_per_m = 0.0                 # LuGre sigma1
    # relative rise of the seal's contact pressure, hence its Coulomb level, per kelvin above the oil's reference
    # temperature (struts.seal_friction.contact_coulomb_level); used by internals: physical only
    contact_temperature_coefficient: per_K = 0.0


class EndStops(Model):
    """Elastic end stops at full extension and full compression (assumed values)."""

    _must_be_positive = ("smoothing",)
    _must_be_non_negative = ("stiffness", "damping")

    stiffness: N_per_m = 2e7
    damping: N_s_per_m = 2e4
    smoothing: m = 0.5e-3


class Limits(Model):
    """Temperature limits of the strut's materials, for validity warnings (vehicle.results.validity), and its
    pressure ratings, for `hpsim vehicle check` (vehicle.physics.vehicle_check).

    None: not known (no warning). The oil data's own range is that of the viscosity datasheet
    points (oil.viscosity_T1 .. viscosity_T2) widened to where the Walther and Andrade extrapolations
    through them differ by 10 % (struts.oil.viscosity_extrapolation_range, vehicle.results.validity).
    """

    seal_max_temperature: K | None = None    # maximum continuous service temperature of the seals
    seal_min_temperature: K | None = None    # below it the seals stiffen and may leak
    oil_max_temperature: K | None = None     # maximum service temperature of the oil
    # pressure ratings of the strut (docs/vehicles.md "Strut files"; `hpsim vehicle check`): the gas pressure
    # it may carry standing (the static load over the gas area) and the highest it may reach at full bump
    rated_static_pressure: Pa | None = None
    rated_peak_pressure: Pa | None = None

    @model_validator(mode="after")
    def _ratings(self):
        lo, hi = self.rated_static_pressure, self.rated_peak_pressure
        for name, v in (("rated_static_pressure", lo), ("rated_peak_pressure", hi)):
            if v is not None and not 0.1e6 <= v <= 200e6:
                raise ValueError(f"{name} must be in [0.1, 200] MPa, got {v / 1e6:.6g} MPa")
        if lo is not None and hi is not None and hi < lo:
            raise ValueError(f"rated_peak_pressure ({hi / 1e6:.6g} MPa) must be >= rated_static_pressure "
                             f"({lo / 1e6:.6g} MPa)")
        return self


class Emulsion(Model):
    """Gas-oil emulsion of the integrated strut (seed 001 eq. 8-11) and, with internals: physical, the dynamics of its
    free-gas fraction (struts.emulsion)."""

    _must_be_fraction = ("initial_gas_fraction",)
    _must_be_positive = ("dissolution_time", "interface_time", "ostwald_reference_temperature")
    _must_be_non_negative = ("ostwald_coefficient", "interface_entrainment", "release_efficiency")

    initial_gas_fraction: Number = 0.006
    # Henry's law: Ostwald coefficient of the charge gas in the oil at a reference temperature and its van 't Hoff
    # dependence on temperature (enthalpy of solution, > 0: more soluble when warmer)
    # (the free-gas dynamics' keys are optional so that a strut without them carries no parameter for them;
    # internals: physical requires those without a default, IntegratedStrut.check_parameters)
    ostwald_coefficient: Number = 0.0
    ostwald_reference_temperature: K | None = None
    solution_enthalpy: Quantity("J/mol") = 0.0
    # share of the gas set free by the valve pressure drop that forms bubbles before the flow leaves the jet
    release_efficiency: Number | None = None
    # entrainment at the agitated gas-oil interface per unit interface acceleration over g [1/s]
    interface_entrainment: Quantity("1/s") = 0.0
    # exponent of the oil viscosity in the interface entrainment: (nu_ref / nu)^m
    entrainment_viscosity_exponent: Number = 0.0
    # time constant of the free gas's return to the gas pocket or into solution at the reference temperature
    dissolution_time: s | None = None
    # the interface's lag behind the strut's motion (its acceleration is read through this first-order lag)
    interface_time: s | None = None


class StrutParams(Model):
    name: str
    description: str = ""
    layout: Literal["separated", "integrated"]
    # integrated strut: "identified" reads the internal parameters (gas fraction, discharge coefficients, friction)
    # from internal_maps or the file's constants, as seed 001 identified them per test; "physical" lets them emerge
    # (struts.integrated: the emulsion's free gas as a state, the check valves' Reynolds law, the seal's contact
    # pressure over temperature) and ignores internal_maps
    internals: Literal["identified", "physical"] = "identified"
    geometry: Geometry
    charge: Charge
    gas: Gas
    oil: Oil
    valve: Valve
    friction: Friction
    end_stops: EndStops = EndStops()
    emulsion: Emulsion = Emulsion()
    limits: Limits = Limits()
    # internal parameters over body temperature and excitation frequency (seed 001 §5.2; struts.maps)
    internal_maps: InternalMaps | None = None
    calibration: dict = {}      # free text: what was fitted to what

    def with_overrides(self, overrides: dict) -> "StrutParams":
        data = deep_update(self.model_dump(), overrides)
        return validate(StrutParams, data, f"strut {self.name} (overrides)")


def builtin_struts() -> list[str]:
    folder = resources.files("struts") / "data"
    return sorted(p.name[:-5] for p in folder.iterdir()
                  if p.name.endswith(".yaml") and p.name != "nitrogen.yaml")


def strut_file(name_or_path: str | Path) -> Path:
    """Resolve a built-in strut name ("apc") or a path to its YAML file."""
    p = Path(name_or_path)
    if p.suffix in (".yaml", ".yml"):
        if not p.exists():
            raise UserInputError(f"strut file {p}: not found")
        return p
    if str(name_or_path) in builtin_struts():
        return Path(str(resources.files("struts") / "data" / f"{name_or_path}.yaml"))
    raise UserInputError(
        f"--strut: unknown strut {str(name_or_path)!r}; built-in: {', '.join(builtin_struts())} "
        "(or an own strut file: a path ending in .yaml; in vehicle and scenario files file: my_strut.yaml)")


def load_strut(name_or_path: str | Path, overrides: dict | None = None) -> StrutParams:
    path = strut_file(name_or_path)
    data = load_yaml(path)
    if not isinstance(data, dict):
        raise UserInputError(f"{path}: expected a mapping of strut parameters")
    if overrides:
        data = deep_update(data, overrides)
    return validate(StrutParams, data, str(path))
