"""`hpsim optimize`'s optimiser on a problem with a known answer: the linear quarter car on a white-noise road.

The comfort / road-holding front found by the study must lie within 2 % of the closed-form optimum (Gobbi and
Mastinu 2001) and cover it; a study stopped mid-generation and run again must end with the same trials bit for
bit without running a finished trial twice; a study on a Dask cluster must give the front of local workers.
"""
import numpy as np
import pytest

from hpsim.errors import UserInputError
from vehicle.studies.optimize_objectives import Constraint, PathError, ReportPath
from vehicle.studies.optimize_pareto import hypervolume_2d, non_dominated
from vehicle.studies.optimize_runner import run_study

from .quarter_car_study import (QuarterCarEvaluator, calls, corner, optimal_front, quarter_car_study, trial_table,
                                variances_closed_form, variances_lyapunov)

pytest.importorskip("optuna")

KS_RANGE, C_RANGE = (2e3, 2e5), (5e2, 5e4)       # N/m, N s/m: around the APC corner's optimal front
REPORT = {"load_shift_pct": 1.5,
          "axles": [{"axle": 1, "T_oil_end_C": 40.0}, {"axle": 2, "T_oil_end_C": 43.0}],
          "ride": {"seats": [{"seat": "driver", "weighted_rms_acceleration_m_s2": 0.4}],
                   "stations": [{"station": "1L", "end_stop_time_s": 0.0}, {"station": "1R", "end_stop_time_s": 0.2}]}}


def test_key_paths_pick_items_by_name_and_reduce_over_items():
    assert ReportPath.parse("ride.seats.driver.weighted_rms_acceleration_m_s2", "t").value(REPORT) == 0.4
    assert ReportPath.parse("max(axles.T_oil_end_C)", "t").value(REPORT) == 43.0
    assert ReportPath.parse("mean(axles.T_oil_end_C)", "t").value(REPORT) == 41.5
    assert ReportPath.parse("axles.2.T_oil_end_C", "t").value(REPORT) == 43.0          # by the axle's number
    with pytest.raises(PathError, match="reduce them"):
        ReportPath.parse("axles.T_oil_end_C", "t").value(REPORT)
    with pytest.raises(PathError, match="ride.seats.commander"):
        ReportPath.parse("ride.seats.commander.weighted_rms_acceleration_m_s2", "t").value(REPORT)
    with pytest.raises(UserInputError, match="objectives.x"):
        ReportPath.parse("sum(axles.T_oil_end_C)", "objectives.x")


def test_constraint_margin_is_the_distance_inside_the_bound():
    c = Constraint.parse("max(ride.stations.end_stop_time_s) <= 0.1", "ride", "t")
    assert c.margin(c.path.value(REPORT)) == pytest.approx(-0.1)          # 0.2 s at the end stops: violated
    assert Constraint.parse("load_shift_pct >= 1", "ride", "t").margin(1.5) == pytest.approx(0.5)


def test_non_dominated_and_hypervolume_of_known_point_sets():
    F = np.array([[1, 3], [2, 2], [3, 1], [2.5, 2.5], [1, 3]], float)
    assert non_dominated(F) == [0, 1, 2]                                 # (2.5, 2.5) dominated, a duplicate once
    # staircase under the reference (4, 4): 3x1 + 2x1 + 1x1
    assert hypervolume_2d(F, (4, 4)) == pytest.approx(6.0)
    assert hypervolume_2d(np.array([[5.0, 5.0]]), (4, 4)) == 0.0


def test_closed_form_variances_match_the_lyapunov_equation():
    p = corner()
    for ks, c in ((2e3, 5e2), (3e4, 4e3), (2e5, 5e4)):
        a, b = variances_lyapunov(ks, c, **p), variances_closed_form(ks, c, **p)
        for k in a:
            assert a[k] == pytest.approx(b[k], rel=1e-9)


def _epsilon(P, Q) -> float:
    """Multiplicative epsilon indicator: the least e such that every point of Q is within (1 + e) of a point of P
    in every objective."""
    return max(float(np.min(np.max(P / q, axis=1))) for q in Q) - 1.0


def test_front_of_the_quarter_car_is_the_closed_form_optimum(tmp_path):
    p = corner()
    study = quarter_car_study(KS_RANGE, C_RANGE, trials=300, population=20)
    study.sampler = "tpe"
    s = run_study(study, tmp_path / "qc", evaluate=QuarterCarEvaluator(**p), workers=1, storage="memory")
    found = np.array([[r["objectives"]["sigma_acc"], r["objectives"]["sigma_tyre"]] for r in s["pareto"]])
    ks, c, exact = optimal_front(np.logspace(-4, 4, 4000), **p)
    inside = (ks >= KS_RANGE[0]) & (ks <= KS_RANGE[1]) & (c >= C_RANGE[0]) & (c <= C_RANGE[1])
    exact = exact[inside]
    assert len(exact) > 100                           # the ranges hold a long stretch of the front
    # no design beats the closed-form optimum (beyond the chords' error of interpolating it between 4000 points)
    lo, hi = exact[:, 0].min(), exact[:, 0].max()
    within = found[(found[:, 0] >= lo) & (found[:, 0] <= hi)]
    assert len(within) >= 10
    order = np.argsort(exact[:, 0])
    t_exact = np.interp(within[:, 0], exact[order, 0], exact[order, 1])
    assert np.all(within[:, 1] >= t_exact * (1 - 1e-5))
    # the found front lies within 2 % of the optimum and covers it within 2 % from end to end
    assert _epsilon(exact, within) < 0.02
    assert _epsilon(found, exact) < 0.02


def test_nsga2_front_converges_towards_the_closed_form_optimum(tmp_path):
    """NSGA-II (the default for several objectives) closes in on the same front as its generations go on."""
    p = corner()
    ks, c, exact = optimal_front(np.logspace(-4, 4, 2000), **p)
    exact = exact[(ks >= KS_RANGE[0]) & (ks <= KS_RANGE[1]) & (c >= C_RANGE[0]) & (c <= C_RANGE[1])]
    gaps = []
    for n in (40, 400):
        s = run_study(quarter_car_study(KS_RANGE, C_RANGE, trials=n, population=20), tmp_path / f"n{n}",
                      evaluate=QuarterCarEvaluator(**p), workers=1, storage="memory")
        found = np.array([[r["objectives"]["sigma_acc"], r["objectives"]["sigma_tyre"]] for r in s["pareto"]])
        gaps.append(_epsilon(found, exact))
    assert gaps[1] < 0.5 * gaps[0] and gaps[1] < 0.05


def test_a_study_stopped_mid_generation_resumes_to_the_same_trials(tmp_path):
    p = corner()
    study = quarter_car_study(KS_RANGE, C_RANGE, trials=20, population=8)
    whole = run_study(study, tmp_path / "whole", evaluate=QuarterCarEvaluator(**p), workers=1)
    log = tmp_path / "calls.txt"
    with pytest.raises(KeyboardInterrupt):            # stopped at trial 11: the second generation is half done
        run_study(study, tmp_path / "stopped", evaluate=QuarterCarEvaluator(**p, calls_log=str(log), stop_at=11),
                  workers=1)
    assert calls(log) == list(range(11))
    resumed = run_study(study, tmp_path / "stopped", evaluate=QuarterCarEvaluator(**p, calls_log=str(log)), workers=1)
    assert sorted(calls(log)) == list(range(20))     # every trial ran once
    assert trial_table(tmp_path / "stopped") == trial_table(tmp_path / "whole")     # bit for bit
    assert [r["trial"] for r in resumed["pareto"]] == [r["trial"] for r in whole["pareto"]]


def test_a_finished_study_is_not_run_again_and_another_definition_is_refused(tmp_path):
    p = corner()
    log = tmp_path / "calls.txt"
    study = quarter_car_study(KS_RANGE, C_RANGE, trials=8, population=4)
    run_study(study, tmp_path / "s", evaluate=QuarterCarEvaluator(**p, calls_log=str(log)), workers=1)
    run_study(study, tmp_path / "s", evaluate=QuarterCarEvaluator(**p, calls_log=str(log)), workers=1)
    assert sorted(calls(log)) == list(range(8))
    other = quarter_car_study(KS_RANGE, (1e3, 5e4), trials=8, population=4)
    with pytest.raises(UserInputError, match="another definition"):
        run_study(other, tmp_path / "s", evaluate=QuarterCarEvaluator(**p), workers=1)


def test_a_study_on_a_dask_cluster_gives_the_front_of_local_workers(tmp_path):
    distributed = pytest.importorskip("distributed")
    p = corner()
    study = quarter_car_study(KS_RANGE, C_RANGE, trials=16, population=8)
    local = run_study(study, tmp_path / "local", evaluate=QuarterCarEvaluator(**p), workers=1, storage="memory")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        remote = run_study(study, tmp_path / "dask", evaluate=QuarterCarEvaluator(**p), client=client,
                           storage="memory")
    assert [(r["trial"], r["objectives"]) for r in remote["pareto"]] == \
        [(r["trial"], r["objectives"]) for r in local["pareto"]]
