"""Messages and exit codes on hostile input and hostile environments: negative quantities with units reach their
option's range check, numbers are printed as numbers, Python warnings are one "warning: ..." line, a bad
HPSIM_CACHE_MAX_MB is named whenever the cache is used, a read-only road store warns and the run goes on, a full
compile cache names the cache and a way out, too-short time-parallel segments are refused before anything is
compiled, a huge spacing count is refused before the grid is allocated."""
from __future__ import annotations

import errno
import logging
import os
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from hpsim.errors import UserInputError

from tests.integration.test_fuzz import case_dir, check_user_error, run_case, warm_imports  # noqa: F401

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("argv, says", [
    (["export", "fmu", "--strut", "apc", "--dt", "-1ms", "-o", "a.fmu"], "--dt: must be in [0.01, 20] ms, got -1 ms"),
    (["road", "generate", "--class", "C", "--length", "-1km", "-o", "r.csv"], "--length: length must be in (0"),
    (["animate", "r.h5", "-o", "a.gif", "--from", "-.5km"], "r.h5"),
])
def test_a_negative_quantity_with_a_unit_is_a_value(case_dir, argv, says):
    res = run_case(case_dir, argv)
    check_user_error(res, must_say=(says,))
    assert "expected one argument" not in res.err


def test_a_gas_pressure_out_of_range_is_printed_as_a_number():
    from struts.gas import _check_range, load_gas

    gas = load_gas("nitrogen")
    with pytest.raises(UserInputError) as exc:
        _check_range(np.array([1e12]), np.array([300.0]), gas)
    assert "p_Pa: 1e+12 Pa is outside" in str(exc.value) and "np.float64" not in str(exc.value)


def test_a_python_warning_is_one_line(capsys):
    from vehicle.cli import setup_logging

    with warnings.catch_warnings():
        warnings.simplefilter("always")
        setup_logging(0)
        warnings.warn("compile cache /x: writable by others; not used")
    err = capsys.readouterr().err
    assert err == "warning: compile cache /x: writable by others; not used\n"
    logging.getLogger("hpsim").handlers.clear()


# --- the cache ----------------------------------------------------------------------------------------------------
def test_a_bad_cache_size_limit_is_named_whenever_the_cache_is_used(monkeypatch, tmp_path):
    from vehicle.numerics import codegen

    monkeypatch.setenv("HPSIM_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv(codegen.CACHE_MAX_ENV, "abc")
    with pytest.raises(UserInputError, match=r"HPSIM_CACHE_MAX_MB: expected the cache size limit in MB \(>= 1\), "
                                             r"got 'abc'"):
        codegen.cache_dir()
    monkeypatch.setenv(codegen.CACHE_MAX_ENV, "50")
    assert codegen.cache_dir() == tmp_path / "cache"


def test_a_read_only_road_store_warns_once_and_the_road_is_computed(monkeypatch, tmp_path):
    from terrain import store

    cache = tmp_path / "cache"
    (cache / store.FOLDER).mkdir(parents=True, mode=0o700)
    os.chmod(cache, 0o700)
    monkeypatch.setenv("HPSIM_CACHE", str(cache))
    store._unwritable.cache_clear()

    def read_only(*args, **kwargs):
        raise PermissionError(errno.EACCES, "Permission denied")

    monkeypatch.setattr(store.tempfile, "mkdtemp", read_only)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for seed in (1, 2):
            (a,) = store.stored_arrays(store.key_of("test", seed), ["a"], lambda: [np.arange(3.0)])
            np.testing.assert_array_equal(a, np.arange(3.0))
    messages = [str(w.message) for w in caught]
    assert len(messages) == 1 and "road store" in messages[0] and "Permission denied" in messages[0]


def test_a_full_compile_cache_names_the_cache_and_a_way_out(monkeypatch, tmp_path):
    from vehicle.numerics import compiler_processes as cp

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(cp.tempfile, "mkdtemp", full)
    with pytest.raises(UserInputError) as exc:
        cp.start_build(cp.BuildJob("cc", ["-O2"], b"int x;", "sha", tmp_path, "lib"))
    text = str(exc.value)
    assert f"compile cache {tmp_path}: No space left on device" in text
    assert "HPSIM_CACHE" in text and "HPSIM_CACHE_MAX_MB" in text


def test_a_compiler_failing_on_a_full_disk_names_the_cache(tmp_path):
    """The compiler itself reports the full disk (its output cannot be written): the same message."""
    from vehicle.numerics import compiler_processes as cp

    script = tmp_path / "cc"
    script.write_text("#!/bin/sh\necho 'fatal error: error writing to /tmp/ccX.s: No space left on device' >&2\n"
                      "exit 1\n")
    script.chmod(0o755)
    build = cp.start_build(cp.BuildJob(str(script), [], b"int x;", "sha", tmp_path, "lib"))
    with pytest.raises(UserInputError, match=r"compile cache .*No space left on device \(fatal error: error writing"):
        cp.finish_build(build)
    assert not cp.RUNNING and not list(tmp_path.glob(".build-*"))


def test_compilers_started_from_any_thread_are_killed_at_exit(tmp_path):
    """A compiler started by an ensemble lane's thread is registered; the exit handler kills its process group."""
    import threading

    from vehicle.numerics import compiler_processes as cp

    script = tmp_path / "cc"
    script.write_text("#!/bin/sh\nsleep 60\n")
    script.chmod(0o755)
    started = []
    t = threading.Thread(target=lambda: started.append(
        cp.start_build(cp.BuildJob(str(script), [], b"int x;", "sha", tmp_path, "lib"))))
    t.start()
    t.join()
    proc = started[0].proc
    assert proc in cp.RUNNING and proc.poll() is None
    cp.kill_running_compilers()
    assert proc.returncode is not None and not cp.RUNNING


def test_sigterm_during_a_lanes_compile_kills_the_compiler(tmp_path):
    """An ensemble lane's thread waits for a compiler (its own session) when SIGTERM reaches the main thread: the
    compiler's process group is killed before Terminated propagates (it used to leave gcc/cc1 running)."""
    import signal
    import threading

    from hpsim.errors import Terminated
    from vehicle.engines.ensemble import run_lockstep
    from vehicle.numerics import compiler_processes as cp

    script = tmp_path / "cc"
    script.write_text("#!/bin/sh\nsleep 60\n")
    script.chmod(0o755)
    started = []

    def compile_in_lane():
        build = cp.start_build(cp.BuildJob(str(script), [], b"int x;", "sha", tmp_path, "lib"))
        started.append(build.proc)
        return {"status": "done", "error": cp.finish_build(build)}

    def raise_terminated(signum, frame):
        raise Terminated

    old = signal.signal(signal.SIGTERM, raise_terminated)
    timer = threading.Timer(1.0, lambda: os.kill(os.getpid(), signal.SIGTERM))
    try:
        timer.start()
        with pytest.raises(Terminated):
            run_lockstep(lambda make_solver: compile_in_lane(), [("case", ())], lanes=2)
    finally:
        timer.cancel()
        signal.signal(signal.SIGTERM, old)
    proc = started[0]
    proc.wait(timeout=5)
    assert proc.returncode == -signal.SIGKILL and not cp.RUNNING


# --- checks before work -----------------------------------------------------------------------------------------
def test_too_short_time_parallel_segments_are_refused_before_compiling(monkeypatch):
    from vehicle.engines import time_parallel
    from vehicle.scenario.speed import SpeedProfile

    def compiled(*args, **kwargs):
        raise AssertionError("the drive was built (compiled) before the segments were checked")

    monkeypatch.setattr(time_parallel, "Drive", compiled)
    settings = SimpleNamespace(speed=SpeedProfile.constant(20 / 3.6), distance_m=600.0)     # 108 s
    with pytest.raises(UserInputError, match=r"4 segments of a 108 s drive are 27 s each, at least 60 s"):
        time_parallel.TimeParallelDrive(None, None, settings, 4)


def test_a_crg_spacing_of_1e300_grid_points_is_refused_before_allocating(case_dir):
    pytest.importorskip("pycrg")
    crg = case_dir / "in" / "t.crg"
    crg.write_bytes((ROOT / "examples" / "track_class_C.crg").read_bytes())
    for argv in (["road", "import", crg, "-o", "x.csv", "--spacing", "1e-300m"], ["road", "psd", crg, "--spacing", "1e-300m"]):
        res = run_case(case_dir, argv)
        check_user_error(res, must_say=("grid points", "at most"))


@pytest.mark.parametrize("command", ["sweep", "uq"])
@pytest.mark.parametrize("lanes", ["1000", "0"])
def test_an_ensemble_beyond_four_vectors_is_refused_before_any_compile(case_dir, command, lanes):
    from tests.integration.test_fuzz import SCENARIO, SWEEP
    from vehicle.engines.ensemble import MAX_LANES

    d = case_dir / "in"
    (d / "base.yaml").write_text(SCENARIO)
    (d / "sweep.yaml").write_text(SWEEP)
    argv = (["sweep", d / "sweep.yaml", "-o", "out", "--yes"] if command == "sweep" else
            ["uq", d / "base.yaml", "--samples", "4", "--method", "lhs", "-o", "out", "--yes"])
    res = run_case(case_dir, [*argv, "--ensemble", lanes])
    check_user_error(res, must_say=(f"--ensemble: must be in [1, {MAX_LANES}] lanes", f"got {lanes}"))


# --- a study of vehicles with different axle counts ------------------------------------------------------------------
def test_runs_of_3_and_4_axle_vehicles_are_compared_axle_by_axle(tmp_path, monkeypatch):
    """A sweep over vehicles of 3 and 4 axles: its comparison (text, figure, HTML table) shows each vehicle's axles,
    '-' (no bar) on the axle a vehicle does not have; it used to stop the sweep with exit code 2 after every case ran.
    The 3-axle run is the 4-axle file's report cut to its first 3 axles."""
    import shutil

    from vehicle.analysis import summary
    from vehicle.presentation.plots import compare_plot
    from vehicle.presentation.report import format_compare

    four = tmp_path / "apc.h5"
    shutil.copy(ROOT / "tests" / "data" / "results_v1.h5", four)
    three = tmp_path / "truck.h5"
    shutil.copy(four, three)
    full_report = summary.report

    def report(path, *args, **kwargs):
        rep = full_report(path, *args, **kwargs)
        return {**rep, "axles": rep["axles"][:3]} if Path(path).name == "truck.h5" else rep

    monkeypatch.setattr(summary, "report", report)
    cmp = summary.compare([four, three])
    assert cmp["n_axles"] == 4 and [len(r["axles"]) for r in cmp["runs"]] == [4, 3]
    assert summary.axle_value(cmp["runs"][1], 3, "dN_pct") is None
    assert summary.axle_value(cmp["runs"][0], 3, "dN_pct") == cmp["runs"][0]["axles"][3]["dN_pct"]
    text = format_compare(cmp)
    row4 = next(line for line in text.splitlines() if line.split()[:1] == ["4"])
    assert row4.split()[-1] == "-" and row4.split()[1] != "-"
    out = compare_plot([four, three], tmp_path / "compare.png")
    assert out.stat().st_size > 10_000
    # the sweep folder's HTML report: the per-axle table of both vehicles
    from vehicle.presentation import html_report

    (tmp_path / "summary.csv").write_text(f"case,status,file,vehicle.name,distance_km\napc,done,{four},apc_8x8,0.3\n"
                                          f"truck,done,{three},truck_6x6,0.3\n")
    doc = html_report.document(tmp_path)
    table = next(t for s in doc.sections if s.title == "Comparison" for t in s.tables)
    row = next(r for r in table.rows if r[0] == "axle 4 dN [%]")
    assert row[1] != "-" and row[2] == "-"

