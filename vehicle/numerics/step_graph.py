"""The ROS2 step's graph tools: the method's constant, the symbolic sparse LU of W, and the rewrites every step
graph goes through before it becomes C (`Ros2.step_functions`, the split step of `vehicle.numerics.split_step`):
divisions by parameters as reciprocals, common subexpressions merged, the parameter-only part lifted out, the
divisions the C compiler would rewrite made explicit."""
from __future__ import annotations

import casadi as ca
import numpy as np

from vehicle.numerics.instructions import defining_instructions, replay

GAMMA = 1.0 - 1.0 / np.sqrt(2.0)


class SparseLU:
    """Symbolic sparse LU without pivoting, A = L U, in the given order (L and U as dicts of rows).

    For W = I - gamma h J of the vehicle (stations first, hull last) the pivots are the
    diagonal of a matrix close to I plus a dissipative part, so no pivoting is needed, and the
    elimination order keeps the fill inside the hull block (arrowhead structure).
    `values`: SX vector of the nonzeros of L, of the strict upper part of U and the reciprocals of the pivots, in a
    fixed order; `solve(b, values=None)` solves A x = b for SX b with these factors or with any vector of the same
    layout (a factorisation made at another step: Jacobian/LU reuse)."""

    def __init__(self, A: ca.SX):
        n = self.n = A.size1()
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
        self.lower, self.upper = lower, rows
        # the layout of `values`: L by rows, the strict upper part of U by rows, then the pivots
        self.lower_keys = [(i, k) for i in range(n) for k in lower[i]]
        self.upper_keys = [(i, j) for i in range(n) for j in self.upper[i] if j > i]
        self.values = ca.vertcat(*[lower[i][k] for i, k in self.lower_keys],
                                 *[self.upper[i][j] for i, j in self.upper_keys],
                                 *[1.0 / self.upper[i][i] for i in range(n)])

    def solve(self, b, values=None):
        n = self.n
        if values is None:
            lower, upper = self.lower, self.upper
        else:
            nl, nu = len(self.lower_keys), len(self.upper_keys)
            lower = [dict() for _ in range(n)]
            upper = [dict() for _ in range(n)]
            for q, (i, k) in enumerate(self.lower_keys):
                lower[i][k] = values[q]
            for q, (i, j) in enumerate(self.upper_keys):
                upper[i][j] = values[nl + q]
            inverse_pivots = [values[nl + nu + i] for i in range(n)]
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
            xs[i] = acc / upper[i][i] if values is None else acc * inverse_pivots[i]
        return ca.vertcat(*xs)


def divisions_as_reciprocals(fn: ca.Function, parameter_inputs: set[int]) -> ca.Function:
    """Same SX function, with every division by a parameter-only quantity written as a product with
    its reciprocal (a / b -> a * (1 / b)).

    With parameters as inputs a divisor such as a mass or a heat capacity is no longer a constant
    the compiler can turn into a multiplication; as a reciprocal it becomes a parameter-only
    subexpression that `extract_parametric` lifts out of the step, evaluated once per call.
    Results differ from the plain division by rounding only. Replays the function's instructions.
    """
    defs = defining_instructions(fn)
    fixed: dict[int, bool] = {}          # instruction -> its value depends on parameters and constants only
    for ins, reads in defs:
        if ins.op == ca.OP_INPUT:
            fixed[ins.index] = ins.inputs[0] in parameter_inputs
        elif ins.op == ca.OP_CONST:
            fixed[ins.index] = True
        elif ins.op != ca.OP_OUTPUT:
            fixed[ins.index] = all(fixed[r] for r in reads)

    def value(ins, operands):
        reads = defs[ins.index][1]
        if ins.op == ca.OP_DIV and fixed[reads[1]] and not fixed[reads[0]]:
            return operands[0] * (1.0 / operands[1])
        return None
    return replay(fn, value)


def explicit_reciprocals(fn: ca.Function, threshold: int = 3) -> ca.Function:
    """Same SX function, with the divisions the C compiler's -freciprocal-math would rewrite rewritten here:
    a / c -> a * (1/c) for a constant c, and a / d -> a * r with r = 1/d computed once for a divisor d of at
    least `threshold` divisions (GCC's rule). The code is then compiled without -freciprocal-math: every
    statement rounds as IEEE arithmetic says, whatever the compiler's choice of instructions, so the scalar
    engine and the vector lanes (vehicle.numerics.lanes) give the same bits (with -freciprocal-math GCC rewrote
    other divisions in vector code than in scalar code: 1 ulp, grown to 0.1 mm of strut travel in 2 s).
    Replays the function's instructions (values, not registers: CasADi reuses registers)."""
    defs = defining_instructions(fn)
    count: dict[int, int] = {}                  # divisor (its defining instruction) -> divisions by it
    for ins, reads in defs:
        if ins.op == ca.OP_DIV:
            count[reads[1]] = count.get(reads[1], 0) + 1
    const = {ins.index: ins.constant for ins, _ in defs if ins.op == ca.OP_CONST}
    recip: dict[int, ca.SX] = {}

    def value(ins, operands):
        if ins.op != ca.OP_DIV:
            return None
        d = defs[ins.index][1][1]
        if d not in const and count[d] < threshold:
            return None
        if d not in recip:
            recip[d] = ca.SX(1.0 / const[d]) if d in const else 1.0 / operands[1]
        return operands[0] * recip[d]
    return replay(fn, value)


def lift_parameters(raw: ca.Function, p_index: int, parametric_name: str) -> tuple:
    """`raw`'s outputs with divisions by parameters as reciprocals (`divisions_as_reciprocals`), repeated
    subexpressions merged (`ca.cse`) and what depends on input `p_index` (the parameters p) only lifted out
    (`ca.extract_parametric`), computed once per call instead of at every step. Returns (the inputs, input p_index
    replaced by pw = [p; w]; the outputs in those inputs; pw; parametric: p -> pw). Results differ from `raw`'s by
    rounding only. The caller forms its functions and applies `explicit_reciprocals` to each."""
    raw = divisions_as_reciprocals(raw, parameter_inputs={p_index})
    args = raw.sx_in()
    p = args[p_index]
    res = raw.call(args)
    sizes = [r.numel() for r in res]
    ret, w_syms, w_exprs = ca.extract_parametric(ca.cse(ca.vertcat(*res)), p)
    parts = ca.vertsplit(ret, [int(v) for v in np.cumsum([0] + sizes)])
    pw = ca.vertcat(p, *w_syms)
    args[p_index] = pw
    parametric = ca.Function(parametric_name, [p], [ca.vertcat(p, *w_exprs)])
    return args, parts, pw, parametric
