"""Tables of docs/validation.md "Predicted" and "Sensitivity over the new mechanisms" from the sweep
scenarios/mechanism_sweep.yaml (the 106 km mileage test, one mechanism per case, same road seed).

    hpsim sweep scenarios/mechanism_sweep.yaml --workers 2 -o results/mechanisms
    hpsim sweep scenarios/mechanism_sweep_30km.yaml --workers 2 -o results/mechanisms_30km   # optional, 30 km
    python docs/scripts/mechanism_table.py results/mechanisms [results/mechanisms_30km] [--data docs/data]

Writes <data>/mileage_prediction.csv (per axle: surface, oil and gas end temperatures, rise, dh and dN
with their weighing bands, for the uncompensated and the compensated drive). It also writes
<data>/mechanism_sensitivity.csv (per case: mean surface rise, the axle-to-axle spread of the rise
and of dN (max - min over the four axles), the per-axle rises and dN, and the change of the spreads
against the case's reference), and prints both as Markdown tables.
"""
from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np

from vehicle.analysis.summary import report

# case -> (mechanism, what was varied, reference case). The CG height acts only through an
# acceleration, so its cases drive the variable speed and compare with it. A baseline reference is
# the baseline driven as far as the case (106 km: `baseline`, 30 km: `baseline_30km`).
CASES = {
    "baseline": ("baseline", "constant 20 km/h, all axles alike, nominal priors", None),
    "speed_variable": ("speed profile", "random 5-40 km/h, trip average 20 km/h (mileage_106km_variable_speed.yaml)", "baseline"),
    "cg_1.1m_variable": ("CG height", "hull.cg_height 1.1 m (prior 1.1-1.5 m), variable speed", "speed_variable"),
    "cg_1.5m_variable": ("CG height", "hull.cg_height 1.5 m, variable speed", "speed_variable"),
    "road_following_0.7": ("per-axle road", "axles 2-4 meet 0.7 of the roughness (prior 0.7-1.0)", "baseline"),
    "compensated": ("(levelling on)", "pressure compensation on (not a mechanism of issue 10)", "baseline"),
    "baseline_30km": ("baseline (30 km)", "the first 30 km of the baseline", None),
    "env_axle1_view_0.3": ("per-axle environment", "axle 1 view factor 0.3 (prior 0.3-0.7; others 0.5)", "baseline_30km"),
    "env_axle1_view_0.7": ("per-axle environment", "axle 1 view factor 0.7", "baseline_30km"),
    "env_axle1_air_x0.5": ("per-axle environment", "axle 1 air speed ratio x0.5 (prior x0.5-x2)", "baseline_30km"),
    "env_axle1_air_x2": ("per-axle environment", "axle 1 air speed ratio x2", "baseline_30km"),
    "env_axle1_ambient_+10K": ("per-axle environment", "axle 1 wheel-bay air +10 K (prior 0-10 K)", "baseline_30km"),
    "env_axle1_source_150W": ("per-axle environment", "axle 1 heat source 150 W per strut (prior 0-150 W)", "baseline_30km"),
    "oil_film_0.6": ("interior resistances", "oil film multiplier 0.6 (prior 0.6-1.5)", "baseline_30km"),
    "oil_film_1.5": ("interior resistances", "oil film multiplier 1.5", "baseline_30km"),
    "wall_k_35": ("interior resistances", "wall conductivity 35 W/mK (prior 35-50)", "baseline_30km"),
    "wall_k_50": ("interior resistances", "wall conductivity 50 W/mK", "baseline_30km"),
    "mount_0.5": ("interior resistances", "mount conductance 0.5 W/K (prior 0.5-2)", "baseline_30km"),
    "mount_2": ("interior resistances", "mount conductance 2 W/K", "baseline_30km"),
    "gas_oil_tau_60s": ("interior resistances", "gas-oil time constant 60 s (prior 10-60 s; rig fit 9.9 s)", "baseline_30km"),
}



def write_csv(path, rows: list[dict]) -> None:
    """The rows as CSV, floats to 4 decimals (the docs' tables are made from these files)."""
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows({k: (round(v, 4) if isinstance(v, float) else v) for k, v in r.items()} for r in rows)

def case_metrics(rep: dict) -> dict:
    ax = rep["axles"]
    rise = np.array([a["T_end_C"] - a["T_start_C"] for a in ax])
    dN = np.array([a["dN_pct"] for a in ax])
    dh = np.array([a["dh_mm"] for a in ax])
    return {"mean_rise_K": float(np.mean(rise)), "rise_spread_K": float(np.ptp(rise)),
            "dN_spread_pp": float(np.ptp(dN)), "load_shift_pct": rep["load_shift_pct"],
            "rise_K": rise, "dN_pct": dN, "dh_mm": dh, "complete": rep["complete"]}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results", nargs="+", help="the sweeps' output folders (one <case>.h5 per case)")
    ap.add_argument("--data", default=str(Path(__file__).resolve().parents[1] / "data"), help="where the CSVs go")
    args = ap.parse_args(argv)
    folders, data = [Path(f) for f in args.results], Path(args.data)
    data.mkdir(parents=True, exist_ok=True)
    reps = {}
    for f in folders:          # a case found in several folders: the first folder's complete run
        for c in CASES:
            if c not in reps and (f / f"{c}.h5").exists():
                r = report(f / f"{c}.h5")
                if r["complete"]:
                    reps[c] = r
    missing = [c for c in CASES if c not in reps]
    if missing:
        print("missing or unfinished cases:", ", ".join(missing))

    # --- the prediction: per axle, uncompensated and compensated
    rows = []
    for case in ("baseline", "compensated"):
        if case not in reps:
            continue
        for a in reps[case]["axles"]:
            rows.append({"case": case, "axle": a["axle"], "T_start_C": a["T_start_C"],
                         "T_surface_end_C": a["T_surface_end_C"], "T_oil_end_C": a["T_oil_end_C"],
                         "T_gas_end_C": a["T_gas_end_C"], "rise_K": a["T_end_C"] - a["T_start_C"],
                         "dh_mm": a["dh_mm"], "dh_band_low_mm": a["dh_band_mm"][0], "dh_band_high_mm": a["dh_band_mm"][1],
                         "N_before_daN": a["N_before_daN"], "N_after_daN": a["N_after_daN"], "dN_pct": a["dN_pct"],
                         "dN_band_low_pct": a["dN_band_pct"][0], "dN_band_high_pct": a["dN_band_pct"][1],
                         "energy_MJ": a["energy_dissipated_MJ"]})
    if rows:
        write_csv(data / "mileage_prediction.csv", rows)
        print("| case | axle | T surface end [degC] | T oil end | T gas end | rise [K] | dh [mm] (weighing band) "
              "| dN [%] (weighing band) |")
        print("|---|---|---|---|---|---|---|---|")
        for r in rows:
            print(f"| {r['case']} | {r['axle']} | {r['T_surface_end_C']:.1f} | {r['T_oil_end_C']:.1f} | "
                  f"{r['T_gas_end_C']:.1f} | {r['rise_K']:.1f} | {r['dh_mm']:+.1f} [{r['dh_band_low_mm']:+.0f}, "
                  f"{r['dh_band_high_mm']:+.0f}] | {r['dN_pct']:+.2f} [{r['dN_band_low_pct']:+.1f}, "
                  f"{r['dN_band_high_pct']:+.1f}] |")
        print()

    # --- the sensitivity over the mechanisms
    M = {c: case_metrics(r) for c, r in reps.items()}
    out = []
    for c, (mech, what, ref) in CASES.items():
        if c not in M:
            continue
        m = M[c]
        row = {"case": c, "mechanism": mech, "varied": what, "reference": ref or "",
               "distance_km": round(reps[c]["distance_km"], 3),
               "mean_rise_K": m["mean_rise_K"], "rise_spread_K": m["rise_spread_K"], "dN_spread_pp": m["dN_spread_pp"],
               "load_shift_pct": m["load_shift_pct"]}
        if ref in ("baseline", "baseline_30km"):   # the baseline driven as far as this case
            same = [b for b in ("baseline", "baseline_30km")
                    if b in reps and abs(reps[b]["distance_km"] - reps[c]["distance_km"]) < 1e-3]
            ref = same[0] if same else None
        if ref and ref in M:
            row["d_mean_rise_K"] = m["mean_rise_K"] - M[ref]["mean_rise_K"]
            row["d_rise_spread_K"] = m["rise_spread_K"] - M[ref]["rise_spread_K"]
            row["d_dN_spread_pp"] = m["dN_spread_pp"] - M[ref]["dN_spread_pp"]
        else:
            row["d_mean_rise_K"] = row["d_rise_spread_K"] = row["d_dN_spread_pp"] = 0.0
        row["reference"] = ref or ""
        for k in range(4):
            row[f"rise_K_axle{k + 1}"] = m["rise_K"][k]
        for k in range(4):
            row[f"dN_pct_axle{k + 1}"] = m["dN_pct"][k]
        for k in range(4):
            row[f"dh_mm_axle{k + 1}"] = m["dh_mm"][k]
        out.append(row)
    write_csv(data / "mechanism_sensitivity.csv", out)
    print("| mechanism | case | km | mean rise [K] | rise spread [K] (change) | dN spread [pp] (change) | "
          "rise per axle [K] | dN per axle [%] |")
    print("|---|---|---|---|---|---|---|---|")
    for r in out:
        rises = " / ".join(f"{r[f'rise_K_axle{k}']:.1f}" for k in range(1, 5))
        dns = " / ".join(f"{r[f'dN_pct_axle{k}']:+.2f}" for k in range(1, 5))
        print(f"| {r['mechanism']} | {r['varied']} | {r['distance_km']:.0f} | {r['mean_rise_K']:.1f} | {r['rise_spread_K']:.2f} "
              f"({r['d_rise_spread_K']:+.3f}) | {r['dN_spread_pp']:.2f} ({r['d_dN_spread_pp']:+.3f}) | {rises} | {dns} |")


if __name__ == "__main__":
    main()
