"""Seed 001's figure set for the integrated strut (yin2023) on the rig, and the numbers behind docs/validation.md
"Seed 001: temperature and frequency".

    python docs/scripts/yin2023_figures.py                       # figures into docs/figures, table into docs/data
    python docs/scripts/yin2023_figures.py --strut old.yaml --tag before --no-figures   # another strut file

The rig runs seed 001's tests with the paper's equations as written (compressible chambers, seed 001 eq. 5-7;
`--chambers file` for the strut file's quasi-steady reduction): body temperatures 30/40/50 degC, sinusoids of 0.5/1/2/4/8 Hz at one peak velocity
(0.1 m/s: the paper held the velocity range constant, §5.2), about 60 mm deflection (mid stroke), three cycles, the
last one kept. Figures (each a panel per frequency 0.5/2/8 Hz, a curve per temperature):
  yin2023_force_loops.png     force-deflection and force-velocity (seed 001 Figs. 4-6)
  yin2023_components.png      gas pressure-deflection, pressure difference-velocity, seal friction-deflection and
                              seal friction-velocity (Figs. 7-9)
  yin2023_internal.png        the internal parameters against frequency per temperature (Figs. 10-11) with the
                              equivalent stiffness and damping (first harmonic of the force)
Table <data>/yin2023_rig<tag>.csv: per run the equivalent stiffness and damping, the energies by mechanism, the
mean force, the peak pressure differences per stroke and the internal parameters.
"""
from __future__ import annotations

import argparse
import csv
import math
from pathlib import Path

import numpy as np

from struts.maps import INTERNAL_NAMES
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


def rows_of(runs: dict, annulus_m2: float) -> list[dict]:
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
        row.update({k: r.internal.get(k) for k in INTERNAL_NAMES})
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
    fig.suptitle(f"{name}: internal parameters (maps, struts/data/{name}.yaml) and external stiffness and damping "
                 "against frequency; solid compression, dashed rebound where two", fontsize=10)
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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--strut", default="yin2023", help="strut name or file (default: yin2023)")
    ap.add_argument("--figures", default="docs/figures")
    ap.add_argument("--data", default="docs/data")
    ap.add_argument("--tag", default="", help="suffix of the CSV name (e.g. before)")
    ap.add_argument("--no-figures", action="store_true")
    ap.add_argument("--chambers", choices=("file", "compressible"), default="compressible",
                    help="compressible (default): seed 001 eq. 5-7 as written, the chamber pressures as states, as on "
                         "the paper's rig; file: the strut file's (yin2023: quasi_steady, the vehicle's reduction)")
    args = ap.parse_args(argv)
    params = load_strut(args.strut)
    if args.chambers == "compressible":
        params = params.with_overrides({"valve.oil_model": "compressible"})
    annulus = params.geometry.piston_area - params.geometry.rod_area
    runs = run_all(params)
    rows = rows_of(runs, annulus)
    Path(args.data).mkdir(parents=True, exist_ok=True)
    out = Path(args.data) / f"yin2023_rig{('_' + args.tag) if args.tag else ''}.csv"
    with open(out, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    print(f"wrote {out}")
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
