"""The instruction list of a CasADi SX function, walked in one place: every rewrite and code generator of hpsim
that reads CasADi's algorithm (`vehicle.numerics.step_graph`, `lanes`, `split_step`) reads it through here.

An SX function's algorithm is a list of instructions, each an operation (`ca.OP_*`) reading work registers (or,
for OP_INPUT, an input and a nonzero of it) and writing one (OP_OUTPUT: an output and a nonzero of it). CasADi
reuses registers, so a register names different values over the list: `defining_instructions` follows the values.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca


@dataclass(frozen=True)
class Instruction:
    """Instruction `index` of an SX function: operation `op` (ca.OP_*), the registers it reads (`inputs`; for
    OP_INPUT: (input, nonzero)) and writes (`outputs`; for OP_OUTPUT: (output, nonzero)), and its value for
    OP_CONST (else None)."""

    index: int
    op: int
    inputs: tuple[int, ...]
    outputs: tuple[int, ...]
    constant: float | None = None

    @property
    def register(self) -> int:
        """The work register this instruction writes (not for OP_OUTPUT)."""
        return self.outputs[0]


def instructions(fn: ca.Function) -> list[Instruction]:
    """The instructions of SX function `fn`, in order."""
    out = []
    for k in range(fn.n_instructions()):
        op = fn.instruction_id(k)
        out.append(Instruction(k, op, tuple(fn.instruction_input(k)), tuple(fn.instruction_output(k)),
                               fn.instruction_constant(k) if op == ca.OP_CONST else None))
    return out


def defining_instructions(fn: ca.Function) -> list[tuple[Instruction, list[int]]]:
    """Per instruction: (it, the indices of the instructions whose values it reads): the registers it reads
    mapped to the instruction that last wrote each."""
    writer: dict[int, int] = {}
    out = []
    for ins in instructions(fn):
        reads = [] if ins.op in (ca.OP_INPUT, ca.OP_CONST) else [writer[r] for r in ins.inputs]
        out.append((ins, reads))
        if ins.op != ca.OP_OUTPUT:
            writer[ins.register] = ins.index
    return out


def replay(fn: ca.Function, value) -> ca.Function:
    """`fn` rebuilt instruction by instruction: value(ins, operands) gives the SX value of each computing
    instruction from the SX values of the registers it reads (`operands`), or None for CasADi's own operation;
    inputs, constants and outputs are copied. Returns a function with fn's name, inputs and outputs."""
    inputs = [ca.SX.sym(fn.name_in(i), fn.sparsity_in(i)) for i in range(fn.n_in())]
    outputs = [[None] * fn.sparsity_out(i).nnz() for i in range(fn.n_out())]
    work: dict[int, ca.SX] = {}
    for ins in instructions(fn):
        if ins.op == ca.OP_INPUT:
            work[ins.register] = inputs[ins.inputs[0]].nz[ins.inputs[1]]
        elif ins.op == ca.OP_OUTPUT:
            outputs[ins.outputs[0]][ins.outputs[1]] = work[ins.inputs[0]]
        elif ins.op == ca.OP_CONST:
            work[ins.register] = ca.SX(ins.constant)
        else:
            operands = [work[r] for r in ins.inputs]
            v = value(ins, operands)
            if v is None:
                v = ca.SX.binary(ins.op, *operands) if len(operands) == 2 else ca.SX.unary(ins.op, operands[0])
            work[ins.register] = v
    outs = [ca.SX(fn.sparsity_out(i), ca.vertcat(*[v if v is not None else ca.SX(0) for v in vals]))
            if vals else ca.SX(fn.sparsity_out(i)) for i, vals in enumerate(outputs)]
    return ca.Function(fn.name(), inputs, outs, fn.name_in(), fn.name_out())
