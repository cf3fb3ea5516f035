"""The tables of a UQ study folder (bands.csv, sobol.csv, ranking.csv) and its summary.json, its numbers made
JSON-safe; each written whole or not at all (hpsim.outputs.atomic_output: an interrupted write keeps the old file)."""
from __future__ import annotations

import csv
import json
import math
import re
from pathlib import Path

import numpy as np

from hpsim.outputs import atomic_output


def _split(name: str) -> tuple[str, str]:
    m = re.fullmatch(r"axle(\d+)\.(.+)", name)
    return (m.group(1), m.group(2)) if m else ("", name)


def write_bands(path: Path, summary: dict) -> Path:
    with atomic_output(path) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["output", "axle", "quantity", "unit", "p5", "p50", "p95", "nominal", "mean", "sd", "min", "max", "n"])
        for k, b in summary["bands"].items():
            axle, q = _split(k)
            w.writerow([k, axle, q, summary["units"].get(k, ""), *(_fmt(b[c]) for c in
                        ("p5", "p50", "p95", "nominal", "mean", "sd", "min", "max")), b["n"]])
    return path


def write_sobol(path: Path, table: dict) -> Path:
    with atomic_output(path) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["output", "parameter", "S1", "S1_conf", "ST", "ST_conf"])
        for k, v in table.items():
            for r in v["rows"]:
                w.writerow([k, r["parameter"], *(_fmt(r[c]) for c in ("S1", "S1_conf", "ST", "ST_conf"))])
    return path


def write_ranking(path: Path, table: dict) -> Path:
    with atomic_output(path) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["output", "parameter", "spearman", "prcc"])
        for k, v in table.items():
            for r in v["rows"]:
                w.writerow([k, r["parameter"], _fmt(r["spearman"]), _fmt(r["prcc"])])
    return path


def _fmt(v) -> str:
    return "" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{v:.6g}"


def write_summary(out_dir: Path, summary: dict) -> Path:
    """DIR/summary.json: the study's summary with non-finite numbers as null."""
    path = out_dir / "summary.json"
    with atomic_output(path) as tmp:
        tmp.write_text(json.dumps(json_safe(summary), indent=1) + "\n")
    return path


def json_safe(obj):
    if isinstance(obj, dict):
        return {k: json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, np.generic):
        return json_safe(obj.item())
    return obj
