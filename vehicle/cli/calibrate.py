"""`hpsim calibrate`: the one heat-transfer parameter against a measured mean rise (vehicle.studies.calibration)."""
from __future__ import annotations

import logging

from hpsim.errors import UserInputError
from hpsim.tables import format_table, print_json
from hpsim.units import parse_quantity

from .stages import command_wall_s


def register(sub):
    p = sub.add_parser("calibrate", help="calibrate the heat-transfer parameter to a measured mean temperature rise")
    p.add_argument("scenario", help="scenario YAML (e.g. scenarios/mileage_106km.yaml)")
    p.add_argument("--target-rise", required=True, help="mean rise of the strut outer surface temperature (pyrometer; the heat network's surface node), e.g. 54K")
    p.add_argument("--parameter", default="heat.air_speed_ratio")
    p.add_argument("--tolerance", default="0.1K", help="accepted error of the mean rise (default 0.1K); refused "
                   "(exit 2) below the rise's noise floor, which is measured near the answer")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_calibrate)


def cmd_calibrate(args):
    from vehicle.studies.calibration import calibrate_heat      # here: the parser needs none of it (`hpsim --help`)

    target = parse_quantity(args.target_rise, "delta_degC", where="--target-rise")
    if not 0 < target < 300:
        raise UserInputError(f"--target-rise: must be in (0, 300) K, got {target}")
    tol = parse_quantity(args.tolerance, "delta_degC", where="--tolerance")
    log = logging.getLogger("hpsim").info            # stderr; -q hides the runs, -v adds the stages
    res = calibrate_heat(args.scenario, target, args.parameter, tol_K=tol, log=log)
    if args.json:
        print_json(res)
    else:
        print(format_table(["parameter", "calibrated value", "mean rise [K]", "target [K]", "noise floor [K]", "runs",
                            "wall [s]"],
                           [(res["parameter"], res["value"], res["achieved_rise_K"], target, res["noise_floor_K"],
                             len(res["runs"]), command_wall_s())]))         # the command's wall time, imports included
