"""Seed 001's figure set for the integrated strut (yin2023) on the rig, and the numbers behind docs/validation.md
"Seed 001: temperature and frequency".

    python docs/scripts/yin2023_figures.py                       # the physical strut: figures, table, checks
    python docs/scripts/yin2023_figures.py --model identified --tag identified --no-figures   # seed 001's model

The rig runs seed 001's tests with the paper's equations as written (compressible chambers, seed 001 eq. 5-7;
`--chambers file` for the strut file's quasi-steady reduction): body temperatures 30/40/50 degC, sinusoids of 0.5/1/2/4/8 Hz at one peak velocity
(0.1 m/s: the paper held the velocity range constant, §5.2), about 60 mm deflection (mid stroke), three cycles, the
last one kept. Figures (each a panel per frequency 0.5/2/8 Hz, a curve per temperature):
  yin2023_force_loops.png     force-deflection and force-velocity (seed 001 Figs. 4-6)
  yin2023_components.png      gas pressure-deflection, pressure difference-velocity, seal friction-deflection and
                              seal friction-velocity (Figs. 7-9)
  yin2023_internal.png        the internal parameters identified from each loop (`struts.identify`, seed 001's eq.
                              1-12 fitted per test as the paper did) against frequency per temperature (Figs.
                              10-11), with the equivalent stiffness and damping (first harmonic of the force)
Table <data>/yin2023_rig<tag>.csv: per run the equivalent stiffness and damping, the energies by mechanism, the
mean force, the peak pressure differences per stroke, the loop widths and the identified internal parameters.
Checks <data>/yin2023_checks<tag>.md: every statement of seed 001 §5 judged by the criterion written beside it
(`CHECKS`, fixed before the table is made).
"""
from __future__ import annotations

import argparse
import csv
import math
from pathlib import Path

import numpy as np

from struts.identify import PAPER_MODEL, Loop, identify_loop
from struts.params import load_strut
from struts.rig import cycle_test

TEMPERATURES_C = (30.0, 40.0, 50.0)
FREQUENCIES_HZ = (0.5, 1.0, 2.0, 4.0, 8.0)
LOOP_FREQUENCIES_HZ = (0.5, 2.0, 8.0)
PEAK_VELOCITY = 0.1        # m/s, every test (seed 001 §5.2: "the velocity range was the same")
MEAN_DEFLECTION = 0.06     # m, mid stroke of yin2023
COLORS = {30.0: "C0", 40.0: "C2", 50.0: "C3"}


def run_all(params) -> dict:
    """{(T_C, f_Hz): CycleResult} for every test."""
    out = {}
    for T in TEMPERATURES_C:
        for f in FREQUENCIES_HZ:
            A = PEAK_VELOCITY / (2 * math.pi * f)
            out[(T, f)] = cycle_test(params, A, f, MEAN_DEFLECTION, cycles=3, T_K=T + 273.15)
    return out


def loop_width(x, y) -> float:
    """|closed integral of y dx| / (range of x * range of y): the hysteresis of a loop y(x) as a fraction of its
    bounding box (0 for a single-valued curve)."""
    x, y = np.append(x, x[0]), np.append(y, y[0])
    area = abs(float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(x))))
    return area / max(float(np.ptp(x) * np.ptp(y)), 1e-300)


def _friction_levels(r) -> dict:
    """Seal friction near the reversals (|v| < 0.2 v_peak) and at speed (|v| > 0.9 v_peak), and its cycle means."""
    fr, v = np.abs(r.components_N["friction"][:-1]), r.v_m_per_s[:-1]
    vp = np.max(np.abs(v))
    return {"friction_near_reversal_N": float(np.max(fr[np.abs(v) < 0.2 * vp])),
            "friction_at_speed_N": float(np.mean(fr[np.abs(v) > 0.9 * vp])),
            "friction_mean_compression_N": float(np.mean(fr[v > 0])),
            "friction_mean_rebound_N": float(np.mean(fr[v < 0])),
            "friction_mean_N": float(np.mean(fr))}


def rows_of(runs: dict, annulus_m2: float, params) -> list[dict]:
    rows = []
    for (T, f), r in sorted(runs.items()):
        dp = r.components_N["valve"] / annulus_m2
        row = {"T_C": T, "f_Hz": f, "amplitude_mm": r.amplitude_m * 1e3,
               "k_eq_kN_m": r.equivalent_stiffness_N_per_m / 1e3, "c_eq_kNs_m": r.equivalent_damping_N_s_per_m / 1e3,
               "F_mean_N": float(np.mean(r.force_N[:-1])), "E_cycle_J": r.energy_per_cycle_J,
               "E_valve_J": r.energy_by_mechanism_J["valve"], "E_friction_J": r.energy_by_mechanism_J["friction"],
               "E_gas_J": r.energy_by_mechanism_J["gas"],
               "dp_compression_max_kPa": float(np.max(dp[r.v_m_per_s > 0])) / 1e3,
               "dp_rebound_max_kPa": float(-np.min(dp[r.v_m_per_s < 0])) / 1e3,
               "friction_abs_max_N": float(np.max(np.abs(r.components_N["friction"]))),
               "p_gas_mean_MPa": float(np.mean(r.gas_pressure_Pa[:-1])) / 1e6,
               "f_eq_Hz": r.excitation_frequency_Hz,
               # hysteresis of the component loops (seed 001 §5.1): pressure difference and friction against
               # velocity, gas pressure against deflection
               "dp_loop_width": loop_width(r.v_m_per_s[:-1], dp[:-1]),
               "friction_loop_width": loop_width(r.v_m_per_s[:-1], r.components_N["friction"][:-1]),
               "gas_loop_width": loop_width(r.x_m[:-1], r.gas_pressure_Pa[:-1])}
        row.update(_friction_levels(r))
        g = r.states.get("gas_fraction")
        row["state_gas_fraction"] = float(np.mean(g)) if g is not None else None
        row.update(identify_loop(params, Loop.from_cycle(r, T + 273.15)))
        rows.append(row)
    return rows


def _loop_axes(plt, nrows, title):
    fig, axes = plt.subplots(nrows, len(LOOP_FREQUENCIES_HZ), figsize=(4.2 * len(LOOP_FREQUENCIES_HZ), 2.9 * nrows),
                             squeeze=False)
    fig.suptitle(title, fontsize=11)
    return fig, axes


def figure_loops(plt, runs, path, name):
    fig, ax = _loop_axes(plt, 2, f"{name}: total force, peak velocity {PEAK_VELOCITY} m/s, mean "
                                 f"{MEAN_DEFLECTION * 1e3:.0f} mm (seed 001 Figs. 4-6)")
    for j, f in enumerate(LOOP_FREQUENCIES_HZ):
        for T in TEMPERATURES_C:
            r = runs[(T, f)]
            ax[0, j].plot(r.x_m * 1e3, r.force_N / 1e3, color=COLORS[T], label=f"{T:.0f} degC")
            ax[1, j].plot(r.v_m_per_s, r.force_N / 1e3, color=COLORS[T], label=f"{T:.0f} degC")
        ax[0, j].set_title(f"{f:g} Hz (amplitude {runs[(40.0, f)].amplitude_m * 1e3:.1f} mm)", fontsize=9)
        ax[0, j].set_xlabel("deflection [mm]")
        ax[1, j].set_xlabel("velocity [m/s] (> 0 compression)")
        for a in ax[:, j]:
            a.set_ylabel("force [kN]")
            a.grid(alpha=0.3)
    ax[0, 0].legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def figure_components(plt, runs, path, name, annulus_m2):
    fig, ax = _loop_axes(plt, 4, f"{name}: gas pressure, pressure difference p_c - p_r and seal friction "
                                 "(seed 001 Figs. 7-9)")
    for j, f in enumerate(LOOP_FREQUENCIES_HZ):
        for T in TEMPERATURES_C:
            r = runs[(T, f)]
            kw = dict(color=COLORS[T], label=f"{T:.0f} degC")
            ax[0, j].plot(r.x_m * 1e3, r.gas_pressure_Pa / 1e6, **kw)
            ax[1, j].plot(r.v_m_per_s, r.components_N["valve"] / annulus_m2 / 1e6, **kw)
            ax[2, j].plot(r.x_m * 1e3, r.components_N["friction"], **kw)
            ax[3, j].plot(r.v_m_per_s, r.components_N["friction"], **kw)
        ax[0, j].set_title(f"{f:g} Hz", fontsize=9)
        labels = (("deflection [mm]", "gas pressure [MPa]"), ("velocity [m/s]", "p_c - p_r [MPa]"),
                  ("deflection [mm]", "seal friction [N]"), ("velocity [m/s]", "seal friction [N]"))
        for i, (xl, yl) in enumerate(labels):
            ax[i, j].set_xlabel(xl, fontsize=8)
            ax[i, j].set_ylabel(yl, fontsize=8)
            ax[i, j].grid(alpha=0.3)
    ax[0, 0].legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def figure_internal(plt, rows, path, name):
    panels = (("gas_fraction", None, 100.0, "gas fraction gamma_0 [%] (Fig. 10a)"),
              ("bleed_discharge_coefficient", "check_discharge_coefficient", 1.0,
               "discharge coefficient [-] (Fig. 10b)\nsolid bleed, dashed check"),
              ("coulomb_compression", "coulomb_rebound", 1.0, "Coulomb friction [N] (Fig. 11a)"),
              ("peak_compression", "peak_rebound", 1.0, "peak friction [N] (Fig. 11b)"),
              ("stribeck_coefficient_compression", "stribeck_coefficient_rebound", 1.0,
               "Stribeck coefficient k [s/m] (Fig. 11c)"),
              ("transition_velocity_compression", "transition_velocity_rebound", 1e3,
               "transition velocity [mm/s] (Fig. 11d)"),
              ("k_eq_kN_m", None, 1.0, "equivalent stiffness [kN/m]"),
              ("c_eq_kNs_m", None, 1.0, "equivalent damping [kN s/m]"))
    fig, axes = plt.subplots(2, 4, figsize=(15, 6.6))
    fig.suptitle(f"{name}: internal parameters identified from each rig loop (seed 001 eq. 1-12 fitted per test, "
                 "struts.identify) and external stiffness and damping; solid compression, dashed rebound where two",
                 fontsize=10)
    for a, (k1, k2, scale, title) in zip(axes.ravel(), panels):
        for T in TEMPERATURES_C:
            sel = [r for r in rows if r["T_C"] == T]
            f = [r["f_Hz"] for r in sel]
            a.plot(f, [r[k1] * scale for r in sel], "o-", color=COLORS[T], label=f"{T:.0f} degC")
            if k2:
                a.plot(f, [r[k2] * scale for r in sel], "s--", color=COLORS[T], mfc="none")
        a.set_xscale("log")
        a.minorticks_off()
        a.set_xticks(FREQUENCIES_HZ)
        a.set_xticklabels([f"{f:g}" for f in FREQUENCIES_HZ])
        a.set_xlabel("frequency [Hz]", fontsize=8)
        a.set_title(title, fontsize=8)
        a.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def side_runs(params, annulus_m2) -> dict:
    """The runs that attribute a loop to its cause: the gas-pressure loop at 0.5 Hz with the gas held polytropic
    (no heat exchange) and at 8 Hz with the emulsion's free gas held near zero, both at 40 degC."""
    out = {}
    for name, over, f in (("polytropic_0.5", {"gas.process": "polytropic"}, 0.5),
                          ("no_gas_8", {"emulsion.initial_gas_fraction": 1e-5, "emulsion.release_efficiency": 0.0,
                                        "emulsion.interface_entrainment": 0.0}, 8.0)):
        if name == "no_gas_8" and params.internals == "identified" and params.internal_maps is not None:
            over = {**over, "internal_maps.gas_fraction": None}
        p = params.with_overrides(over)
        A = PEAK_VELOCITY / (2 * math.pi * f)
        r = cycle_test(p, A, f, MEAN_DEFLECTION, cycles=3, T_K=313.15,
                       **({"gas_fraction_start": 1e-5} if "no_gas" in name and params.internals == "physical" else {}))
        out[name] = {"gas_loop_width": loop_width(r.x_m[:-1], r.gas_pressure_Pa[:-1]),
                     "dp_loop_width": loop_width(r.v_m_per_s[:-1], r.components_N["valve"][:-1] / annulus_m2)}
    return out


def _at(rows, T, f, key):
    return next(r[key] for r in rows if r["T_C"] == T and r["f_Hz"] == f)


def _rel(a, b):
    return a / b - 1.0


# seed 001 §5's statements, each a check with its criterion, written before the table is made. Categories: check
# (judged), input (the model was built or calibrated from it), consequence (follows from the model's own equations
# whatever the data). A check passes (R), holds in direction only (D: the sign right, the size outside the window)
# or fails (N). Magnitudes: a window of a factor 2 about the paper's number unless stated.
def judge(rows, extra) -> str:
    F = FREQUENCIES_HZ
    lines = ["| # | seed 001 (section) | category | criterion (fixed before the run) | hpsim | verdict |",
             "|---|---|---|---|---|---|"]

    def add(num, text, cat, crit, value, verdict):
        lines.append(f"| {num} | {text} | {cat} | {crit} | {value} | {verdict} |")

    def rd(ok, direction_ok=None):
        return "R" if ok else ("D" if direction_ok else "N")

    dF = _rel(_at(rows, 50.0, 0.5, "F_mean_N"), _at(rows, 30.0, 0.5, "F_mean_N"))
    add(1, "higher temperature raises the mean force (§5.1)", "check", "+1 % or more, 30 -> 50 degC, 0.5 Hz",
        f"{100 * dF:+.1f} %", rd(dF > 0.01, dF > 0))
    dP = _rel(_at(rows, 50.0, 0.5, "p_gas_mean_MPa"), _at(rows, 30.0, 0.5, "p_gas_mean_MPa"))
    add(2, "... mainly through the gas pressure (§5.1)", "check", "mean gas pressure +1 % or more",
        f"{100 * dP:+.1f} %", rd(dP > 0.01, dP > 0))
    share = _at(rows, 40.0, 2.0, "E_friction_J") / _at(rows, 40.0, 2.0, "E_cycle_J")
    add(3, "loop hysteresis mainly from the seal friction (§5.1)", "check", "friction > 50 % of the loop energy "
        "(40 degC, 2 Hz)", f"{100 * share:.0f} %", rd(share > 0.5))
    w_dp = [_at(rows, 40.0, f, "dp_loop_width") for f in (0.5, 8.0)]
    w_fr = [_at(rows, 40.0, f, "friction_loop_width") for f in (0.5, 8.0)]
    ok4 = w_dp[1] >= 0.05 and w_dp[1] / w_dp[0] > w_fr[1] / w_fr[0]
    add(4, "frequency adds hysteresis, especially to the pressure difference (§5.1)", "check",
        "dp-v loop width >= 0.05 at 8 Hz and growing more than the friction loop's (40 degC)",
        f"dp {w_dp[0]:.4f} -> {w_dp[1]:.4f}; friction {w_fr[0]:.3f} -> {w_fr[1]:.3f}", rd(ok4, w_dp[1] > w_dp[0]))
    w5, w5p = _at(rows, 40.0, 0.5, "gas_loop_width"), extra["polytropic_0.5"]["gas_loop_width"]
    add(5, "gas-pressure hysteresis at 0.5 Hz from heat transfer (§5.1)", "check",
        "p-x loop width >= 0.01 at 0.5 Hz, <= 10 % of it without heat exchange (polytropic gas)",
        f"{w5:.4f} (polytropic {w5p:.4f})", rd(w5 >= 0.01 and w5p <= 0.1 * w5, w5 > w5p))
    w6, w6n = _at(rows, 40.0, 8.0, "gas_loop_width"), extra["no_gas_8"]["gas_loop_width"]
    add(6, "gas-pressure hysteresis at higher frequency from the emulsion (§5.1)", "check",
        "p-x loop width >= 0.01 at 8 Hz and >= 2x the width with the free gas held near zero (40 degC)",
        f"{w6:.4f} (free gas ~0: {w6n:.4f})", rd(w6 >= 0.01 and w6 >= 2 * w6n, w6 > w6n))
    ratio = [_at(rows, 40.0, f, "friction_near_reversal_N") / _at(rows, 40.0, f, "friction_at_speed_N") for f in F]
    add(7, "Stribeck behaviour: peak friction near zero velocity, decaying with velocity (§5.1)", "check",
        "friction near the reversals >= 1.1x that at speed, every frequency (40 degC)",
        f"{min(ratio):.2f}-{max(ratio):.2f}x", rd(min(ratio) >= 1.1, min(ratio) > 1.0))
    asym = [_at(rows, T, 0.5, "dp_compression_max_kPa") / _at(rows, T, 0.5, "dp_rebound_max_kPa")
            for T in TEMPERATURES_C]
    add(8, "pressure difference smaller in compression than in extension (§5.1)", "check",
        "peak dp compression < rebound, every temperature (0.5 Hz)", f"ratio {min(asym):.2f}-{max(asym):.2f}",
        rd(max(asym) < 1.0))
    dv = [_rel(_at(rows, 50.0, f, "E_valve_J"), _at(rows, 30.0, f, "E_valve_J")) for f in F]
    add(9, "temperature only slightly affects the hydraulic damping (§5.1)", "check",
        "valve energy within +-10 %, 30 -> 50 degC, every frequency", f"{100 * min(dv):+.1f} to {100 * max(dv):+.1f} %",
        rd(max(abs(x) for x in dv) <= 0.10))
    asf = [_at(rows, 40.0, f, "friction_mean_compression_N") / _at(rows, 40.0, f, "friction_mean_rebound_N") for f in F]
    add(10, "friction damping asymmetric, with hysteresis (§5.1)", "consequence",
        "seal levels per stroke are inputs (Coulomb compression > rebound, assumed from §5.2)",
        f"compression / rebound mean {min(asf):.2f}-{max(asf):.2f}", "-")
    add(11, "bulk modulus and viscosity fall with temperature (§5.2)", "input", "Table 1 and the fluid's datasheet",
        "-", "-")
    dk = [_rel(_at(rows, 50.0, f, "k_eq_kN_m"), _at(rows, 30.0, f, "k_eq_kN_m")) for f in F]
    add(12, "higher temperature: greater equivalent stiffness (conclusions)", "check",
        "k_eq +1 % or more, 30 -> 50 degC, every frequency", f"{100 * min(dk):+.1f} to {100 * max(dk):+.1f} %",
        rd(min(dk) > 0.01, min(dk) > 0))
    dc = [_rel(_at(rows, 50.0, f, "c_eq_kNs_m"), _at(rows, 30.0, f, "c_eq_kNs_m")) for f in F]
    add(13, "... and comparable damping (conclusions)", "check", "c_eq within +-10 %, 30 -> 50 degC, every frequency",
        f"{100 * min(dc):+.1f} to {100 * max(dc):+.1f} %", rd(max(abs(x) for x in dc) <= 0.10))
    add(14, "higher frequency: greater friction hysteresis (conclusions)", "check",
        "friction-v loop width x1.5 or more, 0.5 -> 8 Hz (40 degC)", f"{w_fr[0]:.3f} -> {w_fr[1]:.3f}",
        rd(w_fr[1] >= 1.5 * w_fr[0], w_fr[1] > w_fr[0]))
    pk = _rel(_at(rows, 40.0, 8.0, "friction_near_reversal_N"), _at(rows, 40.0, 0.5, "friction_near_reversal_N"))
    mn = _rel(_at(rows, 40.0, 8.0, "friction_mean_N"), _at(rows, 40.0, 0.5, "friction_mean_N"))
    add(15, "higher frequency: smaller seal friction magnitude (conclusions)", "check",
        "peak and cycle-mean friction magnitude -5 % or more, 0.5 -> 8 Hz (40 degC)", f"peak {100 * pk:+.1f} %, mean "
        f"{100 * mn:+.1f} %", rd(pk < -0.05 and mn < -0.05, pk < 0 and mn < 0))
    add(16, "seal friction magnitude grows with temperature (conclusions)", "consequence",
        "the seal's contact pressure over temperature is the model's own law (its coefficient assumed)", "-", "-")
    # identified internal parameters (seed 001 §5.2, Figs. 10-11): from the loops, not the model's constants
    g = {T: [_at(rows, T, f, "gas_fraction") for f in F] for T in TEMPERATURES_C}
    add(17, "gas fraction 0.6 % at 0.5 Hz, +100 % to 8 Hz at 50 degC (§4.2, §5.2)", "input",
        "the emulsion's two calibrated constants", f"identified {100 * g[50.0][0]:.2f} -> {100 * g[50.0][-1]:.2f} %",
        "-")
    i2 = F.index(2.0)
    t2 = 0.5 * _rel(g[50.0][i2], g[30.0][i2])
    t48 = 0.5 * np.mean([_rel(g[50.0][F.index(f)], g[30.0][F.index(f)]) for f in (4.0, 8.0)])
    t05 = 0.5 * _rel(g[50.0][0], g[30.0][0])
    ok = 0.005 <= t2 <= 0.02 and 0.01 <= t48 <= 0.04 and abs(t05) < t48
    add(18, "gas fraction: +1 % per 10 K near 2 Hz, +2 % from 4 to 8 Hz, less at low frequency (§5.2)", "check",
        "0.5-2 %/10 K at 2 Hz, 1-4 %/10 K at 4-8 Hz, the 0.5 Hz value smaller in size", f"{100 * t2:+.2f} / {100 * t48:+.2f} / "
        f"{100 * t05:+.2f} %/10 K", rd(ok, t2 > 0 and t48 > 0 and abs(t05) < t48))
    cb = [r["bleed_discharge_coefficient"] for r in rows]
    cv = [r["check_discharge_coefficient"] for r in rows]
    add(19, "bleed C_d above the check valve's (Fig. 10b)", "check", "every test",
        f"bleed {min(cb):.3f}-{max(cb):.3f}, check {min(cv):.3f}-{max(cv):.3f}",
        rd(all(b > c for b, c in zip(cb, cv))))
    fb = _rel(_at(rows, 40.0, 8.0, "bleed_discharge_coefficient"), _at(rows, 40.0, 0.5, "bleed_discharge_coefficient"))
    add(20, "C_d fall with frequency, saturating near 3 Hz; bleed -7 % (§5.2)", "check",
        "bleed -3.5 to -14 %, 0.5 -> 8 Hz (40 degC)", f"{100 * fb:+.3f} %", rd(-0.14 <= fb <= -0.035, fb < -0.005))
    tc = _rel(_at(rows, 50.0, 1.0, "check_discharge_coefficient"), _at(rows, 30.0, 1.0, "check_discharge_coefficient"))
    tb = _rel(_at(rows, 50.0, 1.0, "bleed_discharge_coefficient"), _at(rows, 30.0, 1.0, "bleed_discharge_coefficient"))
    add(21, "check C_d +11 % from 30 to 50 degC (1 Hz), bleed about unchanged (§5.2)", "check",
        "check +5.5 to +22 %, bleed within +-2 %", f"check {100 * tc:+.1f} %, bleed {100 * tb:+.2f} %",
        rd(0.055 <= tc <= 0.22 and abs(tb) <= 0.02, tc > 0 and abs(tb) <= 0.02))
    cc = [_at(rows, 40.0, f, "coulomb_compression") for f in F]
    crb = [_at(rows, 40.0, f, "coulomb_rebound") for f in F]
    spread = max(max(cc) - min(cc), max(crb) - min(crb))
    add(22, "Coulomb friction within +-0.02 kN over frequency (§5.2)", "check", "spread <= 40 N per stroke (40 degC)",
        f"{spread:.0f} N", rd(spread <= 40.0))
    add(23, "Coulomb larger in compression, more when hot; rising with temperature (Fig. 11a)", "input",
        "per-stroke levels and the contact law's coefficient are assumed from these sentences",
        f"identified {_at(rows, 30.0, 1.0, 'coulomb_compression'):.0f} -> {_at(rows, 50.0, 1.0, 'coulomb_compression'):.0f}"
        " N (compression, 1 Hz)", "-")
    pr = _rel(np.mean([_at(rows, T, 8.0, "peak_rebound") for T in TEMPERATURES_C]),
              np.mean([_at(rows, T, 0.5, "peak_rebound") for T in TEMPERATURES_C]))
    pc = _rel(_at(rows, 40.0, 8.0, "peak_compression"), _at(rows, 40.0, 0.5, "peak_compression"))
    add(24, "peak friction falls with frequency; rebound mean -20 % from 0.5 to 8 Hz (Fig. 11b)", "check",
        "both fall; rebound -10 to -40 %", f"rebound {100 * pr:+.1f} %, compression (40 degC) {100 * pc:+.1f} %",
        rd(pc < 0 and -0.40 <= pr <= -0.10, pc < 0 and pr < 0))
    p34 = [abs(_rel(_at(rows, 30.0, f, "peak_compression"), _at(rows, 40.0, f, "peak_compression"))) for f in F]
    p54 = [_rel(_at(rows, 50.0, f, "peak_compression"), _at(rows, 40.0, f, "peak_compression")) for f in F]
    add(25, "peaks at 30 and 40 degC comparable; compression at 50 degC larger (Fig. 11b)", "check",
        "30 vs 40 within 5 %; 50 above 40 by 5 % or more, every frequency",
        f"30/40 {100 * max(p34):.1f} % at most; 50/40 {100 * min(p54):+.1f} % at least",
        rd(max(p34) <= 0.05 and min(p54) >= 0.05, min(p54) > 0))
    k = {T: [0.5 * (_at(rows, T, f, "stribeck_coefficient_compression") + _at(rows, T, f, "stribeck_coefficient_rebound"))
             for f in F] for T in TEMPERATURES_C}
    k18 = _rel(k[40.0][-1], k[40.0][F.index(1.0)])
    add(26, "Stribeck coefficient -75 % from 1 to 8 Hz, maximum near 1-2 Hz (Fig. 11c)", "check",
        "mean of both strokes -50 to -90 %, 1 -> 8 Hz (40 degC)", f"{100 * k18:+.0f} %",
        rd(-0.9 <= k18 <= -0.5, k18 < 0))
    kT = np.mean([_rel(k[50.0][i], k[30.0][i]) for i in range(len(F))])
    add(27, "Stribeck coefficient lower when hot (Fig. 11c)", "check", "mean over frequency falls, 30 -> 50 degC",
        f"{100 * kT:+.0f} %", rd(kT < 0))
    vh = {T: [0.5 * (_at(rows, T, f, "transition_velocity_compression") + _at(rows, T, f, "transition_velocity_rebound"))
              for f in F] for T in TEMPERATURES_C}
    v05 = [vh[T][0] for T in TEMPERATURES_C]
    v8 = vh[40.0][-1]
    add(28, "transition velocity about 8 mm/s at 0.5 Hz, about 28 mm/s at 8 Hz (Fig. 11d)", "check",
        "4-16 mm/s at 0.5 Hz (every T), 14-56 mm/s at 8 Hz (40 degC)",
        f"{1e3 * min(v05):.1f}-{1e3 * max(v05):.1f} / {1e3 * v8:.1f} mm/s",
        rd(all(0.004 <= v <= 0.016 for v in v05) and 0.014 <= v8 <= 0.056, v8 > max(v05)))
    vT = _rel(vh[50.0][-1], vh[30.0][-1])
    add(29, "transition velocity greater when hot (Fig. 11d)", "check", "rises 30 -> 50 degC at 8 Hz",
        f"{100 * vT:+.1f} %", rd(vT > 0))
    judged = [ln for ln in lines[2:] if "| check |" in ln]
    count = {v: sum(ln.rstrip().endswith(f"| {v} |") for ln in judged) for v in "RDN"}
    lines.append("")
    lines.append(f"Checks: {len(judged)}; reproduced {count['R']}, in direction only {count['D']}, "
                 f"not reproduced {count['N']}.")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--strut", default="yin2023", help="strut name or file (default: yin2023)")
    ap.add_argument("--figures", default="docs/figures")
    ap.add_argument("--data", default="docs/data")
    ap.add_argument("--tag", default="", help="suffix of the CSV name (e.g. before)")
    ap.add_argument("--no-figures", action="store_true")
    ap.add_argument("--model", choices=("file", "identified"), default="file",
                    help="file (default): the strut file (yin2023: physical); identified: seed 001's model with the "
                         "file's maps (struts.identify.PAPER_MODEL)")
    ap.add_argument("--chambers", choices=("file", "compressible"), default="compressible",
                    help="compressible (default): seed 001 eq. 5-7 as written, the chamber pressures as states, as on "
                         "the paper's rig; file: the strut file's (yin2023: quasi_steady, the vehicle's reduction)")
    args = ap.parse_args(argv)
    params = load_strut(args.strut, PAPER_MODEL if args.model == "identified" else None)
    if args.chambers == "compressible":
        params = params.with_overrides({"valve.oil_model": "compressible"})
    annulus = params.geometry.piston_area - params.geometry.rod_area
    runs = run_all(params)
    rows = rows_of(runs, annulus, params)
    Path(args.data).mkdir(parents=True, exist_ok=True)
    out = Path(args.data) / f"yin2023_rig{('_' + args.tag) if args.tag else ''}.csv"
    with open(out, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    print(f"wrote {out}")
    extra = side_runs(params, annulus)
    checks = Path(args.data) / f"yin2023_checks{('_' + args.tag) if args.tag else ''}.md"
    checks.write_text(judge(rows, extra))
    print(f"wrote {checks}")
    if not args.no_figures:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig_dir = Path(args.figures)
        fig_dir.mkdir(parents=True, exist_ok=True)
        figure_loops(plt, runs, fig_dir / "yin2023_force_loops.png", params.name)
        figure_components(plt, runs, fig_dir / "yin2023_components.png", params.name, annulus)
        figure_internal(plt, rows, fig_dir / "yin2023_internal.png", params.name)
        print(f"wrote {fig_dir}/yin2023_force_loops.png, yin2023_components.png, yin2023_internal.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
