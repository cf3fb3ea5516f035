"""The slow manifold of a drive: the vehicle standing in equilibrium as a function of its slow states (thermal
nodes, filtered deflection, levelling oil), how every state moves with them (the slaving matrix), the drive's
distance -> time map, and how the after-drive wheel loads move with the final temperatures and oil volumes.

A part that the multiscale windows, the time-parallel coarse propagation and its join share (docs/CONTRIBUTING.md).
The linear flow of the slow states across the stretches not simulated is `vehicle.engines.slow_flow.LinearFlow`.
"""
from __future__ import annotations

import numpy as np


class SlowManifold:
    """The standing vehicle at given slow states, for one model, charge and drive.

    Parameters
    ----------
    model            the vehicle model (vehicle.physics.model.VehicleModel)
    equilibrium      its equilibrium solver (vehicle.physics.equilibrium.equilibrium_solver)
    gas_masses       the struts' gas masses [kg]
    T_oil_index      the oil temperature state of each station (what the standing vehicle's gas follows)
    s_grid, t_grid   the drive's distance [m] -> time [s] table (`SpeedProfile.time_grid`)
    """

    def __init__(self, model, equilibrium, gas_masses: np.ndarray, T_oil_index: np.ndarray, s_grid: np.ndarray,
                 t_grid: np.ndarray):
        self.model, self.equilibrium, self.gas_masses = model, equilibrium, gas_masses
        self.T_oil_index = T_oil_index
        self.slow_index = np.asarray(model.slow_state_indices(), int)
        self.ext_index = np.arange(model.n_dynamic, model.nx)
        self.oil_index = np.array([model.idx(f"V_oil[{i}]") for i in range(model.n)])
        self.s_grid, self.t_grid = s_grid, t_grid
        self._slaving_matrix: np.ndarray | None = None

    def time_at(self, s_m: float) -> float:
        """The drive's time [s] at distance s_m [m]."""
        return float(np.interp(s_m, self.s_grid, self.t_grid))

    def rest_state(self, x_prev: np.ndarray) -> np.ndarray:
        """The vehicle standing in equilibrium at x_prev's slow states, with x_prev's slow states and quadratures."""
        eq = self.equilibrium.solve(x_prev[self.T_oil_index], self.gas_masses, x_prev[self.oil_index])
        return self._at_rest(eq, x_prev)

    def rest_states(self, xs: list) -> list:
        """`rest_state` of each x in xs, their equilibria solved together (`EquilibriumSolver.solve_many`: the same
        numbers as one by one)."""
        eqs = self.equilibrium.solve_many([x[self.T_oil_index] for x in xs], self.gas_masses,
                                          [x[self.oil_index] for x in xs])
        return [self._at_rest(eq, x) for eq, x in zip(eqs, xs)]

    def _at_rest(self, eq, x_prev: np.ndarray) -> np.ndarray:
        x = self.model.state_at_rest(eq, self.gas_masses)
        x[self.slow_index] = x_prev[self.slow_index]
        x[self.ext_index] = x_prev[self.ext_index]
        return x

    def slaving(self, x: np.ndarray) -> np.ndarray:
        """S = dx/dx_slow (nx, ns) on the manifold of the vehicle at rest (`rest_state`), at x the first time.

        The slow states move one to one, the fast ones as the standing vehicle's do (gas temperatures with the
        strut temperature, deflections with gas expansion and oil), the quadratures not at all. Finite
        differences, computed once per drive (it changes little with the slow states). The standing vehicle
        depends on the oil's temperatures and volumes only: any other slow state's column is its own unit
        column, written without an equilibrium solve (the solve would repeat the base's numbers).
        """
        if self._slaving_matrix is not None:
            return self._slaving_matrix
        S = np.zeros((self.model.nx, len(self.slow_index)))
        standing_inputs = set(self.T_oil_index.tolist()) | set(self.oil_index.tolist())
        moved = []                      # (column, step, perturbed state) of the standing vehicle's inputs
        for k, j in enumerate(self.slow_index):
            h = 1e-4 * max(abs(x[j]), 1e-3)
            xp = x.copy()
            xp[j] += h
            if j in standing_inputs:
                moved.append((k, h, xp))
            else:
                S[j, k] = (xp[j] - x[j]) / h
        base, *rests = self.rest_states([x] + [xp for _, _, xp in moved])
        for (k, h, _), rest in zip(moved, rests):
            S[:, k] = (rest - base) / h
        self._slaving_matrix = S
        return S

    def share_slaving(self, S: np.ndarray) -> None:
        """Use S, computed by another process for the same drive, as this manifold's slaving matrix."""
        self._slaving_matrix = S

    def load_sensitivity(self, x_end: np.ndarray, after, W_ax: np.ndarray, loads_before_N: np.ndarray,
                         compensation: bool, dT: float = 0.5, dV: float = 1e-6) -> np.ndarray:
        """d(per-axle wheel load change [pp of the before-drive load])/d(final T_oil per station [K], V_oil per
        station [m^3]), shape (axles, 2 n), by forward differences of dT and dV about the after-drive equilibrium
        `after` (the V_oil columns zero without compensation: the oil volumes do not move)."""
        m = self.model
        N0 = W_ax @ np.asarray(loads_before_N, float)
        T, V = x_end[self.T_oil_index].copy(), x_end[self.oil_index].copy()
        N1 = W_ax @ np.asarray(after.wheel_loads_N, float)
        T_rows, V_rows = np.tile(T, (m.n, 1)), np.tile(V, (m.n, 1))
        T_rows[np.arange(m.n), np.arange(m.n)] += dT
        steps = [dT] * m.n
        if compensation:
            V_plus = np.tile(V, (m.n, 1))
            V_plus[np.arange(m.n), np.arange(m.n)] += dV
            T_rows, V_rows = np.vstack([T_rows, np.tile(T, (m.n, 1))]), np.vstack([V_rows, V_plus])
            steps += [dV] * m.n
        cols = [100.0 * (W_ax @ np.asarray(e.wheel_loads_N, float) - N1) / N0 / h
                for e, h in zip(self.equilibrium.solve_many(T_rows, self.gas_masses, V_rows), steps)]
        if not compensation:
            cols += [np.zeros(len(N0))] * m.n
        return np.array(cols).T
