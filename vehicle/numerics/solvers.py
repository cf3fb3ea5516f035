"""Solvers for the vehicle DAE.

`Ros2` (the production solver): a fixed-step linearly implicit Rosenbrock-W method,
ROS2 of Verwer, Spee, Blom & Hundsdorfer (1999, SIAM J. Sci. Comput. 20(4)):
    W = I - gamma h J,  gamma = 1 - 1/sqrt(2)
    W k1 = f(t_n, y_n)
    W k2 = f(t_n + h, y_n + h k1) - 2 k1
    y_n+1 = y_n + 3/2 h k1 + 1/2 h k2
The family is L-stable for gamma = 1 +- 1/sqrt(2). (The z^2 term of its stability function's
numerator, 1/2 - 2 gamma + gamma^2, vanishes.) Verwer et al. take the larger root, this engine the
smaller (docs/physics.md uses it for the stage overshoot of an under-resolved mode, 1/gamma - 1).
It is second order for *any* W (a W-method), so J only needs the stiff part of the Jacobian:
the wheel stations, the strut internal states and the hull (seal friction and valves make
them stiff). Slow states (temperatures, levelling, energy quadratures) get W = I, i.e. the
explicit trapezoidal rule. The exceptions are the quadratures of indicator functions (time lifted off, on an end
stop, above each travel-bin edge: `VehicleModel.indicator_quadrature_indices`), whose integrands jump:
the trapezoid's order is lost at every crossing, so they take the rectangle rule on the first stage
(y_n+1 = y_n + h g(y_n), which is also cheaper). The physical states are bit-identical; the times above a
threshold move by less than a step per crossing, with zero mean. The valve algebraic variables are eliminated inside f by Newton
(index-1 DAE -> ODE). The method is L-stable for the exact Jacobian, so stiff friction sticks
instead of ringing.

Many steps are folded into one call and the whole loop is generated as C, compiled with the
system C compiler and cached (keyed by the hash of the generated code), so Python is touched
once per output sample block, not per step. That block function (`vehicle.numerics.lanes`, one lane, batched
calls) takes the step split around the struts where the vehicle allows (`split_step_functions`,
vehicle.numerics.split_step): the strut kernel of all stations in one vector, the rest scalar.

`Idas`: CasADi's IDAS on the DAE (algebraic valve pressure drops kept as algebraic variables)
with tight tolerances: the reference the fast solver is checked against.

Both are solver objects with one interface (`bind(model, steps_per_sample, samples_per_call)`,
`advance(x0, U, p)`, `get_state()`/`set_state()` for what they carry between calls), passed to a
drive rather than chosen inside it.
"""
from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import casadi as ca
import numpy as np

from vehicle.numerics.contract import SolverCapabilities
from vehicle.numerics.codegen import Library, compile_function
from vehicle.numerics.lanes import BatchedBlock, LaneStepper
from vehicle.numerics import split_step
from vehicle.numerics.step_graph import GAMMA, SparseLU, explicit_reciprocals, lift_parameters

# the most steps of one output sample generated as straight-line code; longer samples loop over pieces of this
# many steps (the default 1 s at 4 ms is 250 steps: unrolled)
MAX_UNROLLED_STEPS = 250


def _pieces(K: int, piece: int | None = None) -> list[int]:
    """How a sample of K steps is generated: [K] (unrolled) or [n] * (K // n) + [K % n] with n = `piece` (default
    MAX_UNROLLED_STEPS)."""
    n = MAX_UNROLLED_STEPS if piece is None else piece
    if K <= MAX_UNROLLED_STEPS:
        return [K]
    R, rest = divmod(K, n)
    return [n] * R + ([rest] if rest else [])


def _steps(step, z, U0, U1, PW):
    """The state after the steps with inputs U0, U1 (one column per step) from z, unrolled."""
    zk = z
    for u0, u1 in zip(ca.horzsplit(U0), ca.horzsplit(U1)):
        zk = step(zk, u0, u1, PW)
    return zk


def _unrolled_steps(steps, n: int, nz: int, nu: int, npw: int) -> ca.Function:
    """n steps unrolled by `steps` (see `block_function`) as a function (z, u0 (nu, n), u1 (nu, n), pw) -> z."""
    zs, PW = ca.MX.sym("z", nz), ca.MX.sym("pw", npw)
    U0k, U1k = ca.MX.sym("u0", nu, n), ca.MX.sym("u1", nu, n)
    return ca.Function(f"ros2_steps_{n}", [zs, U0k, U1k, PW], [steps(zs, U0k, U1k, PW)])


def block_function(name: str, steps, parametric: ca.Function, K: int, M: int, nz: int, nu: int,
                   piece: int | None = None) -> ca.Function:
    """The block function (z0, U (nu, K M + 1), p) -> z at the M sample instants (nz, M) of a step given as
    `steps(z, U0, U1, pw) -> z` (unrolling one step per column of U0, U1; pw = parametric(p)).

    K steps make one sample, unrolled by hand so that every step reads the same parameter vector: neither carried
    through the loop's accumulator (a load and a store of every parameter per step) nor copied into a matrix. A long
    output interval (K > MAX_UNROLLED_STEPS) is a loop (`Function.fold`) over pieces of `piece` steps, so the code
    stays the size of one piece whatever the interval. The parameter vector is repeated once per sample."""
    npw = parametric.size1_out(0)
    zs = ca.MX.sym("z", nz)
    U0k, U1k = ca.MX.sym("u0", nu, K), ca.MX.sym("u1", nu, K)
    PW = ca.MX.sym("pw", npw)
    pieces = _pieces(K, piece)
    if len(pieces) == 1:
        zk = steps(zs, U0k, U1k, PW)
    else:
        units = {n: _unrolled_steps(steps, n, nz, nu, npw) for n in set(pieces)}
        zk, k0, rest = zs, 0, pieces
        n_long, R = pieces[0], pieces.count(pieces[0])
        if R > 1:
            # R pieces of n_long steps in a loop (the C code holds one piece), then the remainder
            zk = units[n_long].fold(R)(zk, U0k[:, :R * n_long], U1k[:, :R * n_long], ca.repmat(PW, 1, R))
            k0, rest = R * n_long, pieces[R:]
        for n in rest:
            zk = units[n](zk, U0k[:, k0:k0 + n], U1k[:, k0:k0 + n], PW)
            k0 += n
    sample = ca.Function("ros2_sample", [zs, U0k, U1k, PW], [zk])
    block = sample.mapaccum("ros2_block", M)
    Z0 = ca.MX.sym("z0", nz)
    U = ca.MX.sym("U", nu, K * M + 1)
    P = ca.MX.sym("p", parametric.size1_in(0))
    n = K * M
    out = block(Z0, U[:, :n], U[:, 1:], ca.repmat(parametric(P), 1, M))
    return ca.Function(name, [Z0, U, P], [out])


@dataclass
class Ros2Stages:
    """The two stages of one ROS2 step as SX: f0 = f(t_n, y_n), k1, k2, the step's result x_next = y_n + 3/2 h k1 +
    1/2 h k2 (every state by the method), the memory after it (the second stage's warm starts) and the SparseLU of
    its W (None when the caller solved with its own)."""

    f0: ca.SX
    k1: ca.SX
    k2: ca.SX
    x_next: ca.SX
    mem_next: ca.SX
    lu: SparseLU | None


def ros2_stages(model, h: float, x, mem, u0, u1, p, solve_stiff=None) -> Ros2Stages:
    """One ROS2 step of `model` from (x, mem) with step h (the module docstring's equations). W = I - gamma h J on the
    stiff states only (any W keeps order 2), the slow states W = I. solve_stiff(b): a solver of W on the stiff
    states to use instead of the W of the exact stiff Jacobian at (x, u0), which is made and factorised here."""
    ns = model.n_stiff
    f0, _ = model.ode_function(x, mem, u0, p)
    lu = None
    if solve_stiff is None:
        J = model.jacobian_function(x, mem, u0, p)
        lu = SparseLU(ca.SX.eye(ns) - GAMMA * h * J)
        solve_stiff = lu.solve

    def solve(b):
        return ca.vertcat(solve_stiff(b[:ns]), b[ns:])

    k1 = solve(f0)
    f1, mem1 = model.ode_function(x + h * k1, mem, u1, p)
    k2 = solve(f1 - 2.0 * k1)
    return Ros2Stages(f0, k1, k2, x + 1.5 * h * k1 + 0.5 * h * k2, mem1, lu)


def advance_block(fn, nx: int, x0: np.ndarray, memory: np.ndarray, U: np.ndarray, p: np.ndarray) -> tuple:
    """One call of a block function fn (z0, U, p) -> Z (nx + n_memory, M) from the states x0 and the memory: (the
    states at the M sample instants (nx, M), the memory at each of them (output evaluation), the memory after the
    block)."""
    Z = np.asarray(fn(np.concatenate([x0, memory]), U, p))
    return Z[:nx], Z[nx:], Z[nx:, -1].copy()


def indicators_by_rectangle(model, h: float, x, st: Ros2Stages) -> ca.SX:
    """The step's result `st.x_next` with the indicator quadratures (`VehicleModel.indicator_quadrature_indices`)
    taken by the rectangle rule on the first stage, x + h f0 (module docstring); the other states as they are."""
    x_next = st.x_next
    # their integrands jump, so the trapezoid's second order is lost anyway (both rules err by O(h) at each
    # crossing, with zero mean); the second stage's indicators are then unused and left out of the generated code
    for k in model.indicator_quadrature_indices():
        x_next[k] = x[k] + h * st.f0[k]
    return x_next


class Ros2:
    """The production solver: compiled fixed-step ROS2 over blocks of steps (see the module docstring).

    A solver object is passed to a drive (`vehicle.engines.full.Drive(..., solver=Ros2(dt=0.004))`)
    and bound to a model there (`bind`). It owns the warm-start memory of the eliminated valve
    pressure drops (`memory`), which a checkpoint saves (`get_state`/`set_state`).

    Parameters enter the compiled code as an input: the subexpressions that depend only on
    parameters (viscosity law coefficients, reciprocals of masses, ...) are lifted out of the step
    by `casadi.extract_parametric` and evaluated once per call, so a parameter change reuses the
    compiled library and costs no speed per step.

    batch_calls: the step's exp/log/tanh/pow calls gathered into vector calls (`vehicle.numerics.lanes`) where the
    compiler allows, else CasADi's C. strut_lanes: the step split around the struts (`split_step_functions`);
    False builds the whole step.
    """

    name = "ros2"

    def __init__(self, dt: float = 0.004, *, compile: bool = True, batch_calls: bool = True,
                 strut_lanes: bool = True):
        self.dt = float(dt)
        self.compile = compile
        # the step's exp/log/tanh/pow calls gathered into vector calls (vehicle.numerics.lanes.emit_batched; the
        # same bits): where it applies (compiled, GCC or Clang), else CasADi's C
        self.batch_calls = batch_calls and compile
        # the step split around the struts, their part over lanes of stations (vehicle.numerics.split_step), in
        # the batched block function and the ensemble's lanes; strut_lanes=False: the whole step
        self.strut_lanes = bool(strut_lanes)
        self.memory = None
        self.build_s = 0.0
        self.K, self.M = 1, 1              # steps per sample, samples per call: set by `bind`

    @property
    def capabilities(self) -> SolverCapabilities:
        """Compiled block functions (and block outputs) when compiled; step doubling."""
        return SolverCapabilities(compiled=self.compile, step_doubling=True, compiled_outputs=self.compile)

    def describe(self) -> dict:
        return {"solver": self.name, "dt_s": self.dt, "compiled": self.compile}

    def _key(self, model, K: int, M: int) -> tuple:
        return (model.structure, self.dt, K, M, self.compile, self.batch_calls, self.batch_calls and self.strut_lanes)

    def block_graph(self, model, steps_per_sample: int, samples_per_call: int) -> Library | None:
        """The block function `bind` would compile for this model, as a `codegen.Library` (its graph built only when
        the compile cache misses it), or None when this process holds it compiled already or the solver runs
        uncompiled: what a drive hands to `codegen.precompile` to build its libraries together."""
        K, M = int(steps_per_sample), int(samples_per_call)
        key = self._key(model, K, M)
        if not self.compile or key in _BLOCK_FUNCTIONS:
            return None
        if self.batch_calls:
            stepper = self._batched_stepper(model, load=False)
            if stepper is not None:
                return None if stepper.library is not None else stepper.spec
        return self._library(model, K, M)

    @staticmethod
    def _block_name(model, K: int, M: int) -> str:
        return f"hpsim_ros2_{model.structure}_{K}x{M}"

    def _library(self, model, K: int, M: int) -> Library:
        """The block function for (K, M) as a `codegen.Library`: its name and key, its graph built on demand (once
        per process: kept in _GRAPHS until `bind` compiles it)."""
        key = self._key(model, K, M)

        def build():
            if key not in _GRAPHS:
                _GRAPHS[key] = self.block_function(model, K, M)
            return _GRAPHS[key]
        return Library(self._block_name(model, K, M), key, build)

    def bind(self, model, steps_per_sample: int, samples_per_call: int) -> "Ros2":
        """Build (or fetch from the caches) the compiled block function for this model's structure."""
        t0 = time.perf_counter()
        self.K, self.M = int(steps_per_sample), int(samples_per_call)
        self.nx, self.nmem = model.nx, model.n_memory
        key = self._key(model, self.K, self.M)
        fn = _BLOCK_FUNCTIONS.get(key)
        if fn is None:
            stepper = self._batched_stepper(model) if self.batch_calls else None
            if stepper is not None:
                fn = BatchedBlock(stepper, self.K, self.M)
            else:
                lib = self._library(model, self.K, self.M)
                fn = compile_function(lib) if self.compile else lib.graph()
                _GRAPHS.pop(key, None)
            _BLOCK_FUNCTIONS[key] = fn
        self.fn = fn
        self.memory = model.initial_memory()
        self.build_s = time.perf_counter() - t0
        return self

    def stages(self, model, x, mem, u0, u1, p) -> tuple:
        """One ROS2 step from (x, mem) as SX: (x_next, mem_next, the SparseLU of its W). The indicator quadratures
        (`VehicleModel.indicator_quadrature_indices`) take the rectangle rule (module docstring)."""
        st = ros2_stages(model, self.dt, x, mem, u0, u1, p)
        return indicators_by_rectangle(model, self.dt, x, st), st.mem_next, st.lu

    @staticmethod
    def step_symbols(model):
        """(x, memory, u at the step's start, u at its end) of one step, as SX symbols."""
        return (ca.SX.sym("x", model.nx), ca.SX.sym("mem", model.n_memory), ca.SX.sym("u0", model.nu),
                ca.SX.sym("u1", model.nu))

    def step_functions(self, model) -> tuple:
        """(step, parametric) as SX functions: one step (z, u0, u1, pw) -> z_next and pw = parametric(p): the
        parameters with the parameter-only subexpressions lifted out of the step. Divisions are explicit reciprocals
        in the graph (`explicit_reciprocals`), so scalar and vector code round alike. What the block function
        unrolls, what an FMU wraps (vehicle.fmu) and what `vehicle.numerics.lanes` turns into code over many cases."""
        x, mem, u0, u1 = self.step_symbols(model)
        p = ca.SX.sym("p", model.np)
        z = ca.vertcat(x, mem)
        x_next, mem1, _ = self.stages(model, x, mem, u0, u1, p)
        raw = ca.Function("ros2_step_raw", [z, u0, u1, p], [ca.vertcat(x_next, mem1)])
        # merge repeated subexpressions (the eight stations share one strut's parameter symbols, and
        # f, its Jacobian and the two stages rebuild the same terms): a much shorter step,
        # exact up to rounding order (docs/engines.md); then lift what depends on the parameters only out of the
        # step: computed once per call
        args, parts, pw, parametric = lift_parameters(raw, 3, "ros2_parametric")
        z, u0, u1 = args[:3]
        step = ca.Function("ros2_step", [z, u0, u1, pw], parts[:1])
        return explicit_reciprocals(step), explicit_reciprocals(parametric)

    def split_step_functions(self, model) -> split_step.SplitStep | None:
        """The step split around the struts (`vehicle.numerics.split_step`), or None where it does not apply
        (`strut_lanes=False`, or a model without one strut kernel for all stations): the whole step
        (`step_functions`) then."""
        if not self.strut_lanes:
            return None
        return split_step.build(self, model)

    def block_function(self, model, K: int, M: int) -> ca.Function:
        """The uncompiled block function of this model for blocks of M samples of K steps (`block_function`)."""
        step, parametric = self.step_functions(model)
        return block_function(self._block_name(model, K, M), lambda z, U0, U1, PW: _steps(step, z, U0, U1, PW),
                              parametric, K, M, model.nx + model.n_memory, model.nu)

    def refined_solver(self, factor: int) -> "Ros2":
        """The same solver with the step divided by `factor`, unbound."""
        return type(self)(self.dt / factor, compile=self.compile, batch_calls=self.batch_calls,
                          strut_lanes=self.strut_lanes)

    def _batched_stepper(self, model, load: bool = True) -> LaneStepper | None:
        """The one-lane block library with batched calls for this model structure and step (one per process and
        (structure, dt); K and M are arguments of its calls), or None where it cannot be built (a compiler
        without GCC's vector extension: CasADi's C then). load=False: its C only, unless built already."""
        key = ("batched", model.structure, self.dt, self.strut_lanes)
        if key not in _BLOCK_FUNCTIONS:
            _BLOCK_FUNCTIONS[key] = LaneStepper(self, model, 1, batched=True, load=False)
        stepper = _BLOCK_FUNCTIONS[key]
        if load and stepper is not None and stepper.library is None:
            try:
                stepper.load()
            except RuntimeError as e:
                warnings.warn(f"the batched step could not be built ({e}); using CasADi's C")
                stepper = _BLOCK_FUNCTIONS[key] = None
        return stepper

    def advance(self, x0: np.ndarray, U: np.ndarray, p: np.ndarray) -> np.ndarray:
        """States at the M sample instants (nx, M) from x0 and the inputs U (nu, K*M+1) at every step."""
        X, self.memory_samples, self.memory = advance_block(self.fn, self.nx, x0, self.memory, U, p)
        return X

    def get_state(self) -> np.ndarray:
        return np.asarray(self.memory, float).copy()

    def set_state(self, memory) -> None:
        self.memory = np.asarray(memory, float).reshape(self.nmem).copy()


# compiled block functions of this process by (model structure, dt, K, M, compile, ...), and the compiled
# block outputs by ("outputs", structure, n, compile): a sweep, a
# calibration or a notebook that changes parameters reuses them (the compile cache on disk serves
# other processes)
_BLOCK_FUNCTIONS: dict = {}
# uncompiled block functions built for `codegen.precompile` (Ros2.block_graph), until `bind` compiles them
_GRAPHS: dict = {}


class Idas:
    """Reference solver: IDAS on the DAE with the valve pressure drops as algebraic variables (no
    Newton elimination, no fixed step, no structural Jacobian), tight tolerances.

    Same interface as `Ros2` (`bind`, `advance`, `get_state`/`set_state`): the inputs are
    interpolated linearly between the step-boundary columns of U inside IDAS (a parametric CasADi
    interpolant), so a drive can run on it unchanged. Slow (about 10 s of wall time per simulated
    second for the 8x8), meant for short checks of the production solver.
    """

    name = "idas"
    capabilities = SolverCapabilities()        # uncompiled, no step doubling

    def __init__(self, dt: float = 0.004, *, rtol: float = 1e-8, atol: float = 1e-9):
        self.dt, self.rtol, self.atol = float(dt), rtol, atol
        self.memory = None
        self.build_s = 0.0

    def describe(self) -> dict:
        return {"solver": self.name, "dt_s": self.dt, "rtol": self.rtol, "atol": self.atol}

    def bind(self, model, steps_per_sample: int, samples_per_call: int) -> "Idas":
        t0 = time.perf_counter()
        self.K, self.M = int(steps_per_sample), int(samples_per_call)
        self.model = model
        n_in = self.K * self.M + 1
        chunk_s = self.dt * self.K * self.M
        grid = np.linspace(0.0, chunk_s, n_in)
        x, z, _, p = model.symbols
        t = ca.SX.sym("t")
        data = ca.SX.sym("U", model.nu * n_in)
        u = ca.interpolant("U", "linear", [grid], model.nu)(t, data)
        ode, alg, _ = model.equations(x, z, u, p)
        dae = {"t": t, "x": x, "z": z, "p": ca.vertcat(p, data), "ode": ca.vertcat(*ode),
               "alg": ca.vertcat(*alg) / 1e-4 if alg else ca.SX(0, 1)}
        tout = grid[self.K::self.K]
        self.integrator = ca.integrator("reference", "idas", dae, 0.0, tout,
                                        {"reltol": self.rtol, "abstol": self.atol, "max_num_steps": 10 ** 7,
                                         "calc_ic": True, "max_step_size": self.dt})
        self.memory = np.zeros(model.nz)
        self.build_s = time.perf_counter() - t0
        return self

    def advance(self, x0, U, p):
        sol = self.integrator(x0=x0, z0=self.memory, p=np.concatenate([p, np.asarray(U).ravel(order="F")]))
        Z = np.asarray(sol["zf"]).reshape(self.model.nz, -1)
        self.memory_samples = Z
        if self.model.nz:
            self.memory = Z[:, -1].copy()
        return np.asarray(sol["xf"])

    def get_state(self) -> np.ndarray:
        return np.asarray(self.memory, float).copy()

    def set_state(self, memory) -> None:
        self.memory = np.asarray(memory, float).copy()


SOLVERS = {"ros2": Ros2, "idas": Idas}


def compiled_outputs(model, n: int, compile: bool = True):
    """The model's outputs y(x, memory, u, p) (`VehicleModel.output_function_ode`) at n samples in one compiled call:
    (X (nx, n), memory (n_memory, n), U (nu, n), p (np, 1)) -> (outputs, hull accelerations, axle heights), each
    with n columns. Cached per model structure and n (in this process; on disk by `compile_function`): a drive
    evaluates its block outputs with it instead of in CasADi's virtual machine (same results to rounding). Compiled,
    it is called directly on NumPy arrays (`vehicle.numerics.direct_call`); without a compiler, CasADi's function."""
    key = ("outputs", model.structure, int(n), compile)
    fn = _BLOCK_FUNCTIONS.get(key)
    if fn is None:
        lib = _outputs_library(model, n)
        fn = compile_function(lib, direct=True) if compile else lib.graph()
        _GRAPHS.pop(key, None)
        _BLOCK_FUNCTIONS[key] = fn
    return fn


def _outputs_function(model, n: int) -> ca.Function:
    y = model.output_function_ode()
    X, MEM = ca.MX.sym("X", model.nx, n), ca.MX.sym("memory", model.n_memory, n)
    U, P = ca.MX.sym("U", model.nu, n), ca.MX.sym("p", model.np)
    outs = y.map(n)(X, MEM, U, ca.repmat(P, 1, n))
    return ca.Function(f"hpsim_outputs_{model.structure}_{n}", [X, MEM, U, P], list(outs))


def _outputs_library(model, n: int) -> Library:
    key = ("outputs", model.structure, int(n), True)

    def build():
        if key not in _GRAPHS:
            _GRAPHS[key] = _outputs_function(model, n)
        return _GRAPHS[key]
    return Library(f"hpsim_outputs_{model.structure}_{int(n)}", key, build)


def outputs_graph(model, n: int) -> Library | None:
    """The function of `compiled_outputs(model, n)` as a `codegen.Library` (for `codegen.precompile`), None when this
    process holds it compiled already."""
    if ("outputs", model.structure, int(n), True) in _BLOCK_FUNCTIONS:
        return None
    return _outputs_library(model, n)
