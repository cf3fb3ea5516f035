"""Solvers for the vehicle DAE.

`Ros2Stepper` (the production solver): a fixed-step linearly implicit Rosenbrock-W method,
ROS2 of Verwer, Spee, Blom & Hundsdorfer (1999, SIAM J. Sci. Comput. 20(4)):
    W = I - gamma h J,  gamma = 1 + 1/sqrt(2)
    W k1 = f(t_n, y_n)
    W k2 = f(t_n + h, y_n + h k1) - 2 k1
    y_n+1 = y_n + 3/2 h k1 + 1/2 h k2
It is second order for *any* W (a W-method), so J only needs the stiff part of the Jacobian:
the wheel stations, the strut internal states and the hull (seal friction and valves make
them stiff). Slow states (temperatures, levelling, energy quadratures) get W = I, i.e. the
explicit trapezoidal rule. The valve algebraic variables are eliminated inside f by Newton
(index-1 DAE -> ODE). The method is L-stable for the exact Jacobian, so stiff friction sticks
instead of ringing.

Many steps are folded into one call and the whole loop is generated as C, compiled with the
system C compiler and cached (keyed by the hash of the generated code), so Python is touched
once per output sample block, not per step.

`IdasReference`: CasADi's IDAS on the DAE (algebraic valve pressure drops kept as algebraic
variables) with tight tolerances: the reference the fast solver is checked against.
"""
from __future__ import annotations

import time

import casadi as ca
import numpy as np

from vehicle.numerics.codegen import compile_function

GAMMA = 1.0 - 1.0 / np.sqrt(2.0)


def sparse_lu(A: ca.SX):
    """Symbolic sparse LU without pivoting, A = L U, in the given order: (L, U) as dicts of rows.

    For W = I - gamma h J of the vehicle (stations first, hull last) the pivots are the
    diagonal of a matrix close to I plus a dissipative part, so no pivoting is needed, and the
    elimination order keeps the fill inside the hull block (arrowhead structure).
    Returns a function that solves A x = b for SX b.
    """
    n = A.size1()
    sp = A.sparsity()
    rows = [dict() for _ in range(n)]
    colind, row = sp.colind(), sp.row()
    for j in range(n):
        for k in range(colind[j], colind[j + 1]):
            rows[row[k]][j] = A.nz[k]
    lower = [dict() for _ in range(n)]
    for k in range(n):
        pivot_row = rows[k]
        pivot = pivot_row.get(k)
        if pivot is None:
            raise ValueError(f"structurally zero pivot at {k}")
        for i in range(k + 1, n):
            if k not in rows[i]:
                continue
            l = rows[i].pop(k) / pivot
            lower[i][k] = l
            for j, a in pivot_row.items():
                if j > k:
                    rows[i][j] = rows[i][j] - l * a if j in rows[i] else -l * a
    upper = rows

    def solve(b):
        y = [b[i] for i in range(n)]
        for i in range(n):
            for k, l in lower[i].items():
                y[i] = y[i] - l * y[k]
        xs = [None] * n
        for i in reversed(range(n)):
            acc = y[i]
            for j, a in upper[i].items():
                if j > i:
                    acc = acc - a * xs[j]
            xs[i] = acc / upper[i][i]
        return ca.vertcat(*xs)

    return solve


class Ros2Stepper:
    """Compiled fixed-step ROS2 over blocks of steps.

    `advance(x, U, p)`: U has shape (nu, K*M + 1): the inputs at every step boundary for M
    output samples of K steps each. Returns the states at the M sample instants (nx, M).
    """

    def __init__(self, f: ca.Function, nx: int, nu: int, np_: int, n_stiff: int, dt: float,
                 steps_per_sample: int, samples_per_call: int, compile: bool = True,
                 memory_index=(), jacobian: ca.Function | None = None):
        self.dt, self.K, self.M = float(dt), int(steps_per_sample), int(samples_per_call)
        self.nx, self.nu = nx, nu
        x = ca.SX.sym("x", nx)
        u0 = ca.SX.sym("u0", nu)
        u1 = ca.SX.sym("u1", nu)
        p = ca.SX.sym("p", np_)
        h = self.dt
        f0, mem0 = f(x, u0, p)
        ns = n_stiff
        # W only needs the stiff physics (any W keeps order 2): a structural Jacobian if given
        J = jacobian(x, u0, p) if jacobian is not None else ca.jacobian(f0[:ns], x[:ns])
        W = ca.SX.eye(ns) - GAMMA * h * J
        lu_solve = sparse_lu(W)

        def solve(b):
            return ca.vertcat(lu_solve(b[:ns]), b[ns:])

        k1 = solve(f0)
        f1, mem1 = f(x + h * k1, u1, p)
        k2 = solve(f1 - 2.0 * k1)
        x_next = x + 1.5 * h * k1 + 0.5 * h * k2
        # warm starts of the eliminated algebraic variables: the last stage's solution
        for j, k in enumerate(memory_index):
            x_next[int(k)] = mem1[j]
        step = ca.Function("ros2_step", [x, u0, u1, p], [x_next])
        # K steps -> one sample (inputs per step as columns), then M samples per call
        sample = step.fold(self.K)
        block = sample.mapaccum("ros2_block", self.M)
        Xs = ca.MX.sym("x0", nx)
        U = ca.MX.sym("U", nu, self.K * self.M + 1)
        P = ca.MX.sym("p", np_)
        U0 = U[:, : self.K * self.M]
        U1 = U[:, 1:]
        # regroup: sample m uses columns m*K .. m*K+K-1 of U0 and U1
        out = block(Xs, U0, U1, ca.repmat(P, 1, self.K * self.M))
        fn = ca.Function(f"hpsim_ros2_{nx}_{self.K}x{self.M}", [Xs, U, P], [out])
        t0 = time.perf_counter()
        self.fn = compile_function(fn) if compile else fn
        self.build_s = time.perf_counter() - t0

    def advance(self, x0: np.ndarray, U: np.ndarray, p: np.ndarray) -> np.ndarray:
        return np.asarray(self.fn(x0, U, p))


class IdasReference:
    """Tight-tolerance reference: IDAS on the DAE with the valve pressure drops as algebraic
    variables (no Newton elimination, no fixed step, no structural Jacobian).

    Inputs (road under each tyre, speed, ambient) are given per chunk on a fine time grid and
    interpolated linearly inside IDAS (a parametric CasADi interpolant), so one integrator object
    serves the whole drive. Slow but independent of the production solver's choices.
    """

    def __init__(self, model, chunk_s: float, input_dt_s: float = 1e-3, rtol: float = 1e-8, atol: float = 1e-9,
                 outputs_per_chunk: int = 1):
        self.model = model
        self.chunk_s = float(chunk_s)
        self.n_in = int(round(chunk_s / input_dt_s)) + 1
        self.grid = np.linspace(0.0, chunk_s, self.n_in)
        x, z, u_unused, p = model.symbols
        t = ca.SX.sym("t")
        data = ca.SX.sym("U", model.nu * self.n_in)
        interp = ca.interpolant("U", "linear", [self.grid], model.nu)
        u = interp(t, data)
        ode, alg, _ = model.equations(x, z, u, p)
        # the warm-start memory of the fixed-step solver has no meaning here: hold it constant
        dae = {"t": t, "x": x, "z": z, "p": ca.vertcat(p, data), "ode": ca.vertcat(*ode),
               "alg": ca.vertcat(*alg) / 1e-4}
        tout = np.linspace(0.0, chunk_s, outputs_per_chunk + 1)[1:]
        self.integrator = ca.integrator("reference", "idas", dae, 0.0, tout,
                                        {"reltol": rtol, "abstol": atol, "max_num_steps": 10 ** 7,
                                         "calc_ic": True, "max_step_size": input_dt_s})

    def advance(self, x0, z0, U, p):
        """U: (nu, n_in) inputs on the chunk's grid. Returns (X at the outputs, z at the end)."""
        sol = self.integrator(x0=x0, z0=z0, p=np.concatenate([p, U.ravel(order="F")]))
        return np.asarray(sol["xf"]), np.asarray(sol["zf"])[:, -1]
