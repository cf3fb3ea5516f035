"""Compare two runs' results bit for bit: every numeric dataset of two HDF5 files (or of the files of two sweep
folders), and two `hpsim report --json` outputs, leaving out what measures the machine (wall and CPU times,
dates, paths, versions).

    python benchmarks/compare_results.py BEFORE AFTER      # files, folders of files, or .json reports
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import h5py
import numpy as np

# names that hold timings, dates, paths or versions: they differ between any two runs
VOLATILE = ("wall", "_s_", "cpu", "time_s", "seconds", "date", "created", "host", "version", "path", "commit",
            "build", "compile", "integration", "speed_up", "realtime", "elapsed", "source", "file", "user", "python",
            "coarse_s", "join_s", "check_s", "stage", "cost")


def _volatile(name: str) -> bool:
    low = name.lower()
    return any(v in low for v in VOLATILE) or low.endswith("_s") and "duration" not in low and "time_s" in low


def _numeric(value) -> bool:
    return isinstance(value, (int, float, np.number, np.ndarray)) and np.asarray(value).dtype.kind in "fiub"


def _datasets(path: Path) -> dict:
    out = {}
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            if isinstance(obj, h5py.Dataset) and obj.dtype.kind in "fiub" and not _volatile(name):
                out[name] = obj[()]
                if name.endswith("slots") and "fields" in obj.parent.attrs:     # packed checkpoints: timings left out
                    keep = np.ones(obj.shape[-1], bool)
                    for field, (offset, length, _) in json.loads(obj.parent.attrs["fields"]).items():
                        keep[offset:offset + length] = not _volatile(field)
                    out[name] = out[name][..., keep]
            for key, value in obj.attrs.items():
                if not _volatile(key) and _numeric(value):
                    out[f"{name}@{key}"] = np.asarray(value)
        f.visititems(visit)
        for key, value in f.attrs.items():
            if not _volatile(key) and _numeric(value):
                out[f"@{key}"] = np.asarray(value)
    return out


def compare_h5(a: Path, b: Path) -> list[str]:
    da, db = _datasets(a), _datasets(b)
    diffs = [f"only in {a.name}: {k}" for k in sorted(set(da) - set(db))]
    diffs += [f"only in {b.name}: {k}" for k in sorted(set(db) - set(da))]
    for k in sorted(set(da) & set(db)):
        x, y = da[k], db[k]
        if x.shape != y.shape:
            diffs.append(f"{k}: shape {x.shape} != {y.shape}")
        elif not np.array_equal(x, y, equal_nan=x.dtype.kind == "f"):
            d = np.nanmax(np.abs(x.astype(float) - y.astype(float))) if x.size else 0.0
            diffs.append(f"{k}: differs, max |diff| {d:.3g}")
    return diffs


def _flatten(obj, prefix="") -> dict:
    if isinstance(obj, dict):
        out = {}
        for k, v in obj.items():
            out.update(_flatten(v, f"{prefix}.{k}" if prefix else str(k)))
        return out
    if isinstance(obj, list):
        out = {}
        for i, v in enumerate(obj):
            out.update(_flatten(v, f"{prefix}[{i}]"))
        return out
    return {prefix: obj}


def compare_json(a: Path, b: Path) -> list[str]:
    fa, fb = (_flatten(json.loads(p.read_text())) for p in (a, b))
    return [f"{k}: {fa.get(k)!r} != {fb.get(k)!r}" for k in sorted(set(fa) | set(fb))
            if not _volatile(k) and fa.get(k) != fb.get(k)]


def compare(a: Path, b: Path) -> list[str]:
    if a.is_dir():
        diffs = []
        for p in sorted(a.rglob("*")):
            if p.suffix in (".h5", ".json"):
                q = b / p.relative_to(a)
                diffs += [f"{p.relative_to(a)}: {d}" for d in (compare(p, q) if q.exists() else ["missing"])]
        return diffs
    return compare_json(a, b) if a.suffix == ".json" else compare_h5(a, b)


if __name__ == "__main__":
    found = compare(Path(sys.argv[1]), Path(sys.argv[2]))
    print("\n".join(found) if found else "identical")
    sys.exit(1 if found else 0)
