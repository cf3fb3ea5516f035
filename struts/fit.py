"""Parameter identification from rig data (least squares).

Data: an energy-per-cycle table (CSV columns amplitude_m, frequency_Hz, mean_m, energy_J;
seed 000 Table 1 style) or measured loops (CSV columns amplitude_m, frequency_Hz, mean_m,
t_s, force_N: the force over the last cycle of x = mean + A sin(2 pi f t)).

Fitted parameters are searched in log space (they are all positive), residuals are
relative errors (energy) or force errors scaled by the largest measured force (loops).
The report gives the values, residuals and approximate 95 % confidence intervals from
the Jacobian at the optimum (cov = s^2 (J^T J)^-1).
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import t as student_t

from hpsim.files import decode_text
from hpsim.errors import UserInputError

from .params import StrutParams
from .rig import cycle_test

# name on the command line -> parameter paths it sets (one value for all paths)
FITTABLE = {
    "F0": ("friction.F0_compression", "friction.F0_rebound"),
    "F0_compression": ("friction.F0_compression",),
    "F0_rebound": ("friction.F0_rebound",),
    "pressure_coefficient": ("friction.pressure_coefficient",),
    "breakaway_ratio": ("friction.breakaway_ratio",),
    "viscous": ("friction.viscous",),
    "thermal_time_constant": ("gas.thermal_time_constant",),
    "bleed_area": ("valve.bleed_area",),
    "discharge_coefficient": ("valve.discharge_coefficient",),
    "polytropic_exponent": ("gas.polytropic_exponent",),
}


def _get(params: StrutParams, path: str) -> float:
    obj = params
    for part in path.split("."):
        obj = getattr(obj, part)
    return float(obj)


def with_values(params: StrutParams, names, values) -> StrutParams:
    overrides = {}
    for name, value in zip(names, values):
        for path in FITTABLE[name]:
            overrides[path] = float(value)
    return params.with_overrides(overrides)


@dataclass
class RigData:
    kind: str                     # "energy" or "loops"
    rows: list[dict]
    source: str

    def tests(self):
        """Unique (amplitude, frequency, mean) triples in file order."""
        seen = []
        for r in self.rows:
            key = (r["amplitude_m"], r["frequency_Hz"], r["mean_m"])
            if key not in seen:
                seen.append(key)
        return seen


def read_rig_csv(path: str | Path) -> RigData:
    path = Path(path)
    if not path.exists():
        raise UserInputError(f"--data: {path}: file not found")
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise UserInputError(f"--data: {path}: cannot read ({exc.strerror})") from None
    lines = [ln for ln in decode_text(raw, str(path)).splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise UserInputError(f"{path}: no data rows")
    reader = csv.DictReader(lines)
    cols = set(reader.fieldnames or [])
    base = {"amplitude_m", "frequency_Hz", "mean_m"}
    if base | {"energy_J"} <= cols:
        kind, value_cols = "energy", ("energy_J",)
    elif base | {"t_s", "force_N"} <= cols:
        kind, value_cols = "loops", ("t_s", "force_N")
    else:
        raise UserInputError(
            f"{path}: the header's {len(cols)} columns do not match an energy table "
            "(amplitude_m,frequency_Hz,mean_m,energy_J) or loops (amplitude_m,frequency_Hz,mean_m,t_s,force_N)")
    rows = []
    for i, r in enumerate(reader, start=2):
        try:
            row = {k: float(r[k]) for k in (*base, *value_cols)}
        except (TypeError, ValueError):
            raise UserInputError(f"{path}: line {i} of the table (header = 1): a missing or non-numeric "
                                 "value") from None
        if not all(math.isfinite(v) for v in row.values()):
            raise UserInputError(f"{path}: line {i}: NaN or infinite value")
        rows.append(row)
    return RigData(kind=kind, rows=rows, source=str(path))


def simulate(params: StrutParams, data: RigData, cycles: int = 3) -> np.ndarray:
    """Model values matching the data rows (energies [J] or forces [N])."""
    out = []
    for (A, f, mean) in data.tests():
        res = cycle_test(params, A, f, mean, cycles=cycles)
        rows = [r for r in data.rows if (r["amplitude_m"], r["frequency_Hz"], r["mean_m"]) == (A, f, mean)]
        if data.kind == "energy":
            out += [res.energy_per_cycle_J] * len(rows)
        else:
            phase = (np.array([r["t_s"] for r in rows]) * f) % 1.0
            t_cycle = (res.t_s - res.t_s[0]) * f
            out += list(np.interp(phase, t_cycle, res.force_N))
    return np.asarray(out)


def measured(data: RigData) -> np.ndarray:
    key = "energy_J" if data.kind == "energy" else "force_N"
    return np.array([r[key] for r in data.rows])


def residuals(params: StrutParams, data: RigData, cycles: int = 3) -> np.ndarray:
    y = measured(data)
    model = simulate(params, data, cycles)
    if data.kind == "energy":
        return (model - y) / y
    return (model - y) / np.max(np.abs(y))


@dataclass
class FitResult:
    names: list[str]
    values: dict
    initial: dict
    confidence_95: dict
    residuals: list[float]
    measured: list[float]
    model: list[float]
    cost: float
    success: bool
    message: str

    def as_dict(self) -> dict:
        return {
            "fitted": self.values, "initial": self.initial, "confidence_95": self.confidence_95,
            "measured": self.measured, "model": self.model, "relative_residuals": self.residuals,
            "cost": self.cost, "success": self.success, "message": self.message,
        }


def fit(params: StrutParams, data: RigData, names: list[str], cycles: int = 3, max_nfev: int = 60) -> FitResult:
    unknown = [n for n in names if n not in FITTABLE]
    if unknown:
        raise UserInputError(f"--fit: unknown parameter(s) {unknown}; fittable: {', '.join(FITTABLE)}")
    if not names:
        raise UserInputError("--fit: name at least one parameter")
    theta0 = np.array([_get(params, FITTABLE[n][0]) for n in names])
    if np.any(theta0 <= 0):
        bad = [n for n, v in zip(names, theta0) if v <= 0]
        raise UserInputError(f"--fit: starting values of {bad} must be > 0 (set them in the strut file)")

    def fun(log_theta):
        try:
            return residuals(with_values(params, names, np.exp(log_theta)), data, cycles)
        except RuntimeError:
            return np.full(len(data.rows), 10.0)

    sol = least_squares(fun, np.log(theta0), method="trf", x_scale=1.0, diff_step=1e-3, max_nfev=max_nfev)
    theta = np.exp(sol.x)
    m, p = len(sol.fun), len(names)
    dof = max(m - p, 1)
    s2 = float(sol.fun @ sol.fun) / dof
    try:
        cov_log = s2 * np.linalg.inv(sol.jac.T @ sol.jac)
        half = student_t.ppf(0.975, dof) * np.sqrt(np.clip(np.diag(cov_log), 0, None))
        # a half width beyond e^20 means the data do not identify that parameter
        ci = {n: ([float(v * math.exp(-h)), float(v * math.exp(h))] if h < 20 else [0.0, float("inf")])
              for n, v, h in zip(names, theta, half)}
    except np.linalg.LinAlgError:
        ci = {n: [float("nan"), float("nan")] for n in names}
    fitted = with_values(params, names, theta)
    model = simulate(fitted, data, cycles)
    y = measured(data)
    return FitResult(
        names=list(names), values={n: float(v) for n, v in zip(names, theta)},
        initial={n: float(v) for n, v in zip(names, theta0)}, confidence_95=ci,
        residuals=[float(r) for r in (model - y) / np.abs(y)] if data.kind == "energy" else [float(r) for r in sol.fun],
        measured=[float(v) for v in y], model=[float(v) for v in model], cost=float(sol.cost),
        success=bool(sol.success), message=str(sol.message))
