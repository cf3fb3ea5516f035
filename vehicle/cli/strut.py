"""`hpsim strut ...`: the strut rig on the command line.

    hpsim strut static --strut apc --load 41.8kN [--p0 4.8MPa] [--temperature 20degC] [--json]
    hpsim strut cycle --strut apc --amplitude 10mm,50mm --frequency 0.1Hz --mean 115mm [--cycles 3]
                      [--json] [--plot loops.png] [--csv loops.csv]
    hpsim strut characteristic --strut apc [--p0 ...] [--temperature ...] [--plot f.png] [--csv f.csv]
    hpsim strut fit --strut apc --data rig.csv --fit name1,name2 [--json]
"""
from __future__ import annotations

import csv
import itertools
import re
from pathlib import Path

from hpsim.tables import format_table, print_json
from hpsim.errors import UserInputError
from hpsim.outputs import check_figure_file, check_output_file
from hpsim.units import MAX_LIST_ITEMS, parse_quantity

PROCESSES = ("polytropic", "isothermal")

# allowed ranges, quoted in the error messages
_P0_RANGE_PA = (0.1e6, 30e6)
_T_RANGE_K = (200.0, 450.0)
_N_RANGE = (1.0, 1.7)


def _quantity(text, unit: str, where: str, allowed: str) -> float:
    """A command-line quantity in SI `unit`; errors name the argument and the allowed range."""
    try:
        return parse_quantity(text, unit, where=where)
    except UserInputError as exc:
        raise UserInputError(f"{exc}; allowed: {allowed}") from None


def _quantity_list(text, unit: str, where: str, allowed: str) -> list[float]:
    """Comma-separated quantities ("10mm,50mm"), each through `_quantity`."""
    items = [t for t in str(text).split(",") if t.strip()]
    if not items:
        raise UserInputError(f"{where}: expected one or more quantities in {unit}; allowed: {allowed}")
    if len(items) > MAX_LIST_ITEMS:
        raise UserInputError(f"{where}: {len(items)} values, at most {MAX_LIST_ITEMS}")
    return [_quantity(t, unit, where, allowed) for t in items]


def _accept_negative_values(parser):
    """Let "--amplitude -10mm" reach the range check (argparse would take "-10mm" for an option)."""
    if hasattr(parser, "_negative_number_matcher"):
        parser._negative_number_matcher = re.compile(r"^-\.?\d")


def register(sub):
    p = sub.add_parser("strut", help="strut rig: static, cycle, characteristic, fit")
    ssub = p.add_subparsers(dest="strut_command", required=True, parser_class=type(p))

    def common(sp):
        sp.add_argument("--strut", default="apc", help="built-in strut name or path to a strut .yaml (default apc)")
        sp.add_argument("--p0", help="fill pressure at full extension, e.g. 4.8MPa (default: the file's)")
        sp.add_argument("--temperature", help="strut and gas temperature, e.g. 20degC (default: charge temperature)")
        sp.add_argument("--json", action="store_true", help="print only JSON on stdout")

    s = ssub.add_parser("static", help="static deflection and stiffness at a load")
    common(s)
    s.add_argument("--load", required=True, help="strut force, e.g. 41.8kN")
    s.add_argument("--process", choices=PROCESSES, default="polytropic",
                   help="quasi-static gas law: polytropic with the file's exponent (seed 000 eq. 5, default) "
                        "or isothermal (long standing)")
    s.add_argument("--n", help="polytropic exponent (default: the file's)")
    s.set_defaults(func=cmd_static)

    c = ssub.add_parser("characteristic", help="quasi-static force-deflection curve")
    common(c)
    c.add_argument("--process", choices=PROCESSES, default="polytropic")
    c.add_argument("--n", help="polytropic exponent (default: the file's)")
    c.add_argument("--plot", help="write a PNG")
    c.add_argument("--csv", help="write a CSV (x_m,force_N,gas_pressure_Pa)")
    c.set_defaults(func=cmd_characteristic)

    y = ssub.add_parser("cycle", help="displacement-driven sinusoidal test")
    common(y)
    y.add_argument("--amplitude", required=True, help="one or more, e.g. 10mm,50mm")
    y.add_argument("--frequency", required=True, help="one or more, e.g. 0.1Hz,1Hz")
    y.add_argument("--mean", required=True, help="mean deflection, e.g. 115mm")
    y.add_argument("--cycles", type=int, default=3)
    y.add_argument("--plot", help="write force-displacement and force-velocity loops as PNG")
    y.add_argument("--csv", help="write the last-cycle loops as CSV")
    y.set_defaults(func=cmd_cycle)

    g = ssub.add_parser("gas", help="nitrogen models (ideal, BWR) against CoolProp's reference equation")
    g.add_argument("--temperatures", default="250K,300K,400K", help="isotherms, e.g. 250K,300K,400K")
    g.add_argument("--plot", help="write a PNG")
    g.add_argument("--json", action="store_true")
    g.set_defaults(func=cmd_gas)

    f = ssub.add_parser("fit", help="identify parameters from rig data")
    common(f)
    f.add_argument("--data", required=True, help="CSV: energy table or loops (see struts/fit.py)")
    f.add_argument("--fit", required=True, help="comma-separated names, e.g. F0,pressure_coefficient")
    f.add_argument("--cycles", type=int, default=3)
    f.add_argument("--write", help="write the strut file with the fitted values to this path")
    f.set_defaults(func=cmd_fit)
    for sp in (s, c, y, f):
        _accept_negative_values(sp)


def _params(args, process=None, n=None):
    from struts.params import load_strut

    overrides = {}
    if process == "polytropic":
        overrides["gas.process"] = "polytropic"
    if n is not None:
        n_allowed = f"[{_N_RANGE[0]}, {_N_RANGE[1]}]"
        n_val = _quantity(n, "dimensionless", "--n", n_allowed)
        if not _N_RANGE[0] <= n_val <= _N_RANGE[1]:
            raise UserInputError(f"--n: polytropic exponent must be in {n_allowed}, got {n_val}")
        overrides["gas.polytropic_exponent"] = n_val
    params = load_strut(args.strut, overrides)
    p0 = None
    if args.p0 is not None:
        p0_allowed = f"[{_P0_RANGE_PA[0] / 1e6:g}, {_P0_RANGE_PA[1] / 1e6:g}] MPa"
        p0 = _quantity(args.p0, "Pa", "--p0", p0_allowed)
        if not _P0_RANGE_PA[0] <= p0 <= _P0_RANGE_PA[1]:
            raise UserInputError(f"--p0: fill pressure must be in {p0_allowed}, got {p0 / 1e6:.4g} MPa")
    T = None
    if args.temperature is not None:
        T_allowed = f"[{_T_RANGE_K[0] - 273.15:.4g}, {_T_RANGE_K[1] - 273.15:.4g}] degC"
        T = _quantity(args.temperature, "K", "--temperature", T_allowed)
        if not _T_RANGE_K[0] <= T <= _T_RANGE_K[1]:
            raise UserInputError(f"--temperature: must be in {T_allowed}, got {T - 273.15:.4g} degC")
    return params, p0, T


def cmd_static(args):
    from struts.rig import static_point

    params, p0, T = _params(args, None, args.n)
    load = _quantity(args.load, "N", "--load", "> 0 N, within the strut's force range")
    if load <= 0:
        raise UserInputError(f"--load: must be > 0 N, got {load} N")
    process = "polytropic" if args.process == "polytropic" else "isothermal"
    res = static_point(params, load, p0_Pa=p0, T_K=T, process=process)
    out = {k: res[k] for k in ("static_deflection_m", "stiffness_N_per_m", "gas_pressure_Pa", "gas_temperature_K")}
    if args.json:
        print_json(out)
    else:
        print(format_table(["quantity", "value"], [
            ("strut", params.name), ("load [kN]", load / 1e3), ("process", process),
            ("static deflection [mm]", out["static_deflection_m"] * 1e3),
            ("stiffness [kN/m]", out["stiffness_N_per_m"] / 1e3),
            ("gas pressure [MPa]", out["gas_pressure_Pa"] / 1e6),
            ("gas temperature [degC]", out["gas_temperature_K"] - 273.15)]))


def _check_outputs(args, figure: str | None = "plot", table: str | None = "csv"):
    """The figure and CSV paths of a strut command, checked before any work."""
    if figure and getattr(args, figure, None):
        check_figure_file(getattr(args, figure), f"--{figure}")
    if table and getattr(args, table, None):
        check_output_file(getattr(args, table), f"--{table}")


def cmd_characteristic(args):
    from struts.rig import characteristic

    _check_outputs(args)
    params, p0, T = _params(args, None, args.n)
    res = characteristic(params, p0_Pa=p0, T_K=T, process=args.process)
    if args.csv:
        _write_csv(args.csv, ["x_m", "force_N", "gas_pressure_Pa"],
                   zip(res["x_m"], res["force_N"], res["gas_pressure_Pa"]))
    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6, 4))
        ax.plot(res["x_m"] * 1e3, res["force_N"] / 1e3)
        ax.set_xlabel("deflection [mm]"); ax.set_ylabel("gas force [kN]"); ax.grid(True)
        ax.set_title(f"{params.name}: p0 = {res['p0_Pa'] / 1e6:.3g} MPa, T = {res['temperature_K'] - 273.15:.3g} degC, {args.process}")
        fig.tight_layout(); _save_figure(fig, args.plot, "--plot"); plt.close(fig)
    rows = [{"x_m": float(x), "force_N": float(F)} for x, F in zip(res["x_m"][::20], res["force_N"][::20])]
    if args.json:
        print_json({"x_m": res["x_m"], "force_N": res["force_N"], "gas_pressure_Pa": res["gas_pressure_Pa"]})
    else:
        print(format_table(["x [mm]", "F [kN]"], [(r["x_m"] * 1e3, r["force_N"] / 1e3) for r in rows]))


def cmd_cycle(args):
    from struts.rig import check_cycle_arguments, check_cycle_work, cycle_test

    _check_outputs(args)
    params, p0, T = _params(args)
    stroke_mm = params.geometry.stroke * 1e3
    amps = _quantity_list(args.amplitude, "m", "--amplitude",
                          f"> 0 m with mean ± amplitude inside the stroke [0, {stroke_mm:.4g}] mm")
    freqs = _quantity_list(args.frequency, "Hz", "--frequency", f"(0, {_max_frequency():g}] Hz")
    mean = _quantity(args.mean, "m", "--mean", f"inside the stroke [0, {stroke_mm:.4g}] mm")
    check_cycle_work(len(amps) * len(freqs), args.cycles)
    for A, f in itertools.product(amps, freqs):  # validate all before any work
        check_cycle_arguments(params, A, f, mean, args.cycles)
    results = [cycle_test(params, A, f, mean, cycles=args.cycles, T_K=T, p0_Pa=p0)
               for A, f in itertools.product(amps, freqs)]
    if args.csv:
        header = ["amplitude_m", "frequency_Hz", "mean_m", "t_s", "x_m", "v_m_per_s", "force_N",
                  "gas_force_N", "valve_force_N", "friction_force_N", "end_stop_force_N", "gas_temperature_K"]
        rows = []
        for r in results:
            for i in range(len(r.t_s)):
                rows.append([r.amplitude_m, r.frequency_Hz, r.mean_m, r.t_s[i] - r.t_s[0], r.x_m[i], r.v_m_per_s[i],
                             r.force_N[i], r.components_N["gas"][i], r.components_N["valve"][i],
                             r.components_N["friction"][i], r.components_N["end_stop"][i], r.gas_temperature_K[i]])
        _write_csv(args.csv, header, rows)
    if args.plot:
        plot_loops(results, args.plot, params.name)
    if args.json:
        print_json([r.summary() for r in results])
    else:
        print(format_table(
            ["A [mm]", "f [Hz]", "E/cycle [J]", "valve [J]", "friction [J]", "gas [J]", "Fmax comp [kN]", "Fmin reb [kN]"],
            [(r.amplitude_m * 1e3, r.frequency_Hz, r.energy_per_cycle_J, r.energy_by_mechanism_J["valve"],
              r.energy_by_mechanism_J["friction"], r.energy_by_mechanism_J["gas"],
              r.peak_force_compression_N / 1e3, r.peak_force_rebound_N / 1e3) for r in results]))


def _max_frequency() -> float:
    from struts.rig import _MAX_FREQUENCY_HZ

    return _MAX_FREQUENCY_HZ


def plot_loops(results, path, name):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.2))
    for r in results:
        lab = f"A={r.amplitude_m * 1e3:.3g} mm, f={r.frequency_Hz:.3g} Hz, E={r.energy_per_cycle_J:.4g} J"
        a1.plot(r.x_m * 1e3, r.force_N / 1e3, label=lab)
        a2.plot(r.v_m_per_s * 1e3, (r.force_N - r.components_N["gas"]) / 1e3, label=lab)
    a1.set_xlabel("deflection [mm]"); a1.set_ylabel("force [kN]"); a1.grid(True); a1.legend(fontsize=7)
    a2.set_xlabel("velocity [mm/s]"); a2.set_ylabel("resisting force (F - gas) [kN]"); a2.grid(True)
    fig.suptitle(f"{name}: force-displacement and force-velocity loops (last cycle)")
    fig.tight_layout(); _save_figure(fig, path, "--plot"); plt.close(fig)


def cmd_fit(args):
    from struts.fit import fit, read_rig_csv
    from struts.rig import check_cycle_work

    if args.write:
        check_output_file(args.write, "--write", suffixes=(".yaml", ".yml"))
    params, _, _ = _params(args)
    data = read_rig_csv(args.data)
    check_cycle_work(len(data.rows), args.cycles)
    names = [n.strip() for n in args.fit.split(",") if n.strip()]
    res = fit(params, data, names, cycles=args.cycles)
    if args.write:
        from struts.fit import with_values
        import yaml
        fitted = with_values(params, names, [res.values[n] for n in names])
        try:
            Path(args.write).write_text(yaml.safe_dump(fitted.model_dump(), sort_keys=False))
        except OSError as exc:
            raise UserInputError(f"--write: cannot write {args.write} ({exc.strerror})") from None
    if args.json:
        print_json(res.as_dict())
    else:
        print(format_table(["parameter", "initial", "fitted", "95% CI low", "95% CI high"],
                           [(n, res.initial[n], res.values[n], *res.confidence_95[n]) for n in names]))
        print()
        print(format_table(["test", "measured", "model", "rel. error [%]"],
                           [(i + 1, m, s, 100 * (s - m) / m) for i, (m, s) in enumerate(zip(res.measured, res.model))]))


def cmd_gas(args):
    import numpy as np

    from struts import gas as gaslaw

    try:
        from CoolProp.CoolProp import PropsSI
    except ImportError:
        raise UserInputError("strut gas: needs CoolProp (pip install -e '.[test]')") from None
    _check_outputs(args, table=None)
    temps = _quantity_list(args.temperatures, "K", "--temperatures", "200 K to 600 K")
    if any(not 200 <= T <= 600 for T in temps):
        raise UserInputError("--temperatures: each must be in [200, 600] K")
    N2 = gaslaw.load_gas("nitrogen")
    p_grid = np.geomspace(1e6, 50e6, 40)
    curves = []
    for T in temps:
        rho = np.array([PropsSI("Dmass", "T", T, "P", p, "Nitrogen") for p in p_grid])
        v = 1.0 / rho
        curves.append({"T_K": T, "p_Pa": p_grid, "v": v,
                       "bwr_error_pct": 100 * (gaslaw.pressure(T, v, N2, "bwr") / p_grid - 1),
                       "ideal_error_pct": 100 * (gaslaw.pressure(T, v, N2, "ideal") / p_grid - 1)})
    summary = {"max_abs_bwr_error_pct": float(max(np.max(np.abs(c["bwr_error_pct"])) for c in curves)),
               "max_abs_ideal_error_pct": float(max(np.max(np.abs(c["ideal_error_pct"])) for c in curves)),
               "pressure_range_MPa": [1.0, 50.0], "temperatures_K": temps}
    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 4.2))
        for c in curves:
            l, = ax.plot(c["p_Pa"] / 1e6, c["bwr_error_pct"], label=f"BWR, {c['T_K']:.0f} K")
            ax.plot(c["p_Pa"] / 1e6, c["ideal_error_pct"], "--", color=l.get_color(), label=f"ideal, {c['T_K']:.0f} K")
        ax.axhspan(-3, 3, color="0.9", zorder=0, label="±3 % (test bound for BWR)")
        ax.set_xscale("log"); ax.set_xlabel("pressure [MPa] (CoolProp state)"); ax.grid(True, which="both", alpha=0.4)
        ax.set_ylabel("model pressure error vs CoolProp [%]"); ax.legend(fontsize=7, ncol=2)
        ax.set_title("Nitrogen: p(T, v) of the gas models against CoolProp's reference equation")
        fig.tight_layout(); _save_figure(fig, args.plot, "--plot"); plt.close(fig)
    if args.json:
        print_json(summary)
    else:
        print(format_table(["quantity", "value"], [(k, str(v)) for k, v in summary.items()]))


def _write_csv(path, header, rows):
    try:
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(header)
            for r in rows:
                w.writerow([f"{float(v):.10g}" for v in r])
    except OSError as exc:
        raise UserInputError(f"--csv: cannot write {path} ({exc.strerror})") from None


def _save_figure(fig, path, where: str):
    try:
        fig.savefig(path, dpi=120)
    except OSError as exc:
        raise UserInputError(f"{where}: cannot write {path} ({exc.strerror})") from None
