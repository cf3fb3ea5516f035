"""Tables of docs/validation.md §8 "The mileage prediction with per-axle priors and measurement models" from
an `hpsim uq` study of scenarios/mileage_106km_uq.yaml:

    hpsim uq scenarios/mileage_106km_uq.yaml --method lhs --samples 40 --workers 2 -o results/mileage_uq
    python docs/scripts/uq_per_axle_table.py results/mileage_uq [--data docs/data]

Writes <data>/uq_per_axle_readings.csv (per axle and instrument: the nominal prediction, the model's 5/50/95 %
and the 5/50/95 % of what the instrument would read after minus before the drive; `hpsim validate STUDY`) and
<data>/uq_per_axle_spread.csv (what sets the axle-to-axle spread of the rise and of dN: per prior, grouped
over its per-axle draws, the share of the spread's rank variance a linear regression on the group's ranks
explains, adjusted R^2; and the per-parameter Spearman correlations), and prints both as Markdown tables.
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


if __name__ == "__main__":
    main()
