"""Fuzz families of issue 13: malformed input, output paths and a tampered compile cache.

Every generated case runs `hpsim ...` (vehicle.cli.main) in a forked child process, so a hang is
killed at a limit of CPU time and a crash (bus error, abort) is seen as such instead of taking pytest down.
The limit is of CPU time, not wall time, so a machine loaded by other work does not fail a case.
Each case must

- exit with code 2 (user error) or 3 (simulation stopped), or 0 where the input is fine,
- print no traceback and a short message (never the whole offending input),
- finish within CASE_TIMEOUT_S of CPU time,
- write nothing outside the output path it names (the case's folder is compared before/after).

Families: long quantity strings, YAML alias bombs, encodings, deep nesting, duplicate keys, output
paths, resource limits, calibrate arguments, the compile cache. The results-file families (damaged
HDF5, resume, kill during the final write, full disk, locks) have their own section at the end.
"""
from __future__ import annotations

import io
import json
import logging
import os
import random
import resource
import select
import signal
import sys
import traceback
import warnings
from dataclasses import dataclass
from pathlib import Path

import pytest
from tests.helpers import REPO

VEHICLE_FILE = REPO / "vehicle" / "data" / "apc_8x8.yaml"
STRUT_FILE = REPO / "struts" / "data" / "apc.yaml"
RIG_CSV = REPO / "struts" / "data" / "apc_rig_energy.csv"
ROAD_SPEC = REPO / "terrain" / "data" / "example_road.yaml"

CASE_TIMEOUT_S = 30.0                 # CPU seconds a case may use (RLIMIT_CPU of its child process)
WALL_BACKSTOP_FACTOR = 6.0            # a case blocked without using CPU (a FIFO, a lock) is killed after this many
                                      # times its CPU limit in wall time
MEMORY_LIMIT_BYTES = 3 << 30          # a child allocating more than this fails instead of swapping the machine
MAX_MESSAGE_CHARS = 2000              # an error message is a line or two, never the input echoed back

SCENARIO = """\
description: fuzz base case
vehicle: {name: apc_8x8}
road: {iso_class: D, seed: 3}
speed: 20 km/h
distance: 60 m
ambient_temperature: 25 degC
initial_temperatures: 25 degC
solver: {dt: 4 ms}
output: {interval: 1 s, stats_interval: 30 m}
"""

SWEEP = """\
base: base.yaml
grid:
  speed: [20 km/h]
"""

ROAD_CSV = "distance_m,left_m,right_m\n" + "".join(f"{0.05 * i:.2f},0.0,0.0\n" for i in range(200))


# --- the runner ------------------------------------------------------------------------------------
@dataclass
class Outcome:
    code: int | None          # exit code; None: killed at the CPU or wall limit or crashed
    out: str
    err: str
    timed_out: bool = False
    signal: int = 0           # the signal that ended the child (a crash), 0 if none
    value: object = None      # what a run_forked target returned
    cpu_s: float = 0.0        # the child's CPU time (user + system)


def _limit_cpu(seconds: float) -> None:
    """SIGXCPU after `seconds` of this process's CPU time, SIGKILL shortly after (a fork starts at zero)."""
    soft = max(1, int(seconds + 0.999))
    _, hard = resource.getrlimit(resource.RLIMIT_CPU)
    if hard != resource.RLIM_INFINITY and hard <= soft:
        return
    resource.setrlimit(resource.RLIMIT_CPU, (soft, soft + 5 if hard == resource.RLIM_INFINITY else hard))


def _child(target, cwd, env, w, cpu_limit_s):
    out, err = io.StringIO(), io.StringIO()
    code, value = 1, None
    try:
        _limit_cpu(cpu_limit_s)
        os.chdir(cwd)
        os.environ.update(env or {})
        _, hard = resource.getrlimit(resource.RLIMIT_AS)
        limit = _vm_bytes() + MEMORY_LIMIT_BYTES
        if hard == resource.RLIM_INFINITY or hard > limit:
            resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
        sys.stdout, sys.stderr = out, err
        for handler in logging.getLogger("hpsim").handlers:
            # a command run in this test process before (`main`) set up a handler on the stderr of its time, which
            # pytest has closed since: this child's messages go to its own stderr, as a user's command's do
            if isinstance(handler, logging.StreamHandler):
                handler.stream = err               # (not setStream: it flushes the closed stream first)
        warnings.simplefilter("default")        # printed as a user would see them, not pytest's record
        warnings.showwarning = lambda msg, cat, fname, lineno, file=None, line=None: err.write(
            warnings.formatwarning(msg, cat, fname, lineno, line))
        try:
            code, value = target()
        except SystemExit as exc:   # argparse
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        except BaseException:       # what Python would print: a traceback
            err.write(traceback.format_exc())
            code = 1
    finally:
        try:
            # stdout whole (a study's --json is a few 10 kB), stderr's last 20 kB (a runaway message is cut)
            payload = json.dumps({"code": code, "value": value, "out": out.getvalue()[-2_000_000:],
                                  "err": err.getvalue()[-20000:]}).encode()
            view = memoryview(payload)
            while view:
                n = os.write(w, view)
                view = view[n:]
        finally:
            os._exit(0)


def _vm_bytes() -> int:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")


def run_forked(target, cwd, env=None, timeout=CASE_TIMEOUT_S) -> Outcome:
    """target() -> (exit code, JSON-able value) in a forked child with cwd `cwd` and a memory limit;
    killed after `timeout` seconds of its CPU time (or WALL_BACKSTOP_FACTOR times that in wall time, for a
    child blocked without computing). stdout/stderr (warnings too) are captured."""
    import time

    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:                                    # pragma: no cover - the child
        os.close(r)
        _child(target, cwd, env, w, timeout)
    os.close(w)
    chunks, deadline, timed_out = [], time.monotonic() + WALL_BACKSTOP_FACTOR * timeout, False
    try:
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                timed_out = True
                break
            ready, _, _ = select.select([r], [], [], left)
            if not ready:
                continue
            data = os.read(r, 1 << 16)
            if not data:
                break
            chunks.append(data)
    finally:
        os.close(r)
    if timed_out:
        os.kill(pid, signal.SIGKILL)
    _, status, usage = os.wait4(pid, 0)
    cpu_s = usage.ru_utime + usage.ru_stime
    if timed_out or (os.WIFSIGNALED(status) and os.WTERMSIG(status) in (signal.SIGXCPU, signal.SIGKILL)
                     and cpu_s >= timeout):
        return Outcome(None, "", "", timed_out=True, cpu_s=cpu_s)
    if os.WIFSIGNALED(status):
        return Outcome(None, "", "", signal=os.WTERMSIG(status), cpu_s=cpu_s)
    d = json.loads(b"".join(chunks).decode())
    return Outcome(d["code"], d["out"], d["err"], value=d["value"], cpu_s=cpu_s)


def run_isolated(argv, cwd, env=None, timeout=CASE_TIMEOUT_S) -> Outcome:
    """`hpsim ARGV` (vehicle.cli.main) in a forked child, see run_forked."""

    def target():
        from vehicle import cli

        return cli.main([str(a) for a in argv]), None

    return run_forked(target, cwd, env, timeout)


@pytest.fixture(scope="module", autouse=True)
def warm_imports():
    """Import what the commands import once, here: every forked case then starts warm (fast)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: F401

    from hpsim.units import registry
    from vehicle import cli

    cli.build_parser()
    registry()
    import vehicle.presentation.plots  # noqa: F401
    import vehicle.results.run  # noqa: F401
    import vehicle.studies.sweep  # noqa: F401
    import struts.fit  # noqa: F401
    import struts.rig  # noqa: F401
    import terrain.stats  # noqa: F401


def snapshot(root: Path) -> dict:
    out = {}
    for p in sorted(root.rglob("*")):
        try:
            st = p.lstat()
        except FileNotFoundError:
            continue
        # a folder's own times change when a file is created and removed in it (a write test, a
        # lock): only what stays counts
        out[str(p.relative_to(root))] = "folder" if p.is_dir() and not p.is_symlink() else \
            (st.st_mode, st.st_size, st.st_mtime_ns)
    return out


def check_user_error(res: Outcome, *, codes=(2,), must_say: tuple[str, ...] = ()):
    assert not res.timed_out, f"no answer within the case's CPU-time limit ({res.cpu_s:.1f} s used; a hang)"
    assert not res.signal, f"crashed with signal {res.signal}"
    assert "Traceback" not in res.err, res.err[-3000:]
    assert res.code in codes, f"exit code {res.code}, expected {codes}; stderr: {res.err[-1500:]}"
    assert len(res.err) <= MAX_MESSAGE_CHARS, f"message of {len(res.err)} characters: {res.err[:300]}..."
    for word in must_say:
        assert word.lower() in res.err.lower(), f"message does not say {word!r}: {res.err}"


def _changed(before: dict, after: dict) -> set[str]:
    return {k for k in set(before) | set(after) if before.get(k) != after.get(k)}


@pytest.fixture
def case_dir(tmp_path_factory):
    """case/work (the cwd) and case/in (inputs); nothing may change unless a case names it. (Not
    tmp_path: its name is the test's, and a message naming the path would "say" the test's words.)"""
    d = tmp_path_factory.mktemp("case")
    (d / "work").mkdir()
    (d / "in").mkdir()
    return d


def run_case(case_dir: Path, argv, allowed=(), **kw) -> Outcome:
    before = snapshot(case_dir)
    res = run_isolated(argv, case_dir / "work", **kw)
    changed = _changed(before, snapshot(case_dir))
    allowed_rel = {str(Path(a).relative_to(case_dir)) if Path(a).is_absolute() else str(a) for a in allowed}
    stray = {c for c in changed if not any(c == a or c.startswith(a + os.sep) for a in allowed_rel)}
    assert not stray, f"wrote outside the named output: {sorted(stray)}"
    return res


def _base_files(d: Path) -> dict[str, Path]:
    """A valid scenario, sweep, vehicle, strut, road spec, road CSV and rig CSV in `d`."""
    files = {"scenario": d / "base.yaml", "sweep": d / "sweep.yaml", "vehicle": d / "vehicle.yaml",
             "strut": d / "strut.yaml", "road_spec": d / "road.yaml", "road_csv": d / "road.csv",
             "rig_csv": d / "rig.csv"}
    files["scenario"].write_text(SCENARIO)
    files["sweep"].write_text(SWEEP)
    files["vehicle"].write_text(VEHICLE_FILE.read_text())
    files["strut"].write_text(STRUT_FILE.read_text())
    files["road_spec"].write_text(ROAD_SPEC.read_text())
    files["road_csv"].write_text(ROAD_CSV)
    files["rig_csv"].write_text(RIG_CSV.read_text())
    return files


def command_reading(kind: str, path: Path, d: Path) -> list:
    """The hpsim command that reads a file of this kind (inputs live in `d`)."""
    if kind == "scenario":
        return ["run", path, "-o", d.parent / "work" / "out.h5", "--no-progress"]
    if kind == "sweep":
        return ["sweep", path, "-o", d.parent / "work" / "sweep_out", "--workers", "1"]
    if kind == "vehicle":
        return ["vehicle", "equilibrium", "--vehicle", path]
    if kind == "strut":
        return ["strut", "static", "--strut", path, "--load", "40kN"]
    if kind == "road_spec":
        return ["road", "generate", "--spec", path, "-o", d.parent / "work" / "road_out.csv"]
    if kind == "road_csv":
        return ["road", "psd", path]
    if kind == "rig_csv":
        return ["strut", "fit", "--data", path, "--fit", "F0"]
    raise AssertionError(kind)


YAML_KINDS = ("scenario", "sweep", "vehicle", "strut", "road_spec")
ALL_KINDS = YAML_KINDS + ("road_csv", "rig_csv")


def test_a_case_is_limited_by_its_cpu_time_not_by_the_wall_clock(tmp_path):
    """A child that computes past its limit is stopped there; one that waits longer than its limit in wall time
    (as on a loaded machine, where the CPU goes to others) is not."""
    import time

    def spin():
        while True:
            pass

    def wait():
        time.sleep(2.5)
        return 0, "done"

    busy = run_forked(spin, tmp_path, timeout=1.0)
    assert busy.timed_out and 1.0 <= busy.cpu_s < WALL_BACKSTOP_FACTOR
    idle = run_forked(wait, tmp_path, timeout=1.0)
    assert not idle.timed_out and (idle.code, idle.value) == (0, "done") and idle.cpu_s < 1.0


# --- family: long and crafted quantity strings -----------------------------------------------------
CRAFTED = {
    "digits": "1" * 100_000 + " m",
    "unit_name": "1 " + "m" * 30_000,
    "power_tower": "10**10**10 m",
    "parentheses": "(" * 3000 + "1" + ")" * 3000 + " m",
}
SCENARIO_FIELDS = {
    "speed": "speed: {}",
    "distance": "distance: {}",
    "ambient_temperature": "ambient_temperature: {}",
    "initial_temperatures": "initial_temperatures: [{}]",
    "solver.dt": "solver: {{dt: {}}}",
    "output.interval": "output: {{interval: {}}}",
    "output.stats_interval": "output: {{stats_interval: {}}}",
}
CLI_FIELDS = {
    "strut static --load": ["strut", "static", "--load", "{}"],
    "strut static --p0": ["strut", "static", "--load", "40kN", "--p0", "{}"],
    "strut static --temperature": ["strut", "static", "--load", "40kN", "--temperature", "{}"],
    "strut cycle --amplitude": ["strut", "cycle", "--amplitude", "{}", "--frequency", "1Hz", "--mean", "115mm"],
    "road generate --length": ["road", "generate", "--class", "D", "--length", "{}", "-o", "r.csv"],
    "road generate --spacing": ["road", "generate", "--class", "D", "--length", "1km", "--spacing", "{}",
                                "-o", "r.csv"],
    "vehicle equilibrium --temperatures": ["vehicle", "equilibrium", "--temperatures", "{}"],
}


def _replace_line(text: str, key: str, line: str) -> str:
    top = key.split(".")[0]
    lines = [ln for ln in text.splitlines() if not ln.startswith(top + ":")]
    return "\n".join(lines + [line]) + "\n"


@pytest.mark.parametrize("what", list(CRAFTED))
@pytest.mark.parametrize("field", list(SCENARIO_FIELDS))
def test_long_strings_in_scenario(case_dir, field, what):
    value = CRAFTED[what]
    text = _replace_line(SCENARIO, field, SCENARIO_FIELDS[field].format(f'"{value}"'))
    (case_dir / "in" / "s.yaml").write_text(text)
    res = run_case(case_dir, ["run", case_dir / "in" / "s.yaml", "-o", "out.h5", "--no-progress"])
    check_user_error(res, must_say=(field.split(".")[-1],))


@pytest.mark.parametrize("what", list(CRAFTED))
@pytest.mark.parametrize("field", list(CLI_FIELDS))
def test_long_strings_on_the_command_line(case_dir, field, what):
    argv = [a.format(CRAFTED[what]) if a == "{}" else a for a in CLI_FIELDS[field]]
    res = run_case(case_dir, argv)
    check_user_error(res, must_say=(field.split()[-1],))


# --- family: YAML alias bombs (and aliases at all) ------------------------------------------------
BOMB = "\n".join(["l0: &l0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]"] +
                 [f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 9)}]" for i in range(1, 10)])


def _with_bomb(kind: str, text: str, small: bool) -> str:
    """`text` with one key's value replaced by an alias (of a billion-laughs bomb, or of a small mapping)."""
    anchors = "x: &small {a: 1}\n" if small else BOMB + "\n"
    ref = "*small" if small else "*l9"
    key = "waviness" if kind == "road_spec" else "description"
    lines = [ln for ln in text.splitlines() if not ln.startswith(key + ":")]
    return _hidden(anchors) + "\n".join(lines) + f"\n{key}: {ref}\n"


def _hidden(anchors: str) -> str:
    """Anchor definitions placed under a key of their own (itself unknown: the alias must be refused first)."""
    return "anchors:\n" + "".join("  " + ln + "\n" for ln in anchors.splitlines())


@pytest.mark.parametrize("size", ["bomb", "small"])
@pytest.mark.parametrize("kind", YAML_KINDS)
def test_alias_bombs(case_dir, kind, size):
    files = _base_files(case_dir / "in")
    path = files[kind]
    path.write_text(_with_bomb(kind, path.read_text(), size == "small"))
    res = run_case(case_dir, command_reading(kind, path, case_dir / "in"))
    check_user_error(res, must_say=("alias",))


# --- family: files that are not UTF-8 text --------------------------------------------------------
def _encoded(kind: str, text: str, how: str) -> bytes:
    if how == "utf16":
        return text.encode("utf-16")
    if how == "latin1":
        return ("# Straße, München, café\n" + text).encode("latin-1")
    if how == "garbage":
        rng = random.Random(13 + ALL_KINDS.index(kind))
        return bytes(rng.randrange(256) for _ in range(4096))
    raise AssertionError(how)


@pytest.mark.parametrize("how", ["utf16", "latin1", "garbage"])
@pytest.mark.parametrize("kind", ALL_KINDS)
def test_encodings(case_dir, kind, how):
    files = _base_files(case_dir / "in")
    path = files[kind]
    path.write_bytes(_encoded(kind, path.read_text(), how))
    res = run_case(case_dir, command_reading(kind, path, case_dir / "in"))
    check_user_error(res, must_say=(path.name,))
    assert "\x00" not in res.err and "\ufffd" not in res.err


# --- family: deeply nested YAML -------------------------------------------------------------------
NESTING = {
    "flow_lists": "[" * 20_000 + "]" * 20_000,
    "flow_mappings": "{a: " * 20_000 + "1" + "}" * 20_000,
}


@pytest.mark.parametrize("style", list(NESTING))
@pytest.mark.parametrize("kind", YAML_KINDS)
def test_deep_nesting(case_dir, kind, style):
    files = _base_files(case_dir / "in")
    path = files[kind]
    path.write_text(f"description: {NESTING[style]}\n" + path.read_text())
    res = run_case(case_dir, command_reading(kind, path, case_dir / "in"))
    check_user_error(res, must_say=(path.name, "nest"))


# --- family: duplicate keys -----------------------------------------------------------------------
DUPLICATES = {
    # kind, key, how to duplicate it (appended line(s)), line number of the second occurrence
    "scenario top level": ("scenario", "speed", "speed: 30 km/h\n"),
    "scenario nested": ("scenario", "dt", "solver: {dt: 4 ms, dt: 2 ms}\n"),
    "sweep": ("sweep", "base", "base: other.yaml\n"),
    "vehicle": ("vehicle", "track", "track: 2.4 m\n"),
    "strut": ("strut", "layout", "layout: separated\n"),
    "road spec": ("road_spec", "seed", "seed: 8\n"),
}


@pytest.mark.parametrize("case", list(DUPLICATES))
def test_duplicate_keys(case_dir, case):
    kind, key, extra = DUPLICATES[case]
    files = _base_files(case_dir / "in")
    path = files[kind]
    text = path.read_text()
    if case == "scenario nested":
        text = "\n".join(ln for ln in text.splitlines() if not ln.startswith("solver:")) + "\n"
    text = text.rstrip("\n") + "\n" + extra
    line = text.count("\n")            # the appended line is the last one
    path.write_text(text)
    res = run_case(case_dir, command_reading(kind, path, case_dir / "in"))
    check_user_error(res, must_say=("duplicate", repr(key), f"{path.name}:{line}"))


# --- family: output paths -------------------------------------------------------------------------
@pytest.fixture(scope="module")
def results_file(tmp_path_factory):
    """One tiny finished drive (60 m) for the plot/compare cases."""
    d = tmp_path_factory.mktemp("fuzz_results")
    (d / "base.yaml").write_text(SCENARIO)
    res = run_isolated(["run", d / "base.yaml", "-o", d / "r.h5", "--no-progress"], d, timeout=300)
    assert res.code == 0, res.err
    return d / "r.h5"


def _readonly_dir(case_dir: Path) -> Path:
    """A directory nobody may create files in: chmod 0555, or for root (who ignores modes) /sys."""
    if os.geteuid() == 0:
        return Path("/sys")
    d = case_dir / "readonly"
    d.mkdir()
    d.chmod(0o555)
    return d


def _writers(results: Path | None, d: Path) -> dict:
    """command name -> (argv with {} for the output path, allowed suffix)"""
    strut_cycle = ["strut", "cycle", "--amplitude", "10mm", "--frequency", "1Hz", "--mean", "115mm", "--cycles", "1"]
    return {
        "run -o": (["run", d / "in" / "base.yaml", "-o", "{}", "--no-progress"], ".h5"),
        "plot -o": (["plot", results, "-o", "{}"], ".png"),
        "compare --plot": (["compare", results, results, "--plot", "{}"], ".png"),
        "strut characteristic --plot": (["strut", "characteristic", "--plot", "{}"], ".png"),
        "strut characteristic --csv": (["strut", "characteristic", "--csv", "{}"], ".csv"),
        "strut cycle --plot": ([*strut_cycle, "--plot", "{}"], ".png"),
        "strut cycle --csv": ([*strut_cycle, "--csv", "{}"], ".csv"),
        "strut fit --write": (["strut", "fit", "--data", RIG_CSV, "--fit", "F0", "--write", "{}"],
                              ".yaml"),
        "strut gas --plot": (["strut", "gas", "--temperatures", "300K", "--plot", "{}"], ".png"),
        "road generate -o": (["road", "generate", "--class", "D", "--length", "200m", "-o", "{}"], ".csv"),
        "road plot -o": (["road", "plot", "--class", "D", "--length", "200m", "-o", "{}"], ".png"),
        "road psd --plot": (["road", "psd", "--class", "D", "--length", "200m", "--plot", "{}"], ".png"),
        "sweep -o": (["sweep", d / "in" / "sweep.yaml", "-o", "{}", "--workers", "1"], ""),
    }


WRITERS = list(_writers(None, Path(".")))
PLOTTERS = [w for w in WRITERS if w.endswith("--plot") or w in ("plot -o", "road plot -o")]


def _output_case(case_dir, results_file, writer, target):
    _base_files(case_dir / "in")
    argv, _ = _writers(results_file, case_dir)[writer]
    argv = [target if a == "{}" else a for a in argv]
    return run_case(case_dir, argv)


@pytest.mark.parametrize("writer", WRITERS)
def test_output_in_readonly_directory(case_dir, results_file, writer):
    suffix = _writers(None, case_dir)[writer][1]
    target = _readonly_dir(case_dir) / f"hpsim_fuzz_out{suffix}"
    res = _output_case(case_dir, results_file, writer, target)
    check_user_error(res, must_say=(str(target),))
    assert not target.exists()


@pytest.mark.parametrize("writer", [w for w in WRITERS if w != "sweep -o"])
def test_output_is_a_directory(case_dir, results_file, writer):
    target = case_dir / "work" / "a_folder"
    target.mkdir()
    res = _output_case(case_dir, results_file, writer, target)
    check_user_error(res, must_say=(str(target), "director"))


@pytest.mark.parametrize("writer", WRITERS)
def test_output_below_a_file(case_dir, results_file, writer):
    (case_dir / "work" / "plain_file").write_text("x")
    suffix = _writers(None, case_dir)[writer][1]
    target = case_dir / "work" / "plain_file" / f"out{suffix}"
    res = _output_case(case_dir, results_file, writer, target)
    check_user_error(res, must_say=("plain_file",))


def test_sweep_output_is_an_existing_file(case_dir, results_file):
    target = case_dir / "work" / "sweep_out"
    target.write_text("not a folder")
    res = _output_case(case_dir, results_file, "sweep -o", target)
    check_user_error(res, must_say=(str(target), "not a folder"))


@pytest.mark.parametrize("writer", PLOTTERS)
def test_plot_extension_unknown(case_dir, results_file, writer):
    target = case_dir / "work" / "figure.xyz"
    res = _output_case(case_dir, results_file, writer, target)
    check_user_error(res, must_say=(".xyz", "png"))


# --- family: resource limits ----------------------------------------------------------------------
RESOURCES = {
    "strut cycle --cycles huge": ["strut", "cycle", "--amplitude", "10mm", "--frequency", "1Hz", "--mean", "115mm",
                                  "--cycles", str(10 ** 12)],
    "strut cycle many cases": ["strut", "cycle", "--amplitude", ",".join(["10mm"] * 2000), "--frequency", "1Hz",
                               "--mean", "115mm", "--cycles", "100"],
    "road generate --spacing tiny": ["road", "generate", "--class", "D", "--length", "20km", "--spacing", "1nm",
                                     "-o", "r.csv"],
    "road psd --spacing tiny": ["road", "psd", "--class", "D", "--length", "20km", "--spacing", "1um"],
    "road generate long and fine": ["road", "generate", "--class", "D", "--length", "4000km", "--spacing", "1mm",
                                    "-o", "r.csv"],
}


@pytest.mark.parametrize("case", list(RESOURCES))
def test_resource_limits(case_dir, case):
    res = run_case(case_dir, RESOURCES[case])
    check_user_error(res, must_say=("at most",))


# --- family: calibrate arguments ------------------------------------------------------------------
@pytest.mark.parametrize("tolerance", ["0K", "-1K", "0 delta_degC"])
def test_calibrate_tolerance(case_dir, tolerance):
    _base_files(case_dir / "in")
    res = run_case(case_dir, ["calibrate", case_dir / "in" / "base.yaml", "--target-rise", "10K",
                              "--tolerance", tolerance])
    check_user_error(res, must_say=("--tolerance",))


# --- family: scenario limits at their stated ends -------------------------------------------------
@pytest.mark.parametrize("key,value,accepted", [
    ("speed", "150 km/h", True), ("speed", "150.001 km/h", False), ("speed", "0.36 km/h", True),
    ("distance", "20000 km", False), ("distance", "1 m", True),
])
def test_limits_agree_with_their_messages(tmp_path, key, value, accepted):
    from hpsim.errors import UserInputError
    from vehicle.scenario.schema import read_scenario_text, validate_scenario

    text = _replace_line(SCENARIO, key, f"{key}: {value}")
    src = read_scenario_text(text, "s.yaml", tmp_path)
    if accepted:
        validate_scenario(src)
    else:
        with pytest.raises(UserInputError, match=rf"s\.yaml: {key}: must be in \["):
            validate_scenario(src)


# --- family: the compile cache -------------------------------------------------------------------
def _cache_functions():
    import casadi as ca

    x = ca.SX.sym("x", 3)
    f = ca.Function("hpsim_fuzz_f", [x], [ca.sin(x) * 2 + x[0]])
    y = ca.SX.sym("y", 2)
    g = ca.Function("hpsim_fuzz_g", [y], [ca.cos(y)])      # another model: other shape, other values
    return f, g


def _compile_and_evaluate(cache: Path, which: str = "f", as_library: bool = False):
    """In a child: compile `which` through the cache (as_library: as a codegen.Library, found by its key);
    (0, {value, vm value, library, external})."""

    def target():
        import numpy as np

        from vehicle.numerics.codegen import Library, compile_function

        os.environ["HPSIM_CACHE"] = str(cache)
        fn = dict(zip("fg", _cache_functions()))[which]
        arg = np.arange(1.0, fn.size1_in(0) + 1.0)
        compiled = compile_function(Library(fn.name(), ("fuzz",), lambda: fn) if as_library else fn)
        libs = sorted(str(p) for p in cache.glob(f"{fn.name()}_*.so"))
        return 0, {"value": np.asarray(compiled(arg)).ravel().tolist(), "vm": np.asarray(fn(arg)).ravel().tolist(),
                   "libraries": libs, "external": compiled is not fn}

    return target


def _tamper(lib: Path, how: str, tmp: Path):
    data = lib.read_bytes()
    if how == "truncated":
        lib.write_bytes(data[: len(data) // 2])
    elif how == "zero_bytes":
        lib.write_bytes(b"")
    elif how == "garbage":
        lib.write_bytes(bytes(random.Random(5).randrange(256) for _ in range(len(data))))
    elif how == "foreign_library":
        # a valid library of another model (a foreign library would run its constructor on loading)
        other = tmp / "other_cache"
        res = run_forked(_compile_and_evaluate(other, "g"), tmp)
        assert res.code == 0, res.err
        lib.write_bytes(Path(res.value["libraries"][0]).read_bytes())
    else:
        raise AssertionError(how)


@pytest.mark.parametrize("as_library", [False, True], ids=["by_code", "by_key"])
@pytest.mark.parametrize("how", ["truncated", "zero_bytes", "garbage", "foreign_library"])
def test_tampered_cache_library_is_rebuilt_not_loaded(tmp_path, how, as_library):
    """Whether the library is looked up by its C (a plain function) or by its key before any C is generated (a
    codegen.Library, as the drives do): a library whose bytes are not the recorded ones is rebuilt."""
    cache = tmp_path / "cache"
    first = run_forked(_compile_and_evaluate(cache, as_library=as_library), tmp_path)
    assert first.code == 0 and first.value["external"], first.err
    lib = Path(first.value["libraries"][0])
    good = lib.read_bytes()
    _tamper(lib, how, tmp_path)
    tampered = lib.read_bytes()
    again = run_forked(_compile_and_evaluate(cache, as_library=as_library), tmp_path)
    assert not again.signal, f"crashed with signal {again.signal} loading a {how} library"
    assert again.code == 0 and "Traceback" not in again.err, again.err
    assert again.value["value"] == pytest.approx(again.value["vm"], rel=1e-12)
    assert again.value["external"], "fell back to the virtual machine instead of rebuilding"
    assert lib.read_bytes() != tampered and len(lib.read_bytes()) == len(good)     # rebuilt in place


@pytest.mark.parametrize("problem", ["writable_by_others", "owned_by_another_user"])
def test_untrusted_cache_folder_is_not_used(tmp_path, problem):
    cache = tmp_path / "shared_cache"
    cache.mkdir()
    if problem == "writable_by_others":
        cache.chmod(0o777)
    else:
        if os.geteuid() != 0:
            pytest.skip("needs root to give the folder to another user")
        os.chown(cache, 65534, 65534)
    res = run_forked(_compile_and_evaluate(cache), tmp_path)
    assert res.code == 0, res.err
    assert res.value["value"] == pytest.approx(res.value["vm"], rel=1e-12) and res.value["external"]
    assert not res.value["libraries"], "compiled into (and loaded from) an untrusted folder"
    assert "compile cache" in res.err and "private" in res.err


def test_new_cache_folder_is_private(tmp_path):
    cache = tmp_path / "new" / "cache"
    res = run_forked(_compile_and_evaluate(cache), tmp_path)
    assert res.code == 0, res.err
    assert cache.stat().st_mode & 0o777 == 0o700


def test_cache_evicts_least_recently_used_beyond_its_limit(tmp_path):
    cache = tmp_path / "cache"
    cache.mkdir(mode=0o700)
    now = __import__("time").time()
    for stem, age_s in (("old_model_a", 3000), ("old_model_b", 1000)):
        for suffix, size in ((".so", 600_000), (".json", 100)):
            p = cache / f"{stem}{suffix}"
            p.write_bytes(b"\0" * size)
            os.utime(p, (now - age_s, now - age_s))
    res = run_forked(_compile_and_evaluate(cache), tmp_path, env={"HPSIM_CACHE_MAX_MB": "1"})
    assert res.code == 0, res.err
    names = sorted(p.name for p in cache.iterdir())
    assert "old_model_a.so" not in names and "old_model_a.json" not in names     # least recently used: gone
    assert "old_model_b.so" in names                                             # fits under 1 MB: kept
    assert any(n.startswith("hpsim_fuzz_f_") and n.endswith(".so") for n in names)


# --- family: Ctrl-C ------------------------------------------------------------------------------
def _hpsim_process(args, cwd, env):
    import subprocess

    from tests.helpers import hpsim_subprocess

    # a session of its own: os.killpg then does what Ctrl-C at a terminal does (the whole group)
    return hpsim_subprocess(args, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)


def _wait_for(proc, condition, timeout=120.0) -> bool:
    """Poll until condition() (or the process ended); True when the condition was met."""
    import time

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None:
        if condition():
            return True
        time.sleep(0.01)
    return False


def test_ctrl_c_while_the_model_compiles_stops(tmp_path):
    """Ctrl-C at a terminal goes to the whole foreground process group, compiler included."""
    import psutil

    (tmp_path / "s.yaml").write_text(SCENARIO)
    cache = tmp_path / "cache"          # empty: the model is compiled
    proc = _hpsim_process(["run", "s.yaml", "-o", "out.h5", "--no-progress"], tmp_path, {"HPSIM_CACHE": str(cache)})
    me = psutil.Process(proc.pid)

    def compiling():
        try:
            return any(c.name() in ("cc1", "cc1plus", "as") for c in me.children(recursive=True))
        except psutil.Error:
            return False

    assert _wait_for(proc, compiling), "the compiler never started"
    os.killpg(proc.pid, signal.SIGINT)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, (proc.returncode, err[-2000:])
    # the one line of the interrupt, after the announcement of the compile it interrupted (issue 20)
    lines = [ln for ln in err.strip().splitlines() if not ln.startswith("compiling the vehicle model")]
    assert lines == ["hpsim run: interrupted"], err[-2000:]
    assert not (tmp_path / "out.h5").exists()
    assert not list(cache.glob(".build-*")) and not list(cache.glob("*.so"))   # nothing half-built kept


def test_ctrl_c_in_the_first_second_is_one_line(tmp_path):
    """While main is still importing the commands (numpy being loaded)."""
    (tmp_path / "s.yaml").write_text(SCENARIO)
    proc = _hpsim_process(["run", "s.yaml", "-o", "out.h5", "--no-progress"], tmp_path, {})

    def importing_numpy():
        try:
            return "numpy" in Path(f"/proc/{proc.pid}/maps").read_text()
        except OSError:
            return False

    assert _wait_for(proc, importing_numpy)
    os.kill(proc.pid, signal.SIGINT)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, (proc.returncode, err[-2000:])
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err[-2000:]


def test_ctrl_c_before_the_command_is_known(monkeypatch, capsys):
    from vehicle import cli

    def interrupted():
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "build_parser", interrupted)
    assert cli.main(["run", "x.yaml"]) == 130
    assert capsys.readouterr().err == "hpsim: interrupted\n"


# --- results-file families (H1: damaged HDF5, --resume, kill during the final write, full disk, locks,
# symlinks at <out>.partial) go below this line, using run_isolated/run_case/check_user_error. ---------
