"""The command line of `hpsim strut` (vehicle.cli.strut runs its commands): the sub-commands, their options and
help texts."""
from __future__ import annotations

import re

from .options import add_overwrite

PROCESSES = ("polytropic", "isothermal")
MODELS = ("file", "physical", "identified")
CHAMBERS = ("file", "quasi_steady", "compressible")


def _accept_negative_values(parser):
    """Let "--amplitude -10mm" reach the range check (argparse would take "-10mm" for an option)."""
    if hasattr(parser, "_negative_number_matcher"):
        parser._negative_number_matcher = re.compile(r"^-\.?\d")


def add_parsers(sub, commands: dict) -> None:
    """`hpsim strut` and its sub-commands on `sub`; `commands`: sub-command name -> the function that runs it."""
    p = sub.add_parser("strut", help="strut rig: static, cycle, characteristic, fit")
    ssub = p.add_subparsers(dest="strut_command", required=True, parser_class=type(p))
    s, c, y = _register_rig_tests(ssub, commands)
    g, f, i = _register_models(ssub, commands)
    for sp in (c, y, g, f, i):
        add_overwrite(sp)
    for sp in (s, c, y, f, i):
        _accept_negative_values(sp)


def _common_options(sp):
    """The options every rig command shares: the strut, its fill, its temperature, JSON output, the model."""
    sp.add_argument("--strut", default="apc", help="built-in strut name or path to a strut .yaml (default apc)")
    sp.add_argument("--p0", help="fill pressure at full extension, e.g. 4.8MPa (default: the file's)")
    sp.add_argument("--temperature", help="strut and gas temperature, e.g. 20degC (default: charge temperature)")
    sp.add_argument("--json", action="store_true", help="print only JSON on stdout")
    sp.add_argument("--model", choices=MODELS, default="file",
                    help="integrated struts: the file's internals (default), physical (the internal parameters "
                         "emerge) or identified (seed 001's model: polytropic gas, eq. 2-3 friction, the maps)")


def _chambers_option(sp, default="file"):
    """--chambers of the commands that drive an integrated strut dynamically."""
    sp.add_argument("--chambers", choices=CHAMBERS, default=default,
                    help=f"integrated struts (default {default}): the file's chambers, quasi_steady (the pressure "
                         "difference relaxes at once) or compressible (seed 001 eq. 5-7 as written, needed for the "
                         "emulsion's pressure-difference hysteresis)")


def _register_rig_tests(ssub, commands: dict):
    """The rig's tests of one strut: static, characteristic, cycle (their parsers)."""
    s = ssub.add_parser("static", help="static deflection and stiffness at a load")
    _common_options(s)
    s.add_argument("--load", required=True, help="strut force, e.g. 41.8kN")
    s.add_argument("--process", choices=PROCESSES, default="polytropic",
                   help="quasi-static gas law: polytropic with the file's exponent (seed 000 eq. 5, default) "
                        "or isothermal (long standing)")
    s.add_argument("--n", help="polytropic exponent (default: the file's)")
    s.set_defaults(func=commands["static"])

    c = ssub.add_parser("characteristic", help="quasi-static force-deflection curve")
    _common_options(c)
    c.add_argument("--process", choices=PROCESSES, default="polytropic")
    c.add_argument("--n", help="polytropic exponent (default: the file's)")
    c.add_argument("--plot", help="write a PNG (with the stroke limits and the operating point)")
    c.add_argument("--csv", help="write a CSV (x_m,force_N,gas_pressure_Pa)")
    c.add_argument("--load", help="static strut force of the operating point, e.g. 41.8kN (default: the mean "
                                  "static strut force of a built-in vehicle that uses this strut)")
    c.set_defaults(func=commands["characteristic"])

    y = ssub.add_parser("cycle", help="displacement-driven sinusoidal test")
    _common_options(y)
    y.add_argument("--amplitude", required=True, help="one or more, e.g. 10mm,50mm")
    y.add_argument("--frequency", required=True, help="one or more, e.g. 0.1Hz,1Hz")
    y.add_argument("--mean", required=True, help="mean deflection, e.g. 115mm")
    y.add_argument("--cycles", type=int, default=3)
    y.add_argument("--plot", help="write force-displacement and force-velocity loops as PNG")
    y.add_argument("--csv", help="write the last-cycle loops as CSV")
    y.add_argument("--data", help="measured loops to overlay (CSV: amplitude_m, frequency_Hz, mean_m, t_s, force_N "
                                  "over one cycle of x = mean + A sin(2 pi f t)); their energies join the table")
    _chambers_option(y)
    y.set_defaults(func=commands["cycle"])
    return s, c, y


def _register_models(ssub, commands: dict):
    """The model commands: the gas laws, fitting and identifying parameters (their parsers)."""
    g = ssub.add_parser("gas", help="nitrogen models (ideal, BWR) against CoolProp's reference equation")
    g.add_argument("--temperatures", default="250K,300K,400K", help="isotherms, e.g. 250K,300K,400K")
    g.add_argument("--plot", help="write a PNG")
    g.add_argument("--json", action="store_true")
    g.set_defaults(func=commands["gas"])

    f = ssub.add_parser("fit", help="identify parameters from rig data")
    _common_options(f)
    f.add_argument("--data", required=True, help="CSV: energy table or loops (see struts/fit.py)")
    f.add_argument("--fit", required=True, help="comma-separated names, e.g. F0,pressure_coefficient")
    f.add_argument("--cycles", type=int, default=3)
    f.add_argument("--write", help="write the strut file with the fitted values to this path")
    f.set_defaults(func=commands["fit"])

    i = ssub.add_parser("identify", help="seed 001's internal parameters identified from the strut's rig loops")
    _common_options(i)
    _chambers_option(i, default="compressible")
    i.add_argument("--temperatures", default="30degC,40degC,50degC", help="body temperatures (default: seed 001's)")
    i.add_argument("--frequencies", default="0.5Hz,1Hz,2Hz,4Hz,8Hz", help="sinusoid frequencies (default: seed 001's)")
    i.add_argument("--peak-velocity", default="0.1m/s", help="peak deflection rate of every test (default: seed 001's)")
    i.add_argument("--mean", default="60mm", help="mean deflection (default 60 mm)")
    i.add_argument("--cycles", type=int, default=3)
    i.add_argument("--csv", help="write the identified parameters as CSV (one row per test)")
    i.add_argument("--plot", help="write the identified parameters against frequency per temperature as PNG")
    i.set_defaults(func=commands["identify"])
    return g, f, i
