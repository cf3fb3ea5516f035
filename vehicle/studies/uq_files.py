"""The files of a UQ study folder that let it resume: the sample matrix (samples.csv, with the fingerprint of the
study that drew it) and the records of finished cases (records.jsonl, one JSON line per case)."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from hpsim.errors import UserInputError


def write_samples(path: Path, meta: dict, names: list[str], rows: list[tuple[str, np.ndarray]]) -> None:
    tmp = path.with_name(path.name + ".partial")
    with open(tmp, "w", newline="") as fh:
        fh.write("# hpsim uq sample matrix: one row per case, values in SI; the nominal case holds the files' values\n")
        for k in ("method", "samples", "seed", "groups"):
            fh.write(f"# {k}: {meta[k]}\n")
        fh.write(f"# fingerprint: {json.dumps(meta, sort_keys=True)}\n")
        w = csv.writer(fh)
        w.writerow(["case"] + names)
        for name, x in rows:
            w.writerow([name] + [f"{v:.17g}" for v in x])
    tmp.replace(path)


def read_samples(path: Path) -> tuple[dict, list[str], list[tuple[str, np.ndarray]]]:
    meta, lines = None, []
    with open(path, newline="") as fh:
        for line in fh:
            if line.startswith("# fingerprint: "):
                meta = json.loads(line[len("# fingerprint: "):])
            elif not line.startswith("#"):
                lines.append(line)
    rows = list(csv.reader(lines))
    if meta is None or not rows or rows[0][0] != "case":
        raise UserInputError(f"{path}: not a sample matrix written by hpsim uq (remove the folder to start again)")
    names = rows[0][1:]
    return meta, names, _sample_rows(path, rows[1:], len(names))


def _sample_rows(path: Path, rows: list[list[str]], n: int) -> list[tuple[str, np.ndarray]]:
    """The cases of samples.csv; a damaged row is a one-line error naming the file and line (nothing is changed)."""
    out = []
    lineno = {}
    with open(path, newline="") as fh:             # the file's line of each case (for the message)
        for k, line in enumerate(fh, start=1):
            lineno.setdefault(line.split(",", 1)[0].strip(), k)
    for r in rows:
        case = r[0] if r else ""
        where = f"{path}:{lineno.get(case, '?')}"
        try:
            values = np.array([float(v) for v in r[1:]])
        except ValueError:
            values = None
        if values is None or values.size != n or not np.all(np.isfinite(values)):
            raise UserInputError(f"{where}: case {case!r}: expected {n} finite numbers; the sample matrix is damaged "
                                 "(the study folder was left as it is): restore it, or start again in another folder (-o)")
        out.append((case, values))
    return out


def study_differences(stored: dict, asked: dict) -> list[str]:
    out = []
    for k in ("method", "samples", "seed", "groups"):
        if stored.get(k) != asked.get(k):
            out.append(f"{k} {stored.get(k)} (now {asked.get(k)})")
    if stored.get("parameters") != asked.get("parameters"):
        a, b = set(stored.get("parameters") or []), set(asked.get("parameters") or [])
        what = sorted(a ^ b)
        out.append(f"parameters or priors ({len(what)} differ, e.g. {what[0]!r})" if what else "parameter order")
    if stored.get("model") != asked.get("model"):
        out.append("the scenario, its input files (vehicle, struts, road or speed CSV) or --distance")
    return out


def read_records(path: Path) -> dict[str, dict]:
    """Finished cases of earlier runs (a line cut by a crash is ignored)."""
    out = {}
    if path.exists():
        for line in path.read_text().splitlines():
            try:
                r = json.loads(line)
            except json.JSONDecodeError:
                continue
            if isinstance(r, dict) and "case" in r:
                out[r["case"]] = r
    return out
