"""Studies say what they cost before they start, and how far their ranking can be trusted (issue 20)."""
from __future__ import annotations

import io
import json
import os
import re
import subprocess
import sys
import time

import numpy as np
import pytest
from scipy.stats import spearmanr

from hpsim.errors import UserInputError
from vehicle import cli
from vehicle.engines.ensemble import group_size
from vehicle.numerics import codegen, compile_time, drive_rate
from vehicle.studies import confidence, cost
from tests.helpers import REPO

ROOT = REPO


@pytest.fixture
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv(codegen.CACHE_ENV, str(tmp_path / "cache"))
    return codegen.cache_dir()


def test_a_finished_drive_records_its_rate_and_a_fresh_process_s_set_up(private_cache, monkeypatch):
    monkeypatch.setattr(drive_rate, "_setup_recorded", None)        # as in a fresh process
    monkeypatch.setattr(compile_time, "compiled_s", 2.0)             # which compiled for 2 s in its set-up
    drive_rate.record("full", 0.004, 900.0, 3.0, 7.0)
    drive_rate.record("full", 0.004, 900.0, 4.5, 0.5)     # a later drive of the process: the model was in memory
    r = drive_rate.read("full")
    assert r["steps_per_s"] == pytest.approx(900.0 / 0.004 / 4.5)   # the latest rate
    assert r["build_s"] == pytest.approx(5.0)                        # the first drive's set-up, compile excluded
    assert drive_rate.read("multiscale") is None


def test_uq_list_says_how_many_drives_and_how_long(private_cache, capsys, monkeypatch):
    # the quick demo: 5 km at 20 km/h = 900 s of driving, 225,000 steps of 4 ms
    monkeypatch.setattr(drive_rate, "_setup_recorded", None)
    monkeypatch.setattr(compile_time, "compiled_s", 0.0)
    drive_rate.record("full", 0.004, 900.0, 2.25, 2.0)               # 1e5 steps/s, 2 s of set-up
    code = cli.main(["uq", str(ROOT / "scenarios" / "quick_demo.yaml"), "--list", "--samples", "16",
                     "--workers", "2", "--json"])
    listing = json.loads(capsys.readouterr().out)
    assert code == 0
    per_drive = 2.0 + 225000 / 1e5
    drives = listing["drives"]
    assert drives == 16 * (len(listing["parameters"]) + 2) + 1       # Saltelli: N (d + 2), and the nominal
    # more drives than workers: they run on ensemble lanes, as the study would run them (vehicle.engines.ensemble)
    lanes, group = group_size(None, drives, 2)
    expected = cost.drives_wall([cost.DriveCost(2.0, 225000 / 1e5)] * drives, 2, lanes=lanes, group=group)
    assert lanes > 1 and expected < drives * per_drive / (2 * cost.PARALLEL_EFFICIENCY)
    assert listing["estimated_drives_s"] == pytest.approx(expected, rel=1e-3)
    # the whole command: its start-up so far, the drives, the tables and figures (the default: nothing recorded)
    assert listing["estimated_wall_s"] > listing["estimated_drives_s"] + cost.FINISH_DEFAULT_S["hpsim uq"]
    cli.main(["uq", str(ROOT / "scenarios" / "quick_demo.yaml"), "--list", "--samples", "16", "--workers", "2"])
    text = capsys.readouterr().out
    assert re.search(rf"estimate: {drives} drives on 2 workers in lockstep groups on {lanes} ensemble lanes, "
                     r"estimated [0-9.]+ min wall \(4 s per drive", text), text
    assert "any compile the cache lacks not included" in text


def _estimate(wall_s):
    return cost.Estimate(drives=833, workers=2, per_drive_s=wall_s * 1.3 / 833, wall_s=wall_s, basis="test",
                         drives_s=wall_s)


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_a_long_study_asks_at_a_terminal_and_only_there():
    err = io.StringIO()
    with pytest.raises(UserInputError, match=r"not started \(833 drives, estimated 3 h 0 min\); give --yes"):
        cost.confirm(_estimate(3 * 3600), "hpsim uq", False, stdin=_Terminal("n\n"), stderr=err)
    assert "start 833 drives, about 3 h 0 min? [y/N]" in err.getvalue()
    cost.confirm(_estimate(3 * 3600), "hpsim uq", False, stdin=_Terminal("y\n"), stderr=io.StringIO())
    quiet = io.StringIO()
    cost.confirm(_estimate(3 * 3600), "hpsim uq", True, stdin=_Terminal(""), stderr=quiet)          # --yes
    cost.confirm(_estimate(3 * 3600), "hpsim uq", False, stdin=io.StringIO(""), stderr=quiet)      # a script
    cost.confirm(_estimate(cost.CONFIRM_ABOVE_S / 2), "hpsim uq", False, stdin=_Terminal(""), stderr=quiet)  # short
    assert quiet.getvalue() == ""


def test_a_sweep_prints_its_drives_and_estimate_before_it_starts(tmp_path):
    text = (ROOT / "scenarios" / "quick_demo.yaml").read_text().replace("distance: 5 km", "distance: 300 m")
    (tmp_path / "base.yaml").write_text(text)
    (tmp_path / "sw.yaml").write_text("base: base.yaml\ngrid: {speed: [20 km/h, 25 km/h]}\n")
    # its own cache: the rate is the one this test's probe measures, not one another test recorded
    env = {**os.environ, "HPSIM_CACHE": str(tmp_path / "cache")}
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "vehicle.cli", "sweep", "sw.yaml", "--workers", "1"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=600, env=env)
    wall_s = time.perf_counter() - t0
    assert p.returncode == 0, p.stderr
    m = re.search(r"hpsim sweep: 2 drives on 1 worker(?: in lockstep groups on \d+ ensemble lanes)?, estimated ([0-9.]+) (s|min) wall \(([0-9.]+) (s|min) per drive",
                  p.stderr)
    assert m, p.stderr
    # said before the first case started
    assert p.stderr.index("hpsim sweep: 2 drives") < p.stderr.index("[1/2]")
    estimate_s = float(m.group(1)) * (60 if m.group(2) == "min" else 1)
    assert len(re.findall(r"\[\d/2\] \S+: done in ([0-9.]+) s", p.stderr)) == 2
    # the whole command (its compile, on an empty cache, included) at a rate measured on this machine: the right
    # order of magnitude. The band is wide on purpose: the drives run under another load than the probe (a suite on
    # two workers runs a drive beside this one: 2x; a shared machine at load 15 on 2 cores: 4-8x measured);
    # benchmarks/preview_accuracy.py measures the accuracy
    assert wall_s / 8 < estimate_s < 8 * wall_s, (estimate_s, wall_s)


def test_ranking_intervals_resolve_a_real_effect_and_not_noise():
    rng = np.random.default_rng(7)
    n, d, trials = 12, 10, 300
    z = confidence.family_quantile(d)
    false_alarms = 0
    for _ in range(trials):
        X, y = rng.random((n, d)), rng.random(n)
        rho = [spearmanr(X[:, j], y).statistic for j in range(d)]
        false_alarms += any(lo > 0 or hi < 0 for lo, hi in
                            (confidence.correlation_interval(r, n, spearman=True, z=z) for r in rho))
    # at most 5 % of studies of pure noise claim any parameter (Bonferroni is conservative); 300 trials:
    # a binomial standard deviation of 1.3 %
    assert false_alarms / trials < 0.08
    X = rng.random((20, d))
    y = X[:, 0] + 0.1 * rng.standard_normal(20)
    lo, hi = confidence.correlation_interval(spearmanr(X[:, 0], y).statistic, 20, spearman=True, z=z)
    assert lo > 0


def test_the_issue_s_ranking_of_8_cases_over_50_parameters_says_not_resolved():
    names = [f"p{i}" for i in range(50)]
    summary = {"done": 8, "parameters": [{"name": n} for n in names], "most_influential": {"mean_rise_K": names[:3]},
               "ranking": {"mean_rise_K": {"constant": False, "rows": [
                   {"parameter": n, "prcc": float("nan"), "spearman": r} for n, r in zip(names, [0.76, -0.7, 0.6] + [0.1] * 47)]}}}
    line = confidence.influence_line(summary, "mean_rise_K")
    assert "NOT RESOLVED" in line and line.count("not resolved") == 3 and "0.16 per parameter" in line


def test_without_a_recorded_rate_a_short_probe_drive_measures_it(tmp_path, monkeypatch):
    from vehicle.scenario.schema import prepare, read_scenario

    record = tmp_path / "drive_rate.json"
    monkeypatch.setattr(drive_rate, "_path", lambda: record)        # nothing recorded (the compiled model is cached)
    prep = prepare(read_scenario(ROOT / "scenarios" / "quick_demo.yaml"))
    assert drive_rate.read("full") is None
    est = cost.estimate([prep] * 3, 1)
    assert "rate measured now on a probe drive" in est.basis and est.drives == 3
    rate = drive_rate.read("full")
    assert rate is not None and rate["steps_per_s"] > 0
    # 5 km at 20 km/h in steps of 4 ms, at the probe's rate, plus its set-up
    assert est.per_drive_s == pytest.approx(rate["build_s"] + 225000 / rate["steps_per_s"], rel=1e-9)
    assert est.drives_s == pytest.approx(3 * est.per_drive_s)
    assert est.wall_s == pytest.approx(est.before_s + est.drives_s + est.finish_s)


# the solver modes a study can run in, as scenario overrides of the 5 km quick demo and the study's --ensemble; the
# multiscale layout is the per-axle UQ study's (350 m windows, 30 m warm-ups), its spacing giving the mode's minimum
# of windows over 5 km
MODES = {"full": ({}, 1),
         "multiscale": ({"solver": {"mode": "multiscale", "window": "350 m", "spacing": "1.6 km", "warm_up": "30 m"}}, 1),
         "time_parallel/2": ({"solver": {"time_parallel": 2}}, 1),
         "ensemble": ({}, 4)}


@pytest.fixture
def models_to_compile(monkeypatch):
    """The preview's builds as on an empty compile cache: each engine build announces its three libraries and each
    lane library its one, as `vehicle.numerics.codegen` announces a compile before it starts one. The engines
    themselves come from the suite's cache (a real compile takes a minute per mode: benchmarks/preview_accuracy.py
    runs those)."""
    from vehicle.engines import build, ensemble

    real_build = build.build_engine

    def build_engine(prepared, make_solver=None):
        compile_time.announce([1000, 1000, 1000], 2, codegen.cache_dir())
        return real_build(prepared, make_solver)

    monkeypatch.setattr(build, "build_engine", build_engine)
    monkeypatch.setattr(ensemble, "lane_stepper", lambda *a, **k: compile_time.announce([1000], 1, codegen.cache_dir()))


@pytest.mark.parametrize("mode", MODES)
def test_the_preview_appears_in_every_solver_mode_with_nothing_recorded(mode, tmp_path, monkeypatch, caplog,
                                                                       models_to_compile):
    """No drive recorded in the mode and the model to compile: the probe drive must be a valid scenario of that mode
    (enough multiscale windows, long enough time-parallel segments), the compile is counted (with the lane library
    of an ensemble study) and the study's line is said."""
    import logging

    from vehicle.scenario.schema import ScenarioSource, prepare, read_scenario

    monkeypatch.setattr(drive_rate, "_path", lambda: tmp_path / "drive_rate.json")    # nor the finish's time
    monkeypatch.setattr(compile_time, "compiled_libraries", 0)          # as in a fresh command
    monkeypatch.setattr(compile_time, "compiled_s", 0.0)
    overrides, lanes = MODES[mode]
    src = read_scenario(ROOT / "scenarios" / "quick_demo.yaml")
    data = {**src.data, **{k: {**(src.data.get(k) or {}), **v} for k, v in overrides.items()}}
    prep = prepare(ScenarioSource(text=src.text, name=src.name, base_dir=src.base_dir, data=data))
    rate_mode = drive_rate.mode_of(prep.scenario)
    assert rate_mode == mode.replace("ensemble", "full") and drive_rate.read(rate_mode) is None
    with caplog.at_level(logging.INFO, logger="hpsim"):
        est = cost.estimate([prep] * 3, 1, ensemble=lanes)
        cost.confirm(est, "hpsim uq", True)
    assert est is not None and "rate measured now on a probe drive" in est.basis
    # the announced ones, and any the suite's cache lacked for the engine's real build
    libraries = est.compiles.libraries
    assert libraries >= 3 + (lanes > 1) and est.compiles.models == 1
    line = re.search(r"hpsim uq: 3 drives on 1 worker.*", caplog.text)[0]
    assert re.search(rf"estimated .* per drive, {re.escape(rate_mode)} mode, rate measured now", line), line
    assert f"{libraries} libraries of 1 model compiled before the drives" in line and ("ensemble lanes" in line) == (lanes > 1)
    rate = drive_rate.read(rate_mode)
    assert rate is not None and rate["steps_per_s"] > 0 and rate["build_s"] > 0      # the probe's own set-up
    # one drive is the set-up plus its steps at the recorded rate: 5 km at 20 km/h in 4 ms steps (multiscale: the
    # steps of its windows)
    steps = 225000 if rate_mode != "multiscale" else cost.integrated_s(prep) / 0.004
    assert steps < 225000 or rate_mode != "multiscale"
    assert est.per_drive_s == pytest.approx(rate["build_s"] + steps / rate["steps_per_s"], rel=1e-9)
    assert est.wall_s == pytest.approx(est.before_s + est.drives_s + cost.FINISH_DEFAULT_S["hpsim uq"])


def test_the_estimate_adds_compiles_drives_on_workers_and_lanes_and_the_finish():
    """The arithmetic of vehicle/studies/cost.py's model, by hand: jobs over workers at the parallel efficiency (never
    less than the longest job), lockstep groups of lanes (set-ups one after the other, lanes x steps / the mode's lane gain),
    the whole command's wall as before + drives + finish."""
    e, g = cost.PARALLEL_EFFICIENCY, cost.LANE_GAIN
    drive = cost.DriveCost(set_up_s=2.0, steps_s=4.0)
    assert drive.alone_s == 6.0
    assert cost.drives_wall([drive] * 3, 1) == pytest.approx(18.0)
    assert cost.drives_wall([drive] * 3, 2) == pytest.approx(18.0 / (2 * e))
    assert cost.drives_wall([drive], 2) == pytest.approx(6.0)                      # one job: one worker, alone
    long_one = cost.DriveCost(set_up_s=1.0, steps_s=100.0)
    assert cost.drives_wall([drive, long_one], 2) == pytest.approx(101.0)          # the longest job bounds it
    # four drives in lockstep groups of 2 on a 4-lane library: two jobs of 2 x 2 s + 4 x 4 s / LANE_GAIN
    group = 2 * 2.0 + 4 * 4.0 / g
    assert cost.drives_wall([drive] * 4, 2, lanes=4, group=2) == pytest.approx(max(2 * group / (2 * e), group))
    # multiscale drives: their rate counts the work between windows, which lanes do not speed up
    ms = cost.DriveCost(set_up_s=2.0, steps_s=4.0, lane_gain=cost.MULTISCALE_LANE_GAIN)
    assert cost.drives_wall([ms] * 2, 1, lanes=2, group=2) == pytest.approx(2 * 2.0 + 2 * 4.0 / cost.MULTISCALE_LANE_GAIN)
    # a drive that cannot be a lane runs alone beside the group
    assert cost.drives_wall([drive] * 3, 1, lanes=4, group=2, joins=[True, True, False]) == pytest.approx(group + 6.0)
    assert [cost.lane_count(k) for k in (1, 2, 3, 4, 5, 8)] == [1, 2, 4, 4, 8, 8]
    est = cost.Estimate(drives=3, workers=2, per_drive_s=6.0, wall_s=10.0 + 14.0 + 5.0, basis="test", before_s=10.0,
                        drives_s=14.0, finish_s=5.0, compiles=cost.Compiles(6, 2, 9.0))
    assert est.remaining_s == 19.0
    line = est.line("hpsim uq")
    assert "estimated 29 s wall (6 s per drive" in line
    assert "6 libraries of 2 models compiled before the drives in 9 s (first run only)" in line
    assert "nothing compiled" in cost.Compiles().describe()
    assert "not included" in cost.Compiles(looked=False).describe()          # a listing compiles nothing


def test_a_multiscale_drive_integrates_its_windows_in_whole_solver_calls():
    from vehicle.engines.multiscale import integrated_time_s
    from vehicle.scenario.schema import ScenarioSource, prepare, read_scenario

    src = read_scenario(ROOT / "scenarios" / "quick_demo.yaml")

    def integrated(distance, speed="20 km/h", **solver):
        data = {**src.data, "distance": distance, "speed": speed, "solver": {"mode": "multiscale", **solver}}
        return cost.integrated_s(prepare(ScenarioSource(text=src.text, name=src.name, base_dir=src.base_dir, data=data)))
    # 106 km at 5.3 km spacing: 20 windows of 350 m after 30 m of warm-up; each 380 m at 20 km/h is 68.4 s, integrated
    # in calls of 10 samples of 1 s: 70 s each
    assert integrated("106 km", window="350 m", spacing="5.3 km", warm_up="30 m") == pytest.approx(20 * 70.0)
    # 36 km/h: 38 s per window, 40 s integrated
    assert integrated("106 km", "36 km/h", window="350 m", spacing="5.3 km", warm_up="30 m") == pytest.approx(20 * 40.0)
    # windows back to back: the whole road, each window rounded up to whole calls
    assert integrated("1140 m", window="350 m", spacing="380 m", warm_up="30 m") == pytest.approx(3 * 70.0)
    full = prepare(src)
    assert cost.integrated_s(full) == pytest.approx(full.duration_s())
    assert integrated_time_s(full.settings(), full.scenario.solver.multiscale_settings()) < full.duration_s()


def test_a_uq_preview_sees_the_nominal_case_and_a_typical_draw_whose_model_differs(tmp_path):
    """The per-axle study's nominal drive has no wheel-bay heat source (0 W, a file's zero shapes the compiled
    model) and every draw has one: the preview is given both, so the draws' model is compiled before the
    workers start, once."""
    from vehicle.studies.uq import run_scenario_study

    seen = []

    def stop(cases):
        seen.extend(cases)
        raise UserInputError("stopped after the preview")

    with pytest.raises(UserInputError, match="stopped after the preview"):
        run_scenario_study(ROOT / "scenarios" / "mileage_106km_uq.yaml", samples=3, method="lhs",
                           output_dir=tmp_path / "uq", distance="16 km", before_start=stop)
    assert len(seen) == 4 and seen[1] is not seen[0] and all(c is seen[1] for c in seen[2:])

    def heat_source_W(case):
        return [float((a.heat.heat_source if a.heat else None) or 0.0) for a in case.vehicle.axles]
    assert heat_source_W(seen[0]) == [0.0] * 4
    assert all(q > 0 for q in heat_source_W(seen[1]))
