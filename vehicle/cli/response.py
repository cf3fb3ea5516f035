"""`hpsim vehicle response`: modes and road-to-hull / road-to-tyre-load responses of the linearised vehicle."""
from __future__ import annotations

import argparse

from hpsim.errors import UserInputError

from .options import add_overwrite

EPILOG = """The linearisation holds for small motions about the standing equilibrium; the valves are their
laminar bleed; seal friction is either differentiated at rest (a very stiff damper) or replaced by
its first-harmonic damping 4 F_C / (pi V) at the strut velocity amplitude V (--friction-velocity).

examples:
  hpsim vehicle response                                  # apc_8x8, friction equivalent linear at 100 mm/s
  hpsim vehicle response --friction-velocity 50mm/s --plot response.png
  hpsim vehicle response --friction-velocity 0 --json     # friction differentiated at rest (struts stick)
  hpsim vehicle response --temperatures 80degC --fmin 0.5Hz --fmax 20Hz"""


def strut_temperatures(P, text):
    """--temperatures: one, one per axle or one per strut (default: the charging temperature) [K]."""
    import numpy as np

    from hpsim.units import parse_quantity_list

    if text is None:
        return np.full(P.n_stations, P.charging.temperature)
    T = P.per_station(parse_quantity_list(text, "K", where="--temperatures"), f"--temperatures ({text!r})")
    if np.any(T <= 0) or np.any(T > 273.15 + 250):
        raise UserInputError(f"--temperatures: {text!r} must be in (-273.15, 250] degC")
    return T



def register(vsub):
    p = vsub.add_parser("response", help="modes and road frequency responses of the linearised vehicle",
                        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--vehicle", default="apc_8x8", help="built-in vehicle name or path to a vehicle file (default apc_8x8)")
    p.add_argument("--temperatures", default=None,
                   help="strut temperatures: one, one per axle or one per strut (default: the charging temperature)")
    p.add_argument("--friction-velocity", default="100 mm/s",
                   help="strut velocity amplitude for the equivalent-linear seal friction (default 100 mm/s, about "
                        "the RMS strut velocity on an ISO class D-E road at 20 km/h); 0: friction differentiated at rest")
    p.add_argument("--fmin", default="0.2 Hz", help="lowest frequency (default 0.2 Hz)")
    p.add_argument("--fmax", default="30 Hz", help="highest frequency (default 30 Hz)")
    p.add_argument("--points", type=int, default=300, help="frequencies, log-spaced (default 300, 10..5000)")
    p.add_argument("--json", action="store_true", help="print JSON only (modes and the full responses)")
    p.add_argument("--plot", default=None, metavar="PNG", help="write the response figure to this file")
    add_overwrite(p)
    p.set_defaults(func=cmd_response)


def cmd_response(args):
    import numpy as np

    from hpsim.outputs import check_figure_file
    from hpsim.tables import print_json
    from hpsim.units import parse_quantity

    from vehicle.physics import linear
    from vehicle.physics.params import load_vehicle
    from vehicle.presentation.response import format_response, response_plot, response_report

    if args.plot:
        check_figure_file(args.plot, "--plot", make_parents=True, inputs=[args.vehicle], overwrite=args.overwrite)
    P = load_vehicle(args.vehicle)
    T = strut_temperatures(P, args.temperatures)
    V = parse_quantity(args.friction_velocity, "m/s", where="--friction-velocity")
    if not 0.0 <= V <= 5.0:
        raise UserInputError(f"--friction-velocity: must be in [0, 5] m/s (0: friction at rest), got {V:.6g} m/s")
    fmin = parse_quantity(args.fmin, "Hz", where="--fmin")
    fmax = parse_quantity(args.fmax, "Hz", where="--fmax")
    if not 0.001 <= fmin < fmax <= 1000.0:
        raise UserInputError(f"--fmin/--fmax: need 0.001 Hz <= fmin < fmax <= 1000 Hz, got {fmin:.6g} and {fmax:.6g} Hz")
    if not 10 <= args.points <= 5000:
        raise UserInputError(f"--points: must be in [10, 5000], got {args.points}")
    lin = linear.linearise(P, T, friction_velocity_m_s=V or None)
    rep = response_report(lin, np.logspace(np.log10(fmin), np.log10(fmax), args.points))
    if args.plot:
        response_plot(rep, args.plot)
    if args.json:
        print_json(rep)
        return 0
    print(format_response(rep))
    if args.plot:
        print(f"wrote {args.plot}")
    return 0
