"""Tables of docs/validation.md §9 "The mileage prediction with per-axle priors and measurement models" from
an `hpsim uq` study of scenarios/mileage_106km_uq.yaml:

    hpsim uq scenarios/mileage_106km_uq.yaml --method lhs --samples 40 --workers 2 -o results/mileage_uq
    python docs/scripts/uq_per_axle_table.py results/mileage_uq [--data docs/data]

Writes <data>/uq_per_axle_readings.csv (per axle and instrument: the nominal prediction, the model's 5/50/95 %
and the 5/50/95 % of what the instrument would read after minus before the drive; `hpsim validate STUDY`).
It also writes <data>/uq_per_axle_spread.csv (what sets the axle-to-axle spread of the rise and of dN: per
prior, grouped over its per-axle draws, the share of the spread's rank variance a linear regression on the
group's ranks explains, adjusted R^2; and the per-parameter Spearman correlations), and prints both as Markdown
tables.
"""
from __future__ import annotations

import argparse
import csv
import json
import re
from pathlib import Path

import numpy as np
from scipy.stats import rankdata

from vehicle.studies.validate import instrument_readings

SPREADS = ("rise_spread_K", "dN_spread_pp")


def group_of(name: str) -> str:
    """A parameter's group: a per-axle prior's draws together, else the file section (as --groups section)."""
    m = re.fullmatch(r"(.+)\[(?:axle\d+[LR]?|common)\]", name)
    if m:
        return m.group(1) + " (per axle)"
    parts = name.split(".")
    return ".".join(parts[:3]) if parts[0] == "struts" else ".".join(parts[:2])


def adjusted_r2(X: np.ndarray, y: np.ndarray) -> float:
    """Adjusted R^2 of a least-squares fit of y on the columns of X (with a constant)."""
    n, k = X.shape
    A = np.column_stack([np.ones(n), X])
    res = y - A @ np.linalg.lstsq(A, y, rcond=None)[0]
    r2 = 1.0 - float(res @ res) / float(((y - y.mean()) ** 2).sum())
    return 1.0 - (1.0 - r2) * (n - 1) / (n - k - 1)


def spread_ranking(study: Path) -> list[dict]:
    with open(study / "samples.csv") as fh:
        rows = list(csv.reader(line for line in fh if not line.startswith("#")))
    names = rows[0][1:]
    samples = {r[0]: np.array([float(x) for x in r[1:]]) for r in rows[1:] if r[0] != "nominal"}
    recs = {}
    for line in (study / "cases.jsonl").read_text().splitlines():
        r = json.loads(line)
        if r.get("status") == "done":
            recs[r["case"]] = r["outputs"]
    cases = [c for c in samples if c in recs]
    X = np.array([samples[c] for c in cases])
    R = np.column_stack([rankdata(X[:, j]) for j in range(X.shape[1])])
    groups: dict[str, list[int]] = {}
    for j, n in enumerate(names):
        groups.setdefault(group_of(n), []).append(j)
    out = []
    for g, cols in groups.items():
        row = {"group": g, "parameters": len(cols)}
        for s in SPREADS:
            y = rankdata([recs[c][s] for c in cases])
            row[f"{s}_adj_r2"] = adjusted_r2(R[:, cols], y) if len(cases) > len(cols) + 2 else float("nan")
            rho = [np.corrcoef(R[:, j], y)[0, 1] for j in cols]
            row[f"{s}_max_abs_spearman"] = float(np.max(np.abs(rho)))
        out.append(row)
    return sorted(out, key=lambda r: -np.nan_to_num(r["rise_spread_K_adj_r2"], nan=-1))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("study")
    ap.add_argument("--data", default="docs/data")
    a = ap.parse_args(argv)
    study, data = Path(a.study), Path(a.data)
    data.mkdir(parents=True, exist_ok=True)
    v = instrument_readings(study)
    fields = ["instrument", "axle", "unit", "nominal", "model_p5", "model_p50", "model_p95", "reading_p5",
              "reading_p50", "reading_p95"]
    table = []
    for p in v["points"]:
        for unit, src in ((p["unit"], p), ("%", p.get("percent_of_before"))):
            if src is not None:
                table.append({"instrument": p["instrument"], "axle": p["axle"], "unit": unit,
                              "nominal": src["predicted"], "model_p5": src["predicted_band"][0],
                              "model_p50": src["predicted_median"], "model_p95": src["predicted_band"][1],
                              "reading_p5": src["band"][0], "reading_p50": src["reading_median"],
                              "reading_p95": src["band"][1]})
    with open(data / "uq_per_axle_readings.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=fields)
        w.writeheader()
        w.writerows(table)
    print(f"{v['drives']} drives (+ nominal: {bool(v['nominal'])})\n")
    print("| instrument | axle | unit | nominal | model 50 % [5 %, 95 %] | reading 50 % [5 %, 95 %] |")
    print("|---|---|---|---|---|---|")
    for r in table:
        print(f"| {r['instrument']} | {r['axle']} | {r['unit']} | {r['nominal']:+.3g} | {r['model_p50']:+.3g} "
              f"[{r['model_p5']:+.3g}, {r['model_p95']:+.3g}] | {r['reading_p50']:+.3g} "
              f"[{r['reading_p5']:+.3g}, {r['reading_p95']:+.3g}] |")
    ranking = spread_ranking(study)
    with open(data / "uq_per_axle_spread.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(ranking[0]))
        w.writeheader()
        w.writerows(ranking)
    print("\n| group | parameters | rise spread: adj. R² (max \\|ρ\\|) | dN spread: adj. R² (max \\|ρ\\|) |")
    print("|---|---|---|---|")
    for r in ranking:
        print(f"| {r['group']} | {r['parameters']} | {r['rise_spread_K_adj_r2']:.2f} ({r['rise_spread_K_max_abs_spearman']:.2f}) "
              f"| {r['dN_spread_pp_adj_r2']:.2f} ({r['dN_spread_pp_max_abs_spearman']:.2f}) |")
    print_deviation_shares(study, data)


PER_AXLE_OUTPUTS = ("rise_K", "dN_pct")


def deviation_shares(study: Path) -> dict:
    """What sets the differences between axles. Per output (rise, dN) the deviations of each axle from the
    drive's mean, pooled over drives and axles, are regressed by least squares on each per-axle prior's
    deviations plus one constant per axle (the layout: the pattern all drives share). A prior's deviation is its
    draw on that axle less the mean of its draws (the road factor of axle 1 is 1). Share of a group: beta^2
    var(x) / var(deviation); the rest is what the vehicle-wide priors do to the pattern (interactions) and the
    noise."""
    from vehicle.scenario.schema import read_scenario
    from vehicle.studies.uq import physical_values, scenario_parameters

    summary = json.loads((study / "summary.json").read_text())
    params, _, _ = scenario_parameters(read_scenario(summary["scenario"]))
    with open(study / "samples.csv") as fh:
        rows = list(csv.reader(line for line in fh if not line.startswith("#")))
    names = rows[0][1:]
    recs = {}
    for line in (study / "cases.jsonl").read_text().splitlines():
        r = json.loads(line)
        if r.get("status") == "done" and r["case"] != "nominal":
            recs[r["case"]] = r["outputs"]
    cases = [(r[0], physical_values(params, dict(zip(names, map(float, r[1:]))))) for r in rows[1:] if r[0] in recs]
    n_axles = 4
    groups = sorted({re.sub(r"\[axle\d+\]$", "", n) for n in names if re.search(r"\[axle\d+\]$", n)})

    def value(vals, g, k):
        key = f"{g}[axle{k}]"
        return vals[key] if key in vals else 1.0            # pass factor of axle 1: the road as generated

    out = {}
    for q in PER_AXLE_OUTPUTS:
        y, X, D = [], [], []
        for case, vals in cases:
            ys = np.array([recs[case][f"axle{k}.{q}"] for k in range(1, n_axles + 1)])
            xs = np.array([[np.log(value(vals, g, k)) if "air_speed_ratio" in g else value(vals, g, k)
                            for g in groups] for k in range(1, n_axles + 1)])
            y += list(ys - ys.mean())
            X += list(xs - xs.mean(axis=0))
            D += list(np.eye(n_axles))
        y, X, D = np.array(y), np.array(X), np.array(D)
        A = np.column_stack([X, D])
        beta = np.linalg.lstsq(A, y, rcond=None)[0]
        res = y - A @ beta
        var = float(np.var(y))
        shares = {g: float(beta[i] ** 2 * np.var(X[:, i]) / var) for i, g in enumerate(groups)}
        shares["layout (axle constants)"] = float(np.var(D @ beta[len(groups):]) / var)
        shares["rest (vehicle-wide priors x layout, noise)"] = float(np.var(res) / var)
        out[q] = {"shares": shares, "coefficients": {g: float(beta[i]) for i, g in enumerate(groups)},
                  "sd_deviation": float(np.sqrt(var)), "observations": len(y)}
    return out


def print_deviation_shares(study: Path, data: Path) -> None:
    d = deviation_shares(study)
    with open(data / "uq_per_axle_differences.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["output", "group", "share_of_variance", "coefficient"])
        for q, v in d.items():
            for g, s in v["shares"].items():
                w.writerow([q, g, f"{s:.4g}", f"{v['coefficients'].get(g, float('nan')):.4g}"])
    groups = list(next(iter(d.values()))["shares"])
    print(f"\n| what sets the axle's deviation from the drive's mean | rise (sd {d['rise_K']['sd_deviation']:.2g} K) "
          f"| dN (sd {d['dN_pct']['sd_deviation']:.2g} pp) |")
    print("|---|---|---|")
    for g in sorted(groups, key=lambda g: -d["rise_K"]["shares"][g]):
        print(f"| {g} | {d['rise_K']['shares'][g]:.2f} | {d['dN_pct']['shares'][g]:.2f} |")


if __name__ == "__main__":
    main()
