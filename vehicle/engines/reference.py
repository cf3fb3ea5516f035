"""A fixed-step explicit reference engine: the worked example of a fifth engine (docs/CONTRIBUTING.md).

It composes the parts every engine shares, the vehicle on its road (`VehicleOnRoad`: road envelopes, charge,
inputs, where the drive ends) and the block recorder (`BlockRecorder`: checks, outputs, statistics, sink),
with a solver it is given: here Heun's method (the explicit trapezoidal rule, second order; Hairer, Norsett
& Wanner, Solving ODEs I, sec. II.1) on the model's explicit ODE, in CasADi's virtual machine. No compiled
library, no step-size control: simple enough to check the production engine against, slow (a step of a
fraction of a millisecond keeps the explicit rule stable on the stiff wheel and friction dynamics).
"""
from __future__ import annotations

import time
from typing import Callable

import casadi as ca
import numpy as np

from hpsim.cancellation import NEVER, CancelToken

from vehicle.numerics.contract import SolverCapabilities
from vehicle.scenario.settings import DriveSettings
from vehicle.scenario.work_limits import samples_per_call
from vehicle.engines.contract import DriveResult, DriveState
from vehicle.engines.recorder import BlockRecorder
from vehicle.engines.vehicle_on_road import VehicleOnRoad


class HeunSolver:
    """Heun's method at a fixed step dt [s] on f(x, memory, u, p) (`VehicleModel.ode_function`), a solver of the
    numerics contract (vehicle.numerics.contract): uncompiled, no step doubling.

        k1 = f(x_n, u_n),  k2 = f(x_n + dt k1, u_n+1),  x_n+1 = x_n + dt (k1 + k2) / 2

    The valves' warm-start memory follows the second evaluation."""

    name = "heun"
    capabilities = SolverCapabilities()

    def __init__(self, dt: float):
        self.dt = float(dt)
        self.memory = np.zeros(0)
        self.memory_samples = np.zeros((0, 0))

    def describe(self) -> dict:
        return {"solver": self.name, "dt_s": self.dt}

    def bind(self, model, steps_per_sample: int, samples_per_call: int) -> "HeunSolver":
        """Bound to blocks of samples_per_call samples of steps_per_sample steps each (one CasADi call a block)."""
        self.model, self.K, self.M = model, int(steps_per_sample), int(samples_per_call)
        nx, nm = model.nx, model.n_memory
        z, u0, u1, p = (ca.SX.sym(n, k) for n, k in (("z", nx + nm), ("u0", model.nu), ("u1", model.nu),
                                                     ("p", model.np)))
        x, mem = z[:nx], z[nx:]
        k1, mem1 = model.ode_function(x, mem, u0, p)
        k2, mem2 = model.ode_function(x + self.dt * k1, mem1, u1, p)
        step = ca.Function("heun_step", [z, u0, u1, p], [ca.vertcat(x + 0.5 * self.dt * (k1 + k2), mem2)])
        # every step of a block in one call: the state carried, the inputs mapped, the parameters repeated
        self._block = step.mapaccum("heun_block", self.K * self.M)
        self.memory = model.initial_memory()
        return self

    def advance(self, x0: np.ndarray, U: np.ndarray, p: np.ndarray) -> np.ndarray:
        """The states (nx, M) at the end of each sample of the block from x0; U: the inputs at the K M + 1 step
        boundaries."""
        n = self.K * self.M
        Z = np.asarray(self._block(np.concatenate([x0, self.memory]), U[:, :n], U[:, 1:n + 1],
                                   np.repeat(np.asarray(p, float)[:, None], n, axis=1)))
        Z = Z[:, self.K - 1::self.K]
        self.memory_samples = Z[self.model.nx:]
        self.memory = Z[self.model.nx:, -1].copy()
        return Z[: self.model.nx]

    def get_state(self) -> np.ndarray:
        return np.asarray(self.memory, float).copy()

    def set_state(self, memory) -> None:
        self.memory = np.asarray(memory, float).copy()


class ReferenceDrive:
    """A full-resolution drive of `model` over `road` with `settings` on a fixed-step explicit `solver` (default
    Heun at settings.dt_s): the engine contract (vehicle.engines.contract.Engine) in a few parts."""

    mode = "reference"
    resumable = True

    def __init__(self, model, road, settings: DriveSettings, solver=None):
        solver = solver or HeunSolver(settings.dt_s)
        settings.dt_s = solver.dt
        settings.validate()
        t0 = time.perf_counter()
        self.model, self.settings = model, settings
        self.vehicle = VehicleOnRoad(model, road, settings)
        self.gas_masses, self.total_time_s = self.vehicle.gas_masses, self.vehicle.total_time_s
        self.T_index = self.vehicle.index.T_index
        self.K = int(round(settings.output_interval_s / settings.dt_s))
        self.M = samples_per_call(self.K, settings.samples_per_block)
        self.end = self.vehicle.end(self.K)
        self.solver = solver.bind(model, self.K, self.M)
        self.recorder = BlockRecorder(self.vehicle, settings.distance_m, self.M)
        self.build_s = time.perf_counter() - t0

    def initial_equilibrium(self):
        return self.vehicle.initial_equilibrium()

    def initial_state(self) -> DriveState:
        return self.vehicle.initial_state(self.solver.get_state())

    def describe(self):
        st = self.initial_state()
        t = np.array([0.0])
        block = self.recorder.block_outputs(st.x[:, None], self.vehicle.inputs(t), t, t, st.solver_memory[:, None])
        row = self.recorder.stats_row(self.settings.stats_interval_m, 1.0, np.zeros(len(self.recorder.quad_index)),
                                      st.x)
        return block, row, st.as_dict()

    def final_values(self, state: DriveState) -> dict:
        return self.recorder.final_values(state)

    def summary_extra(self) -> dict:
        return {}

    def run(self, sink=None, state: DriveState | None = None, progress: Callable | None = None,
            checkpoint_every_blocks: int = 6, cancel: CancelToken = NEVER) -> DriveResult:
        """Whole blocks of samples to the last whole sample, then one sample after the steps left (`DriveEnd`),
        each recorded; returns after a checkpointed block once `cancel` is requested."""
        st = self.initial_state() if state is None else state
        self.solver.set_state(st.solver_memory)
        wall0, integ_s, blocks = time.perf_counter(), 0.0, 0
        left, tail = self.end.steps_left(st.t_s)
        pieces = [(self.solver, min(self.M, left - k)) for k in range(0, left, self.M)]
        if tail:
            pieces.append((HeunSolver(self.solver.dt).bind(self.model, tail, 1), 1))
        for i, (solver, take) in enumerate(pieces):
            steps = solver.K * solver.M
            t_cols = st.t_s + self.settings.dt_s * np.arange(steps + 1)
            U = self.vehicle.inputs(t_cols)
            solver.set_state(st.solver_memory)
            ti = time.perf_counter()
            X = solver.advance(st.x, U, self.vehicle.p)[:, :take]
            integ_s += time.perf_counter() - ti
            cols = solver.K * np.arange(1, take + 1)
            t, memory = t_cols[cols], solver.memory_samples[:, :take]
            s = self.vehicle.distance_at(t)
            self.recorder.check(X, t, s, st.x)
            blocks += 1
            last = i == len(pieces) - 1
            checkpoint = blocks % checkpoint_every_blocks == 0 or last
            st = self.recorder.record(st, X, U[:, cols], t, s, memory, sink, None, progress, ends=last,
                                      checkpoint=checkpoint)
            if checkpoint and cancel.requested:
                break
        oil = np.array([self.model.idx(f"V_oil[{i}]") for i in range(self.model.n)])
        after = self.vehicle.equilibrium_solver.solve(st.x[self.recorder.T_oil_index], self.gas_masses, st.x[oil])
        return DriveResult(state=st, after=after, wall_s=time.perf_counter() - wall0, integration_s=integ_s)
