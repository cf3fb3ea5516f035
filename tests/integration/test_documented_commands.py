"""Every documented command runs as a reader would run it: README.md's set-up and tour blocks, then the
commands of each docs/*.md page, in order, in a copy of the repository with an empty compile cache; any
non-zero exit fails.

A page's commands run in a fresh copy of the repository, top to bottom, so a page must make the files its
later commands read. A file a page shows as a block marked `<!-- worked-example: NAME -->` is written
where it appears. Synopsis lines (placeholders in capitals, options in brackets) and messages quoted in a
block are not commands. Where a documented command is a study of hours, it runs shortened, as SHORTENED
says and why; the set-up command's install runs as `.ci/run` (the same fresh virtual environment)."""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.helpers import REPO

pytestmark = pytest.mark.slow

SETUP_HEADING, TOUR_HEADING = "## Install and run", "## A short tour"
# parts of the README's set-up command that CI has already run in this environment (.ci/run: the same fresh
# virtual environment and install); the main job after them runs here
INSTALL_PARTS = re.compile(r"^(python3 -m venv\b|\. \.venv/bin/activate$|pip install\b)")
# a synopsis, not a command: a placeholder in capitals (SCENARIO.yaml, DIR, FILE) or an optional part
SYNOPSIS = re.compile(r"\b[A-Z]{3,}[A-Z_]*\b|\s\[|\.\.\.")
COMMAND = re.compile(r"^(hpsim|python|cat)\s")
# commands that need a program hpsim does not install: not run where it is missing (said in the log)
NEEDS_PROGRAM = {"drive.mp4": "ffmpeg"}
WORKED_EXAMPLE = re.compile(r"<!-- worked-example: (\S+) -->\n```\w*\n(.*?)```", re.S)

# the 106 km studies that docs/validation.md reproduces (hours on 2 cores) run on shortened scenarios: the
# same commands, the full-mode scenarios cut to 2 km, the multiscale ones to 16 km (three windows of their
# 5.3 km spacing, the fewest the mode accepts)
SHORT_DISTANCE = {"mileage_106km.yaml": "2 km", "mileage_106km_compensated.yaml": "2 km",
                  "mileage_106km_variable_speed.yaml": "2 km", "mileage_106km_multiscale.yaml": "16 km",
                  "mileage_106km_uq.yaml": "16 km", "mileage_106km_time_parallel.yaml": "3 km"}
SHORTENED = {
    # documented command (its start) -> (what runs instead, why)
    "hpsim calibrate scenarios/mileage_106km.yaml --target-rise 54K": (
        "hpsim calibrate scenarios/quick_demo.yaml --target-rise 4K --tolerance 0.2K",
        "five drives of 106 km; 54 K is not the shortened scenario's rise: the tour's calibration, the same code"),
    "hpsim uq scenarios/mileage_106km_uq.yaml --method lhs --samples 40": (
        "hpsim uq scenarios/mileage_106km_uq.yaml --method lhs --samples 4 --workers 2 -o results/mileage_uq",
        "41 drives of 106 km (minutes to an hour): four drives of the same study"),
    "hpsim uq scenarios/mileage_106km_uq.yaml --groups section --samples 8": (
        "hpsim uq scenarios/mileage_106km_uq.yaml --groups section --samples 2 --workers 2 --yes "
        "-o results/mileage_uq_sobol --parameters 'vehicle.heat.air_speed_ratio*,scenario.*'",
        "65 drives of 106 km: the same design with two groups and N = 2"),
}


@dataclass
class Step:
    where: str                  # file:line
    command: str                # what runs (a shell command)
    why: str = ""               # why it differs from the documented command, if it does


def _blocks(text: str):
    """(line number, block text) of each indented code block of a Markdown text (fenced blocks are data)."""
    lines, i = text.splitlines(), 0
    while i < len(lines):
        if lines[i].startswith("    ") and (i == 0 or not lines[i - 1].strip()):
            start, block = i + 1, []
            while i < len(lines) and (lines[i].startswith("    ") or not lines[i].strip()):
                block.append(lines[i][4:])
                i += 1
            yield start, "\n".join(block).rstrip()
        i += 1


def commands(block: str):
    """(offset, command) of each command of a block: continuation lines joined, here-documents kept whole,
    synopses and quoted messages left out."""
    lines, i = block.splitlines(), 0
    while i < len(lines):
        line, offset = lines[i].strip(), i
        i += 1
        while line.endswith("\\") and i < len(lines):
            line = line[:-1] + " " + lines[i].strip()
            i += 1
        heredoc = re.search(r"<<'(\w+)'", line)
        if heredoc:
            body = []
            while i < len(lines) and lines[i].strip() != heredoc.group(1):
                body.append(lines[i])
                i += 1
            i += 1
            line = "\n".join([line, *body, heredoc.group(1)])
        first = line.split("\n")[0]
        if not COMMAND.match(first) or re.match(r"^hpsim [\w ]+:", first) or (not heredoc and SYNOPSIS.search(
                first.split("#")[0])):
            continue
        yield offset, line


def _section(text: str, heading: str) -> str:
    start = text.index(heading)
    end = text.find("\n## ", start + 1)
    return text[start:end if end > 0 else None]


def readme_steps() -> list[Step]:
    """The set-up command (less the install CI has run) and the tour, in order."""
    text = (REPO / "README.md").read_text(encoding="utf-8")
    steps = []
    setup = _section(text, SETUP_HEADING)
    main_job = next(b for _, b in _blocks(setup) if ".[all]" in b)
    parts = [p.strip() for p in main_job.split("&&")]
    steps.append(Step("README.md set-up", " && ".join(p for p in parts if not INSTALL_PARTS.match(p)),
                      "the install is .ci/run's, in the same fresh virtual environment"))
    for line, block in _blocks(_section(text, TOUR_HEADING)):
        steps += [Step(f"README.md:{line + k}", c) for k, c in commands(block)]
    return steps


def page_steps(page: Path) -> list[Step]:
    """A docs page's commands, and the worked-example files it shows, in the order they appear."""
    text = page.read_text(encoding="utf-8")
    events = [(m.start(), Step(f"{page.name}:{text.count(chr(10), 0, m.start()) + 1}",
                               f"cat > {m.group(1)} <<'END_OF_EXAMPLE'\n{m.group(2)}END_OF_EXAMPLE"))
              for m in WORKED_EXAMPLE.finditer(text)]
    offsets = [0]
    for line in text.splitlines(keepends=True):
        offsets.append(offsets[-1] + len(line))
    for line, block in _blocks(text):
        for k, c in commands(block):
            short = next(((run, why) for doc, (run, why) in SHORTENED.items() if c.startswith(doc)), None)
            step = Step(f"{page.name}:{line + k}", short[0] if short else c, short[1] if short else "")
            events.append((offsets[line - 1 + k], step))
    return [s for _, s in sorted(events, key=lambda e: e[0])]


def _workspace(tmp_path: Path, name: str) -> Path:
    """A copy of the repository's files a reader has after a clone (no caches, no virtual environment)."""
    work = tmp_path / name
    shutil.copytree(REPO, work, ignore=shutil.ignore_patterns(".git", ".venv", ".hpsim_cache", "__pycache__",
                                                            "*.egg-info", ".pytest_cache", "results"))
    return work


def _shorten_scenarios(work: Path) -> None:
    for name, distance in SHORT_DISTANCE.items():
        path = work / "scenarios" / name
        text, n = re.subn(r"(?m)^distance: .*$", f"distance: {distance}", path.read_text())
        assert n == 1, f"{name}: no top-level distance to shorten"
        path.write_text(text)


def _run(steps: list[Step], work: Path, env: dict, log: list) -> None:
    for step in steps:
        program = next((prog for word, prog in NEEDS_PROGRAM.items() if word in step.command), None)
        if program and shutil.which(program) is None:
            log.append((step.where, 0.0, f"not run: {program} is not installed"))
            continue
        t0 = time.perf_counter()
        p = subprocess.run(["bash", "-c", f"set -eo pipefail\n{step.command}"], cwd=work, env=env,
                           capture_output=True, text=True, timeout=1800)
        log.append((step.where, time.perf_counter() - t0, step.command.split("\n")[0][:90]))
        assert p.returncode == 0, (f"{step.where}: exit {p.returncode}: {step.command}\n"
                                   f"{p.stderr[-3000:]}\n{p.stdout[-1500:]}")


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    """An empty compile cache shared by every page (the first command compiles, as on a fresh machine), and
    this environment's hpsim and python first on the PATH."""
    cache = tmp_path_factory.mktemp("empty_cache")
    bin_dir = str(Path(sys.executable).parent)
    return {**os.environ, "HPSIM_CACHE": str(cache), "PATH": bin_dir + os.pathsep + os.environ.get("PATH", ""),
            "MPLBACKEND": "Agg"}


def test_the_commands_are_found_as_a_reader_would_read_them():
    block = ("hpsim run a.yaml -o a.h5   # a comment\nhpsim run SCENARIO.yaml [-o out.h5]\n"
             "cat > s.yaml <<'END'\nbase: a.yaml\nEND\nhpsim uq a.yaml --samples 2 \\\n    --workers 2\n"
             "hpsim run: error: x.yaml: a quoted message\n")
    found = [c for _, c in commands(block)]
    assert found == ["hpsim run a.yaml -o a.h5   # a comment", "cat > s.yaml <<'END'\nbase: a.yaml\nEND",
                     "hpsim uq a.yaml --samples 2  --workers 2"]
    steps = readme_steps()
    assert steps[0].command.startswith("hpsim run scenarios/mileage_106km.yaml")
    # every command line of the tour is found (a here-document is one command)
    tour = _section((REPO / "README.md").read_text(encoding="utf-8"), TOUR_HEADING)
    assert len(steps) - 1 == len(re.findall(r"(?m)^    (?:hpsim|python|cat) ", tour))


def test_the_set_up_installs_what_the_tour_uses_and_ci_runs_the_readme_s_test_command():
    import tomllib

    text = (REPO / "README.md").read_text(encoding="utf-8")
    setup = _section(text, SETUP_HEADING)
    blocks = [b for _, b in _blocks(setup)]
    assert any('pip install -e ".[all]"' in b and "python3 -m venv" in b for b in blocks), blocks
    extras = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    tour_extras = {"report", "crg", "fmu", "xarray", "mdf", "dask"}
    assert set(extras["all"]) >= {d for e in tour_extras for d in extras[e]}
    assert set(extras["test"]) >= set(extras["all"])          # CI's install covers the set-up's
    test_command = next(b for b in blocks if "pytest" in b)
    ci = (REPO / ".ci" / "run").read_text().strip().splitlines()[-1]
    assert ci == test_command.strip()


def test_the_readme_runs_in_order_from_an_empty_cache(tmp_path, env):
    log: list = []
    try:
        _run(readme_steps(), _workspace(tmp_path, "readme"), env, log)
    finally:
        print("\n".join(f"{w:24s} {s:7.1f} s  {c}" for w, s, c in log))


@pytest.mark.parametrize("page", sorted((REPO / "docs").glob("*.md")), ids=lambda p: p.name)
def test_each_docs_page_runs_in_order(page, tmp_path, env):
    steps = page_steps(page)
    if not steps:
        pytest.skip(f"{page.name} shows no command")     # said, not silent: a page of prose and data
    work = _workspace(tmp_path, page.stem)
    _shorten_scenarios(work)
    log: list = []
    try:
        _run(steps, work, env, log)
    finally:
        print("\n".join(f"{w:24s} {s:7.1f} s  {c}" for w, s, c in log))
