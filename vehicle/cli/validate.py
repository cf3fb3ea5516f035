"""`hpsim validate PREDICTION [MEASURED.yaml] [--json] [--plot FILE]`: predictions against measurements
(vehicle.studies.validate; docs/measurements.md).

Exit codes: 0 done, 2 user error (one line naming the file, the key and the allowed range).
"""
from __future__ import annotations

import argparse

from .options import add_overwrite

EPILOG = """\
examples:
  hpsim validate results/mileage_106km.h5 test.yaml                  # one drive: its nominal prediction
  hpsim validate mileage_uq test.yaml --plot validate.png --json     # an hpsim uq study folder: 5-95 % bands
  hpsim validate mileage_uq --plot readings.png                      # no measurements: what the instruments would read
    (test.yaml: the measurement file; its format: docs/measurements.md)"""


def register(sub):
    p = sub.add_parser("validate", help="compare a prediction (results file or hpsim uq study) with measurements",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("prediction", help="a results file (.h5) or the folder of an `hpsim uq` study")
    p.add_argument("measured", nargs="?", default=None,
                   help="the measurement file (YAML: points per axle or wheel, series from CSV/MDF4); without it, "
                        "the predicted readings of the usual instruments (pyrometer, photogrammetry, scale)")
    p.add_argument("--json", action="store_true", help="print the comparison as JSON only")
    p.add_argument("--plot", default=None, metavar="FILE", help="write the report figure (PNG, PDF, SVG)")
    p.add_argument("--seed", type=int, default=0, help="seed of the measurement-model draws (default 0)")
    add_overwrite(p)
    p.set_defaults(func=cmd_validate)


def cmd_validate(args):
    from hpsim.outputs import check_figure_file
    from hpsim.tables import print_json

    from vehicle.studies.uq import check_seed
    from vehicle.studies.validate import format_readings, format_validation, instrument_readings, validate

    check_seed(args.seed)
    if args.plot:                       # before the computing, whose result would otherwise be lost
        check_figure_file(args.plot, "--plot", make_parents=True, inputs=[args.prediction, args.measured],
                          overwrite=args.overwrite)
    if args.measured is None:
        v = instrument_readings(args.prediction, seed=args.seed)
    else:
        v = validate(args.prediction, args.measured, seed=args.seed)
    if args.plot:
        from vehicle.presentation.validate_plots import validation_plot

        v["plot"] = str(validation_plot(v, args.plot))
    if args.json:
        print_json(v)
    else:
        print(format_validation(v) if args.measured is not None else format_readings(v))
        if args.plot:
            print(f"plot: {v['plot']}")
    return 0
