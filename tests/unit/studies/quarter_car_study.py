"""A linear quarter car on a white-noise road velocity, as an `hpsim optimize` evaluator (tests of the optimiser).

The corner of hpsim's 8x8 APC (sprung mass per wheel, unsprung mass and tyre stiffness of its vehicle file) with a
linear spring k_s and damper c. The road velocity is white noise of intensity q (a road displacement PSD
G_d(n) = A n^-2 driven at speed v gives q = 2 pi^2 A v). The stationary variances come from the Lyapunov equation
(scipy) or in closed form (Gobbi and Mastinu, Vehicle System Dynamics 35 (2001) 191-208, with pi A v = q / 2):

    var(body acceleration) = q/2 [k_t c + M k_s^2 / c] / m_s^2
    var(tyre deflection)   = q/2 [c^2 k_t M^2 + k_s^2 M^3 - 2 k_s k_t m_s m_u M + k_t^2 m_s^2 m_u] / (c k_t^2 m_s^2)
    var(working space)     = q/2 M / c,          M = m_s + m_u.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.linalg import solve_continuous_lyapunov

from vehicle.physics.params import load_vehicle
from vehicle.studies.optimize_objectives import Objective, ReportPath
from vehicle.studies.optimize_study import DesignVariable, Study

ROAD_INTENSITY = 2 * np.pi ** 2 * 16e-6 * 10.0       # ISO class C (A = 16e-6 m) at 10 m/s [m^2/s]
KS = "struts.all.spring_rate"                         # design keys: names for the two parameters
C = "struts.all.damping_rate"


def corner() -> dict:
    """m_s [kg], m_u [kg], k_t [N/m] of one corner of the shipped 8x8 APC."""
    P = load_vehicle("apc_8x8")
    n = len(P.station_names())
    return {"ms": P.sprung_mass() / n, "mu": P.axles[0].unsprung_mass, "kt": P.tyre.stiffness}


def variances_lyapunov(ks, c, ms, mu, kt, q=ROAD_INTENSITY) -> dict:
    """Stationary variances from A P + P A^T + q B B^T = 0; states: working space, tyre deflection, velocities."""
    A = np.array([[0, 0, 1, -1], [0, 0, 0, 1], [-ks / ms, 0, -c / ms, c / ms], [ks / mu, -kt / mu, c / mu, -c / mu]])
    B = np.array([[0.0], [-1.0], [0.0], [0.0]])
    P = solve_continuous_lyapunov(A, -q * B @ B.T)
    acc = A[2:3]
    return {"acc": float((acc @ P @ acc.T)[0, 0]), "tyre": float(P[1, 1]), "ws": float(P[0, 0])}


def variances_closed_form(ks, c, ms, mu, kt, q=ROAD_INTENSITY) -> dict:
    M = ms + mu
    return {"acc": q / 2 * (kt * c + M * ks ** 2 / c) / ms ** 2,
            "tyre": q / 2 * (c ** 2 * kt * M ** 2 + ks ** 2 * M ** 3 - 2 * ks * kt * ms * mu * M + kt ** 2 * ms ** 2 * mu)
            / (c * kt ** 2 * ms ** 2),
            "ws": q / 2 * M / c}


def optimal_front(weights, ms, mu, kt, q=ROAD_INTENSITY) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(k_s, c, [std acc, std tyre]) minimising var(acc) + w var(tyre) for each weight w: both variances are
    a c + b(k_s) / c with b convex, so the weighted sums reach the whole front; setting their derivatives to zero:
    k_s = w m_s m_u k_t / (k_t^2 + w M^2),  c^2 = (M k_s^2 + w b_t(k_s) / k_t^2) / (k_t + w M^2 / k_t)."""
    w = np.asarray(weights, float)
    M = ms + mu
    ks = w * ms * mu * kt / (kt ** 2 + w * M ** 2)
    b_tyre = ks ** 2 * M ** 3 - 2 * ks * kt * ms * mu * M + kt ** 2 * ms ** 2 * mu
    c = np.sqrt((M * ks ** 2 + w * b_tyre / kt ** 2) / (kt + w * M ** 2 / kt))
    v = variances_closed_form(ks, c, ms, mu, kt, q)
    return ks, c, np.sqrt(np.column_stack([v["acc"], v["tyre"]]))


def quarter_car_study(bounds_ks, bounds_c, *, trials, population, seed=0, working_space=False) -> Study:
    """The study: k_s and c (log ranges), objectives std of body acceleration and tyre deflection (and working
    space)."""
    objectives = [Objective("sigma_acc", ReportPath.parse("sigma_acc_m_s2", "test"), "base", "min"),
                  Objective("sigma_tyre", ReportPath.parse("sigma_tyre_m", "test"), "base", "min")]
    if working_space:
        objectives.append(Objective("sigma_ws", ReportPath.parse("sigma_ws_m", "test"), "base", "min"))
    return Study("quarter_car", [DesignVariable(KS, *bounds_ks, "N/m", True), DesignVariable(C, *bounds_c, "N*s/m", True)],
                 objectives, [], [], trials, population, "nsga2", seed)


@dataclass
class QuarterCarEvaluator:
    """An evaluator of the optimiser's contract: the quarter car's standard deviations as a case's report.

    calls_log: a file each finished evaluation appends its trial number to (to count runs across processes);
    stop_at: raise KeyboardInterrupt instead of evaluating this trial (a study killed mid-generation)."""

    ms: float
    mu: float
    kt: float
    calls_log: str | None = None
    stop_at: int | None = None

    def __call__(self, number: int, design: dict) -> dict:
        if number == self.stop_at:
            raise KeyboardInterrupt
        v = variances_lyapunov(design[KS], design[C], self.ms, self.mu, self.kt)
        if self.calls_log:
            with open(self.calls_log, "a") as fh:
                fh.write(f"{number}\n")
        report = {"sigma_acc_m_s2": v["acc"] ** 0.5, "sigma_tyre_m": v["tyre"] ** 0.5, "sigma_ws_m": v["ws"] ** 0.5}
        return {"status": "done", "error": "", "reports": {"base": report}, "seconds": 0.0}


def trial_table(folder: Path) -> list:
    """(trial, design, objectives) of every trial in a study folder's summary, for bit-for-bit comparisons."""
    s = json.loads((Path(folder) / "optimize.json").read_text())
    return [(r["trial"], r["design"], r["objectives"]) for r in s["all_trials"]]


def calls(path) -> list[int]:
    return [int(x) for x in Path(path).read_text().split()] if os.path.exists(path) else []
