"""The ROS2 step split around the struts: lanes across struts (docs/engines.md).

The stations of a vehicle are one strut's equations on different data. Split that way, the step
(`Ros2.step_functions`) is five functions, each put through the step's graph rewrites (`step_graph`):

  A         the kernel inputs of the first stage from the state (hull kinematics, levelling flow).
  kernel 1  the strut kernel (`vehicle.physics.strut_kernel`) of every station at the first stage, with its
            stiffness and damping for W.
  B         the rest of f(x, u0) and J from the kernels' outputs (hull, tyres, wheels, energies, ride filters), the
            sparse LU of W, k1, and the kernel inputs of the second stage at x + h k1.
  kernel 2  the strut kernel of every station at the second stage.
  C         the rest of f(x + h k1, u1), k2 and z_next.

The compiled step (`vehicle.numerics.lanes`, `split_step_source`) runs a kernel over all stations at once: one
case's stations in one vector (the scalar engine's block function), or station after station over the lanes of
cases (the ensemble). Every station's value is the same sequence of IEEE operations in either form, so the
ensemble's lanes equal the scalar engine bit for bit, as with the whole step. Against the whole step the split
differs by rounding only: it lifts, merges and rewrites per function (docs/engines.md, "Lanes across struts").

The kernel is one function for all stations when their kernels are one graph with the station's parameters as
inputs: each station's kernel has its parameter-only part lifted out (`step_graph.lift_parameters`), and the
parameters and lifted values it reads become its per-station inputs (lanes of the kernel's parameter vector).
Stations with struts of different structure, a strut with a compressible oil (no eliminated valve) or stiff
internal states (an exact Jacobian), a vehicle of one station: no split (`build` returns None), the whole step as
before.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from vehicle.numerics.instructions import instructions
from vehicle.numerics.step_graph import GAMMA, SparseLU, explicit_reciprocals, lift_parameters


@dataclass(frozen=True)
class SplitStep:
    """The split step's functions (module docstring). pieces: A (z, u0, pw_a) -> kernel 1 inputs; B (z, u0, u1, pw_b,
    kernel 1 outputs) -> (kernel 2 inputs, k1, LU values); C (z, u1, pw_c, kernel 2 outputs, k1, LU values) ->
    z_next. kernels: (inputs, kernel parameters) -> outputs of one station. Buffers between them hold value q of
    station s at q * padded + s (the stations padded to a power of two: copies of station 0). parametric:
    p -> pw = [pw_a; pw_b; pw_c; kernel 1's parameters; kernel 2's], the kernels' in the stations' layout;
    offsets: where each part starts in pw."""

    pieces: tuple
    kernels: tuple
    parametric: ca.Function
    stations: int
    padded: int
    offsets: dict
    nz: int
    nu: int


def _same_graph(f: ca.Function, g: ca.Function) -> bool:
    """Whether two SX functions are the same sequence of operations on the same inputs and constants."""
    if f.n_instructions() != g.n_instructions() or f.sz_w() != g.sz_w():
        return False
    if [f.size1_in(k) for k in range(f.n_in())] != [g.size1_in(k) for k in range(g.n_in())]:
        return False
    return instructions(f) == instructions(g)


def _kernel(model, i: int, jacobian: bool, name: str) -> tuple[ca.Function, ca.Function]:
    """Station i's kernel as (inputs, q) -> outputs, with q the parameters and lifted values it reads, and
    [the station's run parameters; p] -> q (both through the step's rewrites)."""
    args, parts, pw, parametric = lift_parameters(model.strut_kernel(i, jacobian), 1, f"{name}_parametric")
    lifted = ca.Function(name, args, [ca.densify(parts[0])])
    read = sorted({ins.inputs[1] for ins in instructions(lifted) if ins.op == ca.OP_INPUT and ins.inputs[0] == 1})
    q = ca.vertcat(*[pw[k] for k in read]) if read else ca.SX(0, 1)
    fn = ca.Function(name, [args[0], q], [ca.densify(parts[0])])
    p = parametric.sx_in(0)
    q_of_p = parametric(p)
    return explicit_reciprocals(fn), ca.Function(f"{name}_parametric", [p], [ca.vertcat(*[q_of_p[k] for k in read])])


def _stations_layout(per_station: list, padded: int) -> ca.SX:
    """Values per station (lists of equal length) as one column, value q of station s at q * padded + s; the
    padding stations copy station 0."""
    n = len(per_station)
    rows = [per_station[s if s < n else 0][q] for q in range(len(per_station[0])) for s in range(padded)]
    return ca.vertcat(*rows)


def _kernels(model, padded: int, p: ca.SX):
    """(kernel 1, kernel 2, their parameters in the stations' layout as SX of p) or None where the stations'
    kernels are not one graph."""
    out = []
    for stage, jacobian in ((1, True), (2, False)):
        fns = [_kernel(model, i, jacobian, f"kernel_{stage}") for i in range(model.n)]
        if not all(_same_graph(fns[0][0], fn) for fn, _ in fns[1:]):
            return None
        q = [list(ca.vertsplit(par(ca.vertcat(*model.station_run_parameters(i, p), p)))) if par.size1_out(0) else []
             for i, (_, par) in enumerate(fns)]
        out.append((fns[0][0], _stations_layout(q, padded) if q[0] else ca.SX(0, 1)))
    return out


def build(solver, model) -> SplitStep | None:
    """The split step of `solver` (a `Ros2` with W at every step) on `model`, or None (module docstring)."""
    if not getattr(model, "has_strut_kernel", False) or model.n < 2:
        return None
    n = model.n
    padded = 1 << (n - 1).bit_length()
    # the model's own parameter symbol: the equations read theta through the model's symbolic twin (its tail)
    p = model.symbols[3]
    kernels = _kernels(model, padded, p)
    if kernels is None:
        return None
    x, mem, u0, u1 = solver.step_symbols(model)
    z = ca.vertcat(x, mem)
    h, ns = solver.dt, model.n_stiff
    names_out = [model.strut_kernel_names(0, jacobian)[1] for jacobian in (True, False)]
    KO1s, KO2s = (ca.SX.sym(f"ko{k + 1}", len(names) * padded) for k, names in enumerate(names_out))
    KO1, KO2 = ([{nm: KO[q * padded + s] for q, nm in enumerate(names)} for s in range(n)]
                for KO, names in ((KO1s, names_out[0]), (KO2s, names_out[1])))
    # stage 1: f(x, u0) and the stiff Jacobian from the kernels' outputs, W's LU, k1; the kernel inputs at x + h k1
    f0 = model.rates_from_strut_kernels(x, u0, p, KO1)
    J = model.stiff_jacobian(x, p, [o["dp"] for o in KO1], stiffness=[(o["ks"], o["cs"]) for o in KO1])
    lu = SparseLU(ca.SX.eye(ns) - GAMMA * h * J)
    k1 = ca.vertcat(lu.solve(f0[:ns]), f0[ns:])
    A = ca.Function("piece_a", [z, u0, p], [_stations_layout(model.strut_kernel_inputs(x, mem, u0, p), padded)])
    B = ca.Function("piece_b", [z, u0, u1, p, KO1s],
                    [_stations_layout(model.strut_kernel_inputs(x + h * k1, mem, u1, p), padded), k1, lu.values])
    # stage 2 (`Ros2._stages`): k2, z_next; the indicator quadratures by the rectangle rule on f0 (= k1 there: the
    # rows are not stiff); the valves' warm starts for the next step are this stage's pressure drops
    k1s, F = ca.SX.sym("k1", model.nx), ca.SX.sym("lu", lu.values.numel())
    f1 = model.rates_from_strut_kernels(x + h * k1s, u1, p, KO2)
    k2 = ca.vertcat(lu.solve(f1[:ns] - 2.0 * k1s[:ns], F), f1[ns:] - 2.0 * k1s[ns:])
    x_next = x + 1.5 * h * k1s + 0.5 * h * k2
    for k in model.indicator_quadrature_indices():
        x_next[k] = x[k] + h * k1s[k]
    mem1 = ca.vertcat(*[KO2[s]["dp"] for s in range(n)])
    C = ca.Function("piece_c", [z, u1, p, KO2s, k1s, F], [ca.vertcat(x_next, mem1)])
    pieces, parametric_parts = [], []
    for fn, p_index in ((A, 2), (B, 3), (C, 2)):
        args, parts, _, parametric = lift_parameters(fn, p_index, f"{fn.name()}_parametric")
        pieces.append(explicit_reciprocals(ca.Function(fn.name(), args, list(parts))))
        parametric_parts.append(parametric(p))
    parametric_parts += [kernels[0][1], kernels[1][1]]
    offsets, start = {}, 0
    for key, part in zip(("a", "b", "c", "k1", "k2"), parametric_parts):
        offsets[key] = start
        start += part.numel()
    parametric = explicit_reciprocals(ca.Function("split_parametric", [p], [ca.vertcat(*parametric_parts)]))
    return SplitStep(pieces=tuple(pieces), kernels=(kernels[0][0], kernels[1][0]), parametric=parametric,
                     stations=n, padded=padded, offsets=offsets, nz=model.nx + model.n_memory, nu=model.nu)
