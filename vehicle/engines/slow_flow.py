"""The slow states' linear flow between and across ride windows (docs/engines.md, "Multiscale mode"):
the slow-rate Jacobian, each window's forcing at one reference state, e^{A t} and its integral, the
warm-up correction, and the stated error's Student-t factor. Pure functions of NumPy arrays (the
Jacobian: CasADi AD of the vehicle model)."""
from __future__ import annotations

import casadi as ca
import numpy as np

from vehicle.numerics.codegen import Library, compile_function

ERROR_COVERAGE = 0.95       # the stated error: a 95 % interval of the sampling error (Student t, see error_factor)


def matrix_exponential(M: np.ndarray) -> np.ndarray:
    """The matrix exponential (scipy.linalg.expm), imported on first use: a drive whose flows decompose (`LinearFlow`)
    never needs it, and SciPy's linalg package takes ~0.1 s to import."""
    from scipy.linalg import expm

    return expm(M)


def error_factor(dof: int) -> float:
    """Standard deviations in the stated error: the two-sided ERROR_COVERAGE quantile of Student's t with the
    estimate's degrees of freedom (the windows' scatter is estimated from few windows: 3.2 for 3, 2.1 for 20)."""
    # scipy.special's inverse of Student's t distribution, which scipy.stats.t.ppf evaluates (the same numbers);
    # scipy.stats would cost ~0.4 s to import
    from scipy.special import stdtrit

    return float(stdtrit(max(int(dof), 1), 0.5 + ERROR_COVERAGE / 2))




def slow_rate_library(model) -> Library:
    """J(x, memory, u, p) = d(rates of the slow states)/d(all states) (CasADi AD of model.ode_function) as a
    `codegen.Library`: compiled, and found in the compile cache by the model's structure without building the
    model's equations."""
    name = f"hpsim_jslow_{model.structure}"

    def build():
        idx = model.slow_state_indices()
        x, _, u, p = model.symbols
        mem = model.memory_symbol
        f, _ = model.ode_function(x, mem, u, p)
        fs = ca.vertcat(*[f[i] for i in idx])
        return ca.Function(name, [x, mem, u, p], [ca.jacobian(fs, x)])
    return Library(name, ("J_slow", model.structure), build)


def slow_rate_jacobian(model, compiled: bool = True):
    """`slow_rate_library`'s function, compiled (or in CasADi's virtual machine); once per model object."""
    key = "_multiscale_slow_jacobian"
    fn = model.__dict__.get(key)
    if fn is None:
        lib = slow_rate_library(model)
        fn = compile_function(lib) if compiled else lib.graph()
        model.__dict__[key] = fn
    return fn


def window_forcings(A: np.ndarray, r: np.ndarray, xbar: np.ndarray, x_ref: np.ndarray | None = None) -> np.ndarray:
    """Each window's slow rates carried to one reference slow state by the window's own linearisation:
        b_k = r_k + A_k (x_ref - xbar_k)          (A: (nw, ns, ns), r and xbar: (nw, ns); x_ref: mean of xbar)
    what window k's road would drive at x_ref (docs/engines.md, "Window forcings"). Where the state
    dependence itself depends on the road (the oil film coefficient grows with the stroking and multiplies
    the oil-to-wall temperature difference), r_k - Abar xbar_k (one mean Jacobian) keeps the product of the
    road's and the state's deviations, which a road proxy cannot explain; b_k keeps the road's deviation at
    one state. Exact to first order about each window's own state (remainder: the curvature f''/2 times
    (x_ref - xbar_k)^2). A linear model (A_k = A) gives r_k - A xbar_k plus a constant: the same scatter."""
    A, r, xbar = np.asarray(A, float), np.asarray(r, float), np.asarray(xbar, float)
    if x_ref is None:
        x_ref = xbar.mean(axis=0)
    return r + np.einsum("kij,kj->ki", A, x_ref[None, :] - xbar)


def propagators(A: np.ndarray, b: np.ndarray, tau: float):
    """(e^{A tau}, int_0^tau e^{A s} ds b, int_0^tau e^{A s} ds) by one augmented matrix exponential."""
    n = A.shape[0]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = A * tau
    M[:n, n:] = np.eye(n) * tau
    E = matrix_exponential(M)
    Phi, Gam = E[:n, :n], E[:n, n:]
    return Phi, Gam @ b, Gam


def warm_up_correction(flow, b: np.ndarray, x_start: np.ndarray, x_warm_end: np.ndarray, tw: float,
                       L: float) -> np.ndarray:
    """What to add to a window's simulated end state (slow states) so that its warm-up counts as crossed by the
    window's averaged model x' = b + A x (`flow`: A) instead of as simulated: the modelled state at the warm-up's
    end, e^{A tw} x_start + int_0^tw e^{A s} ds b, less the simulated one x_warm_end. That difference is carried
    through the averaged stretch of duration L by e^{A L} (the simulated stretch started from x_warm_end; for the linear model exactly
    x_end(x_warm_end + d) = x_end(x_warm_end) + e^{A L} d)."""
    d = flow.phi(tw) @ x_start + flow.gamma(tw) @ b - x_warm_end
    return flow.phi(L) @ d


def total_variation_along(flow, x0: np.ndarray, b: np.ndarray, tau: float, rows: np.ndarray,
                          points: int = 64) -> np.ndarray:
    """Total variation of the slow states `rows` (positions in x0) along the linear flow x' = A x + b from x0 over
    [0, tau]: int |x_i'| dt, from the trajectory at `points` times spaced quadratically (dense at the start, where
    the short modes turn). For the levelling oil volume it is the oil the pump moves across a stretch not
    simulated, which the net change |x_i(tau) - x_i(0)| underestimates when the flow turns."""
    if tau <= 0:
        return np.zeros(len(rows))
    t = tau * (np.arange(points + 1) / points) ** 2
    path = np.array([flow.phi(tk)[rows] @ x0 + flow.gamma(tk)[rows] @ b for tk in t])
    return np.sum(np.abs(np.diff(path, axis=0)), axis=0)


class LinearFlow:
    """e^{A t} and int_0^t e^{A s} ds of one matrix A for many t, by its eigen-decomposition (one per drive
    instead of a matrix exponential per call); falls back to `propagators` if A's eigenvectors are ill
    conditioned."""

    def __init__(self, A: np.ndarray):
        self.A = A
        lam, V = np.linalg.eig(A)
        self.ok = bool(np.all(np.isfinite(lam))) and np.linalg.cond(V) < 1e6
        if self.ok:
            self.lam, self.V, self.Vi = lam, V, np.linalg.inv(V)

    def phi(self, t: float) -> np.ndarray:
        if not self.ok:
            return matrix_exponential(self.A * t)
        return np.real((self.V * np.exp(self.lam * t)) @ self.Vi)

    def gamma(self, t: float) -> np.ndarray:
        if not self.ok:
            return propagators(self.A, np.zeros(self.A.shape[0]), t)[2]
        z = self.lam * t
        small = np.abs(z) < 1e-8
        g = np.where(small, t * (1 + z / 2), np.expm1(np.where(small, 1.0, z)) / np.where(small, 1.0, self.lam))
        return np.real((self.V * g) @ self.Vi)
