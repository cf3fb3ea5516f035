"""What `hpsim run` says (issue 20): -q only the path written, -v the stages with their times, the
compile announced with an estimate, the wall time the command's, and validity notes only where the
result may be affected (the oil data's range) or labelled for what they are (the travel bins)."""
from __future__ import annotations

import math
import os
import re
import subprocess
import sys
import time

import casadi as ca
import pytest

from struts import oil
from vehicle.numerics import codegen, compile_time
from vehicle.presentation.report import TRAVEL_NOTE
from tests.helpers import REPO

ROOT = REPO


@pytest.fixture(scope="module")
def flagship_300m(tmp_path_factory):
    """The mileage scenario (25 degC ambient, struts at 24.6-25.3 degC) over its first 300 m."""
    d = tmp_path_factory.mktemp("messages")
    text = (ROOT / "scenarios" / "mileage_106km.yaml").read_text().replace("distance: 106 km", "distance: 300 m")
    assert "distance: 300 m" in text
    (d / "m300.yaml").write_text(text)
    return d / "m300.yaml"


def _hpsim(*argv, cwd):
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "vehicle.cli", *argv], cwd=cwd, capture_output=True, text=True,
                       timeout=600)
    return p, time.perf_counter() - t0


def test_quiet_run_prints_only_the_path_written(flagship_300m):
    p, _ = _hpsim("-q", "run", flagship_300m.name, "-o", "quiet.h5", cwd=flagship_300m.parent)
    assert p.returncode == 0, p.stderr
    assert p.stdout == "quiet.h5\n" and p.stderr == ""
    assert (flagship_300m.parent / "quiet.h5").is_file()


def test_verbose_run_logs_its_stages_and_the_commands_wall_time(flagship_300m):
    p, outside_s = _hpsim("-v", "run", flagship_300m.name, "-o", "verbose.h5", "--no-progress",
                          cwd=flagship_300m.parent)
    assert p.returncode == 0, p.stderr
    stages = dict(re.findall(r"^stage ([A-Za-z :()]+?): ([0-9.]+) s$", p.stderr, re.M))
    for name in ("reading", "output checked against the inputs", "road", "build: model",
                 "compile: looked up in the cache (C generated when missing)", "compile",
                 "build: drive (the compile included)", "drive", "summary"):
        assert name in stages, (name, p.stderr)
    # the wall time printed is the command's (process start to the last line), not the drive's
    command_s, drive_s = map(float, re.search(r"wrote verbose\.h5 \(the command ([0-9.]+) s wall, the drive "
                                              r"([0-9.]+) s\)", p.stdout).groups())
    assert drive_s <= command_s <= outside_s
    assert sum(float(stages[s]) for s in ("reading", "road", "build: drive (the compile included)", "drive")) \
        <= command_s
    # the flagship drive at 25 degC: no oil-data note (inside the range where the extrapolations agree)
    assert "oil data" not in p.stdout and "note:" not in p.stdout
    # the travel extremes say they are bin edges
    assert "travel bin lo [mm]" in p.stdout and TRAVEL_NOTE in p.stdout


def test_the_times_the_run_ends_with_are_rounded_down():
    """The command's and the drive's wall times on `hpsim run`'s last line: tenths rounded down, so that the
    printed command time never exceeds the process's own (it ends right after) and the drive stays within it."""
    from vehicle.cli.stages import tenths_down

    assert [tenths_down(s) for s in (0.0, 0.04, 1.587, 1.6, 1.65, 25.99)] == ["0.0", "0.0", "1.5", "1.6", "1.6",
                                                                           "25.9"]
    for k in range(800):
        drive_s, command_s = 0.0373 * k, 0.0373 * k + 0.0071 * (k % 29)
        assert float(tenths_down(drive_s)) <= float(tenths_down(command_s)) <= command_s


def test_the_oil_data_range_is_where_walther_and_andrade_agree_to_10_percent():
    T1, nu1, T2, nu2 = 313.15, 14e-6, 373.15, 5e-6          # the apc oil's datasheet points (struts/data/apc.yaml)
    A, B = oil.walther_coefficients(T1, nu1, T2, nu2)
    for T, nu in ((T1, nu1), (T2, nu2)):                    # both laws go through the data
        assert float(oil.walther_kinematic_viscosity(T, A, B)) == pytest.approx(nu, rel=1e-12)
        assert float(oil.andrade_kinematic_viscosity(T, T1, nu1, T2, nu2)) == pytest.approx(nu, rel=1e-12)
    lo, hi = oil.viscosity_extrapolation_range(T1, nu1, T2, nu2, 0.1)

    def gap(T):
        w = float(oil.walther_kinematic_viscosity(T, A, B))
        return abs(w - float(oil.andrade_kinematic_viscosity(T, T1, nu1, T2, nu2))) / w

    assert gap(lo) == pytest.approx(0.1, abs=1e-4) and gap(hi) == pytest.approx(0.1, abs=1e-4)
    assert lo < 298.15 < T1 and hi > T2                       # 25 degC is inside: no note on the flagship run
    assert gap(lo - 5.0) > 0.1 and gap(hi + 5.0) > 0.1       # and beyond the edges the laws drift apart


def test_a_compile_is_announced_with_an_estimate_and_its_rate_kept(tmp_path, monkeypatch, caplog):
    monkeypatch.setenv(codegen.CACHE_ENV, str(tmp_path / "cache"))
    x = ca.SX.sym("x", 3)
    fn = ca.Function(f"h20_msg_{os.getpid()}", [x], [ca.sin(x) * ca.exp(x[0])])
    caplog.set_level("INFO", logger="hpsim")
    if codegen._compiler() is None:
        pytest.skip("no C compiler")
    assert codegen.precompile([fn]) == 1
    lines = [r.getMessage() for r in caplog.records if "compiling" in r.getMessage()]
    assert len(lines) == 1 and re.fullmatch(r"compiling the vehicle model \(first run only, ~\d+ s\)", lines[0])
    cache = codegen.cache_dir()
    rate = compile_time._rate(cache)
    assert rate != compile_time.DEFAULT_BYTES_PER_S and math.isfinite(rate) and rate > 0   # measured and kept
    # the estimate is the C size over that rate, spread over the compilers that run at once
    assert compile_time.estimate_s([1000, 1000], 2, cache) == pytest.approx(1000 / rate)
    assert compile_time.estimate_s([1000, 1000], 1, cache) == pytest.approx(2000 / rate)
    caplog.clear()
    assert codegen.precompile([fn]) == 0                     # cached: nothing to say
    assert not [r for r in caplog.records if "compiling" in r.getMessage()]


def test_a_command_called_inside_a_longer_process_counts_its_time_from_its_call(monkeypatch):
    """`main` from Python (a notebook, a test) runs inside a process that has done other work: the command's wall
    time, which a study's cost preview counts as already spent, starts at the call, not at the process start."""
    from vehicle import cli
    from vehicle.cli import stages

    seen = []
    monkeypatch.setattr(cli, "_main", lambda argv: seen.append(stages.command_wall_s()) or 0)
    time.sleep(0.3)
    assert cli.main(["--version"]) == 0
    assert 0.0 <= seen[0] < 0.25
