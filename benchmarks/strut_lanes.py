"""Lanes across the struts of one drive (issue 26 item 2): what the strut part of the ROS2 step is worth in lanes.

    python benchmarks/strut_lanes.py [--repeats 15] [--isa avx2]

The eight struts of apc_8x8 are one strut model on eight stations. The step is split into
  kernel    one strut's part, the same SX graph for every station: the valve's warm Newton step, the strut's
            equations (gas law, valves, friction, end stops), its heat network and, at the first stage, its
            stiffness and damping for W. Inputs: the strut's motion, temperatures, gas mass, oil volume and
            flow, warm start, ambient temperature and speed; outputs: the new warm start, force, rates, powers;
  A         scalar: the kernel inputs of the first stage from the state (hull kinematics, levelling flow);
  B         scalar: the rest of f(x, u0) and J from the kernel outputs, the sparse LU of W, k1, and the kernel
            inputs of the second stage at x + h k1; out: those inputs, k1 and the factor values;
  C         scalar: the rest of f(x + h k1, u1), k2 and z_next.
The kernel runs twice per step over the eight stations: as an 8-lane function (`vehicle.numerics.lanes`,
vector lanes) or the same code with the lanes one after the other (-DHPSIM_LANES_SCALAR: eight scalar calls).
Every piece goes through the step's own pipeline (CSE, parameter lifting, explicit reciprocals), the scalar ones
through CasADi's C generator and the engine's compiler flags, like the monolithic step (`Ros2.step_functions`)
they are compared with. A C driver calls the pieces in sequence, the buffers between them in the lane layout
([value][station]): no separate gather or scatter beyond the loads and stores of those buffers.

Printed: instructions of the SX graphs (kernel x 8 per stage against the whole step), time per call of the
kernel (lanes vs scalar) and of the step (monolithic vs split with lanes vs split scalar), measured in one run
and interleaved (minimum of --repeats); the largest difference of the split step's z_next against the monolithic
step's from 200 states of a drive, and whether the split step with lane kernels equals it with scalar kernels.
"""
from __future__ import annotations

import argparse
import ctypes
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import casadi as ca
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from struts.model import StrutInputs                                                 # noqa: E402
from vehicle.numerics import lanes                                                  # noqa: E402
from vehicle.numerics.codegen import compile_c, generate_c                          # noqa: E402
from vehicle.numerics.solvers import (GAMMA, Ros2, SparseLU, divisions_as_reciprocals,  # noqa: E402
                                      explicit_reciprocals)
from vehicle.physics import thermal                                                 # noqa: E402

KIN = ("x", "v", "T_oil", "T_wall", "T_surface", "m_gas", "V_oil", "q_oil", "x_mid", "dp_guess", "T_amb", "speed")
POWERS = ("power_valve", "power_friction", "heat_gas", "power_end_stop")
DT_NODES = tuple(f"dT_{node}" for node in thermal.NODES)


def kernel_names(strut, jacobian: bool):
    """(input names, output names) of one strut's kernel."""
    kout = ("dp", "force", *strut.state_names, *POWERS, *DT_NODES) + (("ks", "cs") if jacobian else ())
    return KIN + tuple(strut.state_names), kout


def strut_kernel(model, i: int, jacobian: bool) -> ca.Function:
    """Station i's strut part of one stage as (kernel inputs, theta) -> kernel outputs: the calls the model makes
    for that station in f (`eliminate_valves`, `equations`) and J (`_strut_stiffness_damping`)."""
    K = model.sym
    P = K.params
    strut = K.struts[i]
    names_in, _ = kernel_names(strut, jacobian)
    s = {nm: ca.SX.sym(nm) for nm in names_in}
    internal = {nm: s[nm] for nm in strut.state_names}
    sin = StrutInputs(x=s["x"], v=s["v"], T_wall=s["T_oil"], m_gas=s["m_gas"], dV_oil=s["V_oil"],
                      dV_oil_rate=s["q_oil"], dT_wall_rate=0.0, x_mid=s["x_mid"])
    dp = strut.valve_pressure_drop(sin.v, sin.T_wall, dp_guess=s["dp_guess"], newton_iterations=1, warm=True,
                                   u=sin, states=internal)
    eq = strut.equations(sin, internal, dp)
    Pr_shape = thermal.oil_prandtl(P.heat, strut.oil_viscosity(strut.p.oil.reference_temperature),
                                   strut.p.oil.density)
    flows = thermal.network_flows(P.heat, thermal.station_environment(P.heat, P.axles[P.station_axle(i)].heat),
                                  s["T_oil"], s["T_wall"], s["T_surface"], s["T_amb"], s["speed"], s["v"],
                                  strut.oil_viscosity(s["T_oil"]), strut.oil_density(s["T_oil"]),
                                  strut.p.oil.expansion, Pr_shape)
    dT = thermal.network_rates(P.heat, flows, eq["power_valve"], eq["power_friction"], eq["power_end_stop"],
                               eq["heat_gas"])
    outs = [dp, eq["force"], *[eq["rates"][nm] for nm in strut.state_names], *[eq[k] for k in POWERS], *dT]
    if jacobian:
        outs += list(model._strut_stiffness_damping(i, s["x"], s["v"], s["T_oil"], s["m_gas"], s["V_oil"], dp,
                                                     [internal[nm] for nm in strut.state_names]))
    return ca.Function("strut_kernel", [ca.vertcat(*[s[nm] for nm in names_in]), model.parameters.symbols],
                       [ca.vertcat(*outs)])


def finished(fn: ca.Function, p_index: int, name: str):
    """`fn` through the step's pipeline (`Ros2.step_functions`): reciprocals of parameters, CSE, the parameter-only
    subexpressions lifted out: (function with input p_index replaced by pw, parametric p -> pw)."""
    raw = divisions_as_reciprocals(fn, parameter_inputs={p_index})
    args = raw.sx_in()
    res = raw.call(args)
    sizes = [r.numel() for r in res]
    ret, w_syms, w_exprs = ca.extract_parametric(ca.cse(ca.vertcat(*res)), args[p_index])
    parts = ca.vertsplit(ret, [int(v) for v in np.cumsum([0] + sizes)])
    w = ca.vertcat(*w_syms) if w_syms else ca.SX(0, 1)
    ins = list(args)
    ins[p_index] = ca.vertcat(args[p_index], w)
    out = ca.Function(name, ins, parts)
    parametric = ca.Function(f"{name}_parametric", [args[p_index]], [ca.vertcat(args[p_index], *w_exprs)])
    return explicit_reciprocals(out), explicit_reciprocals(parametric)


@contextmanager
def strut_outputs_as_symbols(model, KO):
    """While active, the model's equations and stiff Jacobian take each station's strut part from KO[i] (name ->
    SX) instead of computing it: what stays is the scalar rest (hull, tyres, wheels, energies, ride filters)."""
    current = {}

    class Proxy:
        def __init__(self, i, real):
            self.i, self.real = i, real

        def __getattr__(self, name):
            return getattr(self.real, name)

        def equations(self, sin, internal, dp):
            o = KO[self.i]
            current["i"] = self.i
            return {"force": o["force"], "rates": {nm: o[nm] for nm in self.real.state_names}, "residual": None,
                    "gas_pressure": 0.0, "gas_temperature": 0.0, **{k: o[k] for k in POWERS}}

    saved = (model.sym.struts, thermal.network_flows, thermal.network_rates)
    model.sym.struts = [Proxy(i, s) for i, s in enumerate(saved[0])]
    thermal.network_flows = lambda *a, **k: {}
    thermal.network_rates = lambda *a, **k: tuple(KO[current["i"]][n] for n in DT_NODES)
    model._strut_stiffness_damping = lambda i, *a: (KO[i]["ks"], KO[i]["cs"])
    try:
        yield
    finally:
        model.sym.struts, thermal.network_flows, thermal.network_rates = saved
        del model._strut_stiffness_damping


def kernel_inputs(model, x, mem, u, p):
    """The kernel inputs of every station (lists in `kernel_names` order) at state x, warm starts mem, input u."""
    X = {nm: x[k] for k, nm in enumerate(model.layout.names)}
    iu = model.input_index
    out = []
    for i in range(model.n):
        sin, internal = model.strut_inputs(X, i, p, model.sym)
        out.append([sin.x, sin.v, X[f"T_oil[{i}]"], X[f"T_wall[{i}]"], X[f"T_surface[{i}]"], p[i], sin.dV_oil,
                    sin.dV_oil_rate, sin.x_mid, mem[model._z_index[i]], u[iu["ambient"]], u[iu["speed"]],
                    *[internal[nm] for nm in model.struts[i].state_names]])
    return out


def lane_layout(per_station) -> ca.SX:
    """[value][station] as one column: value q of station i at q * n + i."""
    return ca.vertcat(*[per_station[i][q] for q in range(len(per_station[0])) for i in range(len(per_station))])


def split_step(model, dt: float):
    """(A, B, C) of the split step (module docstring), each (function, parametric), and the kernel symbols' sizes."""
    solver = Ros2(dt)
    x, mem, u0, u1 = solver._step_symbols(model)
    p = model.symbols[3]
    z = ca.vertcat(x, mem)
    n, ns, h = model.n, model.n_stiff, dt
    strut = model.sym.struts[0]
    _, out1 = kernel_names(strut, True)
    _, out2 = kernel_names(strut, False)
    KO1s, KO2s = ca.SX.sym("ko1", len(out1) * n), ca.SX.sym("ko2", len(out2) * n)
    KO1 = [{nm: KO1s[q * n + i] for q, nm in enumerate(out1)} for i in range(n)]
    KO2 = [{nm: KO2s[q * n + i] for q, nm in enumerate(out2)} for i in range(n)]
    with strut_outputs_as_symbols(model, KO1):
        f0 = ca.vertcat(*model.equations(x, None, u0, p, dp_override=[o["dp"] for o in KO1])[0])
        J = model.stiff_jacobian(x, p, [o["dp"] for o in KO1])
    lu = SparseLU(ca.SX.eye(ns) - GAMMA * h * J)
    k1 = ca.vertcat(lu.solve(f0[:ns]), f0[ns:])
    KI2 = lane_layout(kernel_inputs(model, x + h * k1, mem, u1, p))
    A = ca.Function("piece_a", [z, u0, p], [lane_layout(kernel_inputs(model, x, mem, u0, p))])
    B = ca.Function("piece_b", [z, u0, u1, p, KO1s], [KI2, k1, lu.values])
    k1s, F = ca.SX.sym("k1", model.nx), ca.SX.sym("lu", lu.values.numel())
    with strut_outputs_as_symbols(model, KO2):
        f1 = ca.vertcat(*model.equations(x + h * k1s, None, u1, p, dp_override=[o["dp"] for o in KO2])[0])
    k2 = ca.vertcat(lu.solve(f1[:ns] - 2.0 * k1s[:ns], F), f1[ns:] - 2.0 * k1s[ns:])
    x_next = x + 1.5 * h * k1s + 0.5 * h * k2
    for k in model.indicator_quadrature_indices():       # the rectangle rule, as `Ros2._stages` (k1 = f0 there)
        x_next[k] = x[k] + h * k1s[k]
    mem1 = ca.vertcat(*[KO2[i]["dp"] for i in range(n)])
    C = ca.Function("piece_c", [z, u1, p, KO2s, k1s, F], [ca.vertcat(x_next, mem1)])
    return finished(A, 2, "piece_a"), finished(B, 3, "piece_b"), finished(C, 2, "piece_c")


def kernel_stepper(kernel, parametric, lanes_n: int, name: str, isa: str, scalar: bool):
    """The kernel as a lane library (`lanes.LaneStepper.from_functions`): the kernel wrapped as a 'step'
    (z = its inputs padded to a common length, two unused one-element inputs, pw) -> its outputs, padded."""
    n_in, n_out = kernel.size1_in(0), kernel.size1_out(0)
    width = max(n_in, n_out)
    zk, pw = ca.SX.sym("zk", width), ca.SX.sym("pw", kernel.size1_in(1))
    out = kernel(zk[:n_in], pw)
    if width > n_out:
        out = ca.vertcat(out, ca.SX(width - n_out, 1))
    step = ca.Function(name, [zk, ca.SX.sym("u0", 1), ca.SX.sym("u1", 1), pw], [out])
    return lanes.LaneStepper.from_functions(step, parametric, lanes_n, name, isa=isa, scalar=scalar)


_DRIVER = r"""
#include <time.h>
typedef int (*kfun)(const double*, const double*, const double*, const double*, double*);
static casadi_real W_[%(nw)d];
static casadi_int IW_[%(niw)d];
static double now(void) { struct timespec t; clock_gettime(CLOCK_MONOTONIC, &t); return t.tv_sec + 1e-9 * t.tv_nsec; }
/* n monolithic steps from the same inputs: seconds */
double slbench_mono(int n, const double* z, const double* u0, const double* u1, const double* pw, double* out) {
  const casadi_real* arg[4] = {z, u0, u1, pw};
  casadi_real* res[1] = {out};
  double t0 = now();
  for (int i = 0; i < n; ++i) ros2_step(arg, res, IW_, W_, 0);
  return now() - t0;
}
/* n split steps: A, kernel (stage 1), B, kernel (stage 2), C; buffers in the lane layout */
double slbench_split(int n, kfun k1, kfun k2, const double* z, const double* u0, const double* u1, const double* pa,
                 const double* pb, const double* pc, const double* pk1, const double* pk2, double* ki1, double* ko1,
                 double* ki2, double* ko2, double* kk, double* lu, double* out) {
  static const double dummy[%(lanes)d] = {0};
  const casadi_real* argA[3] = {z, u0, pa};
  casadi_real* resA[1] = {ki1};
  const casadi_real* argB[5] = {z, u0, u1, pb, ko1};
  casadi_real* resB[3] = {ki2, kk, lu};
  const casadi_real* argC[6] = {z, u1, pc, ko2, kk, lu};
  casadi_real* resC[1] = {out};
  double t0 = now();
  for (int i = 0; i < n; ++i) {
    piece_a(argA, resA, IW_, W_, 0);
    k1(ki1, dummy, dummy, pk1, ko1);
    piece_b(argB, resB, IW_, W_, 0);
    k2(ki2, dummy, dummy, pk2, ko2);
    piece_c(argC, resC, IW_, W_, 0);
  }
  return now() - t0;
}
/* n kernel calls (all lanes) */
double slbench_kernel(int n, kfun k, const double* in, const double* pw, double* out) {
  static const double dummy[%(lanes)d] = {0};
  double t0 = now();
  for (int i = 0; i < n; ++i) k(in, dummy, dummy, pw, out);
  return now() - t0;
}
"""


def scalar_library(fns, lanes_n: int):
    """The scalar functions (CasADi's C generator, the engine's flags) and the C driver in one library."""
    # the C library's exp/log/pow/tanh, as CasADi's C had them (today's engine: the batched step, benchmarks/ensemble.py)
    code = generate_c(list(fns), "strut_lanes_scalar.c", c_library_math=True).decode()
    code += _DRIVER % {"nw": max(f.sz_w() for f in fns) + 16, "niw": max(f.sz_iw() for f in fns) + 16,
                       "lanes": lanes_n}
    lib, error = compile_c(code.encode(), "hpsim_strut_lanes_scalar")
    if lib is None:
        raise RuntimeError(error)
    return lib


def drive_inputs(model, steps: int):
    """(z0, U (steps + 1, nu), p) of the mileage scenario's first steps (apc_8x8, ISO class D, 20 km/h)."""
    from terrain import RoadSpec, build_road
    from vehicle.engines.full import Drive
    from vehicle.scenario.settings import DriveSettings
    from vehicle.scenario.speed import SpeedProfile

    road = build_road(RoadSpec(iso_class="D", length=600.0, seed=0))
    s = DriveSettings(distance_m=500.0, speed=SpeedProfile.constant(20 / 3.6), error_check_every=0)
    drive = Drive(model, road, s, solver=Ros2(0.004))
    st = drive.initial_state()
    U = np.asarray(drive.inputs(0.004 * np.arange(steps + 1)), float)
    U = U.T if U.shape[0] == model.nu else U
    return np.concatenate([st.x, drive.solver.memory]), np.ascontiguousarray(U), np.asarray(drive.p, float)


def arith(fn: ca.Function) -> int:
    """Operations of an SX function other than reading inputs, writing outputs and loading constants."""
    skip = {ca.OP_INPUT, ca.OP_OUTPUT, ca.OP_CONST}
    return sum(1 for k in range(fn.n_instructions()) if fn.instruction_id(k) not in skip)


class Bench:
    """Everything built and loaded: the monolithic step, the split pieces, the kernels as lanes and as scalar."""

    def __init__(self, isa: str, dt: float = 0.004):
        from vehicle.physics.model import VehicleModel
        from vehicle.physics.params import load_vehicle

        self.model = m = VehicleModel(load_vehicle("apc_8x8"))
        self.n = n = m.n
        self.mono, _, self.mono_par, _ = Ros2(dt).step_functions(m)
        kernels = [strut_kernel(m, i, True) for i in range(n)]
        if len({k.serialize() for k in kernels}) != 1:
            raise RuntimeError("the stations' strut parts differ: no lanes across struts for this vehicle")
        self.k1, self.k1_par = finished(kernels[0], 1, "kernel_j")
        self.k2, self.k2_par = finished(strut_kernel(m, 0, False), 1, "kernel_f")
        (self.A, self.pa), (self.B, self.pb), (self.C, self.pc) = split_step(m, dt)
        self.isa = isa
        self.kern = {(stage, scalar): kernel_stepper(k, kp, n, f"hpsim_strut_{stage}_{isa}", isa, scalar)
                     for stage, k, kp in ((1, self.k1, self.k1_par), (2, self.k2, self.k2_par))
                     for scalar in (False, True)}
        self.lib_path = scalar_library([self.mono, self.A, self.B, self.C], n)
        self.load()

    def load(self):
        self.lib = ctypes.CDLL(str(self.lib_path))
        ptr = np.ctypeslib.ndpointer(dtype=np.float64, flags="C_CONTIGUOUS")
        self.lib.slbench_mono.argtypes = [ctypes.c_int] + [ptr] * 5
        self.lib.slbench_split.argtypes = [ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p] + [ptr] * 15
        self.lib.slbench_kernel.argtypes = [ctypes.c_int, ctypes.c_void_p] + [ptr] * 3
        for f in ("slbench_mono", "slbench_split", "slbench_kernel"):
            getattr(self.lib, f).restype = ctypes.c_double
        self.fp = {key: ctypes.cast(ctypes.CDLL(str(s.library))[f"{s.name}_step"], ctypes.c_void_p).value
                   for key, s in self.kern.items()}

    def set_parameters(self, p):
        m, n = self.model, self.n
        theta = p[m.n_run:]
        lane = lambda w: np.ascontiguousarray(np.repeat(np.asarray(w, float).ravel()[:, None], n, 1))  # noqa: E731
        self.pw = np.asarray(self.mono_par(p), float).ravel()
        self.pA, self.pB, self.pC = (np.asarray(f(p), float).ravel() for f in (self.pa, self.pb, self.pc))
        self.pk1, self.pk2 = lane(self.k1_par(theta)), lane(self.k2_par(theta))
        width = lambda k: max(k.size1_in(0), k.size1_out(0)) * n  # noqa: E731
        self.buf = [np.zeros(width(self.k1)), np.zeros(width(self.k1)), np.zeros(width(self.k2)),
                    np.zeros(width(self.k2)), np.zeros(self.model.nx), np.zeros(self.B.size1_out(2))]

    def mono_step(self, z, u0, u1, n=1):
        out = np.empty_like(z)
        t = self.lib.slbench_mono(n, z, u0, u1, self.pw, out)
        return out, t

    def split_step(self, z, u0, u1, scalar: bool, n=1):
        out = np.empty_like(z)
        t = self.lib.slbench_split(n, self.fp[1, scalar], self.fp[2, scalar], z, u0, u1, self.pA, self.pB, self.pC,
                               self.pk1, self.pk2, *self.buf, out)
        return out, t

    def kernel_time(self, stage: int, scalar: bool, n: int):
        ki = self.buf[0] if stage == 1 else self.buf[2]
        pk = self.pk1 if stage == 1 else self.pk2
        return self.lib.slbench_kernel(n, self.fp[stage, scalar], ki, pk, np.empty_like(ki))


def compare(bench, z0, U, steps: int):
    """The split step against the monolithic step, one step from each state of a monolithic trajectory (largest
    relative difference of z_next: rounding), and the split step's trajectories with lanes and with scalar
    kernels (bitwise equal?). Trajectories of the split and the monolithic step are not compared: the step
    amplifies a 1e-15 change of the state to O(1) in the valves' warm starts within 250 steps (docs/engines.md)."""
    def rel(a, b):
        return float(np.max(np.abs(a - b) / np.maximum(np.abs(b), 1e-8)))
    out = {"one_step_lanes": 0.0, "one_step_scalar": 0.0}
    z, zl, zs = z0.copy(), z0.copy(), z0.copy()
    for k in range(steps):
        zn, _ = bench.mono_step(z, U[k], U[k + 1])
        for scalar in (False, True):
            key = "one_step_scalar" if scalar else "one_step_lanes"
            out[key] = max(out[key], rel(bench.split_step(z, U[k], U[k + 1], scalar)[0], zn))
        zl, _ = bench.split_step(zl, U[k], U[k + 1], False)
        zs, _ = bench.split_step(zs, U[k], U[k + 1], True)
        z = zn
    out["lanes_equal_scalar"] = bool(np.array_equal(zl, zs))
    return out, z


def timings(bench, z, u0, u1, repeats: int, n: int = 4000) -> dict:
    """Seconds per call (minimum of `repeats`, the variants interleaved)."""
    best = {}
    runs = {"step_mono": lambda: bench.mono_step(z, u0, u1, n)[1],
            "step_split_lanes": lambda: bench.split_step(z, u0, u1, False, n)[1],
            "step_split_scalar": lambda: bench.split_step(z, u0, u1, True, n)[1],
            "kernel1_lanes": lambda: bench.kernel_time(1, False, n), "kernel1_scalar": lambda: bench.kernel_time(1, True, n),
            "kernel2_lanes": lambda: bench.kernel_time(2, False, n), "kernel2_scalar": lambda: bench.kernel_time(2, True, n)}
    bench.split_step(z, u0, u1, False)                    # the kernels' input buffers hold this step's values
    for _ in range(repeats):
        for k, f in runs.items():
            best[k] = min(best.get(k, np.inf), f() / n)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--isa", default=None, help="lane instruction set (default: lanes.default_isa())")
    a = ap.parse_args()
    t0 = time.perf_counter()
    isa = a.isa or lanes.default_isa()
    bench = Bench(isa)
    m = bench.model
    z0, U, p = drive_inputs(m, 200)
    bench.set_parameters(p)
    diff, z = compare(bench, z0, U, 200)
    u0, u1 = U[-2], U[-1]
    t = timings(bench, z, u0, u1, a.repeats)
    ops = {"step": arith(bench.mono), "kernel1": arith(bench.k1), "kernel2": arith(bench.k2),
           "A": arith(bench.A), "B": arith(bench.B), "C": arith(bench.C)}
    n = bench.n
    strut = n * (ops["kernel1"] + ops["kernel2"])
    rest = ops["A"] + ops["B"] + ops["C"]
    print(f"apc_8x8, {n} struts, lanes: {isa} x {n} lanes; math: {lanes.__name__} as installed (see docs/engines.md)")
    print("SX operations per step (no inputs, outputs, constants):")
    print(f"  monolithic step                      {ops['step']:7d}")
    print(f"  strut kernels: {n} x ({ops['kernel1']} + {ops['kernel2']}) = {strut:7d}   "
          f"{strut / ops['step']:.0%} of the monolithic step")
    print(f"  scalar rest: A {ops['A']} + B {ops['B']} + C {ops['C']} = {rest:7d}   "
          f"split total {strut + rest} ({(strut + rest) / ops['step'] - 1:+.0%}: the CSE across struts and stages lost)")
    us = {k: v * 1e6 for k, v in t.items()}
    print("time per call, us (minimum of interleaved repeats, this run):")
    for st in (1, 2):
        print(f"  strut kernel stage {st}, all {n} struts: scalar {us[f'kernel{st}_scalar']:6.2f}  "
              f"lanes {us[f'kernel{st}_lanes']:6.2f}   ratio {us[f'kernel{st}_scalar'] / us[f'kernel{st}_lanes']:.2f}x")
    kern_s = us["kernel1_scalar"] + us["kernel2_scalar"]
    kern_l = us["kernel1_lanes"] + us["kernel2_lanes"]
    print(f"  step monolithic      {us['step_mono']:6.2f}")
    print(f"  step split, scalar   {us['step_split_scalar']:6.2f}   kernels {kern_s:.2f} "
          f"({kern_s / us['step_split_scalar']:.0%}), rest {us['step_split_scalar'] - kern_s:.2f}")
    print(f"  step split, lanes    {us['step_split_lanes']:6.2f}   kernels {kern_l:.2f}, "
          f"rest {us['step_split_lanes'] - kern_l:.2f}")
    print(f"  gain of the split lane step over the monolithic step: {us['step_mono'] / us['step_split_lanes']:.2f}x "
          f"(strut share of the monolithic step's time, est. {kern_s / us['step_mono']:.0%}: "
          f"bound {1 / (1 - kern_s / us['step_mono'] + kern_l / us['step_mono']):.2f}x without the split's losses)")
    print(f"largest relative difference of z_next against the monolithic step, one step from 200 states of a drive: "
          f"lanes {diff['one_step_lanes']:.1e}, scalar kernels {diff['one_step_scalar']:.1e}; split step with lanes "
          f"and with scalar kernels over 200 steps: {'bitwise equal' if diff['lanes_equal_scalar'] else 'DIFFERENT'}")
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
