"""What a result was made from: the hash of every input file and of the resolved definition.

A run records, in its results file (/scenario attribute `inputs_json`), the SHA-256 of every file its scenario
reads (the scenario itself, the vehicle file, strut files, road and speed CSVs) and of its resolved definition
(every parameter after defaults and overrides, `Prepared.resolved()`). `--resume` and a study re-run compare them
with the files as they are now (`compare`): a result is never continued or reused from inputs that changed
(the message names the file, and `--overwrite` starts again). `run_inputs` lists the files an output must not
replace (`hpsim.outputs.check_not_input`).
"""
from __future__ import annotations

import functools
import hashlib
import json
import subprocess
from pathlib import Path

from hpsim import __version__
from hpsim.errors import UserInputError
from hpsim.files import MAX_DATA_FILE_BYTES, read_regular_bytes

from vehicle.scenario.schema import resolve_path, prepare, vehicle_data


@functools.lru_cache(maxsize=1)
def code_version() -> str:
    """hpsim version, plus the git commit when running from a checkout."""
    here = Path(__file__).resolve().parent
    try:
        out = subprocess.run(["git", "describe", "--always", "--dirty"], cwd=here, capture_output=True,
                             text=True, timeout=5)
        if out.returncode == 0 and out.stdout.strip():
            return f"{__version__} ({out.stdout.strip()})"
    except (OSError, subprocess.SubprocessError):
        pass
    return __version__


def _sha256(path: Path) -> str | None:
    """SHA-256 of a regular file; None when it cannot be read (missing, not a regular file)."""
    try:
        return hashlib.sha256(read_regular_bytes(path, MAX_DATA_FILE_BYTES)).hexdigest()
    except UserInputError:
        return None


def input_files(prep) -> dict[str, Path]:
    """label -> path of every file a prepared scenario (vehicle.scenario.schema.Prepared) reads."""
    src, S = prep.source, prep.scenario
    files: dict[str, Path] = {}
    if Path(src.name).is_file():
        files["scenario"] = Path(src.name).resolve()
    try:
        files["vehicle"] = Path(vehicle_data(S, src)[1]).resolve()
    except UserInputError:
        pass
    for k, axle in enumerate(prep.vehicle.axles):
        strut = str(axle.strut)
        if strut.endswith((".yaml", ".yml")):
            files[f"strut axle{k + 1}"] = Path(strut).resolve()
    csv = getattr(prep.road_spec, "csv", None)
    if csv:
        files["road.csv"] = Path(resolve_path(str(csv), src.base_dir)).resolve()
    speed_csv = getattr(S.speed, "csv", None)
    if isinstance(speed_csv, str):
        files["speed.csv"] = Path(resolve_path(speed_csv, src.base_dir)).resolve()
    return files


def fingerprint(prep) -> dict:
    """{"files": {label: {"path", "sha256"}}, "definition_sha256"}: what `compare` checks."""
    files = {label: {"path": str(p), "sha256": _sha256(p)} for label, p in input_files(prep).items()}
    resolved = json.dumps(prep.resolved(), sort_keys=True, default=str)
    return {"files": files, "definition_sha256": hashlib.sha256(resolved.encode()).hexdigest()}


def changed(stored: dict, now: dict) -> str | None:
    """What differs between a stored fingerprint and the current one (a phrase naming the file), None if nothing."""
    now_files = now.get("files", {})
    for label, old in stored.get("files", {}).items():
        new = now_files.get(label)
        if new is None or new.get("sha256") != old.get("sha256"):
            path = old.get("path", "?")
            what = "is gone" if new is None or new.get("sha256") is None else "changed"
            return f"the {label} file {path} {what} since the results were made"
    for label, new in now_files.items():
        if label not in stored.get("files", {}):
            return f"the definition now reads the {label} file {new.get('path')}, which the results were not made from"
    if stored.get("definition_sha256") and stored.get("definition_sha256") != now.get("definition_sha256"):
        return "the resolved definition (parameters after defaults and overrides) changed since the results were made"
    return None


def compare(stored_json: str | None, prep, out, action: str = "resume") -> None:
    """Refuse (UserInputError naming the file) to `action` results in `out` whose inputs changed; results written
    before hashes were recorded (no stored fingerprint) pass."""
    if not stored_json:
        return
    try:
        stored = json.loads(stored_json)
    except ValueError:
        return
    why = changed(stored, fingerprint(prep))
    if why:
        raise UserInputError(f"{out}: cannot {action}: {why}; the result would mix two definitions. Start again "
                             "with --overwrite (or write to another output)")


def run_inputs(src, prep=None) -> list[Path]:
    """The input files of a run of scenario source `src` (the scenario, vehicle, strut, road and speed files); a
    scenario that cannot be prepared gives its own file only (its error is reported where it is prepared).
    prep: `src` already prepared (None: prepared here)."""
    files = [Path(src.name).resolve()] if Path(src.name).is_file() else []
    try:
        files += list(input_files(prep if prep is not None else prepare(src)).values())
    except UserInputError:
        pass
    return files
