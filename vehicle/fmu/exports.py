"""The two FMUs hpsim exports (docs/fmu.md): `strut_spec` (one strut with its heat network) and `vehicle_spec`
(the whole vehicle of a scenario), each an `FmuSpec` for `vehicle.fmu.build.build_fmu`.

Both step with the compiled ROS2 solver of a drive (`vehicle.numerics.solvers.Ros2`, one internal step per call
of the generated step function) and take their parameters as an input of the generated C, so a parameter set
through FMI needs no compiler. Units come from the parameter models (`hpsim.config.Quantity`), descriptions
from the parameter files' `source` entries.
"""
from __future__ import annotations

import inspect
from pathlib import Path

import casadi as ca
import numpy as np
from pydantic import BaseModel, BeforeValidator

from hpsim.config import load_yaml
from struts.params import load_strut, strut_file
from vehicle.fmu.build import FmuSpec, Variable
from vehicle.fmu.strut_unit import INPUTS, RATE_OF, RUN_PARAMETERS, StrutUnit
from vehicle.numerics.solvers import Ros2
from vehicle.physics import thermal
from vehicle.physics.equilibrium import EquilibriumSolver, charge_gas_masses
from vehicle.physics.model import ENERGY_TERMS, HULL_ACCELERATIONS, VehicleModel
from vehicle.physics.params import load_vehicle, vehicle_file


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


def _described(path: str, unit: str, source: str, default: str) -> str:
    text = source or default
    return f"{path} [{unit}]: {text}" if text else f"{path} [{unit}]"


def _outputs_as_variables(entries) -> list[Variable]:
    return [Variable(name, unit, text, k) for k, (name, unit, text) in enumerate(entries)]


def _step_function(model, dt_s: float) -> ca.Function:
    """One internal step of the drive's compiled ROS2 solver for `model`: (z, U (nu, 2), p) -> z."""
    return Ros2(dt_s).step_graph(model)


# --- the strut ---------------------------------------------------------------------------------
def strut_spec(strut: str, overrides: dict | None = None, *, heat_from: str = "apc_8x8", dt_s: float = 1e-3,
               motion_centre_m: float | None = None, T_start_K: float | None = None) -> FmuSpec:
    """The strut FMU of strut file `strut` (with `overrides`), its heat network from vehicle file `heat_from`."""
    params = load_strut(strut, overrides or None)
    vehicle = load_vehicle(heat_from)
    unit = StrutUnit(params, vehicle.heat, name=params.name)
    centre = params.geometry.stroke / 2 if motion_centre_m is None else motion_centre_m
    T0 = params.charge.temperature if T_start_K is None else T_start_K
    p_start = unit.default_parameters(centre, T0)
    raw_strut, raw_vehicle = load_yaml(strut_file(strut)), load_yaml(vehicle_file(heat_from))
    parameters = [Variable(name, u, text, k, p_start[k]) for k, (name, u, text) in enumerate(RUN_PARAMETERS)
                  if name != "gas_mass"]
    for k, name in enumerate(unit.parameters.names):
        head, *path = name.split(".")
        model, raw = (params, raw_strut) if head == "strut" else (vehicle.heat, raw_vehicle.get("heat", {}))
        u = field_unit(model, path)
        overridden = " (overridden at export)" if overrides and ".".join(path) in overrides else ""
        parameters.append(Variable(name, u, _described(name, u, source_text(raw, path), "") + overridden,
                                   unit.n_run + k, p_start[unit.n_run + k]))
    inputs = [Variable(n, u, d, k, s) for k, ((n, u, d), s) in
              enumerate(zip(INPUTS, (centre, 0.0, T0, 0.0)))]
    names = [n for n, _, _ in INPUTS]
    rate_of = [names.index(RATE_OF[n]) if n in RATE_OF else -1 for n in names]
    return FmuSpec(
        identifier=f"hpsim_strut_{_c_name(params.name)}", model_name=f"hpsim strut {params.name}",
        description=f"hpsim: {params.description} with its heat network (vehicle file {heat_from}); "
                    f"co-simulation, internal step {dt_s * 1e3:g} ms",
        dt_s=dt_s, step=_step_function(unit, dt_s), outputs=unit.output_function(), initial=unit.initial_function(),
        nx=unit.nx, p_start=p_start, parameters=parameters, inputs=inputs,
        output_variables=_outputs_as_variables(unit.outputs()), rate_of=rate_of,
        run=unit.run_parameters_function(),
        calculated=[Variable("gas_mass", RUN_PARAMETERS[0][1], RUN_PARAMETERS[0][2], 0)])


def _c_name(text: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in text)
