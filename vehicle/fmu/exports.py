"""The two FMUs hpsim exports (docs/fmu.md): `strut_spec` (one strut with its heat network) and `vehicle_spec`
(the whole vehicle of a scenario), each an `FmuSpec` for `vehicle.fmu.build.build_fmu`.

Both step with the compiled ROS2 solver of a drive (`vehicle.numerics.solvers.Ros2`, one internal step per call
of the generated step function) and take their parameters as an input of the generated C, so a parameter set
through FMI needs no compiler. Units come from the parameter models (`hpsim.config.Quantity`), descriptions
from the parameter files' `source` entries.
"""
from __future__ import annotations

import fnmatch
import inspect

import casadi as ca
import numpy as np
from pydantic import BaseModel, BeforeValidator

from hpsim.config import load_yaml
from hpsim.errors import UserInputError
from struts.params import load_strut, strut_file
from vehicle.fmu.build import FmuSpec, Variable
from vehicle.fmu.strut_unit import INPUTS, RATE_OF, RUN_PARAMETERS, StrutUnit
from vehicle.numerics.solvers import Ros2
from vehicle.physics import thermal
from vehicle.physics.equilibrium import EquilibriumSolver, charge_gas_masses
from vehicle.physics.model import VehicleModel
from vehicle.physics.params import load_vehicle, vehicle_file
from vehicle.scenario.schema import vehicle_data


# --- parameter metadata ------------------------------------------------------------------------
def field_unit(model: BaseModel, path: list[str]) -> str:
    """SI unit of the field at `path` in a parameter model (the `Quantity(unit)` it was declared with; "1" for
    plain numbers)."""
    obj = model
    for part in path[:-1]:
        obj = obj[int(part)] if part.isdigit() else getattr(obj, part)
    last = path[-1]
    if last.isdigit():           # an item of a QuantityList: the list field's unit
        return field_unit(model, path[:-1])
    info = type(obj).model_fields[last]
    for md in info.metadata:
        if isinstance(md, BeforeValidator):
            unit = inspect.getclosurevars(md.func).nonlocals.get("unit")
            if unit:
                return unit
    return "1"


def _value_at(model: BaseModel, path: list[str]):
    obj = model
    for part in path:
        obj = obj[int(part)] if part.isdigit() else getattr(obj, part)
    return obj


def source_text(raw, path: list[str]) -> str:
    """The `source` of the value at `path` in a parameter file's mapping ("" when it gives none)."""
    node = raw
    for part in path:
        if isinstance(node, list) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        elif isinstance(node, dict) and part in node:
            node = node[part]
        else:
            return ""
    return str(node.get("source", "")) if isinstance(node, dict) else ""


# An FMU parameter re-tunes a validated file: a value set through FMI keeps the sign of the exported one (a zero
# switches a mechanism off and is structure, not a parameter: hpsim.parameters), so a negative charge pressure or
# stroke, which the file loaders refuse, is refused too; and it stays within this factor of it, wide enough for a
# test rig that holds the strut at its temperature by a capacity 1e7-1e8 times the strut's (docs/fmu.md)
PARAMETER_RANGE_FACTOR = 1e9
# fractions (the model's `_must_be_fraction` fields) stay within [0, 1]
FRACTION_FIELDS = ("emissivity", "view_factor", "anti_squat", "anti_dive", "oil_capacity_fraction",
                   "surface_capacity_fraction")
# the start temperature of the strut FMU: from the cold case of `hpsim vehicle check` (-30 degC) less 20 K to a
# strut far beyond its seals' and oil's limits (200 degC), the range where the oil and gas laws are fitted
T_START_RANGE_K = (223.15, 473.15)


def parameter_range(name: str, value: float) -> tuple[float, float]:
    """The allowed [min, max] of an exposed parameter through FMI (PARAMETER_RANGE_FACTOR, FRACTION_FIELDS)."""
    a, b = value / PARAMETER_RANGE_FACTOR, value * PARAMETER_RANGE_FACTOR
    lo, hi = min(a, b), max(a, b)
    if name.rsplit(".", 1)[-1] in FRACTION_FIELDS:
        lo, hi = max(lo, 0.0), min(hi, 1.0)
    return lo, hi


def _parameter(name: str, unit: str, raw, path: list[str], changed: bool, index: int, p_start) -> Variable:
    """An exposed parameter: its unit, its allowed range, and the file's source as description (unless the export
    changed the value: then the source no longer applies)."""
    source = "set at export" if changed else source_text(raw, path)
    lo, hi = parameter_range(name, p_start[index])
    return Variable(name, unit, f"{name} [{unit}]: {source}" if source else f"{name} [{unit}]", index, p_start[index],
                    lo, hi)


def _outputs_as_variables(entries) -> list[Variable]:
    return [Variable(name, unit, text, k) for k, (name, unit, text) in enumerate(entries)]


def _step_functions(model, dt_s: float) -> dict:
    """One internal step of the drive's compiled ROS2 solver for `model` ((z, u0, u1, pw) -> z) and p -> pw."""
    step, parametric = Ros2(dt_s).step_functions(model)
    return {"step": step, "parametric": parametric}


# --- the strut ---------------------------------------------------------------------------------
def strut_spec(strut: str, overrides: dict | None = None, *, heat_from: str = "apc_8x8", dt_s: float = 1e-3,
               motion_centre_m: float | None = None, T_start_K: float | None = None) -> FmuSpec:
    """The strut FMU of strut file `strut` (with `overrides`), its heat network from vehicle file `heat_from`."""
    params, base = load_strut(strut, overrides or None), load_strut(strut)
    vehicle = load_vehicle(heat_from)
    unit = StrutUnit(params, vehicle.heat, name=params.name)
    stroke = params.geometry.stroke
    centre = stroke / 2 if motion_centre_m is None else motion_centre_m
    T0 = params.charge.temperature if T_start_K is None else T_start_K
    if not 0.0 <= centre <= stroke:
        raise UserInputError(f"--mean: the motion centre must lie in the stroke [0, {stroke * 1e3:.4g}] mm of strut "
                             f"{params.name}, got {centre * 1e3:.4g} mm")
    if not T_START_RANGE_K[0] <= T0 <= T_START_RANGE_K[1]:
        raise UserInputError(f"--start-temperature: must be in [{T_START_RANGE_K[0] - 273.15:g}, "
                             f"{T_START_RANGE_K[1] - 273.15:g}] degC, got {T0 - 273.15:.4g} degC")
    p_start = unit.default_parameters(centre, T0)
    raw_strut, raw_vehicle = load_yaml(strut_file(strut)), load_yaml(vehicle_file(heat_from))
    run_range = {"motion_centre": (0.0, stroke), "T_start": T_START_RANGE_K}
    parameters = [Variable(name, u, text, k, p_start[k], *run_range[name])
                  for k, (name, u, text) in enumerate(RUN_PARAMETERS) if name != "gas_mass"]
    for k, name in enumerate(unit.parameters.names):
        head, *path = name.split(".")
        model, raw = (params, raw_strut) if head == "strut" else (vehicle.heat, raw_vehicle.get("heat", {}))
        changed = head == "strut" and _value_at(base, path) != _value_at(params, path)
        parameters.append(_parameter(name, field_unit(model, path), raw, path, changed, unit.n_run + k, p_start))
    inputs = [Variable(n, u, d, k, s) for k, ((n, u, d), s) in
              enumerate(zip(INPUTS, (centre, 0.0, T0, 0.0)))]
    names = [n for n, _, _ in INPUTS]
    rate_of = [names.index(RATE_OF[n]) if n in RATE_OF else -1 for n in names]
    return FmuSpec(
        identifier=f"hpsim_strut_{_c_name(params.name)}", model_name=f"hpsim strut {params.name}",
        description=f"hpsim: {params.description} with its heat network (vehicle file {heat_from}); "
                    f"co-simulation, internal step {dt_s * 1e3:g} ms",
        dt_s=dt_s, **_step_functions(unit, dt_s), outputs=unit.output_function(), initial=unit.initial_function(),
        nx=unit.nx, p_start=p_start, parameters=parameters, inputs=inputs,
        output_variables=_outputs_as_variables(unit.outputs()), rate_of=rate_of,
        run=unit.run_parameters_function(),
        calculated=[Variable("gas_mass", RUN_PARAMETERS[0][1], RUN_PARAMETERS[0][2], 0)])


def _c_name(text: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in text)


# --- the vehicle -------------------------------------------------------------------------------
# theta entries a vehicle FMU exposes: those that do not shape the standing equilibrium its start state was solved
# for at export (heat, damping, friction, levelling); everything else is fixed by the export (docs/fmu.md)
VEHICLE_PARAMETER_PATTERNS = ("vehicle.heat.", "vehicle.compensation.", "vehicle.axles.*.heat.",
                              "strut*.valve.", "strut*.friction.", "strut*.end_stops.",
                              "strut*.gas.thermal_time_constant", "strut*.oil.viscosity_")
HULL_OUTPUTS = (("heave", "z", "m", "hull heave at the centre of gravity, + up, from the charged pose"),
                ("pitch", "theta", "rad", "hull pitch angle"), ("roll", "phi", "rad", "hull roll angle"),
                ("heave_rate", "dz", "m/s", "hull heave rate"), ("pitch_rate", "dtheta", "rad/s", "hull pitch rate"),
                ("roll_rate", "dphi", "rad/s", "hull roll rate"))
STATION_OUTPUTS = {"wheel_load": ("N", "tyre vertical load"), "strut_force": ("N", "strut force"),
                   "strut_deflection": ("m", "strut deflection, 0 at full extension"),
                   "strut_velocity": ("m/s", "strut deflection rate, > 0 in compression"),
                   "gas_pressure": ("Pa", "strut gas pressure"), "gas_temperature": ("K", "strut gas temperature"),
                   "power_valve": ("W", "power dissipated in the strut's valves"),
                   "power_friction": ("W", "power dissipated by the strut's seal friction")}
RIDE_OUTPUTS = {"aw2": ("m**2/s**3", "int a_w^2 dt (ISO 2631-1 Wk, vertical) since the start; weighted r.m.s. "
                                     "acceleration sqrt(dI/T)"),
                "aw4": ("m**4/s**7", "int a_w^4 dt (Wk) since the start; vibration dose value dI^(1/4)"),
                "awl2": ("m**2/s**3", "int a_wl^2 dt (ISO 2631-1 Wd, lateral) since the start"),
                "pabs": ("J", "int absorbed power dt since the start; absorbed power dI/T")}


def _matches(name: str, pattern: str) -> bool:
    return fnmatch.fnmatchcase(name, pattern + ("*" if pattern.endswith(".") or pattern.endswith("_") else ""))


def _vehicle_outputs(model: VehicleModel):
    """((name, unit, description) list, the output function (x, memory, u, p) -> y)."""
    x, _, u, p = model.symbols
    mem = model.memory_symbol
    y, hull_acc, axle_height = model.output_function_ode()(x, mem, u, p)
    entries, values = [], []
    for name, state, unit_, text in HULL_OUTPUTS:
        entries.append((name, unit_, text))
        values.append(x[model.idx(state)])
    for k, (name, unit_) in enumerate((("heave_acc", "m/s**2"), ("pitch_acc", "rad/s**2"), ("roll_acc", "rad/s**2"))):
        entries.append((name, unit_, f"hull {name.split('_')[0]} acceleration about the equilibrium"))
        values.append(hull_acc[k])
    rows = {k: j for j, k in enumerate(model.OUTPUT_NAMES)}
    for key, (unit_, text) in STATION_OUTPUTS.items():
        for i, st in enumerate(model.station_names):
            entries.append((f"{key}_{st}", unit_, f"{text}, station {st}"))
            values.append(y[rows[key] * model.n + i])
    for node in thermal.NODES:
        for i, st in enumerate(model.station_names):
            entries.append((f"T_{node}_{st}", "K", f"strut {node} temperature (heat network), station {st}"))
            values.append(x[model.idx(f"T_{node}[{i}]")])
    for term in ("valve", "friction", "gas", "end_stop"):
        for i, st in enumerate(model.station_names):
            entries.append((f"E_{term}_{st}", "J", f"strut heat from {term} since the start, station {st}"))
            values.append(x[model.idx(f"E_{term}[{i}]")])
    for k in range(model.params.n_axles):
        entries.append((f"axle_height_{k + 1}", "m", f"hull height change above axle {k + 1}"))
        values.append(axle_height[k])
    for q, (unit_, text) in RIDE_OUTPUTS.items():
        for seat in model.seat_names:
            entries.append((f"ride_{q}_{seat}", unit_, f"{text}, seat {seat}"))
            values.append(x[model.idx(f"I_{q}_{seat}")])
    return entries, ca.Function("y", [x, mem, u, p], [ca.vertcat(*values)])


def _vehicle_inputs(model: VehicleModel, ambient_K: float, speed_m_s: float):
    """(input variables in the order of u, rate_of) from the model's INPUTS."""
    names = [""] * model.nu
    variables = [None] * model.nu
    ix = model.input_index
    for i, st in enumerate(model.station_names):
        variables[ix["road"].start + i] = (f"road_{st}", "m", f"road height under the tyre of station {st} "
                                           "(enveloped road), + up", 0.0)
        variables[ix["road_rate"].start + i] = (f"road_rate_{st}", "m/s", f"rate of road_{st}; within a "
                                                "communication step the road height is extrapolated with it", 0.0)
    variables[ix["speed"]] = ("speed", "m/s", "forward speed (forced convection at the struts)", speed_m_s)
    variables[ix["ambient"]] = ("ambient_temperature", "K", "air temperature", ambient_K)
    variables[ix["acceleration"]] = ("acceleration", "m/s**2", "longitudinal acceleration, + forward (load "
                                     "transfer, drive and brake forces)", 0.0)
    names = [v[0] for v in variables]
    rate_of = [-1] * model.nu
    for i, st in enumerate(model.station_names):
        rate_of[ix["road"].start + i] = names.index(f"road_rate_{st}")
    return [Variable(n, u_, d, k, s) for k, (n, u_, d, s) in enumerate(variables)], rate_of


def _distinct_strut(model: VehicleModel, k: int):
    """(numeric StrutParams, strut file name) of the model's k-th distinct strut (`strut{k}` in theta)."""
    seen = []
    for i, strut in enumerate(model.struts):
        if all(strut is not s for s, _ in seen):
            seen.append((strut, model.params.axles[model.params.station_axle(i)].strut))
    strut, name = seen[k]
    return strut.p, name


def vehicle_spec(prepared, *, dt_s: float | None = None, label: str = "") -> FmuSpec:
    """The vehicle FMU of a prepared scenario (vehicle.scenario.schema.prepare): its vehicle, struts, overrides,
    initial temperatures, ambient, compensation switch and solver step; the start state is the standing
    equilibrium at the initial temperatures, solved here."""
    S = prepared.scenario
    model = prepared.model()
    dt_s = S.solver.dt if dt_s is None else dt_s
    gas = charge_gas_masses(model)
    eq = EquilibriumSolver(model).solve(np.asarray(prepared.initial_temperatures_K, float), gas)
    z0 = np.concatenate([model.state_at_rest(eq, gas), model.initial_memory()])
    p_start = [float(v) for v in model.run_parameters(gas, S.compensation.enabled)]
    *_, p = model.symbols
    initial = ca.Function("init", [p, ca.SX.sym("u", model.nu)], [ca.DM(z0)])
    entries, outputs = _vehicle_outputs(model)
    parameters = [Variable("compensation_enabled", "1", "pressure compensation (levelling) on: 1, off: 0",
                           2 * model.n, p_start[2 * model.n], 0.0, 1.0)]
    V = prepared.vehicle
    raw_vehicle, _ = vehicle_data(S, prepared.source)
    for k, name in enumerate(model.parameters.names):
        if not any(_matches(name, pat) for pat in VEHICLE_PARAMETER_PATTERNS):
            continue
        head, *path = name.split(".")
        if head == "vehicle":      # raw_vehicle holds the scenario's overrides: an overridden value has no source
            unit_, raw, changed = field_unit(V, path), raw_vehicle, False
        else:
            strut_params, strut_name = _distinct_strut(model, int(head[len("strut"):]))
            unit_, raw = field_unit(strut_params, path), load_yaml(strut_file(strut_name))
            changed = _value_at(load_strut(strut_name), path) != _value_at(strut_params, path)
        parameters.append(_parameter(name, unit_, raw, path, changed, model.n_run + k, p_start))
    inputs, rate_of = _vehicle_inputs(model, S.ambient_temperature, float(prepared.settings().speed.speed(0.0)))
    name = label or S.vehicle.name or "vehicle"
    return FmuSpec(
        identifier=f"hpsim_vehicle_{_c_name(str(name))}", model_name=f"hpsim vehicle {name}",
        description=f"hpsim: the vehicle {name} ({model.n} stations, struts with heat networks) from "
                    f"{prepared.source.name}; co-simulation, internal step {dt_s * 1e3:g} ms",
        dt_s=dt_s, **_step_functions(model, dt_s), outputs=outputs, initial=initial, nx=model.nx,
        p_start=p_start, parameters=parameters, inputs=inputs, output_variables=_outputs_as_variables(entries),
        rate_of=rate_of, stop_time_s=60.0)
