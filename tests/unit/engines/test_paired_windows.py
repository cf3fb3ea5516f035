"""Paired windows of the multiscale mode (`solver.paired_windows`, vehicle.engines.multiscale): the window after
each odd one integrates on a second thread from the start the slow model predicts, and its warm-up correction
carries it to its true start (exact to first order in the offset).

- with no tolerance for the offset every predicted window is integrated again from its true start: the result is
  the windows' one-by-one result bit for bit (the second thread and solver change nothing in the numerics);
- the threads change nothing either: run on the drive's own solver one after the other, the same bits;
- with the default tolerance the paired result stays a small fraction of the stated error from the one-by-one
  result, the last window is never predicted, and the report says how many were;
- the key is checked with the other multiscale keys (test_multiscale.py);
- an interrupted run keeps its windows and says to start again.
"""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from vehicle.analysis.summary import report_from
from vehicle.engines import window_pair
from vehicle.results.run import run_in_memory
from vehicle.scenario.schema import read_scenario_text
from vehicle.scenario.settings import MultiscaleSettings

# the struts start away from their running temperatures (they cool and warm over the drive): the slow states move
# between windows, so a predicted start is off
BASE = {"description": "paired windows", "vehicle": {"name": "apc_8x8"}, "road": {"iso_class": "D", "seed": 2},
        "speed": "20 km/h", "distance": "6 km", "ambient_temperature": "25 degC",
        "initial_temperatures": ["45 degC", "40 degC", "35 degC", "30 degC"],
        "output": {"interval": "1 s", "stats_interval": "1 km"},
        "solver": {"mode": "multiscale", "window": "200 m", "spacing": "600 m", "warm_up": "40 m",
                   "placement": "systematic"}}
KEYS = ("T_end_C", "dN_pct", "dh_mm")


def _run(paired: bool):
    data = {**BASE, "solver": {**BASE["solver"], "paired_windows": paired}}
    sink = run_in_memory(read_scenario_text(yaml.safe_dump(data), "paired.yaml", "."))
    return sink, report_from(sink, "paired")


def _values(rep: dict) -> np.ndarray:
    return np.array([[a[k] for k in KEYS] for a in rep["axles"]])


@pytest.fixture(scope="module")
def one_by_one():
    return _run(False)


def test_with_no_tolerance_every_predicted_window_runs_again_and_equals_one_by_one(one_by_one, monkeypatch):
    monkeypatch.setattr(MultiscaleSettings, "PAIRED_START_TOLERANCE_K", 0.0)
    sink, rep = _run(True)
    seq_sink, seq = one_by_one
    assert rep["estimated_error"]["paired"] == 0
    np.testing.assert_array_equal(_values(rep), _values(seq))
    for name in ("strut_temperature_K", "wheel_load_N"):
        np.testing.assert_array_equal(np.asarray(sink.series(name)), np.asarray(seq_sink.series(name)))


def test_the_second_thread_changes_no_bit(monkeypatch):
    threaded_sink, threaded = _run(True)

    def at_once(self, slot, x0, t0, t_warm, t_end):  # the drive's own solver, one window after the other
        from concurrent.futures import Future
        done = Future()
        done.set_result(self.drive.integrate(self.drive.solver, x0, t0, t_end, t_warm))
        return done
    monkeypatch.setattr(window_pair.WindowPair, "submit", at_once)
    sink, rep = _run(True)
    assert threaded["estimated_error"]["paired"] >= 2
    np.testing.assert_array_equal(_values(rep), _values(threaded))
    np.testing.assert_array_equal(np.asarray(sink.series("strut_temperature_K")),
                                  np.asarray(threaded_sink.series("strut_temperature_K")))


def test_paired_windows_stay_within_a_small_part_of_the_stated_error(one_by_one):
    _, seq = one_by_one
    _, rep = _run(True)
    est = rep["estimated_error"]
    n = est["windows"]
    assert n == 10 and 2 <= est["paired"] <= (n - 2) // 2        # the first and the last window from true starts
    for a_seq, a, eT, eN in zip(seq["axles"], rep["axles"], est["T_end_K"], est["dN_pct"]):
        # the carry to the true start is exact to first order: what is left is a small part of the sampling error
        assert abs(a["T_end_C"] - a_seq["T_end_C"]) < 0.25 * eT
        assert abs(a["dN_pct"] - a_seq["dN_pct"]) < 0.25 * eN
    assert not np.array_equal(_values(rep), _values(seq))          # the windows really did start elsewhere
    assert "from a predicted start" in multiscale_report_line(rep)


def multiscale_report_line(rep: dict) -> str:
    from vehicle.presentation.report import format_report
    return next(line for line in format_report(rep).splitlines() if line.startswith("solver mode multiscale"))


def test_an_interrupted_multiscale_run_keeps_its_windows_and_says_to_start_again(tmp_path, monkeypatch):
    """A stop requested (Ctrl-C, a sweep worker's orphan watch) in the third window: the windows before it are in the
    file (written while the next ones integrate, and on the way out), the status says interrupted, and the message
    says to start again (a multiscale run is not resumed)."""
    from vehicle.results.reader import open_results
    from vehicle.results.run import RunInterrupted, run_scenario

    class AtThirdCheck:
        """A cancellation token requested from the third time the drive reads it (once per written window)."""

        def __init__(self):
            self.reads = 0

        def request(self):
            self.reads = 3

        @property
        def requested(self):
            self.reads += 1
            return self.reads >= 3

    scen = tmp_path / "ms.yaml"
    scen.write_text(yaml.safe_dump({**BASE, "solver": {**BASE["solver"], "paired_windows": True}}))
    out = tmp_path / "ms.h5"
    with pytest.raises(RunInterrupted) as info:
        run_scenario(scen, out, progress=False, cancel=AtThirdCheck())
    assert "--overwrite" in str(info.value) and "--resume" not in str(info.value)
    with open_results(out) as r:
        assert r.status() == "interrupted"
        t = np.asarray(r.series("time"))
        # three windows of 240 m at 20 km/h (43 s each, 1 s samples) were processed before the stop
        assert 3 * 40 <= len(t) <= 3 * 45 and np.all(np.diff(t) > 0)
