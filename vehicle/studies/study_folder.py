"""A study's folder (`hpsim sweep`, `hpsim uq`): one writer at a time, safe case names, no stale case reused.

- `StudyLock(folder)`: the lock file `<folder>/study.lock` (pid, host, as a run's `<out>.lock`): a second study
  writing into the same folder at once is refused, a lock whose process is gone is taken over.
- `safe_names(names)`: case names as file names: only letters, digits and `._+-`, no leading dot (never `..`),
  at most MAX_NAME_CHARS, and collision-free (case-insensitively: `a` and `A` are one file on some file systems);
  a name that would collide gets `-2`, `-3`, ...
- `check_study_kind(folder, kind)`: a folder holding another kind of study (a sweep's summary.csv, a UQ study's
  samples.csv, cases.jsonl or summary.json) is refused: its report would show only one of the two.
- `case_state(file, source)`: what a re-run does with a case's results file: "new" (none), "complete" (made from
  this very definition: skipped), "resume" (incomplete, same definition) or "changed: <why>" (made from another
  definition: the scenario text after overrides differs, or an input file or the resolved definition changed,
  vehicle.results.provenance). A changed case is never served from its old results: the study refuses with
  `--overwrite` advice, or runs it again with --overwrite.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

from hpsim.errors import UserInputError

from vehicle.results import provenance
from vehicle.results.reader import open_results
from vehicle.results.run import OutputLock
from vehicle.scenario.schema import prepare

MAX_NAME_CHARS = 120
MAX_CASES = 2000            # cases of one study (each validated up front)


class StudyLock(OutputLock):
    """`<folder>/study.lock`: one study writing into a folder at a time."""

    def __init__(self, folder: Path):
        folder = Path(folder)
        super().__init__(folder / "study")
        self.folder = folder

    def acquire(self) -> "StudyLock":
        try:
            return super().acquire()
        except UserInputError as exc:
            text = str(exc).replace(f"{self.out}: being written", f"{self.folder}: a study is being written")
            raise UserInputError(text.replace("wait for it", "wait for it (or give another folder with -o)")) from None


# the files that make a folder a study of one kind (written by vehicle.studies.sweep and vehicle.studies.uq)
STUDY_FILES = {"sweep": ("summary.csv",), "uq": ("samples.csv", "cases.jsonl", "summary.json")}


def check_study_kind(folder: str | Path, kind: str, where: str = "-o/--output-dir") -> None:
    """UserInputError when `folder` holds a study of another kind than `kind` ("sweep" or "uq")."""
    folder = Path(folder)
    for other, names in STUDY_FILES.items():
        found = next((n for n in names if (folder / n).exists()), None) if other != kind else None
        if found:
            raise UserInputError(f"{where}: {folder} holds an `hpsim {other}` study ({found}); give another folder "
                                 f"for this `hpsim {kind}`")


def safe_name(name: str) -> str:
    text = re.sub(r"[^A-Za-z0-9._+-]+", "", str(name).replace(" ", ""))
    text = text.lstrip(".-") or "case"
    return text[:MAX_NAME_CHARS]


def safe_names(names: list[str]) -> list[str]:
    """Sanitised, collision-free (case-insensitively) file names, in order."""
    out, seen = [], set()
    for name in names:
        base = safe_name(name)
        candidate, k = base, 1
        while candidate.lower() in seen or candidate.lower() == "study":
            k += 1
            candidate = f"{base[:MAX_NAME_CHARS - 6]}-{k}"
        seen.add(candidate.lower())
        out.append(candidate)
    return out


def check_case_count(n: int, where: str, what: str = "cases", advice: str = "fewer grid values or cases") -> None:
    """A study of at most MAX_CASES cases (refused before its cases are expanded)."""
    if n > MAX_CASES:
        raise UserInputError(f"{where}: {n} {what}, at most {MAX_CASES} in one study; give {advice}, or split it into "
                             "several studies")


def case_state(path: Path, source) -> str:
    """'new', 'complete', 'resume' or 'changed: <why>' for a case's results file and its definition (a
    ScenarioSource); an unreadable file is 'resume' (run_scenario reports it)."""
    path = Path(path)
    if not path.exists():
        return "new"
    try:
        with open_results(path) as r:
            sc = r.scenario_attrs
            text, inputs, status = str(sc.get("yaml", "")), sc.get("inputs_json"), r.status()
    except UserInputError:
        return "resume"
    if text != source.text:
        return "changed: its scenario (base scenario or overrides) is not the one its results were made from"
    if inputs is not None:
        why = provenance.changed(_json(inputs), provenance.fingerprint(prepare(source)))
        if why:
            return f"changed: {why}"
    return "complete" if status == "complete" else "resume"


def _json(text) -> dict:
    try:
        return json.loads(str(text))
    except ValueError:
        return {}


def refuse_changed(folder: Path, changed: list[tuple[str, str]]) -> None:
    """One line naming the first changed case and how many there are."""
    if changed:
        name, why = changed[0]
        more = f" (and {len(changed) - 1} more)" if len(changed) > 1 else ""
        raise UserInputError(f"{folder}: case {name}{more}: {why.removeprefix('changed: ')}; its old results are not "
                             "reused: run again with --overwrite to replace them, or give another folder with -o")
