"""The solvers the benchmarks measure the production one against, built from the production solver's public parts
(`vehicle.numerics.solvers`: `ros2_stages`, `indicators_by_rectangle`, `block_function`, `Ros2.step_symbols`).

    BaselineRos2(dt)              the yardstick of benchmarks/engine.py and benchmarks/time_parallel.py --baseline
    JacobianReuseRos2(dt, every)  W and its LU made every `every` steps and reused in between

Both fulfil the solver contract (vehicle/numerics/contract.py) and go to a drive as `Ros2` does:
`Drive(model, road, settings, solver=BaselineRos2(0.004))`.

BaselineRos2 is the same method as `Ros2` on the same model, in its simplest compiled form: the parameter values
baked into the code as constants (the compiled function serves one parameter set; only the run parameters are an
input), no common-subexpression elimination, the K steps of a sample folded (`Function.fold`) with the run
parameters repeated for every step, every state by the trapezoid of the method (no rectangle rule for the
indicator quadratures), the C library's exp, log, pow and tanh (CasADi's C as written, not
vehicle.numerics.vector_math's), the block outputs in CasADi's virtual machine, no batched calls.

JacobianReuseRos2: ROS2 is a W-method, second order for any W, so a W made at an earlier step keeps the order and
changes only the error constant and the damping of the stiff modes. The steps of one output sample are counted
from its start, so a sample always starts with a fresh W.

    python benchmarks/baseline_solvers.py --check      # the two checks below (a few minutes)

checks that the baseline integrates the production drive to rounding over one second of class D road, and that
reusing W every 5th step stays within the step's own error and falls with the step like a second-order method.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import casadi as ca
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from vehicle.numerics import solvers  # noqa: E402
from vehicle.numerics.codegen import casadi_c, compile_c, compile_function  # noqa: E402
from vehicle.numerics.contract import SolverCapabilities  # noqa: E402
from vehicle.numerics.step_graph import explicit_reciprocals, lift_parameters  # noqa: E402

# compiled block functions of this process, by the variant's key
_COMPILED: dict = {}


class BlockSolver:
    """The solver contract around a variant's block function (z0, U (nu, K M + 1), p) -> Z (nx + n_memory, M):
    `variant.block(model, dt, K, M)` builds it, `variant.load(graph)` compiles it (or returns it uncompiled)."""

    name = "ros2"

    def __init__(self, dt: float, variant, compile: bool = True):
        self.dt, self.variant, self.compile = float(dt), variant, compile
        self.capabilities = SolverCapabilities(compiled=compile, step_doubling=True,
                                               compiled_outputs=compile and variant.compiled_outputs)
        self.memory = None
        self.build_s = 0.0
        self.K, self.M = 1, 1

    def describe(self) -> dict:
        return {"solver": self.name, "dt_s": self.dt, "compiled": self.compile, **self.variant.describe()}

    def block_graph(self, model, steps_per_sample: int, samples_per_call: int):
        """Nothing to build beside the drive's other libraries: `bind` compiles the block function."""
        return None

    def bind(self, model, steps_per_sample: int, samples_per_call: int) -> "BlockSolver":
        t0 = time.perf_counter()
        self.K, self.M = int(steps_per_sample), int(samples_per_call)
        self.nx, self.nmem = model.nx, model.n_memory
        key = (self.variant.key(model), self.dt, self.K, self.M, self.compile)
        if key not in _COMPILED:
            graph = self.variant.block(model, self.dt, self.K, self.M)
            _COMPILED[key] = self.variant.load(graph) if self.compile else graph
        self.fn = _COMPILED[key]
        self.memory = model.initial_memory()
        self.build_s = time.perf_counter() - t0
        return self

    def advance(self, x0: np.ndarray, U: np.ndarray, p: np.ndarray) -> np.ndarray:
        X, self.memory_samples, self.memory = solvers.advance_block(self.fn, self.nx, x0, self.memory, U, p)
        return X

    def get_state(self) -> np.ndarray:
        return np.asarray(self.memory, float).copy()

    def set_state(self, memory) -> None:
        self.memory = np.asarray(memory, float).reshape(self.nmem).copy()

    def refined_solver(self, factor: int) -> "BlockSolver":
        return BlockSolver(self.dt / factor, self.variant, self.compile)


class Baseline:
    """The baseline's block function (module docstring)."""

    compiled_outputs = False

    def describe(self) -> dict:
        return {"engine": "baseline"}

    def key(self, model) -> tuple:
        return ("baseline", model.structure, model.parameters.numeric().tobytes())

    def block(self, model, dt: float, K: int, M: int) -> ca.Function:
        nx, nu, np_, nm, n_run = model.nx, model.nu, model.np, model.n_memory, model.n_run
        x, mem, u0, u1 = solvers.Ros2.step_symbols(model)
        p_run = ca.SX.sym("p_run", n_run)
        # the parameter values as constants: SX folds the arithmetic on them while the step is built
        p = ca.vertcat(p_run, ca.DM(model.parameters.numeric()))
        st = solvers.ros2_stages(model, dt, x, mem, u0, u1, p)
        step = ca.Function("ros2_step", [ca.vertcat(x, mem), u0, u1, p_run], [ca.vertcat(st.x_next, st.mem_next)])
        block = step.fold(K).mapaccum("ros2_block", M)
        Z0 = ca.MX.sym("z0", nx + nm)
        U = ca.MX.sym("U", nu, K * M + 1)
        P = ca.MX.sym("p", np_)
        n = K * M
        out = block(Z0, U[:, :n], U[:, 1:], ca.repmat(P[:n_run], 1, n))
        return ca.Function(f"hpsim_ros2_baseline_{model.structure}_{K}x{M}", [Z0, U, P], [out])

    def load(self, graph: ca.Function):
        """CasADi's C as written (the C library's math), compiled with the production flags and cached."""
        lib, error = compile_c(casadi_c([graph], f"{graph.name()}.c"), graph.name())
        if lib is None:
            raise RuntimeError(f"the baseline block function did not compile: {error}")
        return ca.external(graph.name(), str(lib))


class JacobianReuse:
    """The block function of ROS2 with W made every `every` steps (module docstring)."""

    compiled_outputs = True

    def __init__(self, every: int):
        if int(every) < 1:
            raise ValueError(f"JacobianReuse every: must be >= 1, got {every}")
        self.every = int(every)

    def describe(self) -> dict:
        return {"jacobian_every": self.every}

    def key(self, model) -> tuple:
        return ("jacobian_every", self.every, model.structure)

    def step_functions(self, model, dt: float) -> tuple:
        """(step, reuse, parametric): the step with a fresh W (z, u0, u1, pw) -> (z_next, the factor values of its
        W), the step solving with given factor values (z, u0, u1, pw, lu) -> z_next, and pw = parametric(p)."""
        x, mem, u0, u1 = solvers.Ros2.step_symbols(model)
        p = ca.SX.sym("p", model.np)
        fresh = solvers.ros2_stages(model, dt, x, mem, u0, u1, p)
        # the reusing step reads the factor values of an earlier fresh step, in this step's layout (the same
        # sparsity at every step)
        F = ca.SX.sym("lu", fresh.lu.values.numel())
        reused = solvers.ros2_stages(model, dt, x, mem, u0, u1, p, solve_stiff=lambda b: fresh.lu.solve(b, F))
        outs = [ca.vertcat(solvers.indicators_by_rectangle(model, dt, x, fresh), fresh.mem_next), fresh.lu.values,
                ca.vertcat(solvers.indicators_by_rectangle(model, dt, x, reused), reused.mem_next)]
        raw = ca.Function("ros2_step_raw", [ca.vertcat(x, mem), u0, u1, p, F], outs)
        args, parts, pw, parametric = lift_parameters(raw, 3, "ros2_parametric")
        z, u0, u1 = args[:3]
        step = ca.Function("ros2_step", [z, u0, u1, pw], parts[:2])
        reuse = ca.Function("ros2_step_reuse", [z, u0, u1, pw, args[4]], [parts[2]])
        return explicit_reciprocals(step), explicit_reciprocals(reuse), explicit_reciprocals(parametric)

    def block(self, model, dt: float, K: int, M: int) -> ca.Function:
        every = min(self.every, K)
        step, reuse, parametric = self.step_functions(model, dt)

        def steps(z, U0, U1, PW):
            zk, lu = z, None
            for k, (u0, u1) in enumerate(zip(ca.horzsplit(U0), ca.horzsplit(U1))):
                if k % every == 0:
                    zk, lu = step(zk, u0, u1, PW)
                else:
                    zk = reuse(zk, u0, u1, PW, lu)
            return zk
        # pieces of a long sample a multiple of `every` steps: each starts with a fresh W, as the sample does
        longest = solvers.MAX_UNROLLED_STEPS
        piece = max(every, longest - longest % every)
        return solvers.block_function(f"hpsim_ros2_{model.structure}_{K}x{M}_j{every}", steps, parametric, K, M,
                                      model.nx + model.n_memory, model.nu, piece)

    def load(self, graph: ca.Function):
        return compile_function(graph)


def BaselineRos2(dt: float = 0.004, *, compile: bool = True) -> BlockSolver:
    """The baseline solver (module docstring)."""
    return BlockSolver(dt, Baseline(), compile)


def JacobianReuseRos2(dt: float = 0.004, every: int = 5, *, compile: bool = True) -> BlockSolver:
    """ROS2 with W made every `every` steps (module docstring)."""
    return BlockSolver(dt, JacobianReuse(every), compile)


# --- the checks (python benchmarks/baseline_solvers.py --check) ---------------------------------------------
ONE_SECOND_M = 20 / 3.6          # one second of drive at 20 km/h: whole output intervals (no partial last one)


def _run(model, road, solver, distance_m, interval_s=0.2):
    """A drive with 5 output samples per second (K = 50 steps at 4 ms: small compiled functions), no error
    estimate: (final state, drive)."""
    from vehicle.engines.full import Drive
    from vehicle.scenario.settings import DriveSettings
    from vehicle.scenario.speed import SpeedProfile

    s = DriveSettings(distance_m=distance_m, speed=SpeedProfile.constant(20 / 3.6), output_interval_s=interval_s,
                      samples_per_block=2, error_check_every=0)
    d = Drive(model, road, s, solver=solver)
    x = d.run().state.x
    assert np.all(np.isfinite(x))
    return x, d


def check_baseline(model, road) -> dict:
    """Over the first second (250 steps from rest on class D) the baseline's dissipated heat agrees with the
    production solver's to 1e-4 relative, the temperatures to 1e-8 K, the deflections to 1 um, while halving the
    step changes the heat by more than 1 % (so the tolerance means something). Longer drives are not compared: a
    friction or valve event amplifies rounding."""
    x_cur, d = _run(model, road, solvers.Ros2(0.004), ONE_SECOND_M)
    x_base, d_base = _run(model, road, BaselineRos2(0.004), ONE_SECOND_M)
    x_half, _ = _run(model, road, solvers.Ros2(0.002), ONE_SECOND_M)
    heat = [sum(x[idx] for idx in d.heat_index) for x in (x_cur, x_base, x_half)]     # [J] per strut
    defl = model.strut_deflections(np.stack([x_cur, x_base], axis=1))
    got = {"heat_rel": float(np.max(np.abs(heat[1] - heat[0]) / heat[0])),
           "temperature_K": float(np.max(np.abs(x_base[d.T_index] - x_cur[d.T_index]))),
           "deflection_m": float(np.max(np.abs(defl[:, 1] - defl[:, 0]))),
           "half_step_heat_rel": float(np.max(np.abs(heat[2] - heat[0]) / heat[0]))}
    assert d_base.compiled_outputs is None and d.compiled_outputs is not None
    assert np.all(heat[0] > 0) and got["heat_rel"] < 1e-4 and got["temperature_K"] < 1e-8, got
    assert got["deflection_m"] < 1e-6 and got["half_step_heat_rel"] > 1e-2, got
    return got


def check_jacobian_reuse(model, road) -> dict:
    """W made every 5th step over 100 m of class D road (stick-slip seal friction at every reversal), against a
    1 ms exact-W reference: its errors in the final strut temperatures and deflections are within 2x (temperature)
    and 3x (deflection) of the exact-W run's own error at 4 ms, and fall at least 2.5x from 4 ms to 2 ms."""
    dist = 100.0
    x_ref, d = _run(model, road, solvers.Ros2(0.001), dist)

    def errors(x):
        defl = model.strut_deflections(np.stack([x, x_ref], axis=1))
        return float(np.max(np.abs(x[d.T_index] - x_ref[d.T_index]))), float(np.max(np.abs(defl[:, 0] - defl[:, 1])))

    err = {}
    for dt in (0.004, 0.002):
        for every in (1, 5):
            solver = solvers.Ros2(dt) if every == 1 else JacobianReuseRos2(dt, every)
            err[f"{dt * 1e3:g}ms_every{every}"] = errors(_run(model, road, solver, dist)[0])
    assert err["4ms_every1"][0] > 1e-4, err
    for q, within in ((0, 2.0), (1, 3.0)):
        assert err["4ms_every5"][q] < within * err["4ms_every1"][q], err
        assert err["2ms_every5"][q] < err["4ms_every5"][q] / 2.5, err
    return err


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="run the two checks of the module docstring")
    args = ap.parse_args(argv)
    if not args.check:
        ap.print_help()
        return
    from terrain import RoadSpec, build_road
    from vehicle.physics.model import VehicleModel
    from vehicle.physics.params import load_vehicle

    model, road = VehicleModel(load_vehicle("apc_8x8")), build_road(RoadSpec(iso_class="D", length=140.0, seed=3))
    print("baseline against the production solver:", check_baseline(model, road))
    print("W reused every 5th step (temperature K, deflection m):", check_jacobian_reuse(model, road))


if __name__ == "__main__":
    main()
