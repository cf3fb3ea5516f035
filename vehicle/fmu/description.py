"""modelDescription.xml of an hpsim FMU (FMI 2.0, co-simulation; docs/fmu.md).

Variables in the order parameters, calculated parameters, inputs, outputs; value references as in
fmi2_wrapper.c (p, then u, then y). Units are the parameter files' SI units, each defined by its SI base-unit
exponents (pint); kelvin has a degC display unit.
"""
from __future__ import annotations

import time
import xml.etree.ElementTree as ET
from functools import lru_cache

from hpsim.units import registry

_BASE = {"[mass]": "kg", "[length]": "m", "[time]": "s", "[current]": "A", "[temperature]": "K",
         "[substance]": "mol", "[luminosity]": "cd"}


@lru_cache(maxsize=None)
def base_units(unit: str) -> dict:
    """FMI BaseUnit attributes of an SI unit string (exponents of kg, m, s, A, K, mol, cd; factor)."""
    if unit in ("1", ""):
        return {}
    q = registry()(unit).to_base_units()
    out = {}
    for dim, power in q.dimensionality.items():
        if dim not in _BASE or power != int(power):
            raise ValueError(f"unit {unit!r}: no FMI base-unit form ({dim}^{power})")
        out[_BASE[dim]] = str(int(power))
    if abs(q.magnitude - 1.0) > 1e-12:
        out["factor"] = repr(float(q.magnitude))
    return out


def _fmt(value: float) -> str:
    return repr(float(value))


def _scalar(parent, name, vr, description, causality, variability, unit, start=None, initial=None, bounds=(None, None)):
    attrs = {"name": name, "valueReference": str(vr), "description": description, "causality": causality,
             "variability": variability}
    if initial is not None:
        attrs["initial"] = initial
    sv = ET.SubElement(parent, "ScalarVariable", attrs)
    real = {"unit": unit} if unit not in ("1", "") else {}
    if bounds[0] is not None:
        real["min"] = _fmt(bounds[0])
    if bounds[1] is not None:
        real["max"] = _fmt(bounds[1])
    if start is not None:
        real["start"] = _fmt(start)
    ET.SubElement(sv, "Real", real)


def model_description(spec, guid: str, source_files: list[str]) -> bytes:
    """The XML text of `spec` (vehicle.fmu.build.FmuSpec)."""
    s = spec.sizes
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "2.0", "modelName": spec.model_name, "guid": guid, "description": spec.description,
        "generationTool": "hpsim export fmu", "generationDateAndTime": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "variableNamingConvention": "flat", "numberOfEventIndicators": "0"})
    cs = ET.SubElement(root, "CoSimulation", {
        "modelIdentifier": spec.identifier, "canHandleVariableCommunicationStepSize": "true",
        "canGetAndSetFMUstate": "true", "canSerializeFMUstate": "true", "canInterpolateInputs": "true", "maxOutputDerivativeOrder": "0",
        "canBeInstantiatedOnlyOncePerProcess": "false", "canNotUseMemoryManagementFunctions": "false"})
    files = ET.SubElement(cs, "SourceFiles")
    for f in source_files:
        ET.SubElement(files, "File", {"name": f})
    variables = spec.parameters + spec.calculated + spec.inputs + spec.output_variables
    units = sorted({v.unit for v in variables if v.unit not in ("1", "")})
    ud = ET.SubElement(root, "UnitDefinitions")
    for u in units:
        el = ET.SubElement(ud, "Unit", {"name": u})
        ET.SubElement(el, "BaseUnit", base_units(u))
        if u == "K":
            ET.SubElement(el, "DisplayUnit", {"name": "degC", "offset": "-273.15"})
    ET.SubElement(root, "DefaultExperiment", {"startTime": "0.0", "stopTime": _fmt(spec.stop_time_s),
                                              "stepSize": _fmt(spec.dt_s)})
    mv = ET.SubElement(root, "ModelVariables")
    index, outputs, initial_unknowns = 0, [], []
    for v in spec.parameters:
        _scalar(mv, v.name, v.index, v.description, "parameter", "fixed", v.unit, spec.p_start[v.index], "exact",
                (v.min, v.max))
        index += 1
    for v in spec.calculated:
        _scalar(mv, v.name, v.index, v.description, "calculatedParameter", "fixed", v.unit, None, "calculated")
        index += 1
        initial_unknowns.append(index)
    for v in spec.inputs:
        _scalar(mv, v.name, s["np"] + v.index, v.description, "input", "continuous", v.unit, v.start)
        index += 1
    for v in spec.output_variables:
        _scalar(mv, v.name, s["np"] + s["nu"] + v.index, v.description, "output", "continuous", v.unit)
        index += 1
        outputs.append(index)
        initial_unknowns.append(index)
    ms = ET.SubElement(root, "ModelStructure")
    out_el = ET.SubElement(ms, "Outputs")
    for k in outputs:
        ET.SubElement(out_el, "Unknown", {"index": str(k)})
    init_el = ET.SubElement(ms, "InitialUnknowns")
    for k in sorted(initial_unknowns):
        ET.SubElement(init_el, "Unknown", {"index": str(k)})
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)
