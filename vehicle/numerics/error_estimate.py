"""A posteriori error estimate of the fixed-step solver: step doubling on a sample of blocks.

The drive integrates in blocks of output samples. At the start of its second block and then every
`every` blocks (a block counted as at least ERROR_WINDOW_S of drive), a window of ERROR_WINDOW_S (W steps of dt,
whatever the output interval) is integrated a second time. That run starts from the same state and solver
memory with half the step (a second compiled function: 2W steps of dt/2). The run at dt over the window
is the block's own samples when the window ends on one of them, else a third run of W steps of dt. ROS2 is of order q = 2, so by Richardson extrapolation the error of the dt result is

    y_dt - y  ~  (y_dt - y_dt/2) * 2^q / (2^q - 1) = 4/3 (y_dt - y_dt/2)

(Hairer, Norsett & Wanner, Solving ODEs I, sec. II.4). It is measured on what the drive is for:

- heat: the energy each strut dissipated over the window (valve, friction, gas, end stops), summed
  with its sign over all checked windows. Its relative error is the relative error of the strut's
  heat input and so of its temperature rise rate: `relative_heat_error`, the worst strut. This is
  the number compared with the scenario's tolerance (solver.tolerance).
- deflection: the strut deflections at the window's end (the heights follow from them): the
  largest error in metres, reported beside it.

When the estimate exceeds the tolerance, the next checked windows are also integrated with dt/4,
which estimates the error of a run at dt/2 the same way. The advice names the largest step that
the estimates say meets the tolerance (dt/2 when its own estimate does, else the order-2
extrapolation from dt/2), rounded down to a step that divides the output interval.

Cost: 2W half steps (plus W steps when the window is not a sample) per `every` blocks (of at least one
window), i.e. 2 % for the default 1 s output at 4 ms (W = K, M = 10, every 10th block). The dt/4 windows
(4/(M * every)) are added only in a run that fails its tolerance. The half-step function is compiled once per structure (cached on disk).
Beyond the asymptotic range (a step that under-resolves a fast relaxation) the 4/3 factor is not
exact, but the difference of the two runs still measures the error of the coarse one as long as the
fine one is much better, which the dt/4 level checks.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

ORDER = 2
RICHARDSON = 2 ** ORDER / (2 ** ORDER - 1)          # 4/3 for order 2
# the window integrated again: this much drive, whatever the output interval (a window of one output sample
# would weigh a single step's error against its own tiny heat and overstate it), started every
# error_check_every blocks, a block counted as at least one window long
ERROR_WINDOW_S = 1.0


def window_steps(dt_s: float) -> int:
    """Steps of dt_s in one error window (ERROR_WINDOW_S, at least one step)."""
    return max(1, int(round(ERROR_WINDOW_S / dt_s)))


def check_spacing_s(block_s: float) -> float:
    """Drive time between two windows when error_check_every is 1: one block, at least one window."""
    return max(block_s, ERROR_WINDOW_S)


# candidate steps of the advice [s] (the largest that meets the tolerance and divides the output interval)
NICE_STEPS_S = (0.02, 0.01, 0.008, 0.005, 0.004, 0.0025, 0.002, 0.001, 0.0008, 0.0005, 0.0004, 0.00025,
                0.0002, 0.0001)


def nice_step(dt_target_s: float, interval_s: float) -> float:
    """The largest of NICE_STEPS_S <= dt_target_s that divides interval_s (the smallest one if none)."""
    for h in NICE_STEPS_S:
        k = interval_s / h
        if h <= dt_target_s * (1 + 1e-9) and abs(k - round(k)) < 1e-6:
            return h
    return NICE_STEPS_S[-1]


@dataclass
class _Level:
    """Accumulated differences between a run at h and one at h/2 over the checked windows."""

    diff_heat_J: np.ndarray                     # sum of (E_h - E_h/2) per strut
    heat_J: np.ndarray                          # sum of E_h/2 per strut
    max_deflection_diff_m: float = 0.0
    windows: int = 0

    def add(self, heat_coarse, heat_fine, defl_coarse, defl_fine):
        self.diff_heat_J += heat_coarse - heat_fine
        self.heat_J += heat_fine
        self.max_deflection_diff_m = max(self.max_deflection_diff_m, float(np.max(np.abs(defl_coarse - defl_fine))))
        self.windows += 1

    def relative_heat_error(self) -> np.ndarray:
        """Per strut: |estimated error of the heat| / heat (Richardson)."""
        return RICHARDSON * np.abs(self.diff_heat_J) / np.maximum(np.abs(self.heat_J), 1e-9)

    def deflection_error_m(self) -> float:
        return RICHARDSON * self.max_deflection_diff_m


@dataclass
class StepDoublingEstimate:
    """Accumulates the step-doubling windows of a drive and turns them into the summary entries."""

    dt_s: float
    tolerance: float                            # relative error of the strut heat
    interval_s: float                           # output interval (the advice must divide it)
    n_struts: int
    names: list = field(default_factory=list)   # station names, for the message
    cost_s: float = 0.0                         # wall time of the extra integrations

    def __post_init__(self):
        z = np.zeros(self.n_struts)
        self.levels = [_Level(z.copy(), z.copy()), _Level(z.copy(), z.copy())]   # dt vs dt/2, dt/2 vs dt/4

    def add(self, level: int, heat_coarse, heat_fine, defl_coarse, defl_fine):
        self.levels[level].add(np.asarray(heat_coarse, float), np.asarray(heat_fine, float),
                               np.asarray(defl_coarse, float), np.asarray(defl_fine, float))

    @property
    def windows(self) -> int:
        return self.levels[0].windows

    def error(self) -> float:
        """The estimate: worst strut's relative heat error at dt (nan before any window)."""
        if not self.windows:
            return float("nan")
        return float(np.max(self.levels[0].relative_heat_error()))

    def exceeded(self) -> bool:
        return self.windows > 0 and self.error() > self.tolerance

    def half_step_error(self) -> float | None:
        lv = self.levels[1]
        return float(np.max(lv.relative_heat_error())) if lv.windows else None

    def advised_dt_s(self) -> float | None:
        """The step the estimates say meets the tolerance (None when dt does)."""
        err = self.error()
        if not err > self.tolerance:
            return None
        err2 = self.half_step_error()
        if err2 is None:                         # only the asymptotic extrapolation from dt
            return nice_step(0.9 * self.dt_s * np.sqrt(self.tolerance / err), self.interval_s)
        if err2 <= self.tolerance or not self.asymptotic():
            return nice_step(self.dt_s / 2, self.interval_s)
        return nice_step(0.9 * self.dt_s / 2 * np.sqrt(self.tolerance / err2), self.interval_s)

    def asymptotic(self) -> bool:
        """The errors at dt and dt/2 fall as the order says (ratio 3 to 6 for 4 expected): the extrapolation holds.
        Otherwise dt is outside the convergent range: its own states are off (a fast relaxation under-resolved),
        a dt/2 window started from them says little about a dt/2 run, and the advice is to halve dt and check again."""
        err2 = self.half_step_error()
        return err2 is not None and 3.0 * err2 <= self.error() <= 6.0 * err2

    def advice(self) -> str:
        if not self.windows:
            return ""
        ms = self.dt_s * 1e3
        err = self.error()
        if not err > self.tolerance:
            return f"solver.dt {ms:.4g} ms meets the tolerance"
        worst = int(np.argmax(self.levels[0].relative_heat_error()))
        who = f" (worst: strut {self.names[worst]})" if self.names else ""
        err2 = self.half_step_error()
        at_half = "" if err2 is None else f"; at {ms / 2:.4g} ms {err2:.2g}"
        again = "" if err2 is None or err2 <= self.tolerance or self.asymptotic() else \
            f" (the step is outside the solver's convergent range; check the estimate of the new run)"
        return (f"strut heat error estimate {err:.2g} at solver.dt {ms:.4g} ms{who}{at_half}, tolerance "
                f"{self.tolerance:.2g}: reduce solver.dt to {self.advised_dt_s() * 1e3:.4g} ms{again}")

    def summary(self, integration_s: float) -> dict:
        """Entries of the results' /summary (attributes): NaN estimate and empty advice when no window ran."""
        err2 = self.half_step_error()
        return {"solver_error_estimate": self.error(),
                "solver_tolerance": float(self.tolerance),
                "solver_advice": self.advice(),
                "solver_error_deflection_m": self.levels[0].deflection_error_m() if self.windows else float("nan"),
                "solver_error_half_step": float("nan") if err2 is None else err2,
                "solver_error_windows": int(self.windows),
                "solver_error_cost_pct": 100.0 * self.cost_s / max(integration_s, 1e-12)}
