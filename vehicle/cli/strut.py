"""`hpsim strut ...`: the strut rig on the command line.

    hpsim strut static --strut apc --load 41.8kN [--p0 4.8MPa] [--temperature 20degC] [--json]
    hpsim strut cycle --strut apc --amplitude 10mm,50mm --frequency 0.1Hz --mean 115mm [--cycles 3]
                      [--json] [--plot loops.png] [--csv loops.csv]
    hpsim strut characteristic --strut apc [--p0 ...] [--temperature ...] [--plot f.png] [--csv f.csv]
    hpsim strut fit --strut apc --data rig.csv --fit name1,name2 [--json]
    hpsim strut identify --strut yin2023 [--temperatures 30degC,40degC,50degC] [--frequencies 0.5Hz,...,8Hz]
                         [--peak-velocity 0.1m/s] [--mean 60mm] [--chambers compressible] [--json] [--csv t.csv]
                         [--plot internal.png]
"""
from __future__ import annotations

import csv
import itertools
import logging
import sys

from hpsim.tables import format_table, print_json
from hpsim.errors import UserInputError
from hpsim.outputs import atomic_output, check_figure_file, check_output_file
from hpsim.units import MAX_LIST_ITEMS, parse_quantity
from hpsim.extras import install_hint

from .strut_args import add_parsers


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


def register(sub):
    add_parsers(sub, {"static": cmd_static, "characteristic": cmd_characteristic, "cycle": cmd_cycle, "gas": cmd_gas,
                      "fit": cmd_fit, "identify": cmd_identify})

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
    model = getattr(args, "model", "file")
    chambers = getattr(args, "chambers", "file")
    if model != "file" or chambers != "file":
        layout = load_strut(args.strut).layout
        if layout != "integrated":
            flag = "--model" if model != "file" else "--chambers"
            raise UserInputError(f"{flag}: only for integrated struts; strut {args.strut} has layout {layout} "
                                 f"(allowed: file)")
    if model == "identified":
        from struts.identify import PAPER_MODEL
        overrides.update(PAPER_MODEL)
    elif model == "physical":
        overrides.update({"internals": "physical"})
    if chambers != "file":
        overrides["valve.oil_model"] = chambers
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


def _inputs(args) -> list:
    """The files a strut command reads (a built-in strut name is no file and is ignored by the output checks)."""
    return [getattr(args, "strut", None), getattr(args, "data", None)]


def _check_outputs(args, figure: str | None = "plot", table: str | None = "csv"):
    """The figure and CSV paths of a strut command, checked before any work: never one of its inputs, an
    existing file only with --overwrite."""
    if figure and getattr(args, figure, None):
        check_figure_file(getattr(args, figure), f"--{figure}", inputs=_inputs(args), overwrite=args.overwrite)
    if table and getattr(args, table, None):
        check_output_file(getattr(args, table), f"--{table}", inputs=_inputs(args), overwrite=args.overwrite)


def cmd_characteristic(args):
    from struts.rig import characteristic

    _check_outputs(args)
    params, p0, T = _params(args, None, args.n)
    res = characteristic(params, p0_Pa=p0, T_K=T, process=args.process)
    op = _operating_point(args, params, p0, T)
    if args.csv:
        _write_csv(args.csv, ["x_m", "force_N", "gas_pressure_Pa"],
                   zip(res["x_m"], res["force_N"], res["gas_pressure_Pa"]))
    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6.4, 4.2), layout="constrained")
        ax.plot(res["x_m"] * 1e3, res["force_N"] / 1e3, label="gas force")
        stroke_mm = params.geometry.stroke * 1e3
        # labels where the rising curve is not: top left, bottom right
        for x_mm, y, text in ((0.0, 0.97, "full extension\n(rebound stop)"),
                              (stroke_mm, 0.03, "full compression\n(bump stop)")):
            ax.axvline(x_mm, color="k", lw=1.0)
            ax.annotate(text, (x_mm, y), xycoords=("data", "axes fraction"), ha="left" if x_mm == 0 else "right",
                        va="top" if y > 0.5 else "bottom", fontsize=7, xytext=(3 if x_mm == 0 else -3, 0),
                        textcoords="offset points")
        if op is not None:
            ax.plot(op["x_m"] * 1e3, op["load_N"] / 1e3, "o", color="C3", label=f"operating point ({op['label']})")
            ax.annotate(f"{op['x_m'] * 1e3:.0f} mm, {op['load_N'] / 1e3:.1f} kN\nk = {op['stiffness_N_per_m'] / 1e3:.0f} kN/m",
                        (op["x_m"] * 1e3, op["load_N"] / 1e3), xytext=(-8, 8), textcoords="offset points", fontsize=7,
                        ha="right", va="bottom")        # above left: the curve rises to the right
        ax.set_xlim(-0.03 * stroke_mm, 1.03 * stroke_mm)
        ax.set_xlabel("deflection [mm]"); ax.set_ylabel("gas force [kN]"); ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="center left")
        ax.set_title(f"{params.name}: p0 = {res['p0_Pa'] / 1e6:.3g} MPa, T = {res['temperature_K'] - 273.15:.3g} degC, "
                     f"{args.process}", fontsize=10)
        _save_figure(fig, args.plot, "--plot"); plt.close(fig)
    rows = [{"x_m": float(x), "force_N": float(F)} for x, F in zip(res["x_m"][::20], res["force_N"][::20])]
    if args.json:
        print_json({"x_m": res["x_m"], "force_N": res["force_N"], "gas_pressure_Pa": res["gas_pressure_Pa"],
                    "stroke_m": params.geometry.stroke, "operating_point": op})
    else:
        print(format_table(["x [mm]", "F [kN]"], [(r["x_m"] * 1e3, r["force_N"] / 1e3) for r in rows]))
        if op is not None:
            print(f"operating point ({op['label']}): {op['x_m'] * 1e3:.1f} mm at {op['load_N'] / 1e3:.2f} kN, "
                  f"stiffness {op['stiffness_N_per_m'] / 1e3:.0f} kN/m; stroke 0-{params.geometry.stroke * 1e3:.0f} mm")


def _operating_point(args, params, p0, T) -> dict | None:
    """Static deflection and stiffness at --load, or at the mean static strut force of a built-in
    vehicle that uses this strut (charging loads less the unsprung weight, through the motion ratio)."""
    from struts.rig import static_point

    if args.load is not None:
        load = _quantity(args.load, "N", "--load", "> 0 N")
        if load <= 0:
            raise UserInputError(f"--load: must be > 0 N, got {load} N")
        label = "at --load"
    else:
        load = label = None
        from vehicle.physics.params import GRAVITY, builtin_vehicles, load_vehicle

        for name in builtin_vehicles():
            P = load_vehicle(name)
            forces = [(w - ax.unsprung_mass * GRAVITY) / ax.motion_ratio
                      for w, ax in zip(P.charging.wheel_loads, P.axles) if ax.strut == params.name]
            if forces:
                load, label = sum(forces) / len(forces), f"static on {name}"
                break
        if load is None:
            return None
    try:
        res = static_point(params, load, p0_Pa=p0, T_K=T, process=args.process)
    except UserInputError:
        if args.load is not None:
            raise
        # a vehicle that charges its struts to its own loads (charging.method load_and_height, e.g. the light 4x4
        # on yin2023) may carry more than the file's fill can: no operating point at this fill
        return None
    return {"load_N": load, "x_m": res["static_deflection_m"], "stiffness_N_per_m": res["stiffness_N_per_m"],
            "label": label}


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
    measured = _measured_loops(args.data) if args.data else []
    results = [cycle_test(params, A, f, mean, cycles=args.cycles, T_K=T, p0_Pa=p0)
               for A, f in itertools.product(amps, freqs)]
    energy_measured = [next((m["energy_per_cycle_J"] for m in measured if _same_test(m, r)), None) for r in results]
    for w in dict.fromkeys(w for r in results for w in r.warnings):
        print(f"warning: {w}", file=sys.stderr)
    if args.csv:
        header = ["amplitude_m", "frequency_Hz", "mean_m", "t_s", "x_m", "v_m_per_s", "force_N",
                  "gas_force_N", "valve_force_N", "friction_force_N", "end_stop_force_N", "gas_temperature_K",
                  "gas_pressure_Pa", "rod_chamber_pressure_Pa"]
        rows = []
        for r in results:
            for i in range(len(r.t_s)):
                rows.append([r.amplitude_m, r.frequency_Hz, r.mean_m, r.t_s[i] - r.t_s[0], r.x_m[i], r.v_m_per_s[i],
                             r.force_N[i], r.components_N["gas"][i], r.components_N["valve"][i],
                             r.components_N["friction"][i], r.components_N["end_stop"][i], r.gas_temperature_K[i],
                             r.gas_pressure_Pa[i], r.rod_chamber_pressure_Pa[i]])
        _write_csv(args.csv, header, rows)
    if args.plot:
        plot_loops(results, args.plot, params.name, measured)
    if args.json:
        out = [r.summary() for r in results]
        if args.data:
            for o, e in zip(out, energy_measured):
                o["measured_energy_per_cycle_J"] = e
        print_json(out)
    else:
        headers = ["A [mm]", "f [Hz]", "E/cycle [J]", "valve [J]", "friction [J]", "gas [J]", "Fmax comp [kN]",
                   "Fmin reb [kN]", "k_eq [kN/m]", "c_eq [kN s/m]"] + (["E measured [J]"] if args.data else [])
        print(format_table(headers,
            [(r.amplitude_m * 1e3, r.frequency_Hz, r.energy_per_cycle_J, r.energy_by_mechanism_J["valve"],
              r.energy_by_mechanism_J["friction"], r.energy_by_mechanism_J["gas"],
              r.peak_force_compression_N / 1e3, r.peak_force_rebound_N / 1e3,
              r.equivalent_stiffness_N_per_m / 1e3, r.equivalent_damping_N_s_per_m / 1e3)
             + ((("-" if e is None else e),) if args.data else ()) for r, e in zip(results, energy_measured)]))
        unmatched = [m for m in measured if not any(_same_test(m, r) for r in results)]
        if unmatched:
            print("measured tests without a simulated one (overlaid only): " + ", ".join(
                f"A={m['amplitude_m'] * 1e3:.4g} mm f={m['frequency_Hz']:.4g} Hz mean={m['mean_m'] * 1e3:.4g} mm"
                for m in unmatched))


def _same_test(m: dict, r) -> bool:
    import math

    return all(math.isclose(a, b, rel_tol=1e-6, abs_tol=1e-12) for a, b in
               ((m["amplitude_m"], r.amplitude_m), (m["frequency_Hz"], r.frequency_Hz), (m["mean_m"], r.mean_m)))


def _measured_loops(path) -> list[dict]:
    """Measured loops of a rig CSV: per test, x, v and F over one cycle (sorted by phase) and the
    energy per cycle, the loop's area (closed trapezoid sum of F dx)."""
    import numpy as np

    from struts.fit import read_rig_csv

    data = read_rig_csv(path)
    if data.kind != "loops":
        raise UserInputError(f"--data: {path} is an energy table; the overlay needs measured loops "
                             "(columns amplitude_m, frequency_Hz, mean_m, t_s, force_N)")
    out = []
    for A, f, mean in data.tests():
        rows = [r for r in data.rows if (r["amplitude_m"], r["frequency_Hz"], r["mean_m"]) == (A, f, mean)]
        phase = np.array([r["t_s"] for r in rows]) * f % 1.0
        order = np.argsort(phase)
        phase, F = phase[order], np.array([r["force_N"] for r in rows])[order]
        x = mean + A * np.sin(2 * np.pi * phase)
        xc, Fc = np.append(x, x[0]), np.append(F, F[0])            # close the loop
        out.append({"amplitude_m": A, "frequency_Hz": f, "mean_m": mean, "phase": phase, "x_m": x, "force_N": F,
                    "v_m_per_s": 2 * np.pi * f * A * np.cos(2 * np.pi * phase),
                    "energy_per_cycle_J": float(np.sum(0.5 * (Fc[1:] + Fc[:-1]) * np.diff(xc)))})
    return out


def _max_frequency() -> float:
    from struts.rig import _MAX_FREQUENCY_HZ

    return _MAX_FREQUENCY_HZ


def plot_loops(results, path, name, measured=()):
    """Force-displacement and force-velocity loops; measured loops as wide light lines under the model's thin
    ones (the same colour for the same test, a colour of its own without a simulated one); the smallest loop on
    top and, when it is much smaller than the largest, magnified in an inset of the force-velocity panel.
    Returns the (label, colour) of each line of the force-displacement panel."""
    import matplotlib
    import numpy as np
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.4), layout="constrained")
    v_max = [float(np.max(np.abs(r.v_m_per_s))) * 1e3 for r in results]
    small = int(np.argmin(v_max)) if results else 0
    inset = None
    if len(results) > 1 and v_max[small] < 0.25 * max(v_max):
        inset = a2.inset_axes([0.6, 0.06, 0.37, 0.37])
    measured_style = dict(lw=4.0, alpha=0.35, solid_capstyle="round", zorder=1)
    for j, r in enumerate(results):
        c, z = f"C{j % 10}", 3 + len(results) - j           # later (larger) loops below the earlier ones
        lab = f"A={r.amplitude_m * 1e3:.3g} mm, f={r.frequency_Hz:.3g} Hz, E={r.energy_per_cycle_J:.4g} J"
        resist = (r.force_N - r.components_N["gas"]) / 1e3
        a1.plot(r.x_m * 1e3, r.force_N / 1e3, label=lab, color=c, lw=1.2, zorder=z)
        for a in (a2, inset) if (inset is not None and j == small) else (a2,):
            a.plot(r.v_m_per_s * 1e3, resist, label=lab, color=c, lw=1.2, zorder=z)
        # the measured loop of the same test; its resisting force is the measured force less the model's gas
        # force at the same phase of the cycle
        for m in measured:
            if _same_test(m, r):
                gas = np.interp(m["phase"], ((r.t_s - r.t_s[0]) * r.frequency_Hz) % 1.0, r.components_N["gas"],
                                period=1.0)
                a1.plot(m["x_m"] * 1e3, m["force_N"] / 1e3, color=c, label=f"measured, E={m['energy_per_cycle_J']:.4g} J",
                        **measured_style)
                a2.plot(m["v_m_per_s"] * 1e3, (m["force_N"] - gas) / 1e3, color=c, **measured_style)
    # measured loops without a simulated test: each its own colour after the simulated tests' (in one black
    # they were one grey in the legend)
    unmatched = [m for m in measured if not any(_same_test(m, r) for r in results)]
    for i, m in enumerate(unmatched):
        a1.plot(m["x_m"] * 1e3, m["force_N"] / 1e3, color=f"C{(len(results) + i) % 10}",
                label=f"measured A={m['amplitude_m'] * 1e3:.3g} mm, f={m['frequency_Hz']:.3g} Hz "
                      "(no simulated test)", **{**measured_style, "lw": 2.5})
    if inset is not None:
        inset.set_title(f"A={results[small].amplitude_m * 1e3:.3g} mm magnified", fontsize=7)
        inset.tick_params(labelsize=6)
        inset.grid(True, alpha=0.4)
    a1.set_xlabel("deflection [mm]"); a1.set_ylabel("force [kN]"); a1.grid(True)
    a1.legend(fontsize=7, loc="upper left")
    a2.set_xlabel("velocity [mm/s] (> 0: compression)"); a2.set_ylabel("resisting force (F - gas) [kN]"); a2.grid(True)
    fig.suptitle(f"{name}: force-displacement and force-velocity loops (last cycle)"
                 + ("; wide light lines: measured" if len(measured) else ""))
    legend = [(line.get_label(), matplotlib.colors.to_hex(line.get_color())) for line in a1.get_lines()]
    _save_figure(fig, path, "--plot"); plt.close(fig)
    return legend


def cmd_fit(args):
    from struts.fit import fit, read_rig_csv
    from struts.rig import check_cycle_work

    if args.write:
        check_output_file(args.write, "--write", suffixes=(".yaml", ".yml"), inputs=_inputs(args),
                          overwrite=args.overwrite)
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
            with atomic_output(args.write) as tmp:
                tmp.write_text(yaml.safe_dump(fitted.model_dump(), sort_keys=False))
        except OSError as exc:
            raise UserInputError(f"--write: cannot write {args.write} ({exc.strerror})") from None
    unidentified = [n for n in names if not _identified(res.confidence_95[n])]
    log = logging.getLogger("hpsim")
    for n in unidentified:
        lo, hi = res.confidence_95[n]
        log.warning(f"{n} is not identified by these data: 95 % confidence interval {lo:.3g} to {hi:.3g} "
                    f"{FIT_UNITS.get(n, '')} ({_orders(lo, hi)}); {EXCITED_BY.get(n, 'tests that excite it')} "
                    "would identify it")
    if unidentified:
        kept = [n for n in names if n not in unidentified]
        n_tests = len(data.tests())
        log.warning(f"what to do: {n_tests} test(s) of {data.kind} data for {len(names)} parameter(s); "
                    + (f"fit {', '.join(kept)} alone (--fit {','.join(kept)}) and hold "
                       f"{', '.join(unidentified)} at the strut file's value(s) (--set to change them)"
                       if kept else "hold them at the strut file's values and fit one at a time")
                    + ("; loops (force against deflection per test) identify more than an energy per cycle"
                       if data.kind == "energy" else ""))
    if args.json:
        out = res.as_dict()
        out["units"] = {n: FIT_UNITS.get(n, "") for n in names}
        out["not_identified"] = unidentified
        print_json(out)
    else:
        print(format_table(["parameter", "unit", "initial", "fitted", "95% CI low", "95% CI high", "identified"],
                           [(n, FIT_UNITS.get(n, "") or "-", res.initial[n], res.values[n], *res.confidence_95[n],
                             "no" if n in unidentified else "yes") for n in names]))
        print()
        print(format_table(["test", "measured", "model", "rel. error [%]"],
                           [(i + 1, m, s, 100 * (s - m) / m) for i, (m, s) in enumerate(zip(res.measured, res.model))]))


# the rig tests that excite each fittable parameter (what to add when the data do not identify it): the seal
# friction dominates where the valve force (~ v^2) is small, its pressure part needs different mean pressures,
# the gas's heat exchange acts at periods near its time constant, the valves at high velocities
EXCITED_BY = {
    "F0": "slow tests (peak velocity below about 0.05 m/s, where the valve force is small)",
    "F0_compression": "slow tests (peak velocity below about 0.05 m/s) as loops, compression half",
    "F0_rebound": "slow tests (peak velocity below about 0.05 m/s) as loops, rebound half",
    "pressure_coefficient": "slow tests at two or more mean deflections (different gas pressures)",
    "breakaway_ratio": "loops of slow tests (the force step at each reversal)",
    "viscous": "tests over a range of moderate velocities (0.05-0.3 m/s)",
    "thermal_time_constant": "slow cycles with periods near the gas's time constant (0.01-0.1 Hz)",
    "bleed_area": "fast tests (peak velocity above about 0.3 m/s)",
    "discharge_coefficient": "fast tests (peak velocity above about 0.3 m/s)",
    "polytropic_exponent": "loops of large-amplitude tests (the gas spring's slope)",
}
# SI units of the fittable parameters (struts.fit.FITTABLE), for the table
FIT_UNITS = {"F0": "N", "F0_compression": "N", "F0_rebound": "N", "pressure_coefficient": "N/Pa",
             "breakaway_ratio": "", "viscous": "N s/m", "thermal_time_constant": "s", "bleed_area": "m^2",
             "discharge_coefficient": "", "polytropic_exponent": ""}
# a parameter is taken as identified when its 95 % interval spans less than this factor
IDENTIFIED_SPAN = 10.0


def _identified(ci) -> bool:
    import math

    lo, hi = (float(v) for v in ci)
    return math.isfinite(lo) and math.isfinite(hi) and lo > 0 and hi / lo < IDENTIFIED_SPAN


def _orders(lo: float, hi: float) -> str:
    import math

    if not math.isfinite(hi):
        return "unbounded"
    if not math.isfinite(lo) or lo <= 0:
        return "reaches zero"
    return f"{math.log10(hi / lo):.1f} orders of magnitude"


def cmd_identify(args):
    from struts.identify import IDENTIFIED_NAMES, identify_rig
    from struts.rig import check_cycle_arguments, check_cycle_work

    from struts.params import load_strut

    _check_outputs(args)
    layout = load_strut(args.strut).layout
    if layout != "integrated":
        raise UserInputError(f"--strut: identify needs an integrated strut (seed 001's model); {args.strut} has "
                             f"layout {layout}")
    params, p0, _ = _params(args)
    temps = _quantity_list(args.temperatures, "K", "--temperatures", "[-73, 177] degC")
    if any(not _T_RANGE_K[0] <= T <= _T_RANGE_K[1] for T in temps):
        raise UserInputError(f"--temperatures: each must be in [{_T_RANGE_K[0] - 273.15:.4g}, "
                             f"{_T_RANGE_K[1] - 273.15:.4g}] degC")
    freqs = _quantity_list(args.frequencies, "Hz", "--frequencies", f"(0, {_max_frequency():g}] Hz")
    if any(not 0 < f <= _max_frequency() for f in freqs):
        raise UserInputError(f"--frequencies: each must be in (0, {_max_frequency():g}] Hz")
    v_peak = _quantity(args.peak_velocity, "m/s", "--peak-velocity", "(0, 2] m/s")
    if not 0 < v_peak <= 2.0:
        raise UserInputError(f"--peak-velocity: must be in (0, 2] m/s, got {v_peak:g} m/s")
    stroke_mm = params.geometry.stroke * 1e3
    mean = _quantity(args.mean, "m", "--mean", f"inside the stroke [0, {stroke_mm:.4g}] mm")
    check_cycle_work(len(temps) * len(freqs), args.cycles)
    for f in freqs:
        check_cycle_arguments(params, v_peak / (2.0 * 3.141592653589793 * f), f, mean, args.cycles)
    rows = identify_rig(params, temps, freqs, v_peak, mean, cycles=args.cycles, p0_Pa=p0)
    if args.csv:
        header = ["temperature_K", "frequency_Hz", "amplitude_m"] + list(IDENTIFIED_NAMES) + ["state_gas_fraction"]
        _write_csv(args.csv, header, [[r["temperature_K"], r["frequency_Hz"], r["amplitude_m"]]
                                      + [r["identified"][n] for n in IDENTIFIED_NAMES]
                                      + [r["state_gas_fraction"] if r["state_gas_fraction"] is not None else float("nan")]
                                      for r in rows])
    if args.plot:
        plot_identified(rows, args.plot, params.name)
    if args.json:
        print_json(rows)
    else:
        print(format_table(["T [degC]", "f [Hz]", "gamma_0 [%]", "C_b", "C_v", "F_c comp [N]", "F_c reb [N]",
                            "peak comp [N]", "peak reb [N]", "k comp [s/m]", "k reb [s/m]", "v_h comp [mm/s]",
                            "v_h reb [mm/s]"],
                           [(r["temperature_K"] - 273.15, r["frequency_Hz"], 100 * r["identified"]["gas_fraction"],
                             r["identified"]["bleed_discharge_coefficient"],
                             r["identified"]["check_discharge_coefficient"],
                             r["identified"]["coulomb_compression"], r["identified"]["coulomb_rebound"],
                             r["identified"]["peak_compression"], r["identified"]["peak_rebound"],
                             r["identified"]["stribeck_coefficient_compression"],
                             r["identified"]["stribeck_coefficient_rebound"],
                             1e3 * r["identified"]["transition_velocity_compression"],
                             1e3 * r["identified"]["transition_velocity_rebound"]) for r in rows]))


# panels of the identified-parameter figure: (title, [(name, label)], scale, unit)
_IDENTIFIED_PANELS = (
    ("gas fraction (Fig. 10a)", [("gas_fraction", "")], 100.0, "%"),
    ("discharge coefficients (Fig. 10b)", [("bleed_discharge_coefficient", "bleed"),
                                           ("check_discharge_coefficient", "check")], 1.0, "-"),
    ("Coulomb friction (Fig. 11a)", [("coulomb_compression", "comp"), ("coulomb_rebound", "reb")], 1.0, "N"),
    ("peak friction (Fig. 11b)", [("peak_compression", "comp"), ("peak_rebound", "reb")], 1.0, "N"),
    ("Stribeck coefficient (Fig. 11c)", [("stribeck_coefficient_compression", "comp"),
                                         ("stribeck_coefficient_rebound", "reb")], 1.0, "s/m"),
    ("transition velocity (Fig. 11d)", [("transition_velocity_compression", "comp"),
                                        ("transition_velocity_rebound", "reb")], 1e3, "mm/s"),
)


def plot_identified(rows, path, name):
    """The identified internal parameters against frequency, one line per temperature and stroke (seed 001 Figs.
    10-11 layout)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    temps = sorted({r["temperature_K"] for r in rows})
    fig, axes = plt.subplots(2, 3, figsize=(13, 7.5))
    styles = ("-", "--")
    for ax, (title, names, scale, unit) in zip(axes.ravel(), _IDENTIFIED_PANELS):
        for k, T in enumerate(temps):
            sel = sorted((r for r in rows if r["temperature_K"] == T), key=lambda r: r["frequency_Hz"])
            f = [r["frequency_Hz"] for r in sel]
            for j, (n, lab) in enumerate(names):
                ax.plot(f, [scale * r["identified"][n] for r in sel], styles[j], marker="o", ms=3, color=f"C{k}",
                        label=f"{T - 273.15:.0f} degC" + (f" {lab}" if lab else ""))
        ax.set_xscale("log"); ax.set_xlabel("frequency [Hz]"); ax.set_ylabel(f"[{unit}]")
        ax.set_title(title, fontsize=9); ax.grid(True, which="both", alpha=0.4)
        ax.legend(fontsize=6, ncol=2 if len(names) > 1 else 1, loc="best")
    fig.suptitle(f"{name}: seed 001's internal parameters identified from the rig loops (eq. 1-12 fitted per test)")
    fig.tight_layout()
    _save_figure(fig, path, "--plot"); plt.close(fig)


def cmd_gas(args):
    import numpy as np

    from struts import gas as gaslaw

    try:
        from CoolProp.CoolProp import PropsSI
    except ImportError:
        raise UserInputError(f"strut gas: needs CoolProp ({install_hint('test')})") from None
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
        with atomic_output(path) as tmp, open(tmp, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(header)
            for r in rows:
                w.writerow([f"{float(v):.10g}" for v in r])
    except OSError as exc:
        raise UserInputError(f"--csv: cannot write {path} ({exc.strerror})") from None


def _save_figure(fig, path, where: str):
    try:
        with atomic_output(path) as tmp:
            fig.savefig(tmp, dpi=120)
    except OSError as exc:
        raise UserInputError(f"{where}: cannot write {path} ({exc.strerror})") from None
