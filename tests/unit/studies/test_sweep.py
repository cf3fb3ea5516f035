"""`hpsim sweep`: cases in parallel processes, one HDF5 each, a summary CSV and plots; failed cases
reported without stopping the others; finished cases skipped on a re-run; and the physics the
sweep is for: pressure compensation holds the heights, so uneven strut temperatures redistribute
the wheel loads less than without it."""
from __future__ import annotations

import csv
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from vehicle import cli

# Struts start hot at axles 1 and 4 (60 degC) and at ambient at axles 2 and 3: the hot struts are
# longer and carry more load. A small heat capacity (2 kJ/K instead of 35) lets the temperatures
# move within 1.5 km. Without compensation the after-drive loads follow the uneven temperatures;
# with it (small dead band, fast loop) oil is moved until every strut is back at its charged
# deflection, so the after-drive loads return towards the charged (set-up) loads.
BASE = """\
vehicle:
  name: apc_8x8
  overrides: {heat.capacity: 2 kJ/K}
road: {iso_class: D, seed: 3}
speed: 20 km/h
distance: 1.5 km
ambient_temperature: 25 degC
initial_temperatures: [60 degC, 25 degC, 25 degC, 60 degC]
compensation: {enabled: false, dead_band: 2 mm, time_constant: 5 s, filter_time_constant: 5 s}
output: {interval: 1 s, stats_interval: 0.5 km}
"""
SWEEP = """\
base: base.yaml
grid:
  compensation.enabled: [false, true]
"""


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("sweep")
    (d / "base.yaml").write_text(BASE)
    (d / "sweep.yaml").write_text(SWEEP)
    return d


@pytest.fixture(scope="module")
def two_cases(sweep_dir):
    out = sweep_dir / "out"
    code = cli.main(["sweep", str(sweep_dir / "sweep.yaml"), "--workers", "2", "-o", str(out)])
    assert code == 0
    return out


def _summary(out: Path) -> dict:
    with open(out / "summary.csv") as fh:
        return {r["case"]: r for r in csv.DictReader(fh)}


def test_two_cases_in_parallel_give_both_results_and_the_summary(two_cases):
    rows = _summary(two_cases)
    assert set(rows) == {"c00_enabled-false", "c01_enabled-true"}
    for name, r in rows.items():
        assert r["status"] == "done" and r["error"] == ""
        assert float(r["distance_km"]) == pytest.approx(1.5)
        with h5py.File(two_cases / f"{name}.h5", "r") as f:
            assert f["summary"].attrs["complete"]
            assert f["timeseries/time"].shape[0] == 270
    assert rows["c00_enabled-false"]["compensation.enabled"] == "False"
    assert rows["c01_enabled-true"]["compensation.enabled"] == "True"
    assert (two_cases / "compare.png").stat().st_size > 10_000


def test_compensation_reduces_load_redistribution(two_cases):
    rows = _summary(two_cases)
    off, on = rows["c00_enabled-false"], rows["c01_enabled-true"]
    # same heat input: the compensation moves oil, not heat
    assert float(on["mean_temperature_rise_K"]) == pytest.approx(float(off["mean_temperature_rise_K"]), abs=1.0)
    # wheel loads after the drive against the set-up loads: compensation keeps them much closer
    assert float(on["load_shift_vs_charged_pct"]) < 0.7 * float(off["load_shift_vs_charged_pct"])
    assert float(off["load_shift_vs_charged_pct"]) > 1.0
    # and it holds the heights: after the drive the hull stands near its charged height with
    # compensation, well above it without (hot gas, constant mass and oil)
    heights = {}
    for name in rows:
        with h5py.File(two_cases / f"{name}.h5", "r") as f:
            heights[name] = np.asarray(f["equilibrium/after/axle_height_change"]) * 1e3
            oil = f["timeseries/oil_added_volume"][-1]
            if name.endswith("true"):
                assert np.any(np.abs(oil) > 1e-6)          # the levelling moved oil
            else:
                np.testing.assert_array_equal(oil, 0.0)
    assert np.max(np.abs(heights["c01_enabled-true"])) < 0.5 * np.min(heights["c00_enabled-false"])


def test_summary_csv_carries_each_case_s_ride_numbers_and_bands(two_cases):
    """The CSV's per-axle interior temperatures, weighing bands and ride numbers are the case report's values
    (vehicle.analysis.summary.report), and the band columns bracket the frictionless load change."""
    from vehicle.analysis.summary import report

    rows = _summary(two_cases)
    for name, row in rows.items():
        rep = report(two_cases / f"{name}.h5")
        for a in rep["axles"]:
            k = a["axle"]
            assert float(row[f"T_oil_end_C_axle{k}"]) == pytest.approx(a["T_oil_end_C"])
            lo, hi = float(row[f"dN_band_pct_low_axle{k}"]), float(row[f"dN_band_pct_high_axle{k}"])
            assert lo <= float(row[f"dN_pct_axle{k}"]) <= hi
        seats = rep["ride"]["seats"]
        assert seats, "the drive stores the seat filters"
        for s in seats:
            assert float(row[f"weighted_rms_acceleration_m_s2_{s['seat']}"]) == pytest.approx(
                s["weighted_rms_acceleration_m_s2"])
            assert float(row[f"vdv_m_s175_{s['seat']}"]) > 0
        dlc = [float(row[f"dynamic_load_coefficient_axle{k}"]) for k in range(1, 5)]
        assert all(0 < d < 1 for d in dlc)      # a class D road at 20 km/h: tyre loads vary, wheels stay down mostly


def test_rerun_skips_finished_cases(two_cases, sweep_dir, capsys):
    mtimes = {p.name: p.stat().st_mtime_ns for p in two_cases.glob("*.h5")}
    code = cli.main(["sweep", str(sweep_dir / "sweep.yaml"), "--workers", "2", "-o", str(two_cases)])
    assert code == 0
    assert "skipped" in capsys.readouterr().err
    assert {p.name: p.stat().st_mtime_ns for p in two_cases.glob("*.h5")} == mtimes
    assert {r["status"] for r in _summary(two_cases).values()} == {"skipped"}


def test_a_failed_case_does_not_stop_the_others(tmp_path, capsys):
    (tmp_path / "base.yaml").write_text(BASE.replace("distance: 1.5 km", "distance: 0.3 km"))
    # a strut shorter than the charged deflection cannot be charged: this case fails when it runs
    (tmp_path / "sweep.yaml").write_text("base: base.yaml\ncases:\n  - {name: short_stroke, struts: {all: "
                                         "{overrides: {geometry.stroke: 0.1 m}}}}\n  - {name: fine}\n")
    code = cli.main(["sweep", str(tmp_path / "sweep.yaml"), "--workers", "2", "-o", str(tmp_path / "out")])
    out, err = capsys.readouterr()
    assert code == 3
    assert "short_stroke" in err and "FAILED" in err and "stroke" in err
    rows = _summary(tmp_path / "out")
    assert rows["short_stroke"]["status"] == "failed" and "stroke" in rows["short_stroke"]["error"]
    assert rows["fine"]["status"] == "done"
    assert (tmp_path / "out" / "fine.h5").exists()


def test_every_case_is_validated_before_any_runs(tmp_path, capsys):
    (tmp_path / "base.yaml").write_text(BASE)
    (tmp_path / "sweep.yaml").write_text("base: base.yaml\ngrid:\n  compensation.enabled: [false, true]\n"
                                         "  road.iso_clas: [D, E]\n")
    code = cli.main(["sweep", str(tmp_path / "sweep.yaml"), "-o", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and "road.iso_clas" in err and "unknown key" in err and "case" in err
    assert not list((tmp_path / "out").glob("*.h5")) if (tmp_path / "out").exists() else True
    (tmp_path / "sweep.yaml").write_text("base: base.yaml\ngrid: {speed: [20 km/h, 20 kg]}\n")
    code = cli.main(["sweep", str(tmp_path / "sweep.yaml"), "-o", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and "speed" in err and "20 kg" in err
    (tmp_path / "sweep.yaml").write_text("base: nope.yaml\n")
    assert cli.main(["sweep", str(tmp_path / "sweep.yaml")]) == 2
    assert "nope.yaml" in capsys.readouterr().err


def test_scheduler_without_dask_is_a_clear_error(tmp_path, capsys, monkeypatch):
    """Without Dask's distributed package (made unimportable here, as where the extra is not installed) --scheduler
    says which extra to install."""
    monkeypatch.setitem(sys.modules, "distributed", None)       # `import distributed` raises ImportError
    (tmp_path / "base.yaml").write_text(BASE)
    (tmp_path / "sweep.yaml").write_text(SWEEP)
    code = cli.main(["sweep", str(tmp_path / "sweep.yaml"), "--scheduler", "tcp://127.0.0.1:8786",
                     "-o", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and 'pip install -e ".[dask]"' in err and "Traceback" not in err


# --- interrupting a sweep -----------------------------------------------------------------------------
def _start_sweep(tmp_path):
    """A two-case sweep in a child process whose drives hold after their first checkpoint until they are asked to
    stop (HPSIM_FAULT=hold_until_cancelled): both are certain to be running when the test interrupts them."""
    import subprocess

    from tests.helpers import hpsim_subprocess

    (tmp_path / "base.yaml").write_text(BASE)
    (tmp_path / "sweep.yaml").write_text("base: base.yaml\ngrid:\n  road.seed: [3, 4]\n")
    out = tmp_path / "out"
    p = hpsim_subprocess(["sweep", tmp_path / "sweep.yaml", "--workers", "2", "-o", out], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, start_new_session=True,
                         env={"HPSIM_FAULT": "hold_until_cancelled"})
    return p, out


def _running_workers(p, out, timeout=120.0) -> list[int]:
    """The worker pids, from the cases' lock files, once both cases are driving (status running)."""
    import json
    import time

    from vehicle.results.reader import open_read
    from vehicle.results.layout import valid_counts

    t0 = time.time()
    while time.time() - t0 < timeout:
        assert p.poll() is None, p.communicate()
        locks = sorted(out.glob("*.h5.lock")) if out.exists() else []
        if len(locks) == 2:
            try:
                pids = [json.loads(lk.read_text())["pid"] for lk in locks]
                counts = []
                for h5 in sorted(out.glob("*.h5")):
                    with open_read(h5) as f:
                        counts.append(valid_counts(f)[0])
                if len(counts) == 2 and min(counts) > 0:
                    return pids
            except (OSError, ValueError, KeyError):
                pass
        time.sleep(0.05)
    raise AssertionError("the sweep's cases did not start in time")


def test_kill_9_of_the_sweep_leaves_no_worker_running(tmp_path):
    import os
    import signal
    import time

    from vehicle.results.run import _pid_alive

    p, out = _start_sweep(tmp_path)
    try:
        workers = _running_workers(p, out)
        assert p.pid not in workers
        os.kill(p.pid, signal.SIGKILL)
        p.wait(timeout=30)
        t0 = time.time()
        while any(_pid_alive(w) for w in workers) and time.time() - t0 < 30:
            time.sleep(0.05)
        alive = [w for w in workers if _pid_alive(w)]
    finally:
        if p.poll() is None:
            p.kill()
        for w in workers if "workers" in locals() else []:
            if _pid_alive(w):
                os.kill(w, signal.SIGKILL)
    assert not alive, f"workers {alive} still running after the sweep was killed"


def test_ctrl_c_stops_the_sweep_with_130_and_a_command_that_continues_it(tmp_path, capsys):
    import os
    import shlex
    import signal
    import time

    p, out = _start_sweep(tmp_path)
    try:
        workers = _running_workers(p, out)
        os.killpg(p.pid, signal.SIGINT)          # Ctrl-C in a terminal: the whole process group
        _, err = p.communicate(timeout=120)
        # the parent may exit a moment before its workers have released their results files' locks: wait for
        # them, so that the continuing sweep below does not meet a live writer
        from vehicle.results.run import _pid_alive

        deadline = time.time() + 60
        while any(_pid_alive(pid) for pid in workers) and time.time() < deadline:
            time.sleep(0.05)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
    assert p.returncode == 130, err
    assert "Traceback" not in err
    line = [ln for ln in err.splitlines() if "Continue with: " in ln]
    assert line, err
    cmd = shlex.split(line[0].split("Continue with: ", 1)[1])
    assert cmd[:2] == ["hpsim", "sweep"]
    # the suggested command exists and finishes the sweep (interrupted cases resume)
    assert cli.main(cmd[1:] + ["--workers", "2"]) == 0
    assert {r["status"] for r in _summary(out).values()} == {"done"}
