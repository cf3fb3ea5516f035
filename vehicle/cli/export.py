"""`hpsim export fmu`: the strut (with its heat network) or the whole vehicle as an FMI 2.0 co-simulation FMU
(vehicle.fmu; docs/fmu.md)."""
from __future__ import annotations

import argparse

from hpsim.config import parse_yaml
from hpsim.errors import UserInputError
from hpsim.outputs import check_not_input, check_output_file
from hpsim.tables import format_table, print_json
from hpsim.units import parse_quantity

from .options import add_overwrite

EPILOG = """\
examples:
  hpsim export fmu --strut apc -o apc.fmu
  hpsim export fmu --strut apc --set friction.F0_compression=1.8kN --dt 0.5ms --mean 115mm -o apc.fmu
  hpsim export fmu --vehicle apc_8x8 -o apc_8x8.fmu
  hpsim export fmu --scenario scenarios/quick_demo.yaml --set compensation.enabled=true -o demo.fmu"""


def register(sub):
    p = sub.add_parser("export", help="export models for other tools (FMI 2.0 co-simulation FMUs)")
    ex = p.add_subparsers(dest="export_command", required=True, parser_class=type(p))
    f = ex.add_parser("fmu", help="an FMI 2.0 co-simulation FMU of a strut with its heat network, or of the vehicle",
                      epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    which = f.add_mutually_exclusive_group(required=True)
    which.add_argument("--strut", help="built-in strut name or path to a strut .yaml: the strut FMU")
    which.add_argument("--vehicle", help="built-in vehicle name or path: the vehicle FMU (defaults of a scenario)")
    which.add_argument("--scenario", help="scenario .yaml: the vehicle FMU of its vehicle, struts, overrides, "
                                          "initial temperatures, ambient, compensation and step")
    f.add_argument("--set", "--overrides", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override (repeatable): a strut-file key (--strut: friction.F0_compression=1.8kN) or a "
                        "scenario key (--vehicle/--scenario: vehicle.overrides.heat.capacity=30kJ/K)")
    f.add_argument("--dt", help="internal (solver) step; the communication step must be a multiple "
                                "(default: 1 ms for a strut, the scenario's solver.dt for a vehicle)")
    f.add_argument("--heat-from", default="apc_8x8",
                   help="--strut: vehicle file whose heat section is the strut's heat network (default apc_8x8)")
    f.add_argument("--mean", help="--strut: default of the motion_centre parameter (default: half the stroke)")
    f.add_argument("--start-temperature", help="--strut: default of the T_start parameter (default: the charge "
                                               "temperature)")
    f.add_argument("-o", "--output", required=True, help="the .fmu file to write")
    f.add_argument("--json", action="store_true", help="print what was written as JSON")
    add_overwrite(f)
    f.set_defaults(func=cmd_export_fmu)


def parse_overrides(items: list[str]) -> dict:
    """KEY=VALUE strings -> {key: value}, the value read as a YAML scalar (numbers, booleans, quantities)."""
    out = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise UserInputError(f"--set: expected KEY=VALUE, got {item!r}")
        out[key.strip()] = parse_yaml(text, f"--set {key.strip()}")
    return out


def _vehicle_prepared(args, overrides: dict):
    from vehicle.scenario.schema import apply_overrides, prepare, read_scenario, read_scenario_text

    if args.scenario:
        src = read_scenario(args.scenario)
    else:
        # the vehicle as a scenario with its defaults (start at the ambient temperature, no compensation)
        text = (f"vehicle: {{name: {args.vehicle!r}}}\nroad: {{iso_class: A}}\nspeed: 20 km/h\ndistance: 1 km\n"
                "ambient_temperature: 25 degC\n")
        src = read_scenario_text(text, f"--vehicle {args.vehicle}", ".")
    if overrides:
        src.data = apply_overrides(src.data, overrides, "--set")
    return prepare(src)


def cmd_export_fmu(args):
    from vehicle.fmu.build import build_fmu, fmi_headers
    from vehicle.fmu.exports import strut_spec, vehicle_spec
    from vehicle.results.provenance import input_files

    fmi_headers()                       # FMPy (the FMI headers) before any work: a one-line error without it
    check_output_file(args.output, "-o/--output", make_parents=True, overwrite=args.overwrite,
                      inputs=[args.strut, args.vehicle, args.scenario, args.heat_from])
    overrides = parse_overrides(args.overrides)
    dt = None if args.dt is None else parse_quantity(args.dt, "s", where="--dt")
    if dt is not None and not 1e-5 <= dt <= 0.02:
        raise UserInputError(f"--dt: must be in [0.01, 20] ms, got {dt * 1e3:.4g} ms")
    if args.strut:
        spec = strut_spec(args.strut, overrides, heat_from=args.heat_from, dt_s=dt or 1e-3,
                          motion_centre_m=None if args.mean is None else parse_quantity(args.mean, "m", where="--mean"),
                          T_start_K=None if args.start_temperature is None else
                          parse_quantity(args.start_temperature, "K", where="--start-temperature"))
    else:
        for key in ("heat_from", "mean", "start_temperature"):
            if getattr(args, key) not in (None, "apc_8x8"):
                raise UserInputError(f"--{key.replace('_', '-')}: only with --strut")
        prepared = _vehicle_prepared(args, overrides)
        # nor any file the scenario reads (its vehicle, struts, road)
        check_not_input(args.output, "-o/--output", input_files(prepared).values())
        spec = vehicle_spec(prepared, dt_s=dt)
    info = build_fmu(spec, args.output)
    info.update(model=spec.model_name, internal_step_s=spec.dt_s, parameters=len(spec.parameters),
                inputs=len(spec.inputs), outputs=len(spec.output_variables))
    if args.json:
        print_json(info)
    else:
        print(format_table(["FMU", "model", "size [kB]", "internal step [ms]", "parameters", "inputs", "outputs"],
                           [(info["path"], info["model"], info["bytes"] / 1e3, spec.dt_s * 1e3, info["parameters"],
                             info["inputs"], info["outputs"])]))
