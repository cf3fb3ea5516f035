"""`hpsim run / report / compare / plot` end to end on a short drive: the HDF5 layout, the report
against the file's content, kill-and-resume and Ctrl-C-and-resume giving the result of one
uninterrupted run, and a solver failure keeping what was written."""
from __future__ import annotations

import json
import signal
import subprocess
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from tests.helpers import hpsim_subprocess, run_hpsim
from vehicle import cli

SCENARIO = """\
# short drive for the tests: 4 km of class D at 20 km/h, struts warmer at the front
description: test drive
vehicle: {name: apc_8x8}
road: {iso_class: D, seed: 5}
speed: 20 km/h
distance: 4 km
ambient_temperature: 25 degC
initial_temperatures: [40 degC, 35 degC, 30 degC, 25 degC]
compensation: {enabled: false}
solver: {dt: 4 ms}
output: {interval: 1 s, stats_interval: 0.5 km, chunk_samples: 50}   # write + checkpoint every 50 s
"""
DISTANCE_M, SPEED, STATS_M = 4000.0, 20 / 3.6, 500.0


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    d = tmp_path_factory.mktemp("run")
    (d / "drive.yaml").write_text(SCENARIO)
    return d


@pytest.fixture(scope="module")
def reference(workdir):
    """One uninterrupted run (in this process)."""
    out = workdir / "ref.h5"
    code = cli.main(["run", str(workdir / "drive.yaml"), "-o", str(out), "--no-progress"])
    assert code == 0
    return out


def _final_state(f):
    from vehicle.results.layout import read_state

    return read_state(f)


def assert_same_results(a: Path, b: Path):
    """Every stored series, statistics row, the final state and both equilibria are identical."""
    with h5py.File(a, "r") as A, h5py.File(b, "r") as B:
        for g in ("timeseries", "stats", "equilibrium/before", "equilibrium/after"):
            assert set(A[g]) == set(B[g])
            for k in A[g]:
                np.testing.assert_array_equal(A[g][k][()], B[g][k][()], err_msg=f"{g}/{k}")
        sa, sb = _final_state(A), _final_state(B)
        for k in sa:
            np.testing.assert_array_equal(sa[k], sb[k], err_msg=f"checkpoint {k}")
        for k in ("distance_km", "simulated_s", "n_samples", "n_stats"):
            assert A["summary"].attrs[k] == B["summary"].attrs[k]


def test_layout_is_netcdf4_cf_hdf5(reference, workdir):
    n = int(round(DISTANCE_M / SPEED))
    with h5py.File(reference, "r") as f:
        assert f.attrs["format"] == "hpsim-drive" and f.attrs["format_version"] == 2 and f.attrs["Conventions"] == "CF-1.8"
        sc = f["scenario"]
        assert sc.attrs["yaml"] == SCENARIO
        assert sc.attrs["hpsim_version"]
        resolved = json.loads(sc.attrs["resolved_json"])
        assert resolved["scenario"]["distance"] == DISTANCE_M
        assert resolved["vehicle"]["name"] == "apc_8x8" and resolved["road"]["iso_class"] == "D"
        assert set(resolved["struts"]) == {"axle1", "axle2", "axle3", "axle4"}
        assert len(resolved["vehicle_derived"]["gas_masses_kg"]) == 8
        ts = f["timeseries"]
        t = ts["time"][()]
        assert len(t) == n and np.allclose(np.diff(t), 1.0) and t[-1] == pytest.approx(DISTANCE_M / SPEED)
        assert ts["distance"][-1] == pytest.approx(DISTANCE_M)
        for k, shape in (("strut_temperature", (n, 8)), ("wheel_load", (n, 8)), ("axle_height_change", (n, 4)),
                         ("energy_valve", (n, 8)), ("heave_acceleration", (n,)), ("roll_acceleration", (n,))):
            assert ts[k].shape == shape
            assert ts[k].chunks is not None and ts[k].compression == "gzip" and ts[k].maxshape[0] is None
        assert [str(s) for s in ts["station"].asstr()[:2]] == ["axle1_left", "axle1_right"]
        assert ts["wheel_load"].attrs["units"] == "N" and ts["pitch_acceleration"].attrs["units"] == "rad s-2"
        st = f["stats"]
        assert st["km"].shape == (int(DISTANCE_M / STATS_M),)
        np.testing.assert_allclose(st["km"][()], np.arange(1, 9) * STATS_M / 1e3)
        np.testing.assert_allclose(st["duration"][()], STATS_M / SPEED, rtol=1e-6)
        for g in ("before", "after", "charged"):
            assert "wheel_load" in f["equilibrium"][g]
        assert f["summary"].attrs["complete"] and f["summary"].attrs["status"] == "complete"
        for k in ("distance_km", "simulated_s", "wall_s", "build_s"):
            assert k in f["summary"].attrs


def test_report_agrees_with_the_file(reference, capsys):
    assert cli.main(["report", str(reference), "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["distance_km"] == pytest.approx(DISTANCE_M / 1e3)
    assert rep["simulated_s"] == pytest.approx(DISTANCE_M / SPEED)
    assert rep["wall_s"] > 0
    assert [a["axle"] for a in rep["axles"]] == [1, 2, 3, 4] and rep["file"] == str(reference)
    with h5py.File(reference, "r") as f:
        before, after = f["equilibrium/before"], f["equilibrium/after"]
        ts = f["timeseries"]
        T_last = ts["strut_temperature"][-1]
        E_last = sum(ts[f"energy_{e}"][-1] for e in ("valve", "friction", "gas", "end_stop"))
        for k, a in enumerate(rep["axles"]):
            l, r = 2 * k, 2 * k + 1
            assert a["T_start_C"] == pytest.approx(0.5 * (before["oil_temperature"][l] + before["oil_temperature"][r]) - 273.15)
            # T_end_C is the outer surface (pyrometer), the heat network's surface node
            assert a["T_end_C"] == pytest.approx(0.5 * (T_last[l] + T_last[r]) - 273.15)
            assert a["T_surface_end_C"] == a["T_end_C"]
            oil_last, gas_last = ts["oil_temperature"][-1], f["stats/mean_gas_temperature"][-1]
            assert a["T_oil_end_C"] == pytest.approx(0.5 * (oil_last[l] + oil_last[r]) - 273.15)
            assert a["T_gas_end_C"] == pytest.approx(0.5 * (gas_last[l] + gas_last[r]) - 273.15)
            # the after-drive statics stand at the oil temperature (the gas follows it at rest)
            assert a["T_oil_end_C"] == pytest.approx(0.5 * (after["oil_temperature"][l] + after["oil_temperature"][r]) - 273.15)
            assert a["T_oil_end_C"] > a["T_end_C"]          # the heat flows from the oil out through the surface
            assert a["dh_mm"] == pytest.approx(1e3 * (after["axle_height_change"][k] - before["axle_height_change"][k]))
            N0 = 0.5 * (before["wheel_load"][l] + before["wheel_load"][r])
            N1 = 0.5 * (after["wheel_load"][l] + after["wheel_load"][r])
            assert a["N_before_daN"] == pytest.approx(N0 / 10) and a["N_after_daN"] == pytest.approx(N1 / 10)
            assert a["dN_pct"] == pytest.approx(100 * (N1 - N0) / N0)
            assert a["energy_dissipated_MJ"] == pytest.approx((E_last[l] + E_last[r]) / 1e6)    # both struts
        # physics: every strut heats (it dissipates), the before-drive state is at the initial temperatures
        assert all(a["T_end_C"] > a["T_start_C"] for a in rep["axles"])
        assert [round(a["T_start_C"], 6) for a in rep["axles"]] == [40, 35, 30, 25]
        # the dissipated energy matches the per-interval mean powers of the statistics
        st = f["stats"]
        P = sum(st[f"power_{e}"][()] for e in ("valve", "friction", "gas", "end_stop"))
        E_stats = (P * st["duration"][()][:, None]).sum(axis=0)
        np.testing.assert_allclose(E_stats, E_last, rtol=1e-6)
        # energy is additive: the axles' dissipated energies add up to the vehicle's total
        assert sum(a["energy_dissipated_MJ"] for a in rep["axles"]) == pytest.approx(rep["energy_dissipated_MJ"], rel=1e-12)
        # the total wheel load is the vehicle's weight before and after
        assert np.sum(after["wheel_load"]) == pytest.approx(np.sum(before["wheel_load"]), rel=1e-6)
    # the text table
    assert cli.main(["report", str(reference)]) == 0
    text = capsys.readouterr().out
    assert "complete" in text and "dN [%]" in text and len(text.splitlines()) >= 7


def _wait_for_samples(path: Path, proc: subprocess.Popen, n: int, timeout: float = 120.0) -> int:
    from vehicle.results.reader import open_read
    from vehicle.results.layout import valid_counts

    t0 = time.time()
    while time.time() - t0 < timeout:
        assert proc.poll() is None, "the run ended before it could be stopped"
        if path.exists():
            try:
                with open_read(path) as f:
                    done = valid_counts(f)[0]
                if done >= n:
                    return done
            except (OSError, KeyError):
                pass
        time.sleep(0.05)
    raise AssertionError("no checkpoint in time")


def test_kill_and_resume_gives_the_uninterrupted_result(reference, workdir):
    out = workdir / "killed.h5"
    p = hpsim_subprocess(["run", workdir / "drive.yaml", "-o", out, "--no-progress"],
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        _wait_for_samples(out, p, 60)
    finally:
        p.send_signal(signal.SIGKILL)
        p.wait()
    assert p.returncode == -signal.SIGKILL
    # the killed file is readable and says how far it got
    r = run_hpsim(["report", out, "--json"])
    assert r.returncode == 0, r.stderr
    rep = json.loads(r.stdout)
    assert rep["status"] != "complete" and 0 < rep["distance_km"] < DISTANCE_M / 1e3
    # resume (also from the scenario stored in the file) and compare with the uninterrupted run
    r = run_hpsim(["run", workdir / "drive.yaml", "-o", out, "--resume", "--no-progress"])
    assert r.returncode == 0, r.stderr
    assert "resuming at" in r.stderr
    assert_same_results(reference, out)
    # resuming a complete file does nothing
    r = run_hpsim(["run", workdir / "drive.yaml", "-o", out, "--resume", "--no-progress"])
    assert r.returncode == 0 and "already complete" in r.stderr


def test_ctrl_c_leaves_a_readable_resumable_file(reference, workdir):
    out = workdir / "interrupted.h5"
    p = hpsim_subprocess(["run", workdir / "drive.yaml", "-o", out], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True)
    try:
        _wait_for_samples(out, p, 60)
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 130, err
    assert "interrupted at" in err and "--resume" in err and "Traceback" not in err
    with h5py.File(out, "r") as f:            # closed cleanly: plain h5py opens it
        assert f["summary"].attrs["status"] == "interrupted"
        assert f["timeseries/time"].shape[0] >= 60
    # an existing file is not overwritten by mistake
    r = run_hpsim(["run", workdir / "drive.yaml", "-o", out, "--no-progress"])
    assert r.returncode == 2 and "--resume" in r.stderr
    # a changed scenario is not resumed into the file
    changed = workdir / "changed.yaml"
    changed.write_text(SCENARIO.replace("seed: 5", "seed: 6"))
    r = run_hpsim(["run", changed, "-o", out, "--resume", "--no-progress"])
    assert r.returncode == 2 and "differs" in r.stderr
    r = run_hpsim(["run", workdir / "drive.yaml", "-o", out, "--resume", "--no-progress"])
    assert r.returncode == 0, r.stderr
    assert_same_results(reference, out)


def test_solver_failure_stops_with_a_message_and_keeps_the_data(workdir, monkeypatch, capsys):
    from hpsim.errors import SimulationError
    from vehicle.engines.recorder import BlockRecorder

    def failing_check(self, X, t, s, *more):
        if s[-1] > 1200.0:
            raise SimulationError(f"strut axle2_left bottomed out (beyond the bump stop) at {s[-1] / 1e3:.3f} km "
                                  f"(t = {t[-1]:.1f} s)")

    monkeypatch.setattr(BlockRecorder, "check", failing_check)
    out = workdir / "failed.h5"
    code = cli.main(["run", str(workdir / "drive.yaml"), "-o", str(out), "--no-progress"])
    err = capsys.readouterr().err
    assert code == 3
    assert "axle2_left" in err and "km" in err and str(out) in err and "Traceback" not in err
    with h5py.File(out, "r") as f:
        assert f["summary"].attrs["status"] == "failed" and not f["summary"].attrs["complete"]
        assert "axle2_left" in f["summary"].attrs["error"]
        d = f["timeseries/distance"][()]
        assert 1100.0 < d[-1] <= 1200.0 + 1e-6
    monkeypatch.undo()
    assert cli.main(["report", str(out), "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["status"] == "failed" and "axle2_left" in rep["error"] and rep["axles"][0]["N_after_daN"] is None
    # the dashboard of what was done
    assert cli.main(["plot", str(out), "-o", str(workdir / "failed.png")]) == 0
    assert (workdir / "failed.png").stat().st_size > 20_000


def test_plot_and_compare(reference, workdir, capsys):
    png = workdir / "dash.png"
    assert cli.main(["plot", str(reference), "-o", str(png)]) == 0
    assert png.stat().st_size > 20_000
    import matplotlib.image as mpimg

    img = mpimg.imread(png)
    assert img.shape[0] > 500 and img.shape[1] > 800
    cmp_png = workdir / "cmp.png"
    capsys.readouterr()
    assert cli.main(["compare", str(reference), str(reference), "--json", "--plot", str(cmp_png)]) == 0
    cmp = json.loads(capsys.readouterr().out)
    assert len(cmp["runs"]) == 2 and cmp["runs"][0]["axles"] == cmp["runs"][1]["axles"]
    assert cmp_png.stat().st_size > 10_000
    assert cli.main(["compare", str(reference), str(reference)]) == 0
    text = capsys.readouterr().out
    assert "wheel load change" in text and "load shift" in text


def test_report_of_a_file_that_is_not_results(tmp_path, capsys):
    bad = tmp_path / "x.h5"
    with h5py.File(bad, "w") as f:
        f["a"] = 1
    assert cli.main(["report", str(bad)]) == 2
    assert "not an hpsim results file" in capsys.readouterr().err
    assert cli.main(["report", str(tmp_path / "missing.h5")]) == 2
