"""`hpsim vehicle check` and `hpsim vehicle new` (docs/vehicles.md)."""
from __future__ import annotations

import argparse
import re

from hpsim.errors import UserInputError

CHECK_EPILOG = """examples:
  hpsim vehicle check apc_8x8                      # a shipped vehicle by name
  hpsim vehicle check my_truck.yaml --json         # everything as JSON
  hpsim vehicle check my_truck.yaml --no-modes     # statics only (no linearisation)"""

CHECK_DESCRIPTION = """Check a vehicle file: consistency, the standing vehicle, ride modes.

Exit code 0: the vehicle stands (warnings may be listed); 2: a schema error or a finding that stops a
drive (masses against wheel loads, a strut that cannot carry its station). The same check, without
the modes, runs quietly before every drive (docs/vehicles.md "Checking a vehicle")."""

NEW_EPILOG = """examples:
  hpsim vehicle new -o truck.yaml --positions 0m,3.5m,4.9m --axle-loads 7.5t,7.25t,7.25t --track 2.05m --ride-height 1.25m
  hpsim vehicle new -o car.yaml --positions 0m,2.9m --mass 3.2t --cg-x 1.3m --track 1.7m --ride-height 0.9m --strut apc --motion-ratio 0.5
  hpsim vehicle new -o mixed.yaml --positions 0m,1.5m,3.6m,5.1m --axle-loads 6t --track 2.4m --ride-height 1.4m --strut apc,apc,my_strut.yaml,my_strut.yaml"""

NEW_DESCRIPTION = """Write a complete, commented vehicle file from a few numbers.

Every strut is charged (charging.method load_and_height) to carry its wheel load at the static deflection
at the charging temperature: the vehicle stands at the given loads and heights. Everything not given
comes from labelled defaults (vehicle/data/templates/new_vehicle.yaml) and says so in the file; the file
is checked (hpsim vehicle check) as the file it will be, and written only when the check passes."""


def register(vsub):
    pc = vsub.add_parser("check", help="check a vehicle file: consistency, the standing vehicle, ride modes",
                         description=CHECK_DESCRIPTION, epilog=CHECK_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    pc.add_argument("vehicle", help="vehicle file (.yaml) or a built-in vehicle name")
    pc.add_argument("--json", action="store_true", help="print JSON only")
    pc.add_argument("--no-modes", action="store_true", help="skip the linearised modes (statics only)")
    pc.set_defaults(func=cmd_check)

    pn = vsub.add_parser("new", help="write a complete, commented vehicle file from a few numbers",
                         description=NEW_DESCRIPTION, epilog=NEW_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    pn.add_argument("-o", "--output", required=True, help="the vehicle file to write (.yaml)")
    pn.add_argument("--name", default=None, help="vehicle name (default: the file's name)")
    pn.add_argument("--positions", required=True, help="axle positions behind axle 1, e.g. 0m,3.5m,4.9m (2-10 axles)")
    pn.add_argument("--axle-loads", default=None,
                    help="static load per axle (both wheels), as mass (7.5t, 7500kg) or force (73.5kN); one for all")
    pn.add_argument("--mass", default=None, help="total mass instead of axle loads (with --cg-x)")
    pn.add_argument("--cg-x", default=None, help="CG of the total mass behind axle 1 (with --mass)")
    pn.add_argument("--track", required=True, help="track (wheel centre to wheel centre), e.g. 2.05m")
    pn.add_argument("--ride-height", required=True, help="hull height above the ground when charged: one or one per axle")
    pn.add_argument("--strut", default="apc", help="strut per axle: built-in name or strut file; one for all (default apc)")
    pn.add_argument("--strut-deflection", default=None, help="static strut deflection (default 0.48 of the stroke)")
    pn.add_argument("--motion-ratio", default=None, help="strut travel / wheel travel: one or one per axle (default 0.7)")
    pn.add_argument("--unsprung-mass", default=None, help="per wheel station: one or one per axle (default 0.136 of the mean wheel load)")
    pn.add_argument("--tyre-radius", default=None, help="unloaded tyre radius (default 0.55 m)")
    pn.add_argument("--cg-height", default=None, help="sprung CG above the ground (default 2 tyre radii)")
    pn.add_argument("--charging-temperature", default=None, help="strut temperature when charged (default 20 degC)")
    pn.add_argument("--description", default="", help="one line for the file's description")
    pn.add_argument("--overwrite", action="store_true", help="replace an existing file")
    pn.add_argument("--json", action="store_true", help="print the check of the written file as JSON only")
    pn.set_defaults(func=cmd_new)
    pn._negative_number_matcher = re.compile(r"^-\.?\d")


def cmd_check(args):
    from hpsim.tables import print_json

    from vehicle.physics.vehicle_check import check_file
    from vehicle.presentation.vehicle_check import format_check

    rep = check_file(args.vehicle, modes=not args.no_modes).as_dict()
    if args.json:
        print_json(rep)
    else:
        print(format_check(rep))
    return 0 if rep["ok"] else 2


def spec_from_args(args):
    from pathlib import Path

    from vehicle.physics.vehicle_builder import spec_from_values

    return spec_from_values(
        args.name or Path(args.output).stem, positions=args.positions, track=args.track,
        ride_height=args.ride_height, axle_loads=args.axle_loads, mass=args.mass, cg_x=args.cg_x,
        struts=args.strut, strut_deflection=args.strut_deflection, motion_ratio=args.motion_ratio,
        unsprung_mass=args.unsprung_mass, tyre_radius=args.tyre_radius, cg_height=args.cg_height,
        charging_temperature=args.charging_temperature, description=args.description)


def _as_option(exc: UserInputError) -> UserInputError:
    """The builder names its values as the Python API does (cg_x); on the command line they are options (--cg-x)."""
    text = str(exc)
    head = text.split(":", 1)[0].split(" (", 1)[0]
    names = {"struts": "--strut", "loads": "--axle-loads/--mass"}
    if re.fullmatch(r"[a-z_]+", head):
        return UserInputError(names.get(head, "--" + head.replace("_", "-")) + text[len(head):])
    return exc


def cmd_new(args):
    """Build the file in memory, check it as the file it will be, and write it only when the check passes."""
    from pathlib import Path

    from hpsim.tables import print_json

    from hpsim.outputs import check_output_file
    from vehicle.physics.vehicle_builder import built_vehicle, write_text
    from vehicle.physics.vehicle_check import check_vehicle
    from vehicle.presentation.vehicle_check import format_check

    out = Path(args.output)
    try:
        spec = spec_from_args(args)
        text, params = built_vehicle(spec, out)
    except UserInputError as exc:
        raise _as_option(exc) from None
    check_output_file(out, "-o/--output", make_parents=True, inputs=spec.struts, overwrite=args.overwrite)
    rep = check_vehicle(params, str(out)).as_dict()
    if rep["ok"]:
        write_text(out, text, overwrite=args.overwrite, inputs=spec.struts)
    if args.json:
        print_json(rep)
    else:
        print(format_check(rep))
        print(f"wrote {out}" if rep["ok"] else f"not written: {out} (the vehicle fails its check: see the errors)")
    return 0 if rep["ok"] else 2
